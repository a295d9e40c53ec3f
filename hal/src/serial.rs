//! The command port's transports: they move bytes; what the bytes mean is
//! the library's `port` interpreter's business.
//!
//! | board | port 0 (to the PC) | port 1 (plain UART, 9600 8N1, 3.3 V) |
//! |---|---|---|
//! | Black Pill F411CE | USB CDC-ACM on the USB-C socket (PA11/PA12) | USART1: TX PA9, RX PA10 |
//! | Nucleo-F446RE | USART2 (PA2/PA3) to the ST-LINK's virtual COM port, 9600 8N1 | USART6: TX PC6 (CN10-4), RX PC7 (CN10-19, D9) |
//! | Discovery F407VG | USB CDC-ACM on the micro-USB socket CN5 (OTG FS, PA11/PA12) | USART2: TX PA2, RX PA3 |
//! | B-L475E-IOT01A | USART1 (PB6/PB7) to the ST-LINK's virtual COM port, 9600 8N1 | UART4: TX PA0 (D1), RX PA1 (D0) |
//!
//! Port 1 is for a Bluetooth or WiFi serial bridge (HC-05, ESP32 with a
//! serial bridge): its TX goes to the bridge's RX and back, and the grounds
//! joined. 9600 baud is what LX200 clients and the bridges start at.
//!
//! Both transports implement `embedded_io_async`'s `Read` and `Write`, so
//! the firmware relays them with one piece of code. USB without VBUS
//! sensing: the boards are powered by the mount, not the cable, and neither
//! routes VBUS to a free pin (the Black Pill's PA9 is the UART here); the
//! host finds the device when it is plugged in, and a read or write while
//! unplugged reports [`Gone`] until the host configures it again.
//!
//! RAM: each UART 2 x [`UART_BUFFER`] bytes; the USB stack
//! [`USB_DESCRIPTOR_BUFFERS`] bytes of descriptors and control buffer, its
//! receive FIFO buffer and the CDC state.

use embassy_stm32::usart::{self, BufferedUart};
use embassy_stm32::{bind_interrupts, peripherals, Peri};
use static_cell::StaticCell;

/// Baud rate of the UARTs.
pub const UART_BAUD: u32 = 9600;
/// Each UART's receive and its transmit buffer, bytes: a burst of commands
/// (INDI's connect sends about 150 bytes at once) and a telemetry line.
pub const UART_BUFFER: usize = 256;

/// The transport went away (a USB host that unplugged or deconfigured) or
/// failed (a UART framing or overrun error: the bytes are lost and the
/// interpreter's framer resynchronises at the next `:`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct Gone;

impl core::fmt::Display for Gone {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("serial port gone")
    }
}

impl core::error::Error for Gone {}

impl embedded_io_async::Error for Gone {
    fn kind(&self) -> embedded_io_async::ErrorKind {
        embedded_io_async::ErrorKind::NotConnected
    }
}

/// Static buffers of one UART.
struct UartBuffers {
    rx: [u8; UART_BUFFER],
    tx: [u8; UART_BUFFER],
}

/// A UART's buffers, once each: `StaticCell` hands out `'static` memory.
macro_rules! uart_buffers {
    () => {{
        static BUFFERS: StaticCell<UartBuffers> = StaticCell::new();
        BUFFERS.try_init(UartBuffers {
            rx: [0; UART_BUFFER],
            tx: [0; UART_BUFFER],
        })
    }};
}

fn uart_config() -> usart::Config {
    let mut config = usart::Config::default();
    config.baudrate = UART_BAUD;
    // The reader wakes for every byte, not only at a half-full buffer or
    // an idle line: a command is read as it arrives (and QEMU's UART
    // model never reports an idle line).
    config.eager_reads = Some(1);
    config
}

/// Pins and peripheral of one UART.
pub struct UartPins<
    U: embassy_stm32::PeripheralType + 'static,
    Tx: embassy_stm32::PeripheralType + 'static,
    Rx: embassy_stm32::PeripheralType + 'static,
> {
    pub uart: Peri<'static, U>,
    pub tx: Peri<'static, Tx>,
    pub rx: Peri<'static, Rx>,
}

#[cfg(feature = "stm32f411ce")]
mod chip {
    use super::*;
    bind_interrupts!(pub struct Irqs {
        OTG_FS => embassy_stm32::usb::InterruptHandler<peripherals::USB_OTG_FS>;
        USART1 => usart::BufferedInterruptHandler<peripherals::USART1>;
    });
    pub type AuxUart = peripherals::USART1;
    pub type AuxTx = peripherals::PA9;
    pub type AuxRx = peripherals::PA10;
}

#[cfg(feature = "stm32f407vg")]
mod chip {
    use super::*;
    bind_interrupts!(pub struct Irqs {
        OTG_FS => embassy_stm32::usb::InterruptHandler<peripherals::USB_OTG_FS>;
        USART2 => usart::BufferedInterruptHandler<peripherals::USART2>;
    });
    pub type AuxUart = peripherals::USART2;
    pub type AuxTx = peripherals::PA2;
    pub type AuxRx = peripherals::PA3;
}

#[cfg(feature = "stm32l475vg")]
mod chip {
    use super::*;
    bind_interrupts!(pub struct Irqs {
        USART1 => usart::BufferedInterruptHandler<peripherals::USART1>;
        UART4 => usart::BufferedInterruptHandler<peripherals::UART4>;
    });
    pub type AuxUart = peripherals::UART4;
    pub type AuxTx = peripherals::PA0;
    pub type AuxRx = peripherals::PA1;
    pub type VcpUart = peripherals::USART1;
    pub type VcpTx = peripherals::PB6;
    pub type VcpRx = peripherals::PB7;
}

#[cfg(feature = "stm32f446re")]
mod chip {
    use super::*;
    bind_interrupts!(pub struct Irqs {
        USART2 => usart::BufferedInterruptHandler<peripherals::USART2>;
        USART6 => usart::BufferedInterruptHandler<peripherals::USART6>;
    });
    pub type AuxUart = peripherals::USART6;
    pub type AuxTx = peripherals::PC6;
    pub type AuxRx = peripherals::PC7;
    pub type VcpUart = peripherals::USART2;
    pub type VcpTx = peripherals::PA2;
    pub type VcpRx = peripherals::PA3;
}

/// Sets the NVIC priority of the transports' interrupts (embassy leaves
/// them at the reset value, the highest, which is the step tick's).
pub fn set_interrupt_priority(priority: embassy_stm32::interrupt::Priority) {
    use embassy_stm32::interrupt::{self, InterruptExt};
    #[cfg(feature = "stm32f411ce")]
    for irq in [interrupt::OTG_FS, interrupt::USART1] {
        irq.set_priority(priority);
    }
    #[cfg(feature = "stm32f407vg")]
    for irq in [interrupt::OTG_FS, interrupt::USART2] {
        irq.set_priority(priority);
    }
    #[cfg(feature = "stm32f446re")]
    for irq in [interrupt::USART2, interrupt::USART6] {
        irq.set_priority(priority);
    }
    #[cfg(feature = "stm32l475vg")]
    for irq in [interrupt::USART1, interrupt::UART4] {
        irq.set_priority(priority);
    }
}

/// Port 1's pins on this board.
pub type AuxPins = UartPins<chip::AuxUart, chip::AuxTx, chip::AuxRx>;

/// A UART on `pins` with `buffers`, at [`UART_BAUD`].
fn start_uart<U, Tx, Rx>(
    pins: UartPins<U, Tx, Rx>,
    buffers: &'static mut UartBuffers,
) -> Option<BufferedUart<'static>>
where
    U: usart::Instance,
    Tx: usart::TxPin<U>,
    Rx: usart::RxPin<U>,
    chip::Irqs: embassy_stm32::interrupt::typelevel::Binding<
        U::Interrupt,
        usart::BufferedInterruptHandler<U>,
    >,
{
    BufferedUart::new(
        pins.uart,
        pins.rx,
        pins.tx,
        &mut buffers.tx,
        &mut buffers.rx,
        chip::Irqs,
        uart_config(),
    )
    .ok()
}

/// Starts port 1, the plain UART. `None` if it was started before or the
/// configuration is refused (neither happens with the constants here).
pub fn start_aux(pins: AuxPins) -> Option<BufferedUart<'static>> {
    start_uart(pins, uart_buffers!()?)
}

/// Port 0 on the Nucleo and the B-L475E-IOT01A: a UART to the ST-LINK's
/// virtual COM port.
#[cfg(any(feature = "stm32f446re", feature = "stm32l475vg"))]
pub type VcpPins = UartPins<chip::VcpUart, chip::VcpTx, chip::VcpRx>;

/// Starts port 0 on the Nucleo and the B-L475E-IOT01A (see [`start_aux`]).
#[cfg(any(feature = "stm32f446re", feature = "stm32l475vg"))]
pub fn start_vcp(pins: VcpPins) -> Option<BufferedUart<'static>> {
    start_uart(pins, uart_buffers!()?)
}

#[cfg(any(feature = "stm32f411ce", feature = "stm32f407vg"))]
pub use usb::*;

#[cfg(any(feature = "stm32f411ce", feature = "stm32f407vg"))]
mod usb {
    use super::*;
    use embassy_stm32::usb::Driver;
    use embassy_usb::class::cdc_acm::{CdcAcmClass, Receiver, Sender, State};
    use embassy_usb::driver::EndpointError;
    use embassy_usb::{Builder, UsbDevice};

    /// pid.codes' vendor ID for open-source hardware, and its test product
    /// ID: a board sold to others should ask pid.codes for its own.
    const VENDOR_ID: u16 = 0x1209;
    const PRODUCT_ID: u16 = 0x0001;
    /// Full-speed bulk packets.
    pub const USB_PACKET: usize = 64;
    /// Configuration and BOS descriptors and the control buffer, bytes.
    pub const USB_DESCRIPTOR_BUFFERS: usize = 256 + 256 + 64;
    /// The OTG driver's receive buffer: every OUT endpoint's packet.
    const EP_OUT_BUFFER: usize = 256;

    pub type UsbDriver = Driver<'static, peripherals::USB_OTG_FS>;

    /// Port 0's pins: the OTG FS peripheral and its data lines.
    pub struct UsbPins {
        pub usb: Peri<'static, peripherals::USB_OTG_FS>,
        pub dp: Peri<'static, peripherals::PA12>,
        pub dm: Peri<'static, peripherals::PA11>,
    }

    struct UsbBuffers {
        config_descriptor: [u8; 256],
        bos_descriptor: [u8; 256],
        control: [u8; 64],
        ep_out: [u8; EP_OUT_BUFFER],
        state: State<'static>,
    }

    /// The running USB device: run [`UsbDevice::run`] in a task of its own.
    pub type UsbRunner = UsbDevice<'static, UsbDriver>;

    /// Starts port 0 as a USB CDC-ACM serial port: the device to run and
    /// the port's two halves. `None` if it was started before.
    pub fn start_usb(pins: UsbPins) -> Option<(UsbRunner, UsbRx, UsbTx)> {
        static BUFFERS: StaticCell<UsbBuffers> = StaticCell::new();
        let b = BUFFERS.try_init(UsbBuffers {
            config_descriptor: [0; 256],
            bos_descriptor: [0; 256],
            control: [0; 64],
            ep_out: [0; EP_OUT_BUFFER],
            state: State::new(),
        })?;
        let mut otg = embassy_stm32::usb::Config::default();
        otg.vbus_detection = false;
        let driver = Driver::new_fs(pins.usb, chip::Irqs, pins.dp, pins.dm, &mut b.ep_out, otg);
        let mut config = embassy_usb::Config::new(VENDOR_ID, PRODUCT_ID);
        config.manufacturer = Some("mkgp-mount");
        config.product = Some("mkgp-mount telescope mount");
        config.serial_number = Some(env!("CARGO_PKG_VERSION"));
        config.max_power = 0;
        let mut builder = Builder::new(
            driver,
            config,
            &mut b.config_descriptor,
            &mut b.bos_descriptor,
            &mut [],
            &mut b.control,
        );
        let class = CdcAcmClass::new(&mut builder, &mut b.state, USB_PACKET as u16);
        let (tx, rx) = class.split();
        Some((builder.build(), UsbRx(rx), UsbTx { tx, full: false }))
    }

    /// Port 0's receiving half.
    pub struct UsbRx(Receiver<'static, UsbDriver>);
    /// Port 0's sending half.
    pub struct UsbTx {
        tx: Sender<'static, UsbDriver>,
        /// The last packet was full: the host waits for a short one.
        full: bool,
    }

    impl embedded_io_async::ErrorType for UsbRx {
        type Error = Gone;
    }

    impl embedded_io_async::Read for UsbRx {
        /// One packet; `buf` must hold [`USB_PACKET`] bytes (a shorter one
        /// is refused as [`Gone`]). Waits for the host first.
        async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Gone> {
            if buf.len() < USB_PACKET {
                return Err(Gone);
            }
            self.0.wait_connection().await;
            self.0
                .read_packet(buf)
                .await
                .map_err(|_: EndpointError| Gone)
        }
    }

    impl embedded_io_async::ErrorType for UsbTx {
        type Error = Gone;
    }

    impl embedded_io_async::Write for UsbTx {
        /// Up to one packet of `buf`.
        async fn write(&mut self, buf: &[u8]) -> Result<usize, Gone> {
            let n = buf.len().min(USB_PACKET);
            let packet = buf.get(..n).ok_or(Gone)?;
            self.tx.write_packet(packet).await.map_err(|_| Gone)?;
            self.full = n == USB_PACKET;
            Ok(n)
        }

        /// Ends the transfer: a zero-length packet after a full one, so
        /// that the host hands the bytes on now.
        async fn flush(&mut self) -> Result<(), Gone> {
            if core::mem::take(&mut self.full) {
                self.tx.write_packet(&[]).await.map_err(|_| Gone)?;
            }
            Ok(())
        }
    }
}
