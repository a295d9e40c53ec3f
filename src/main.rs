//! Firmware entry point: boots the board, validates the mount configuration,
//! then tracks at the sidereal rate, obeys ST4 guide pulses and learns the
//! gear error, whose predicted rate it adds to the RA rate (feed-forward).
//!
//! This file only wires hardware to the library's loop
//! ([`mkgp_mount::control_loop`]), which decides everything and which the
//! simulator drives too; `hal` moves the pins and timers. Priorities (NVIC,
//! lower number first):
//!
//! - **Step tick** (`TIM2`, `P0`, at `step_tick_hz`): each axis's
//!   [`AxisStepper::tick`] says what to change on STEP and DIR; `hal`'s
//!   [`StepAxis`] changes it.
//! - **ST4 edges** (`EXTI9_5`/`EXTI15_10`, `P1`, in `hal::st4`): each edge is
//!   timestamped in its interrupt and queued. embassy's time driver (`TIM5`)
//!   is at `P1` too.
//! - **Guiding task** ([`guiding_task`], on [`EXECUTOR_HIGH`], an
//!   `InterruptExecutor` on the otherwise unused `SDIO` vector at `P2`):
//!   sleeps until an edge or [`ControlLoop::next_wake_us`], then hands the
//!   queued edges, the time, the RA step count and the newest feed-forward
//!   to [`ControlLoop::wake`], sets the rates it returns, moves completed
//!   frames to [`FRAMES`] while there is room, and logs.
//! - **Thread mode** (lowest): the learning task ([`learning_task`]) runs
//!   the model, a `Learner<2>` in the static [`LEARNER`], once per frame,
//!   and signals the feed-forward to the guiding task, which installs it at
//!   its next wake-up (within `RATE_UPDATE_US`). The status log and the LED
//!   run here too. Everything above preempts it, so the model never delays
//!   a pulse or a step.
//!
//! `docs/firmware.md` has the memory layout at start-up and the latency from
//! an ST4 edge to the new rate.
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

use hal::st4::{PinEdge, St4Edges};
use hal::stepper::{StepAxis, StepTicker};
use mkgp_mount::control_loop::st4_feed::{EdgeQueue, EdgeSource, RawEdge};
use mkgp_mount::control_loop::stepping::AxisStepper;
use mkgp_mount::control_loop::{ControlLoop, FrameRecord, Wake};
use mkgp_mount::mount::config::{Mount, MountConfig};
use mkgp_mount::mount::frame::{FeedForward, FrameKind, Rates};
use mkgp_mount::mount::guiding::FRAME_QUEUE;
use mkgp_mount::mount::learner::Learner;
use mkgp_mount::mount::st4::{Axis, Direction, Line, St4Counters, St4Event};
use mkgp_mount::mount::step_pulse::PinChange;

/// Interval of the status log line and LED toggle.
const HEARTBEAT: Duration = Duration::from_secs(1);
/// Status log every this many heartbeats.
const STATUS_EVERY: u32 = 10;
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

/// One axis: the library's stepper and the pins it drives.
struct Axle {
    stepper: AxisStepper,
    pins: StepAxis,
}

impl Axle {
    #[inline]
    fn tick(&mut self) {
        match self.stepper.tick() {
            PinChange::None => {}
            PinChange::StepLow => self.pins.set_step(false),
            PinChange::StepHigh => self.pins.set_step(true),
            PinChange::Dir { forward } => self.pins.set_dir(forward),
        }
    }
}

/// Everything the step tick touches. Owned by the `TIM2` handler; the
/// guiding task changes the rates and reads the counts in critical
/// sections.
struct Stepping {
    ticker: StepTicker,
    ra: Axle,
    dec: Axle,
}

static STEPPING: Mutex<CriticalSectionRawMutex, RefCell<Option<Stepping>>> =
    Mutex::new(RefCell::new(None));

/// The step tick (hal::stepper::StepTimer = TIM2): integer work only.
#[interrupt]
fn TIM2() {
    critical_section::with(|cs| {
        let mut stepping = STEPPING.borrow(cs).borrow_mut();
        if let Some(s) = stepping.as_mut() {
            s.ticker.ack();
            s.ra.tick();
            s.dec.tick();
        }
    });
}

/// The rates last set (f32 bits), for the status log.
static RA_RATE_BITS: AtomicU32 = AtomicU32::new(0);
static DEC_RATE_BITS: AtomicU32 = AtomicU32::new(0);

/// Sets both axes' rates; returns the rates actually set. One critical
/// section per axis: `set_rate` does a software `f64` division, so each
/// holds the step tick off for a few µs, well inside a tick.
fn set_rates(rates: Rates) -> Rates {
    let set = |rate: f32, axle: fn(&mut Stepping) -> &mut Axle| {
        critical_section::with(|cs| {
            let mut stepping = STEPPING.borrow(cs).borrow_mut();
            stepping
                .as_mut()
                .map_or(0.0, |s| axle(s).stepper.set_rate(rate))
        })
    };
    let set = Rates {
        ra_steps_per_s: set(rates.ra_steps_per_s, |s| &mut s.ra),
        dec_steps_per_s: set(rates.dec_steps_per_s, |s| &mut s.dec),
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
            .map_or((0, 0), |s| (s.ra.stepper.steps(), s.dec.stepper.steps()))
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

/// Guide frames, from the guiding task to the learning task. The loop keeps
/// the frames there is no room for here, and drops its oldest when the
/// learner falls further behind (counted).
static FRAMES: Channel<CriticalSectionRawMutex, FrameRecord, FRAME_QUEUE> = Channel::new();

/// The newest feed-forward, from the learning task to the guiding task (an
/// older one not yet installed is replaced).
static FEED_FORWARD: Signal<CriticalSectionRawMutex, FeedForward> = Signal::new();

/// The hal's edge queue, with the edge that woke the task first.
struct HalEdges<'a> {
    first: Option<PinEdge>,
    queue: &'a mut St4Edges,
}

impl EdgeSource for HalEdges<'_> {
    fn next_edge(&mut self) -> Option<RawEdge> {
        let e = self.first.take().or_else(|| self.queue.try_next())?;
        // The hal numbers its inputs in the order of `Line::ALL`.
        Some(RawEdge {
            line: Line::ALL[usize::from(e.index) % Line::ALL.len()],
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

fn axis_name(axis: Axis) -> &'static str {
    match axis {
        Axis::Ra => "RA",
        Axis::Dec => "Dec",
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

fn log_wake(wake: &Wake) {
    if wake.lost_edges > 0 {
        defmt::warn!(
            "ST4: {} edges lost (input storm?), resynchronised",
            wake.lost_edges
        );
    }
    for ev in &wake.events {
        log_event(ev);
    }
    if wake.more_events > 0 {
        defmt::info!("ST4: {} more events not logged", wake.more_events);
    }
    if let Some(c) = wake.st4_counters {
        log_counters(c);
        ST4_COUNTERS.lock(|s| s.set(Some(c)));
    }
}

/// Moves the hal's edges and the time into the loop, and its rates out.
#[embassy_executor::task]
async fn guiding_task(mut edges: St4Edges, mount: Mount) {
    let (ra_steps, _) = step_counts();
    let (mut lp, rates) = ControlLoop::start(&mount, Instant::now().as_micros(), ra_steps);
    let rates = set_rates(rates);
    defmt::info!(
        "tracking: RA {} steps/s, Dec {} steps/s",
        rates.ra_steps_per_s,
        rates.dec_steps_per_s
    );
    loop {
        let wake_at = Instant::from_micros(lp.next_wake_us());
        let first = match select(edges.next(), Timer::at(wake_at)).await {
            Either::First(edge) => Some(edge),
            Either::Second(()) => None,
        };
        // Every edge stamped before `now` is in the queue by now: the EXTI
        // interrupt preempts this task, and it stamps and queues in one go.
        let now_us = Instant::now().as_micros();
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
        log_wake(&wake);
    }
}

// ---------------------------------------------------------------------------
// Learning (thread mode, lowest priority)

/// The model's storage: a static, handed out once.
static LEARNER: StaticCell<Learner<STAGES>> = StaticCell::new();

/// Builds the model in [`LEARNER`]. Not inlined, so that its stack frame is
/// its own and can be read in the disassembly: `Learner::new` returns by
/// value, and LLVM builds most of it in a temporary on the stack
/// (`docs/firmware.md`).
#[inline(never)]
fn make_learner(mount: &Mount) -> Option<&'static mut Learner<STAGES>> {
    LEARNER.try_init_with(|| Learner::new(mount))
}

/// Runs the model once per guide frame (the longest thing that runs here)
/// and hands the feed-forward to the guiding task. Everything else preempts
/// it.
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
fn log_frame(learner: &Learner<STAGES>, msg: &FrameRecord, ff: &FeedForward) {
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

    let tick_hz = config.step_tick_hz;
    STEPPING.lock(|s| {
        s.replace(Some(Stepping {
            ticker,
            ra: Axle {
                stepper: AxisStepper::new(mount.max_ra_steps_per_s(), tick_hz),
                pins: ra,
            },
            dec: Axle {
                stepper: AxisStepper::new(mount.max_dec_steps_per_s(), tick_hz),
                pins: dec,
            },
        }))
    });
    critical_section::with(|cs| {
        if let Some(s) = STEPPING.borrow(cs).borrow_mut().as_mut() {
            s.ticker.start();
            s.ra.pins.set_enabled(true);
            s.dec.pins.set_enabled(true);
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
