//! A small HTTP/1.1 server for the page: GET only, `Connection: close`, a
//! thread per connection and at most [`MAX_CONNECTIONS`] of them. It
//! serves the page's three files from the binary, the state as JSON and
//! the session as CSV; nothing else, nothing from outside, and only to
//! requests that name it ([`request::read`]).

pub mod request;

use super::session::Session;
use super::state;
use std::collections::VecDeque;
use std::io::Write;
use std::net::{Shutdown, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

const INDEX: &str = include_str!("page/index.html");
const SCRIPT: &str = include_str!("page/view.js");
const STYLE: &str = include_str!("page/view.css");

/// Connections served at once. A browser opens a few per server (the page
/// fetches one thing a second); slow clients beyond this cannot take more
/// threads.
pub const MAX_CONNECTIONS: usize = 16;

/// The time a client has to send its whole request head. A browser sends
/// it at once; a client that dribbles it is cut off here (408).
pub const HEAD_DEADLINE: Duration = Duration::from_secs(2);

/// The time one write of a response may wait for a client that does not
/// read.
const WRITE_TIMEOUT: Duration = Duration::from_secs(5);

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
    let _ = s.set_write_timeout(Some(WRITE_TIMEOUT));
    let req = match request::read(&s, Instant::now() + HEAD_DEADLINE) {
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

/// A connection being served: a handle on its socket, to cut it short, and
/// its thread.
struct Served {
    socket: TcpStream,
    thread: JoinHandle<()>,
}

/// The connections being served, oldest first.
#[derive(Default)]
struct Connections(VecDeque<Served>);

impl Connections {
    /// Joins the threads that are done (gone, not merely finishing).
    fn reap(&mut self) {
        while let Some(i) = self.0.iter().position(|c| c.thread.is_finished()) {
            if let Some(c) = self.0.remove(i) {
                let _ = c.thread.join();
            }
        }
    }

    /// Makes room for one more: when all are taken, the oldest is cut
    /// short (its read or write fails at once) and its thread joined. The
    /// oldest is the one least likely to be a browser, which sends its
    /// request at once and reads the answer as it comes; refusing the
    /// newest instead would let slow clients keep the page from loading.
    fn make_room(&mut self) {
        self.reap();
        if self.0.len() >= MAX_CONNECTIONS {
            if let Some(oldest) = self.0.pop_front() {
                let _ = oldest.socket.shutdown(Shutdown::Both);
                let _ = oldest.thread.join();
            }
        }
    }

    /// Serves `s` on a thread of its own (dropped if there is none).
    fn spawn(&mut self, s: TcpStream, session: &Arc<Mutex<Session>>) {
        let Ok(socket) = s.try_clone() else { return };
        let session = Arc::clone(session);
        if let Ok(thread) = std::thread::Builder::new().spawn(move || serve(s, &session)) {
            self.0.push_back(Served { socket, thread });
        }
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
    let mut served = Connections::default();
    while !stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((s, _)) => {
                s.set_nonblocking(false)?;
                served.make_room();
                served.spawn(s, &session);
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                served.reap();
                std::thread::sleep(Duration::from_millis(20))
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            // Too many open files and the like: wait, do not die.
            Err(_) => std::thread::sleep(Duration::from_millis(200)),
        }
    }
    Ok(())
}
