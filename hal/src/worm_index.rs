//! The optional worm-index sensor's input: PA1 (EXTI1) on every board
//! (Black Pill pin A1, Nucleo CN8 A1, Discovery P1 PA1), pulled up; the
//! sensor pulls it low as the worm's mark passes (an open-collector Hall
//! switch with a magnet on the worm, or a slotted optical switch with an
//! NPN output; 3.3 V logic). With nothing connected the pull-up keeps it
//! high and no pass is ever seen.

use embassy_stm32::exti::{self, ExtiInput};
use embassy_stm32::gpio::Pull;
use embassy_stm32::mode::Async;
use embassy_stm32::{bind_interrupts, interrupt, peripherals, Peri};

bind_interrupts!(struct Irqs {
    EXTI1 => exti::InterruptHandler<interrupt::typelevel::EXTI1>;
});

/// The input's pin and EXTI channel.
pub struct IndexPins {
    pub pin: Peri<'static, peripherals::PA1>,
    pub exti: Peri<'static, peripherals::EXTI1>,
}

/// The sensor's input.
pub struct IndexInput(ExtiInput<'static, Async>);

impl IndexInput {
    pub fn new(pins: IndexPins) -> Self {
        IndexInput(ExtiInput::new(pins.pin, pins.exti, Pull::Up, Irqs))
    }

    /// Waits for the mark to pass (a falling edge).
    pub async fn next_pass(&mut self) {
        self.0.wait_for_falling_edge().await
    }
}
