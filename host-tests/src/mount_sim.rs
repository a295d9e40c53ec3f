//! `guide-sim mount`: the firmware's loop on a virtual mount, in real time,
//! with its command port served on a pseudo-terminal (and/or a TCP port on
//! 127.0.0.1) for real LX200 clients: INDI's `indi_lx200generic`, KStars,
//! PHD2 through INDI.
//!
//! The mount is `st4_sim`'s [`Rig`] (the same `ControlLoop`, `Learner<FIRMWARE_STAGES>`
//! and step generators as `guide-sim st4`). Its own simulated camera and
//! PHD2-like guider pulse the ST4 input unless [`Options::st4_guider`] is
//! off, so that the mount learns with no client guiding (a demo for
//! `guide-sim view`); off, only the port's client guides (the tests that
//! measure a client's pulses exactly). Simulated time runs
//! [`Options::speed`] times real time. Each transport has its own
//! `Interpreter` (precision, selected rate, site and telemetry are a
//! port's own, as on the board); the sync is the mount's, shared. Replies
//! leave through a pipe of the board's size, whole or not at all: a client
//! that stops reading loses replies (counted in that port's
//! `replies_dropped`), it does not stop the mount.
//!
//! The pty's slave side is kept open here and set raw: with no client on it
//! the master would read end-of-file, and with the terminal's default echo
//! every reply would come back to us as input.

use crate::cases::Case;
use crate::st4_sim::{Firmware, Rig};
use mkgp_mount::control_loop::port_mount::PortState;
use mkgp_mount::port::mount_port::Identity;
use mkgp_mount::port::{Interpreter, ReplySink};
use mkgp_mount::safety::reset_cause::ResetCause;
use std::fs::File;
use std::io::{self, ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The longest the loop sleeps waiting for bytes, ms: the simulation runs
/// at least this often, and a command waits at most this long.
const POLL_MS: i32 = 2;

/// What `guide-sim mount` serves.
pub struct Options {
    pub case: Case,
    pub noise_px: f64,
    /// Where to link the pty's slave.
    pub pty: Option<PathBuf>,
    /// A TCP port on 127.0.0.1.
    pub tcp: Option<u16>,
    /// Simulated time per real time (1: real time).
    pub speed: f64,
    /// The rig's own camera and guider pulse the ST4 input.
    pub st4_guider: bool,
}

/// The identity the virtual mount reports: the library's, marked simulated.
pub const IDENTITY: Identity = Identity {
    product: "mkgp-mount-sim",
    version: env!("CARGO_PKG_VERSION"),
    date: "Nov 23 2026",
    time: "00:00:00",
};

/// A pseudo-terminal: the master we serve, the slave kept open, the link.
pub struct Pty {
    master: File,
    _slave: OwnedFd,
    link: PathBuf,
    slave_path: PathBuf,
}

impl Pty {
    /// Opens a pty, sets it raw and links its slave at `link` (replacing a
    /// symlink there, never another file).
    pub fn open(link: &Path) -> io::Result<Pty> {
        let (mut master, mut slave) = (-1, -1);
        // SAFETY: openpty writes two descriptors; name, termios and
        // winsize may be null.
        let r = unsafe {
            libc::openpty(
                &mut master,
                &mut slave,
                std::ptr::null_mut(),
                std::ptr::null(),
                std::ptr::null(),
            )
        };
        if r != 0 {
            return Err(io::Error::last_os_error());
        }
        // SAFETY: both descriptors were just opened and are ours alone.
        let (master, slave) = unsafe { (File::from_raw_fd(master), OwnedFd::from_raw_fd(slave)) };
        // SAFETY: termios is plain data, filled by tcgetattr before use.
        unsafe {
            let mut t: libc::termios = std::mem::zeroed();
            if libc::tcgetattr(slave.as_raw_fd(), &mut t) != 0 {
                return Err(io::Error::last_os_error());
            }
            libc::cfmakeraw(&mut t);
            if libc::tcsetattr(slave.as_raw_fd(), libc::TCSANOW, &t) != 0 {
                return Err(io::Error::last_os_error());
            }
            let flags = libc::fcntl(master.as_raw_fd(), libc::F_GETFL);
            libc::fcntl(master.as_raw_fd(), libc::F_SETFL, flags | libc::O_NONBLOCK);
        }
        let slave_path = std::fs::read_link(format!("/proc/self/fd/{}", slave.as_raw_fd()))?;
        if let Ok(m) = std::fs::symlink_metadata(link) {
            if !m.file_type().is_symlink() {
                return Err(io::Error::new(
                    ErrorKind::AlreadyExists,
                    format!("{} exists and is no symlink", link.display()),
                ));
            }
            std::fs::remove_file(link)?;
        }
        std::os::unix::fs::symlink(&slave_path, link)?;
        Ok(Pty {
            master,
            _slave: slave,
            link: link.to_path_buf(),
            slave_path,
        })
    }
}

impl Drop for Pty {
    fn drop(&mut self) {
        // Only our own link: it may have been replaced meanwhile.
        if std::fs::read_link(&self.link).is_ok_and(|p| p == self.slave_path) {
            let _ = std::fs::remove_file(&self.link);
        }
    }
}

/// The bytes of replies waiting for the transport, at most: the board's
/// transmit pipe per port (docs/port.md).
const TX_PIPE: usize = 512;

/// The replies a port's transport has not taken yet.
#[derive(Default)]
struct TxPipe(Vec<u8>);

impl TxPipe {
    /// Writes what the transport takes now; the rest waits for the next
    /// call. An error is the client gone, not a full transport.
    fn flush(&mut self, w: &mut impl Write) -> io::Result<()> {
        while !self.0.is_empty() {
            match w.write(&self.0) {
                Ok(0) => return Err(ErrorKind::WriteZero.into()),
                Ok(n) => drop(self.0.drain(..n)),
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}

/// A pipe and its transport, where the interpreter sends, as on the
/// board: a reply goes out whole or not at all (the interpreter counts it
/// in `replies_dropped`), so a client that stops reading loses replies,
/// never the mount. What the transport takes goes at once; the pipe holds
/// only the rest. Errors wait for [`TxPipe::flush`] after the feed.
struct Sending<'a, W> {
    tx: &'a mut TxPipe,
    w: &'a mut W,
}

impl<W: Write> ReplySink for Sending<'_, W> {
    fn send(&mut self, reply: &[u8]) -> bool {
        let _ = self.tx.flush(self.w);
        let fits = self.tx.0.len() + reply.len() <= TX_PIPE;
        if fits {
            self.tx.0.extend_from_slice(reply);
            let _ = self.tx.flush(self.w);
        }
        fits
    }
}

/// One transport's side of the command port: its own interpreter, and the
/// replies the transport has not taken yet.
#[derive(Default)]
struct PortIo {
    port: Interpreter,
    tx: TxPipe,
}

impl PortIo {
    /// The interpreter, and where it sends its replies on `w`.
    fn sending<'a, W>(&'a mut self, w: &'a mut W) -> (&'a mut Interpreter, Sending<'a, W>) {
        (
            &mut self.port,
            Sending {
                tx: &mut self.tx,
                w,
            },
        )
    }
}

/// Reads what is there without blocking: `None` at end of file.
fn read_ready(r: &mut impl Read, buf: &mut [u8]) -> io::Result<Option<usize>> {
    match r.read(buf) {
        Ok(0) => Ok(None),
        Ok(n) => Ok(Some(n)),
        Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::Interrupted) => Ok(Some(0)),
        Err(e) => Err(e),
    }
}

/// One transport's bytes through its interpreter on the rig; the replies
/// sent back on `w`.
fn serve_bytes(
    rig: &mut Rig,
    io: &mut PortIo,
    w: &mut impl Write,
    state: &mut PortState,
    bytes: &[u8],
) {
    let (port, mut out) = io.sending(w);
    rig.feed_port(port, state, bytes, &mut out);
    // The motion a command started is set at the loop's next wake-up, a
    // microsecond on, as the board's guiding task would.
    let now = rig.now_us;
    rig.run_until(now + 1);
}

/// Runs the mount until `stop` is set; `ready` is called once with a line
/// saying where it listens.
pub fn serve(opts: Options, stop: &AtomicBool, ready: impl FnOnce(&str)) -> io::Result<()> {
    let mut rig = Rig::new(&opts.case, Firmware::Mkgp, opts.noise_px, 1);
    rig.guider_on = opts.st4_guider;
    let mut state = PortState::new(&rig.mount, IDENTITY, ResetCause::PowerOn);
    let mut pty = match &opts.pty {
        Some(link) => Some((Pty::open(link)?, PortIo::default())),
        None => None,
    };
    let listener = match opts.tcp {
        Some(p) => {
            let l = TcpListener::bind(("127.0.0.1", p))?;
            l.set_nonblocking(true)?;
            Some(l)
        }
        None => None,
    };
    let mut client: Option<(TcpStream, PortIo)> = None;
    let mut where_ = Vec::new();
    if let Some((p, _)) = &pty {
        where_.push(format!(
            "pty {} -> {}",
            p.link.display(),
            p.slave_path.display()
        ));
    }
    if let Some(l) = &listener {
        where_.push(format!("tcp {}", l.local_addr()?));
    }
    ready(&format!(
        "guide-sim mount: ready on {}, case {}, noise {} px, speed {}, st4 guider {}",
        where_.join(", "),
        opts.case.name,
        opts.noise_px,
        opts.speed,
        if opts.st4_guider { "on" } else { "off" }
    ));

    let start = Instant::now();
    let mut buf = [0u8; 4096];
    while !stop.load(Ordering::SeqCst) {
        let mut fds = Vec::new();
        if let Some((p, _)) = &pty {
            fds.push(p.master.as_raw_fd());
        }
        if let Some(l) = &listener {
            fds.push(l.as_raw_fd());
        }
        if let Some((c, _)) = &client {
            fds.push(c.as_raw_fd());
        }
        let mut pfds: Vec<libc::pollfd> = fds
            .iter()
            .map(|&fd| libc::pollfd {
                fd,
                events: libc::POLLIN,
                revents: 0,
            })
            .collect();
        // SAFETY: pfds is a live array of pfds.len() pollfd. A signal ends
        // the wait early (EINTR), which the loop's check handles.
        unsafe { libc::poll(pfds.as_mut_ptr(), pfds.len() as libc::nfds_t, POLL_MS) };
        let now_us = (start.elapsed().as_secs_f64() * opts.speed * 1e6) as u64;
        rig.run_until(now_us.max(rig.now_us));

        if let Some((p, io)) = &mut pty {
            // EIO: no client has the slave open (cannot happen while we
            // hold it; harmless if it does).
            if let Ok(Some(n)) = read_ready(&mut p.master, &mut buf) {
                if n > 0 {
                    serve_bytes(&mut rig, io, &mut p.master, &mut state, &buf[..n]);
                }
            }
        }
        if let Some(l) = &listener {
            if let Ok((s, _)) = l.accept() {
                // One client at a time: a new one replaces the old.
                s.set_nonblocking(true)?;
                s.set_nodelay(true)?;
                client = Some((s, PortIo::default()));
            }
        }
        if let Some((s, io)) = &mut client {
            match read_ready(s, &mut buf) {
                Ok(Some(0)) => {}
                Ok(Some(n)) => serve_bytes(&mut rig, io, s, &mut state, &buf[..n]),
                Ok(None) | Err(_) => client = None,
            }
        }
        if let Some(learned) = rig.take_learned() {
            let line = learned.telemetry(rig.now_us);
            if let Some((p, io)) = &mut pty {
                let (port, mut out) = io.sending(&mut p.master);
                port.send_telemetry(&line, &mut out);
            }
            if let Some((s, io)) = &mut client {
                let (port, mut out) = io.sending(s);
                port.send_telemetry(&line, &mut out);
            }
        }
        // Whatever the clients read meanwhile makes room for the rest.
        if let Some((p, io)) = &mut pty {
            let _ = io.tx.flush(&mut p.master);
        }
        if let Some((s, io)) = &mut client {
            if io.tx.flush(s).is_err() {
                client = None;
            }
        }
        if state.take_reset_request() {
            rig.reset_model();
        }
    }
    Ok(())
}
