//! ST4 input logic: what the raw edges of the four guide lines mean.
//!
//! The hal timestamps every edge of the four lines (RA+, RA-, Dec+, Dec-;
//! active low, so "asserted" is the low level) and feeds it to
//! [`St4::edge`]; it calls [`St4::poll`] until `None` after every edge and
//! whenever [`St4::next_deadline_us`] comes due. Out come [`St4Event`]s:
//! the start and the end of each axis' guide pulse, with the times of the
//! edges that made them.
//!
//! **Debounce, per line.** A level change is confirmed only when the line
//! keeps its new level for `glitch_us`; a change undone sooner (an
//! assert-release pair, or a release-assert dropout inside a pulse) is a
//! glitch: counted in [`St4Counters::glitches`] and otherwise ignored. Contact
//! bounce is thus a few glitches and then a clean edge. A confirmed edge
//! takes effect at its own time (the pulse starts at the assert edge's time
//! and ends at the release edge's time), so the debounce delays the events
//! by `glitch_us` but does not shorten or lengthen the pulses.
//!
//! **Pulses, per axis.** A confirmed assert on an idle axis starts a pulse
//! ([`St4Event::PulseStart`]); the confirmed release of that line ends it
//! ([`St4Event::PulseEnd`]).
//! - *Both lines* of an axis asserted (confirmed): the axis' pulse ends at
//!   the time of the second line's edge, and no pulse is accepted on the
//!   axis until both lines are released. Counted once per such episode in
//!   `both_lines`. (A stuck line counts as asserted.)
//! - *Cap*: a pulse still asserted `pulse_cap_us` after its start is cut:
//!   `PulseEnd` at start + cap, counted in `capped`. A pulse of exactly the
//!   cap ends normally. The line, still asserted, is then *stuck*: counted
//!   once in `stuck` and ignored until it is released (its release produces
//!   no event). Every cut leaves its line stuck, so `capped` and `stuck`
//!   move together; `stuck` is the number of lines found still asserted at
//!   the cap, `capped` the number of pulses cut.
//!
//! **Time.** Timestamps are `u64` microseconds (embassy-time's 1 MHz tick).
//! An edge older than the previous edge is out of order: ignored and counted
//! in `out_of_order`. An edge older than the latest `poll` time but not
//! older than the previous edge (an edge that waited in a channel while the
//! task polled) takes effect at that poll time, so that nothing already
//! decided changes (its events are late by the delivery delay). A `poll`
//! time older than the latest time seen is harmless: it advances nothing.
//! An edge that repeats the line's current raw level (an edge in between was
//! missed) is ignored. Edges at the very time a cut is due come first (a
//! pulse of exactly the cap ends normally) unless a poll at that time came
//! before them, so the events and counters do not depend on the order in
//! which edges of the same microsecond arrive (with `glitch_us` 0 each edge
//! still takes effect as it arrives).
//!
//! **Events** wait in a fixed queue (`heapless::Deque`) of
//! [`ST4_QUEUE_LEN`] events. When it is full, the oldest event is dropped and counted in
//! `dropped`; nothing panics. Poll after every edge and nothing is ever
//! dropped: one `edge` or `poll` makes at most a few events. Per axis the
//! events alternate `PulseStart`, `PulseEnd` (unless dropped) and their
//! times never decrease; between the two axes the order of the events
//! follows the time at which they were confirmed.
//!
//! RAM: the queue (16 bytes an event, plus its indices), 4 lines, 2 axes,
//! the counters and two times; the unit test `size` pins the total.

use heapless::Deque;

/// A mount axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    Ra,
    Dec,
}

/// The direction of a guide pulse on its axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    Plus,
    Minus,
}

impl Direction {
    /// +1 for Plus, -1 for Minus.
    pub fn sign(self) -> f32 {
        match self {
            Direction::Plus => 1.0,
            Direction::Minus => -1.0,
        }
    }
}

/// The four lines, active low. RA+ = move west = RA axis faster than
/// sidereal; RA- = slower; Dec+ = north.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Line {
    RaPlus = 0,
    RaMinus = 1,
    DecPlus = 2,
    DecMinus = 3,
}

impl Line {
    /// The four lines in the order of the port's signals; the hal numbers
    /// its inputs the same way (`hal::board::St4Pins`).
    pub const ALL: [Line; 4] = [Line::RaPlus, Line::RaMinus, Line::DecPlus, Line::DecMinus];

    /// The line's place in [`Line::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// The axis the line guides.
    pub fn axis(self) -> Axis {
        match self {
            Line::RaPlus | Line::RaMinus => Axis::Ra,
            Line::DecPlus | Line::DecMinus => Axis::Dec,
        }
    }

    /// The direction the line asks for.
    pub fn direction(self) -> Direction {
        match self {
            Line::RaPlus | Line::DecPlus => Direction::Plus,
            Line::RaMinus | Line::DecMinus => Direction::Minus,
        }
    }

    /// The other line of the same axis.
    pub fn opposite(self) -> Line {
        match self {
            Line::RaPlus => Line::RaMinus,
            Line::RaMinus => Line::RaPlus,
            Line::DecPlus => Line::DecMinus,
            Line::DecMinus => Line::DecPlus,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum St4Event {
    /// A guide pulse began (after the line stayed asserted for glitch_us;
    /// at_us is the edge's own time).
    PulseStart {
        axis: Axis,
        direction: Direction,
        at_us: u64,
    },
    /// The axis' pulse ended: released (at the release edge's time), cut at
    /// the cap, or stopped by a fault.
    PulseEnd { axis: Axis, at_us: u64 },
}

crate::counters! {
    /// What went wrong on the lines, since start-up (wrapping counts).
    pub struct St4Counters {
        /// Level changes undone within `glitch_us` (ignored).
        glitches,
        /// Episodes of both lines of an axis asserted.
        both_lines,
        /// Pulses cut at the cap.
        capped,
        /// Lines still asserted at the cap (each counted once until released).
        stuck,
        /// Edges older than the previous edge (ignored).
        out_of_order,
        /// Events dropped from the full queue (the oldest first).
        dropped,
    }
}

/// Capacity of the event queue.
pub const ST4_QUEUE_LEN: usize = 16;

#[derive(Clone, Copy, Debug)]
struct LineState {
    /// Last raw level seen (asserted = true).
    raw: bool,
    /// Debounced level.
    stable: bool,
    /// Cut at the cap and not yet released.
    stuck: bool,
    /// Time of the raw edge that made `raw` differ from `stable` (a change
    /// is pending while they differ).
    raw_since: u64,
}

impl LineState {
    const RELEASED: LineState = LineState {
        raw: false,
        stable: false,
        stuck: false,
        raw_since: 0,
    };

    fn pending(&self) -> bool {
        self.raw != self.stable
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum AxisState {
    Idle,
    /// A pulse on `line` since `start_us`.
    Active {
        line: Line,
        start_us: u64,
    },
    /// Both lines were asserted; waiting for both to be released.
    Blocked,
}

/// What `advance` does next.
#[derive(Clone, Copy)]
enum Action {
    Confirm(Line),
    Cut(Axis),
}

/// The ST4 state machine: per-line debounce, per-axis pulses, the event
/// queue and the fault counters. See the module documentation.
pub struct St4 {
    glitch_us: u64,
    cap_us: u64,
    /// RA+, RA-, Dec+, Dec-.
    lines: [LineState; 4],
    /// RA, Dec.
    axes: [AxisState; 2],
    queue: Deque<St4Event, ST4_QUEUE_LEN>,
    counters: St4Counters,
    /// The latest time seen (edges and polls).
    now_us: u64,
    /// The time of the latest accepted edge.
    last_edge_us: u64,
}

impl St4 {
    /// All lines released, no pulse, time 0. `glitch_us` 0 confirms every
    /// edge at once; `pulse_cap_us` 0 cuts every pulse at its start.
    pub fn new(glitch_us: u32, pulse_cap_us: u32) -> Self {
        St4 {
            glitch_us: glitch_us as u64,
            cap_us: pulse_cap_us as u64,
            lines: [LineState::RELEASED; 4],
            axes: [AxisState::Idle; 2],
            queue: Deque::new(),
            counters: St4Counters::default(),
            now_us: 0,
            last_edge_us: 0,
        }
    }

    /// A raw edge from the hardware: the line's new level (asserted = true)
    /// and its timestamp.
    pub fn edge(&mut self, line: Line, asserted: bool, at_us: u64) {
        if at_us < self.last_edge_us {
            self.counters.out_of_order = self.counters.out_of_order.wrapping_add(1);
            return;
        }
        self.last_edge_us = at_us;
        // An edge delivered after a poll at a later time takes effect at
        // that time: what was decided up to then stands.
        let at_us = at_us.max(self.now_us);
        // Everything due before this edge happens first (confirmations due
        // at its very time too; a cut due then waits for it).
        self.advance(at_us, false);
        let st = self.line_mut(line);
        if st.raw == asserted {
            return;
        }
        st.raw = asserted;
        if st.raw == st.stable {
            // The pending change was undone within glitch_us.
            self.counters.glitches = self.counters.glitches.wrapping_add(1);
        } else {
            st.raw_since = at_us;
        }
        // With glitch_us = 0 it is due at once. A cut due at this very
        // instant waits for a poll: another edge of the same microsecond
        // may still come and end the pulse normally, whatever the order in
        // which the lines' interrupts delivered them.
        self.advance(self.now_us, false);
    }

    /// Advance time (called at least every glitch_us while a line is
    /// pending, and regularly otherwise); emits confirmed starts, cap cuts.
    /// Call until `None`.
    pub fn poll(&mut self, now_us: u64) -> Option<St4Event> {
        self.advance(now_us, true);
        self.queue.pop_front()
    }

    pub fn counters(&self) -> St4Counters {
        self.counters
    }

    /// When poll() next needs to be called to confirm a pending edge or cut
    /// a pulse, if ever (the latest time seen when events are waiting).
    pub fn next_deadline_us(&self) -> Option<u64> {
        if !self.queue.is_empty() {
            return Some(self.now_us);
        }
        let mut next: Option<u64> = None;
        let mut take = |t: u64| {
            next = Some(match next {
                Some(n) if n <= t => n,
                _ => t,
            })
        };
        for st in self.lines.iter() {
            if st.pending() {
                take(st.raw_since.saturating_add(self.glitch_us));
            }
        }
        for axis in [Axis::Ra, Axis::Dec] {
            if let Some(t) = self.cut_time(axis) {
                take(t);
            }
        }
        next
    }

    /// Whether `line` is asserted (debounced).
    pub fn is_asserted(&self, line: Line) -> bool {
        self.line(line).stable
    }

    /// The pulse running on `axis`, if any: its direction and start time.
    pub fn active_pulse(&self, axis: Axis) -> Option<(Direction, u64)> {
        match self.axis(axis) {
            AxisState::Active { line, start_us } => Some((line.direction(), start_us)),
            _ => None,
        }
    }

    fn line(&self, line: Line) -> &LineState {
        match line {
            Line::RaPlus => &self.lines[0],
            Line::RaMinus => &self.lines[1],
            Line::DecPlus => &self.lines[2],
            Line::DecMinus => &self.lines[3],
        }
    }

    fn line_mut(&mut self, line: Line) -> &mut LineState {
        match line {
            Line::RaPlus => &mut self.lines[0],
            Line::RaMinus => &mut self.lines[1],
            Line::DecPlus => &mut self.lines[2],
            Line::DecMinus => &mut self.lines[3],
        }
    }

    fn axis(&self, axis: Axis) -> AxisState {
        match axis {
            Axis::Ra => self.axes[0],
            Axis::Dec => self.axes[1],
        }
    }

    fn set_axis(&mut self, axis: Axis, state: AxisState) {
        match axis {
            Axis::Ra => self.axes[0] = state,
            Axis::Dec => self.axes[1] = state,
        }
    }

    /// Queues an event; a full queue drops its oldest (counted).
    fn push(&mut self, ev: St4Event) {
        if self.queue.is_full() {
            self.queue.pop_front();
            self.counters.dropped = self.counters.dropped.wrapping_add(1);
        }
        // Cannot fail: there is room now.
        let _ = self.queue.push_back(ev);
    }

    /// When the axis' pulse is to be cut, if it runs and the cut is
    /// decided: no edge at or before the cut time is still pending on the
    /// axis (its confirmation could end the pulse earlier).
    fn cut_time(&self, axis: Axis) -> Option<u64> {
        let AxisState::Active { line, start_us } = self.axis(axis) else {
            return None;
        };
        let cut = start_us.saturating_add(self.cap_us);
        for l in [line, line.opposite()] {
            let st = self.line(l);
            if st.pending() && st.raw_since <= cut {
                return None;
            }
        }
        Some(cut)
    }

    /// Processes everything due at or before `now_us` (cuts due at `now_us`
    /// only if `cuts_at_now`), in the order of the events' own times
    /// (confirmations first on a tie).
    fn advance(&mut self, now_us: u64, cuts_at_now: bool) {
        if now_us > self.now_us {
            self.now_us = now_us;
        }
        let now = self.now_us;
        // Each action confirms a pending line (4 at most) or cuts a pulse
        // (one per confirmed assert, plus the 2 running): 10 at most.
        for _ in 0..16 {
            let mut best: Option<(u64, Action)> = None;
            for line in [Line::RaPlus, Line::RaMinus, Line::DecPlus, Line::DecMinus] {
                let st = self.line(line);
                if st.pending() && st.raw_since.saturating_add(self.glitch_us) <= now {
                    match best {
                        Some((t, _)) if t <= st.raw_since => {}
                        _ => best = Some((st.raw_since, Action::Confirm(line))),
                    }
                }
            }
            for axis in [Axis::Ra, Axis::Dec] {
                if let Some(cut) = self.cut_time(axis) {
                    if cut < now || (cuts_at_now && cut == now) {
                        match best {
                            Some((t, _)) if t <= cut => {}
                            _ => best = Some((cut, Action::Cut(axis))),
                        }
                    }
                }
            }
            match best {
                None => break,
                Some((_, Action::Confirm(line))) => self.confirm(line),
                Some((_, Action::Cut(axis))) => self.cut(axis),
            }
        }
    }

    fn confirm(&mut self, line: Line) {
        let st = self.line_mut(line);
        st.stable = st.raw;
        let (asserted, at_us) = (st.stable, st.raw_since);
        let axis = line.axis();
        let other = self.line(line.opposite()).stable;
        let state = self.axis(axis);
        if asserted {
            if other {
                // Both lines asserted.
                if let AxisState::Active { .. } = state {
                    self.push(St4Event::PulseEnd { axis, at_us });
                }
                if state != AxisState::Blocked {
                    self.counters.both_lines = self.counters.both_lines.wrapping_add(1);
                    self.set_axis(axis, AxisState::Blocked);
                }
            } else if state == AxisState::Idle {
                self.set_axis(
                    axis,
                    AxisState::Active {
                        line,
                        start_us: at_us,
                    },
                );
                self.push(St4Event::PulseStart {
                    axis,
                    direction: line.direction(),
                    at_us,
                });
            }
        } else {
            self.line_mut(line).stuck = false;
            match state {
                AxisState::Active { line: l, .. } if l == line => {
                    self.set_axis(axis, AxisState::Idle);
                    self.push(St4Event::PulseEnd { axis, at_us });
                }
                AxisState::Blocked if !other => self.set_axis(axis, AxisState::Idle),
                _ => {}
            }
        }
    }

    fn cut(&mut self, axis: Axis) {
        if let AxisState::Active { line, start_us } = self.axis(axis) {
            let at_us = start_us.saturating_add(self.cap_us);
            self.set_axis(axis, AxisState::Idle);
            self.push(St4Event::PulseEnd { axis, at_us });
            self.counters.capped = self.counters.capped.wrapping_add(1);
            self.line_mut(line).stuck = true;
            self.counters.stuck = self.counters.stuck.wrapping_add(1);
        }
    }
}

#[cfg(test)]
mod tests;
