use super::*;
use crate::mount::config::{Mount, MountConfig};
use crate::port::mount_port::StepCounts;
use crate::testing::SplitMix64;

fn mount() -> Mount {
    MountConfig::default().validate().unwrap()
}

fn turn(mount: &Mount) -> i64 {
    i64::from(mount.config().ra_steps_per_worm_turn)
}

const S: u64 = 1_000_000;

/// The caller's handle on its store: a number, to see the one given
/// lent back.
type Storage = u8;
const STORAGE: Storage = 7;

/// A periodic save's step on `storage`, with the last pass `index_pass`.
fn periodic(storage: &mut Storage, index_pass: Option<i64>) -> Save<'_, Storage> {
    Save {
        storage,
        erase: Erase::Defer,
        index_pass,
    }
}

/// A reset asked (once or more) goes before the next frame only.
#[test]
fn a_reset_goes_before_the_next_frame() {
    let mut p = LearningPolicy::<Storage>::without_store();
    assert_eq!(p.frame(), Learn { reset_first: false });
    p.ask_reset();
    p.ask_reset();
    assert_eq!(p.frame(), Learn { reset_first: true });
    assert_eq!(p.frame(), Learn { reset_first: false });
}

/// Saves come every [`SAVE_EVERY_US`] from the start, then from the last
/// save (not from when it was due), at the first frame learned after.
#[test]
fn saves_every_ten_minutes_of_learning() {
    let t0 = 7 * S;
    let mut p = LearningPolicy::with_store(STORAGE, false, WormIndex::new(&mount()), t0);
    assert_eq!(p.learned(t0), None);
    assert_eq!(p.learned(t0 + SAVE_EVERY_US - 1), None);
    assert_eq!(
        p.learned(t0 + SAVE_EVERY_US + 3 * S),
        Some(periodic(&mut { STORAGE }, None))
    );
    assert_eq!(p.learned(t0 + SAVE_EVERY_US + 4 * S), None);
    let t1 = t0 + 2 * SAVE_EVERY_US + 3 * S;
    assert_eq!(p.learned(t1 - 1), None);
    assert_eq!(p.learned(t1), Some(periodic(&mut { STORAGE }, None)));
    // A frame after a long silence saves once, not once per period missed.
    assert_eq!(
        p.learned(t1 + 5 * SAVE_EVERY_US),
        Some(periodic(&mut { STORAGE }, None))
    );
    assert_eq!(p.learned(t1 + 5 * SAVE_EVERY_US + S), None);
}

/// The first pass restores, with the worm's phase from it; bounces and
/// later passes do not; saves and store requests carry the last pass.
#[test]
fn the_first_index_pass_restores() {
    let mount = mount();
    let turn = turn(&mount);
    let mut p = LearningPolicy::with_store(STORAGE, false, WormIndex::new(&mount), 0);
    let restore = p.index_edge(1_000).expect("the first pass restores");
    assert_eq!((*restore.storage, restore.pass.ra_steps), (STORAGE, 1_000));
    let saved = 1_000 + 5 * turn;
    assert_eq!(
        restore.pass.phase(saved),
        Phase::Worm {
            gear_time_offset_s: WormIndex::new(&mount).offset_s(saved, 1_000)
        }
    );
    assert_eq!(p.index_edge(1_002), None, "a bounce");
    assert_eq!(p.index_edge(1_000 + turn), None, "the second pass");
    assert_eq!(
        p.learned(SAVE_EVERY_US),
        Some(periodic(&mut { STORAGE }, Some(1_000 + turn)))
    );
    assert_eq!(
        p.store_request(StoreRequest::Model { port: 1 }),
        StoreStep::Serve {
            storage: &mut { STORAGE },
            request: StoreRequest::Model { port: 1 },
            index_pass: Some(1_000 + turn)
        }
    );
}

/// Parked: the boot's restore had the phase; the passes are only noted.
#[test]
fn parked_the_index_pass_restores_nothing() {
    let mount = mount();
    let mut p = LearningPolicy::with_store(STORAGE, true, WormIndex::new(&mount), 0);
    assert_eq!(p.index_edge(-40), None);
    assert_eq!(
        p.learned(SAVE_EVERY_US),
        Some(periodic(&mut { STORAGE }, Some(-40)))
    );
    let park = StoreRequest::Park(StepCounts { ra: 9, dec: -3 });
    assert_eq!(
        p.store_request(park),
        StoreStep::Serve {
            storage: &mut { STORAGE },
            request: park,
            index_pass: Some(-40)
        }
    );
}

/// Without a store nothing is saved or restored, and a request is
/// answered "not saved" to the port that asked.
#[test]
fn without_a_store_requests_are_refused() {
    let mut p = LearningPolicy::<Storage>::without_store();
    assert_eq!(p.index_edge(0), None);
    assert_eq!(p.learned(100 * SAVE_EVERY_US), None);
    assert_eq!(
        p.store_request(StoreRequest::Model { port: 1 }),
        StoreStep::Refuse(StoreOutcome {
            reply_to: Some(1),
            saved: false,
            counters: StoreCounters::default(),
        })
    );
    assert_eq!(
        p.store_request(StoreRequest::Unpark),
        StoreStep::Refuse(StoreOutcome {
            reply_to: None,
            saved: false,
            counters: StoreCounters::default(),
        })
    );
}

/// Random sequences of events against what the policy promises: a reset
/// before the first frame after it was asked and never otherwise; saves
/// at least [`SAVE_EVERY_US`] apart and none missed; one restore, at the
/// first pass, with a store and unparked; the last pass with every save.
#[test]
fn random_event_sequences_keep_the_promises() {
    let mount = mount();
    let turn = turn(&mount);
    let mut rng = SplitMix64::new(28);
    for run in 0..500 {
        let store = rng.below(4) != 0;
        let parked = rng.below(3) == 0;
        let mut now = rng.below(1 << 40);
        let mut p = if store {
            LearningPolicy::with_store(STORAGE, parked, WormIndex::new(&mount), now)
        } else {
            LearningPolicy::<Storage>::without_store()
        };
        let mut last_save = now;
        let (mut reset_asked, mut edges, mut restores) = (false, 0u32, 0u32);
        let mut last_pass: Option<i64> = None;
        for _ in 0..400 {
            match rng.below(10) {
                0 => {
                    p.ask_reset();
                    reset_asked = true;
                }
                1 | 2 => {
                    // A pass a few turns on or back, or a bounce just by
                    // the last one (just by 0 before any).
                    let pass = last_pass.is_none() || rng.below(2) == 0;
                    let from = last_pass.unwrap_or(0);
                    let at = if pass {
                        let turns = rng.below(7) as i64 - 3;
                        from + if turns == 0 { turn } else { turns * turn }
                    } else {
                        from + rng.below(11) as i64 - 5
                    };
                    let restore = p.index_edge(at);
                    let first = edges == 0;
                    edges += 1;
                    if store && pass {
                        last_pass = Some(at);
                    }
                    match restore {
                        Some(r) => {
                            restores += 1;
                            assert!(store && !parked && first, "run {run}");
                            assert_eq!(r.pass.ra_steps, at, "run {run}");
                        }
                        None => assert!(!(store && !parked && first), "run {run}"),
                    }
                }
                3 => {
                    let request = match rng.below(3) {
                        0 => StoreRequest::Model {
                            port: rng.below(2) as usize,
                        },
                        1 => StoreRequest::Park(StepCounts { ra: 1, dec: 2 }),
                        _ => StoreRequest::Unpark,
                    };
                    match p.store_request(request) {
                        StoreStep::Serve {
                            storage,
                            request: r,
                            index_pass,
                        } => {
                            assert!(store, "run {run}");
                            assert_eq!(*storage, STORAGE, "run {run}");
                            assert_eq!((r, index_pass), (request, last_pass), "run {run}");
                        }
                        StoreStep::Refuse(outcome) => {
                            assert!(!store, "run {run}");
                            assert_eq!(outcome.reply_to, request.reply_to(), "run {run}");
                            assert!(!outcome.saved, "run {run}");
                        }
                    }
                }
                _ => {
                    assert_eq!(
                        p.frame().reset_first,
                        core::mem::take(&mut reset_asked),
                        "run {run}"
                    );
                    // Frames a few seconds apart, sometimes after a long
                    // silence, sometimes at the same microsecond.
                    now += match rng.below(20) {
                        0 => 0,
                        1 => rng.below(3 * SAVE_EVERY_US),
                        _ => rng.below(5 * S),
                    };
                    match p.learned(now) {
                        Some(save) => {
                            assert!(store, "run {run}");
                            assert!(now - last_save >= SAVE_EVERY_US, "run {run}");
                            assert_eq!(save, periodic(&mut { STORAGE }, last_pass), "run {run}");
                            last_save = now;
                        }
                        None => assert!(
                            !store || now - last_save < SAVE_EVERY_US,
                            "run {run}: a save missed"
                        ),
                    }
                }
            }
        }
        assert!(restores <= 1, "run {run}");
    }
}
