//! The whole firmware binary, booted in QEMU 10's `b-l475e-iot01a` machine
//! (ST's B-L475E-IOT01A: an STM32L475VG): main.rs, the tasks, executors
//! and priorities, the interrupts, hal and the defmt log as they run on a
//! board. test.sh builds the binary with target-tests/board/build.sh and
//! passes its path in `MKGP_BOARD_ELF`.
//!
//! The test drives and reads the machine through QEMU's qtest protocol
//! while the CPU runs: `set_irq_in` on a GPIO controller's input drives a
//! pin (its EXTI fires), `read` and `writel` reach RAM, where the defmt
//! log's RTT buffer is drained and decoded with the ELF's own table.
//! Emulated time runs slower than the wall clock, and slower still on a
//! loaded host, so every figure compares the firmware's own clock (the
//! log's timestamps) with its own counters, never the wall clock.
//!
//! The command ports are QEMU ptys: port 0 (USART1) for INDI's driver,
//! port 1 (UART4) for our own `:~` queries.
//!
//! Asserts, in one boot:
//! - start-up reaches the loop: the log says the firmware is up and
//!   tracking at the configuration's sidereal rate;
//! - tracking: the RA step rate between two status lines at least 60
//!   emulated seconds apart is the configured rate within 0.5 %;
//! - ST4: a pulse on each of the four lines, each between two status
//!   lines, moves its axis its way by the guide rate over the pulse's
//!   length (as the firmware timed it) within 2 %, and leaves the other
//!   axis alone;
//! - ST4 bounce and both lines, as documented (src/mount/st4): four
//!   assert-release pairs shorter than glitch_us then a held pulse count
//!   as glitches and the pulse moves RA as its clean edge says (within
//!   2 %); both RA lines at once for 2 s move nothing beyond tracking (1.5
//!   steps) and count one `both_lines` episode (the counters and step
//!   counts from port 1);
//! - guiding: RA pulses at a guide cadence become guide frames, and the
//!   learner learns at least one of every two;
//! - the stack: its high-water mark (the firmware paints it at reset)
//!   leaves at least 25 % of it.
//!
//! And in another, INDI's `indi_lx200generic` on port 0: it connects
//! within 5 s, syncs and reads the position back; W and E as a move and a
//! stop (the driver's default) move RA at the guide rate within 1 % (and
//! a step's and a millisecond's reading) in the guide's middle, stop it (a step either way in the second after) and
//! last no longer than the driver's wall-clock length; N, S, W and E as
//! timed pulses (`:Mg`) move their axis by the guide rate x the length
//! within 1 % and the other by at most 3 steps; the driver's coordinates
//! show what the step counters moved (to the reply's second of time and
//! arcsecond); and the guiding counters count 4 RA and 2 Dec pulses, all
//! 6 from the port. Skipped without indiserver, as tests/indi.rs.
//!
//! And in a third, of the build with the test-only feature
//! `inject-model-fault` (`MKGP_BOARD_FAULT_ELF`; the model's task panics
//! at its third learned frame): RA pulses until it faults; the fault path
//! drives both ENABLE pins high (driver off) before the reset, as qtest's
//! interception of GPIOA's outputs shows in order; the next boot's log
//! names the panic (the fault record kept in RAM across the reset), and
//! the board tracks again with both drivers on.
//!
//! And a fourth, of the build with the test-only feature `emulator-tick`
//! (`MKGP_BOARD_LONG_ELF`), booted with a store that holds a model learned
//! on the host (tests/common/store_image.rs): 31 emulated minutes of RA
//! pulses that correct a two-stage gear error, the worm index's mark once
//! per turn. The model is restored at boot and at the index's first pass;
//! the three periodic saves are attempted (QEMU's flash does not program);
//! every pulse is counted; the learner takes frames to the end; and the
//! stack leaves at least 25 % of it.
//!
//! Without `MKGP_BOARD_ELF` the test is skipped with a message (the plain
//! `cargo test` of host-tests; test.sh runs it again with the binary, and
//! under CI=true fails if QEMU cannot). With it, a QEMU without the machine
//! fails the test. QEMU is killed at the end.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

mod common;

use common::lx200::{self, Indi, Own, Steps};
use common::store_image;
use defmt_decoder::{DecodeError, Table};
use mkgp_mount::counters::Counters;
use mkgp_mount::mount::guiding::GuidingCounters;
use object::{Object, ObjectSymbol};

/// The QEMU machine, killed on drop.
struct Qemu(Child);

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// One decoded log line: the firmware's uptime, s, and the message.
#[derive(Clone, Debug)]
struct Line {
    at_s: f64,
    text: String,
}

/// The running board: its qtest connection, its log and its serial ports.
struct Board {
    _qemu: Qemu,
    /// The ptys of the command ports: port 0 (USART1, QEMU's first serial
    /// device) and port 1 (UART4, its fourth).
    ports: [PathBuf; 2],
    qtest: BufReader<UnixStream>,
    /// `_SEGGER_RTT`, the RTT control block.
    rtt: u64,
    /// The stack's bottom and top (`_stack_end`, `_stack_start`).
    stack: (u64, u64),
    table: Table,
    /// Every byte of the defmt stream so far (of this boot).
    stream: Vec<u8>,
    /// qtest's notifications of intercepted outputs, in order (`IRQ raise
    /// 4`: pin 4 went high).
    events: Vec<String>,
    dir: PathBuf,
}

/// GPIO ports as QEMU names their controllers.
#[derive(Clone, Copy)]
struct Pin {
    port: char,
    number: u8,
}

/// The ST4 inputs of the L475 board (hal/src/board.rs): RA+ PB8, RA- PB9,
/// Dec+ PD14, Dec- PA15; active low.
const ST4: [(&str, Pin); 4] = [
    (
        "RA +",
        Pin {
            port: 'b',
            number: 8,
        },
    ),
    (
        "RA -",
        Pin {
            port: 'b',
            number: 9,
        },
    ),
    (
        "Dec +",
        Pin {
            port: 'd',
            number: 14,
        },
    ),
    (
        "Dec -",
        Pin {
            port: 'a',
            number: 15,
        },
    ),
];

impl Board {
    /// Boots `elf` with QEMU's options `extra`; `name` keeps this boot's
    /// files apart from another's.
    fn boot(elf: &Path, name: &str, extra: &[&str]) -> Board {
        let bytes = std::fs::read(elf).unwrap_or_else(|e| panic!("{}: {e}", elf.display()));
        let table = Table::parse(&bytes)
            .expect("the ELF's defmt table")
            .expect("the ELF has a defmt table");
        let file = object::File::parse(&*bytes).expect("an ELF");
        let symbol = |name: &str| {
            file.symbols()
                .find(|s| s.name() == Ok(name))
                .unwrap_or_else(|| panic!("{name} in the ELF"))
                .address()
        };
        let rtt = symbol("_SEGGER_RTT");
        let stack = (symbol("_stack_end"), symbol("_stack_start"));
        let dir = std::env::temp_dir().join(format!("mkgp-board-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let socket = dir.join("qtest.sock");
        let listener = UnixListener::bind(&socket).unwrap();
        let mut qemu = Qemu(
            Command::new("qemu-system-arm")
                .args(["-M", "b-l475e-iot01a", "-display", "none", "-accel", "tcg"])
                .args(extra)
                .arg("-kernel")
                .arg(elf)
                .arg("-qtest")
                .arg(format!("unix:{}", socket.display()))
                .args(["-qtest-log", "/dev/null"])
                .args(["-serial", "pty", "-serial", "null", "-serial", "null"])
                .args(["-serial", "pty", "-monitor", "none"])
                .arg("-D")
                .arg(dir.join("qemu.log"))
                .args(["-d", "guest_errors"])
                .stdin(Stdio::null())
                .stdout(Stdio::piped())
                .stderr(Stdio::inherit())
                .spawn()
                .expect("qemu-system-arm"),
        );
        // QEMU names each pty on stdout ("char device redirected to
        // /dev/pts/N (label serialK)"); the rest is passed on.
        let stdout = qemu.0.stdout.take().expect("piped stdout");
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                match line
                    .strip_prefix("char device redirected to ")
                    .and_then(|rest| rest.split_once(" (label "))
                {
                    Some((path, label)) => {
                        let _ = tx.send((label.trim_end_matches(')').to_string(), path.into()));
                    }
                    None => println!("{line}"),
                }
            }
        });
        let mut ptys = std::collections::HashMap::<String, PathBuf>::new();
        while ptys.len() < 2 {
            let (label, path) = rx
                .recv_timeout(Duration::from_secs(20))
                .expect("QEMU names its two ptys");
            ptys.insert(label, path);
        }
        let ports = ["serial0", "serial3"].map(|l| ptys[l].clone());
        listener.set_nonblocking(true).unwrap();
        let deadline = Instant::now() + Duration::from_secs(20);
        let stream = loop {
            match listener.accept() {
                Ok((s, _)) => break s,
                Err(_) if Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(20))
                }
                Err(e) => panic!("QEMU did not connect to qtest: {e}"),
            }
        };
        stream.set_nonblocking(false).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(30)))
            .unwrap();
        Board {
            _qemu: qemu,
            ports,
            qtest: BufReader::new(stream),
            rtt,
            stack,
            table,
            stream: Vec::new(),
            events: Vec::new(),
            dir,
        }
    }

    /// One qtest command; its `OK` reply's rest.
    fn cmd(&mut self, command: &str) -> String {
        let s = self.qtest.get_mut();
        writeln!(s, "{command}").unwrap();
        loop {
            let mut line = String::new();
            let n = self.qtest.read_line(&mut line).expect("qtest reply");
            assert!(n > 0, "QEMU closed qtest after {command}");
            let line = line.trim();
            if let Some(rest) = line.strip_prefix("OK") {
                return rest.trim().to_string();
            }
            assert!(
                !line.starts_with("FAIL") && !line.starts_with("ERR"),
                "qtest {command}: {line}"
            );
            // Notifications of intercepted outputs come in between.
            if line.starts_with("IRQ ") {
                self.events.push(line.to_string());
            }
        }
    }

    fn read(&mut self, addr: u64, len: u64) -> Vec<u8> {
        let hex = self.cmd(&format!("read 0x{addr:x} 0x{len:x}"));
        let hex = hex.trim_start_matches("0x");
        (0..hex.len() / 2)
            .map(|i| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).unwrap())
            .collect()
    }

    fn read_u32(&mut self, addr: u64) -> u32 {
        let b = self.read(addr, 4);
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }

    /// Drains RTT up-channel 0 (the defmt stream) into `stream`.
    fn drain(&mut self) {
        // The control block: a 16-byte id, two i32 counts, then the up
        // buffers: name, buffer, size, write offset, read offset, flags.
        let up = self.rtt + 24;
        let (buf, size, write) = (
            u64::from(self.read_u32(up + 4)),
            u64::from(self.read_u32(up + 8)),
            u64::from(self.read_u32(up + 12)),
        );
        let read = u64::from(self.read_u32(up + 16));
        if size == 0 || write == read {
            return;
        }
        let mut bytes = if write > read {
            self.read(buf + read, write - read)
        } else {
            self.read(buf + read, size - read)
        };
        if write < read && write > 0 {
            bytes.extend(self.read(buf, write));
        }
        self.cmd(&format!("writel 0x{:x} {}", up + 16, write));
        self.stream.extend(bytes);
    }

    /// The board reset: its log starts again (the firmware sets up the RTT
    /// buffer anew at boot).
    fn log_restarts(&mut self) {
        self.stream.clear();
    }

    /// Every line of the log so far.
    fn lines(&self) -> Vec<Line> {
        let mut decoder = self.table.new_stream_decoder();
        decoder.received(&self.stream);
        let mut lines = Vec::new();
        loop {
            match decoder.decode() {
                Ok(frame) => {
                    let at_s = frame
                        .display_timestamp()
                        .map(|t| t.to_string())
                        .and_then(|t| t.trim().parse::<f64>().ok())
                        .unwrap_or(f64::NAN);
                    lines.push(Line {
                        at_s,
                        text: frame.display_message().to_string(),
                    });
                }
                Err(DecodeError::UnexpectedEof) => break,
                // A frame cut short: the firmware's RTT buffer does not
                // block (defmt-rtt drops what does not fit), and a host
                // that drains late, under load, loses the end of a frame.
                // The decoder has dropped it and goes on at the next.
                Err(DecodeError::Malformed) => continue,
            }
        }
        lines
    }

    /// Drains the log until a line satisfies `found`, within `wall` of the
    /// wall clock (emulated time is slower).
    fn wait_for(&mut self, what: &str, wall: Duration, found: impl Fn(&Line) -> bool) -> Line {
        let deadline = Instant::now() + wall;
        loop {
            self.drain();
            if let Some(line) = self.lines().into_iter().find(&found) {
                return line;
            }
            assert!(
                Instant::now() < deadline,
                "no log line {what} within {wall:?}; the log:\n{}",
                self.transcript()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Bytes of the stack used so far: cortex-m-rt painted it with
    /// `0xCCCC_CCCC` at reset (the firmware's `paint-stack`); the lowest
    /// word changed since marks the deepest the stack has reached.
    fn stack_used(&mut self) -> u64 {
        let (bottom, top) = self.stack;
        let words = self.read(bottom, top - bottom);
        let untouched = words.chunks(4).take_while(|w| *w == [0xcc; 4]).count() as u64;
        top - bottom - 4 * untouched
    }

    /// Prints the stack's high-water mark so far after `label`, and fails
    /// with less than a quarter of the stack left.
    fn check_stack(&mut self, label: &str) {
        let used = self.stack_used();
        let size = self.stack.1 - self.stack.0;
        println!(
            "{label}: {used} of {size} B used ({:.0} % left)",
            100.0 * (1.0 - used as f64 / size as f64)
        );
        assert!(
            used * 4 <= size * 3,
            "the stack reached {used} of its {size} B: less than 25 % left"
        );
    }

    fn transcript(&self) -> String {
        self.lines()
            .iter()
            .map(|l| format!("{:10.6} {}\n", l.at_s, l.text))
            .collect()
    }

    /// Drives a GPIO input (its EXTI sees the edge).
    fn set_pin(&mut self, pin: Pin, high: bool) {
        self.cmd(&format!(
            "set_irq_in /machine/soc/gpio{} unnamed-gpio-in {} {}",
            pin.port,
            pin.number,
            u8::from(high)
        ));
    }
}

/// `text`'s number after `key` (up to the next space, comma or `x`).
fn number_after(text: &str, key: &str) -> Option<f64> {
    let rest = &text[text.find(key)? + key.len()..];
    let end = rest.find([' ', ',', 'x']).unwrap_or(rest.len());
    rest[..end].parse().ok()
}

/// A pulse's length by the firmware's clock, s, and when its end was
/// logged: from the first "ST4 pulse start `name`" line after `after_s` to
/// the next "ST4 pulse end" of its axis.
fn logged_pulse(board: &mut Board, name: &str, after_s: f64) -> (f64, f64) {
    let axis = name.split(' ').next().unwrap();
    let start = board.wait_for(&format!("ST4 {name} start"), Duration::from_secs(10), |l| {
        l.text.starts_with(&format!("ST4 pulse start {name} at ")) && l.at_s > after_s
    });
    let end = board.wait_for(&format!("ST4 {axis} end"), Duration::from_secs(10), |l| {
        l.text.starts_with(&format!("ST4 pulse end {axis} at ")) && l.at_s > start.at_s
    });
    let start_us = number_after(&start.text, " at ").unwrap();
    let end_us = number_after(&end.text, " at ").unwrap();
    ((end_us - start_us) / 1e6, end.at_s)
}

/// A status line: its time and the RA and Dec step counts.
#[derive(Clone, Copy, Debug)]
struct Status {
    at_s: f64,
    ra: f64,
    dec: f64,
}

fn status(line: &Line) -> Option<Status> {
    let text = line.text.strip_prefix("status: ")?;
    Some(Status {
        at_s: line.at_s,
        ra: number_after(text, "RA ")?,
        dec: number_after(text, "Dec ")?,
    })
}

fn statuses(board: &Board) -> Vec<Status> {
    board.lines().iter().filter_map(status).collect()
}

/// Waits for the first status line after `after_s`.
fn next_status(board: &mut Board, after_s: f64) -> Status {
    let line = board.wait_for(
        &format!("status after {after_s} s"),
        Duration::from_secs(900),
        |l| l.at_s > after_s && status(l).is_some(),
    );
    status(&line).unwrap()
}

/// RA pulses of the guiding phase.
const GUIDE_PULSES: u32 = 20;

/// The last value the log gave a counter line `key` (`group name value`).
fn last_counter(board: &Board, key: &str) -> Option<f64> {
    board
        .lines()
        .iter()
        .rev()
        .find(|l| l.text.starts_with(key))
        .and_then(|l| number_after(&l.text, key))
}

fn have_qemu_l475() -> bool {
    Command::new("qemu-system-arm")
        .args(["-M", "help"])
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("b-l475e-iot01a"))
}

/// The mount's figures as the firmware's start-up log gives them.
#[derive(Clone, Copy, Debug)]
struct Figures {
    /// Sidereal rate, RA steps/s.
    sidereal: f64,
    /// Guide rate, RA and Dec steps/s.
    ra_guide: f64,
    dec_guide: f64,
    ra_arcsec_per_step: f64,
    dec_arcsec_per_step: f64,
}

/// One boot at a time: the checks compare emulated time with the wall
/// clock's pacing, which two QEMUs on two cores would upset.
static ONE_BOARD: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The ELF under test, or `None` (the test skipped, with a message).
fn board_elf() -> Option<PathBuf> {
    let Some(elf) = std::env::var_os("MKGP_BOARD_ELF").map(PathBuf::from) else {
        eprintln!(
            "SKIPPED: MKGP_BOARD_ELF unset (test.sh sets it to the ELF that \
             target-tests/board/build.sh builds); the board test did not run"
        );
        return None;
    };
    assert!(
        have_qemu_l475(),
        "qemu-system-arm has no b-l475e-iot01a machine: QEMU 10 or later is needed \
         (.ci/run installs it from Debian's backports)"
    );
    Some(elf)
}

/// Boots the board (QEMU's options `extra`) and waits for its start-up
/// log: up, the mount's figures, tracking at the configuration's sidereal
/// rate.
fn start(elf: &Path, name: &str, extra: &[&str]) -> (Board, Figures) {
    let mut board = Board::boot(elf, name, extra);
    board.wait_for("saying the firmware is up", Duration::from_secs(30), |l| {
        l.text.starts_with("mkgp-mount ") && l.text.contains(" up, SYSCLK 80000000 Hz")
    });
    let mount = board.wait_for("with the mount's figures", Duration::from_secs(30), |l| {
        l.text.starts_with("mount: ")
    });
    let sidereal = number_after(&mount.text, "sidereal ").expect("sidereal steps/s");
    let guide = number_after(&mount.text, "guide ").expect("guide rate");
    let ra_arcsec_per_step = number_after(&mount.text, "steps/s, ").expect("arcsec per RA step");
    let dec_arcsec_per_step =
        number_after(&mount.text, "arcsec/RA step, ").expect("arcsec per Dec step");
    let tracking = board.wait_for("saying it tracks", Duration::from_secs(30), |l| {
        l.text.starts_with("tracking: RA ")
    });
    let rate = number_after(&tracking.text, "tracking: RA ").unwrap();
    assert!(
        (rate - sidereal).abs() < 1e-3,
        "tracking at {rate} steps/s, the configuration's sidereal rate is {sidereal}"
    );
    // Guide rate in steps/s: RA at the sidereal rate's share, Dec the same
    // angular rate in Dec steps.
    let ra_guide = guide * sidereal;
    let figures = Figures {
        sidereal,
        ra_guide,
        dec_guide: ra_guide * ra_arcsec_per_step / dec_arcsec_per_step,
        ra_arcsec_per_step,
        dec_arcsec_per_step,
    };
    (board, figures)
}

#[test]
fn the_binary_boots_tracks_and_obeys_st4_in_qemu() {
    let Some(elf) = board_elf() else {
        return;
    };
    let _one = ONE_BOARD.lock().unwrap_or_else(|e| e.into_inner());
    let (mut board, figures) = start(&elf, "st4", &[]);
    let Figures {
        sidereal,
        ra_guide,
        dec_guide,
        ..
    } = figures;

    // Tracking over at least 60 emulated seconds.
    let first = next_status(&mut board, 0.0);
    let last = next_status(&mut board, first.at_s + 60.0);
    let span = last.at_s - first.at_s;
    let measured = (last.ra - first.ra) / span;
    println!(
        "tracking: {measured:.4} RA steps/s over {span:.1} emulated s (configured {sidereal:.5}, \
         {:+.3} %)",
        100.0 * (measured / sidereal - 1.0)
    );
    assert!(
        (measured / sidereal - 1.0).abs() <= 0.005,
        "RA at {measured} steps/s over {span} s, configured {sidereal}"
    );
    assert_eq!(last.dec, first.dec, "Dec moved while only tracking");

    // ST4: a pulse on each line, each between two status lines. QEMU's
    // EXTI believes every line low until the line has changed while routed
    // to it (the pull-up came before the routing), so it would miss the
    // first falling edge: each line is driven low and high once first. The
    // firmware sees only the rising edge of that, on a released line, and
    // reports nothing.
    for &(_, pin) in &ST4 {
        board.set_pin(pin, false);
        board.set_pin(pin, true);
    }
    let mut at = last;
    for (name, pin) in ST4 {
        let before = next_status(&mut board, at.at_s);
        board.set_pin(pin, false);
        std::thread::sleep(Duration::from_secs(3));
        board.set_pin(pin, true);
        let axis = name.split(' ').next().unwrap();
        let (length_s, end_at_s) = logged_pulse(&mut board, name, before.at_s);
        let after = next_status(&mut board, end_at_s);
        let dt = after.at_s - before.at_s;
        let ra_beyond = (after.ra - before.ra) - sidereal * dt;
        let dec_moved = after.dec - before.dec;
        let sign = if name.ends_with('+') { 1.0 } else { -1.0 };
        let (moved, rate, other) = if axis == "RA" {
            (ra_beyond, ra_guide, dec_moved)
        } else {
            (dec_moved, dec_guide, ra_beyond)
        };
        let expected = sign * rate * length_s;
        println!(
            "ST4 {name}: {length_s:.3} s pulse moved {axis} {moved:+.1} steps beyond tracking \
             (expected {expected:+.1}); the other axis {other:+.1}"
        );
        assert!(
            (moved / expected - 1.0).abs() <= 0.02,
            "ST4 {name}: {moved} steps, expected {expected}; the log:\n{}",
            board.transcript()
        );
        // RA's own tracking over the interval is counted to a step or two.
        assert!(
            other.abs() <= 3.0,
            "ST4 {name} moved the other axis {other} steps"
        );
        at = after;
    }
    assert!(
        statuses(&board).len() >= 6,
        "status lines: {:?}",
        statuses(&board)
    );

    // Contact bounce, then a held pulse: the bounce's assert-release pairs
    // (each far shorter than glitch_us, 1 ms) are glitches, counted and
    // ignored; the pulse runs from the clean edge. The step counters, the
    // firmware's clock and the ST4 counters come from port 1.
    let (ra_plus, ra_minus) = (ST4[0].1, ST4[1].1);
    let mut own = Own::new(lx200::open_pty(&board.ports[1]));
    let st4_counter =
        |own: &mut Own<std::fs::File>, name: &str| lx200::field(&own.ask(":~Cs#"), name);
    // Steps beyond tracking from `s0` until `quiet_s` of firmware time
    // after now.
    let beyond_until = |own: &mut Own<std::fs::File>, s0: Steps, quiet_s: f64| {
        let until = own.steps().t_s + quiet_s;
        let s1 = own.steps_at(until, Duration::from_millis(100));
        (
            (s1.ra - s0.ra) as f64 - sidereal * (s1.t_s - s0.t_s),
            (s1.dec - s0.dec) as f64,
        )
    };
    let glitches0 = st4_counter(&mut own, "glitches");
    let s0 = own.steps();
    // The core must run between the edges to see them (the EXTI handler
    // reads the line), so they are a few hundred microseconds apart: a
    // few hundred or less of emulated time, still far inside glitch_us.
    let bounce = Duration::from_micros(300);
    for _ in 0..4 {
        board.set_pin(ra_plus, false);
        std::thread::sleep(bounce);
        board.set_pin(ra_plus, true);
        std::thread::sleep(bounce);
    }
    board.set_pin(ra_plus, false);
    std::thread::sleep(Duration::from_secs(2));
    board.set_pin(ra_plus, true);
    let (ra_beyond, dec_moved) = beyond_until(&mut own, s0, 0.5);
    let glitches = st4_counter(&mut own, "glitches") - glitches0;
    let (length_s, _) = logged_pulse(&mut board, "RA +", s0.t_s);
    let expected = ra_guide * length_s;
    println!(
        "ST4 bounce: 4 glitch pairs then a {length_s:.3} s pulse: {glitches} glitches counted, \
         RA {ra_beyond:+.1} steps beyond tracking (expected {expected:+.1}), Dec {dec_moved:+}"
    );
    // Each pair the core saw whole is one (on a loaded host it may see
    // fewer): none is a pulse.
    assert!(
        (1..=4).contains(&glitches),
        "{glitches} glitches counted for 4 bounces"
    );
    assert!(
        (ra_beyond / expected - 1.0).abs() <= 0.02,
        "after the bounce: {ra_beyond} steps, expected {expected}"
    );
    assert_eq!(dec_moved, 0.0);

    // Both lines of RA at once: the axis takes no pulse until both are
    // released (tracking goes on), one episode counted.
    let both0 = st4_counter(&mut own, "both_lines");
    let s0 = own.steps();
    board.set_pin(ra_plus, false);
    board.set_pin(ra_minus, false);
    std::thread::sleep(Duration::from_secs(2));
    board.set_pin(ra_plus, true);
    board.set_pin(ra_minus, true);
    let (ra_beyond, _) = beyond_until(&mut own, s0, 0.5);
    let both = st4_counter(&mut own, "both_lines") - both0;
    println!("ST4 both RA lines for 2 s: RA {ra_beyond:+.1} steps beyond tracking, {both} episode");
    assert_eq!(both, 1, "both_lines episodes");
    assert!(
        ra_beyond.abs() <= 1.5,
        "both RA lines moved RA {ra_beyond} steps beyond tracking"
    );

    // Guiding: short RA pulses, alternating in sign, one per guide cadence
    // of the wall clock (a little more of emulated time), as a guider
    // sends them. Each becomes a guide frame that the learner learns.
    let learned_before = last_counter(&board, "model learned ").unwrap_or(0.0);
    for k in 0..GUIDE_PULSES {
        let pin = if k % 2 == 0 { ra_plus } else { ra_minus };
        board.set_pin(pin, false);
        std::thread::sleep(Duration::from_millis(150));
        board.set_pin(pin, true);
        std::thread::sleep(Duration::from_millis(1850));
        board.drain();
    }
    let line = board.wait_for("the model learning", Duration::from_secs(30), |l| {
        l.text.starts_with("model learned ")
            && number_after(&l.text, "model learned ")
                .is_some_and(|n| n >= learned_before + f64::from(GUIDE_PULSES / 2))
    });
    let measured_frames = board
        .lines()
        .iter()
        .filter(|l| l.text.starts_with("frame measured at gear "))
        .count();
    println!(
        "guiding: {GUIDE_PULSES} RA pulses; {} (before them {learned_before}; {measured_frames} \
         frames logged as measured in all)",
        line.text
    );

    board.check_stack("stack");
    let _ = std::fs::remove_dir_all(&board.dir);
}

/// The guides' length through the driver, ms.
const INDI_GUIDE_MS: u64 = 5_000;

/// What one guide through the driver did: the step counters (RA beyond
/// sidereal tracking, Dec) and the driver's coordinates (hours, degrees)
/// moved by; the rates beyond tracking (RA, Dec steps/s) in its middle,
/// over `during_s` of the firmware's time; the steps beyond tracking (RA,
/// Dec) in the second after it.
struct Guided {
    ra_beyond: f64,
    dec: f64,
    ra_h: f64,
    dec_deg: f64,
    during: (f64, f64),
    during_s: f64,
    after: (f64, f64),
}

/// The rates beyond tracking between two readings (RA, Dec steps/s).
fn rates(a: Steps, b: Steps, figures: &Figures) -> (f64, f64) {
    let dt = b.t_s - a.t_s;
    (
        (b.ra - a.ra) as f64 / dt - figures.sidereal,
        (b.dec - a.dec) as f64 / dt,
    )
}

fn guide_through_indi(
    indi: &Indi,
    own: &mut Own<std::fs::File>,
    figures: &Figures,
    prop: &str,
) -> Guided {
    let (ra0, dec0) = indi.coords();
    let s0 = own.steps();
    let wall0 = Instant::now();
    indi.set(&format!("{prop}={INDI_GUIDE_MS}"));
    // Its middle: well inside the guide on either clock.
    let guide = Duration::from_millis(INDI_GUIDE_MS);
    std::thread::sleep(guide / 5);
    let mid0 = own.steps();
    std::thread::sleep(guide * 3 / 5);
    let mid1 = own.steps();
    // Its end on both clocks, and two of the driver's 1 s polls.
    let end_s = s0.t_s + guide.as_secs_f64() + 2.0;
    while own.steps().t_s < end_s || wall0.elapsed() < guide + Duration::from_millis(2_500) {
        std::thread::sleep(Duration::from_millis(200));
    }
    let s1 = own.steps();
    std::thread::sleep(Duration::from_secs(1));
    let s2 = own.steps();
    let (ra1, dec1) = indi.coords();
    Guided {
        ra_beyond: (s1.ra - s0.ra) as f64 - figures.sidereal * (s1.t_s - s0.t_s),
        dec: (s1.dec - s0.dec) as f64,
        ra_h: ra1 - ra0,
        dec_deg: dec1 - dec0,
        during: rates(mid0, mid1, figures),
        during_s: mid1.t_s - mid0.t_s,
        after: {
            let (ra, dec) = rates(s1, s2, figures);
            (ra * (s2.t_s - s1.t_s), dec * (s2.t_s - s1.t_s))
        },
    }
}

#[test]
fn indi_lx200generic_drives_the_binary_in_qemu() {
    let Some(elf) = board_elf() else {
        return;
    };
    if !lx200::available() {
        return;
    }
    let _one = ONE_BOARD.lock().unwrap_or_else(|e| e.into_inner());
    let (board, figures) = start(&elf, "indi", &[]);
    let mut own = Own::new(lx200::open_pty(&board.ports[1]));
    let indi = Indi::start(&board.dir.join("indi"));
    let connect = indi.connect(&board.ports[0]);
    println!("indi: connected on port 0 in {connect:?}");
    assert!(connect < Duration::from_secs(5), "connect took {connect:?}");

    let (ra, dec) = indi.sync(6.0, 10.0);
    println!("indi: after the sync RA {ra} h, Dec {dec} deg");
    assert!((ra - 6.0).abs() < 1.0 / 3600.0 && (dec - 10.0).abs() < 1.0 / 3600.0);

    let guide_s = INDI_GUIDE_MS as f64 * 1e-3;
    // The driver's RA is whole seconds of time, its Dec whole arcseconds:
    // what the counters moved shows to within one of them.
    let shows = |g: &Guided, what: &str| {
        let ra_h = -g.ra_beyond * figures.ra_arcsec_per_step / 15.0 / 3600.0;
        let dec_deg = g.dec * figures.dec_arcsec_per_step / 3600.0;
        assert!(
            (g.ra_h - ra_h).abs() <= 1.0 / 3600.0 + 1e-9,
            "{what}: the driver's RA moved {} h, the counters {ra_h} h",
            g.ra_h
        );
        assert!(
            (g.dec_deg - dec_deg).abs() <= 1.0 / 3600.0 + 1e-9,
            "{what}: the driver's Dec moved {} deg, the counters {dec_deg} deg",
            g.dec_deg
        );
    };
    // W then E in the driver's default mode: a move at the guide rate
    // (`:RG#` `:Mw#`) and its stop (`:Qw#`) INDI_GUIDE_MS later on the
    // wall clock, which is less of emulated time: RA moves at the guide
    // rate in the middle, at the sidereal rate after, and no longer than
    // the driver asked.
    for (prop, sign) in [
        ("TELESCOPE_TIMED_GUIDE_WE.TIMED_GUIDE_W", 1.0),
        ("TELESCOPE_TIMED_GUIDE_WE.TIMED_GUIDE_E", -1.0),
    ] {
        let g = guide_through_indi(&indi, &mut own, &figures, prop);
        let rate = sign * figures.ra_guide;
        let length_s = g.ra_beyond / rate;
        println!(
            "indi: {prop} (move and stop): RA {:+.2} steps/s beyond tracking in its middle \
             (expected {rate:+.2}), {:+.1} steps in the second after; moved {:+.1} steps ({length_s:.2} emulated s \
             of the driver's {guide_s} s), Dec {:+}",
            g.during.0, g.after.0, g.ra_beyond, g.dec
        );
        // Within 1 %, and what whole steps and whole milliseconds read
        // over the window: a loaded host runs QEMU slower, and the same
        // 3 s of wall clock hold less of the firmware's time.
        let resolution = (1.0 + 2e-3 * (figures.sidereal + rate.abs())) / g.during_s;
        assert!(
            (g.during.0 - rate).abs() <= 0.01 * rate.abs() + resolution,
            "{prop}: {} steps/s in its middle over {} s, expected {rate}",
            g.during.0,
            g.during_s
        );
        assert!(
            g.after.0.abs() <= 1.0,
            "{prop}: still moving after the stop"
        );
        // (At least its middle: the rate there is the guide rate.)
        assert!(
            length_s <= guide_s * 1.01,
            "{prop}: moved for {length_s} emulated s of {guide_s} s"
        );
        assert_eq!(g.dec, 0.0, "{prop} moved Dec");
        shows(&g, prop);
    }
    // Timed pulses (`:Mg<d><ms>#`), each way on each axis: the firmware
    // times them itself.
    indi.set("Use Pulse Cmd.Off=Off;On=On");
    for (prop, axis, sign) in [
        ("TELESCOPE_TIMED_GUIDE_NS.TIMED_GUIDE_N", "Dec", 1.0),
        ("TELESCOPE_TIMED_GUIDE_NS.TIMED_GUIDE_S", "Dec", -1.0),
        ("TELESCOPE_TIMED_GUIDE_WE.TIMED_GUIDE_W", "RA", 1.0),
        ("TELESCOPE_TIMED_GUIDE_WE.TIMED_GUIDE_E", "RA", -1.0),
    ] {
        let g = guide_through_indi(&indi, &mut own, &figures, prop);
        let (moved, other, rate) = if axis == "RA" {
            (g.ra_beyond, g.dec, figures.ra_guide)
        } else {
            (g.dec, g.ra_beyond, figures.dec_guide)
        };
        let expected = sign * rate * guide_s;
        println!(
            "indi: {prop} (timed): {axis} {moved:+.1} steps (expected {expected:+.1}), the other \
             axis {other:+.1}; {:+.2}, {:+.2} steps/s in its middle",
            g.during.0, g.during.1
        );
        assert!(
            (moved / expected - 1.0).abs() <= 0.01,
            "{prop}: {moved} steps, expected {expected}"
        );
        // RA's tracking over the interval is counted to a step or two.
        assert!(other.abs() <= 3.0, "{prop} moved the other axis {other}");
        shows(&g, prop);
    }

    // The firmware's counters say the same: four RA pulses and two Dec
    // pulses reached the guiding, all six through the port.
    let g = own.ask(":~Cg#");
    let p = own.ask(&format!(":~Cg{}#", GuidingCounters::NAMES.len()));
    println!("indi: guiding {g} {p}");
    assert_eq!(lx200::field(&g, "ra_pulses"), 4, "{g}");
    assert_eq!(lx200::field(&g, "dec_pulses"), 2, "{g}");
    assert_eq!(lx200::field(&p, "port_pulses"), 6, "{p}");
    drop(indi);
    let _ = std::fs::remove_dir_all(&board.dir);
}

/// The ENABLE pins of the L475 board (hal/src/board.rs): RA PA4, Dec PA6;
/// high = driver off.
const ENABLE_PINS: [u8; 2] = [4, 6];
/// GPIOA's output data register.
const GPIOA_ODR: u64 = 0x4800_0014;
/// QEMU's reset of the GPIO controllers drives PA13 (SWDIO) to its pull-up
/// level: in the intercepted outputs, the first sign of a reset.
const RESET_SIGN: &str = "IRQ raise 13";

#[test]
fn a_fault_in_the_model_task_disables_the_drivers_and_is_named_at_the_next_boot() {
    let Some(elf) = std::env::var_os("MKGP_BOARD_FAULT_ELF").map(PathBuf::from) else {
        eprintln!(
            "SKIPPED: MKGP_BOARD_FAULT_ELF unset (test.sh sets it to the ELF that \
             `target-tests/board/build.sh inject-model-fault` builds); the fault test did not run"
        );
        return;
    };
    assert!(
        have_qemu_l475(),
        "qemu-system-arm has no b-l475e-iot01a machine"
    );
    let _one = ONE_BOARD.lock().unwrap_or_else(|e| e.into_inner());
    let (mut board, _) = start(&elf, "fault", &[]);
    board.cmd("irq_intercept_out /machine/soc/gpioa");
    let odr = board.read_u32(GPIOA_ODR);
    for pin in ENABLE_PINS {
        assert_eq!(
            odr >> pin & 1,
            0,
            "PA{pin}: the driver is off while tracking"
        );
    }

    // RA pulses at a guide cadence until the model's task has learned the
    // frame at which the build faults it, and the board resets.
    let (ra_plus, ra_minus) = (ST4[0].1, ST4[1].1);
    for pin in [ra_plus, ra_minus] {
        board.set_pin(pin, false);
        board.set_pin(pin, true);
    }
    let deadline = Instant::now() + Duration::from_secs(120);
    let mut k = 0;
    while !board.events.iter().any(|e| e == RESET_SIGN) {
        assert!(
            Instant::now() < deadline,
            "no reset within 2 minutes of pulses; the log:\n{}",
            board.transcript()
        );
        let pin = if k % 2 == 0 { ra_plus } else { ra_minus };
        board.set_pin(pin, false);
        std::thread::sleep(Duration::from_millis(150));
        board.set_pin(pin, true);
        std::thread::sleep(Duration::from_millis(1850));
        k += 1;
    }
    // Before the reset, the last thing each ENABLE pin did was go high:
    // the fault path turned both drivers off.
    let reset = board.events.iter().position(|e| e == RESET_SIGN).unwrap();
    let last_before = |pin: u8| {
        board.events[..reset]
            .iter()
            .rev()
            .find(|e| e.ends_with(&format!(" {pin}")))
            .cloned()
    };
    println!(
        "fault: after {k} RA pulses; outputs of GPIOA up to the reset: {:?}",
        &board.events[..reset]
    );
    for pin in ENABLE_PINS {
        assert_eq!(
            last_before(pin).as_deref(),
            Some(format!("IRQ raise {pin}").as_str()),
            "PA{pin} before the reset: {:?}",
            &board.events[..reset]
        );
    }

    // The next boot names the fault: the record kept in RAM across the
    // reset, read at start-up.
    board.log_restarts();
    let named = board.wait_for(
        "naming the fault at the next boot",
        Duration::from_secs(30),
        |l| {
            l.text
                .starts_with("last reset was the fault path's: panic at ")
        },
    );
    println!("fault: the next boot logs \"{}\"", named.text);
    assert!(
        named.text.contains("learning_task.rs") && named.text.ends_with("; drivers disabled"),
        "{}",
        named.text
    );
    // And it starts again: tracking, both drivers on.
    board.wait_for("tracking again", Duration::from_secs(30), |l| {
        l.text.starts_with("tracking: RA ")
    });
    let odr = board.read_u32(GPIOA_ODR);
    for pin in ENABLE_PINS {
        assert_eq!(
            odr >> pin & 1,
            0,
            "PA{pin}: the driver is off after the new boot"
        );
    }
    let _ = std::fs::remove_dir_all(&board.dir);
}

/// Emulated minutes of the long run: three of the learning policy's
/// 10-minute saves.
const LONG_RUN_MIN: f64 = 31.0;
/// The worm-index input of the L475 board (hal/src/board.rs): PC4, low at
/// the mark.
const WORM_INDEX: Pin = Pin {
    port: 'c',
    number: 4,
};
/// The long run's guide cadence, emulated s.
const CADENCE_S: f64 = 2.0;

/// The whole binary for 31 emulated minutes of guiding, booted with a
/// learned model in its store: the restores at boot and at the worm
/// index's first pass, the periodic saves, and the stack's high-water mark
/// after all of it. The build with the test-only feature `emulator-tick`
/// (`MKGP_BOARD_LONG_ELF`; SysTick and the step tick at 1 kHz, the lowest
/// the configuration allows, as QEMU's cost is per interrupt)
/// under QEMU's instruction-counted time (`-icount shift=4,sleep=off`:
/// 62.5 M instructions per emulated second, near the chip's 80 MHz, and
/// the clock skips ahead while the core sleeps), so the run takes a few
/// minutes of wall clock.
#[test]
fn thirty_emulated_minutes_of_learning_leave_a_quarter_of_the_stack() {
    let Some(elf) = std::env::var_os("MKGP_BOARD_LONG_ELF").map(PathBuf::from) else {
        eprintln!(
            "SKIPPED: MKGP_BOARD_LONG_ELF unset (test.sh sets it to the ELF that \
             `target-tests/board/build.sh emulator-tick` builds); the long run did not run"
        );
        return;
    };
    assert!(
        have_qemu_l475(),
        "qemu-system-arm has no b-l475e-iot01a machine"
    );
    let _one = ONE_BOARD.lock().unwrap_or_else(|e| e.into_inner());
    // 40 minutes learned on the host, saved with an index pass at RA step
    // 0 (any count: the phase is the difference).
    let image = std::env::temp_dir().join(format!("mkgp-board-store-{}.elf", std::process::id()));
    std::fs::write(&image, store_image::learned_model(2400.0, 0)).unwrap();
    // The guider corrects the gear the image learned; the index marks once
    // per worm turn.
    let gear = store_image::gear();
    let worm_period_s = gear.sinusoids[0].period_s;
    let loader = format!("loader,file={}", image.display());
    let (mut board, figures) = start(
        &elf,
        "long",
        &["-icount", "shift=4,sleep=off", "-device", &loader],
    );
    let _ = std::fs::remove_file(&image);
    let restored = board.wait_for("restoring the stored model", Duration::from_secs(30), |l| {
        l.text.starts_with("model restored (")
    });
    println!(
        "long run: at boot \"{}\", stack {} B so far",
        restored.text,
        board.stack_used()
    );
    let mut own = Own::new(lx200::open_pty(&board.ports[1]));
    let (ra_plus, ra_minus) = (ST4[0].1, ST4[1].1);
    for pin in [ra_plus, ra_minus, WORM_INDEX] {
        board.set_pin(pin, false);
        board.set_pin(pin, true);
    }
    let guide_arcsec_per_s = figures.ra_guide * figures.ra_arcsec_per_step;
    let wall0 = Instant::now();
    let t0 = own.steps().t_s;
    let wait_until =
        |own: &mut Own<std::fs::File>, t_s: f64| own.steps_at(t_s, Duration::from_millis(5)).t_s;
    let frames = |own: &mut Own<std::fs::File>| lx200::field(&own.ask(":~Cl#"), "frames");
    let ra_pulses = |own: &mut Own<std::fs::File>| lx200::field(&own.ask(":~Cg#"), "ra_pulses");
    let ra_pulses0 = ra_pulses(&mut own);
    // A guider's RA pulses, one per cadence, correcting the gear error's
    // change over the cadence (at least 30 ms: a frame each); the worm
    // index's mark once per worm turn, the first a minute in.
    let mut pulses = 0u32;
    let mut t = t0;
    let mut next_index = t0 + 60.0;
    let mut frames_halfway = None;
    while t < t0 + LONG_RUN_MIN * 60.0 {
        // 1 px = 1 arcsec.
        let correction = gear.gear_error(t - t0) - gear.gear_error(t - t0 + CADENCE_S);
        let pin = if correction > 0.0 { ra_plus } else { ra_minus };
        let length_s = (correction.abs() / guide_arcsec_per_s).max(0.03);
        board.set_pin(pin, false);
        let start = wait_until(&mut own, t);
        wait_until(&mut own, start + length_s);
        board.set_pin(pin, true);
        pulses += 1;
        // The mark right after a pulse's end: both edges pending at once,
        // as when the index's interrupt took the ST4 line's edge with it.
        if t >= next_index {
            board.set_pin(WORM_INDEX, false);
            wait_until(&mut own, t + 0.3);
            board.set_pin(WORM_INDEX, true);
            next_index += worm_period_s;
        }
        t = wait_until(&mut own, start + CADENCE_S);
        board.drain();
        if pulses.is_multiple_of(150) {
            eprintln!(
                "long run: {:.0} emulated min in {:.1} wall min, stack {} B so far",
                (t - t0) / 60.0,
                wall0.elapsed().as_secs_f64() / 60.0,
                board.stack_used()
            );
        }
        if frames_halfway.is_none() && t >= t0 + LONG_RUN_MIN * 30.0 {
            frames_halfway = Some(frames(&mut own));
        }
    }
    let frames_end = frames(&mut own);
    let ra_pulses_seen = ra_pulses(&mut own) - ra_pulses0;
    board.drain();
    let lines = board.lines();
    let find = |prefix: &str| -> Vec<&Line> {
        lines
            .iter()
            .filter(|l| l.text.starts_with(prefix))
            .collect()
    };
    let index_restore = find("model restored at the worm index");
    let saves: Vec<&Line> = ["model saved", "model not saved", "model save deferred"]
        .iter()
        .flat_map(|p| find(p))
        .collect();
    println!(
        "long run: {:.1} emulated min in {:.1} wall min, {pulses} RA pulses ({ra_pulses_seen} \
         counted), the learner's frames {} at half time and {frames_end} at the end",
        (t - t0) / 60.0,
        wall0.elapsed().as_secs_f64() / 60.0,
        frames_halfway.unwrap_or(0),
    );
    for l in index_restore.iter().chain(&saves) {
        println!("long run: {:8.1} s \"{}\"", l.at_s, l.text);
    }
    board.check_stack("long run: stack");
    // Every pulse counted: the worm index's interrupt once took the ST4
    // lines' pending edges with its own and left them masked.
    assert_eq!(ra_pulses_seen, i64::from(pulses), "RA pulses counted");
    assert_eq!(
        index_restore.len(),
        1,
        "restores at the worm index's first pass; the log:\n{}",
        board.transcript()
    );
    assert!(
        saves.len() >= 3,
        "periodic save attempts; the log:\n{}",
        board.transcript()
    );
    assert!(
        frames_halfway.is_some_and(|h| frames_end > h),
        "the learner stopped taking frames; the log:\n{}",
        board.transcript()
    );
    let _ = std::fs::remove_dir_all(&board.dir);
}
