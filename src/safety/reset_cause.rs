//! Why the board last started, from the reset flags the chip keeps (RCC_CSR
//! on the STM32F4, read and cleared by the board at boot).

/// The chip's reset flags, one per source.
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

/// The cause of the last reset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetCause {
    PowerOn,
    BrownOut,
    /// The independent watchdog: the guiding task stopped feeding it.
    Watchdog,
    WindowWatchdog,
    LowPower,
    /// A software reset: the fault path's (with a fault record) or a
    /// debugger's.
    Software,
    /// The reset pin (the board's button, or a probe).
    Pin,
    /// No flag set.
    Unknown,
}

impl ResetCause {
    /// One cause from the flags. A power-on also sets the brown-out and pin
    /// flags, and every internal reset also sets the pin flag (the chip
    /// drives its own reset pin), so the more specific flag wins.
    pub fn from_flags(f: ResetFlags) -> Self {
        if f.power_on {
            ResetCause::PowerOn
        } else if f.brown_out {
            ResetCause::BrownOut
        } else if f.independent_watchdog {
            ResetCause::Watchdog
        } else if f.window_watchdog {
            ResetCause::WindowWatchdog
        } else if f.low_power {
            ResetCause::LowPower
        } else if f.software {
            ResetCause::Software
        } else if f.pin {
            ResetCause::Pin
        } else {
            ResetCause::Unknown
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ResetCause::PowerOn => "power-on",
            ResetCause::BrownOut => "brown-out",
            ResetCause::Watchdog => "watchdog",
            ResetCause::WindowWatchdog => "window watchdog",
            ResetCause::LowPower => "low-power",
            ResetCause::Software => "software",
            ResetCause::Pin => "reset pin",
            ResetCause::Unknown => "unknown",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_specific_flag_wins() {
        let pin = ResetFlags {
            pin: true,
            ..ResetFlags::default()
        };
        let cases = [
            (
                ResetFlags {
                    power_on: true,
                    brown_out: true,
                    ..pin
                },
                ResetCause::PowerOn,
            ),
            (
                ResetFlags {
                    brown_out: true,
                    ..pin
                },
                ResetCause::BrownOut,
            ),
            (
                ResetFlags {
                    independent_watchdog: true,
                    ..pin
                },
                ResetCause::Watchdog,
            ),
            (
                ResetFlags {
                    software: true,
                    ..pin
                },
                ResetCause::Software,
            ),
            (pin, ResetCause::Pin),
            (ResetFlags::default(), ResetCause::Unknown),
        ];
        for (flags, cause) in cases {
            assert_eq!(ResetCause::from_flags(flags), cause, "{flags:?}");
        }
    }
}
