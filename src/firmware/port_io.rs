//! The command port's plumbing: each transport's received bytes go into a
//! pipe that the guiding task drains into that port's interpreter, and the
//! replies come back through another pipe. The transports run in thread
//! mode; the guiding task touches the pipes only without waiting, so a
//! stalled or flooding client can neither block it nor make it allocate.
//!
//! Flow control: when a port's receive pipe is full its transport waits
//! (USB NAKs the host; a UART's own buffer fills, then overruns and the
//! bytes are lost). A reply that finds no room in the transmit pipe is
//! dropped whole and counted by the interpreter (`replies_dropped`).
//!
//! RAM: [`PORTS`](crate::firmware::shared::PORTS) x ([`RX_PIPE`] + [`TX_PIPE`]) bytes of pipes, and each
//! relay's [`CHUNK`]-byte buffers in its task.

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_futures::join::join;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;
use embedded_io_async::{Read, Write};

use mkgp_mount::port::ReplySink;

use crate::firmware::shared::{PORTS, RECEIVED};

/// Bytes received and not yet interpreted, per port: INDI's connect burst
/// (about 150 bytes) fits.
pub const RX_PIPE: usize = 256;
/// Reply bytes not yet sent, per port: a telemetry line and the replies of
/// a burst of commands.
pub const TX_PIPE: usize = 512;
/// What a relay moves at once: one USB packet.
pub const CHUNK: usize = 64;

/// One port's two pipes and its transport's error count.
pub struct Link {
    rx: Pipe<CriticalSectionRawMutex, RX_PIPE>,
    tx: Pipe<CriticalSectionRawMutex, TX_PIPE>,
    /// Receive errors (UART framing, noise, overrun; a USB host gone).
    errors: AtomicU32,
}

impl Link {
    const fn new() -> Self {
        Link {
            rx: Pipe::new(),
            tx: Pipe::new(),
            errors: AtomicU32::new(0),
        }
    }

    /// Received bytes into `buf`, without waiting; 0 if none.
    pub fn take_received(&self, buf: &mut [u8]) -> usize {
        self.rx.try_read(buf).unwrap_or(0)
    }

    pub fn errors(&self) -> u32 {
        self.errors.load(Ordering::Relaxed)
    }
}

pub static LINKS: [Link; PORTS] = [Link::new(), Link::new()];

/// Replies into a link's transmit pipe: whole, or dropped.
pub struct LinkSink(pub &'static Link);

impl ReplySink for LinkSink {
    fn send(&mut self, reply: &[u8]) -> bool {
        if self.0.tx.free_capacity() < reply.len() {
            return false;
        }
        // Only this task writes the pipe: the room checked stays. The loop
        // covers a write that stops at the ring's end.
        let mut rest = reply;
        while !rest.is_empty() {
            match self.0.tx.try_write(rest) {
                Ok(n) => rest = rest.get(n..).unwrap_or(&[]),
                Err(_) => return false,
            }
        }
        true
    }
}

/// Moves one transport's bytes both ways, for ever.
pub async fn relay(mut rx: impl Read, mut tx: impl Write, link: &'static Link) {
    join(receive(&mut rx, link), send(&mut tx, link)).await;
}

async fn receive(rx: &mut impl Read, link: &Link) {
    let mut buf = [0u8; CHUNK];
    loop {
        match rx.read(&mut buf).await {
            Ok(n) => {
                let mut rest = buf.get(..n).unwrap_or(&[]);
                while !rest.is_empty() {
                    let written = link.rx.write(rest).await;
                    rest = rest.get(written..).unwrap_or(&[]);
                    RECEIVED.signal(());
                }
            }
            Err(_) => {
                link.errors.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

async fn send(tx: &mut impl Write, link: &Link) {
    let mut buf = [0u8; CHUNK];
    loop {
        let n = link.tx.read(&mut buf).await;
        let mut rest = buf.get(..n).unwrap_or(&[]);
        // A host gone takes what was meant for it with it.
        while !rest.is_empty() {
            match tx.write(rest).await {
                Ok(0) | Err(_) => break,
                Ok(written) => rest = rest.get(written..).unwrap_or(&[]),
            }
        }
        if link.tx.is_empty() {
            let _ = tx.flush().await;
        }
    }
}

/// Runs the USB device (enumeration, control requests).
#[cfg(any(feature = "stm32f411ce", feature = "stm32f407vg"))]
#[embassy_executor::task]
async fn usb_device(mut device: hal::serial::UsbRunner) {
    device.run().await
}

/// Port 0 over USB.
#[cfg(any(feature = "stm32f411ce", feature = "stm32f407vg"))]
#[embassy_executor::task]
async fn usb_port(rx: hal::serial::UsbRx, tx: hal::serial::UsbTx) {
    relay(rx, tx, &LINKS[0]).await
}

/// A port over a UART.
#[embassy_executor::task(pool_size = 2)]
async fn uart_port(uart: embassy_stm32::usart::BufferedUart<'static>, link: &'static Link) {
    let (tx, rx) = uart.split();
    relay(rx, tx, link).await
}

/// NVIC priority of the transports' interrupts: below the step tick, the
/// ST4 edges and the guiding task, whose timing matters; the bytes wait.
const TRANSPORT_PRIORITY: embassy_stm32::interrupt::Priority =
    embassy_stm32::interrupt::Priority::P3;

/// Starts the board's transports on `spawner` (thread mode). An error
/// names the one that did not start; the others run.
pub fn start(
    spawner: embassy_executor::Spawner,
    pins: hal::board::PortPins,
) -> Result<(), &'static str> {
    hal::serial::set_interrupt_priority(TRANSPORT_PRIORITY);
    #[cfg(any(feature = "stm32f411ce", feature = "stm32f407vg"))]
    let port0 = {
        let (device, rx, tx) = hal::serial::start_usb(pins.usb).ok_or("USB")?;
        spawner.spawn(usb_device(device).map_err(|_| "USB device task")?);
        usb_port(rx, tx).map_err(|_| "USB port task")?
    };
    #[cfg(any(feature = "stm32f446re", feature = "stm32l475vg"))]
    let port0 = {
        let uart = hal::serial::start_vcp(pins.vcp).ok_or("UART port 0")?;
        uart_port(uart, &LINKS[0]).map_err(|_| "UART port 0 task")?
    };
    spawner.spawn(port0);
    let aux = hal::serial::start_aux(pins.aux).ok_or("UART port 1")?;
    spawner.spawn(uart_port(aux, &LINKS[1]).map_err(|_| "UART port 1 task")?);
    Ok(())
}
