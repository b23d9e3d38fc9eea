//! The built page (written by `build.rs` into `OUT_DIR`), looked up by file name.

include!(concat!(env!("OUT_DIR"), "/assets.rs"));

/// A file of the page.
pub(crate) struct Asset {
    /// Its bytes.
    pub(crate) bytes: &'static [u8],
    /// The same, gzipped.
    pub(crate) gzipped: &'static [u8],
    /// Its entity tag (quoted).
    pub(crate) tag: &'static str,
    /// Its media type.
    pub(crate) kind: &'static str,
}

/// The file `name` of the page.
pub(crate) fn get(name: &str) -> Option<Asset> {
    let &(_, bytes, gzipped, tag) = FILES.iter().find(|(n, ..)| *n == name)?;
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
    Some(Asset {
        bytes,
        gzipped,
        tag,
        kind,
    })
}
