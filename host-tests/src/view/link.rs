//! The byte link to a command port: a serial device (a board's USB serial
//! or UART, set raw at 9600 8N1), the virtual mount's pty, or its TCP port.
//! All three are file descriptors, read through `poll` so that a quiet
//! port, a port that went away and a closed connection are told apart.

use std::fs::{File, OpenOptions};
use std::io::{self, ErrorKind, Read, Write};
use std::net::TcpStream;
use std::os::fd::AsRawFd;
use std::os::unix::fs::OpenOptionsExt;
use std::path::PathBuf;
use std::time::Duration;

/// Where the command port is.
#[derive(Clone, Debug)]
pub enum Target {
    /// A serial device: set raw, 9600 8N1.
    Serial(PathBuf),
    /// The virtual mount's pty (already raw; set raw again, harmlessly).
    Pty(PathBuf),
    /// HOST:PORT.
    Tcp(String),
}

impl std::fmt::Display for Target {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Target::Serial(p) => write!(f, "serial {}", p.display()),
            Target::Pty(p) => write!(f, "pty {}", p.display()),
            Target::Tcp(a) => write!(f, "tcp {a}"),
        }
    }
}

/// An open link.
pub enum Link {
    Tty(File),
    Tcp(TcpStream),
}

/// Raw mode at 9600 baud, 8 data bits, no parity, one stop bit, no flow
/// control: what the board's UART speaks (its USB serial ignores the rate).
fn set_raw_9600(f: &File) -> io::Result<()> {
    // SAFETY: termios is plain data, filled by tcgetattr before use; the
    // descriptor is open for the call.
    unsafe {
        let mut t: libc::termios = std::mem::zeroed();
        if libc::tcgetattr(f.as_raw_fd(), &mut t) != 0 {
            return Err(io::Error::last_os_error());
        }
        libc::cfmakeraw(&mut t);
        t.c_cflag &= !(libc::PARENB | libc::CSTOPB | libc::CSIZE | libc::CRTSCTS);
        t.c_cflag |= libc::CS8 | libc::CLOCAL | libc::CREAD;
        t.c_iflag &= !(libc::IXON | libc::IXOFF | libc::IXANY);
        libc::cfsetispeed(&mut t, libc::B9600);
        libc::cfsetospeed(&mut t, libc::B9600);
        if libc::tcsetattr(f.as_raw_fd(), libc::TCSANOW, &t) != 0 {
            return Err(io::Error::last_os_error());
        }
    }
    Ok(())
}

impl Link {
    pub fn open(target: &Target) -> io::Result<Link> {
        match target {
            Target::Serial(p) | Target::Pty(p) => {
                let f = OpenOptions::new()
                    .read(true)
                    .write(true)
                    .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
                    .open(p)?;
                set_raw_9600(&f)?;
                Ok(Link::Tty(f))
            }
            Target::Tcp(addr) => {
                let s = TcpStream::connect(addr)?;
                s.set_nonblocking(true)?;
                s.set_nodelay(true)?;
                Ok(Link::Tcp(s))
            }
        }
    }

    fn fd(&self) -> i32 {
        match self {
            Link::Tty(f) => f.as_raw_fd(),
            Link::Tcp(s) => s.as_raw_fd(),
        }
    }

    /// Waits at most `timeout` for bytes: `Ok(0)` if none came, an error
    /// if the port is gone (end of file, hang-up, a read error).
    pub fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let mut p = libc::pollfd {
            fd: self.fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        // SAFETY: one live pollfd.
        let r = unsafe { libc::poll(&mut p, 1, timeout.as_millis().min(60_000) as i32) };
        if r < 0 {
            let e = io::Error::last_os_error();
            return if e.kind() == ErrorKind::Interrupted {
                Ok(0)
            } else {
                Err(e)
            };
        }
        if r == 0 {
            return Ok(0);
        }
        let n = match self {
            Link::Tty(f) => f.read(buf),
            Link::Tcp(s) => s.read(buf),
        };
        match n {
            Ok(0) => Err(io::Error::new(ErrorKind::UnexpectedEof, "the port closed")),
            Ok(n) => Ok(n),
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::Interrupted) => Ok(0),
            Err(e) => Err(e),
        }
    }

    pub fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        // Non-blocking: a full buffer is retried briefly, then the port
        // counts as stuck.
        let mut rest = bytes;
        let mut tries = 0;
        while !rest.is_empty() {
            let r = match self {
                Link::Tty(f) => f.write(rest),
                Link::Tcp(s) => s.write(rest),
            };
            match r {
                Ok(0) => {
                    return Err(io::Error::new(
                        ErrorKind::WriteZero,
                        "the port took nothing",
                    ))
                }
                Ok(n) => rest = &rest[n..],
                Err(e) if e.kind() == ErrorKind::WouldBlock && tries < 100 => {
                    tries += 1;
                    std::thread::sleep(Duration::from_millis(10));
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}
