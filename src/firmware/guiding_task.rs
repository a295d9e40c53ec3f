//! The guiding task, on the high-priority executor: moves the hal's edges,
//! the time, the step count and the feed-forward into the library's
//! `ControlLoop`, sets the rates it returns and hands the frames on.

use core::cell::{Cell, RefCell};

use embassy_executor::InterruptExecutor;
use embassy_futures::select::{select, Either};
use embassy_stm32::interrupt;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use embassy_time::{Instant, Timer};

use hal::reset::Watchdog;
use hal::st4::{PinEdge, St4Edges};
use mkgp_mount::control_loop::st4_feed::{EdgeQueue, EdgeSource, RawEdge};
use mkgp_mount::control_loop::storm::StormGuard;
use mkgp_mount::control_loop::{ControlLoop, FrameRecord};
use mkgp_mount::mount::config::Mount;
use mkgp_mount::mount::frame::FeedForward;
use mkgp_mount::mount::guiding::FRAME_QUEUE;
use mkgp_mount::mount::st4::{Line, St4Counters};
use mkgp_mount::safety::fault_record::FaultRecord;
use mkgp_mount::safety::liveness::{Liveness, Progress, Verdict};

use crate::firmware::fault::enter_safe_state;
use crate::firmware::learning_task::frames_learned;
use crate::firmware::log;
use crate::firmware::step_tick::{self, set_rates, step_counts};

pub static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();

/// The high-priority executor's vector: SDIO exists on all three chips and
/// none of the boards uses it.
#[interrupt]
unsafe fn SDIO() {
    // SAFETY: the executor was started on this vector before it was enabled.
    unsafe { EXECUTOR_HIGH.on_interrupt() }
}

/// The ST4 counters, for the status log.
pub static ST4_COUNTERS: Mutex<CriticalSectionRawMutex, Cell<Option<St4Counters>>> =
    Mutex::new(Cell::new(None));

/// Guide frames, from the guiding task to the learning task. The loop keeps
/// the frames there is no room for here, and drops its oldest when the
/// learner falls further behind (counted).
pub static FRAMES: Channel<CriticalSectionRawMutex, FrameRecord, FRAME_QUEUE> = Channel::new();

/// The newest feed-forward, from the learning task to the guiding task (an
/// older one not yet installed is replaced).
pub static FEED_FORWARD: Signal<CriticalSectionRawMutex, FeedForward> = Signal::new();

/// The ST4 edge budgets: asked by the EXTI interrupt before it queues an
/// edge, polled by the guiding task for masked lines. Borrowed only inside
/// its lock and never across one, so a borrow cannot fail: `try_borrow*`
/// keeps the borrow panics out of the firmware.
static STORM: Mutex<CriticalSectionRawMutex, RefCell<StormGuard>> =
    Mutex::new(RefCell::new(StormGuard::new()));

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

/// ST4 edge storms caught since start, for the status log.
pub fn storms() -> u32 {
    STORM.lock(|g| g.try_borrow().map_or(0, |g| g.storms()))
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
    }
}

/// Moves the hal's edges and the time into the loop, and its rates out;
/// feeds the watchdog while the liveness check finds everything alive.
#[embassy_executor::task]
pub async fn guiding_task(mut edges: St4Edges, mount: Mount, mut watchdog: Watchdog) {
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
        let first = match select(edges.next(), Timer::at(wake_at)).await {
            Either::First(edge) => Some(edge),
            Either::Second(()) => None,
        };
        // Every edge stamped before `now` is in the queue by now: the EXTI
        // interrupt preempts this task, and it stamps and queues in one go.
        let now_us = Instant::now().as_micros();
        poll_masked(&mut edges, now_us);
        let (ra_steps, _) = step_counts();
        let mut source = HalEdges {
            first,
            queue: &mut edges,
        };
        let wake = lp.wake(now_us, ra_steps, &mut source, FEED_FORWARD.try_take());
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
        log::wake(&wake);
        match liveness.check(now_us, progress()) {
            Verdict::Wait => {}
            Verdict::Feed => watchdog.feed(),
            Verdict::Stalled(part) => enter_safe_state(&FaultRecord::stalled(part)),
        }
    }
}
