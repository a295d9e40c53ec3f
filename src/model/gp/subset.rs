//! The subset of the grid an inference uses: the [`SUBSET`] cells most
//! correlated with the prediction point under the full kernel.

use core::cell::Cell;
use core::cmp::Ordering;

use crate::model::gp::grid::{Grid, CELL_S, UNMEASURED_VARIANCE};
use crate::model::gp::kernel::Kernel;
use crate::model::gp::SUBSET;
use crate::model::numeric::scalar::Scalar;

/// The members of one inference: held-cell indices, ascending.
pub(super) struct Subset {
    cells: [u16; SUBSET],
    n: usize,
}

impl Subset {
    pub(super) fn new() -> Self {
        Self {
            cells: [0; SUBSET],
            n: 0,
        }
    }

    pub(super) fn clear(&mut self) {
        self.n = 0;
    }

    pub(super) fn cells(&self) -> &[u16] {
        self.cells.get(..self.n).unwrap_or(&[])
    }

    /// Choose the cells with the largest full-kernel covariance to `centre`;
    /// of equal covariances the older cell wins (NaN counts as the lowest).
    /// `measured_only`: a cell without a measurement
    /// ([`UNMEASURED_VARIANCE`]) counts as the lowest too. Its variance
    /// gives it next to no weight in the prediction, but the short kernels
    /// rank it high when it lies near `centre`: after a re-pointing or
    /// clouds, the gap's cells took most of the places and left out the
    /// measured data that knows the phase.
    /// `scratch` must hold two covariances per cell (`2 * grid.len()`);
    /// returns false otherwise.
    ///
    /// The members are exactly the `SUBSET` first cells in the order
    /// (covariance descending, cell ascending), found without a heap: the
    /// covariances go to `scratch`, the `SUBSET`-th of them is found in a
    /// copy ([`nth`], O(cells)), and one pass in cell order takes every cell
    /// above that threshold and, of the cells equal to it, the oldest ones,
    /// ascending as they come.
    // Inline in `Gp::infer`, its one caller, as before the split: out of
    // line the Cortex-M4 bench (guide-sim bench) measured more instructions
    // a frame.
    #[inline(always)]
    pub(super) fn select<S: Scalar, const N: usize>(
        &mut self,
        grid: &Grid<S>,
        kernel: &Kernel<S, N>,
        centre: f64,
        scratch: &mut [S],
        measured_only: bool,
    ) -> bool {
        let total = grid.len();
        let k = total.min(SUBSET);
        self.n = k;
        if total <= SUBSET {
            for (i, c) in self.cells.iter_mut().enumerate().take(total) {
                *c = i as u16;
            }
            return true;
        }
        let Some((cov, rest)) = scratch.split_at_mut_checked(total) else {
            return false;
        };
        let Some(copy) = rest.get_mut(..total) else {
            return false;
        };
        let centre_s = S::from_f64(centre);
        // Cell times in S, stepping 5 s from the oldest: exact (multiples of
        // 2.5 s; in f32 up to 2^23 s), so each equals
        // `S::from_f64(grid.cell_time(j))` bit for bit without the software
        // f64 arithmetic per cell on the target.
        let step = S::from_f64(CELL_S);
        let unmeasured = S::from_f64(UNMEASURED_VARIANCE);
        // The centre lies after a dark gap: the cells before it are that
        // much nearer in observed time.
        let unobserved = grid.unobserved();
        let mut t_j = S::from_f64(grid.cell_time(0));
        for (j, c) in cov.iter_mut().enumerate() {
            *c = if measured_only && grid.cell(j).1 >= unmeasured {
                S::from_f64(f64::NAN)
            } else {
                let d = centre_s - t_j;
                kernel.full_observed(d, d - unobserved.before(j))
            };
            t_j += step;
        }
        copy.copy_from_slice(cov);
        let Some((threshold, above)) = nth(copy, k - 1, descending) else {
            return false;
        };
        let mut ties = k - above;
        let mut m = 0;
        for (j, c) in cov.iter().enumerate() {
            let take = match descending(c, &threshold) {
                Ordering::Less => true,
                Ordering::Equal if ties > 0 => {
                    ties -= 1;
                    true
                }
                _ => false,
            };
            if take {
                if let Some(slot) = self.cells.get_mut(m) {
                    *slot = j as u16;
                }
                m += 1;
            }
        }
        true
    }
}

/// The element at `k` of `v` sorted by `order` (a total order) and the
/// number of elements strictly before it, by quickselect; `v` is permuted.
/// None only if `k >= v.len()`.
///
/// Each round takes the middle element as the pivot and moves the elements
/// before it to the front (Lomuto), counting those equal to it; the side
/// that holds `k` is the next round's. Written with `Cell`s and iterators,
/// unlike core's `select_nth_unstable_by`, so that no bounds check and no
/// panic is left in the firmware. The cells come in time order, in which the
/// covariance mostly rises towards the centre, so the middle is a fair
/// pivot.
fn nth<S: Copy>(
    mut v: &mut [S],
    mut k: usize,
    order: impl Fn(&S, &S) -> Ordering,
) -> Option<(S, usize)> {
    // Elements dropped in earlier rounds as before every one left.
    let mut dropped_before = 0;
    loop {
        let pivot = *v.get(v.len() / 2)?;
        let cells = Cell::from_mut(&mut *v).as_slice_of_cells();
        let mut front = cells.iter();
        let (mut before, mut equal) = (0, 0);
        for x in cells {
            match order(&x.get(), &pivot) {
                Ordering::Less => {
                    if let Some(f) = front.next() {
                        let y = f.get();
                        f.set(x.get());
                        x.set(y);
                    }
                    before += 1;
                }
                Ordering::Equal => equal += 1,
                Ordering::Greater => {}
            }
        }
        if k < before {
            v = core::mem::take(&mut v).get_mut(..before)?;
        } else if k < before + equal {
            return Some((pivot, dropped_before + before));
        } else {
            // The elements after the pivot, compacted to the front of the
            // rest (their order does not matter).
            let rest = core::mem::take(&mut v).get_mut(before..)?;
            let cells = Cell::from_mut(&mut *rest).as_slice_of_cells();
            let mut front = cells.iter();
            let mut after = 0;
            for x in cells {
                if order(&x.get(), &pivot) == Ordering::Greater {
                    if let Some(f) = front.next() {
                        f.set(x.get());
                    }
                    after += 1;
                }
            }
            dropped_before += before + equal;
            k -= before + equal;
            v = rest.get_mut(..after)?;
        }
    }
}

/// Covariance descending, NaN last: a total order.
fn descending<S: Scalar>(a: &S, b: &S) -> Ordering {
    if *a > *b {
        Ordering::Less
    } else if *a < *b {
        Ordering::Greater
    } else if *a == *b || (is_nan(*a) && is_nan(*b)) {
        Ordering::Equal
    } else if is_nan(*a) {
        Ordering::Greater
    } else {
        Ordering::Less
    }
}

fn is_nan<S: Scalar>(x: S) -> bool {
    x.partial_cmp(&x).is_none()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::gp::grid::{Averaging, GRID_CELLS};
    use std::vec::Vec;

    /// The subset by sorting every cell: (measured first if
    /// `measured_only`, covariance descending among the measured, cell
    /// ascending), the first `SUBSET`, ascending.
    fn reference<S: Scalar, const N: usize>(
        grid: &Grid<S>,
        kernel: &Kernel<S, N>,
        centre: f64,
        measured_only: bool,
    ) -> Vec<u16> {
        let centre_s = S::from_f64(centre);
        let mut all: Vec<(bool, S, u16)> = (0..grid.len())
            .map(|j| {
                let t = S::from_f64(grid.cell_time(j));
                let dark = measured_only && grid.cell(j).1.to_f64() >= UNMEASURED_VARIANCE;
                let cov = if dark {
                    S::ZERO
                } else {
                    kernel.full(centre_s - t)
                };
                (dark, cov, j as u16)
            })
            .collect();
        all.sort_by(|a, b| {
            a.0.cmp(&b.0)
                .then(b.1.partial_cmp(&a.1).unwrap())
                .then(a.2.cmp(&b.2))
        });
        let mut cells: Vec<u16> = all.iter().take(SUBSET).map(|x| x.2).collect();
        cells.sort();
        cells
    }

    fn grid<S: Scalar>(seconds: f64) -> Grid<S> {
        let mut g = Grid::new(Averaging::Reference);
        let mut t = 0.0;
        while t < seconds {
            g.push(t, libm::sin(t / 50.0), 0.5);
            t += 2.0;
        }
        g
    }

    fn check<S: Scalar, const N: usize>(grid: &Grid<S>, kernel: &Kernel<S, N>, centre: f64) {
        for measured_only in [false, true] {
            let mut subset = Subset::new();
            let mut scratch = [S::ZERO; 2 * GRID_CELLS];
            assert!(subset.select(grid, kernel, centre, &mut scratch, measured_only));
            let want = reference(grid, kernel, centre, measured_only);
            assert_eq!(subset.cells(), &want[..], "centre {centre}");
        }
    }

    /// Measured from 0 to `gap_from` s, nothing measured (variance 10^4)
    /// for `gap_s`, measured again for `after_s`.
    fn gapped<S: Scalar>(gap_from: f64, gap_s: f64, after_s: f64) -> Grid<S> {
        let mut g = Grid::new(Averaging::Reference);
        let mut t = 0.0;
        while t < gap_from + gap_s + after_s {
            let dark = (gap_from..gap_from + gap_s).contains(&t);
            g.push(t, libm::sin(t / 50.0), if dark { 1e4 } else { 0.5 });
            t += 2.0;
        }
        g
    }

    #[test]
    fn nth_is_the_sorted_element_with_ties_and_nan() {
        // Many repeats and some NaNs, scrambled.
        let values: Vec<f64> = (0..300u32)
            .map(|i| match (i * 7919) % 23 {
                5 => f64::NAN,
                r => f64::from(r % 11),
            })
            .collect();
        let mut sorted = values.clone();
        sorted.sort_by(descending);
        for k in 0..values.len() {
            let mut v = values.clone();
            let (x, before) = nth(&mut v, k, descending).unwrap();
            assert_eq!(descending(&x, &sorted[k]), Ordering::Equal, "k {k}");
            let want = sorted
                .iter()
                .filter(|&s| descending(s, &x) == Ordering::Less)
                .count();
            assert_eq!(before, want, "k {k}");
        }
        assert!(nth(&mut values.clone(), values.len(), descending::<f64>).is_none());
    }

    #[test]
    fn select_is_the_sorted_top_subset() {
        let g64 = grid::<f64>(6000.0);
        let g32 = grid::<f32>(6000.0);
        let k1: Kernel<f64, 1> = Kernel::new(&[288.0], &[1.0]);
        let k2: Kernel<f64, 2> = Kernel::new(&[288.0, 110.0], &[1.0, 0.7]);
        let k1f: Kernel<f32, 1> = Kernel::new(&[288.0], &[1.0]);
        let k2f: Kernel<f32, 2> = Kernel::new(&[432.0, 155.0], &[1.0, 1.0]);
        let newest = g64.cell_time(g64.len() - 1);
        for centre in [newest + 2.5, newest + 3.7, newest + 40.0, newest - 1000.0] {
            check(&g64, &k1, centre);
            check(&g64, &k2, centre);
            check(&g32, &k1f, centre);
            check(&g32, &k2f, centre);
        }
        // Centred between two cells in the middle: every covariance comes
        // twice (k(d) = k(-d)), and of each pair the older cell must win.
        let mid = g64.cell_time(600) + 2.5;
        check(&g64, &k1, mid);
        check(&g64, &k2, mid);
        check(&g32, &k1f, mid);
        check(&g32, &k2f, mid);
        // Few cells: all of them.
        let small = grid::<f64>(300.0);
        check(&small, &k1, 310.0);
    }

    /// After a re-pointing's gap of 2,000 s and a minute of new data, the
    /// short kernels rank the gap's cells near the frame above the older
    /// data: every cell of the subset is measured only if asked.
    #[test]
    fn a_gaps_cells_take_no_place_when_measured_only() {
        let g = gapped::<f32>(4000.0, 2000.0, 60.0);
        let k: Kernel<f32, 2> = Kernel::new(&[288.0, 110.0], &[1.0, 1.0]);
        let centre = g.cell_time(g.len() - 1) + 2.5;
        check(&g, &k, centre);
        let dark = |measured_only| {
            let mut subset = Subset::new();
            let mut scratch = [0.0; 2 * GRID_CELLS];
            assert!(subset.select(&g, &k, centre, &mut scratch, measured_only));
            subset
                .cells()
                .iter()
                .filter(|&&j| g.cell(usize::from(j)).1 >= 100.0)
                .count()
        };
        assert_eq!(dark(true), 0);
        assert!(dark(false) > SUBSET / 2, "{}", dark(false));
        // Fewer measured cells than places: the unmeasured fill the rest.
        let mostly_dark = gapped::<f32>(100.0, 5000.0, 0.0);
        check(&mostly_dark, &k, 5100.0);
    }
}
