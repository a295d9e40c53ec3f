//! The chip's side of a reset: why it happened (RCC_CSR's flags), a reset on
//! demand, and the independent watchdog.

use embassy_stm32::pac;
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::Peri;

/// The reset flags (RCC_CSR) as they were at boot; clears them, so that
/// the next boot sees only its own reset's.
pub fn take_reset_flags() -> pac::rcc::regs::Csr {
    let csr = pac::RCC.csr().read();
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    csr
}

/// Resets the chip now.
pub fn reset() -> ! {
    cortex_m::peripheral::SCB::sys_reset()
}

/// The independent watchdog (IWDG, on its own 32 kHz LSI clock): once
/// started it resets the chip unless fed within its timeout, and nothing but
/// a reset stops it.
pub struct Watchdog(IndependentWatchdog<'static, IWDG>);

impl Watchdog {
    /// Starts the watchdog with `timeout_us`. The LSI runs anywhere from 17
    /// to 47 kHz on these chips, so the real timeout can be as short as
    /// 0.68 x `timeout_us`: feed well inside it. It is frozen while a
    /// debugger halts the core, so a breakpoint does not reset the board.
    pub fn start(iwdg: Peri<'static, IWDG>, timeout_us: u32) -> Self {
        pac::DBGMCU.apb1fzr().modify(|w| w.set_iwdg(true));
        let mut wdg = IndependentWatchdog::new(iwdg, timeout_us);
        wdg.unleash();
        Watchdog(wdg)
    }

    pub fn feed(&mut self) {
        self.0.pet();
    }
}
