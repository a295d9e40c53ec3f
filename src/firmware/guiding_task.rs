//! The guiding task, on the high-priority executor: moves the hal's edges,
//! the time, the step count and the feed-forward into the library's
//! `ControlLoop`, sets the rates it returns and hands the frames on. It
//! also serves the command ports: their bytes go to each port's
//! `Interpreter` on the loop (`PortMount`), and each learned frame's
//! telemetry line to the ports that asked for it.

use core::cell::Cell;

use embassy_executor::InterruptExecutor;
use embassy_futures::select::{select3, Either3};
use embassy_stm32::interrupt;
use embassy_time::{Instant, Timer};

use hal::reset::Watchdog;
use hal::st4::{PinEdge, St4Edges};
use mkgp_mount::control_loop::port_mount::{LearnedFrame, PortMount, PortState};
use mkgp_mount::control_loop::st4_feed::{EdgeQueue, EdgeSource, RawEdge};
use mkgp_mount::control_loop::ControlLoop;
use mkgp_mount::mount::config::Mount;
use mkgp_mount::mount::st4::Line;
use mkgp_mount::port::mount_port::{Identity, StepCounts};
use mkgp_mount::port::Interpreter;
use mkgp_mount::safety::fault_record::FaultRecord;
use mkgp_mount::safety::liveness::{Liveness, Progress, Verdict};
use mkgp_mount::safety::reset_cause::ResetCause;

use crate::firmware::fault::enter_safe_state;
use crate::firmware::log;
use crate::firmware::port_io::{LinkSink, CHUNK, LINKS};
use crate::firmware::shared::{
    frames_learned, StoreDone, FRAMES, INDEX_EDGE, LEARNED, MODEL_ORIGIN, PORTS, RECEIVED,
    RESET_MODEL, ST4_COUNTERS, STORE_REQUESTS, STORM,
};
use crate::firmware::step_tick::{self, set_rates, step_counts};

pub static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();

/// The high-priority executor's vector: SPI3 exists on all four chips and
/// the firmware leaves it unused.
#[interrupt]
unsafe fn SPI3() {
    // SAFETY: the executor was started on this vector before it was enabled.
    unsafe { EXECUTOR_HIGH.on_interrupt() }
}

/// Reports each edge of the worm-index sensor with the RA step count then
/// (on the high-priority executor: the count is taken within microseconds
/// of the edge).
#[embassy_executor::task]
pub async fn index_task(mut input: hal::worm_index::IndexInput) {
    loop {
        input.next_pass().await;
        let (ra_steps, _) = step_counts();
        INDEX_EDGE.signal(ra_steps);
    }
}

/// What the ports report as the firmware.
const IDENTITY: Identity = Identity {
    product: env!("CARGO_PKG_NAME"),
    version: env!("CARGO_PKG_VERSION"),
    date: env!("MKGP_BUILD_DATE"),
    time: env!("MKGP_BUILD_TIME"),
};

/// Received bytes one wake-up interprets per port at most: a flood waits
/// in its pipe, and the edges and rates are never late for it.
const RX_PER_WAKE: usize = 4 * CHUNK;

/// The hal numbers its inputs in the order of `Line::ALL`.
fn line(index: u8) -> Line {
    Line::ALL[usize::from(index) % Line::ALL.len()]
}

/// The hal's question before it queues an edge (in the EXTI interrupt).
pub fn allow_edge(index: u8, at_us: u64) -> bool {
    STORM.lock(|g| {
        g.try_borrow_mut()
            .is_ok_and(|mut g| g.on_edge(line(index), at_us))
    })
}

/// Unmasks each masked input that the storm guard finds quiet.
fn poll_masked(edges: &mut St4Edges, now_us: u64) {
    for index in 0..Line::ALL.len() as u8 {
        if let Some(level) = edges.masked_level(index) {
            if STORM.lock(|g| {
                g.try_borrow_mut()
                    .is_ok_and(|mut g| g.poll(line(index), now_us, level))
            }) {
                edges.unmask(index);
            }
        }
    }
}

/// The hal's edge queue, with the edge that woke the task first.
struct HalEdges<'a> {
    first: Option<PinEdge>,
    queue: &'a mut St4Edges,
}

impl EdgeSource for HalEdges<'_> {
    fn next_edge(&mut self) -> Option<RawEdge> {
        let e = self.first.take().or_else(|| self.queue.try_next())?;
        Some(RawEdge {
            line: line(e.index),
            asserted: e.asserted,
            at_us: e.at_us,
        })
    }

    fn queue(&self) -> EdgeQueue {
        EdgeQueue {
            dropped: self.queue.dropped(),
            levels: self.queue.levels(),
        }
    }
}

/// What the liveness check reads.
fn progress() -> Progress {
    Progress {
        step_ticks: step_tick::ticks(),
        frames_learned: frames_learned(),
        frames_waiting: !FRAMES.is_empty(),
        flash_operations: crate::firmware::storage::flash_operations(),
    }
}

/// The command ports beside the loop: one interpreter each, the state
/// they share.
struct Ports {
    interpreters: [Interpreter; PORTS],
    state: PortState,
}

impl Ports {
    /// Interprets what arrived on each port (at most [`RX_PER_WAKE`]
    /// bytes), or lets a stale half command time out.
    fn serve(&mut self, lp: &mut ControlLoop, now_us: u64) {
        let (ra, dec) = step_counts();
        let done = StoreDone::take();
        self.state.store_counters = done.counters;
        for ((port, link), saved) in self.interpreters.iter_mut().zip(&LINKS).zip(done.replies) {
            if let Some(saved) = saved {
                port.store_done(saved, &mut LinkSink(link));
            }
        }
        let mut mount = PortMount {
            control: lp,
            state: &mut self.state,
            now_us,
            steps: StepCounts { ra, dec },
            port: 0,
        };
        let mut more = false;
        for (index, (port, link)) in self.interpreters.iter_mut().zip(&LINKS).enumerate() {
            mount.port = index;
            let mut buf = [0u8; CHUNK];
            let mut sink = LinkSink(link);
            port.feed(&[], now_us, &mut mount, &mut sink);
            let mut taken = 0;
            while taken < RX_PER_WAKE {
                let n = link.take_received(&mut buf);
                if n == 0 {
                    break;
                }
                port.feed(buf.get(..n).unwrap_or(&[]), now_us, &mut mount, &mut sink);
                taken += n;
            }
            more |= taken >= RX_PER_WAKE;
        }
        // The rest at the next wake-up, after this one's edges and rates.
        if more {
            RECEIVED.signal(());
        }
        if self.state.take_reset_request() {
            RESET_MODEL.signal(());
        }
        // Moved on only while the learning task has room: the rest waits in
        // the port's queue, and a port that finds that full answers `0`.
        while !STORE_REQUESTS.is_full() {
            let Some(request) = self.state.take_store_request() else {
                break;
            };
            // Cannot fail: there is room, and this task is the only sender.
            let _ = STORE_REQUESTS.try_send(request);
        }
        self.state.model_origin = MODEL_ORIGIN.lock(Cell::get);
    }

    /// A learned frame: the summary for the queries, its telemetry line to
    /// the ports that asked.
    fn learned(&mut self, learned: &LearnedFrame, now_us: u64) {
        self.state.learner = learned.summary.clone();
        let line = learned.telemetry(now_us);
        for (port, link) in self.interpreters.iter_mut().zip(&LINKS) {
            port.send_telemetry(&line, &mut LinkSink(link));
        }
    }
}

/// Moves the hal's edges, the ports' bytes and the time into the loop, and
/// its rates out; feeds the watchdog while the liveness check finds
/// everything alive.
#[embassy_executor::task]
pub async fn guiding_task(
    mut edges: St4Edges,
    mount: Mount,
    mut watchdog: Watchdog,
    reset_cause: ResetCause,
    has_store: bool,
) {
    let mut ports = Ports {
        interpreters: [Interpreter::new(), Interpreter::new()],
        state: PortState::new(&mount, IDENTITY, reset_cause),
    };
    ports.state.store = has_store;
    let (ra_steps, _) = step_counts();
    let (mut lp, rates) = ControlLoop::start(&mount, Instant::now().as_micros(), ra_steps);
    let rates = set_rates(rates);
    defmt::info!(
        "tracking: RA {} steps/s, Dec {} steps/s",
        rates.ra_steps_per_s,
        rates.dec_steps_per_s
    );
    let mut liveness = Liveness::new(
        mount.config().step_tick_hz,
        Instant::now().as_micros(),
        progress(),
    );
    loop {
        let wake_at = Instant::from_micros(lp.next_wake_us().min(liveness.next_check_us()));
        let first = match select3(edges.next(), Timer::at(wake_at), RECEIVED.wait()).await {
            Either3::First(edge) => Some(edge),
            Either3::Second(()) | Either3::Third(()) => None,
        };
        // Every edge stamped before `now` is in the queue by now: the EXTI
        // interrupt preempts this task, and it stamps and queues in one go.
        let now_us = Instant::now().as_micros();
        poll_masked(&mut edges, now_us);
        // Before the wake-up: the motion a command starts is set by it.
        ports.serve(&mut lp, now_us);
        let (ra_steps, _) = step_counts();
        let mut source = HalEdges {
            first,
            queue: &mut edges,
        };
        let learned = LEARNED.try_take();
        let feed_forward = learned.as_ref().map(|l| l.feed_forward);
        let wake = lp.wake(now_us, ra_steps, &mut source, feed_forward);
        if let Some(rates) = wake.rates {
            set_rates(rates);
        }
        // Completed frames to the learner, after the rates are set.
        while !FRAMES.is_full() {
            let Some(record) = lp.take_frame() else {
                break;
            };
            // Cannot fail: there is room, and this task is the only sender.
            let _ = FRAMES.try_send(record);
        }
        if let Some(c) = wake.st4_counters {
            ST4_COUNTERS.lock(|s| s.set(Some(c)));
        }
        if let Some(learned) = &learned {
            ports.learned(learned, now_us);
        }
        log::wake(&wake);
        match liveness.check(now_us, progress()) {
            Verdict::Wait => {}
            Verdict::Feed => watchdog.feed(),
            Verdict::Stalled(part) => enter_safe_state(&FaultRecord::stalled(part)),
        }
    }
}
