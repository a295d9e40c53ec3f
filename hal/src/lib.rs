//! Board support for the mkgp-mount firmware, on top of `embassy-stm32`.
//!
//! Select exactly one chip with a cargo feature (`stm32f411ce`,
//! `stm32f446re`, `stm32f407vg` or `stm32l475vg`); the firmware forwards
//! its own.
//!
//! - [`board`]: the documented pin map of each supported board, and the
//!   [`take_board!`] macro that moves those pins out of the `Peripherals`.
//! - [`clocks`]: system clock configuration per chip; [`clocks::init`] is the
//!   first call of the firmware and returns the `Peripherals`.
//! - [`st4`]: the ST4 guide port's four inputs on EXTI, each edge
//!   timestamped in its interrupt and queued for one task.
//! - [`stepper`]: STEP/DIR/ENABLE of each axis and the step tick timer, and
//!   [`stepper::force_drivers_off`] for the fault path.
//! - [`reset`]: the reset flags, a reset on demand and the independent
//!   watchdog.
//! - [`serial`]: the command port's transports, USB CDC-ACM and UARTs.
//! - [`flash_map`], [`storage`]: where the store's sectors are, and the
//!   flash driver that reaches them.
//! - [`worm_index`]: the optional worm-index sensor's input.
//! - `systick_time` (the L475 board only): SysTick as embassy-time's
//!   driver and as the step tick's source.
//!
//! This crate knows the hardware only; what edges mean and how many steps to
//! make is the `mkgp-mount` library's business, glued together in the
//! firmware's `main.rs` (the firmware depends on this crate, so this crate
//! cannot depend back on the library without a package cycle).
//!
//! Interrupt priorities (NVIC, lower number = more urgent): step tick `P0`;
//! ST4 EXTI and embassy's time driver (TIM5, or SysTick on the L475) `P1`; the firmware's
//! high-priority executor `P2`; thread mode below all of them.
#![no_std]

#[cfg(not(any(
    feature = "stm32f411ce",
    feature = "stm32f446re",
    feature = "stm32f407vg",
    feature = "stm32l475vg"
)))]
compile_error!(
    "mount-hal: select one chip feature: stm32f411ce, stm32f446re, stm32f407vg or stm32l475vg"
);

#[cfg(any(
    all(feature = "stm32f411ce", feature = "stm32f446re"),
    all(feature = "stm32f411ce", feature = "stm32f407vg"),
    all(feature = "stm32f411ce", feature = "stm32l475vg"),
    all(feature = "stm32f446re", feature = "stm32f407vg"),
    all(feature = "stm32f446re", feature = "stm32l475vg"),
    all(feature = "stm32f407vg", feature = "stm32l475vg"),
))]
compile_error!("mount-hal: select only one chip feature");

#[cfg(all(feature = "emulator-tick", not(feature = "stm32l475vg")))]
compile_error!("mount-hal: emulator-tick is for the stm32l475vg build in QEMU only");

pub mod board;
pub mod clocks;
pub mod flash_map;
pub mod reset;
pub mod serial;
pub mod st4;
pub mod stepper;
pub mod storage;
#[cfg(feature = "stm32l475vg")]
pub mod systick_time;
pub mod worm_index;

/// Re-exported so that users of the board types need not name the version.
pub use embassy_stm32;
