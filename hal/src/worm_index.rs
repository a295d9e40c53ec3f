//! The optional worm-index sensor's input: PA1 (EXTI1) on the F4 boards
//! (Black Pill pin A1, Nucleo CN8 A1, Discovery P1 PA1), PC4 (EXTI4,
//! Arduino A1) on the B-L475E-IOT01A, pulled up; the
//! sensor pulls it low as the worm's mark passes (an open-collector Hall
//! switch with a magnet on the worm, or a slotted optical switch with an
//! NPN output; 3.3 V logic). With nothing connected the pull-up keeps it
//! high and no pass is ever seen.

use embassy_stm32::exti::{self, ExtiInput};
use embassy_stm32::gpio::Pull;
use embassy_stm32::mode::Async;
use embassy_stm32::{bind_interrupts, interrupt, peripherals, Peri};

#[cfg(not(feature = "stm32l475vg"))]
mod chip {
    use super::*;
    bind_interrupts!(pub struct Irqs {
        EXTI1 => exti::InterruptHandler<interrupt::typelevel::EXTI1>;
    });
    pub type Pin = peripherals::PA1;
    pub type Exti = peripherals::EXTI1;
}

#[cfg(feature = "stm32l475vg")]
mod chip {
    use super::*;
    bind_interrupts!(pub struct Irqs {
        EXTI4 => exti::InterruptHandler<interrupt::typelevel::EXTI4>;
    });
    pub type Pin = peripherals::PC4;
    pub type Exti = peripherals::EXTI4;
}

/// The input's pin and EXTI channel.
pub struct IndexPins {
    pub pin: Peri<'static, chip::Pin>,
    pub exti: Peri<'static, chip::Exti>,
}

/// The sensor's input.
pub struct IndexInput(ExtiInput<'static, Async>);

impl IndexInput {
    pub fn new(pins: IndexPins) -> Self {
        IndexInput(ExtiInput::new(pins.pin, pins.exti, Pull::Up, chip::Irqs))
    }

    /// Waits for the mark to pass (a falling edge).
    pub async fn next_pass(&mut self) {
        self.0.wait_for_falling_edge().await
    }
}
