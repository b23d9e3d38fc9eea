//! Builds the studio's page from the pinned npm packages (`web/package-lock.json`) into
//! `OUT_DIR/dist` — `npm ci` into `OUT_DIR/web` (outside the source tree, only when the lockfile
//! changed), then `web/build.mjs` (esbuild) — and writes `OUT_DIR/assets.rs`, the built files as
//! `include_bytes!`. Nothing third-party is committed. Without Node and npm (or the registry),
//! the page is one of our own that says how to get the real one, and the build warns.

use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    let here = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets it"));
    let web = here.join("web");
    for watched in ["src", "build.mjs", "package.json", "package-lock.json"] {
        println!("cargo:rerun-if-changed={}", web.join(watched).display());
    }
    let dist = out.join("dist");
    let _ = std::fs::remove_dir_all(&dist);
    std::fs::create_dir_all(&dist).expect("OUT_DIR/dist");
    if let Err(why) = build(&web, &out, &dist) {
        println!("cargo:warning=TRACE Studio was built without its page: {why}");
        let _ = std::fs::remove_dir_all(&dist);
        std::fs::create_dir_all(&dist).expect("OUT_DIR/dist");
        std::fs::write(dist.join("index.html"), fallback(&why)).expect("fallback page");
    }
    write_assets(&dist, &out.join("assets.rs"));
    // The installed packages, for tests that run Camunda's template validator on them.
    println!(
        "cargo:rustc-env=TRACE_STUDIO_NODE_MODULES={}",
        out.join("web/node_modules").display()
    );
}

/// `npm ci` (when the lockfile differs from the one installed) and the esbuild script.
fn build(web: &Path, out: &Path, dist: &Path) -> Result<(), String> {
    let modules = out.join("web");
    let lock = std::fs::read(web.join("package-lock.json")).map_err(|e| e.to_string())?;
    let installed = std::fs::read(modules.join("package-lock.json")).ok();
    if installed.as_deref() != Some(&lock[..]) || !modules.join("node_modules").is_dir() {
        std::fs::create_dir_all(&modules).map_err(|e| e.to_string())?;
        std::fs::copy(web.join("package.json"), modules.join("package.json"))
            .map_err(|e| e.to_string())?;
        std::fs::write(modules.join("package-lock.json"), &lock).map_err(|e| e.to_string())?;
        run(
            Command::new("npm")
                .args(["ci", "--no-audit", "--no-fund", "--loglevel=error"])
                .current_dir(&modules),
            "npm ci",
        )?;
    }
    run(
        Command::new("node")
            .arg(web.join("build.mjs"))
            .arg(dist)
            .env("TRACE_NODE_MODULES", modules.join("node_modules")),
        "node build.mjs",
    )
}

fn run(command: &mut Command, what: &str) -> Result<(), String> {
    let output = command
        .output()
        .map_err(|e| format!("{what} could not start ({e}): install Node.js and npm"))?;
    if output.status.success() {
        Ok(())
    } else {
        Err(format!(
            "{what} failed: {}",
            String::from_utf8_lossy(&output.stderr).trim()
        ))
    }
}

fn fallback(why: &str) -> String {
    let why = why.replace('&', "&amp;").replace('<', "&lt;");
    format!(
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>TRACE Studio</title></head>\
         <body data-ready=\"true\" data-fallback=\"true\"><h1>TRACE Studio was built without its page</h1>\
         <p>{why}</p><p>The page is built from npm packages when the <code>executive-studio</code> crate \
         is compiled. On Debian: <code>apt-get install nodejs npm</code>, then build again \
         (<code>cargo build</code>).</p></body></html>"
    )
}

/// `OUT_DIR/assets.rs`: `pub(crate) static FILES: &[(&str, &[u8], &[u8], &str)]`, every file
/// of `dist` with its gzipped bytes (`OUT_DIR/gz/`) and an entity tag of its content.
fn write_assets(dist: &Path, to: &Path) {
    let gz = dist.with_file_name("gz");
    let _ = std::fs::remove_dir_all(&gz);
    std::fs::create_dir_all(&gz).expect("OUT_DIR/gz");
    let mut files: Vec<_> = std::fs::read_dir(dist)
        .expect("dist")
        .filter_map(Result::ok)
        .filter(|e| e.path().is_file())
        .map(|e| e.path())
        .collect();
    files.sort();
    let mut text = String::from(
        "/// Every file of the built page, by name: its bytes, gzipped, and its entity tag.\n\
         pub(crate) static FILES: &[(&str, &[u8], &[u8], &str)] = &[\n",
    );
    for f in files {
        let name = f.file_name().expect("name").to_string_lossy().into_owned();
        let bytes = std::fs::read(&f).expect("a built file");
        let zipped = gz.join(format!("{name}.gz"));
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        std::io::Write::write_all(&mut enc, &bytes).expect("gzip");
        std::fs::write(&zipped, enc.finish().expect("gzip")).expect("gzipped file");
        // FNV-1a of the content: the same tag for the same page.
        let tag = bytes.iter().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
            (h ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3)
        });
        text.push_str(&format!(
            "    ({name:?}, include_bytes!({:?}), include_bytes!({:?}), \"\\\"{tag:016x}\\\"\"),\n",
            f.display().to_string(),
            zipped.display().to_string()
        ));
    }
    text.push_str("];\n");
    std::fs::write(to, text).expect("assets.rs");
}
