//! The optional worm-index sensor's input: PA1 (EXTI1) on the F4 boards
//! (Black Pill pin A1, Nucleo CN8 A1, Discovery P1 PA1), PC4 (EXTI4,
//! Arduino A1) on the B-L475E-IOT01A, pulled up; the
//! sensor pulls it low as the worm's mark passes (an open-collector Hall
//! switch with a magnet on the worm, or a slotted optical switch with an
//! NPN output; 3.3 V logic). With nothing connected the pull-up keeps it
//! high and no pass is ever seen.

//!
//! The input's interrupt is this module's, not embassy-stm32's
//! `exti::InterruptHandler`: that handler takes every pending EXTI line,
//! the ST4 lines included (5-15, [`crate::st4`]), masks each and clears its
//! flag, so an ST4 edge pending when the mark passed was lost and its line
//! stayed masked for good. This one clears its own line's flag only.

use embassy_stm32::exti::{ExtiInput, TriggerEdge};
use embassy_stm32::gpio::Pull;
use embassy_stm32::mode::Blocking;
use embassy_stm32::{interrupt, pac, peripherals, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;

#[cfg(not(feature = "stm32l475vg"))]
mod chip {
    use super::*;
    pub type Pin = peripherals::PA1;
    pub type Exti = peripherals::EXTI1;
    /// The pin's EXTI line (its number).
    pub const LINE: usize = 1;
}

#[cfg(feature = "stm32l475vg")]
mod chip {
    use super::*;
    pub type Pin = peripherals::PC4;
    pub type Exti = peripherals::EXTI4;
    /// The pin's EXTI line (its number).
    pub const LINE: usize = 4;
}

/// A falling edge since the task last took one.
static PASS: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// The input's pin and EXTI channel.
pub struct IndexPins {
    pub pin: Peri<'static, chip::Pin>,
    pub exti: Peri<'static, chip::Exti>,
}

/// The sensor's input.
pub struct IndexInput {
    _input: ExtiInput<'static, Blocking>,
}

impl IndexInput {
    /// Interrupts on falling edges (embassy-stm32's init enabled the
    /// vector in the NVIC already).
    pub fn new(pins: IndexPins) -> Self {
        IndexInput {
            _input: ExtiInput::new_blocking(pins.pin, pins.exti, Pull::Up, TriggerEdge::Falling),
        }
    }

    /// Waits for the mark to pass (a falling edge).
    pub async fn next_pass(&mut self) {
        PASS.wait().await
    }
}

fn on_edge() {
    pac::EXTI.pr(0).write(|w| w.set_line(chip::LINE, true));
    PASS.signal(());
}

#[cfg(not(feature = "stm32l475vg"))]
#[interrupt]
fn EXTI1() {
    on_edge();
}

#[cfg(feature = "stm32l475vg")]
#[interrupt]
fn EXTI4() {
    on_edge();
}
