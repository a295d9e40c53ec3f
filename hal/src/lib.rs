//! Board support for the mkgp-mount firmware, on top of `embassy-stm32`.
//!
//! Select exactly one chip with a cargo feature (`stm32f411ce`,
//! `stm32f446re` or `stm32f407vg`); the firmware forwards its own.
//!
//! - [`board`]: the documented pin map of each supported board, and the
//!   [`take_board!`] macro that moves those pins out of the `Peripherals`.
//! - [`clocks`]: system clock configuration per chip; [`clocks::init`] is the
//!   first call of the firmware and returns the `Peripherals`.
#![no_std]

#[cfg(not(any(
    feature = "stm32f411ce",
    feature = "stm32f446re",
    feature = "stm32f407vg"
)))]
compile_error!("mount-hal: select one chip feature: stm32f411ce, stm32f446re or stm32f407vg");

#[cfg(any(
    all(feature = "stm32f411ce", feature = "stm32f446re"),
    all(feature = "stm32f411ce", feature = "stm32f407vg"),
    all(feature = "stm32f446re", feature = "stm32f407vg"),
))]
compile_error!("mount-hal: select only one chip feature");

pub mod board;
pub mod clocks;

/// Re-exported so that users of the board types need not name the version.
pub use embassy_stm32;
