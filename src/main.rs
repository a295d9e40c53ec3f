//! Firmware entry point: boots the board, then runs the mount's tasks.
//!
//! For now it brings up the clocks through `hal`, logs a startup line over
//! defmt (RTT) and blinks the status LED with a heartbeat log line; guiding,
//! tracking and the gear-error model are added as their tasks land.
#![no_std]
#![no_main]

use defmt_rtt as _;
use panic_probe as _;

use embassy_executor::Spawner;
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_time::{Duration, Ticker};

/// Interval of the heartbeat log line and LED toggle.
const HEARTBEAT: Duration = Duration::from_secs(1);

#[embassy_executor::main]
async fn main(_spawner: Spawner) {
    let p = hal::clocks::init();
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
    let mut ticker = Ticker::every(HEARTBEAT);
    let mut beats: u32 = 0;
    loop {
        ticker.next().await;
        beats = beats.wrapping_add(1);
        led.toggle();
        defmt::info!("heartbeat {}", beats);
    }
}
