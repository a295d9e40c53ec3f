//! `guide-sim view` against bad input, from the one test RNG
//! (`mkgp_mount::testing::SplitMix64`, fixed seed): lines written by the
//! firmware's own telemetry writer, then mutated (bit flips, truncation,
//! duplication, deletion, random bytes, letters in digits, huge numbers,
//! lines run together), fed in random chunks through the view's stream
//! splitter, parser and session. Nothing may panic; an unmutated line must
//! read back exactly; memory stays bounded; the page's state is still made.
//! `MKGP_RANDOMIZED_SCALE=K` runs K times as many lines.

use host_tests::view::session::{Session, MAX_FRAMES, MAX_LOG};
use host_tests::view::stream::{Expect, Item, Stream, MAX_LINE};
use host_tests::view::{state, telemetry};
use mkgp_mount::port::mount_port::Stage;
use mkgp_mount::port::reply::Reply;
use mkgp_mount::port::telemetry::{write, TelemetryFrame};
use mkgp_mount::testing::SplitMix64;

use host_tests::noise::randomized_scale as scale;

/// A valid line as the firmware writes it, and what it says.
fn valid(rng: &mut SplitMix64, t_ms: u64) -> (Vec<u8>, telemetry::Telemetry) {
    let i32_ = |rng: &mut SplitMix64, r: u64| (rng.below(2 * r + 1) as i64 - r as i64) as i32;
    let stages: Vec<Stage> = (0..rng.below(4))
        .map(|_| Stage {
            period_ms: rng.below(4_000_000) as u32,
            amplitude_mas: 0,
            gate_permille: rng.below(1001) as u16,
        })
        .collect();
    let f = TelemetryFrame {
        time_ms: t_ms,
        gear_time_ms: t_ms.saturating_sub(rng.below(1000)),
        kind: b"mfud"[rng.below(4) as usize],
        observation_mas: i32_(rng, 100_000),
        pulse_mas: i32_(rng, 10_000),
        applied_mas: i32_(rng, 100_000),
        prediction_mas: i32_(rng, 5_000),
        feed_forward_mas_per_s: i32_(rng, 2_000),
        learned_permille: rng.below(1001) as u16,
        stages: &stages,
    };
    let mut r = Reply::new();
    write(&f, &mut r);
    let want = telemetry::Telemetry {
        t_ms: f.time_ms,
        gear_ms: f.gear_time_ms,
        kind: f.kind,
        obs_mas: f.observation_mas.into(),
        pulse_mas: f.pulse_mas.into(),
        applied_mas: f.applied_mas.into(),
        pred_mas: f.prediction_mas.into(),
        ff_mas_s: f.feed_forward_mas_per_s.into(),
        learn_pm: f.learned_permille,
        stages: stages
            .iter()
            .map(|s| telemetry::Stage {
                period_ms: s.period_ms,
                amp_mas: s.amplitude_mas.into(),
                gate_pm: s.gate_permille,
            })
            .collect(),
    };
    (r.as_bytes().to_vec(), want)
}

/// One random mutation of `line`.
fn mutate(rng: &mut SplitMix64, line: &mut Vec<u8>) {
    let n = line.len().max(1) as u64;
    let at = rng.below(n) as usize;
    match rng.below(9) {
        0 => {
            if let Some(b) = line.get_mut(at) {
                *b ^= 1 << rng.below(8);
            }
        }
        1 => line.truncate(at),
        2 => {
            let end = (at + 1 + rng.below(20) as usize).min(line.len());
            let piece = line[at..end].to_vec();
            line.splice(at..at, piece);
        }
        3 => {
            let end = (at + 1 + rng.below(20) as usize).min(line.len());
            line.drain(at..end);
        }
        4 => line.insert(at.min(line.len()), rng.below(256) as u8),
        5 => {
            if let Some(b) = line.get_mut(at).filter(|b| b.is_ascii_digit()) {
                *b = b'a' + rng.below(26) as u8;
            }
        }
        6 => {
            let huge = b"99999999999999999999999";
            line.splice(at..at, huge.iter().copied());
        }
        // Lines run together: the '#' lost.
        7 => line.retain(|&b| b != b'#'),
        _ => line.extend((0..rng.below(40)).map(|_| rng.below(256) as u8)),
    }
}

#[test]
fn mutated_telemetry_never_panics_and_memory_stays_bounded() {
    let mut rng = SplitMix64::new(11);
    let mut stream = Stream::default();
    let mut session = Session::new("test".into());
    let lines = 2_000_000 * scale();
    let (mut exact, mut refused, mut accepted_mutants) = (0u64, 0u64, 0u64);
    for i in 0..lines {
        let (mut line, want) = valid(&mut rng, i * 2000);
        let mutated = rng.below(3) != 0;
        if mutated {
            for _ in 0..1 + rng.below(3) {
                mutate(&mut rng, &mut line);
            }
        }
        let text = String::from_utf8_lossy(&line);
        match telemetry::parse(&text) {
            Ok(t) if !mutated => {
                assert_eq!(t, want, "{text}");
                exact += 1;
            }
            Ok(_) => accepted_mutants += 1,
            Err(_) if !mutated => panic!("a valid line refused: {text}"),
            Err(_) => refused += 1,
        }
        // Now as bytes on a port, in random chunks, with a query's reply
        // awaited now and then.
        if rng.below(50) == 0 {
            stream.expect(if rng.below(2) == 0 {
                Expect::Hash
            } else {
                Expect::Byte
            });
        }
        let mut rest = &line[..];
        while !rest.is_empty() {
            let k = (1 + rng.below(64) as usize).min(rest.len());
            let (chunk, tail) = rest.split_at(k);
            rest = tail;
            stream.push(chunk, &mut |item| match item {
                Item::Telemetry(l) => session.line(&l),
                Item::Garbled(g) => session.bad_line(&g, "cut"),
                Item::Reply(_) | Item::Garbage(_) => {}
            });
            assert!(stream.held() <= MAX_LINE + 64);
        }
        if i % (lines / 8) == 0 {
            // The page's state is made from whatever was accepted.
            let json = state::json(&session);
            assert!(json.starts_with('{') && json.ends_with('}'));
        }
    }
    assert!(session.frames.len() <= MAX_FRAMES);
    assert!(session.log.len() <= MAX_LOG);
    // A long valid session stops at the cap.
    for i in 0..MAX_FRAMES as u64 + 100 {
        let (line, _) = valid(&mut rng, lines * 2000 + i * 2000);
        session.line(&String::from_utf8_lossy(&line));
    }
    assert_eq!(session.frames.len(), MAX_FRAMES);
    assert!(session.lines_ok > 0 && session.lines_bad > 0);
    // Most mutants are refused; the valid third all read back exactly.
    assert!(exact > lines / 4, "{exact} of {lines}");
    assert!(
        refused > 3 * accepted_mutants,
        "{refused} refused, {accepted_mutants} accepted"
    );
    println!(
        "{lines} lines: {exact} valid read back exactly, {refused} mutants refused, \
         {accepted_mutants} mutants still well-formed; session kept {} frames, {} bad",
        session.frames.len(),
        session.lines_bad
    );
}
