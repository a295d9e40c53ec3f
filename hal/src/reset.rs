//! The chip's side of a reset: why it happened (RCC_CSR's flags), a reset on
//! demand, and the independent watchdog.

use embassy_stm32::pac;
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::Peri;

/// Why the chip reset, as RCC_CSR's flags say.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ResetFlags {
    pub power_on: bool,
    pub brown_out: bool,
    pub pin: bool,
    pub software: bool,
    pub independent_watchdog: bool,
    pub window_watchdog: bool,
    pub low_power: bool,
}

/// The reset flags (RCC_CSR) as they were at boot; clears them, so that
/// the next boot sees only its own reset's.
pub fn take_reset_flags() -> ResetFlags {
    let csr = pac::RCC.csr().read();
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    #[cfg(not(feature = "stm32l475vg"))]
    let flags = ResetFlags {
        power_on: csr.porrstf(),
        brown_out: csr.borrstf(),
        pin: csr.padrstf(),
        software: csr.sftrstf(),
        independent_watchdog: csr.wdgrstf(),
        window_watchdog: csr.wwdgrstf(),
        low_power: csr.lpwrrstf(),
    };
    // The L4 has no power-on flag of its own: a power-on sets BORRSTF, as
    // a brown-out does. A power-on is by far the likelier, so that is what
    // it is called.
    #[cfg(feature = "stm32l475vg")]
    let flags = ResetFlags {
        power_on: csr.borrstf(),
        brown_out: false,
        pin: csr.pinrstf(),
        software: csr.sftrstf(),
        independent_watchdog: csr.iwdgrstf(),
        window_watchdog: csr.wwdgrstf(),
        low_power: csr.lpwrrstf(),
    };
    flags
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
        #[cfg(not(feature = "stm32l475vg"))]
        pac::DBGMCU.apb1fzr().modify(|w| w.set_iwdg(true));
        #[cfg(feature = "stm32l475vg")]
        pac::DBGMCU.apb1fzr1().modify(|w| w.set_iwdg(true));
        let mut wdg = IndependentWatchdog::new(iwdg, timeout_us);
        wdg.unleash();
        Watchdog(wdg)
    }

    pub fn feed(&mut self) {
        self.0.pet();
    }
}
