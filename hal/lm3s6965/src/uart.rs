//! UART0 of the LM3S6965 (an ARM PL011; QEMU routes it with `-serial`): the operator's serial line
//! for a G-code sender. RX and TX by interrupt (the UART0 hardware task, a priority below the
//! frame): every received byte goes to the caller's sink at once (the protocol takes realtime
//! bytes out there); bytes to send wait in a lock-free queue that the interrupt drains while the
//! transmit FIFO has room. `init` from the loader (`crate::loader::QemuLoader`, the loader's
//! `LoaderBoard`, in serial mode); `on_interrupt` from the UART0 task; `kick` from the loader.
//!
//! Registers (LM3S6965 datasheet, PL011): DR 0x000, FR 0x018 (RXFE bit 4, TXFF bit 5), IBRD 0x024,
//! FBRD 0x028, LCRH 0x02C, CTL 0x030, IM 0x038, MIS 0x040, ICR 0x044; clock gate RCGC1 bit 0.
use heapless::spsc::Consumer;

use crate::board::{read, write};

const SYSCTL_RCGC1: usize = 0x400F_E104;
const RCGC1_UART0: u32 = 1;
const UART0: usize = 0x4000_C000;
const DR: usize = 0x000;
const FR: usize = 0x018;
const IBRD: usize = 0x024;
const FBRD: usize = 0x028;
const LCRH: usize = 0x02C;
const CTL: usize = 0x030;
const IM: usize = 0x038;
const MIS: usize = 0x040;
const ICR: usize = 0x044;
const FR_RXFE: u32 = 1 << 4;
const FR_TXFF: u32 = 1 << 5;
/// 8 data bits, FIFOs on.
const LCRH_8N1_FIFO: u32 = (0b11 << 5) | (1 << 4);
const CTL_UARTEN: u32 = 1;
const CTL_TXE: u32 = 1 << 8;
const CTL_RXE: u32 = 1 << 9;
const INT_RX: u32 = 1 << 4;
const INT_TX: u32 = 1 << 5;
const INT_RT: u32 = 1 << 6;

/// Transmit queue slots (holds one less): a status report and a few replies.
pub const TX_QUEUE: usize = 512;

/// Ungates UART0 and sets it up for 115200 baud, 8N1, FIFOs, receive and receive-timeout
/// interrupts on (the transmit interrupt is enabled while bytes wait). `clock_hz` is the UART's
/// clock. Loader or init context, before the UART0 task can run.
pub fn init(clock_hz: u32) {
    write(SYSCTL_RCGC1, read(SYSCTL_RCGC1) | RCGC1_UART0);
    let _ = read(SYSCTL_RCGC1);
    write(UART0 + CTL, 0);
    // Divisor = clock / (16 * baud) as 16.6 fixed point (datasheet formula), rounded.
    let div64 = ((u64::from(clock_hz) * 4) + 115_200 / 2) / 115_200;
    write(UART0 + IBRD, (div64 >> 6) as u32);
    write(UART0 + FBRD, (div64 & 0x3F) as u32);
    write(UART0 + LCRH, LCRH_8N1_FIFO);
    write(UART0 + ICR, 0x7FF);
    write(UART0 + IM, INT_RX | INT_RT);
    write(UART0 + CTL, CTL_UARTEN | CTL_TXE | CTL_RXE);
    // Bytes that arrived before the interrupts were on (their interrupt was cleared above): let
    // the UART0 task take them now.
    if read(UART0 + FR) & FR_RXFE == 0 {
        cortex_m::peripheral::NVIC::pend(lm3s6965::Interrupt::UART0);
    }
}

/// The UART0 interrupt: every received byte to `rx` (in order), then as many queued bytes as the
/// transmit FIFO takes; the transmit interrupt stays enabled only while bytes wait. UART0 task.
pub fn on_interrupt<const N: usize>(tx: &mut Consumer<'static, u8, N>, mut rx: impl FnMut(u8)) {
    let _ = read(UART0 + MIS);
    write(UART0 + ICR, INT_RX | INT_RT | INT_TX);
    while read(UART0 + FR) & FR_RXFE == 0 {
        rx(read(UART0 + DR) as u8);
    }
    drain(tx);
}

/// Moves queued bytes into the transmit FIFO while it has room; enables the transmit interrupt
/// when bytes are left. UART0 task ([`kick`] pends it to start sending).
fn drain<const N: usize>(tx: &mut Consumer<'static, u8, N>) {
    while read(UART0 + FR) & FR_TXFF == 0 {
        match tx.dequeue() {
            Some(b) => write(UART0 + DR, u32::from(b)),
            None => break,
        }
    }
    let im = read(UART0 + IM);
    if tx.ready() {
        write(UART0 + IM, im | INT_TX);
    } else {
        write(UART0 + IM, im & !INT_TX);
    }
}

/// Pends UART0 so that it moves queued bytes out (the serial console's writer). Loader task.
pub fn kick() {
    cortex_m::peripheral::NVIC::pend(lm3s6965::Interrupt::UART0);
}
