//! Raw ST4 edges into the [`St4`] state machine, in time order.
//!
//! The hal stamps each edge in its interrupt and queues it; this feeds them
//! to [`St4`] with the deadlines that fell before each, never letting time
//! go back (an edge stamped before the last time given is taken at that
//! time), and resynchronises the line levels after edges were lost to a
//! full queue.

use crate::mount::st4::{Line, St4, St4Event};

/// A level change of one ST4 line as the hal saw it: `asserted` is the new
/// level (true = pulled low by the camera), `at_us` the time of the
/// interrupt in microseconds since boot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawEdge {
    pub line: Line,
    pub asserted: bool,
    pub at_us: u64,
}

/// Where the edges come from: the hal's queue on the board, the simulated
/// camera in the simulator.
pub trait EdgeSource {
    /// The next queued edge, oldest first.
    fn next_edge(&mut self) -> Option<RawEdge>;
    /// The queue's loss counter and the levels its producer saw last, read
    /// after the queue was drained.
    fn queue(&self) -> EdgeQueue;
}

/// The hal's edge queue as seen at a wake-up: how many edges it has lost
/// since boot, and the line levels its interrupt saw last.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EdgeQueue {
    pub dropped: u32,
    /// Indexed like [`Line::ALL`] (true = asserted).
    pub levels: [bool; 4],
}

/// [`St4`] and what it has been given.
pub struct St4Feed {
    st4: St4,
    /// Latest time given to `st4` (edges and polls never go back).
    last_us: u64,
    /// Line levels as given to `st4`, for resynchronising after a loss.
    levels: [bool; 4],
    dropped_seen: u32,
}

impl St4Feed {
    pub fn new(glitch_us: u32, pulse_cap_us: u32) -> Self {
        St4Feed {
            st4: St4::new(glitch_us, pulse_cap_us),
            last_us: 0,
            levels: [false; 4],
            dropped_seen: 0,
        }
    }

    pub fn st4(&self) -> &St4 {
        &self.st4
    }

    /// Latest time given to the state machine, µs.
    pub fn last_us(&self) -> u64 {
        self.last_us
    }

    /// Feeds one edge: first the deadlines that fell before it, then the
    /// edge. Events go to `on_event`.
    pub fn edge(&mut self, edge: RawEdge, on_event: &mut impl FnMut(St4Event)) {
        let at_us = edge.at_us.max(self.last_us);
        self.poll(at_us, on_event);
        self.st4.edge(edge.line, edge.asserted, at_us);
        self.levels[edge.line as usize] = edge.asserted;
    }

    /// Runs the deadlines up to `now_us`.
    pub fn poll(&mut self, now_us: u64, on_event: &mut impl FnMut(St4Event)) {
        let now_us = now_us.max(self.last_us);
        self.last_us = now_us;
        while let Some(ev) = self.st4.poll(now_us) {
            on_event(ev);
        }
    }

    /// After edges were lost to a full queue: feeds the difference between
    /// the levels the interrupt saw last and those `st4` has, at `now_us`.
    /// Returns how many edges were newly lost.
    pub fn resync(
        &mut self,
        queue: EdgeQueue,
        now_us: u64,
        on_event: &mut impl FnMut(St4Event),
    ) -> u32 {
        let lost = queue.dropped.wrapping_sub(self.dropped_seen);
        if lost == 0 {
            return 0;
        }
        self.dropped_seen = queue.dropped;
        for line in Line::ALL {
            let asserted = queue.levels[line as usize];
            if asserted != self.levels[line as usize] {
                let edge = RawEdge {
                    line,
                    asserted,
                    at_us: now_us,
                };
                self.edge(edge, on_event);
            }
        }
        lost
    }
}
