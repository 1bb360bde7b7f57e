//! The loader in serial mode (idle task): G-code streamed by a sender over UART0 instead of the
//! semihosting program file, through the grbl 1.1 protocol core (`millac::protocol`): the banner,
//! one `ok` or `error:N` per line (grbl's numbers), `$` commands and settings (`$$`, `$N=value`
//! on the in-memory table), `?` status reports, `$C` check mode, `$X`. Each G-code line runs
//! through the tape (`Tape::line`: an error refuses that line only) into the block queue; the
//! look-ahead's held block runs as soon as no next line has come and the machine would otherwise
//! stop. The RX interrupt (the app's UART0 task) pushes every byte into the protocol's ring
//! (`RxIsr::push_byte`), which takes the realtime bytes out at once.
//!
//! `$J=` jogs run as their own block (no look-ahead, no AC ceiling); the parser then stands at the
//! jog's end with its modes unchanged; the state is `Jog` until the machine is idle.
//!
//! Not yet (issue 7): feed hold and resume, overrides on the feed, jog cancel (0x85), soft reset
//! during motion (the queued blocks still run), settings persistence, resume after an AC hold.
use core::sync::atomic::Ordering::Relaxed;

use heapless::spsc::Producer;
use millac::ac::FeedCeiling;
use millac::gcode::tape::{finish_block, Tape};
use millac::nc::{Block, FrameConfig, Motion};
use millac::protocol::codes::GrblError;
use millac::protocol::report::{feed_blu_per_min, State, StatusData};
use millac::protocol::settings::MachineSettings;
use millac::protocol::{Context, Event, Protocol, SettingsTable};
use millac::rt::Status;
use millac::Settings;

use crate::uart::Tx;

/// Loader task: never returns (the operator ends the session by resetting the machine).
pub fn run<const Q: usize, const T: usize>(
    blocks: &mut Producer<'static, Block, Q>,
    settings: Settings,
    ceiling: Option<FeedCeiling>,
    proto: &mut Protocol<'static>,
    tx: &mut Producer<'static, u8, T>,
    status: &Status,
    uart_clock_hz: u32,
) -> ! {
    crate::uart::init(uart_clock_hz);
    let mut out = Tx::new(tx);
    proto.start(&mut out);
    let mut log = crate::session::SessionLog::create();
    let mut table = MachineSettings {
        nc: settings,
        ..MachineSettings::default()
    };
    let mut tape = match ceiling {
        Some(c) => Tape::with_ac_ceiling(settings, c),
        None => Tape::new(settings),
    };
    let mut line_no = 0u32;
    // The programmed feed of the block the loader queued last (the status report's feed).
    let mut last_feed = 0u32;
    let cfg = FrameConfig::from_settings(&settings);
    // A jog is queued and has not finished yet (the state is Jog until the machine is idle).
    let mut jogging = false;
    loop {
        let idle = blocks.len() == 0 && status.idle.load(Relaxed);
        if idle {
            jogging = false;
        }
        let state = match (idle, jogging) {
            (true, _) => State::Idle,
            (false, true) => State::Jog,
            (false, false) => State::Run,
        };
        let mut cx = Context {
            table: &mut table,
            modes: tape.parser().modes(),
            machine: &settings,
            state,
        };
        match proto.poll(&mut out, &mut cx) {
            Event::None => {
                // Nothing more has come: let the held block run once the machine would stop.
                if idle && tape.holds_a_block() {
                    log.flush();
                    tape.flush(|b| enqueue(blocks, b, &mut last_feed));
                }
            }
            Event::Gcode { line, check } => {
                line_no = line_no.wrapping_add(1);
                let result = if check {
                    // `$C`: parse and validate on a copy; nothing is queued.
                    let mut probe = tape.parser().clone();
                    probe
                        .line(line_no, line)
                        .map(|_| ())
                        .map_err(GrblError::from)
                } else {
                    tape.line(line_no, line, |b| enqueue(blocks, b, &mut last_feed))
                        .map(|()| log.gcode(line))
                        .map_err(GrblError::from)
                };
                proto.reply(result, &mut out);
            }
            Event::Jog(jog) => {
                // Planned on a copy of the parser (validated like any block, soft limits
                // included); queued as it is (no AC ceiling: a jog is the operator's feed); the
                // parser then stands at its end, its modes unchanged.
                let result = jog.plan(tape.parser()).map(|plan| {
                    if let Some(b) = plan.block {
                        let signs = match b.motion {
                            Motion::Linear(l) => l.signs,
                            _ => tape.parser().signs(),
                        };
                        let b = finish_block(b, None, &cfg, settings.q0);
                        log.jog(&jog);
                        enqueue(blocks, b, &mut last_feed);
                        tape.jogged_to(plan.end, signs);
                        jogging = true;
                    }
                });
                proto.reply(result, &mut out);
            }
            Event::Realtime(p) => {
                if p.status() {
                    let options = table.report_options();
                    let data = StatusData {
                        state,
                        position: status.encoder(),
                        feed_blu_per_min: if idle {
                            0
                        } else {
                            feed_blu_per_min(&settings, last_feed)
                        },
                        spindle_rpm: tape.parser().spindle_rpm(),
                        blocks_free: (Q - 1 - blocks.len()) as u16,
                        ac: None,
                    };
                    proto.status_report(&data, options, settings.blu, &mut out);
                }
            }
            Event::Reset => {
                // Modes back to power-up; the position stays the machine's (the held block is
                // queued first: during motion the queued blocks still run, not yet stopped).
                log.reset();
                tape.reset(|b| enqueue(blocks, b, &mut last_feed));
            }
            Event::RxOverflow { lost } => proto.rx_overflow(lost, &mut out),
            Event::Replied | Event::Unlock | Event::CheckMode(_) => {}
        }
    }
}

/// [`enqueue_block`], remembering the block's programmed feed (for the status report).
fn enqueue<const Q: usize>(blocks: &mut Producer<'static, Block, Q>, b: Block, feed: &mut u32) {
    *feed = match b.motion {
        Motion::Linear(l) => l.f,
        Motion::Arc(a) => a.f,
        _ => *feed,
    };
    enqueue_block(blocks, b);
}

/// Queues a block, waiting while the queue is full (the frame drains it). Loader task, both modes.
pub fn enqueue_block<const Q: usize>(blocks: &mut Producer<'static, Block, Q>, b: Block) {
    while blocks.enqueue(b).is_err() {
        cortex_m::asm::nop();
    }
}
