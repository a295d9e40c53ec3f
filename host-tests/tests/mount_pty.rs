//! `guide-sim mount --pty`: the virtual mount driven through its pty with
//! raw LX200 bytes, as a client would: the connect queries, a sync, timed
//! guides read back through the step counters and our `:~` queries, the
//! telemetry line, a model reset, and a clean exit on SIGTERM (the link
//! removed); and a client that never reads its replies.

mod common;

use common::lx200::open_pty;
use common::process::{guide_sim, Group};
use mkgp_mount::counters::Counters;
use mkgp_mount::mount::guiding::GuidingCounters;
use mkgp_mount::mount::learner::FIRMWARE_STAGES;
use std::fs::File;
use std::io::{ErrorKind, Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Starts `guide-sim mount --pty link` and waits for its ready line.
fn start(link: &Path) -> (Group, String) {
    let link = link.to_str().expect("a UTF-8 temporary path");
    guide_sim(&["mount", "--case", "C1", "--no-st4-guider", "--pty", link])
}

/// Sends `cmd` and reads until `replies` replies ended by `#` (or, for
/// single-byte replies, that many bytes) came, at most 2 s.
fn ask(pty: &mut File, cmd: &str, hashes: usize) -> String {
    pty.write_all(cmd.as_bytes()).unwrap();
    let deadline = Instant::now() + Duration::from_secs(2);
    let mut got = Vec::new();
    let mut buf = [0u8; 1024];
    while got.iter().filter(|&&b| b == b'#').count() < hashes && Instant::now() < deadline {
        match pty.read(&mut buf) {
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(2))
            }
            Err(e) => panic!("{e}"),
        }
    }
    String::from_utf8(got).unwrap()
}

/// Reads exactly `n` bytes (replies without `#`), at most 2 s.
fn ask_bytes(pty: &mut File, cmd: &str, n: usize) -> String {
    pty.write_all(cmd.as_bytes()).unwrap();
    let deadline = Instant::now() + Duration::from_secs(2);
    let mut got = Vec::new();
    let mut buf = [0u8; 64];
    while got.len() < n && Instant::now() < deadline {
        match pty.read(&mut buf) {
            Ok(k) => got.extend_from_slice(&buf[..k]),
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(2))
            }
            Err(e) => panic!("{e}"),
        }
    }
    String::from_utf8(got).unwrap()
}

/// `:~P#` as (ra_steps, dec_steps), and when it was answered.
fn steps(pty: &mut File) -> (i64, i64, Instant) {
    let r = ask(pty, ":~P#", 1);
    let at = Instant::now();
    (field(&r, "ra_steps="), field(&r, "dec_steps="), at)
}

/// The number after `key` in a `key=value ...#` reply.
fn field(reply: &str, key: &str) -> i64 {
    reply
        .split([' ', '#'])
        .find_map(|f| f.strip_prefix(key))
        .unwrap_or_else(|| panic!("{key} in {reply:?}"))
        .parse()
        .unwrap()
}

/// A link of this test's own (the tests run in parallel).
fn link_path(test: &str) -> PathBuf {
    std::env::temp_dir().join(format!("mkgp-mount-pty-{test}-{}", std::process::id()))
}

#[test]
fn the_virtual_mount_answers_lx200_on_its_pty() {
    let link = link_path("answers");
    let (mut sim, ready) = start(&link);
    assert!(
        ready.starts_with("guide-sim mount: ready on pty"),
        "{ready}"
    );
    let mut pty = open_pty(&link);

    // What indi_lx200generic asks on connect.
    assert_eq!(ask_bytes(&mut pty, "\x06", 1), "P");
    assert_eq!(ask(&mut pty, ":GVP#", 1), "mkgp-mount-sim#");
    assert_eq!(ask(&mut pty, ":GT#", 1), "60.1#");
    assert_eq!(ask(&mut pty, ":Gc#:GM#", 2), "24#Site#");
    assert_eq!(ask_bytes(&mut pty, ":Sr06:00:00#:Sd+10*00:00#", 2), "11");
    assert_eq!(ask(&mut pty, ":CM#", 1), "N/A#");
    assert_eq!(ask(&mut pty, ":GR#:GD#", 2), "06:00:00#+10*00:00#");

    // The mount's step rates: guide-sim's mount for case C1 (the default
    // mount with the case's worm period); the guide rate is 0.5x sidereal
    // on both axes.
    let cases = host_tests::cases::load(&host_tests::data::cases_file()).unwrap();
    let c1 = cases.iter().find(|c| c.name == "C1").unwrap();
    let mount = host_tests::st4_sim::mount_config(c1).validate().unwrap();
    let sidereal_sps = mount.sidereal_ra_steps_per_s_f64();
    let arcsec_per_ra_step = f64::from(mount.arcsec_per_ra_step());
    let dec_arcsec_per_step = f64::from(mount.arcsec_per_dec_step());
    let guide_arcsec_per_s = f64::from(mount.guide_rate_arcsec_per_s());

    // A timed guide north of 2 s: the Dec counter moves by the guide rate
    // x 2 s (exact: Dec does not track).
    let (_, dec0, _) = steps(&mut pty);
    ask(&mut pty, ":Mgn2000#", 0);
    std::thread::sleep(Duration::from_millis(100));
    let status = ask(&mut pty, ":GU#", 1);
    assert!(status.contains('G'), "guiding shows: {status}");
    std::thread::sleep(Duration::from_millis(2400));
    let (_, dec1, _) = steps(&mut pty);
    let want = guide_arcsec_per_s * 2.0 / dec_arcsec_per_step;
    let moved = (dec1 - dec0) as f64;
    assert!(
        (moved / want - 1.0).abs() < 0.01,
        "Dec {moved} steps, want {want}"
    );

    // West 2 s: RA steps beyond sidereal by the guide rate x 2 s (within
    // the few ms the wall clock between the two queries is uncertain).
    let (ra0, _, t0) = steps(&mut pty);
    ask(&mut pty, ":Mgw2000#", 0);
    std::thread::sleep(Duration::from_millis(2500));
    let (ra1, _, t1) = steps(&mut pty);
    let beyond = (ra1 - ra0) as f64 - sidereal_sps * (t1 - t0).as_secs_f64();
    let want = guide_arcsec_per_s * 2.0 / arcsec_per_ra_step;
    assert!(
        (beyond / want - 1.0).abs() < 0.03,
        "RA {beyond} steps beyond tracking, want {want}"
    );
    // 15 arcsec west: RA one second of time smaller; Dec 15 arcsec north.
    assert_eq!(ask(&mut pty, ":GR#:GD#", 2), "05:59:59#+10*00:15#");

    // Our own queries: the pulses reached the guiding and made frames.
    let g = ask(&mut pty, ":~Cg#", 1);
    assert!(g.starts_with("ra_pulses=1 dec_pulses=1 frames="), "{g}");
    let l = ask(&mut pty, ":~L#", 1);
    assert!(
        l.starts_with("learn_pm=") && l.ends_with(&format!(" stages={FIRMWARE_STAGES} from=cold#")),
        "{l}"
    );
    assert_eq!(
        ask(
            &mut pty,
            &format!(":~Cg{}#", GuidingCounters::NAMES.len()),
            1
        ),
        "port_pulses=2 manual_moves=0 port_refused=0 st4_refused=0#"
    );
    // Asked together, as `guide-sim view` does: more than the transmit
    // pipe holds, all of it read at once.
    let all = ask(&mut pty, ":~Cp#:~Cg#:~Cf#:~Cl#:~Cs#:~L#", 6);
    assert_eq!(all.matches('#').count(), 6, "{all}");
    assert!(all.len() > 512, "{} bytes", all.len());

    // Telemetry: asked for, a line per learned frame arrives unasked.
    assert_eq!(ask_bytes(&mut pty, ":~T1#", 1), "1");
    ask(&mut pty, ":Mge300#", 0);
    std::thread::sleep(Duration::from_millis(2000));
    let line = ask(&mut pty, ":Mgw300#", 1);
    let line = line.trim_start_matches(|c| c != '~');
    assert!(
        line.starts_with("~T t_ms=") && line.contains(" learn_pm=") && line.ends_with('#'),
        "{line:?}"
    );
    assert_eq!(ask_bytes(&mut pty, ":~T0#", 1), "1");

    // A model reset asked on the port: the model starts again.
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(ask_bytes(&mut pty, ":~R#", 1), "1");
    let l = ask(&mut pty, ":~L#", 1);
    assert!(l.starts_with("learn_pm=0 "), "{l}");

    // SIGTERM: a clean exit, the link removed.
    // SAFETY: kill(2) on our own child's pid.
    unsafe { libc::kill(sim.0.id() as libc::pid_t, libc::SIGTERM) };
    let deadline = Instant::now() + Duration::from_secs(5);
    let status = loop {
        if let Some(s) = sim.0.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "no exit 5 s after SIGTERM");
        std::thread::sleep(Duration::from_millis(10));
    };
    assert!(status.success(), "{status}");
    assert!(
        std::fs::symlink_metadata(&link).is_err(),
        "the link is removed"
    );
}

/// Issue 26: clients that write `:GR#` and never read (2,200 one-shot
/// clients did it) fill the pty; the mount must drop the replies that find
/// no room, whole, count them in `replies_dropped` (`:~Cp#`) and go on.
#[test]
fn replies_nobody_reads_are_dropped_whole_and_counted() {
    let link = link_path("unread");
    let (mut sim, _) = start(&link);
    let mut pty = open_pty(&link);

    // 10,000 replies of 9 bytes: far more than the pty holds.
    const SENT: usize = 10_000;
    let mut cmds = ":GR#".repeat(SENT).into_bytes();
    let deadline = Instant::now() + Duration::from_secs(10);
    while !cmds.is_empty() && Instant::now() < deadline {
        match pty.write(&cmds) {
            Ok(n) => drop(cmds.drain(..n)),
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(2))
            }
            // The mount went away: the check below says how.
            Err(_) => break,
        }
    }
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(
        sim.0.try_wait().unwrap(),
        None,
        "the mount exited with its replies unread"
    );
    assert!(cmds.is_empty(), "the mount stopped reading its commands");

    // Now read: whole replies only, then the mount answers again.
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    let mut quiet_since = Instant::now();
    while quiet_since.elapsed() < Duration::from_millis(300) {
        match pty.read(&mut buf) {
            Ok(n) => {
                got.extend_from_slice(&buf[..n]);
                quiet_since = Instant::now();
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(2))
            }
            Err(e) => panic!("{e}"),
        }
    }
    let got = String::from_utf8(got).unwrap();
    let replies: Vec<&str> = got.strip_suffix('#').unwrap_or(&got).split('#').collect();
    assert!(
        replies
            .iter()
            .all(|r| r.len() == 8 && r.as_bytes()[2] == b':'),
        "a reply cut or mixed: {:?}",
        replies.iter().find(|r| r.len() != 8)
    );
    let counters = ask(&mut pty, ":~Cp#", 1);
    let dropped = field(&counters, "replies_dropped=") as usize;
    println!(
        "{SENT} :GR# unread: {} replies kept, {dropped} dropped",
        replies.len()
    );
    assert_eq!(field(&counters, "commands=") as usize, SENT);
    assert!(dropped > 0, "nothing dropped: {counters}");
    assert_eq!(replies.len() + dropped, SENT, "{counters}");
    assert_eq!(ask(&mut pty, ":GR#", 1).len(), 9);
}
