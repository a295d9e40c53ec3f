//! A small HTTP/1.1 server for the page: GET only, one thread per
//! connection, `Connection: close`. It serves the page's three files from
//! the binary, the state as JSON and the session as CSV; nothing else,
//! nothing from outside, and only to requests that name it
//! ([`request::read`]).

pub mod request;

use super::session::Session;
use super::state;
use std::io::Write;
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

const INDEX: &str = include_str!("page/index.html");
const SCRIPT: &str = include_str!("page/view.js");
const STYLE: &str = include_str!("page/view.css");

fn respond(s: &mut TcpStream, status: &str, kind: &str, extra: &str, body: &[u8]) {
    let head = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nConnection: close\r\n{extra}\r\n",
        body.len()
    );
    // A browser that went away is no error of ours.
    let _ = s.write_all(head.as_bytes()).and_then(|_| s.write_all(body));
}

fn serve(mut s: TcpStream, session: &Mutex<Session>) {
    let _ = s.set_read_timeout(Some(Duration::from_secs(5)));
    let _ = s.set_write_timeout(Some(Duration::from_secs(5)));
    let req = match request::read(&s) {
        Ok(r) => r,
        Err((status, why)) => return respond(&mut s, status, "text/plain", "", why.as_bytes()),
    };
    if req.method != "GET" {
        return respond(
            &mut s,
            "405 Method Not Allowed",
            "text/plain",
            "Allow: GET\r\n",
            b"GET only\n",
        );
    }
    let path = req.path.split('?').next().unwrap_or("");
    match path {
        "/" | "/index.html" => respond(
            &mut s,
            "200 OK",
            "text/html; charset=utf-8",
            "",
            INDEX.as_bytes(),
        ),
        "/view.js" => respond(
            &mut s,
            "200 OK",
            "text/javascript; charset=utf-8",
            "",
            SCRIPT.as_bytes(),
        ),
        "/view.css" => respond(
            &mut s,
            "200 OK",
            "text/css; charset=utf-8",
            "",
            STYLE.as_bytes(),
        ),
        "/state" => {
            let body = state::json(&session.lock().unwrap());
            respond(&mut s, "200 OK", "application/json", "", body.as_bytes())
        }
        "/session.csv" => {
            let body = session.lock().unwrap().csv();
            respond(
                &mut s,
                "200 OK",
                "text/csv",
                "Content-Disposition: attachment; filename=\"mkgp-session.csv\"\r\n",
                body.as_bytes(),
            )
        }
        _ => respond(&mut s, "404 Not Found", "text/plain", "", b"not found\n"),
    }
}

/// Serves until `stop` (checked between connections, at least every
/// 200 ms).
pub fn run(
    listener: TcpListener,
    session: Arc<Mutex<Session>>,
    stop: &AtomicBool,
) -> std::io::Result<()> {
    listener.set_nonblocking(true)?;
    while !stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((s, _)) => {
                s.set_nonblocking(false)?;
                let session = Arc::clone(&session);
                std::thread::spawn(move || serve(s, &session));
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(20))
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            // Too many open files and the like: wait, do not die.
            Err(_) => std::thread::sleep(Duration::from_millis(200)),
        }
    }
    Ok(())
}
