//! Firmware entry point: boots the board, validates the mount configuration,
//! then tracks at the sidereal rate, obeys ST4 guide pulses and learns the
//! gear error, whose predicted rate it adds to the RA rate (feed-forward).
//!
//! This file only wires hardware to the library's loop
//! ([`mkgp_mount::control_loop`]), which decides everything and which the
//! simulator drives too; `hal` moves the pins and timers. Priorities (NVIC,
//! lower number first):
//!
//! - **Step tick** ([`firmware::step_tick`]; `TIM2`, `P0`, at
//!   `step_tick_hz`): each axis's `AxisStepper::tick` says what to change
//!   on STEP and DIR; `hal`'s `StepAxis` changes it.
//! - **ST4 edges** (`EXTI9_5`/`EXTI15_10`, `P1`, in `hal::st4`): each edge is
//!   timestamped in its interrupt and queued. embassy's time driver (`TIM5`;
//!   SysTick on the L475 board) is at `P1` too.
//! - **Guiding task** ([`firmware::guiding_task`], on an `InterruptExecutor`
//!   on the otherwise unused `SPI3` vector at `P2`): sleeps until an edge or
//!   `ControlLoop::next_wake_us`, then hands the queued edges, the time, the
//!   RA step count and the newest feed-forward to `ControlLoop::wake`, sets
//!   the rates it returns, moves completed frames to the learning task while
//!   there is room, and logs.
//! - **Command ports** ([`firmware::port_io`]): USB CDC-ACM (or the
//!   Nucleo's ST-LINK UART) and a plain UART, in thread mode; their bytes
//!   reach the guiding task through pipes, and the guiding task interprets
//!   them on the loop (`hal::serial` has the pins).
//! - **Thread mode** (lowest): the learning task
//!   ([`firmware::learning_task`]) runs the model, a `Learner<STAGES>` in a
//!   static, once per frame, and signals the feed-forward to the guiding
//!   task, which installs it at its next wake-up (within `RATE_UPDATE_US`);
//!   it resets, saves and restores the model as the library's
//!   `control_loop::learning::LearningPolicy` decides.
//!   The status log ([`firmware::log`]) and the LED run here too. Everything
//!   above preempts it, so the model never delays a pulse or a step.
//!
//! `docs/firmware.md` has the memory layout at start-up and the latency from
//! an ST4 edge to the new rate.
#![no_std]
#![no_main]

mod firmware;

use defmt_rtt as _;

use embassy_executor::Spawner;
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_time::{Duration, Ticker};

use firmware::guiding_task::{guiding_task, EXECUTOR_HIGH};
use firmware::learning_task::{learning_task, make_learner};
use firmware::{fault, log, step_tick};
use hal::stepper::{StepAxis, StepTicker};
use mkgp_mount::mount::config::MountConfig;

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
/// Timeout of the independent watchdog, µs: above the longest flash
/// sector erase (2 s, the datasheet's maximum), during which every flash
/// read, the guiding task's that feeds the watchdog included, stalls.
const WATCHDOG_TIMEOUT_US: u32 = 4_000_000;
/// Where RAM starts (memory.x); flip-link puts the bottom of the stack here.
const RAM_ORIGIN: u32 = 0x2000_0000;
/// Periodic stages of the gear-error model (the library's choice).
pub(crate) use mkgp_mount::mount::learner::FIRMWARE_STAGES as STAGES;

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    // SAFETY: first thing; nothing lies in the megabyte below RAM.
    unsafe { mkgp_mount::safety::fault_entry::install_stack_guard(RAM_ORIGIN) };
    let p = hal::clocks::init();
    let last_reset = fault::take_last_reset();
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

    // The configuration (the stored one, or the defaults) and the park the
    // mount was switched off in, if any.
    let mut store = firmware::storage::open(p.FLASH);
    let (config, park) = match store.as_deref_mut() {
        Some(store) => (
            firmware::storage::boot_config(store).await,
            firmware::storage::boot_park(store).await,
        ),
        None => (MountConfig::default(), None),
    };
    // Test-only: the emulator's slower tick is the configuration's too,
    // with a top speed it can step (half the tick: 3 x sidereal).
    #[cfg(feature = "emulator-tick")]
    let config = MountConfig {
        step_tick_hz: hal::systick_time::TICK_HZ,
        max_rate_sidereal: 3.0,
        ..config
    };
    let running = start(
        spawner,
        Hardware {
            tim: p.TIM2,
            iwdg: p.IWDG,
            ra,
            dec,
            st4_pins: board.st4,
            index_pins: board.index,
        },
        config,
        Boot {
            store,
            park,
            reset_cause: last_reset.cause,
        },
    );
    // The ports answer even with the motors disabled: they tell why.
    if let Err(which) = firmware::port_io::start(spawner, board.ports) {
        defmt::error!("command port: {} did not start", which);
    }
    if running.is_err() {
        defmt::error!("motors stay disabled; fix the configuration and reflash");
    }

    let mut ticker = Ticker::every(HEARTBEAT);
    let mut beats: u32 = 0;
    loop {
        ticker.next().await;
        beats = beats.wrapping_add(1);
        led.toggle();
        if !beats.is_multiple_of(STATUS_EVERY) {
            continue;
        }
        match running {
            Ok(()) => log::status(),
            Err(()) => defmt::error!("configuration refused at start-up; motors disabled"),
        }
        fault::log_last_reset(&last_reset);
    }
}

/// What `start` drives.
struct Hardware {
    tim: embassy_stm32::Peri<'static, hal::stepper::StepTimer>,
    iwdg: embassy_stm32::Peri<'static, embassy_stm32::peripherals::IWDG>,
    ra: StepAxis,
    dec: StepAxis,
    st4_pins: hal::board::St4Pins,
    index_pins: hal::worm_index::IndexPins,
}

/// What the boot found: the store, the park, why the board started.
struct Boot {
    store: Option<&'static mut firmware::storage::FirmwareStore>,
    park: Option<mkgp_mount::persist::Park>,
    reset_cause: mkgp_mount::safety::reset_cause::ResetCause,
}

/// Validates the configuration, builds the model, starts the step tick
/// (from the parked counts, if the mount was parked), enables the drivers
/// and starts the guiding task (high priority) and the learning task (on
/// `spawner`, thread mode, with the store if there is one), and the
/// watchdog. On a refused configuration: logs why and returns with the
/// drivers disabled and nothing started.
fn start(spawner: Spawner, hw: Hardware, config: MountConfig, boot: Boot) -> Result<(), ()> {
    let Boot {
        store,
        park,
        reset_cause,
    } = boot;
    let Hardware {
        tim,
        iwdg,
        ra,
        dec,
        st4_pins,
        index_pins,
    } = hw;
    let mount = match config.validate() {
        Ok(mount) => mount,
        Err(e) => {
            log::config_refused(&e);
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
    let has_store = store.is_some();
    let storage = match (store, firmware::storage::snapshot_buffer()) {
        (Some(store), Some(buf)) => Some(firmware::learning_task::Storage {
            store,
            buf,
            // Only a model saved with the park is on its counts' clock.
            parked: park.is_some_and(|p| p.carries_model),
            index: mkgp_mount::mount::worm_index::WormIndex::new(&mount),
        }),
        _ => None,
    };
    match learning_task(learner, storage) {
        Ok(token) => spawner.spawn(token),
        Err(_) => {
            defmt::error!("learning task could not be spawned");
            return Err(());
        }
    }

    let counts = park.map_or((0, 0), |p| (p.ra_steps, p.dec_steps));
    step_tick::start(ticker, ra, dec, &mount, counts);

    let edges = hal::st4::start(st4_pins, firmware::guiding_task::allow_edge);
    interrupt::SPI3.set_priority(EXECUTOR_HIGH_PRIORITY);
    let high = EXECUTOR_HIGH.start(interrupt::SPI3);
    // From here on a hung guiding task resets the board.
    let watchdog = hal::reset::Watchdog::start(iwdg, WATCHDOG_TIMEOUT_US);
    match guiding_task(edges, mount, watchdog, reset_cause, has_store) {
        Ok(token) => high.spawn(token),
        Err(_) => {
            defmt::error!("guiding task could not be spawned");
            return Err(());
        }
    }
    // The worm index only matters with a store to restore from.
    if has_store {
        let input = hal::worm_index::IndexInput::new(index_pins);
        match firmware::guiding_task::index_task(input) {
            Ok(token) => high.spawn(token),
            Err(_) => defmt::error!("worm-index task could not be spawned"),
        }
    }
    Ok(())
}
