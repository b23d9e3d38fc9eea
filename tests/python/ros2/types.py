"""What rclpy says of every message and action definition under a `share/` directory: each
field's type as `get_fields_and_field_types()` names it, printed as one JSON object
(`{"pkg/msg/Name": {field: type}, "pkg/action/Name": [goal, result, feedback]}`), for
tests/it/ros2.rs to compare with TRACE's reading of the same files."""

import importlib
import json
import os
import sys


def main():
    share = sys.argv[1]
    packages = sys.argv[2:]
    out = {}
    for pkg in packages:
        for kind in ("msg", "action"):
            folder = os.path.join(share, pkg, kind)
            if not os.path.isdir(folder):
                continue
            module = importlib.import_module(f"{pkg}.{kind}")
            for file in sorted(os.listdir(folder)):
                if not file.endswith("." + kind):
                    continue
                name = file[: -len(kind) - 1]
                t = getattr(module, name)
                key = f"{pkg}/{kind}/{name}"
                if kind == "msg":
                    out[key] = t.get_fields_and_field_types()
                else:
                    out[key] = [
                        t.Goal.get_fields_and_field_types(),
                        t.Result.get_fields_and_field_types(),
                        t.Feedback.get_fields_and_field_types(),
                    ]
    print(json.dumps(out))


main()
