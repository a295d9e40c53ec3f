//! Clients of the mount's command port: INDI's own LX200 driver
//! (`indi_lx200generic`, Debian's indi-bin) run headless, as
//! docs/reference.md section 5 describes (`indiserver` with its own `-u`
//! socket, port and a temporary HOME, driven with `indi_setprop`,
//! `indi_getprop` and `indi_eval`), and our own `:~` queries on a link of
//! their own (a pty or TCP). Shared by the INDI tests of `guide-sim mount`
//! (tests/indi.rs) and of the binary in QEMU (tests/board.rs). Every
//! external command has a timeout; the server's whole process group, its
//! driver included, is killed on drop.

use super::process::Group;
use std::fs::{File, OpenOptions};
use std::io::{ErrorKind, Read, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

pub const DEVICE: &str = "Standard LX200";

/// Runs `cmd` to its end within `limit`: its stdout, or why it failed.
pub fn try_run(cmd: &mut Command, limit: Duration) -> Result<String, String> {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("{cmd:?}: {e}"))?;
    let deadline = Instant::now() + limit;
    while child.try_wait().map_err(|e| e.to_string())?.is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("{cmd:?} took longer than {limit:?}"));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let mut out = String::new();
    let mut err = String::new();
    let _ = child.stdout.take().unwrap().read_to_string(&mut out);
    let _ = child.stderr.take().unwrap().read_to_string(&mut err);
    let status = child.wait().map_err(|e| e.to_string())?;
    if status.success() {
        Ok(out)
    } else {
        Err(format!("{cmd:?}: {status} {err}"))
    }
}

fn run(cmd: &mut Command, limit: Duration) -> String {
    try_run(cmd, limit).unwrap_or_else(|e| panic!("{e}"))
}

fn have(cmd: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(cmd).is_file()))
}

/// Whether indiserver and the driver are installed. Without them the test
/// is skipped with a message, except under CI=true, where it fails.
pub fn available() -> bool {
    if have("indiserver") && have("indi_lx200generic") {
        return true;
    }
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("indiserver or indi_lx200generic missing under CI (.ci/run installs indi-bin)");
    }
    eprintln!(
        "SKIPPED: indiserver not found (apt-get install indi-bin); the INDI test did not run"
    );
    false
}

fn free_port() -> u16 {
    std::net::TcpListener::bind(("127.0.0.1", 0))
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// indiserver running indi_lx200generic.
pub struct Indi {
    port: u16,
    _server: Group,
}

impl Indi {
    /// Starts the server (its HOME under `dir`) and waits, at most 15 s,
    /// for the driver's properties.
    pub fn start(dir: &Path) -> Indi {
        std::fs::create_dir_all(dir.join("home")).unwrap();
        let port = free_port();
        let server = Group(
            Command::new("indiserver")
                .args(["-p", &port.to_string(), "-u"])
                .arg(dir.join("sock"))
                .arg("indi_lx200generic")
                .env("HOME", dir.join("home"))
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .process_group(0)
                .spawn()
                .expect("indiserver runs"),
        );
        let indi = Indi {
            port,
            _server: server,
        };
        let start = Instant::now();
        while try_run(
            &mut indi.prop_command("indi_getprop", "DEVICE_PORT.PORT", 1),
            Duration::from_secs(5),
        )
        .is_err()
        {
            assert!(
                start.elapsed() < Duration::from_secs(15),
                "the driver never came up"
            );
            std::thread::sleep(Duration::from_millis(200));
        }
        indi
    }

    /// Connects the driver to the serial port at `path`: how long the
    /// driver took (its queries and the mount's replies).
    pub fn connect(&self, path: &Path) -> Duration {
        self.set("DEVICE_AUTO_SEARCH.INDI_ENABLED=Off;INDI_DISABLED=On");
        self.set(&format!("DEVICE_PORT.PORT={}", path.display()));
        let t0 = Instant::now();
        self.set("CONNECTION.CONNECT=On");
        self.wait(&format!("\"{DEVICE}.CONNECTION.CONNECT\"==1"), 10);
        t0.elapsed()
    }

    /// `tool` (indi_setprop or indi_getprop) on this server for `prop` of
    /// the device, waiting at most `wait_s`.
    fn prop_command(&self, tool: &str, prop: &str, wait_s: u32) -> Command {
        let mut c = Command::new(tool);
        c.args([
            "-p",
            &self.port.to_string(),
            "-t",
            &wait_s.to_string(),
            &format!("{DEVICE}.{prop}"),
        ]);
        c
    }

    pub fn set(&self, prop: &str) {
        run(
            &mut self.prop_command("indi_setprop", prop, 3),
            Duration::from_secs(10),
        );
    }

    pub fn get(&self, prop: &str) -> f64 {
        let out = run(
            &mut self.prop_command("indi_getprop", prop, 3),
            Duration::from_secs(10),
        );
        out.trim()
            .rsplit_once('=')
            .and_then(|(_, v)| v.parse().ok())
            .unwrap_or_else(|| panic!("{prop}: {out:?}"))
    }

    /// Waits (at most `limit_s`) until `expr` holds.
    pub fn wait(&self, expr: &str, limit_s: u32) {
        run(
            Command::new("indi_eval").args([
                "-p",
                &self.port.to_string(),
                "-t",
                &limit_s.to_string(),
                "-w",
                expr,
            ]),
            Duration::from_secs(u64::from(limit_s) + 5),
        );
    }

    /// Syncs the mount to `ra_h` hours, `dec_deg` degrees through the
    /// driver; what the driver shows after two of its 1 s polls.
    pub fn sync(&self, ra_h: f64, dec_deg: f64) -> (f64, f64) {
        self.set("ON_COORD_SET.TRACK=Off;SLEW=Off;SYNC=On");
        self.set(&format!("EQUATORIAL_EOD_COORD.RA={ra_h};DEC={dec_deg}"));
        std::thread::sleep(Duration::from_millis(1_500));
        self.coords()
    }

    /// RA (hours) and Dec (degrees) as the driver shows them.
    pub fn coords(&self) -> (f64, f64) {
        (
            self.get("EQUATORIAL_EOD_COORD.RA"),
            self.get("EQUATORIAL_EOD_COORD.DEC"),
        )
    }
}

/// The client's end of a pty, as a serial program opens it (non-blocking).
pub fn open_pty(path: &Path) -> File {
    OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(libc::O_NOCTTY | libc::O_NONBLOCK)
        .open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The step counters and the firmware's clock, as `:~P#` gives them.
#[derive(Clone, Copy, Debug)]
pub struct Steps {
    pub ra: i64,
    pub dec: i64,
    /// s since the firmware started.
    pub t_s: f64,
}

/// Our own queries on a link of their own (a TCP connection, a pty).
pub struct Own<S> {
    link: S,
    /// How long a reply may take.
    patience: Duration,
}

impl<S: Read + Write> Own<S> {
    /// Replies within 5 s.
    pub fn new(link: S) -> Self {
        Own {
            link,
            patience: Duration::from_secs(5),
        }
    }

    /// Sends `cmd` and reads its reply, up to its `#`.
    pub fn ask(&mut self, cmd: &str) -> String {
        self.link.write_all(cmd.as_bytes()).unwrap();
        let deadline = Instant::now() + self.patience;
        let mut got = Vec::new();
        let mut b = [0u8; 1];
        while got.last() != Some(&b'#') {
            assert!(Instant::now() < deadline, "{cmd}: no reply, got {got:?}");
            match self.link.read(&mut b) {
                Ok(0) => panic!("{cmd}: the link closed"),
                Ok(_) => got.push(b[0]),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    std::thread::sleep(Duration::from_millis(2))
                }
                Err(e) => panic!("{cmd}: {e}"),
            }
        }
        String::from_utf8(got).unwrap()
    }

    pub fn steps(&mut self) -> Steps {
        let r = self.ask(":~P#");
        Steps {
            ra: field(&r, "ra_steps"),
            dec: field(&r, "dec_steps"),
            t_s: field(&r, "t_ms") as f64 * 1e-3,
        }
    }

    /// The first counts at or after the firmware's time `t_s`, asked every
    /// `poll` of wall clock.
    pub fn steps_at(&mut self, t_s: f64, poll: Duration) -> Steps {
        loop {
            let s = self.steps();
            if s.t_s >= t_s {
                return s;
            }
            std::thread::sleep(poll);
        }
    }
}

/// The number `key=` gives in a `key=value ...#` reply.
pub fn field(reply: &str, key: &str) -> i64 {
    reply
        .trim_end_matches('#')
        .split(' ')
        .find_map(|f| f.strip_prefix(key)?.strip_prefix('='))
        .unwrap_or_else(|| panic!("{key} in {reply:?}"))
        .parse()
        .unwrap()
}
