//! `http-get URL`: one HTTP/1.1 GET of a plain `http://host:port/path` URL; prints the body and
//! exits 0 on a 2xx status, else prints the status line and body to stderr and exits 1. For
//! tests that ask a server inside a network namespace (`ip netns exec NS http-get …`), where
//! the test process itself cannot connect.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::ExitCode;
use std::time::Duration;

fn main() -> ExitCode {
    let Some(url) = std::env::args().nth(1) else {
        eprintln!("usage: http-get http://HOST:PORT/PATH");
        return ExitCode::from(2);
    };
    let Some(rest) = url.strip_prefix("http://") else {
        eprintln!("{url}: only http:// URLs");
        return ExitCode::from(2);
    };
    let (host, path) = rest
        .split_once('/')
        .map_or((rest, "/".to_owned()), |(h, p)| (h, format!("/{p}")));
    let mut stream = match TcpStream::connect(host) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{host}: {e}");
            return ExitCode::FAILURE;
        }
    };
    let _ = stream.set_read_timeout(Some(Duration::from_secs(30)));
    let request = format!("GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n");
    let mut response = Vec::new();
    if let Err(e) = stream
        .write_all(request.as_bytes())
        .and_then(|()| stream.read_to_end(&mut response))
    {
        eprintln!("{url}: {e}");
        return ExitCode::FAILURE;
    }
    let text = String::from_utf8_lossy(&response);
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    let status = head.lines().next().unwrap_or_default();
    if status
        .split_whitespace()
        .nth(1)
        .is_some_and(|s| s.starts_with('2'))
    {
        print!("{body}");
        ExitCode::SUCCESS
    } else {
        eprintln!("{status}\n{body}");
        ExitCode::FAILURE
    }
}
