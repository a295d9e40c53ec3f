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
//! Asserts, in one boot:
//! - start-up reaches the loop: the log says the firmware is up and
//!   tracking at the configuration's sidereal rate;
//! - tracking: the RA step rate between two status lines at least 60
//!   emulated seconds apart is the configured rate within 0.5 %;
//! - ST4: a pulse on each of the four lines, each between two status
//!   lines, moves its axis its way by the guide rate over the pulse's
//!   length (as the firmware timed it) within 2 %, and leaves the other
//!   axis alone;
//! - guiding: RA pulses at a guide cadence become guide frames, and the
//!   learner learns at least one of every two;
//! - the stack: its high-water mark (the firmware paints it at reset)
//!   leaves at least 25 % of it.
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

use defmt_decoder::{DecodeError, Table};
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

/// The running board: its qtest connection and its log.
struct Board {
    _qemu: Qemu,
    qtest: BufReader<UnixStream>,
    /// `_SEGGER_RTT`, the RTT control block.
    rtt: u64,
    /// The stack's bottom and top (`_stack_end`, `_stack_start`).
    stack: (u64, u64),
    table: Table,
    /// Every byte of the defmt stream so far.
    stream: Vec<u8>,
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
    fn boot(elf: &Path) -> Board {
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
        let dir = std::env::temp_dir().join(format!("mkgp-board-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let socket = dir.join("qtest.sock");
        let listener = UnixListener::bind(&socket).unwrap();
        let qemu = Qemu(
            Command::new("qemu-system-arm")
                .args(["-M", "b-l475e-iot01a", "-display", "none", "-accel", "tcg"])
                .arg("-kernel")
                .arg(elf)
                .arg("-qtest")
                .arg(format!("unix:{}", socket.display()))
                .args(["-qtest-log", "/dev/null"])
                .args(["-serial", "null", "-monitor", "none"])
                .arg("-D")
                .arg(dir.join("qemu.log"))
                .args(["-d", "guest_errors"])
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::inherit())
                .spawn()
                .expect("qemu-system-arm"),
        );
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
            qtest: BufReader::new(stream),
            rtt,
            stack,
            table,
            stream: Vec::new(),
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
            // IRQ notifications and the like come in between.
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
                Err(DecodeError::Malformed) => panic!("malformed defmt stream"),
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
        Duration::from_secs(180),
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

#[test]
fn the_binary_boots_tracks_and_obeys_st4_in_qemu() {
    let Some(elf) = std::env::var_os("MKGP_BOARD_ELF").map(PathBuf::from) else {
        eprintln!(
            "SKIPPED: MKGP_BOARD_ELF unset (test.sh sets it to the ELF that \
             target-tests/board/build.sh builds); the board test did not run"
        );
        return;
    };
    assert!(
        have_qemu_l475(),
        "qemu-system-arm has no b-l475e-iot01a machine: QEMU 10 or later is needed \
         (.ci/run installs it from Debian's backports)"
    );
    let mut board = Board::boot(&elf);

    // Start-up reaches the loop.
    board.wait_for("saying the firmware is up", Duration::from_secs(30), |l| {
        l.text.starts_with("mkgp-mount ") && l.text.contains(" up, SYSCLK 80000000 Hz")
    });
    let mount = board.wait_for("with the mount's figures", Duration::from_secs(30), |l| {
        l.text.starts_with("mount: ")
    });
    let sidereal = number_after(&mount.text, "sidereal ").expect("sidereal steps/s");
    let guide = number_after(&mount.text, "guide ").expect("guide rate");
    let ra_arcsec = number_after(&mount.text, "steps/s, ").expect("arcsec per RA step");
    let dec_arcsec = number_after(&mount.text, "arcsec/RA step, ").expect("arcsec per Dec step");
    let tracking = board.wait_for("saying it tracks", Duration::from_secs(30), |l| {
        l.text.starts_with("tracking: RA ")
    });
    let rate = number_after(&tracking.text, "tracking: RA ").unwrap();
    assert!(
        (rate - sidereal).abs() < 1e-3,
        "tracking at {rate} steps/s, the configuration's sidereal rate is {sidereal}"
    );

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
    // Guide rate in steps/s: RA at the sidereal rate's share, Dec the same
    // angular rate in Dec steps.
    let ra_guide = guide * sidereal;
    let dec_guide = ra_guide * ra_arcsec / dec_arcsec;
    let mut at = last;
    for (name, pin) in ST4 {
        let before = next_status(&mut board, at.at_s);
        board.set_pin(pin, false);
        std::thread::sleep(Duration::from_secs(3));
        board.set_pin(pin, true);
        let axis = name.split(' ').next().unwrap();
        let start = board.wait_for(&format!("ST4 {name} start"), Duration::from_secs(10), |l| {
            l.text.starts_with(&format!("ST4 pulse start {name} at ")) && l.at_s > before.at_s
        });
        let end = board.wait_for(&format!("ST4 {axis} end"), Duration::from_secs(10), |l| {
            l.text.starts_with(&format!("ST4 pulse end {axis} at ")) && l.at_s > start.at_s
        });
        let start_us = number_after(&start.text, " at ").unwrap();
        let end_us = number_after(&end.text, " at ").unwrap();
        let length_s = (end_us - start_us) / 1e6;
        let after = next_status(&mut board, end.at_s);
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

    // Guiding: short RA pulses, alternating in sign, one per guide cadence
    // of the wall clock (a little more of emulated time), as a guider
    // sends them. Each becomes a guide frame that the learner learns.
    let learned_before = last_counter(&board, "model learned ").unwrap_or(0.0);
    let (ra_plus, ra_minus) = (ST4[0].1, ST4[1].1);
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

    // The stack's high-water mark so far.
    let used = board.stack_used();
    let size = board.stack.1 - board.stack.0;
    println!(
        "stack: {used} of {size} B used ({:.0} % left)",
        100.0 * (1.0 - used as f64 / size as f64)
    );
    assert!(
        used * 4 <= size * 3,
        "the stack reached {used} of its {size} B: less than 25 % left"
    );
    let _ = std::fs::remove_dir_all(&board.dir);
}
