//! INDI's own LX200 driver (`indi_lx200generic`, Debian's indi-bin) against
//! `guide-sim mount`: the driver on the pty, our own queries on the TCP
//! port. Headless, as docs/reference.md section 5 describes: `indiserver`
//! with its own `-u` socket, port and a temporary HOME, driven with
//! `indi_setprop`, `indi_getprop` and `indi_eval`.
//!
//! Asserts: the driver connects in under 2 s; after a sync to 6h +10° it
//! reads RA and Dec back; 20 s timed guides W then E (the default mode,
//! `:RG#` + `:Mw#`...`:Qw#`) and N then S ("Use Pulse Cmd" on, `:Mg..#`)
//! move the axes by the guide rate x 20 s within 1 % on the step counters
//! (our `:~P#`), and as the driver's RA and Dec show (Dec within 1 %; RA to
//! the LX200 reply's whole second of time); the model received the frames.
//!
//! Without `indiserver` the test is skipped with a message, unless CI=true.
//! Every process it starts is killed at the end (indiserver's whole process
//! group, its driver included); each external command has a timeout.

mod common;

use common::lx200::{field, Indi, Own};
use common::process::guide_sim;
use mkgp_mount::counters::Counters;
use mkgp_mount::mount::guiding::GuidingCounters;
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The guides' length, ms.
const GUIDE_MS: u64 = 20_000;

/// One timed guide through the driver: what the counters moved (RA steps
/// beyond sidereal tracking, Dec steps) and what the driver's coordinates
/// moved (hours, degrees).
fn guide(
    indi: &Indi,
    own: &mut Own<TcpStream>,
    sidereal_sps: f64,
    prop: &str,
) -> (f64, f64, f64, f64) {
    let (ra0, dec0) = indi.coords();
    let s0 = own.steps();
    indi.set(&format!("{prop}={GUIDE_MS}"));
    // The guide's end, and two of the driver's 1 s polls.
    std::thread::sleep(Duration::from_millis(GUIDE_MS + 2_500));
    let s1 = own.steps();
    let (ra1, dec1) = indi.coords();
    let beyond = (s1.ra - s0.ra) as f64 - sidereal_sps * (s1.t_s - s0.t_s);
    (beyond, (s1.dec - s0.dec) as f64, ra1 - ra0, dec1 - dec0)
}

#[test]
fn indi_lx200generic_connects_syncs_and_guides_the_virtual_mount() {
    if !common::lx200::available() {
        return;
    }
    let dir: PathBuf = std::env::temp_dir().join(format!("mkgp-indi-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let pty = dir.join("pty");

    // The virtual mount: pty for the driver, TCP for us.
    let (mut sim, ready) = guide_sim(&[
        "mount",
        "--case",
        "C1",
        "--no-st4-guider",
        "--tcp",
        "0",
        "--pty",
        pty.to_str().expect("a UTF-8 temporary path"),
    ]);
    let tcp: u16 = ready
        .split("tcp 127.0.0.1:")
        .nth(1)
        .and_then(|s| s.split(',').next()?.trim().parse().ok())
        .unwrap_or_else(|| panic!("no tcp port in {ready:?}"));
    let stream = TcpStream::connect(("127.0.0.1", tcp)).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(5)))
        .unwrap();
    let mut own = Own::new(stream);

    let indi = Indi::start(&dir);
    let connect = indi.connect(&pty);
    eprintln!("indi: connected in {connect:?}");
    assert!(connect < Duration::from_secs(2), "connect took {connect:?}");

    let (ra, dec) = indi.sync(6.0, 10.0);
    eprintln!("indi: after the sync RA {ra} h, Dec {dec} deg");
    assert!((ra - 6.0).abs() < 1.0 / 3600.0 && (dec - 10.0).abs() < 1.0 / 3600.0);

    let cases = host_tests::cases::load(&host_tests::data::cases_file()).unwrap();
    let c1 = cases.iter().find(|c| c.name == "C1").unwrap();
    let mount = host_tests::st4_sim::mount_config(c1).validate().unwrap();
    let sidereal_sps = mount.sidereal_ra_steps_per_s_f64();
    let guide_arcsec = f64::from(mount.guide_rate_arcsec_per_s()) * GUIDE_MS as f64 * 1e-3;
    let ra_steps = guide_arcsec / f64::from(mount.arcsec_per_ra_step());
    let dec_steps = guide_arcsec / f64::from(mount.arcsec_per_dec_step());
    // The driver's RA is whole seconds of time (15 arcsec): a move of
    // guide_arcsec shows to within one of them.
    let ra_hours = guide_arcsec / 15.0 / 3600.0;
    let dec_deg = guide_arcsec / 3600.0;

    let within = |what: &str, got: f64, want: f64, tol: f64| {
        eprintln!(
            "indi: {what}: {got:.4} (want {want:.4}, {:+.3} %)",
            (got / want - 1.0) * 100.0
        );
        assert!((got - want).abs() <= tol, "{what}: {got} want {want}");
    };
    // W then E in the driver's default mode (motion commands).
    for (prop, sign) in [
        ("TELESCOPE_TIMED_GUIDE_WE.TIMED_GUIDE_W", 1.0),
        ("TELESCOPE_TIMED_GUIDE_WE.TIMED_GUIDE_E", -1.0),
    ] {
        let (beyond, dec, dra, ddec) = guide(&indi, &mut own, sidereal_sps, prop);
        within(
            &format!("{prop} RA steps"),
            beyond,
            sign * ra_steps,
            0.01 * ra_steps,
        );
        assert_eq!(dec, 0.0, "{prop} moved Dec");
        // West: a smaller RA.
        within(
            &format!("{prop} driver RA h"),
            dra,
            -sign * ra_hours,
            1.0 / 3600.0,
        );
        assert_eq!(ddec, 0.0);
    }
    // N then S with timed pulses (`:Mg..#`).
    indi.set("Use Pulse Cmd.Off=Off;On=On");
    for (prop, sign) in [
        ("TELESCOPE_TIMED_GUIDE_NS.TIMED_GUIDE_N", 1.0),
        ("TELESCOPE_TIMED_GUIDE_NS.TIMED_GUIDE_S", -1.0),
    ] {
        let (beyond, dec, dra, ddec) = guide(&indi, &mut own, sidereal_sps, prop);
        within(
            &format!("{prop} Dec steps"),
            dec,
            sign * dec_steps,
            0.01 * dec_steps,
        );
        assert!(beyond.abs() < 2.0, "{prop} moved RA by {beyond} steps");
        within(
            &format!("{prop} driver Dec deg"),
            ddec,
            sign * dec_deg,
            0.01 * dec_deg,
        );
        assert!(dra.abs() <= 1.0 / 3600.0 + 1e-9);
    }

    // The four pulses reached the guiding; the RA ones (20 s: dithers)
    // reached the model as dither frames, among the frames it learned.
    let g = own.ask(":~Cg#");
    assert_eq!(field(&g, "ra_pulses"), 2, "{g}");
    assert_eq!(field(&g, "dec_pulses"), 2, "{g}");
    assert_eq!(field(&g, "dithers"), 2, "{g}");
    let l = own.ask(":~Cl#");
    eprintln!("indi: guiding {g} learner {l}");
    assert_eq!(field(&l, "dithers"), 2, "{l}");
    assert!(field(&l, "frames") >= field(&g, "frames") - 4, "{l} {g}");
    // The port motion's counters follow guiding's own.
    let p = own.ask(&format!(":~Cg{}#", GuidingCounters::NAMES.len()));
    assert_eq!(field(&p, "port_pulses"), 4, "{p}");

    drop(indi);
    // SIGTERM: the simulator exits cleanly and removes its link.
    // SAFETY: kill(2) on our own child.
    unsafe { libc::kill(sim.0.id() as libc::pid_t, libc::SIGTERM) };
    let deadline = Instant::now() + Duration::from_secs(5);
    while sim.0.try_wait().unwrap().is_none() {
        assert!(Instant::now() < deadline, "no exit 5 s after SIGTERM");
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(
        std::fs::symlink_metadata(Path::new(&pty)).is_err(),
        "the link is removed"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
