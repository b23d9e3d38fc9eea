//! The built page (written by `build.rs` into `OUT_DIR`), looked up by file name.

include!(concat!(env!("OUT_DIR"), "/assets.rs"));

/// The file `name` of the page and its media type.
pub(crate) fn get(name: &str) -> Option<(&'static [u8], &'static str)> {
    let bytes = FILES.iter().find(|(n, _)| *n == name)?.1;
    let kind = match name.rsplit('.').next() {
        Some("html") => "text/html; charset=utf-8",
        Some("js") => "text/javascript; charset=utf-8",
        Some("css") => "text/css; charset=utf-8",
        Some("woff2") => "font/woff2",
        Some("woff") => "font/woff",
        Some("ttf") => "font/ttf",
        Some("svg") => "image/svg+xml",
        Some("eot") => "application/vnd.ms-fontobject",
        _ => "application/octet-stream",
    };
    Some((bytes, kind))
}
