//! The learned model as bytes, to be kept across a power cycle: the stages'
//! periods (with how settled each is), the evidence gates and the search
//! state behind them, and the newest part of the grid with its gear-time
//! origin. Enough that a restored model predicts as the saved one did
//! (`Guider::snapshot`, `Guider::restore`; docs/model.md, "Snapshot and
//! restore").
//!
//! Layout, little-endian, fixed ([`FORMAT_VERSION`] 1):
//!
//! | offset | bytes | field |
//! |---|---|---|
//! | 0 | 4 | magic `MKGS` |
//! | 4 | 2 | format version |
//! | 6 | 2 | stages `N` |
//! | 8 | 2 | cells `M` (at most [`SNAPSHOT_CELLS`]) |
//! | 10 | 2 | reserved, 0 |
//! | 12 | 8 | `f64`: the gear time (the caller's clock) at grid time 0 |
//! | 20 | 40 `N` | per stage: period (s), disagreement, gate, smoothed amplitude ratio (`f64` each), frames since found (`u32`), found (`u8`, 0 or 1), 3 bytes 0 |
//! | 20 + 40 `N` | 8 `M` | per cell, oldest first: gear error, variance (`f32` each); cell `i` is centred at grid time `5 i - 2.5` s |
//! | 20 + 40 `N` + 8 `M` | 4 | CRC-32 (IEEE) of all bytes before it |
//!
//! Cells are `f32` whatever the model's scalar: that is the target's, and
//! an `f64` model loses only digits far below the noise.
//!
//! [`Snapshot::parse`] checks everything before anything is used: length,
//! magic, version, stage count, checksum, and every value's range (finite,
//! in bounds), so that a truncated, garbled or foreign payload is a typed
//! [`SnapshotError`], never a panic and never a model holding NaN or
//! infinity. Nothing is copied: the parsed view reads the bytes.

/// Version of the layout above. A payload of another version is refused
/// ([`SnapshotError::Version`]): the model then starts cold.
pub const FORMAT_VERSION: u16 = 1;
/// Cells kept: the newest 1,000 of the grid (5,000 s, 83 min: more than 11
/// worm periods of 432 s), so that a snapshot of a three-stage model fits
/// the store's ~8 KiB record ([`SNAPSHOT_MAX`]).
pub const SNAPSHOT_CELLS: usize = 1000;
/// Stages of the largest model a snapshot buffer is sized for: the
/// firmware's (`mount::learner::FIRMWARE_STAGES` asserts it fits).
pub const SNAPSHOT_MAX_STAGES: usize = 3;
/// Largest snapshot, of a three-stage model: 8,144 bytes. A model of fewer
/// stages writes less ([`snapshot_len`]).
pub const SNAPSHOT_MAX: usize = snapshot_len(SNAPSHOT_MAX_STAGES, SNAPSHOT_CELLS);

const MAGIC: [u8; 4] = *b"MKGS";
const HEADER_LEN: usize = 20;
const STAGE_LEN: usize = 40;
const CELL_LEN: usize = 8;
const CRC_LEN: usize = 4;
/// Bounds of the values a model can hold (the checks of `parse`): far
/// outside what a mount produces, and inside what the model's arithmetic
/// takes without overflow in `f32`.
const MAX_PERIOD_S: f64 = 1e6;
const MAX_GEAR: f32 = 1e7;
const MAX_VARIANCE: f32 = 1e7;
const MAX_TRACKER_VALUE: f64 = 1e6;

/// Bytes of a snapshot of `stages` stages and `cells` cells.
pub const fn snapshot_len(stages: usize, cells: usize) -> usize {
    HEADER_LEN + STAGE_LEN * stages + CELL_LEN * cells + CRC_LEN
}

/// Where the gear's phase stands after a power cycle, given at restore.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Phase {
    /// Known for every stage (a park whose RA step count was saved, an
    /// absolute encoder): the saved model's gear time = the new gear time +
    /// `gear_time_offset_s`. The model continues where it was.
    Known { gear_time_offset_s: f64 },
    /// The worm's phase known, the other stages' not (a worm-index
    /// sensor): as [`Known`](Self::Known), with an offset that is right
    /// modulo the worm's period. The saved data goes right before the
    /// first frame with the worm's share at its phase; each other stage's
    /// share is put back at the phase the first tenth of a worm period of
    /// new data shows (a stage that cannot be told from the worm's
    /// harmonics over the saved span: the data at the worm's phase, the
    /// others placed by the search of [`Unknown`](Self::Unknown)).
    Worm { gear_time_offset_s: f64 },
    /// Unknown (neither): the periods, stages and gates are kept as the
    /// prior, and the phase is found again by matching the first half worm
    /// period of new data against the saved data.
    Unknown,
}

/// Why a snapshot could not be written or read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SnapshotError {
    /// The output buffer is shorter than the snapshot (`encode`).
    BufferTooSmall { needed: usize },
    /// The payload is shorter or longer than its header says, or shorter
    /// than a header.
    Length { expected: usize, found: usize },
    /// Not a snapshot at all.
    Magic,
    /// Written by another layout.
    Version(u16),
    /// Saved from a model with another number of stages.
    Stages { saved: u16, model: u16 },
    /// More cells than [`SNAPSHOT_CELLS`].
    Cells(u16),
    /// The bytes were changed after they were written.
    Checksum,
    /// A value out of its range (the checksum matched: a writer's bug).
    Invalid(Field),
    /// Learned under a configured worm period far from today's (another
    /// mount or worm; `mount::learner`): refused, the model learns this
    /// one from its prior.
    WormPeriod,
    /// Not now: restored data is still waiting for its phase search (or,
    /// with the phase unknown, for the first frame), so the grid holds it
    /// at no known phase (`Guider::snapshot`). The previous save stays the
    /// one to keep; half a worm period of guiding later the model can be
    /// saved again.
    Placing,
}

impl SnapshotError {
    /// Why, in a few words, for the log.
    pub fn reason(&self) -> &'static str {
        match self {
            SnapshotError::BufferTooSmall { .. } => "buffer too small",
            SnapshotError::Length { .. }
            | SnapshotError::Magic
            | SnapshotError::Version(_)
            | SnapshotError::Stages { .. }
            | SnapshotError::Cells(_) => "another layout",
            SnapshotError::Checksum => "checksum",
            SnapshotError::Invalid(_) => "a value no learning gives",
            SnapshotError::WormPeriod => "learned under another worm period",
            SnapshotError::Placing => "restored data not placed yet",
        }
    }
}

/// The field [`SnapshotError::Invalid`] names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    Reserved,
    Origin,
    Period,
    Disagreement,
    Gate,
    Ratio,
    Found,
    CellGear,
    CellVariance,
    /// The cells' trend: steeper than the gear can change.
    Trend,
    /// The pulse share the learner saves with the model
    /// (`mount::guiding::earned_share::SavedShare`).
    PulseShare,
}

/// One stage as saved.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SavedStage {
    /// Tracked period, seconds.
    pub period_s: f64,
    /// The period tracker's smoothed disagreement (how settled it is).
    pub disagreement: f64,
    /// Evidence gate, 0..=1 (the worm's is 1).
    pub gate: f64,
    /// Smoothed amplitude ratio against the worm (drives the gate).
    pub ratio: f64,
    pub frames_found: u32,
    /// The search has found this stage (always false for the worm).
    pub found: bool,
}

impl SavedStage {
    fn check(&self, stage: usize) -> Result<(), Field> {
        let in_range = |x: f64, hi: f64| x.is_finite() && (0.0..=hi).contains(&x);
        if !(in_range(self.period_s, MAX_PERIOD_S) && self.period_s > 0.0) {
            return Err(Field::Period);
        }
        if !in_range(self.disagreement, MAX_TRACKER_VALUE) {
            return Err(Field::Disagreement);
        }
        let gate_ok = if stage == 0 {
            self.gate == 1.0
        } else {
            in_range(self.gate, 1.0)
        };
        if !gate_ok {
            return Err(Field::Gate);
        }
        if !in_range(self.ratio, MAX_TRACKER_VALUE) {
            return Err(Field::Ratio);
        }
        if stage == 0 && self.found {
            return Err(Field::Found);
        }
        Ok(())
    }
}

/// Whether a cell's values are ones the grid can hold.
fn check_cell(gear: f32, variance: f32) -> Result<(), Field> {
    if !(gear.is_finite() && gear.abs() <= MAX_GEAR) {
        return Err(Field::CellGear);
    }
    if !(variance.is_finite() && variance > 0.0 && variance <= MAX_VARIANCE) {
        return Err(Field::CellVariance);
    }
    Ok(())
}

/// CRC-32 (IEEE 802.3, reflected, as zlib's), bit by bit: no table in
/// flash, and a snapshot is written or read a few times a night. Also the
/// check of the pulse share saved with it (`mount::learner`).
pub(crate) fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            let mask = (crc & 1).wrapping_neg();
            crc = (crc >> 1) ^ (0xEDB8_8320 & mask);
        }
    }
    !crc
}

/// Writes fields in order into a buffer whose length was checked.
struct Writer<'a> {
    out: &'a mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn put(&mut self, bytes: &[u8]) {
        let end = self.at.saturating_add(bytes.len());
        if let Some(dst) = self.out.get_mut(self.at..end) {
            // Byte by byte: `copy_from_slice` keeps a length check's panic.
            for (d, &b) in dst.iter_mut().zip(bytes) {
                *d = b;
            }
        }
        self.at = end;
    }
}

/// Write a snapshot of `stages` and `cells` (gear error and variance,
/// oldest first, at most [`SNAPSHOT_CELLS`]; more are an error) into `out`;
/// returns its length. `origin_s`: the gear time at grid time 0, where
/// the first cell starts.
pub fn encode(
    stages: &[SavedStage],
    origin_s: f64,
    cells: impl ExactSizeIterator<Item = (f32, f32)>,
    out: &mut [u8],
) -> Result<usize, SnapshotError> {
    let n_cells = cells.len();
    let (Ok(n16), Ok(m16)) = (u16::try_from(stages.len()), u16::try_from(n_cells)) else {
        return Err(SnapshotError::Cells(u16::MAX));
    };
    if n_cells > SNAPSHOT_CELLS {
        return Err(SnapshotError::Cells(m16));
    }
    let len = snapshot_len(stages.len(), n_cells);
    let Some(out) = out.get_mut(..len) else {
        return Err(SnapshotError::BufferTooSmall { needed: len });
    };
    let mut w = Writer { out, at: 0 };
    w.put(&MAGIC);
    w.put(&FORMAT_VERSION.to_le_bytes());
    w.put(&n16.to_le_bytes());
    w.put(&m16.to_le_bytes());
    w.put(&[0, 0]);
    w.put(&origin_s.to_le_bytes());
    for s in stages {
        w.put(&s.period_s.to_le_bytes());
        w.put(&s.disagreement.to_le_bytes());
        w.put(&s.gate.to_le_bytes());
        w.put(&s.ratio.to_le_bytes());
        w.put(&s.frames_found.to_le_bytes());
        w.put(&[u8::from(s.found), 0, 0, 0]);
    }
    for (gear, variance) in cells.take(n_cells) {
        w.put(&gear.to_le_bytes());
        w.put(&variance.to_le_bytes());
    }
    let body = len - CRC_LEN;
    let crc = crc32(w.out.get(..body).unwrap_or(&[]));
    w.at = body;
    w.put(&crc.to_le_bytes());
    Ok(len)
}

fn bytes_at<const K: usize>(bytes: &[u8], at: usize) -> [u8; K] {
    bytes
        .get(at..at.saturating_add(K))
        .and_then(|b| b.try_into().ok())
        .unwrap_or([0; K])
}

fn u16_at(bytes: &[u8], at: usize) -> u16 {
    u16::from_le_bytes(bytes_at(bytes, at))
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes_at(bytes, at))
}

fn f32_at(bytes: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(bytes_at(bytes, at))
}

fn f64_at(bytes: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(bytes_at(bytes, at))
}

/// A checked snapshot: a view of its bytes. Every value it returns passed
/// the checks of [`parse`](Self::parse).
#[derive(Clone, Copy, Debug)]
pub struct Snapshot<'a> {
    bytes: &'a [u8],
    stages: usize,
    cells: usize,
}

impl<'a> Snapshot<'a> {
    /// Check `bytes` as the snapshot of a model of `stages` stages.
    pub fn parse(bytes: &'a [u8], stages: usize) -> Result<Self, SnapshotError> {
        let found = bytes.len();
        if found < HEADER_LEN {
            return Err(SnapshotError::Length {
                expected: HEADER_LEN,
                found,
            });
        }
        if bytes_at::<4>(bytes, 0) != MAGIC {
            return Err(SnapshotError::Magic);
        }
        let version = u16_at(bytes, 4);
        if version != FORMAT_VERSION {
            return Err(SnapshotError::Version(version));
        }
        let saved = u16_at(bytes, 6);
        if usize::from(saved) != stages {
            return Err(SnapshotError::Stages {
                saved,
                model: u16::try_from(stages).unwrap_or(u16::MAX),
            });
        }
        let m = u16_at(bytes, 8);
        let cells = usize::from(m);
        if cells > SNAPSHOT_CELLS {
            return Err(SnapshotError::Cells(m));
        }
        let expected = snapshot_len(stages, cells);
        if found != expected {
            return Err(SnapshotError::Length { expected, found });
        }
        let body = expected - CRC_LEN;
        if crc32(bytes.get(..body).unwrap_or(&[])) != u32_at(bytes, body) {
            return Err(SnapshotError::Checksum);
        }
        let snapshot = Self {
            bytes,
            stages,
            cells,
        };
        snapshot.check().map_err(SnapshotError::Invalid)?;
        Ok(snapshot)
    }

    fn check(&self) -> Result<(), Field> {
        if u16_at(self.bytes, 10) != 0 {
            return Err(Field::Reserved);
        }
        if !self.origin_s().is_finite() {
            return Err(Field::Origin);
        }
        for s in 0..self.stages {
            let stage = self.read_stage(s);
            stage.check(s)?;
            let pad = bytes_at::<4>(self.bytes, self.stage_at(s) + 36);
            if pad[0] > 1 {
                return Err(Field::Found);
            }
            if pad[1..] != [0, 0, 0] {
                return Err(Field::Reserved);
            }
        }
        self.cells().try_for_each(|(g, v)| check_cell(g, v))
    }

    /// The gear time (the saving clock) at grid time 0.
    pub fn origin_s(&self) -> f64 {
        f64_at(self.bytes, 12)
    }

    /// Number of stages.
    pub fn stages(&self) -> usize {
        self.stages
    }

    fn stage_at(&self, s: usize) -> usize {
        HEADER_LEN + STAGE_LEN * s
    }

    fn read_stage(&self, s: usize) -> SavedStage {
        let at = self.stage_at(s);
        SavedStage {
            period_s: f64_at(self.bytes, at),
            disagreement: f64_at(self.bytes, at + 8),
            gate: f64_at(self.bytes, at + 16),
            ratio: f64_at(self.bytes, at + 24),
            frames_found: u32_at(self.bytes, at + 32),
            found: self.bytes.get(at + 36) == Some(&1),
        }
    }

    /// Stage `s` (`None` beyond the last).
    pub fn stage(&self, s: usize) -> Option<SavedStage> {
        (s < self.stages).then(|| self.read_stage(s))
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.cells
    }

    /// The cells, oldest first: gear error and variance.
    pub fn cells(&self) -> impl ExactSizeIterator<Item = (f32, f32)> + 'a {
        let bytes = self.bytes;
        let first = HEADER_LEN + STAGE_LEN * self.stages;
        (0..self.cells).map(move |i| {
            let at = first + CELL_LEN * i;
            (f32_at(bytes, at), f32_at(bytes, at + 4))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::SplitMix64;

    fn stages() -> [SavedStage; 2] {
        [
            SavedStage {
                period_s: 431.7,
                disagreement: 0.004,
                gate: 1.0,
                ratio: 0.0,
                frames_found: 0,
                found: false,
            },
            SavedStage {
                period_s: 155.2,
                disagreement: 0.01,
                gate: 0.8,
                ratio: 0.31,
                frames_found: 4000,
                found: true,
            },
        ]
    }

    fn cell(i: usize) -> (f32, f32) {
        (libm::sinf(i as f32 * 0.07) * 9.0, 0.4 + (i % 7) as f32)
    }

    fn payload(cells: usize, out: &mut [u8]) -> usize {
        encode(&stages(), 1234.5, (0..cells).map(cell), out).unwrap()
    }

    #[test]
    fn size_bound_is_what_the_docs_say() {
        assert_eq!(SNAPSHOT_MAX, 8144);
        assert_eq!(snapshot_len(2, SNAPSHOT_CELLS), 8104);
        let mut buf = [0u8; SNAPSHOT_MAX];
        assert_eq!(
            payload(SNAPSHOT_CELLS, &mut buf),
            snapshot_len(2, SNAPSHOT_CELLS)
        );
    }

    #[test]
    fn round_trip() {
        let mut buf = [0u8; SNAPSHOT_MAX];
        let n = payload(700, &mut buf);
        let s = Snapshot::parse(&buf[..n], 2).unwrap();
        assert_eq!(s.origin_s(), 1234.5);
        assert_eq!(s.stage(0), Some(stages()[0]));
        assert_eq!(s.stage(1), Some(stages()[1]));
        assert_eq!(s.stage(2), None);
        assert_eq!(s.cell_count(), 700);
        assert!(s.cells().enumerate().all(|(i, c)| c == cell(i)));
    }

    #[test]
    fn refusals_are_typed() {
        let mut buf = [0u8; SNAPSHOT_MAX];
        let n = payload(10, &mut buf);
        let ok = &buf[..n];
        assert_eq!(
            Snapshot::parse(ok, 1).unwrap_err(),
            SnapshotError::Stages { saved: 2, model: 1 }
        );
        assert!(matches!(
            Snapshot::parse(&ok[..n - 1], 2),
            Err(SnapshotError::Length { .. })
        ));
        let mut other = [0u8; SNAPSHOT_MAX];
        other[..n].copy_from_slice(ok);
        other[4] = 2;
        assert_eq!(
            Snapshot::parse(&other[..n], 2).unwrap_err(),
            SnapshotError::Version(2)
        );
        other[4] = 1;
        other[30] ^= 1;
        assert_eq!(
            Snapshot::parse(&other[..n], 2).unwrap_err(),
            SnapshotError::Checksum
        );
        // A NaN written by a buggy writer, with a correct checksum.
        let mut bad = stages();
        bad[1].gate = f64::NAN;
        let n = encode(&bad, 0.0, (0..3).map(cell), &mut other).unwrap();
        assert_eq!(
            Snapshot::parse(&other[..n], 2).unwrap_err(),
            SnapshotError::Invalid(Field::Gate)
        );
        let n = encode(
            &stages(),
            0.0,
            [(f32::INFINITY, 1.0)].into_iter(),
            &mut other,
        )
        .unwrap();
        assert_eq!(
            Snapshot::parse(&other[..n], 2).unwrap_err(),
            SnapshotError::Invalid(Field::CellGear)
        );
        assert_eq!(
            encode(&stages(), 0.0, (0..10).map(cell), &mut other[..50]),
            Err(SnapshotError::BufferTooSmall {
                needed: snapshot_len(2, 10)
            })
        );
    }

    /// Mutated payloads (bytes flipped, cut, extended, fields rewritten
    /// with the checksum fixed): never a panic, and whatever parses holds
    /// only values in range.
    #[test]
    fn randomized_mutations_never_panic_nor_pass_bad_values() {
        let mut rng = SplitMix64::new(9);
        let mut good = [0u8; SNAPSHOT_MAX];
        let (mut parsed, mut refused) = (0, 0);
        for round in 0..3000 {
            let cells = rng.below(40) as usize;
            let n = payload(cells, &mut good);
            let mut buf = [0u8; SNAPSHOT_MAX + 16];
            buf[..n].copy_from_slice(&good[..n]);
            let mut len = n;
            for _ in 0..1 + rng.below(4) {
                match rng.below(5) {
                    0 => len = rng.below(len as u64 + 1) as usize,
                    1 => len = (len + rng.below(16) as usize).min(buf.len()),
                    2 | 3 => {
                        let i = rng.below(len.max(1) as u64) as usize;
                        buf[i] = rng.next_u64() as u8;
                    }
                    _ => {
                        // Rewrite 4 or 8 bytes with a special value and fix
                        // the checksum: only the range checks stand.
                        let specials = [f64::NAN, f64::INFINITY, -1.0, 0.0, 2.0, 1e300];
                        let v = specials[rng.below(specials.len() as u64) as usize];
                        let i = rng.below(len.saturating_sub(12).max(1) as u64) as usize;
                        if round % 2 == 0 {
                            buf[i..i + 8].copy_from_slice(&v.to_le_bytes());
                        } else {
                            buf[i..i + 4].copy_from_slice(&(v as f32).to_le_bytes());
                        }
                        if len >= 4 {
                            let crc = crc32(&buf[..len - 4]);
                            buf[len - 4..len].copy_from_slice(&crc.to_le_bytes());
                        }
                    }
                }
            }
            match Snapshot::parse(&buf[..len], 2) {
                Ok(s) => {
                    parsed += 1;
                    assert!(s.origin_s().is_finite());
                    for k in 0..2 {
                        assert_eq!(s.stage(k).unwrap().check(k), Ok(()));
                    }
                    assert!(s.cells().all(|(g, v)| check_cell(g, v).is_ok()));
                }
                Err(_) => refused += 1,
            }
        }
        // Both outcomes occur: the mutations reach the range checks.
        assert!(parsed > 0 && refused > 0, "{parsed} {refused}");
    }
}
