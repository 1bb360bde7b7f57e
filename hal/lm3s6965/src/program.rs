//! Program mode of the QEMU board (the idle loader, when QEMU's working directory holds
//! `program.nc`): reads the program through semihosting, parses it through the tape and queues
//! its blocks through the re-planner's record, turns the chatter reaction while it waits, lets
//! every accepted block run, reports the final position (or the hold's) and exits QEMU. The first
//! refused line stops the reading; the blocks before it still run.
use core::sync::atomic::Ordering::Relaxed;

use cortex_m_semihosting::nr;
use heapless::spsc::Producer;
use millac::ac::FeedCeiling;
use millac::gcode::tape::Tape;
use millac::nc::Block;
use millac::protocol::settings::record::RecordError;
use millac::rt::replan::{self, Replan};
use millac::Settings;

use crate::shared::{QUEUE, RECORD, STATUS};
use crate::voice::{exit, log_error, report, text, Text};
use crate::{results, semihost};

/// Semihosting read size.
const CHUNK: usize = 256;

/// Runs `program.nc` to its end and exits QEMU (success unless a line, the file or the settings
/// record was refused); returns only when there is no program file (serial mode). Idle loader.
pub fn run(
    producer: &mut Producer<'static, Block, QUEUE>,
    replan: &mut Replan<RECORD>,
    settings: &Settings,
    ceiling: Option<FeedCeiling>,
    refused: Option<RecordError>,
) {
    // The loader's errors, logged once the machine is idle (see `load`).
    let mut errors = Errors::new();
    let ok = match load(producer, replan, settings, ceiling, refused, &mut errors) {
        Loaded::All => true,
        Loaded::Error => false,
        Loaded::NoFile => return,
    };
    // Every accepted block runs to completion, also after an error (and every detour of a
    // chatter re-plan).
    while producer.len() != 0 || !STATUS.idle.load(Relaxed) || replan.pending() || replan.aborting()
    {
        react(replan, producer);
    }
    for t in &errors {
        log_error(t);
    }
    report_position(false);
    exit(ok)
}

/// Program mode: the run ends on a hold with the machine standing: `millac: hold blocks=N
/// position=x,y,z` (the exact position), exit with failure.
pub fn held_exit() -> ! {
    report_position(true);
    exit(false);
}

/// The run's last line, `millac: [hold ]blocks=N position=x,y,z` (the exact position as the
/// frame last published it), into the result file and the log.
fn report_position(held: bool) {
    let [x, y, z] = STATUS.position();
    let blocks = STATUS.blocks_done.load(Relaxed);
    results::line(format_args!(
        "millac: {}blocks={} position={},{},{}",
        if held { "hold " } else { "" },
        blocks,
        x,
        y,
        z
    ));
    if held {
        defmt::warn!(
            "held: blocks={=u32} position={=i32},{=i32},{=i32}",
            blocks,
            x,
            y,
            z
        );
    } else {
        defmt::info!(
            "done: blocks={=u32} position={=i32},{=i32},{=i32}",
            blocks,
            x,
            y,
            z
        );
    }
}

/// Program mode: a frame that overran its period (the interrupts took longer than it; the
/// frame held its pulses back, so none is lost) holds the machine as in serial mode
/// (`ALARM:111`) and, once it stands, ends the run with the hold's report. Idle loader.
fn overrun_check() {
    let n = STATUS.frame_overruns.load(Relaxed);
    if n == 0 {
        return;
    }
    STATUS
        .operator
        .store(millac::nc::operator::word(100, 100, true, false), Relaxed);
    let t = text(format_args!(
        "frame overrun: the interrupts took longer than the frame period ({} frames, no pulse \
         lost): the CPU is too slow for these settings",
        n
    ));
    results::line(format_args!("alarm: {}", t));
    defmt::warn!("alarm: {=str}", t.as_str());
    while !STATUS.stopped() {}
    held_exit();
}

/// The chatter reaction's turn (tape mode): a re-plan, a spindle speed (applied to the
/// simulated spindle, then the AC resumes) or a refusal, into the result file and the log.
fn react(replan: &mut Replan<RECORD>, producer: &mut Producer<'static, Block, QUEUE>) {
    overrun_check();
    // An AC hold holds rapids too (`millac::nc::operator::with_ac_hold`); not while the
    // frame drops the queue for a re-plan: that word carries the abort bit until
    // `Replan::poll` has finished it.
    if !replan.aborting() {
        STATUS.operator.store(
            millac::nc::operator::with_ac_hold(
                millac::nc::operator::RUN,
                STATUS.feed_cap.load(Relaxed),
            ),
            Relaxed,
        );
    }
    match replan.poll(producer, &STATUS) {
        replan::Event::None => {}
        replan::Event::Speed(s) => {
            crate::uart::set_spindle_rpm(s.to);
            replan.speed_applied(&STATUS, s.to);
            results::line(format_args!("chatter: spindle {}", s));
            defmt::warn!(
                "chatter: spindle S{=u32} -> S{=u32} ({=u32} Hz)",
                s.from,
                s.to,
                s.chatter_hz
            );
        }
        replan::Event::Replanned(r) => {
            results::line(format_args!("chatter: re-planned {}", r));
            defmt::warn!(
                "chatter: re-plan {=u32}: lift {=u32} BLU from {=i32},{=i32},{=i32}",
                r.count,
                r.lift,
                r.at[0],
                r.at[1],
                r.at[2]
            );
        }
        replan::Event::Refused { at, why } => {
            results::line(format_args!(
                "chatter: not re-planned at {},{},{}: {}",
                at[0],
                at[1],
                at[2],
                why.message()
            ));
            defmt::warn!("chatter: not re-planned: {=str}", why.message());
        }
    }
}

/// The loader's error messages for the log (more are in the result file only).
type Errors = heapless::Vec<Text, 2>;

/// How loading ended.
enum Loaded {
    /// Program end (M2/M30) or end of file.
    All,
    /// A line was refused or the file could not be read (printed); the blocks before it run.
    Error,
    /// No `program.nc`: serial mode.
    NoFile,
}

/// Reads, parses and queues the program. With a refused settings record nothing runs (see
/// "Settings" in the crate docs). Errors go to the result file at once and into `errors` for
/// the log, which the loader writes once the accepted blocks have run: the blocks before an
/// error still run, and the logger's critical section (tens of microseconds for a long line)
/// must not hold back a frame, at a rapid period of 38 us.
fn load(
    producer: &mut Producer<'static, Block, QUEUE>,
    replan: &mut Replan<RECORD>,
    settings: &Settings,
    ceiling: Option<FeedCeiling>,
    refused: Option<RecordError>,
    errors: &mut Errors,
) -> Loaded {
    let mut refuse = |what: core::fmt::Arguments| {
        let _ = errors.push(report(what));
    };
    // Through the loader's record; while it is full, the re-plan's turn (a chatter hold).
    let mut enqueue = |b: Block| {
        let mut b = b;
        while let Err(back) = replan.offer(producer, b) {
            b = back;
            react(replan, producer);
        }
    };
    let Some(fd) = semihost::open(b"program.nc\0", nr::open::R) else {
        return Loaded::NoFile;
    };
    if let Some(e) = refused {
        refuse(format_args!(
            "settings: {}; nothing runs (fix or remove {})",
            e.message(),
            crate::files::SETTINGS_NAME
        ));
        semihost::close(fd);
        return Loaded::Error;
    }

    // The tape finishes every block, with an enabled AC's feed ceiling.
    let mut tape = match ceiling {
        Some(c) => Tape::with_ac_ceiling(*settings, c),
        None => Tape::new(*settings),
    };
    let mut chunk = [0u8; CHUNK];
    let mut ok = true;
    // The program's S as last published (0: none yet).
    let mut program_rpm = 0u32;
    loop {
        let Some(n) = semihost::read(fd, &mut chunk) else {
            refuse(format_args!("cannot read program.nc"));
            ok = false;
            // What was accepted still runs.
            let _ = tape.finish(&mut enqueue);
            break;
        };
        let bytes = chunk.get(..n).unwrap_or(&[]);
        let result = if bytes.is_empty() {
            tape.finish(&mut enqueue)
        } else {
            tape.feed(bytes, &mut enqueue)
        };
        if let Err(e) = result {
            refuse(format_args!("{}", e));
            ok = false;
        }
        // The program's spindle speed (its last S word read so far) for the process
        // monitors: a tape has no spindle output to sync with the motion, so the speed
        // reaches them once per 256-byte chunk, after the chunk's blocks are queued: up to
        // a queue of blocks early or late. A program should set S before its first cut (the
        // host simulation cuts the whole program at its S); the serial loader publishes it
        // with the motion. Only a change of the program's S is published: a speed the chatter
        // reaction chose (`$277`) stays until the program commands another.
        let rpm = tape.parser().spindle_rpm();
        if rpm != 0 && rpm != program_rpm {
            program_rpm = rpm;
            STATUS.spindle_rpm.store(rpm, Relaxed);
            // The simulated spindle turns at the program's S (the host starts it there);
            // once the reaction has commanded it, it follows the program's changes too.
            if crate::uart::spindle_rpm() != 0 {
                crate::uart::set_spindle_rpm(rpm);
            }
        }
        if tape.done() {
            break;
        }
    }
    semihost::close(fd);
    if ok {
        Loaded::All
    } else {
        Loaded::Error
    }
}
