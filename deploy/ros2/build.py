"""Builds a ROS 2 interface package (`.action` and `.msg` files) for rclpy, without colcon.

    python build.py PACKAGE_DIR PREFIX

Run it with the Python that has ROS 2 (the generators come with `ros-jazzy-rclpy`'s wheels), and
with a C and C++ compiler on PATH. It does what `colcon build` does for a message package:
ROS 2's own generators (rosidl_adapter, rosidl_generator_c, the Fast DDS and introspection type
supports, rosidl_typesupport_c, rosidl_generator_py), then the compiler. PREFIX becomes an
install prefix like colcon's:

    PREFIX/share/<package>/{action,msg}/      the definitions (for TRACE's catalogues)
    PREFIX/lib/lib<package>__*.so             the type support libraries
    PREFIX/lib/python3.X/site-packages/<package>/   the Python types

Use it as `source install/setup.bash` would: PREFIX on AMENT_PREFIX_PATH, PREFIX/lib on
LD_LIBRARY_PATH, the site-packages on PYTHONPATH. A robot's own ROS 2 workspace builds its
packages with colcon instead; TRACE only reads the definitions.
"""

import os
import pathlib
import shutil
import subprocess
import sys
import sysconfig

# Every action package depends on these (goal ids, status, times, service events).
DEPENDS = ["action_msgs", "builtin_interfaces", "unique_identifier_msgs", "service_msgs"]


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    src = pathlib.Path(sys.argv[1]).resolve()
    prefix = pathlib.Path(sys.argv[2]).resolve()
    pkg = src.name
    venv = pathlib.Path(sys.prefix)
    os.environ.setdefault("AMENT_PREFIX_PATH", str(venv))

    from ament_index_python import get_package_share_directory
    from rosidl_adapter.action import convert_action_to_idl
    from rosidl_adapter.msg import convert_msg_to_idl
    from rosidl_generator_c.cli import GenerateC
    from rosidl_generator_py.cli import GeneratePython
    from rosidl_typesupport_c.cli import GenerateCTypesupport
    from rosidl_typesupport_fastrtps_c.cli import GenerateFastRTPSCTypesupport
    from rosidl_typesupport_introspection_c.cli import GenerateIntrospectionCTypesupport

    build = prefix / "build" / pkg
    shutil.rmtree(build, ignore_errors=True)
    idl = build / "idl"
    for p in sorted(src.glob("msg/*.msg")):
        convert_msg_to_idl(src, pkg, p.relative_to(src), idl / "msg")
    for p in sorted(src.glob("action/*.action")):
        convert_action_to_idl(src, pkg, p.relative_to(src), idl / "action")
    files = [f"{idl}:{p.relative_to(idl)}" for p in sorted(idl.glob("*/*.idl"))]
    if not files:
        sys.exit(f"{src}: no msg/*.msg or action/*.action")
    include = [get_package_share_directory(d) for d in DEPENDS]

    # The generators, as rosidl_cmake runs them; rmw_fastrtps needs both type supports
    # (Fast DDS's for the wire, introspection's for the type object), so the C type support
    # dispatches between them.
    gen = build / "gen"
    GenerateC("c").generate(pkg, files, include, build / "c")
    GenerateFastRTPSCTypesupport("fastrtps_c").generate(pkg, files, include, build / "fastrtps_c")
    GenerateIntrospectionCTypesupport("introspection_c").generate(
        pkg, files, include, build / "introspection_c"
    )
    GenerateCTypesupport(
        "typesupport_c",
        typesupport_implementations=[
            "rosidl_typesupport_fastrtps_c",
            "rosidl_typesupport_introspection_c",
        ],
    ).generate(pkg, files, include, build / "typesupport_c")
    GeneratePython("py", typesupport_implementations=["rosidl_typesupport_c"]).generate(
        pkg, files, include, build / "py"
    )
    for kind in ("c", "fastrtps_c", "introspection_c", "typesupport_c"):
        shutil.copytree(build / kind, gen / pkg, dirs_exist_ok=True,
                        ignore=shutil.ignore_patterns("tmp"))

    import numpy

    lib = prefix / "lib"
    lib.mkdir(parents=True, exist_ok=True)
    flags = ["-shared", "-fPIC", "-O1", "-w", "-I", str(gen), "-I", str(venv / "include")]
    flags += [a for d in sorted((venv / "include").iterdir()) for a in ("-I", str(d))]
    flags += ["-I", numpy.get_include(), "-I", sysconfig.get_paths()["include"]]
    flags += ["-L", str(lib), "-L", str(venv / "lib"), f"-Wl,-rpath,{lib}:{venv / 'lib'}"]

    def link(out, sources, libs, cxx=False):
        cmd = ["g++" if cxx else "gcc", "-o", str(out)] + [str(s) for s in sources] + flags
        subprocess.run(cmd + [f"-l{name}" for name in libs], check=True)

    def each(kind):
        return [f"{d}__{kind}" for d in DEPENDS]

    c = f"{pkg}__rosidl_generator_c"
    link(lib / f"lib{c}.so", sorted((build / "c").glob("**/*.c")),
         ["rosidl_runtime_c", "rcutils"] + each("rosidl_generator_c"))
    link(lib / f"lib{pkg}__rosidl_typesupport_fastrtps_c.so",
         sorted((build / "fastrtps_c").glob("**/*.cpp")),
         [c, "fastcdr", "rmw", "rosidl_runtime_c", "rosidl_typesupport_fastrtps_c",
          "rosidl_typesupport_fastrtps_cpp", "rcutils"]
         + each("rosidl_typesupport_fastrtps_c") + each("rosidl_generator_c"), cxx=True)
    link(lib / f"lib{pkg}__rosidl_typesupport_introspection_c.so",
         sorted((build / "introspection_c").glob("**/*.c")),
         [c, "rosidl_runtime_c", "rosidl_typesupport_introspection_c"]
         + each("rosidl_typesupport_introspection_c") + each("rosidl_generator_c"))
    link(lib / f"lib{pkg}__rosidl_typesupport_c.so",
         sorted((build / "typesupport_c").glob("**/*.cpp")),
         [c, "rosidl_runtime_c", "rosidl_typesupport_c", "rcpputils", "rcutils"]
         + each("rosidl_typesupport_c"), cxx=True)
    py = build / "py"
    link(lib / f"lib{pkg}__rosidl_generator_py.so", sorted(py.glob("*/*_s.c")),
         [c, "rosidl_runtime_c", "rcutils"] + each("rosidl_generator_py") + each("rosidl_generator_c"))

    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    site = lib / version / "site-packages" / pkg
    shutil.rmtree(site, ignore_errors=True)
    shutil.copytree(py, site, ignore=shutil.ignore_patterns("tmp", "*.c"))
    (site / "__init__.py").touch()
    link(site / f"{pkg}_s__rosidl_typesupport_c.so", [py / f"_{pkg}_s.ep.rosidl_typesupport_c.c"],
         [f"{pkg}__rosidl_generator_py", f"{pkg}__rosidl_typesupport_c", c, "rosidl_runtime_c"])

    share = prefix / "share" / pkg
    shutil.rmtree(share, ignore_errors=True)
    for kind in ("msg", "action"):
        if (src / kind).is_dir():
            shutil.copytree(src / kind, share / kind)
    if (src / "package.xml").is_file():
        shutil.copy(src / "package.xml", share / "package.xml")
    index = prefix / "share" / "ament_index" / "resource_index" / "packages"
    index.mkdir(parents=True, exist_ok=True)
    (index / pkg).touch()
    shutil.rmtree(prefix / "build", ignore_errors=True)
    print(f"built {pkg} into {prefix}")


main()
