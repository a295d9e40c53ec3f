//! Pin map of each supported board.
//!
//! The ST4 autoguider port has four active-low inputs (the camera pulls a
//! line to ground for the length of a guide pulse); they are wired to pins on
//! distinct EXTI lines so each can interrupt on its own. Each axis has a
//! stepper driver (A4988 / DRV8825 / TMC2209 style) with STEP, DIR and an
//! active-low ENABLE; the STEP pins are timer channel 1 outputs so that step
//! pulses can later come from hardware timers. Pins used by the board itself
//! (SWD, crystal, USB, on-board peripherals) are left alone.
//!
//! | signal | Black Pill F411CE | Nucleo-F446RE | Discovery F407VG | B-L475E-IOT01A (Arduino header) |
//! |---|---|---|---|---|
//! | ST4 RA+ (west)  | PB12 (EXTI12) | PC8 (EXTI8), CN10-2 | PD8 (EXTI8) | PB8 (EXTI8), D15 |
//! | ST4 RA- (east)  | PB13 (EXTI13) | PC9 (EXTI9), CN10-1 | PD9 (EXTI9) | PB9 (EXTI9), D14 |
//! | ST4 Dec+ (north)| PB14 (EXTI14) | PC10 (EXTI10), CN7-1 | PD10 (EXTI10) | PD14 (EXTI14), D2 |
//! | ST4 Dec- (south)| PB15 (EXTI15) | PC11 (EXTI11), CN7-2 | PD11 (EXTI11) | PA15 (EXTI15), D9 |
//! | RA STEP         | PA8 (TIM1_CH1) | PA8 (TIM1_CH1), D7 | PE9 (TIM1_CH1) | PB4 (TIM3_CH1), D5 |
//! | RA DIR          | PB0 | PB4, D5 | PE7 | PB0, D3 |
//! | RA ENABLE (low) | PB1 | PB5, D4 | PE8 | PA4, D7 |
//! | Dec STEP        | PB6 (TIM4_CH1) | PB6 (TIM4_CH1), D10 | PC6 (TIM3_CH1 / TIM8_CH1) | PA2 (TIM15_CH1), D10 |
//! | Dec DIR         | PB4 | PB10, D6 | PE10 | PA7, D11 |
//! | Dec ENABLE (low)| PB5 | PA9, D8 | PE12 | PA6, D12 |
//! | status LED      | PC13 (active low) | PA5 = LD2, D13 (active high) | PD12 = LD4 green (active high) | PB14 = LED2 green (active high) |
//! | worm index (optional, low at the mark) | PA1 (EXTI1) | PA1 (EXTI1), A1 | PA1 (EXTI1) | PC4 (EXTI4), A1 |
//!
//! The command port's USB and UART pins are in [`crate::serial`]'s table.
//! Left free on purpose: SPI1 PA5-PA7 on the Black Pill (driver
//! configuration), the audio codec and accelerometer on the Discovery, and
//! the B-L475E-IOT01A's sensors, radios and QSPI flash (its Arduino header
//! carries the mount's signals; D0/D1 are port 1's UART).
//!
//! The types below name the concrete embassy peripherals of the selected
//! chip; [`take_board!`](crate::take_board) moves them out of the
//! `Peripherals` (leaving the rest usable) into a [`Board`].

use embassy_stm32::{Peri, PeripheralType};

/// Concrete pin and EXTI channel types of the selected board.
#[cfg(feature = "stm32f411ce")]
pub mod pins {
    use embassy_stm32::peripherals as p;
    pub type St4RaPlus = p::PB12;
    pub type St4RaPlusExti = p::EXTI12;
    pub type St4RaMinus = p::PB13;
    pub type St4RaMinusExti = p::EXTI13;
    pub type St4DecPlus = p::PB14;
    pub type St4DecPlusExti = p::EXTI14;
    pub type St4DecMinus = p::PB15;
    pub type St4DecMinusExti = p::EXTI15;
    pub type RaStep = p::PA8;
    pub type RaDir = p::PB0;
    pub type RaEnable = p::PB1;
    pub type DecStep = p::PB6;
    pub type DecDir = p::PB4;
    pub type DecEnable = p::PB5;
    pub type Led = p::PC13;
    /// The LED lights when its pin is low.
    pub const LED_ACTIVE_LOW: bool = true;
}

/// Concrete pin and EXTI channel types of the selected board.
#[cfg(feature = "stm32f446re")]
pub mod pins {
    use embassy_stm32::peripherals as p;
    pub type St4RaPlus = p::PC8;
    pub type St4RaPlusExti = p::EXTI8;
    pub type St4RaMinus = p::PC9;
    pub type St4RaMinusExti = p::EXTI9;
    pub type St4DecPlus = p::PC10;
    pub type St4DecPlusExti = p::EXTI10;
    pub type St4DecMinus = p::PC11;
    pub type St4DecMinusExti = p::EXTI11;
    pub type RaStep = p::PA8;
    pub type RaDir = p::PB4;
    pub type RaEnable = p::PB5;
    pub type DecStep = p::PB6;
    pub type DecDir = p::PB10;
    pub type DecEnable = p::PA9;
    pub type Led = p::PA5;
    /// The LED lights when its pin is low.
    pub const LED_ACTIVE_LOW: bool = false;
}

/// Concrete pin and EXTI channel types of the selected board.
#[cfg(feature = "stm32f407vg")]
pub mod pins {
    use embassy_stm32::peripherals as p;
    pub type St4RaPlus = p::PD8;
    pub type St4RaPlusExti = p::EXTI8;
    pub type St4RaMinus = p::PD9;
    pub type St4RaMinusExti = p::EXTI9;
    pub type St4DecPlus = p::PD10;
    pub type St4DecPlusExti = p::EXTI10;
    pub type St4DecMinus = p::PD11;
    pub type St4DecMinusExti = p::EXTI11;
    pub type RaStep = p::PE9;
    pub type RaDir = p::PE7;
    pub type RaEnable = p::PE8;
    pub type DecStep = p::PC6;
    pub type DecDir = p::PE10;
    pub type DecEnable = p::PE12;
    pub type Led = p::PD12;
    /// The LED lights when its pin is low.
    pub const LED_ACTIVE_LOW: bool = false;
}

/// Concrete pin and EXTI channel types of the selected board.
#[cfg(feature = "stm32l475vg")]
pub mod pins {
    use embassy_stm32::peripherals as p;
    pub type St4RaPlus = p::PB8;
    pub type St4RaPlusExti = p::EXTI8;
    pub type St4RaMinus = p::PB9;
    pub type St4RaMinusExti = p::EXTI9;
    pub type St4DecPlus = p::PD14;
    pub type St4DecPlusExti = p::EXTI14;
    pub type St4DecMinus = p::PA15;
    pub type St4DecMinusExti = p::EXTI15;
    pub type RaStep = p::PB4;
    pub type RaDir = p::PB0;
    pub type RaEnable = p::PA4;
    pub type DecStep = p::PA2;
    pub type DecDir = p::PA7;
    pub type DecEnable = p::PA6;
    pub type Led = p::PB14;
    /// The LED lights when its pin is low.
    pub const LED_ACTIVE_LOW: bool = false;
}

pub use pins::LED_ACTIVE_LOW;

/// The four ST4 inputs with their EXTI channels.
pub struct St4Pins {
    pub ra_plus: Peri<'static, pins::St4RaPlus>,
    pub ra_plus_exti: Peri<'static, pins::St4RaPlusExti>,
    pub ra_minus: Peri<'static, pins::St4RaMinus>,
    pub ra_minus_exti: Peri<'static, pins::St4RaMinusExti>,
    pub dec_plus: Peri<'static, pins::St4DecPlus>,
    pub dec_plus_exti: Peri<'static, pins::St4DecPlusExti>,
    pub dec_minus: Peri<'static, pins::St4DecMinus>,
    pub dec_minus_exti: Peri<'static, pins::St4DecMinusExti>,
}

/// STEP, DIR and (active-low) ENABLE of one stepper driver.
pub struct AxisPins<
    Step: PeripheralType + 'static,
    Dir: PeripheralType + 'static,
    Enable: PeripheralType + 'static,
> {
    pub step: Peri<'static, Step>,
    pub dir: Peri<'static, Dir>,
    pub enable: Peri<'static, Enable>,
}

/// Right-ascension axis pins.
pub type RaPins = AxisPins<pins::RaStep, pins::RaDir, pins::RaEnable>;
/// Declination axis pins.
pub type DecPins = AxisPins<pins::DecStep, pins::DecDir, pins::DecEnable>;

/// The command port's pins on this board (`crate::serial` has the map).
#[cfg(any(feature = "stm32f411ce", feature = "stm32f407vg"))]
pub struct PortPins {
    pub usb: crate::serial::UsbPins,
    pub aux: crate::serial::AuxPins,
}

/// The command port's pins on this board (`crate::serial` has the map).
#[cfg(any(feature = "stm32f446re", feature = "stm32l475vg"))]
pub struct PortPins {
    pub vcp: crate::serial::VcpPins,
    pub aux: crate::serial::AuxPins,
}

/// Every pin the firmware uses on this board.
pub struct Board {
    pub st4: St4Pins,
    pub ra: RaPins,
    pub dec: DecPins,
    pub led: Peri<'static, pins::Led>,
    pub ports: PortPins,
    pub index: crate::worm_index::IndexPins,
}

/// Moves the board's pins out of an `embassy_stm32::Peripherals` binding and
/// returns a [`Board`](crate::board::Board); the other peripherals stay in
/// the binding (a partial move).
///
/// ```ignore
/// let p = hal::clocks::init();
/// let board = hal::take_board!(p);
/// ```
#[cfg(feature = "stm32f411ce")]
#[macro_export]
macro_rules! take_board {
    ($p:ident) => {
        $crate::board::Board {
            st4: $crate::board::St4Pins {
                ra_plus: $p.PB12,
                ra_plus_exti: $p.EXTI12,
                ra_minus: $p.PB13,
                ra_minus_exti: $p.EXTI13,
                dec_plus: $p.PB14,
                dec_plus_exti: $p.EXTI14,
                dec_minus: $p.PB15,
                dec_minus_exti: $p.EXTI15,
            },
            ra: $crate::board::AxisPins {
                step: $p.PA8,
                dir: $p.PB0,
                enable: $p.PB1,
            },
            dec: $crate::board::AxisPins {
                step: $p.PB6,
                dir: $p.PB4,
                enable: $p.PB5,
            },
            led: $p.PC13,
            index: $crate::worm_index::IndexPins {
                pin: $p.PA1,
                exti: $p.EXTI1,
            },
            ports: $crate::board::PortPins {
                usb: $crate::serial::UsbPins {
                    usb: $p.USB_OTG_FS,
                    dp: $p.PA12,
                    dm: $p.PA11,
                },
                aux: $crate::serial::UartPins {
                    uart: $p.USART1,
                    tx: $p.PA9,
                    rx: $p.PA10,
                },
            },
        }
    };
}

/// Moves the board's pins out of an `embassy_stm32::Peripherals` binding and
/// returns a [`Board`](crate::board::Board); the other peripherals stay in
/// the binding (a partial move).
#[cfg(feature = "stm32f446re")]
#[macro_export]
macro_rules! take_board {
    ($p:ident) => {
        $crate::board::Board {
            st4: $crate::board::St4Pins {
                ra_plus: $p.PC8,
                ra_plus_exti: $p.EXTI8,
                ra_minus: $p.PC9,
                ra_minus_exti: $p.EXTI9,
                dec_plus: $p.PC10,
                dec_plus_exti: $p.EXTI10,
                dec_minus: $p.PC11,
                dec_minus_exti: $p.EXTI11,
            },
            ra: $crate::board::AxisPins {
                step: $p.PA8,
                dir: $p.PB4,
                enable: $p.PB5,
            },
            dec: $crate::board::AxisPins {
                step: $p.PB6,
                dir: $p.PB10,
                enable: $p.PA9,
            },
            led: $p.PA5,
            index: $crate::worm_index::IndexPins {
                pin: $p.PA1,
                exti: $p.EXTI1,
            },
            ports: $crate::board::PortPins {
                vcp: $crate::serial::UartPins {
                    uart: $p.USART2,
                    tx: $p.PA2,
                    rx: $p.PA3,
                },
                aux: $crate::serial::UartPins {
                    uart: $p.USART6,
                    tx: $p.PC6,
                    rx: $p.PC7,
                },
            },
        }
    };
}

/// Moves the board's pins out of an `embassy_stm32::Peripherals` binding and
/// returns a [`Board`](crate::board::Board); the other peripherals stay in
/// the binding (a partial move).
#[cfg(feature = "stm32f407vg")]
#[macro_export]
macro_rules! take_board {
    ($p:ident) => {
        $crate::board::Board {
            st4: $crate::board::St4Pins {
                ra_plus: $p.PD8,
                ra_plus_exti: $p.EXTI8,
                ra_minus: $p.PD9,
                ra_minus_exti: $p.EXTI9,
                dec_plus: $p.PD10,
                dec_plus_exti: $p.EXTI10,
                dec_minus: $p.PD11,
                dec_minus_exti: $p.EXTI11,
            },
            ra: $crate::board::AxisPins {
                step: $p.PE9,
                dir: $p.PE7,
                enable: $p.PE8,
            },
            dec: $crate::board::AxisPins {
                step: $p.PC6,
                dir: $p.PE10,
                enable: $p.PE12,
            },
            led: $p.PD12,
            index: $crate::worm_index::IndexPins {
                pin: $p.PA1,
                exti: $p.EXTI1,
            },
            ports: $crate::board::PortPins {
                usb: $crate::serial::UsbPins {
                    usb: $p.USB_OTG_FS,
                    dp: $p.PA12,
                    dm: $p.PA11,
                },
                aux: $crate::serial::UartPins {
                    uart: $p.USART2,
                    tx: $p.PA2,
                    rx: $p.PA3,
                },
            },
        }
    };
}

/// Moves the board's pins out of an `embassy_stm32::Peripherals` binding and
/// returns a [`Board`](crate::board::Board); the other peripherals stay in
/// the binding (a partial move).
#[cfg(feature = "stm32l475vg")]
#[macro_export]
macro_rules! take_board {
    ($p:ident) => {
        $crate::board::Board {
            st4: $crate::board::St4Pins {
                ra_plus: $p.PB8,
                ra_plus_exti: $p.EXTI8,
                ra_minus: $p.PB9,
                ra_minus_exti: $p.EXTI9,
                dec_plus: $p.PD14,
                dec_plus_exti: $p.EXTI14,
                dec_minus: $p.PA15,
                dec_minus_exti: $p.EXTI15,
            },
            ra: $crate::board::AxisPins {
                step: $p.PB4,
                dir: $p.PB0,
                enable: $p.PA4,
            },
            dec: $crate::board::AxisPins {
                step: $p.PA2,
                dir: $p.PA7,
                enable: $p.PA6,
            },
            led: $p.PB14,
            index: $crate::worm_index::IndexPins {
                pin: $p.PC4,
                exti: $p.EXTI4,
            },
            ports: $crate::board::PortPins {
                vcp: $crate::serial::UartPins {
                    uart: $p.USART1,
                    tx: $p.PB6,
                    rx: $p.PB7,
                },
                aux: $crate::serial::UartPins {
                    uart: $p.UART4,
                    tx: $p.PA0,
                    rx: $p.PA1,
                },
            },
        }
    };
}
