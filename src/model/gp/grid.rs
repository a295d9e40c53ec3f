//! The regular 5 s grid the model infers on, filled as frames arrive.
//!
//! Frames come at irregular times; the model works on cells of 5 s holding
//! the trapezoidal average of the accumulated gear error and of the
//! measurement variance. A cell is emitted once a frame arrives past its end,
//! and never changes afterwards, so no raw history is kept: the cells live in
//! a ring of [`GRID_CELLS`] and the oldest is dropped when it is full.
//!
//! The averaging reproduces the single-kernel reference implementation
//! (INDIGO 3.0, and PHD2 before it) exactly, including two of its quirks that
//! the reference traces depend on:
//! - inside a cell, every trapezoid is taken between the value interpolated
//!   at the cell's start (the *anchor*) and the new sample, not between
//!   consecutive samples;
//! - the first sample opens a cell centred at -2.5 s whose average is half the
//!   sample (the integration starts from zero at -5 s).
//!
//! The first quirk weighs the past: a cell's average stands for the gear
//! error some time before the cell's centre (the anchor carries half the
//! weight, and each anchor is interpolated between the previous one and a
//! sample), by an amount that depends on where the frames fall against the
//! cells' ends (tens of seconds at 2.5 s frames that land just before
//! each end). A PC guider's frames keep one phase against the cells, and
//! the reference's traces are kept to the digit; the mount's frames drift
//! against them, so the mount's guider averages [`Averaging::Exact`]ly:
//! each cell holds the mean over it of the straight lines between
//! consecutive samples, centred on the cell whatever the frames' times,
//! and over pairs of long frames while the loop swings from frame to
//! frame ([`Averaging::Paired`]).
//!
//! Time bookkeeping is `f64`: O(1) work per frame, and it keeps sub-ms
//! precision over a night also where the model runs in `f32`.

use core::mem::MaybeUninit;

use crate::model::in_place::{build, fill, init_fields};
use crate::model::numeric::scalar::Scalar;

mod pairs;
use pairs::Pairs;

/// Number of cells: 2048 x 5 s = 2.8 h of history.
pub const GRID_CELLS: usize = 2048;
/// Width of a cell in seconds.
pub const CELL_S: f64 = 5.0;
/// A cell of at least this variance holds no measurement: frames without
/// one (clouds, a calibration, the gap a re-pointing leaves) are pushed
/// with 10^4.
pub const UNMEASURED_VARIANCE: f64 = 100.0;

/// How a cell's average is taken from the samples in it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Averaging {
    /// The reference's: every trapezoid from the anchor interpolated at the
    /// cell's start (a PC guider's; INDIGO's traces to the digit).
    Reference,
    /// The mean of the straight lines between consecutive samples: the
    /// cell's average stands for its centre (the mount's guider).
    Exact,
    /// [`Exact`](Self::Exact) over pairs of long frames while the loop
    /// swings from frame to frame (`pairs`).
    Paired,
}

/// Outcome of adding a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Push {
    /// Accepted; this many cells were completed by it.
    Accepted { new_cells: u32 },
    /// Time ran backwards, or a value was not finite: ignored.
    Rejected,
    /// The sample came more than a whole window after the previous one: the
    /// grid restarted from it.
    Restarted,
}

/// Ring of completed cells plus the running state of the open cell.
/// RAM: 2 x 2048 scalars (16 KiB in `f32`) plus 168 bytes.
pub struct Grid<S> {
    gear: [S; GRID_CELLS],
    variance: [S; GRID_CELLS],
    /// Ring index of the oldest cell.
    head: usize,
    len: usize,
    /// Cells emitted since the origin; the newest cell has index `emitted - 1`.
    emitted: u64,
    /// Time of the first sample; cell `i` is centred at `origin + 5 i - 2.5`.
    origin: f64,
    started: bool,
    averaging: Averaging,
    // Running state of the open cell, times relative to `origin`.
    cell_end: f64,
    last_time: f64,
    anchor_gear: f64,
    anchor_variance: f64,
    gear_sum: f64,
    variance_sum: f64,
    /// The newest gap in which the gears were not observed (`set_dark`).
    dark: Option<Dark>,
    /// The frames' pairing (`Averaging::Paired`), absolute times.
    pairs: Pairs,
}

/// Cells a placement left without observation: the gears turned through
/// them (a slew) while nobody watched. Absolute cell
/// indices (counted from the origin), so that they keep their meaning as
/// cells are emitted and dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Dark {
    /// The first cell after the gap.
    end: u64,
    cells: u64,
}

impl<S: Scalar> Grid<S> {
    pub fn new(averaging: Averaging) -> Self {
        build(|slot| Self::init(slot, averaging))
    }

    /// [`new`](Self::new) in place (`crate::model::in_place`).
    pub fn init(slot: &mut MaybeUninit<Self>, averaging: Averaging) -> &mut Self {
        init_fields!(slot, Self {
            gear in |f| fill(f, S::ZERO),
            variance in |f| fill(f, S::ZERO),
            head = 0,
            len = 0,
            emitted = 0,
            origin = 0.0,
            started = false,
            averaging = averaging,
            cell_end = 0.0,
            last_time = -CELL_S,
            anchor_gear = 0.0,
            anchor_variance = 0.0,
            gear_sum = 0.0,
            variance_sum = 0.0,
            dark = None,
            pairs = Pairs::NEW,
        })
    }

    /// Empty, as new (with the same averaging), in place: `*self = Self::new()` let LLVM build the
    /// 16 KiB grid in a temporary on the stack first (a 16,640 B frame in
    /// `push`, which overflowed the L475's 20 KiB stack at boot).
    pub fn clear(&mut self) {
        let slot = self as *mut Self;
        // SAFETY: `slot` is this grid, valid for writes and borrowed by
        // nothing else; every field is plain data (nothing to drop), and
        // `init` writes each one before the grid is used again.
        let averaging = self.averaging;
        // SAFETY: as above.
        Self::init(unsafe { &mut *slot.cast::<MaybeUninit<Self>>() }, averaging);
    }

    /// How the cells are averaged.
    pub fn averaging(&self) -> Averaging {
        self.averaging
    }

    /// Number of completed cells held.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Time of the first sample (the grid's origin), if any.
    pub fn origin(&self) -> Option<f64> {
        self.started.then_some(self.origin)
    }

    /// Centre of the `i`-th held cell (0 = oldest), relative to the origin.
    pub fn cell_time(&self, i: usize) -> f64 {
        let index = self.emitted - self.len as u64 + i as u64;
        CELL_S * index as f64 - 0.5 * CELL_S
    }

    /// Gear error and variance of the `i`-th held cell (0 = oldest).
    pub fn cell(&self, i: usize) -> (S, S) {
        let k = (self.head + i) % GRID_CELLS;
        (self.gear[k], self.variance[k])
    }

    /// Add a sample: `time` in seconds (any origin, non-decreasing), the
    /// accumulated gear error and the measurement variance.
    pub fn push(&mut self, time: f64, gear: f64, variance: f64) -> Push {
        let (time, gear, variance) = if self.averaging == Averaging::Paired {
            self.pairs.pair((time, gear, variance))
        } else {
            (time, gear, variance)
        };
        self.push_sample(time, gear, variance)
    }

    /// [`push`](Self::push) after the pairing.
    fn push_sample(&mut self, time: f64, gear: f64, variance: f64) -> Push {
        if !(time.is_finite() && gear.is_finite() && variance.is_finite()) {
            return Push::Rejected;
        }
        if !self.started {
            self.started = true;
            self.origin = time;
        }
        let t = time - self.origin;
        if t < self.last_time {
            return Push::Rejected;
        }
        if t - self.cell_end >= GRID_CELLS as f64 * CELL_S {
            // A jump longer than the window: nothing before it can be used,
            // and emitting every empty cell on the way would take unbounded
            // time. Start again from this sample.
            self.clear();
            self.push_sample(time, gear, variance);
            return Push::Restarted;
        }
        let mut new_cells = 0;
        while t >= self.cell_end {
            let p = (self.cell_end - self.last_time) / (t - self.last_time);
            let g = p * gear + (1.0 - p) * self.anchor_gear;
            let v = p * variance + (1.0 - p) * self.anchor_variance;
            self.add_trapezoid(self.cell_end, g, v);
            self.emit(self.gear_sum / CELL_S, self.variance_sum / CELL_S);
            new_cells += 1;
            self.anchor_gear = g;
            self.anchor_variance = v;
            self.cell_end += CELL_S;
            self.gear_sum = 0.0;
            self.variance_sum = 0.0;
        }
        // The reference folds the stretch from a cell's start to the sample
        // that crossed into it into the next sample's trapezoid.
        if new_cells == 0 || self.averaging != Averaging::Reference {
            self.add_trapezoid(t, gear, variance);
        }
        Push::Accepted { new_cells }
    }

    /// Add the trapezoid from the last sample's time to `t`, between the
    /// anchor and this sample; exact averaging makes the sample the next
    /// trapezoid's anchor.
    fn add_trapezoid(&mut self, t: f64, gear: f64, variance: f64) {
        let w = 0.5 * (t - self.last_time);
        self.gear_sum += w * (self.anchor_gear + gear);
        self.variance_sum += w * (self.anchor_variance + variance);
        self.last_time = t;
        if self.averaging != Averaging::Reference {
            self.anchor_gear = gear;
            self.anchor_variance = variance;
        }
    }

    /// Refill with saved `cells` (gear error and variance, oldest first, at
    /// most [`GRID_CELLS`]): cell `i` is centred at `5 i - 2.5` s from the
    /// origin, and the open cell starts where the last one ends, from the
    /// last cell's gear error and `anchor_variance` (a variance that makes
    /// the cells bridging a gap to the next sample count for little).
    pub fn restore(&mut self, cells: impl Iterator<Item = (S, S)>, anchor_variance: f64) {
        self.clear();
        for (gear, variance) in cells.take(GRID_CELLS) {
            self.emit(gear.to_f64(), variance.to_f64());
            self.anchor_gear = gear.to_f64();
        }
        if self.len == 0 {
            return;
        }
        self.started = true;
        self.cell_end = CELL_S * self.len as f64;
        self.last_time = self.cell_end - CELL_S;
        self.anchor_variance = anchor_variance;
    }

    /// Where the open cell ends, relative to the origin.
    pub fn open_cell_end(&self) -> f64 {
        self.cell_end
    }

    /// Add `by` to the gear error of the held cells `cells` (0 = oldest; a
    /// change of level), and to the open cell's if they reach the newest.
    pub fn shift_gear(&mut self, cells: core::ops::Range<usize>, by: f64) {
        self.shift_gear_with(cells, |_| by);
    }

    /// Add `by(i)` to the gear error of each held cell `i` of `cells` (0 =
    /// oldest); if they reach the newest, the open cell's too, by
    /// `by(len)`.
    pub fn shift_gear_with(&mut self, cells: core::ops::Range<usize>, by: impl Fn(usize) -> f64) {
        let end = cells.end.min(self.len);
        for i in cells.start..end {
            let k = (self.head + i) % GRID_CELLS;
            self.gear[k] += S::from_f64(by(i));
        }
        if end == self.len {
            let by = by(self.len);
            self.anchor_gear += by;
            self.gear_sum += by * (self.last_time - (self.cell_end - CELL_S));
        }
    }

    /// Mark the `cells` cells before held cell `end` (0 = oldest; it may
    /// be the open cell, or one not emitted yet) as not observed: the gears
    /// turned through them unwatched. Replaces an older mark (whose cells
    /// then count as observed again).
    pub fn set_dark(&mut self, end: usize, cells: usize) {
        self.dark = (cells > 0).then(|| Dark {
            end: self.absolute(end),
            cells: cells as u64,
        });
    }

    /// The dark gap as held indices: the first held cell after it (at most
    /// `len`: the open cell, or one still to come) and its length in
    /// cells. None without one, or once every held cell is after it.
    // Out of line: three callers each frame, a few instructions each.
    #[inline(never)]
    pub fn dark(&self) -> Option<(usize, usize)> {
        let dark = self.dark?;
        let oldest = self.absolute(0);
        let end = dark.end.checked_sub(oldest).filter(|&e| e > 0)?;
        Some((end as usize, dark.cells as usize))
    }

    /// How much nearer in observed time each held cell is to the data
    /// after the dark gap: the cells before it by the gap's length.
    pub fn unobserved(&self) -> Unobserved<S> {
        self.dark().map_or(
            Unobserved {
                end: 0,
                seconds: S::ZERO,
            },
            |(end, cells)| Unobserved {
                end,
                seconds: S::from_usize(cells) * S::from_f64(CELL_S),
            },
        )
    }

    /// Absolute index of held cell `i` (0 = oldest): a cell keeps it while
    /// older ones are dropped.
    pub fn absolute(&self, i: usize) -> u64 {
        self.emitted - self.len as u64 + i as u64
    }

    /// The held index of the cell at `absolute` index: 0 for a cell
    /// dropped, `len` for the open cell and any after it.
    pub fn held(&self, absolute: u64) -> usize {
        let i = absolute.saturating_sub(self.absolute(0));
        i.min(self.len as u64) as usize
    }

    /// Drop the `count` oldest cells; the others keep their times.
    pub fn drop_oldest(&mut self, count: usize) {
        let count = count.min(self.len);
        self.head = (self.head + count) % GRID_CELLS;
        self.len -= count;
    }

    /// Insert `count` cells without data (gear interpolated between the
    /// neighbours, `variance`) before held cell `at` (0 = oldest): the cells
    /// before it move back in time by `count` cells, the newer ones keep
    /// their times. The oldest cells are dropped if the ring overflows.
    pub fn insert_gap(&mut self, at: usize, count: usize, variance: f64) {
        let at = at.min(self.len);
        let drop = (self.len + count).saturating_sub(GRID_CELLS).min(at);
        self.head = (self.head + drop) % GRID_CELLS;
        self.len -= drop;
        let at = at - drop;
        let count = count.min(GRID_CELLS - self.len);
        let at_absolute = self.absolute(at);
        if let Some(dark) = &mut self.dark {
            if dark.end >= at_absolute {
                dark.end += count as u64;
            }
        }
        let gear_at = |g: &Self, i: usize| g.gear[(g.head + i) % GRID_CELLS].to_f64();
        let after = if at < self.len {
            gear_at(self, at)
        } else {
            self.anchor_gear
        };
        let before = if at > 0 { gear_at(self, at - 1) } else { after };
        for i in (at..self.len).rev() {
            let (from, to) = (
                (self.head + i) % GRID_CELLS,
                (self.head + i + count) % GRID_CELLS,
            );
            self.gear[to] = self.gear[from];
            self.variance[to] = self.variance[from];
        }
        for j in 0..count {
            let k = (self.head + at + j) % GRID_CELLS;
            let p = (j + 1) as f64 / (count + 1) as f64;
            self.gear[k] = S::from_f64(before + p * (after - before));
            self.variance[k] = S::from_f64(variance);
        }
        self.len += count;
        self.emitted += count as u64;
        let shift = CELL_S * count as f64;
        self.origin -= shift;
        self.cell_end += shift;
        self.last_time += shift;
    }

    fn emit(&mut self, gear: f64, variance: f64) {
        let k = (self.head + self.len) % GRID_CELLS;
        self.gear[k] = S::from_f64(gear);
        self.variance[k] = S::from_f64(variance);
        if self.len < GRID_CELLS {
            self.len += 1;
        } else {
            self.head = (self.head + 1) % GRID_CELLS;
        }
        self.emitted += 1;
    }
}

/// The seconds of gear time a held cell's lags to the data after the
/// dark gap hold that nobody watched (`Grid::unobserved`).
#[derive(Clone, Copy, Debug)]
pub struct Unobserved<S> {
    end: usize,
    seconds: S,
}

impl<S: Scalar> Unobserved<S> {
    /// The unwatched seconds between held cell `i` and the data after
    /// the gap: the gap's length before it, none after.
    pub fn before(&self, i: usize) -> S {
        if i < self.end {
            self.seconds
        } else {
            S::ZERO
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples of a gear error equal to the time, every `step` s from `t`
    /// until `until`; returns the time of the next.
    fn ramp(g: &mut Grid<f64>, mut t: f64, until: f64, step: f64) -> f64 {
        while t < until {
            g.push(t, t, 1.0);
            t += step;
        }
        t
    }

    #[test]
    fn constant_signal_gives_constant_cells() {
        let mut g: Grid<f64> = Grid::new(Averaging::Reference);
        for i in 0..100 {
            g.push(2.0 * i as f64, 3.0, 0.5);
        }
        // Cell 0 is the half-weight start cell; the others average exactly.
        assert!((g.cell(0).0 - 1.5).abs() < 1e-12);
        for i in 1..g.len() {
            assert!((g.cell(i).0 - 3.0).abs() < 1e-12, "cell {i}");
            assert!((g.cell(i).1 - 0.5).abs() < 1e-12);
            assert_eq!(g.cell_time(i), 5.0 * i as f64 - 2.5);
        }
        assert_eq!(g.len(), 40); // samples up to 198 s complete cells ending at 0..195
    }

    /// The largest distance, over the cells after the first, between a
    /// cell's average and its centre's time on a gear error equal to the
    /// time: an origin frame at 0, then frames every `spacing` s from
    /// `first` s.
    fn worst_off_centre(averaging: Averaging, spacing: f64, first: f64) -> f64 {
        let mut g: Grid<f64> = Grid::new(averaging);
        g.push(0.0, 0.0, 1.0);
        ramp(&mut g, first, 2_000.0, spacing);
        (1..g.len())
            .map(|k| (g.cell(k).0 - g.cell_time(k)).abs())
            .fold(0.0, f64::max)
    }

    /// On a gear error that grows linearly with time an exact cell holds
    /// the error at its centre whatever the frames' times. The
    /// reference's cell sits before its centre, by tens of seconds where
    /// the frames land just before each cell's end.
    #[test]
    fn exact_cells_are_centred_whatever_the_frames_times() {
        for (spacing, first) in [(2.5, 2.4), (2.5, 2.5), (1.0, 0.3), (2.03, 2.03), (9.5, 1.0)] {
            let off = worst_off_centre(Averaging::Exact, spacing, first);
            assert!(off < 1e-9, "{spacing} {first}: {off}");
        }
        assert!(worst_off_centre(Averaging::Reference, 2.5, 2.4) > 20.0);
        assert!(worst_off_centre(Averaging::Reference, 2.5, 2.5) < 1.0);
    }

    /// The largest distance between a cell's average and the gear error
    /// at its centre, on a gear error of a tenth of the time plus a swing
    /// of one from frame to frame (an overcorrecting loop's), frames every
    /// `spacing` s, and the cells themselves.
    fn swing(averaging: Averaging, spacing: f64) -> (f64, Grid<f64>) {
        let mut g: Grid<f64> = Grid::new(averaging);
        let mut sign = 1.0;
        for k in 0..500 {
            let t = spacing * k as f64;
            g.push(t, 0.1 * t + sign, 1.0);
            sign = -sign;
        }
        // The first frames come before the steps' correlation is known.
        let off = (4..g.len())
            .map(|k| (g.cell(k).0 - 0.1 * g.cell_time(k)).abs())
            .fold(0.0, f64::max);
        (off, g)
    }

    /// At 4 s frames an exact cell passes the swing on (a period of 8 s,
    /// which 5 s cells see at 13.3 s); pairs cancel it and stay centred.
    /// At 2 s frames, and beyond a cell, pairing changes nothing.
    #[test]
    fn pairs_cancel_the_frame_to_frame_swing_of_long_frames() {
        let (exact, _) = swing(Averaging::Exact, 4.0);
        let (paired, _) = swing(Averaging::Paired, 4.0);
        assert!(exact > 0.2, "{exact}");
        assert!(paired < 1e-12, "{paired}");
        for spacing in [2.0, 6.0] {
            let (_, exact) = swing(Averaging::Exact, spacing);
            let (_, paired) = swing(Averaging::Paired, spacing);
            assert_eq!(exact.len(), paired.len());
            for k in 0..exact.len() {
                assert_eq!(exact.cell(k), paired.cell(k), "{spacing} s, cell {k}");
            }
        }
    }

    #[test]
    fn rejects_backwards_time_and_nan() {
        let mut g: Grid<f64> = Grid::new(Averaging::Reference);
        g.push(10.0, 1.0, 1.0);
        g.push(12.0, 1.0, 1.0);
        assert_eq!(g.push(11.0, 1.0, 1.0), Push::Rejected);
        assert_eq!(g.push(13.0, f64::NAN, 1.0), Push::Rejected);
        assert_eq!(g.push(f64::INFINITY, 1.0, 1.0), Push::Rejected);
    }

    #[test]
    fn ring_keeps_the_newest_cells() {
        let mut g: Grid<f64> = Grid::new(Averaging::Reference);
        ramp(&mut g, 0.0, 12_000.0, 2.0);
        assert_eq!(g.len(), GRID_CELLS);
        // Newest cell: ends at the last boundary passed, holds ~its centre.
        let last = g.len() - 1;
        let c = g.cell_time(last);
        assert!((g.cell(last).0 - c).abs() < 2.0, "{} {}", g.cell(last).0, c);
        assert_eq!(g.cell_time(0), c - 5.0 * (GRID_CELLS - 1) as f64);
    }

    #[test]
    fn a_gap_moves_the_older_cells_back_and_keeps_the_newer() {
        let mut g: Grid<f64> = Grid::new(Averaging::Reference);
        let t = ramp(&mut g, 0.0, 1000.0, 2.0);
        let (len, newest_time) = (g.len(), g.cell_time(g.len() - 1) + g.origin().unwrap());
        let old_time = g.cell_time(10) + g.origin().unwrap();
        g.insert_gap(100, 7, 1e4);
        assert_eq!(g.len(), len + 7);
        assert_eq!(g.cell_time(g.len() - 1) + g.origin().unwrap(), newest_time);
        assert_eq!(g.cell_time(10) + g.origin().unwrap(), old_time - 35.0);
        // The gap: no data, the gear error interpolated across it.
        for i in 100..107 {
            assert_eq!(g.cell(i).1, 1e4);
            assert!(g.cell(99).0 < g.cell(i).0 && g.cell(i).0 < g.cell(107).0);
        }
        assert_eq!(g.cell(107).1, 1.0);
        // The next sample continues where the grid was.
        assert_eq!(g.push(t, t, 1.0), Push::Accepted { new_cells: 1 });
        let newest = g.cell(g.len() - 1);
        g.drop_oldest(107);
        assert_eq!(g.cell(0).1, 1.0);
        assert_eq!(g.cell(g.len() - 1), newest);
        assert_eq!(
            g.cell_time(g.len() - 1) + g.origin().unwrap(),
            newest_time + 5.0
        );
    }

    /// A dark mark stays on its cells as cells come and go, moves with
    /// them when a gap is inserted before it, and is gone once every held
    /// cell is after it, or with the cells.
    #[test]
    fn the_dark_gap_stays_on_its_cells() {
        let mut g: Grid<f64> = Grid::new(Averaging::Reference);
        let t = ramp(&mut g, 0.0, 1000.0, 2.0);
        assert_eq!(g.dark(), None);
        let len = g.len();
        // The gap still to come: it ends at the open cell.
        g.set_dark(len + 40, 40);
        assert_eq!(g.dark(), Some((len + 40, 40)));
        g.set_dark(len, 0);
        assert_eq!(g.dark(), None);
        g.set_dark(150, 40);
        g.drop_oldest(10);
        assert_eq!(g.dark(), Some((140, 40)));
        // New cells leave it where it is; a gap inserted after it too.
        let t = ramp(&mut g, t, 1100.0, 2.0);
        assert_eq!(g.dark(), Some((140, 40)));
        g.insert_gap(141, 5, 1e4);
        assert_eq!(g.dark(), Some((140, 40)));
        // One before it (or at its end) moves it with its cells.
        g.insert_gap(140, 5, 1e4);
        assert_eq!(g.dark(), Some((145, 40)));
        g.insert_gap(3, 5, 1e4);
        assert_eq!(g.dark(), Some((150, 40)));
        g.drop_oldest(149);
        assert_eq!(g.dark(), Some((1, 40)));
        g.drop_oldest(1);
        assert_eq!(g.dark(), None);
        g.set_dark(100, 40);
        ramp(&mut g, t, 20_000.0, 2.0);
        assert_eq!(g.dark(), None);
        g.set_dark(100, 40);
        g.restore([(0.0, 1.0); 200].into_iter(), 1e4);
        assert_eq!(g.dark(), None);
    }

    /// A gap moves the grid's time axis under the open cell: the cells
    /// after it, the open one included, stay centred.
    #[test]
    fn a_gap_keeps_exact_cells_centred() {
        let mut g: Grid<f64> = Grid::new(Averaging::Exact);
        let t = ramp(&mut g, 0.0, 1_000.0, 2.03);
        let open = g.len();
        g.insert_gap(100, 100, 1e4);
        let after = g.len();
        ramp(&mut g, t, 1_100.0, 2.03);
        assert!(g.len() > after);
        for k in after..g.len() {
            let off = g.cell(k).0 - (g.cell_time(k) + g.origin().unwrap());
            assert!(off.abs() < 1e-9, "{k} ({open} before the gap): {off}");
        }
    }

    #[test]
    fn huge_jump_restarts() {
        let mut g: Grid<f64> = Grid::new(Averaging::Reference);
        g.push(0.0, 1.0, 1.0);
        g.push(2.0, 1.0, 1.0);
        assert_eq!(g.push(1e12, 1.0, 1.0), Push::Restarted);
        assert_eq!(g.origin(), Some(1e12));
        assert_eq!(g.len(), 1);
    }
}
