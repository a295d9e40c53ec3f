//! A command's body (between `:` and `#`) to its meaning: one variant per
//! meaning, every number range-checked here, so the interpreter only ever
//! holds values it may act on.

use super::config_value;
use super::coords::{Dec, Ra};
use super::mount_port::{Axis, CounterGroup, GuidePulse, Line, ManualRate};
use super::site::{Date, Latitude, Longitude, TimeOfDay, UtcOffset};
use crate::mount::config::{Field, MountConfig, Value};

/// The rate `:Mn#` and its siblings move at, chosen by `:RG# :RC# :RM#
/// :RS#`. At the guide rate a move is a guide pulse (INDI guides this way by
/// default).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlewRate {
    Guide,
    Manual(ManualRate),
}

/// Questions with an answer and no effect.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Query {
    /// `:GR#`
    Ra,
    /// `:GD#`
    Dec,
    /// `:Gc#`, 12 or 24 hour clock.
    ClockFormat,
    /// `:GM#`
    SiteName,
    /// `:GT#`, the tracking rate in Hz of a 60 Hz synchronous motor.
    TrackingRate,
    /// `:Gt#`
    Latitude,
    /// `:Gg#`
    Longitude,
    /// `:GG#`
    UtcOffset,
    /// `:GL#`
    LocalTime,
    /// `:GC#`
    Date,
    /// `:GU#`, OnStep's status flags.
    Status,
    /// `:GVP#`
    Product,
    /// `:GVN#`
    Version,
    /// `:GVD#`
    BuildDate,
    /// `:GVT#`
    BuildTime,
}

/// Setters, answered `1` (or `0` when their value is refused).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Setting {
    /// `:Sr HH:MM:SS#`, the RA a following `:CM#` syncs to.
    TargetRa(Ra),
    /// `:Sd sDD*MM:SS#`
    TargetDec(Dec),
    /// `:SG sHH.H#`
    UtcOffset(UtcOffset),
    /// `:St sDD*MM#`
    Latitude(Latitude),
    /// `:Sg DDD*MM#`
    Longitude(Longitude),
    /// `:SL HH:MM:SS#`
    LocalTime(TimeOfDay),
    /// `:SC MM/DD/YY#`
    Date(Date),
}

/// Our own commands, `:~...#` (docs/port.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Own {
    /// `:~L#` learning and feed-forward.
    Learning,
    /// `:~S<n>#` stage `n` (0-9) of the model.
    Stage(usize),
    /// `:~C<group>#` or `:~C<group><start>#`, counters from index `start`.
    Counters { group: Counters, start: usize },
    /// `:~P#` the step counters.
    Steps,
    /// `:~F1#` / `:~F0#`
    FeedForward(bool),
    /// `:~R#` forget the model.
    ResetModel,
    /// `:~V#` firmware version and reset cause.
    Firmware,
    /// `:~T1#` / `:~T0#` a telemetry line per guide frame on this port.
    Telemetry(bool),
    /// `:~K#` / `:~K<k>#` the pending configuration, from field `k`.
    ConfigList(usize),
    /// `:~K<name>#` one field of it; `None`: no field has that name.
    ConfigGet(Option<Field>),
    /// `:~K<name>=<value>#`; `None`: the text is no value of the field's
    /// kind.
    ConfigSet { field: Field, value: Option<Value> },
    /// `:~KD#` the pending configuration back to the defaults.
    ConfigDefaults,
    /// `:~KW#` save the pending configuration for the next start.
    ConfigSave,
    /// `:~W#` save the learned model now.
    SaveModel,
}

/// Whose counters `:~C...#` reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Counters {
    /// The port's own ([`super::PortCounters`]).
    Port,
    Mount(CounterGroup),
}

/// What a command means.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    Get(Query),
    Set(Setting),
    /// `:U#`
    TogglePrecision,
    /// `:CM#`
    Sync,
    /// `:MS#`, refused: this mount has no goto.
    Goto,
    /// `:D#`, the distance bars of a goto in progress.
    DistanceBars,
    /// `:Mg[nsew]DDDD#`
    Guide(GuidePulse),
    /// `:RG# :RC# :RM# :RS#`
    SelectRate(SlewRate),
    /// `:Mn# :Ms# :Me# :Mw#`
    Move(Line),
    /// `:Qn# :Qs# :Qe# :Qw#`: stops the axis, whichever way it moves.
    Stop(Axis),
    /// `:Q#`
    StopAll,
    /// `:Te#` / `:Td#` (OnStep's)
    Tracking(bool),
    /// `:hP#`: park here (Meade's, OnStep's).
    Park,
    /// `:hR#`: unpark (OnStep's).
    Unpark,
    Own(Own),
}

/// Why a command was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// Not a command we know: no reply.
    Unknown,
    /// A known command with a malformed or out-of-range value: no reply.
    BadValue,
    /// A setter with a malformed or out-of-range value: replied `0`.
    BadSetting,
}

/// The line a direction letter names: north is Dec+, west is RA+ (the ST4
/// port's convention).
fn line(letter: u8) -> Option<Line> {
    match letter {
        b'n' => Some(Line::DecPlus),
        b's' => Some(Line::DecMinus),
        b'w' => Some(Line::RaPlus),
        b'e' => Some(Line::RaMinus),
        _ => None,
    }
}

/// A guide duration: 1 to 5 decimal digits (INDI writes `%04d`), nothing
/// else, at most [`GuidePulse::MAX_MS`].
fn duration_ms(digits: &[u8]) -> Option<u32> {
    if digits.is_empty() || digits.len() > 5 {
        return None;
    }
    digits.iter().try_fold(0u32, |n, d| {
        d.is_ascii_digit().then(|| n * 10 + u32::from(d - b'0'))
    })
}

pub fn parse(body: &[u8]) -> Result<Command, Refusal> {
    use Command::*;
    let command = match body {
        b"GR" => Get(Query::Ra),
        b"GD" => Get(Query::Dec),
        b"Gc" => Get(Query::ClockFormat),
        b"GM" => Get(Query::SiteName),
        b"GT" => Get(Query::TrackingRate),
        b"Gt" => Get(Query::Latitude),
        b"Gg" => Get(Query::Longitude),
        b"GG" => Get(Query::UtcOffset),
        b"GL" => Get(Query::LocalTime),
        b"GC" => Get(Query::Date),
        b"GU" => Get(Query::Status),
        b"GVP" => Get(Query::Product),
        b"GVN" => Get(Query::Version),
        b"GVD" => Get(Query::BuildDate),
        b"GVT" => Get(Query::BuildTime),
        b"U" => TogglePrecision,
        b"CM" => Sync,
        b"MS" => Goto,
        b"D" => DistanceBars,
        b"RG" => SelectRate(SlewRate::Guide),
        b"RC" => SelectRate(SlewRate::Manual(ManualRate::Centering)),
        b"RM" => SelectRate(SlewRate::Manual(ManualRate::Find)),
        b"RS" => SelectRate(SlewRate::Manual(ManualRate::Max)),
        b"Q" => StopAll,
        b"Te" => Tracking(true),
        b"Td" => Tracking(false),
        b"hP" => Park,
        b"hR" => Unpark,
        [b'M', b'g', rest @ ..] => {
            let [letter, digits @ ..] = rest else {
                return Err(Refusal::BadValue);
            };
            let line = line(*letter).ok_or(Refusal::BadValue)?;
            let ms = duration_ms(digits).ok_or(Refusal::BadValue)?;
            Guide(GuidePulse::new(line, ms).ok_or(Refusal::BadValue)?)
        }
        [b'M', letter] => Move(line(*letter).ok_or(Refusal::Unknown)?),
        [b'Q', letter] => Stop(line(*letter).ok_or(Refusal::Unknown)?.axis()),
        [b'S', which, arg @ ..] => Set(setting(*which, arg)?),
        [b'~', rest @ ..] => Own(own(rest)?),
        _ => return Err(Refusal::Unknown),
    };
    Ok(command)
}

fn setting(which: u8, arg: &[u8]) -> Result<Setting, Refusal> {
    let bad = Refusal::BadSetting;
    Ok(match which {
        b'r' => Setting::TargetRa(Ra::parse(arg).ok_or(bad)?),
        b'd' => Setting::TargetDec(Dec::parse(arg).ok_or(bad)?),
        b'G' => Setting::UtcOffset(UtcOffset::parse(arg).ok_or(bad)?),
        b't' => Setting::Latitude(Latitude::parse(arg).ok_or(bad)?),
        b'g' => Setting::Longitude(Longitude::parse(arg).ok_or(bad)?),
        b'L' => Setting::LocalTime(TimeOfDay::parse(arg).ok_or(bad)?),
        b'C' => Setting::Date(Date::parse(arg).ok_or(bad)?),
        _ => return Err(Refusal::Unknown),
    })
}

fn own(rest: &[u8]) -> Result<Own, Refusal> {
    Ok(match rest {
        b"L" => Own::Learning,
        [b'S', d @ b'0'..=b'9'] => Own::Stage(usize::from(d - b'0')),
        b"P" => Own::Steps,
        b"F1" => Own::FeedForward(true),
        b"F0" => Own::FeedForward(false),
        b"R" => Own::ResetModel,
        b"V" => Own::Firmware,
        b"W" => Own::SaveModel,
        b"T1" => Own::Telemetry(true),
        b"T0" => Own::Telemetry(false),
        [b'C', group, start @ ..] => {
            let group = match group {
                b'p' => Counters::Port,
                b's' => Counters::Mount(CounterGroup::St4),
                b'g' => Counters::Mount(CounterGroup::Guiding),
                b'l' => Counters::Mount(CounterGroup::Learner),
                b'f' => Counters::Mount(CounterGroup::Faults),
                _ => return Err(Refusal::BadValue),
            };
            let start = match start {
                [] => 0,
                // Two digits: no group has a hundred counters.
                [d @ b'0'..=b'9'] => usize::from(d - b'0'),
                [d1 @ b'0'..=b'9', d2 @ b'0'..=b'9'] => {
                    usize::from(d1 - b'0') * 10 + usize::from(d2 - b'0')
                }
                _ => return Err(Refusal::BadValue),
            };
            Own::Counters { group, start }
        }
        [b'K', rest @ ..] => config(rest)?,
        _ => return Err(Refusal::Unknown),
    })
}

/// `:~K...#`: field names are lower case, so `D` and `W` cannot be one.
fn config(rest: &[u8]) -> Result<Own, Refusal> {
    Ok(match rest {
        b"D" => Own::ConfigDefaults,
        b"W" => Own::ConfigSave,
        [] => Own::ConfigList(0),
        [d @ b'0'..=b'9'] => Own::ConfigList(usize::from(d - b'0')),
        [d1 @ b'0'..=b'9', d2 @ b'0'..=b'9'] => {
            Own::ConfigList(usize::from(d1 - b'0') * 10 + usize::from(d2 - b'0'))
        }
        _ => match rest.iter().position(|&b| b == b'=') {
            None => Own::ConfigGet(Field::from_name(rest)),
            Some(eq) => {
                let name = rest.get(..eq).unwrap_or(&[]);
                let text = rest.get(eq + 1..).unwrap_or(&[]);
                let field = Field::from_name(name).ok_or(Refusal::BadSetting)?;
                // The kind of value the field takes, from any configuration.
                let like = MountConfig::default().get(field);
                let value = config_value::parse(text, like);
                Own::ConfigSet { field, value }
            }
        },
    })
}
