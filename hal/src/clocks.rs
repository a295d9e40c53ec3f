//! System clock configuration.
//!
//! | board | source | PLL (M, N, P, Q) | SYSCLK | HCLK | APB1 | APB2 | 48 MHz (Q) |
//! |---|---|---|---|---|---|---|---|
//! | WeAct Black Pill F411CE | 25 MHz crystal | 25, 192, 2, 4 | 96 MHz | 96 MHz | 48 MHz | 96 MHz | yes |
//! | Nucleo-F446RE | 8 MHz from ST-LINK MCO, HSE bypass | 4, 180, 2, 8 | 180 MHz | 180 MHz | 45 MHz | 90 MHz | no (45 MHz) |
//! | STM32F4-Discovery (F407VG) | 8 MHz crystal | 4, 168, 2, 7 | 168 MHz | 168 MHz | 42 MHz | 84 MHz | yes |
//! | B-L475E-IOT01A (L475VG) | 4 MHz MSI locked to the 32.768 kHz LSE crystal | 1, 40, R 2 | 80 MHz | 80 MHz | 80 MHz | 80 MHz | no |
//!
//! The PLL input is 1 MHz (F411) or 2 MHz (F446, F407), within the 1-2 MHz
//! range of the reference manuals, and the VCO runs at 192, 360 and 336 MHz.
//! F411CE runs at 96 rather than 100 MHz so that the Q output is exactly
//! 48 MHz for USB. On the F446 embassy enables over-drive, which 180 MHz
//! needs. Flash wait states and voltage scaling are set by embassy from the
//! resulting HCLK.
//!
//! The L475 board has no HSE crystal: its MSI runs in PLL mode against the
//! LSE (embassy turns that on with a 32.768 kHz LSE), which holds it to the
//! crystal's accuracy (tens of ppm) instead of the MSI's own 1 %, as the
//! tracking rate needs. Its voltage range 1 allows the 80 MHz.

use embassy_stm32::rcc::{AHBPrescaler, APBPrescaler, Pll, PllMul, PllPreDiv, PllSource, Sysclk};
#[cfg(not(feature = "stm32l475vg"))]
use embassy_stm32::rcc::{Hse, HseMode, PllPDiv, PllQDiv};
#[cfg(feature = "stm32l475vg")]
use embassy_stm32::rcc::{LsConfig, MSIRange, PllRDiv};
#[cfg(not(feature = "stm32l475vg"))]
use embassy_stm32::time::Hertz;
use embassy_stm32::{Config, Peripherals};

/// System clock (HCLK) after [`init`], in Hz.
#[cfg(feature = "stm32f411ce")]
pub const SYSCLK_HZ: u32 = 96_000_000;
/// System clock (HCLK) after [`init`], in Hz.
#[cfg(feature = "stm32f446re")]
pub const SYSCLK_HZ: u32 = 180_000_000;
/// System clock (HCLK) after [`init`], in Hz.
#[cfg(feature = "stm32f407vg")]
pub const SYSCLK_HZ: u32 = 168_000_000;

/// System clock (HCLK) after [`init`], in Hz.
#[cfg(feature = "stm32l475vg")]
pub const SYSCLK_HZ: u32 = 80_000_000;

/// NVIC priority of embassy's time driver (below the step tick's `P0`).
pub const TIME_DRIVER_PRIORITY: embassy_stm32::interrupt::Priority =
    embassy_stm32::interrupt::Priority::P1;

/// The embassy configuration for this board: clock tree as in the table above.
pub fn config() -> Config {
    let mut config = Config::default();
    let rcc = &mut config.rcc;

    #[cfg(feature = "stm32f411ce")]
    {
        rcc.hse = Some(Hse {
            freq: Hertz::mhz(25),
            mode: HseMode::Oscillator,
        });
        rcc.pll = Some(Pll {
            prediv: PllPreDiv::DIV25,
            mul: PllMul::MUL192,
            divp: Some(PllPDiv::DIV2),
            divq: Some(PllQDiv::DIV4),
            divr: None,
        });
        rcc.apb1_pre = APBPrescaler::DIV2;
        rcc.apb2_pre = APBPrescaler::DIV1;
    }

    #[cfg(feature = "stm32f446re")]
    {
        rcc.hse = Some(Hse {
            freq: Hertz::mhz(8),
            mode: HseMode::Bypass,
        });
        rcc.pll = Some(Pll {
            prediv: PllPreDiv::DIV4,
            mul: PllMul::MUL180,
            divp: Some(PllPDiv::DIV2),
            divq: Some(PllQDiv::DIV8),
            divr: None,
        });
        rcc.apb1_pre = APBPrescaler::DIV4;
        rcc.apb2_pre = APBPrescaler::DIV2;
    }

    #[cfg(feature = "stm32f407vg")]
    {
        rcc.hse = Some(Hse {
            freq: Hertz::mhz(8),
            mode: HseMode::Oscillator,
        });
        rcc.pll = Some(Pll {
            prediv: PllPreDiv::DIV4,
            mul: PllMul::MUL168,
            divp: Some(PllPDiv::DIV2),
            divq: Some(PllQDiv::DIV7),
            divr: None,
        });
        rcc.apb1_pre = APBPrescaler::DIV4;
        rcc.apb2_pre = APBPrescaler::DIV2;
    }

    #[cfg(not(feature = "stm32l475vg"))]
    {
        rcc.pll_src = PllSource::HSE;
        rcc.sys = Sysclk::PLL1_P;
    }

    #[cfg(feature = "stm32l475vg")]
    {
        rcc.ls = LsConfig::default_lse();
        rcc.msi = Some(MSIRange::RANGE4M);
        rcc.pll = Some(Pll {
            source: PllSource::MSI,
            prediv: PllPreDiv::DIV1,
            mul: PllMul::MUL40,
            divp: None,
            divq: None,
            divr: Some(PllRDiv::DIV2),
        });
        rcc.sys = Sysclk::PLL1_R;
        rcc.apb1_pre = APBPrescaler::DIV1;
        rcc.apb2_pre = APBPrescaler::DIV1;
    }

    rcc.hsi = false;
    rcc.ahb_pre = AHBPrescaler::DIV1;
    config
}

/// Configures the clocks and the time driver (at [`TIME_DRIVER_PRIORITY`])
/// and returns the peripherals. Call once, first thing in `main`.
pub fn init() -> Peripherals {
    let p = embassy_stm32::init(config());
    #[cfg(not(feature = "stm32l475vg"))]
    {
        use embassy_stm32::interrupt::InterruptExt;
        embassy_stm32::interrupt::TIM5.set_priority(TIME_DRIVER_PRIORITY);
    }
    #[cfg(feature = "stm32l475vg")]
    crate::systick_time::start(SYSCLK_HZ, TIME_DRIVER_PRIORITY);
    defmt::info!("clocks: SYSCLK {} Hz", SYSCLK_HZ);
    p
}
