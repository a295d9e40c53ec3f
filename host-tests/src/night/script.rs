//! The night's script: what happens when, as a list of timed events, one
//! line each ([`DEFAULT`], the night `guide-sim night` runs).
//!
//! An event happens at its time; the ones that last (a slew, a refocus,
//! clouds) end by themselves, and the next event comes after. Between
//! events the guider does what its section asks: calibrate, then guide
//! through the imaging sequence (a main exposure, the download, a dither
//! and its settling, the next exposure). A section runs from its `Start`
//! to the next `Stop` or `End`; the guider starts each one afresh, with no
//! memory of the one before. The mount is re-pointed only while the guider
//! is stopped.

use mkgp_mount::port::mount_port::ManualRate;

/// What the guider and the imaging sequence do in one section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Section {
    /// A label for the tables (PHD2 knows no target).
    pub target: &'static str,
    /// The target's declination, for the log's header. The simulated
    /// camera measures 1 px per arcsec of RA axis angle whatever the Dec,
    /// so the default targets lie within 10 degrees of the equator, where
    /// a real camera would see the same within 1.5 %.
    pub dec_deg: f64,
    /// The guide camera's exposure, and the time from one frame to the next
    /// (at least the exposure), s.
    pub exposure_s: f64,
    pub interval_s: f64,
    /// The main camera's exposure (a sub), s. After each the guide frames
    /// miss for the download, then the guider dithers and settles.
    pub sub_s: f64,
    /// The download's shortest and longest, s: each is drawn from the seed.
    pub download_s: (f64, f64),
    /// The largest dither, px (RA only; 0: no dither): each one is drawn
    /// from the seed, 0.5 to 1 of it either way.
    pub dither_px: f64,
}

/// A way to re-point the RA axis through the command port.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Way {
    /// RA+ (`:Mw#`): the axis runs ahead of the sky, the gears turn with it.
    West,
    /// RA- (`:Me#`): the RA rate is clamped at 0 (the axis never reverses,
    /// docs/port.md): the axis stands while the sky turns.
    East,
}

/// What happens.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum What {
    /// The guider starts a section afresh: it picks the star, calibrates
    /// (RA west then back east, Dec north then back south), guides, and the
    /// imaging sequence starts once it has settled.
    Start(Section),
    /// The guider stops (`Guiding Ends`).
    Stop,
    /// Re-pointing through the port's manual motion: `:RC#`, `:RM#` or
    /// `:RS#`, then `:Mw#` or `:Me#`, stopped `seconds` later.
    Slew {
        way: Way,
        rate: ManualRate,
        seconds: f64,
    },
    /// Re-pointing by hand with the clutch released: the hour angle moves
    /// by `hours` (west positive), the star with it; no step, the gears
    /// keep their phase.
    Push { hours: f64 },
    /// A meridian flip: the port turns the RA axis 12 h west at its
    /// highest rate and the camera turns over with the tube (the pier side
    /// changes; the guider's RA and Dec sense flip, so the next section
    /// must calibrate again, as every `Start` does).
    Flip,
    /// The star is lost for this many of the guider's frames (DROP rows).
    LoseStar { frames: u32 },
    /// The guider pauses without pulses while the main camera refocuses;
    /// then it settles and imaging goes on.
    Refocus { seconds: f64 },
    /// Clouds hide the star: every frame is a DROP row; imaging stops and
    /// goes on once the guider has settled after them.
    Clouds { seconds: f64 },
    /// The night ends (the guider stops if it runs).
    End,
}

/// The kinds of event, for counting and for the tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Kind {
    Start,
    Stop,
    Slew,
    Push,
    Flip,
    LoseStar,
    Refocus,
    Clouds,
    End,
}

impl Kind {
    pub const ALL: [Kind; 9] = [
        Kind::Start,
        Kind::Stop,
        Kind::Slew,
        Kind::Push,
        Kind::Flip,
        Kind::LoseStar,
        Kind::Refocus,
        Kind::Clouds,
        Kind::End,
    ];
}

impl What {
    pub fn kind(&self) -> Kind {
        match self {
            What::Start(_) => Kind::Start,
            What::Stop => Kind::Stop,
            What::Slew { .. } => Kind::Slew,
            What::Push { .. } => Kind::Push,
            What::Flip => Kind::Flip,
            What::LoseStar { .. } => Kind::LoseStar,
            What::Refocus { .. } => Kind::Refocus,
            What::Clouds { .. } => Kind::Clouds,
            What::End => Kind::End,
        }
    }

    /// How long the event itself lasts, s, given the mount's highest rate
    /// in multiples of the sidereal rate (a flip's duration depends on it).
    pub fn duration_s(&self, max_rate_sidereal: f64) -> f64 {
        match *self {
            What::Slew { seconds, .. } => seconds,
            What::Flip => flip_seconds(max_rate_sidereal),
            What::Refocus { seconds } | What::Clouds { seconds } => seconds,
            _ => 0.0,
        }
    }
}

/// Seconds at the highest rate for the axis to gain 12 h on the sky: it
/// runs at `max_rate_sidereal` while the sky turns at 1.
pub fn flip_seconds(max_rate_sidereal: f64) -> f64 {
    const HALF_TURN_S: f64 = 12.0 * 3600.0 * mkgp_mount::mount::config::SIDEREAL_DAY_S / 86_400.0;
    HALF_TURN_S / (max_rate_sidereal - 1.0)
}

/// An event at its time since the night began.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    pub at_s: f64,
    pub what: What,
}

/// An event at `h`:`min` into the night.
pub const fn at(h: u32, min: u32, what: What) -> Event {
    Event {
        at_s: (h * 3600 + min * 60) as f64,
        what,
    }
}

/// A section with the night's usual imaging: 5-minute subs, downloads
/// of 10-30 s.
const fn section(
    target: &'static str,
    dec_deg: f64,
    exposure_s: f64,
    interval_s: f64,
    dither_px: f64,
) -> Section {
    Section {
        target,
        dec_deg,
        exposure_s,
        interval_s,
        sub_s: 300.0,
        download_s: (10.0, 30.0),
        dither_px,
    }
}

// The sections of the default night (T3 three times: before and after the
// meridian flip, and after the guider's restart).
const T1: Section = section("T1", 2.0, 2.0, 2.0, 3.0);
const T2: Section = section("T2", -5.0, 3.0, 4.5, 5.0);
const T3: Section = Section {
    sub_s: 180.0,
    download_s: (10.0, 20.0),
    ..section("T3", 8.0, 1.0, 1.0, 3.0)
};
const T3_FLIPPED: Section = Section {
    interval_s: 1.5,
    ..T3
};
/// After the restart the user sets 2 s and dithers wide enough that the
/// firmware takes most of them for dithers (a pulse beyond 3 s, 22.6 px).
const T3_RESTARTED: Section = section("T3", 8.0, 2.0, 2.0, 40.0);
/// A frame only every 9.5 s, as some real nights have.
const T4: Section = section("T4", -8.0, 3.0, 9.5, 5.0);
const T5: Section = section("T5", 4.0, 4.0, 5.0, 5.0);

/// A re-pointing through the port, `seconds` long.
pub const fn slew(way: Way, rate: ManualRate, seconds: f64) -> What {
    What::Slew { way, rate, seconds }
}

/// The default night: 6 h 40 min, five targets, seven sections.
pub const DEFAULT: &[Event] = &[
    at(0, 0, What::Start(T1)),
    at(0, 25, What::LoseStar { frames: 5 }),
    at(0, 40, What::Refocus { seconds: 240.0 }),
    at(1, 5, What::Stop),
    at(1, 5, slew(Way::East, ManualRate::Max, 180.0)),
    at(1, 9, What::Start(T2)),
    at(1, 35, What::Clouds { seconds: 1200.0 }),
    at(2, 20, What::Stop),
    at(2, 20, What::Push { hours: -1.5 }),
    at(2, 23, What::Start(T3)),
    at(2, 50, What::Refocus { seconds: 480.0 }),
    at(3, 25, What::Stop),
    at(3, 25, What::Flip),
    at(3, 34, What::Start(T3_FLIPPED)),
    at(4, 15, What::Stop),
    at(4, 16, What::Start(T3_RESTARTED)),
    at(4, 55, What::Stop),
    at(4, 55, slew(Way::West, ManualRate::Max, 30.0)),
    at(4, 57, What::Start(T4)),
    at(5, 40, What::Stop),
    at(5, 40, slew(Way::West, ManualRate::Find, 40.0)),
    at(5, 42, What::Start(T5)),
    at(6, 40, What::End),
];

/// A script that cannot run: the event and why.
#[derive(Debug, Clone, PartialEq)]
pub struct ScriptError {
    pub index: usize,
    pub message: String,
}

impl std::fmt::Display for ScriptError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "script event {}: {}", self.index, self.message)
    }
}

/// Checks that `script` can run on a mount whose highest rate is
/// `max_rate_sidereal`: times in order, each event after the one before
/// has ended, sections started and stopped in turn, the mount re-pointed
/// only while the guider is stopped, section settings physical, one `End`
/// last.
pub fn check(script: &[Event], max_rate_sidereal: f64) -> Result<(), ScriptError> {
    let err = |index: usize, message: String| Err(ScriptError { index, message });
    let mut free_from = 0.0;
    let mut guiding = false;
    for (i, e) in script.iter().enumerate() {
        if e.at_s.is_nan() || e.at_s < free_from {
            return err(i, format!("at {} s, before {free_from} s", e.at_s));
        }
        free_from = e.at_s + e.what.duration_s(max_rate_sidereal);
        let last = i + 1 == script.len();
        match e.what {
            What::Start(s) => {
                if guiding {
                    return err(i, "a start while the guider runs".into());
                }
                let ok = (0.1..=60.0).contains(&s.exposure_s)
                    && s.interval_s >= s.exposure_s
                    && s.sub_s > 0.0
                    && 0.0 <= s.download_s.0
                    && s.download_s.0 <= s.download_s.1
                    && s.dither_px >= 0.0;
                if !ok {
                    return err(i, format!("section {s:?} is not physical"));
                }
                guiding = true;
            }
            What::Stop => {
                if !guiding {
                    return err(i, "a stop without a start".into());
                }
                guiding = false;
            }
            What::Slew { seconds, .. } if seconds.is_nan() || seconds <= 0.0 => {
                return err(i, "a slew needs a duration".into());
            }
            What::Slew { .. } | What::Push { .. } | What::Flip if guiding => {
                return err(i, "re-pointed while the guider runs".into());
            }
            What::LoseStar { .. } | What::Refocus { .. } | What::Clouds { .. } if !guiding => {
                return err(i, "needs a guiding section".into());
            }
            What::End if !last => return err(i, "events after the end".into()),
            _ => {}
        }
        if last && e.what != What::End {
            return err(i, "the script must end with End".into());
        }
    }
    if script.is_empty() {
        return err(0, "an empty script".into());
    }
    Ok(())
}

/// The night's length, s.
pub fn length_s(script: &[Event]) -> f64 {
    script.last().map_or(0.0, |e| e.at_s)
}
