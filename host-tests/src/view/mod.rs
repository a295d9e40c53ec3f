//! `guide-sim view`: a live web page of what the mount learns, read from
//! the telemetry of its command port (a board's serial port, or the
//! virtual mount's pty or TCP port).
//!
//! - [`link`]: the byte link (serial set raw 9600 8N1, pty, TCP);
//! - [`stream`]: the port's bytes split into replies and telemetry lines;
//! - [`telemetry`]: a telemetry line read into numbers;
//! - [`client`]: identity and version checks, telemetry on, counters;
//! - [`session`]: what was heard, bounded, and the CSV of it;
//! - [`analysis`]: the spectrum and the stage fit of the gear error;
//! - [`state`]: all of it as the page's JSON;
//! - [`http`]: the local server of the page (`page/`, built in), for
//!   requests that name it, a bounded number at a time.

pub mod analysis;
pub mod client;
pub mod http;
pub mod link;
pub mod session;
pub mod state;
pub mod stream;
pub mod telemetry;

use link::Target;
use session::Session;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr, TcpListener};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

/// Connects to `target` and serves the page on `listen` until `stop`;
/// `ready` is called once with the page's URL.
pub fn run(
    target: Target,
    listen: &str,
    stop: &'static AtomicBool,
    ready: impl FnOnce(&str),
) -> std::io::Result<()> {
    let listener = TcpListener::bind(listen)?;
    let at = listener.local_addr()?;
    if !at.ip().to_canonical().is_loopback() {
        eprintln!(
            "guide-sim view: warning: listening on {at}, not only on this machine: \
             whoever can reach it can read the session (read-only, nothing reaches the mount)"
        );
    }
    // Every interface: the URL to open here is this machine's own address
    // (the server answers only to the address a client reached).
    let url_at: SocketAddr = match at.ip() {
        IpAddr::V4(ip) if ip.is_unspecified() => (Ipv4Addr::LOCALHOST, at.port()).into(),
        IpAddr::V6(ip) if ip.is_unspecified() => (Ipv6Addr::LOCALHOST, at.port()).into(),
        _ => at,
    };
    let session = Arc::new(Mutex::new(Session::new(target.to_string())));
    let port_session = Arc::clone(&session);
    let port = std::thread::spawn(move || client::run(&target, &port_session, stop));
    ready(&format!(
        "guide-sim view: serving http://{url_at}/ for {}",
        session.lock().unwrap().target
    ));
    let served = http::run(listener, session, stop);
    let _ = port.join();
    served
}
