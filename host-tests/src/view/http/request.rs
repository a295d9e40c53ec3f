//! A request's head, read against one deadline, and whether it is meant
//! for this server.

use std::io::{self, BufRead, BufReader, ErrorKind, Read};
use std::net::{IpAddr, SocketAddr, TcpStream};
use std::time::Instant;

/// A request line and headers longer than this are refused.
const MAX_HEAD: u64 = 8192;

/// What the server reads of a request (it serves no body).
pub struct Request {
    pub method: String,
    pub path: String,
    /// `HTTP/1.0`, `HTTP/1.1`, ...
    pub version: String,
    /// The value of each `Host` header.
    pub hosts: Vec<String>,
}

/// A request refused: its status line's status and a body saying why.
pub type Refusal = (&'static str, String);

/// Reads a request head from `s`, all of it before `deadline`, and
/// refuses it unless it is meant for this server ([`Request::check_host`]).
pub fn read(s: &TcpStream, deadline: Instant) -> Result<Request, Refusal> {
    let bad = || ("400 Bad Request", "bad request\n".to_string());
    let local = s.local_addr().map_err(|_| bad())?;
    let mut r = BufReader::new(Until { s, deadline }.take(MAX_HEAD));
    let mut line = String::new();
    let mut next = |line: &mut String| -> Result<(), Refusal> {
        line.clear();
        match r.read_line(line) {
            // The head ends with an empty line, not with the connection.
            Ok(0) => Err(bad()),
            Ok(_) => Ok(()),
            Err(e) if e.kind() == ErrorKind::TimedOut => Err((
                "408 Request Timeout",
                "the request did not come in time\n".to_string(),
            )),
            Err(_) => Err(bad()),
        }
    };
    next(&mut line)?;
    let mut it = line.split_whitespace();
    let (Some(method), Some(path), Some(version)) = (it.next(), it.next(), it.next()) else {
        return Err(bad());
    };
    let mut req = Request {
        method: method.to_string(),
        path: path.to_string(),
        version: version.to_string(),
        hosts: Vec::new(),
    };
    loop {
        next(&mut line)?;
        let header = line.trim_end_matches(['\r', '\n']);
        if header.is_empty() {
            return req.check_host(local).map(|()| req);
        }
        if let Some((name, value)) = header.split_once(':') {
            if name.eq_ignore_ascii_case("host") {
                req.hosts.push(value.trim().to_string());
            }
        }
    }
}

impl Request {
    /// Refuses a request not meant for this server as its client reached
    /// it (`local`): `Host` must name that address or localhost, with its
    /// port. A browser sends the name it looked up, so a page of another
    /// site whose name was made to resolve here (DNS rebinding) is refused.
    /// HTTP/1.1 requires `Host`; an HTTP/1.0 request without one is served,
    /// since no browser sends one.
    pub fn check_host(&self, local: SocketAddr) -> Result<(), Refusal> {
        match &self.hosts[..] {
            [] if self.version == "HTTP/1.0" => Ok(()),
            [host] if names(host, local) => Ok(()),
            [_] => Err((
                "421 Misdirected Request",
                format!(
                    "this page is served as http://{local}/ or http://localhost:{}/ only\n",
                    local.port()
                ),
            )),
            _ => Err(("400 Bad Request", "more than one Host header\n".to_string())),
        }
    }
}

/// Whether a `Host` value names `local` or localhost, with `local`'s port.
fn names(host: &str, local: SocketAddr) -> bool {
    // The port follows the last colon, unless that is inside an IPv6
    // literal's brackets; without one it is HTTP's 80.
    let (name, port) = match host.rsplit_once(':') {
        Some((name, port)) if !port.contains(']') => (name, port.parse().ok()),
        _ => (host, Some(80)),
    };
    let ip = name
        .trim_start_matches('[')
        .trim_end_matches(']')
        .parse::<IpAddr>();
    port == Some(local.port())
        && (name.eq_ignore_ascii_case("localhost")
            || ip.is_ok_and(|ip| ip.to_canonical() == local.ip().to_canonical()))
}

/// `s` read against one deadline for the whole head: a timeout per read
/// would let a client that sends a byte now and then keep its connection,
/// and a thread, for ever.
struct Until<'a> {
    s: &'a TcpStream,
    deadline: Instant,
}

impl Read for Until<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let left = self.deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(ErrorKind::TimedOut.into());
        }
        self.s.set_read_timeout(Some(left))?;
        match self.s.read(buf) {
            Err(e) if e.kind() == ErrorKind::WouldBlock => Err(ErrorKind::TimedOut.into()),
            r => r,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::names;

    #[test]
    fn a_host_names_the_address_or_localhost_with_the_port() {
        let v4 = "127.0.0.1:8080".parse().unwrap();
        let v6 = "[::1]:8080".parse().unwrap();
        let web = "127.0.0.1:80".parse().unwrap();
        for (host, local, ok) in [
            ("127.0.0.1:8080", v4, true),
            ("localhost:8080", v4, true),
            ("LOCALHOST:8080", v4, true),
            ("127.0.0.1:8081", v4, false),
            ("127.0.0.1", v4, false),
            ("127.0.0.1:", v4, false),
            ("evil.example:8080", v4, false),
            ("127.0.0.1.evil.example:8080", v4, false),
            ("", v4, false),
            ("[::1]:8080", v6, true),
            ("[0:0:0:0:0:0:0:1]:8080", v6, true),
            ("[::1]", v6, false),
            ("localhost:8080", v6, true),
            ("127.0.0.1", web, true),
            ("localhost", web, true),
            ("[::ffff:127.0.0.1]:8080", v4, true),
        ] {
            assert_eq!(names(host, local), ok, "{host:?} for {local}");
        }
    }
}
