//! The loader in serial mode (idle task): G-code streamed by a sender over UART0 instead of the
//! semihosting program file. Sends the banner, splits the received bytes into lines (CR, LF,
//! CRLF), runs each through the tape (`Tape::line`: an error refuses that line only) into the
//! block queue and answers every line with `ok` or `error:N`. The look-ahead's held block runs
//! when no next line has come and the machine would otherwise stop.
//!
//! Interim: this is the transport and the line loop; the grbl protocol core (realtime bytes other
//! than `?`, `$` commands and settings, grbl's error numbers, the full status report) replaces the
//! line handling here when it lands (issue 7). Until then `?` anywhere in the stream gets a short
//! status report and every refused line gets `error:20` after a `[MSG:...]` with millac's reason.
use core::fmt::Write as _;
use core::sync::atomic::Ordering::Relaxed;

use heapless::spsc::{Consumer, Producer};
use millac::ac::FeedCeiling;
use millac::gcode::lines::Lines;
use millac::gcode::tape::Tape;
use millac::nc::Block;
use millac::rt::Status;
use millac::Settings;

use crate::uart::Tx;

/// Loader task: never returns (the operator ends the session by resetting the machine).
pub fn run<const Q: usize, const R: usize, const T: usize>(
    blocks: &mut Producer<'static, Block, Q>,
    settings: Settings,
    ceiling: Option<FeedCeiling>,
    rx: &mut Consumer<'static, u8, R>,
    tx: &mut Producer<'static, u8, T>,
    status: &Status,
    uart_clock_hz: u32,
) -> ! {
    crate::uart::init(uart_clock_hz);
    let mut out = Tx::new(tx);
    banner(&mut out);
    let mut tape = match ceiling {
        Some(c) => Tape::with_ac_ceiling(settings, c),
        None => Tape::new(settings),
    };
    let mut lines = Lines::new();
    loop {
        let mut got = false;
        while let Some(b) = rx.dequeue() {
            got = true;
            if b == b'?' {
                status_report(&mut out, status, blocks.len() == 0);
                continue;
            }
            // Soft reset (interim: only the banner, which senders wait for after sending it; a
            // sender that connects after the first banner gets it this way).
            if b == 0x18 {
                banner(&mut out);
                continue;
            }
            lines.feed(&[b], |n, text| {
                let result = match text {
                    Ok(t) => tape
                        .line(n, t, |blk| enqueue(blocks, blk))
                        .map_err(|e| (e.line(), e)),
                    Err(e) => Err((
                        n,
                        millac::gcode::tape::TapeError::Line { line: n, error: e },
                    )),
                };
                match result {
                    Ok(()) => {
                        let _ = out.write_str("ok\r\n");
                    }
                    Err((_, e)) => {
                        let _ = write!(out, "[MSG:{}]\r\nerror:20\r\n", e);
                    }
                }
                true
            });
        }
        // Nothing more has come: let the held block run once the machine would stop.
        if !got && tape.holds_a_block() && blocks.len() == 0 && status.idle.load(Relaxed) {
            tape.flush(|blk| enqueue(blocks, blk));
        }
    }
}

/// The grbl banner senders wait for, and millac's name and version.
fn banner<const T: usize>(out: &mut Tx<'_, T>) {
    let _ = write!(
        out,
        "\r\nGrbl 1.1h ['$' for help]\r\n[MSG:millac {} serial line]\r\n",
        env!("CARGO_PKG_VERSION")
    );
}

/// Queues a block, waiting while the queue is full (the frame drains it).
fn enqueue<const Q: usize>(blocks: &mut Producer<'static, Block, Q>, b: Block) {
    while blocks.enqueue(b).is_err() {
        cortex_m::asm::nop();
    }
}

/// `<Idle|MPos:x,y,z|FS:0,0>` or `<Run|...>`: the position the frame published, in mm.
fn status_report<const T: usize>(out: &mut Tx<'_, T>, status: &Status, queue_empty: bool) {
    let state = if queue_empty && status.idle.load(Relaxed) {
        "Idle"
    } else {
        "Run"
    };
    let _ = write!(out, "<{state}|MPos:");
    for (k, blu) in status.encoder().iter().enumerate() {
        // 0.0001 in = 0.00254 mm: blu * 254 in 1e-5 mm, rounded to 1e-3 mm.
        let v = i64::from(*blu) * 254;
        let r = (v.abs() + 50) / 100;
        let sign = if v < 0 && r != 0 { "-" } else { "" };
        let sep = if k < 2 { "," } else { "" };
        let _ = write!(out, "{sign}{}.{:03}{sep}", r / 1000, r % 1000);
    }
    let _ = out.write_str("|FS:0,0>\r\n");
}
