//! Firmware entry point: boots the board, validates the mount configuration,
//! then tracks at the sidereal rate, obeys ST4 guide pulses and learns the
//! gear error, whose predicted rate it adds to the RA rate (feed-forward).
//!
//! # Structure
//!
//! The library (`mkgp_mount`) decides everything and knows no hardware; the
//! board crate (`hal`) drives pins and timers and knows no guiding; this file
//! glues them together on embassy. `hal` cannot depend on the library (the
//! firmware package depends on `hal`: a dependency back would be a package
//! cycle), so the glue that needs both lives here:
//!
//! - **Step tick** (`TIM2` interrupt, NVIC priority `P0`, the highest, at
//!   `step_tick_hz` = 50 kHz): advances each axis'
//!   [`PhaseAccumulator`] (integer, no float) and lets `hal`'s [`StepAxis`]
//!   raise or lower STEP; counts the steps emitted (signed `i64`).
//! - **ST4 edges** (`EXTI9_5`/`EXTI15_10`, `P1`, in `hal::st4`): each edge is
//!   timestamped in its interrupt and queued.
//! - **Guiding task** ([`guiding_task`], on [`EXECUTOR_HIGH`], an
//!   `InterruptExecutor` on the otherwise unused `SDIO` vector at `P2`): owns
//!   the library's [`St4`] and the controller's fast part, [`Guiding`];
//!   feeds the edges to `St4`, calls `poll` at `next_deadline_us()`, passes
//!   the events to `Guiding::on_event`, installs the newest feed-forward
//!   from [`FEED_FORWARD`] (`Guiding::set_feed_forward`), and on every event
//!   and every [`RATE_UPDATE_US`] sets `Guiding::rates(now, RA steps)` on the
//!   accumulators. Then (after the rates) it moves the completed guide
//!   frames (`Guiding::take_frame`) into [`FRAMES`] and logs the ST4 events.
//! - **Thread mode** (lowest): the learning task ([`learning_task`]) owns the
//!   model, a `Learner<2>` in the static [`LEARNER`]; per frame it runs
//!   `Learner::learn` (about 1.5 M instructions, 20-30 ms on the F411),
//!   signals the feed-forward to the guiding task and logs the frame, the
//!   learning %, each stage's period and gate, the feed-forward and the
//!   counters. The status log and LED run here too. Everything above
//!   preempts this, so the model never delays a pulse or a step; a new
//!   feed-forward takes effect at the guiding task's next wake-up (within
//!   [`RATE_UPDATE_US`]).
//!
//! # Memory
//!
//! The model's state (~55 KiB) is in the static [`LEARNER`] (`.bss`), built
//! once at start-up by [`make_learner`]. `Learner::new` returns it by value,
//! and with Rust 1.95 at opt-level 3 LLVM builds most of it (grid, scratch,
//! GP state) in a temporary on the stack and copies it: `make_learner`'s
//! frame is 54,584 B (the `sub sp` and pushes in the release disassembly,
//! at commit 1bc450e). On the F411 the static RAM is then 58,808 B, so at
//! that moment RAM holds 58,808 + 54,584 B + the callers' frames (under
//! 1 KiB) = about 112 KiB of 128 KiB: it fits, with about 16 KiB to spare. After start-up the deepest stack is a
//! few KiB (`learn`, plus the nested interrupts). The stack has no guard (no
//! flip-link): if the model's state grows by more than about 8 KiB (it
//! counts twice here), look at `make_learner`'s frame again; the way out is
//! an in-place constructor down to the grid and the GP state.
//!
//! # Latency from an ST4 edge to the rate change
//!
//! A pulse start is confirmed `glitch_us` (1 ms) after the assert edge by
//! design (debounce): [`St4`] reports it with the edge's own timestamp, and
//! the guiding task wakes on that deadline. A release edge ends the pulse at
//! once. From the moment the change is due (release edge, or end of the
//! debounce window) to the new rate in the step generator, on the slowest
//! board (F411 at 96 MHz; the F446 and F407 run 1.9x and 1.75x faster).
//! Estimated from the instructions on the path (the release build's
//! disassembly, and `Guiding`'s calls counted in QEMU), not measured on
//! hardware:
//!
//! | stage | worst case |
//! |---|---|
//! | EXTI interrupt (`P1`, `hal::st4`): stamp, clear, read 4 pins, queue; or the time driver's alarm (`P1`) for a deadline | ~5 µs |
//! | preemption by the step tick meanwhile (`P0`, ~80 instructions with entry and exit) | ~1.5 µs per tick, ~6 µs in all |
//! | `SDIO` executor interrupt (`P2`): task polled, `St4::edge`/`poll`, `FEED_FORWARD.try_take`, `Guiding::on_event` + `Guiding::rates` (software `f64`: ~3,200 instructions) | ~45 µs |
//! | `set_rate` on both axes, one critical section each (software `f64` division, ~600 cycles each) | ~13 µs |
//! | the new increment takes effect on the next step tick | <= 20 µs |
//!
//! About **90 µs** end to end: 0.009 % of a 1 s guide pulse, and both ends
//! of a pulse shift alike, so its length is kept better than that. Thread
//! mode, where the gear-error model runs, cannot add to this: every stage
//! above preempts it. Frames are handed on and events logged after the
//! rates are set. What can add: critical sections elsewhere (embassy's, and
//! defmt-rtt's, which holds one while it encodes a log line: the lines are
//! kept to at most six values, roughly 10 µs each). The step tick itself is
//! held off by at most the longest critical section (a log line, or one
//! `set_rate`, ~6 µs), less than a tick, so no tick is lost and STEP stays
//! high for at least ~10 µs (drivers need 1-2 µs). The tick costs ~1.5 µs
//! of every 20 µs (about 7 % of the F411's CPU), the rate updates ~0.5 %.
#![no_std]
#![no_main]

use core::cell::{Cell, RefCell};
use core::sync::atomic::{AtomicU32, Ordering};

use defmt_rtt as _;
use panic_probe as _;

use embassy_executor::{InterruptExecutor, Spawner};
use embassy_futures::select::{select, Either};
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Instant, Ticker, Timer};
use static_cell::StaticCell;

use hal::st4::{RawEdge, St4Edges, St4Line};
use hal::stepper::{StepAxis, StepTicker};
use mkgp_mount::mount::config::{Mount, MountConfig};
use mkgp_mount::mount::guiding::{
    FeedForward, Frame, FrameKind, Guiding, GuidingCounters, Learner, Rates, FRAME_QUEUE,
};
use mkgp_mount::mount::st4::{Axis, Direction, Line, St4, St4Counters, St4Event};
use mkgp_mount::mount::stepgen::PhaseAccumulator;

/// Interval of the status log line and LED toggle.
const HEARTBEAT: Duration = Duration::from_secs(1);
/// Status log every this many heartbeats.
const STATUS_EVERY: u32 = 10;
/// Events logged per wake-up of the guiding task (the rest are counted).
const LOG_EVENTS: usize = 4;
/// The guiding task recomputes and sets the rates at least this often (µs).
const RATE_UPDATE_US: u64 = 10_000;
/// DIR level for forward (RA: tracking direction; Dec: north) steps. Flip if
/// an axis turns the wrong way (or swap one coil's two wires).
const RA_DIR_FORWARD_HIGH: bool = true;
const DEC_DIR_FORWARD_HIGH: bool = true;
/// NVIC priority of the high-priority executor (below the step tick `P0`,
/// the ST4 EXTI and the time driver `P1`).
const EXECUTOR_HIGH_PRIORITY: Priority = Priority::P2;
/// NVIC priority of embassy's time driver (TIM5); `P0` is the step tick's.
const TIME_DRIVER_PRIORITY: Priority = Priority::P1;
/// Periodic stages of the gear-error model: the worm and one more (MKGP).
const STAGES: usize = 2;

// ---------------------------------------------------------------------------
// Step tick

/// Everything the step tick touches. Owned by the `TIM2` handler; the
/// guiding task changes the rates and reads the counts in critical
/// sections.
struct Stepping {
    ticker: StepTicker,
    ra: StepAxis,
    dec: StepAxis,
    ra_acc: PhaseAccumulator,
    dec_acc: PhaseAccumulator,
    /// Steps emitted, signed (forward positive).
    ra_steps: i64,
    dec_steps: i64,
}

static STEPPING: Mutex<CriticalSectionRawMutex, RefCell<Option<Stepping>>> =
    Mutex::new(RefCell::new(None));

/// The step tick (hal::stepper::StepTimer = TIM2): integer work only, about
/// 60 instructions for both axes.
#[interrupt]
fn TIM2() {
    critical_section::with(|cs| {
        let mut stepping = STEPPING.borrow(cs).borrow_mut();
        if let Some(s) = stepping.as_mut() {
            s.ticker.ack();
            let due = s.ra_acc.tick();
            s.ra_steps += i64::from(s.ra.tick(due));
            let due = s.dec_acc.tick();
            s.dec_steps += i64::from(s.dec.tick(due));
        }
    });
}

/// The rates last set (f32 bits), for the status log.
static RA_RATE_BITS: AtomicU32 = AtomicU32::new(0);
static DEC_RATE_BITS: AtomicU32 = AtomicU32::new(0);

/// Sets both axes' rates (clamped to the mount's maxima); returns the rates
/// actually set. One critical section per axis: `set_rate` costs about 600
/// cycles (a software `f64` division), so each holds the step tick off for
/// at most ~6 µs on the F411, well inside a 20 µs tick.
fn set_rates(mount: &Mount, rates: Rates) -> Rates {
    let tick_hz = mount.config().step_tick_hz;
    let set = |rate: f32, max: f32, acc: fn(&mut Stepping) -> &mut PhaseAccumulator| {
        critical_section::with(|cs| {
            let mut stepping = STEPPING.borrow(cs).borrow_mut();
            stepping
                .as_mut()
                .map_or(0.0, |s| acc(s).set_rate(rate, max, tick_hz))
        })
    };
    let set = Rates {
        ra_steps_per_s: set(rates.ra_steps_per_s, mount.max_ra_steps_per_s(), |s| {
            &mut s.ra_acc
        }),
        dec_steps_per_s: set(rates.dec_steps_per_s, mount.max_dec_steps_per_s(), |s| {
            &mut s.dec_acc
        }),
    };
    RA_RATE_BITS.store(set.ra_steps_per_s.to_bits(), Ordering::Relaxed);
    DEC_RATE_BITS.store(set.dec_steps_per_s.to_bits(), Ordering::Relaxed);
    set
}

/// Steps emitted so far on (RA, Dec).
fn step_counts() -> (i64, i64) {
    critical_section::with(|cs| {
        STEPPING
            .borrow(cs)
            .borrow()
            .as_ref()
            .map_or((0, 0), |s| (s.ra_steps, s.dec_steps))
    })
}

// ---------------------------------------------------------------------------
// Guiding (high priority)

static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();

/// The high-priority executor's vector: SDIO exists on all three chips and
/// none of the boards uses it.
#[interrupt]
unsafe fn SDIO() {
    // SAFETY: the executor was started on this vector before it was enabled.
    unsafe { EXECUTOR_HIGH.on_interrupt() }
}

/// The ST4 counters, for the status log.
static ST4_COUNTERS: Mutex<CriticalSectionRawMutex, Cell<Option<St4Counters>>> =
    Mutex::new(Cell::new(None));

/// A completed guide frame for the learner, with the guiding task's counters
/// when it was sent (logged with the frame).
#[derive(Clone, Copy)]
struct FrameMsg {
    frame: Frame,
    st4: St4Counters,
    guiding: GuidingCounters,
}

/// Guide frames, from the guiding task to the learning task. Frames are only
/// taken from `Guiding` while there is room here, so a learner that falls
/// behind loses the oldest of `Guiding`'s own queue, counted in
/// `GuidingCounters::frames_dropped`.
static FRAMES: Channel<CriticalSectionRawMutex, FrameMsg, FRAME_QUEUE> = Channel::new();

/// The newest feed-forward, from the learning task to the guiding task (an
/// older one not yet installed is replaced).
static FEED_FORWARD: Signal<CriticalSectionRawMutex, FeedForward> = Signal::new();

fn line_of(line: St4Line) -> Line {
    match line {
        St4Line::RaPlus => Line::RaPlus,
        St4Line::RaMinus => Line::RaMinus,
        St4Line::DecPlus => Line::DecPlus,
        St4Line::DecMinus => Line::DecMinus,
    }
}

fn axis_name(axis: Axis) -> &'static str {
    match axis {
        Axis::Ra => "RA",
        Axis::Dec => "Dec",
    }
}

/// The library's ST4 state machine, fed in time order.
struct St4Feed {
    st4: St4,
    /// Latest time given to `st4` (edges and polls never go back).
    last_us: u64,
    /// Line levels as given to `st4`, for resynchronising after a lost edge.
    levels: [bool; 4],
    dropped_seen: u32,
}

impl St4Feed {
    /// Feeds one edge: first the deadlines that fell before it, then the
    /// edge. Events go to `on_event`.
    fn edge(&mut self, edge: RawEdge, on_event: &mut impl FnMut(St4Event)) {
        let at_us = edge.at_us.max(self.last_us);
        self.poll(at_us, on_event);
        self.st4.edge(line_of(edge.line), edge.asserted, at_us);
        self.levels[edge.line as usize] = edge.asserted;
    }

    fn poll(&mut self, now_us: u64, on_event: &mut impl FnMut(St4Event)) {
        let now_us = now_us.max(self.last_us);
        self.last_us = now_us;
        while let Some(ev) = self.st4.poll(now_us) {
            on_event(ev);
        }
    }

    /// After edges were lost to a full queue: feed the difference between
    /// the levels the interrupt saw last and those `st4` has.
    fn resync(&mut self, edges: &St4Edges, now_us: u64, on_event: &mut impl FnMut(St4Event)) {
        let dropped = edges.dropped();
        if dropped == self.dropped_seen {
            return;
        }
        defmt::warn!(
            "ST4: {} edges lost (input storm?), resynchronising",
            dropped - self.dropped_seen
        );
        self.dropped_seen = dropped;
        let levels = edges.levels();
        for line in St4Line::ALL {
            let asserted = levels[line as usize];
            if asserted != self.levels[line as usize] {
                let edge = RawEdge {
                    line,
                    asserted,
                    at_us: now_us,
                };
                self.edge(edge, on_event);
            }
        }
    }
}

fn log_event(ev: &St4Event) {
    match *ev {
        St4Event::PulseStart {
            axis,
            direction,
            at_us,
        } => defmt::info!(
            "ST4 pulse start {} {} at {} us",
            axis_name(axis),
            match direction {
                Direction::Plus => "+",
                Direction::Minus => "-",
            },
            at_us
        ),
        St4Event::PulseEnd { axis, at_us } => {
            defmt::info!("ST4 pulse end {} at {} us", axis_name(axis), at_us)
        }
    }
}

fn log_counters(c: St4Counters) {
    defmt::info!(
        "ST4 counters: glitches {}, both lines {}, capped {}, stuck {}, out of order {}, events dropped {}",
        c.glitches,
        c.both_lines,
        c.capped,
        c.stuck,
        c.out_of_order,
        c.dropped
    );
}

/// Owns the ST4 logic and the guiding: edges and deadlines in, rates out.
#[embassy_executor::task]
async fn guiding_task(mut edges: St4Edges, mount: Mount) {
    let config = *mount.config();
    let mut feed = St4Feed {
        st4: St4::new(config.glitch_us, config.pulse_cap_us),
        last_us: 0,
        levels: [false; 4],
        dropped_seen: 0,
    };
    let mut guiding = Guiding::new(&mount);
    let (ra_steps, _) = step_counts();
    let rates = set_rates(&mount, guiding.rates(Instant::now().as_micros(), ra_steps));
    defmt::info!(
        "tracking: RA {} steps/s, Dec {} steps/s",
        rates.ra_steps_per_s,
        rates.dec_steps_per_s
    );
    let mut next_update_us = Instant::now().as_micros() + RATE_UPDATE_US;
    let mut last_counters = St4Counters::default();

    loop {
        let wake_us = feed
            .st4
            .next_deadline_us()
            .map_or(next_update_us, |d| d.min(next_update_us));
        let first = match select(edges.next(), Timer::at(Instant::from_micros(wake_us))).await {
            Either::First(edge) => Some(edge),
            Either::Second(()) => None,
        };

        // Every edge stamped before `now` is in the queue by now: the EXTI
        // interrupt preempts this task, and it stamps and queues in one go.
        let now_us = Instant::now().as_micros();
        // Events are applied at once and logged after the new rates are
        // set, so that logging never delays a rate change.
        let mut events = [None; LOG_EVENTS];
        let mut n_events = 0usize;
        let mut on_event = |ev: St4Event| {
            guiding.on_event(ev);
            if let Some(slot) = events.get_mut(n_events) {
                *slot = Some(ev);
            }
            n_events += 1;
        };
        if let Some(edge) = first {
            feed.edge(edge, &mut on_event);
        }
        while let Some(edge) = edges.try_next() {
            feed.edge(edge, &mut on_event);
        }
        feed.resync(&edges, now_us, &mut on_event);
        feed.poll(now_us, &mut on_event);
        let changed = n_events > 0;
        let feed_forward = FEED_FORWARD.try_take();
        if let Some(ff) = feed_forward {
            guiding.set_feed_forward(ff);
        }

        let now_us = now_us.max(feed.last_us);
        if changed || feed_forward.is_some() || now_us >= next_update_us {
            let (ra_steps, _) = step_counts();
            set_rates(&mount, guiding.rates(now_us, ra_steps));
        }

        // Completed frames to the learner, after the rates are set.
        while !FRAMES.is_full() {
            let Some(frame) = guiding.take_frame() else {
                break;
            };
            let msg = FrameMsg {
                frame,
                st4: feed.st4.counters(),
                guiding: guiding.counters(),
            };
            // Cannot fail: there is room, and this task is the only sender.
            let _ = FRAMES.try_send(msg);
        }

        for ev in events.iter().flatten() {
            log_event(ev);
        }
        if n_events > LOG_EVENTS {
            defmt::info!("ST4: {} more events not logged", n_events - LOG_EVENTS);
        }
        let counters = feed.st4.counters();
        if changed || counters != last_counters {
            log_counters(counters);
            last_counters = counters;
            ST4_COUNTERS.lock(|c| c.set(Some(counters)));
        }
        if now_us >= next_update_us {
            next_update_us += RATE_UPDATE_US;
            if next_update_us <= now_us {
                next_update_us = now_us + RATE_UPDATE_US;
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Learning (thread mode, lowest priority)

/// The model's storage (~55 KiB): a static, handed out once.
static LEARNER: StaticCell<Learner<STAGES>> = StaticCell::new();

/// Builds the model in [`LEARNER`]. Not inlined, so that its stack frame is
/// its own: `Learner::new`'s value is built in the static (small frame, see
/// the module doc), not in a temporary on the stack.
#[inline(never)]
fn make_learner(mount: &Mount) -> Option<&'static mut Learner<STAGES>> {
    LEARNER.try_init_with(|| Learner::new(mount))
}

/// Runs the model once per guide frame (about 20-30 ms on the F411, the
/// longest thing that runs here) and hands the feed-forward to the guiding
/// task. Everything else preempts it.
#[embassy_executor::task]
async fn learning_task(learner: &'static mut Learner<STAGES>) {
    loop {
        let msg = FRAMES.receive().await;
        let ff = learner.learn(msg.frame);
        FEED_FORWARD.signal(ff);
        log_frame(learner, &msg, &ff);
    }
}

/// The per-frame log. defmt-rtt holds a critical section while it encodes a
/// line (the step tick waits meanwhile), so the lines are kept short.
fn log_frame(learner: &Learner<STAGES>, msg: &FrameMsg, ff: &FeedForward) {
    let f = &msg.frame;
    let model = learner.guider();
    let kind = match f.kind {
        FrameKind::Measured if f.filled => "filled",
        FrameKind::Measured => "measured",
        FrameKind::Unmeasured => "unmeasured",
        FrameKind::Dither { .. } => "dither",
    };
    defmt::info!(
        "frame {} at gear {} s: gear error {} arcsec (pulse {} arcsec)",
        kind,
        f.gear_time_s,
        f.gear_error_arcsec,
        f.pulse_arcsec
    );
    defmt::info!(
        "model: learning {} %, blend {}, feed-forward {} arcsec/s",
        (model.learning_progress() * 100.0) as f32,
        model.blend_weight() as f32,
        ff.rate_arcsec_per_s
    );
    for stage in 0..STAGES {
        defmt::info!(
            "model stage {}: period {} s, gate {}",
            stage,
            model.period_s(stage) as f32,
            model.gate(stage) as f32
        );
    }
    let l = learner.counters();
    let m = model.faults();
    defmt::info!(
        "model counters: frames {}, learned {}, not learned {}, dithers {}",
        l.frames,
        l.learned,
        l.not_learned,
        l.dithers
    );
    defmt::info!(
        "model faults: bad time {}, bad input {}, inference {}, grid restarts {}, bad dithers {}",
        m.bad_time,
        m.bad_input,
        m.inference_failures,
        m.grid_restarts,
        m.bad_dithers
    );
    let g = &msg.guiding;
    defmt::info!(
        "guiding: pulses RA {} Dec {}, frames {} (filled {}, unmeasured {}, dropped {})",
        g.ra_pulses,
        g.dec_pulses,
        g.frames,
        g.filled_frames,
        g.unmeasured_frames,
        g.frames_dropped
    );
    defmt::info!(
        "guiding: dithers {}, silences {}, stray ends {}, time backwards {}, clamped RA {} Dec {}",
        g.dithers,
        g.silences,
        g.stray_ends,
        g.time_backwards,
        g.ra_clamped,
        g.dec_clamped
    );
    defmt::info!(
        "feed-forward: rejected {}, limited {}, expired {}, faded {}",
        g.feed_forward_rejected,
        g.feed_forward_limited,
        g.feed_forward_expired,
        g.feed_forward_faded
    );
    log_counters(msg.st4);
}

// ---------------------------------------------------------------------------
// Start-up and thread mode

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let p = hal::clocks::init();
    interrupt::TIM5.set_priority(TIME_DRIVER_PRIORITY);
    let board = hal::take_board!(p);
    defmt::info!(
        "{} {} up, SYSCLK {} Hz",
        env!("CARGO_PKG_NAME"),
        env!("CARGO_PKG_VERSION"),
        hal::clocks::SYSCLK_HZ
    );

    // LED off at start.
    let off = if hal::board::LED_ACTIVE_LOW {
        Level::High
    } else {
        Level::Low
    };
    let mut led = Output::new(board.led, off, Speed::Low);

    // Drivers disabled (ENABLE high) until the configuration is known good.
    let ra = StepAxis::new(board.ra, RA_DIR_FORWARD_HIGH);
    let dec = StepAxis::new(board.dec, DEC_DIR_FORWARD_HIGH);

    let running = start(spawner, p.TIM2, ra, dec, board.st4);
    if running.is_err() {
        defmt::error!("motors stay disabled; fix the configuration and reflash");
    }

    let mut ticker = Ticker::every(HEARTBEAT);
    let mut beats: u32 = 0;
    loop {
        ticker.next().await;
        beats = beats.wrapping_add(1);
        led.toggle();
        if beats % STATUS_EVERY != 0 {
            continue;
        }
        match running {
            Ok(()) => log_status(),
            Err(()) => defmt::error!("configuration refused at start-up; motors disabled"),
        }
    }
}

/// Validates the configuration, builds the model, starts the step tick,
/// enables the drivers and starts the guiding task (high priority) and the
/// learning task (on `spawner`, thread mode). On a refused configuration:
/// logs why and returns with the drivers disabled and nothing started.
fn start(
    spawner: Spawner,
    tim: embassy_stm32::Peri<'static, hal::stepper::StepTimer>,
    ra: StepAxis,
    dec: StepAxis,
    st4_pins: hal::board::St4Pins,
) -> Result<(), ()> {
    let config = MountConfig::default();
    let mount = match config.validate() {
        Ok(mount) => mount,
        Err(e) => {
            defmt::error!("mount configuration refused: {}", defmt::Display2Format(&e));
            return Err(());
        }
    };
    let ticker = match StepTicker::new(tim, config.step_tick_hz) {
        Ok(t) => t,
        Err(e) => {
            defmt::error!("step tick: {}", e);
            return Err(());
        }
    };
    defmt::info!(
        "mount: {} RA steps/worm turn, worm {} s, sidereal {} steps/s, {} arcsec/RA step, {} arcsec/Dec step, guide {}x, tick {} Hz",
        config.ra_steps_per_worm_turn,
        config.worm_period_s,
        mount.sidereal_ra_steps_per_s(),
        mount.arcsec_per_ra_step(),
        mount.arcsec_per_dec_step(),
        config.guide_rate_sidereal,
        config.step_tick_hz
    );
    let Some(learner) = make_learner(&mount) else {
        defmt::error!("the model was already built");
        return Err(());
    };
    match learning_task(learner) {
        Ok(token) => spawner.spawn(token),
        Err(_) => {
            defmt::error!("learning task could not be spawned");
            return Err(());
        }
    }

    STEPPING.lock(|s| {
        s.replace(Some(Stepping {
            ticker,
            ra,
            dec,
            ra_acc: PhaseAccumulator::new(),
            dec_acc: PhaseAccumulator::new(),
            ra_steps: 0,
            dec_steps: 0,
        }))
    });
    critical_section::with(|cs| {
        if let Some(s) = STEPPING.borrow(cs).borrow_mut().as_mut() {
            s.ticker.start();
            s.ra.set_enabled(true);
            s.dec.set_enabled(true);
        }
    });

    let edges = hal::st4::start(st4_pins);
    interrupt::SDIO.set_priority(EXECUTOR_HIGH_PRIORITY);
    let high = EXECUTOR_HIGH.start(interrupt::SDIO);
    match guiding_task(edges, mount) {
        Ok(token) => high.spawn(token),
        Err(_) => {
            defmt::error!("guiding task could not be spawned");
            return Err(());
        }
    }
    Ok(())
}

fn log_status() {
    let (ra_steps, dec_steps) = step_counts();
    defmt::info!(
        "status: RA {} steps at {} steps/s, Dec {} steps at {} steps/s",
        ra_steps,
        f32::from_bits(RA_RATE_BITS.load(Ordering::Relaxed)),
        dec_steps,
        f32::from_bits(DEC_RATE_BITS.load(Ordering::Relaxed)),
    );
    if let Some(c) = ST4_COUNTERS.lock(|c| c.get()) {
        log_counters(c);
    }
}
