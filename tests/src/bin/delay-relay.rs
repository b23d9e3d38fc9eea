//! `delay-relay LISTEN TO DELAY_MS`: a UDP relay that holds every datagram DELAY_MS before
//! passing it on, in both directions — seconds of latency on a link between two test hosts,
//! which the kernel here cannot add (no `netem`). The routers speak QUIC, so the relay is UDP:
//! one client (the router that connects to LISTEN, its latest address) to one server (TO).
//! Prints `ready` once listening; runs until killed.

use std::net::{SocketAddr, UdpSocket};
use std::process::ExitCode;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A datagram and when it may leave.
type Held = (Instant, Vec<u8>);

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [listen, to, delay] = args.as_slice() else {
        eprintln!("usage: delay-relay LISTEN TO DELAY_MS");
        return ExitCode::from(2);
    };
    match run(listen, to, delay) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            println!("error {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(listen: &str, to: &str, delay: &str) -> Result<(), String> {
    let delay = Duration::from_millis(delay.parse().map_err(|e| format!("DELAY_MS: {e}"))?);
    let front = UdpSocket::bind(listen).map_err(|e| format!("listen {listen}: {e}"))?;
    let back = UdpSocket::bind("0.0.0.0:0").map_err(|e| e.to_string())?;
    back.connect(to).map_err(|e| format!("to {to}: {e}"))?;
    let client: Arc<Mutex<Option<SocketAddr>>> = Arc::default();
    let (up_tx, up_rx) = mpsc::channel::<Held>();
    let (down_tx, down_rx) = mpsc::channel::<Held>();
    println!("ready {listen} -> {to}, {} ms each way", delay.as_millis());

    let (front_in, who) = (
        front.try_clone().map_err(|e| e.to_string())?,
        client.clone(),
    );
    std::thread::spawn(move || {
        let mut buf = vec![0u8; 65536];
        while let Ok((n, from)) = front_in.recv_from(&mut buf) {
            *who.lock().unwrap_or_else(|p| p.into_inner()) = Some(from);
            let _ = up_tx.send((Instant::now() + delay, buf[..n].to_vec()));
        }
    });
    let back_in = back.try_clone().map_err(|e| e.to_string())?;
    std::thread::spawn(move || {
        let mut buf = vec![0u8; 65536];
        loop {
            match back_in.recv(&mut buf) {
                Ok(n) => {
                    let _ = down_tx.send((Instant::now() + delay, buf[..n].to_vec()));
                }
                // The server's port closed (a router restarting): keep listening.
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {}
                Err(_) => return,
            }
        }
    });
    std::thread::spawn(move || {
        for (at, bytes) in up_rx {
            hold_until(at);
            let _ = back.send(&bytes);
        }
    });
    for (at, bytes) in down_rx {
        hold_until(at);
        let to = *client.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(to) = to {
            let _ = front.send_to(&bytes, to);
        }
    }
    Ok(())
}

/// The delay itself: what this relay is for.
fn hold_until(at: Instant) {
    let now = Instant::now();
    if at > now {
        std::thread::sleep(at - now);
    }
}
