//! The loader in serial mode (idle task of every board; host tests): G-code streamed by a sender
//! over the board's serial line (the QEMU board's UART0 instead of its semihosting program file,
//! the Nucleo's USART2), through the grbl 1.1 protocol core (`crate::protocol`), over a board's
//! [`LoaderBoard`]: the banner,
//! one `ok` or `error:N` per line (grbl's numbers), `$` commands and settings (`$$`; `$N=value`
//! stored at once through the settings storage, effective at the next start for the NC and AC
//! settings), `?` status reports, `$C` check mode, `$X`. Each G-code line runs
//! through the tape (`Tape::line`: an error refuses that line only) into the block queue; the
//! look-ahead's held block runs as soon as no next line has come and the machine would otherwise
//! stop. The RX interrupt (the app's serial task) pushes every byte into the protocol's ring
//! (`RxIsr::push_byte`), which takes the realtime bytes out at once.
//!
//! `$J=` jogs run as their own block (no look-ahead, no AC ceiling); the parser then stands at the
//! jog's end with its modes unchanged; the state is `Jog` until the machine is idle.
//!
//! Operator actions (the loader is the only writer of `Status::operator`, the frame's one word
//! for them, see `millac::nc::operator`):
//! - `!` (and the safety door 0x84) holds the feed: the frame ramps to a stop at the
//!   acceleration (`Hold:1`, then `Hold:0` once `Status::stopped`); `~` resumes the same block.
//! - 0x90..0x94 and 0x95..0x97 set the feed and rapid overrides; the frame ramps to them.
//! - 0x18 soft reset: the frame stops at once and drops the queue (the abort bit), the held block
//!   is dropped, the parser stands where the machine stopped; a reset during motion raises
//!   `ALARM:3` (as grbl; the position is exact nonetheless and reported).
//! - 0x85 jog cancel: a running jog is held to a stop, then dropped like a reset (no alarm).
//! - An AC hold: an overload is a feed hold (`Hold`, `[MSG:...]` with F, T and the limits; `~`
//!   resumes the AC from f_min); a sensor fault is an alarm (`ALARM:10x`, `$X` resumes).
//!
//! The loader never blocks: while the block queue has no room for a line's blocks it polls the
//! realtime requests only (`Protocol::poll_realtime`), so `?`, `!`, `~` and a reset are served at
//! once whatever the queue holds, and a hold with a full queue cannot stall it.
use core::sync::atomic::Ordering::Relaxed;

use crate::ac::{Alarm, FeedCeiling};
use crate::gcode::tape::{finish_block, Tape};
use crate::nc::{operator, Block, FrameConfig, Motion};
use crate::ports::SettingsStorage;
use crate::protocol::codes::{ac_alarm, alarm, GrblError};
use crate::protocol::report::{feed_blu_per_min, AcReport, AcState, State, StatusData};
use crate::protocol::rx::Overrides;
use crate::protocol::settings::Persistent;
use crate::protocol::{Context, Event, Protocol, SettingsTable};
use crate::rt::ac::AC_RUN;
use crate::rt::replan::{self, Replan};
use crate::rt::Status;
use heapless::spsc::{Consumer, Producer};

use crate::gcode::{Parsed, Spindle};
use crate::inputs::{Events, Trip};
use crate::protocol::jog::JogRequest;
use crate::protocol::LINE_MAX;

/// Free queue slots a line needs before the loader takes it: the look-ahead's held block and the
/// line's own (a line emits at most two blocks).
const ROOM_PER_LINE: usize = 2;

/// What the loader needs of a board: its serial line, and optionally a session log, a spindle
/// output and operator inputs (the defaults: none). Loader task.
pub trait LoaderBoard {
    /// Sets up the serial line (115200 8N1, receive interrupts on) before the banner.
    fn start(&mut self);
    /// Pends the serial interrupt so that it moves queued bytes out (the writer calls it after
    /// queueing, and while the transmit queue is full). Must not block.
    fn kick();

    /// The session log (the QEMU board writes `serve.nc`, see `session`): every accepted G-code
    /// line, in the order the loader fed its tape.
    fn log_gcode(&mut self, _line: &str) {}
    /// A jog that was queued.
    fn log_jog(&mut self, _jog: &JogRequest) {}
    /// The look-ahead's held block ran before the next line came.
    fn log_flush(&mut self) {}
    /// Soft reset.
    fn log_reset(&mut self) {}

    /// The board drives a spindle: a line that changes M3/M4/M5 or S waits until the motion
    /// queued before it has finished (grbl's buffer sync), then [`LoaderBoard::spindle`] applies
    /// it, and only then does the line's own motion queue; its `ok` comes after that.
    const SPINDLE: bool = false;
    /// Sets the spindle output (the machine stands): `rpm` of `max_rpm` (`$30`, as the table
    /// holds it now: a change acts at the next spindle command). Also called with `Off` on a soft
    /// reset and on an e-stop or limit alarm, before the queue is dropped.
    fn spindle(&mut self, _state: Spindle, _rpm: u32, _max_rpm: u32) {}

    /// The operator inputs' events since the last call (debounced by the board; see
    /// `millac::inputs`).
    fn inputs(&mut self) -> Events {
        Events::default()
    }
    /// The e-stop and limit switches that latched the alarm, if it is latched.
    fn latched(&mut self) -> Option<Trip> {
        None
    }
    /// `$X`: clears the latch; false while an e-stop or limit line is still active.
    fn acknowledge(&mut self) -> bool {
        true
    }
    /// The alarm is latched and an e-stop or limit line is still active (`$X` would be refused:
    /// the protocol answers it with `error:9` before saying anything else).
    fn latch_active(&mut self) -> bool {
        false
    }

    /// The most cycles the board's frame ISR may take (its `BoardLimits::frame_work_ns` in core
    /// cycles), when the board measures its frame (`Status::frame_cycles`): a measured frame
    /// above it holds the feed and raises `ALARM:111` once. None: no check (the default).
    fn frame_limit_cycles(&self) -> Option<u32> {
        None
    }

    /// Called once per turn of the loader's loop: false ends [`run`]. A board's firmware never
    /// ends it (the default); a host test runs its frames and its sender from here.
    fn running(&mut self) -> bool {
        true
    }
    /// Called while the loader waits for the frame (a full queue, an abort draining it). Must
    /// not block; the default is a spin-loop hint. A host test runs a frame here.
    fn wait(&mut self) {
        core::hint::spin_loop();
    }
}

/// The writer's end of the transmit queue. Loader task.
pub struct Tx<'a, const N: usize, B: LoaderBoard> {
    queue: &'a mut Producer<'static, u8, N>,
    board: core::marker::PhantomData<B>,
}

impl<'a, const N: usize, B: LoaderBoard> Tx<'a, N, B> {
    pub fn new(queue: &'a mut Producer<'static, u8, N>) -> Self {
        Tx {
            queue,
            board: core::marker::PhantomData,
        }
    }

    /// Queues `bytes`, waiting while the queue is full (the serial interrupt drains it), and kicks
    /// the serial interrupt so that it starts sending. Loader task.
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            while self.queue.enqueue(b).is_err() {
                B::kick();
                core::hint::spin_loop();
            }
        }
        B::kick();
    }
}

impl<const N: usize, B: LoaderBoard> core::fmt::Write for Tx<'_, N, B> {
    /// Queues the text (for `write!`).
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.write(s.as_bytes());
        Ok(())
    }
}

/// The alarm an input trip raises: the e-stop grblHAL's 10, a limit switch grbl's 1 (hard limit).
fn trip_alarm(t: &Trip) -> u8 {
    if t.estop {
        alarm::ESTOP
    } else {
        alarm::HARD_LIMIT
    }
}

/// A line that waits for the machine to stop: one that changes the spindle (see
/// [`LoaderBoard::SPINDLE`]) or ends the program (M2/M30, as grbl syncs its buffer there).
struct Deferred {
    line: heapless::String<LINE_MAX>,
    no: u32,
    spindle: Spindle,
    rpm: u32,
    /// The program's end: once it has run, the AC starts the next job afresh
    /// (`Status::ac_new_job`).
    end: bool,
}

/// Loader task: runs while [`LoaderBoard::running`] (on a board: for ever; the operator ends the
/// session by resetting the machine). `table`: the settings init loaded (and started the frame
/// with) and their storage.
#[allow(clippy::too_many_arguments)]
// Called once per board (its idle loop). Inlined there it takes about a third of the code it
// takes as a function of its own (measured on the QEMU firmware: 37 KiB inside idle, 109 KiB
// alone; LLVM stopped inlining it when it grew by a few lines in issue 10, and the firmware
// overflowed its 256 KiB of flash by 27 KiB; the F446 build shrank by 14 KiB with it).
#[inline(always)]
pub fn run<
    const Q: usize,
    const T: usize,
    const A: usize,
    const R: usize,
    S: SettingsStorage,
    B: LoaderBoard,
>(
    blocks: &mut Producer<'static, Block, Q>,
    replan: &mut Replan<R>,
    table: &mut Persistent<S>,
    ceiling: Option<FeedCeiling>,
    proto: &mut Protocol<'static>,
    tx: &mut Producer<'static, u8, T>,
    ac_alarms: &mut Consumer<'static, Alarm, A>,
    status: &Status,
    board: &mut B,
) {
    board.start();
    let mut out = Tx::<T, B>::new(tx);
    proto.start(&mut out);
    // The frame's configuration and the parser's, fixed at init: a `$N=value` the table stores
    // (and `$$` lists) at once takes effect for the NC settings at the next start.
    let settings = table.settings.nc;
    // The AC's limits F0, T0 for the `AC:` field, as the AC task started with them.
    let ac_settings = table.settings.ac;
    // The AC caps the feed (the boards give the ceiling only then): the status report's `AC:`
    // field is about that, so a measure-only AC has none.
    let ac_enabled = ceiling.is_some();
    if !ac_enabled {
        replan.without_reactions();
    }
    let mut tape = match ceiling {
        Some(c) => Tape::with_ac_ceiling(settings, c),
        None => Tape::new(settings),
    };
    let mut line_no = 0u32;
    // The programmed feed of the block the loader queued last (the AC field's feed share).
    let mut last_feed = 0u32;
    let cfg = FrameConfig::from_settings(&settings);
    let mm_per_blu = {
        let (num, den) = settings.blu.per_mm();
        den as f32 / num as f32
    };
    // A jog is queued and has not finished yet (the state is Jog until the machine is idle).
    let mut jogging = false;
    // The operator's feed hold, and a jog cancel waiting for the jog to stop.
    let mut hold = false;
    let mut cancel_jog = false;
    let mut overrides = proto.overrides();
    // The operator's word, held also while the AC holds (a cap of 0 stops only the feed: with
    // the hold a rapid walks its ladder down and no block starts, see `operator::with_ac_hold`).
    let publish = |hold: bool, ov: Overrides| {
        status.operator.store(
            operator::with_ac_hold(
                operator::word(ov.feed, ov.rapid, hold, false),
                status.feed_cap.load(Relaxed),
            ),
            Relaxed,
        );
    };
    publish(hold, overrides);
    // The spindle output as last applied, and a line waiting to change it.
    let mut spindle = (Spindle::Off, 0u32);
    let mut deferred: Option<Deferred> = None;
    // A tool breakage stopped the job: until a reset, `$X` is refused and the spindle stays off.
    let mut broken = false;
    // The longest frame already reported over the board's limit (said again only when a longer
    // one comes).
    let mut overrun = 0u32;
    // Frames that overran their period (pulses held back), as last reported.
    let mut overruns = status.frame_overruns.load(Relaxed);
    // The AC's hold as last published into the operator's word.
    let mut ac_held = status.feed_cap.load(Relaxed) == 0;
    while board.running() {
        if (status.feed_cap.load(Relaxed) == 0) != ac_held {
            ac_held = !ac_held;
            publish(hold, overrides);
        }
        // A frame too long for the running settings (a board that measures its frame: said
        // again only when a longer one comes), or a frame that found the last pulse still on the
        // pins (the interrupts take longer than the period: no pulse was lost, the frame held
        // them back, but the motion no longer keeps its timing; said once per hold, overruns
        // while already held are not news): hold with ALARM:111.
        let n = status.frame_overruns.load(Relaxed);
        let late = core::mem::replace(&mut overruns, n) != n && !hold;
        let long = match (board.frame_limit_cycles(), status.frame_cycles()) {
            (Some(limit), Some((_, max))) if max > limit && max > overrun => {
                overrun = max;
                Some((max, limit))
            }
            _ => None,
        };
        if late || long.is_some() {
            hold = true;
            publish(hold, overrides);
            proto.alarm(alarm::FRAME_OVERRUN, &mut out);
            match long {
                Some((max, limit)) => proto.message(
                    &mut out,
                    format_args!(
                        "Frame ISR took {max} cycles, the board allows {limit}: lower $201 or $110"
                    ),
                ),
                None => proto.message(
                    &mut out,
                    format_args!(
                        "Frame overran its period ({n} frames so far, no pulse lost): lower $201 or $110"
                    ),
                ),
            }
        }
        // A tool breakage (the AC task's request): the spindle stops at once and stays off; the
        // job ends: only a reset (which drops the queue) leads on, then `$X` (see `interlock`), as
        // grbl's hard limit. No waiting spindle line is applied meanwhile.
        if status.spindle_stop.swap(false, Relaxed) {
            broken = true;
            if spindle.0 != Spindle::Off {
                spindle = (Spindle::Off, 0);
                board.spindle(Spindle::Off, 0, table.settings.spindle_max_rpm);
                proto.message(&mut out, format_args!("Spindle stopped"));
            }
        }
        // AC holds: said once each, as they come. A chatter hold with a depth step or a spindle
        // speed reaction set is answered (below), not an alarm, unless the reaction is refused.
        while let Some(a) = ac_alarms.dequeue() {
            if !ac_enabled {
                // A measure-only AC holds nothing: what it would have held for is told, and the
                // machine goes on unlocked (an alarm would refuse the sender's next line). The
                // AC's controller entered its hold with the verdict: it resumes at once, so the
                // next verdict is told too.
                proto.message(
                    &mut out,
                    format_args!("AC (measure only) would hold: {}", a),
                );
                status.ac_resume.store(true, Relaxed);
                continue;
            }
            proto.message(&mut out, format_args!("AC hold: {}", a));
            let replanned = matches!(a, Alarm::Chatter { .. }) && replan.reacts();
            if !matches!(a, Alarm::Overload { .. }) && !replanned {
                proto.alarm(ac_alarm(&a), &mut out);
            }
        }
        // Chatter suppression: a chatter hold that has stopped the machine is re-planned (the
        // frame drops the queue, waited for here; the detour and the copies are queued; the AC
        // resumes).
        let mut event = replan.poll(blocks, status);
        while replan.aborting() {
            board.wait();
            event = replan.poll(blocks, status);
        }
        match event {
            replan::Event::None => {}
            replan::Event::Replanned(r) => {
                let mm = |blu: i32| blu as f32 * mm_per_blu;
                proto.message(
                    &mut out,
                    format_args!(
                        "Chatter: depth reduced by {:.3} mm from X{:.3} Y{:.3} Z{:.3}, the rest \
                         of line {} in two passes to X{:.3} Y{:.3} (re-plan {})",
                        r.lift as f32 * mm_per_blu,
                        mm(r.at[0]),
                        mm(r.at[1]),
                        mm(r.at[2]),
                        r.line,
                        mm(r.to[0]),
                        mm(r.to[1]),
                        r.count
                    ),
                );
            }
            replan::Event::Speed(s) => {
                // The spindle turns at the lobe's speed until the program commands another (in
                // its state: a stopped spindle stays stopped; a simulated one turns anyway); the
                // AC resumes once it is applied.
                spindle.1 = s.to;
                board.spindle(spindle.0, s.to, table.settings.spindle_max_rpm);
                replan.speed_applied(status, s.to);
                proto.message(
                    &mut out,
                    format_args!(
                        "Chatter: spindle speed S{} to S{} (chatter {} Hz, {} tooth periods per \
                         chatter period) at line {} (change {})",
                        s.from, s.to, s.chatter_hz, s.m, s.line, s.count
                    ),
                );
            }
            replan::Event::Refused { why, .. } => {
                proto.alarm(alarm::AC_CHATTER, &mut out);
                proto.message(
                    &mut out,
                    format_args!("Chatter: not re-planned: {}", why.message()),
                );
            }
        }
        // Operator inputs: the buttons as `!` and `~`; an e-stop or a limit switch stops at
        // once like a soft reset (below: queue and held block dropped, the parser at the
        // machine's position in power-up modes, the spindle off) and raises its alarm.
        let inputs = board.inputs();
        let tripped = inputs.tripped.then(|| {
            board.latched().unwrap_or(Trip {
                estop: true,
                limits: 0,
            })
        });
        if inputs.feed_hold {
            hold = true;
            publish(hold, overrides);
        }
        // An alarm (a frame overrun, a trip) keeps the hold until `$X`.
        if inputs.cycle_start && hold && proto.alarm_code().is_none() {
            hold = false;
            publish(hold, overrides);
        }
        let idle = blocks.len() == 0 && status.idle.load(Relaxed) && !replan.pending();
        if idle {
            jogging = false;
        }
        // A measure-only AC's verdict holds nothing (its state is only logged).
        let ac_held = ac_enabled && status.ac_state.load(Relaxed) > AC_RUN;
        if cancel_jog && status.stopped() {
            // The jog has stopped: drop it and any jog queued behind it. The parser keeps its
            // modes (a jog changes none) and stands where the machine stopped.
            let (at, signs) = abort(blocks, status, board);
            replan.restart(at);
            tape.jogged_to(at, signs);
            cancel_jog = false;
            jogging = false;
            hold = false;
            publish(hold, overrides);
        }
        // A line that changes the spindle runs once everything before it has run (not in the
        // turn of a trip: the trip drops it below).
        if let (Some(d), None, false) = (deferred.as_ref(), tripped, broken) {
            if idle && !tape.holds_a_block() {
                if B::SPINDLE && (d.spindle, d.rpm) != spindle {
                    board.spindle(d.spindle, d.rpm, table.settings.spindle_max_rpm);
                    spindle = (d.spindle, d.rpm);
                    if d.rpm != 0 {
                        status.spindle_rpm.store(d.rpm, Relaxed);
                    }
                }
                let result = tape
                    .line(d.no, &d.line, |b| {
                        enqueue(blocks, replan, status, b, &mut last_feed)
                    })
                    .map(|()| board.log_gcode(&d.line))
                    .map_err(GrblError::from);
                if d.end && result.is_ok() {
                    status.ac_new_job.store(true, Relaxed);
                }
                proto.reply(result, &mut out);
                deferred = None;
            } else if idle {
                run_held(&mut tape, board, blocks, replan, status, &mut last_feed);
            }
        }
        let state = if hold || ac_held {
            State::Hold {
                complete: status.stopped(),
            }
        } else {
            match (idle, jogging) {
                (true, _) => State::Idle,
                (false, true) => State::Jog,
                (false, false) => State::Run,
            }
        };
        let room = Q - 1 - blocks.len() >= ROOM_PER_LINE && deferred.is_none() && !replan.pending();
        let mut cx = Context {
            table: &mut *table,
            modes: tape.parser().modes(),
            machine: &settings,
            state,
            frame_cycles: status.frame_cycles(),
            // After a tool breakage the tool is still in the cut and broken: `$X` alone would
            // resume the feed there. A reset first (the queue dropped, the spindle off); then
            // `$X`, jog clear, change the tool and restart the program.
            interlock: if broken {
                Some(alarm::AC_BREAKAGE)
            } else if board.latch_active() {
                board.latched().map(|t| trip_alarm(&t))
            } else {
                None
            },
        };
        let event = if tripped.is_some() {
            Event::Reset
        } else if room {
            proto.poll(&mut out, &mut cx)
        } else {
            proto.poll_realtime(&mut out)
        };
        match event {
            Event::None => {
                // Nothing more has come: let the held block run once the machine would stop.
                if room && idle {
                    run_held(&mut tape, board, blocks, replan, status, &mut last_feed);
                }
            }
            Event::Gcode { line, check } => {
                line_no = line_no.wrapping_add(1);
                if check {
                    // `$C`: parse and validate on a copy; nothing is queued.
                    let mut probe = tape.parser().clone();
                    let result = probe
                        .line(line_no, line)
                        .map(|_| ())
                        .map_err(GrblError::from);
                    proto.reply(result, &mut out);
                } else if let Some((state, rpm, end)) =
                    sync_line::<B>(&tape, line_no, line, spindle)
                {
                    // Wait for the machine (the `ok` comes when the line has run).
                    let mut text = heapless::String::new();
                    if text.push_str(line).is_ok() {
                        run_held(&mut tape, board, blocks, replan, status, &mut last_feed);
                        deferred = Some(Deferred {
                            line: text,
                            no: line_no,
                            spindle: state,
                            rpm,
                            end,
                        });
                    } else {
                        proto.reply(Err(GrblError::OVERFLOW), &mut out);
                    }
                } else {
                    let result = tape
                        .line(line_no, line, |b| {
                            enqueue(blocks, replan, status, b, &mut last_feed)
                        })
                        .map(|()| board.log_gcode(line))
                        .map_err(GrblError::from);
                    proto.reply(result, &mut out);
                }
            }
            Event::Jog(jog) => {
                // The look-ahead's held block goes first (the parser already stands at its end,
                // where the jog is planned from).
                run_held(&mut tape, board, blocks, replan, status, &mut last_feed);
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
                        board.log_jog(&jog);
                        enqueue(blocks, replan, status, b, &mut last_feed);
                        tape.jogged_to(plan.end, signs);
                        jogging = true;
                    }
                });
                proto.reply(result, &mut out);
            }
            Event::Realtime(p) => {
                if p.hold() || p.door() {
                    hold = true;
                }
                if p.resume() && proto.alarm_code().is_none() {
                    hold = false;
                    if ac_held && proto.alarm_code().is_none() {
                        status.ac_resume.store(true, Relaxed);
                    }
                }
                if p.jog_cancel() && jogging {
                    hold = true;
                    cancel_jog = true;
                }
                if p.overrides() {
                    overrides = proto.overrides();
                }
                publish(hold, overrides);
                if p.status() {
                    let options = table.report_options();
                    let v = status.velocity_q8.load(Relaxed);
                    let ac = match status.ac_state.load(Relaxed) {
                        _ if !ac_enabled => None,
                        0 => None,
                        n => {
                            let (f, t) = status.ac_measured();
                            Some(AcReport {
                                feed_share_pct: AcReport::feed_share(
                                    status.feed_cap.load(Relaxed),
                                    last_feed,
                                ),
                                f_ratio_milli: AcReport::ratio_milli(f, ac_settings.f0_n()),
                                t_ratio_milli: AcReport::ratio_milli(t, ac_settings.t0_nm()),
                                state: if n > AC_RUN {
                                    AcState::Hold(n)
                                } else {
                                    AcState::Run
                                },
                            })
                        }
                    };
                    let data = StatusData {
                        // A block the look-ahead holds is a move about to start (queued at the
                        // loader's next turn when no next line comes): the report says `Run`,
                        // so a sender that polls after its last `ok` does not take the job for
                        // done. (The protocol still takes a jog behind it as in Idle.)
                        state: match state {
                            State::Idle if tape.holds_a_block() => State::Run,
                            s => s,
                        },
                        position: status.encoder(),
                        feed_blu_per_min: if idle {
                            0
                        } else {
                            feed_blu_per_min(&settings, v >> 8)
                        },
                        spindle_rpm: tape.parser().spindle_rpm(),
                        blocks_free: (Q - 1 - blocks.len()) as u16,
                        ac,
                        frame_cycles: status.frame_cycles(),
                    };
                    proto.status_report(&data, options, settings.blu, &mut out);
                }
            }
            Event::Reset => {
                // A soft reset (the protocol has answered it) or an input trip: stop at once,
                // drop the queue and the held block; the parser stands where the machine
                // stopped. A reset during motion is an alarm, as in grbl (the position is exact
                // here, and reported); a trip is always one.
                let moving = !idle && !status.stopped();
                // The spindle first (the parser goes back to power-up modes, M5), then the
                // queue.
                spindle = (Spindle::Off, 0);
                broken = false;
                board.spindle(Spindle::Off, 0, table.settings.spindle_max_rpm);
                board.log_reset();
                // A soft reset ends the job: the AC starts the next one afresh.
                status.ac_new_job.store(true, Relaxed);
                let (at, signs) = abort(blocks, status, board);
                replan.restart(at);
                tape.abort(at, signs);
                // A line waiting for the spindle: a soft reset discards it with the stream (the
                // protocol has done so); after a trip it is answered, refused.
                let waiting = deferred.take().is_some();
                hold = false;
                cancel_jog = false;
                jogging = false;
                overrides = proto.overrides();
                publish(hold, overrides);
                match tripped {
                    Some(t) => {
                        proto.alarm(trip_alarm(&t), &mut out);
                        if t.estop {
                            proto.message(&mut out, format_args!("E-stop"));
                        } else {
                            proto.message(
                                &mut out,
                                format_args!("Limit switch {:03b} (ZYX)", t.limits),
                            );
                        }
                        if waiting {
                            proto.reply(Err(GrblError::GCODE_LOCK), &mut out);
                        }
                    }
                    None if moving => proto.alarm(alarm::ABORT_CYCLE, &mut out),
                    None => {}
                }
            }
            Event::Unlock => {
                if let Some(t) = board.latched() {
                    if !board.acknowledge() {
                        // The e-stop or a limit switch is still active: the alarm stays.
                        proto.alarm(trip_alarm(&t), &mut out);
                        proto.message(
                            &mut out,
                            format_args!("E-stop or limit switch still active"),
                        );
                        continue;
                    }
                }
                // `$X` also clears an AC sensor hold: the AC resumes from f_min.
                if ac_held {
                    status.ac_resume.store(true, Relaxed);
                }
            }
            Event::RxOverflow { lost } => proto.rx_overflow(lost, &mut out),
            Event::Replied | Event::CheckMode(_) => {}
        }
    }
}

/// Whether a G-code line waits for the machine to stop before it runs: it ends the program
/// (M2/M30, on every board) or, on a board with a spindle, changes the spindle output. Returns the
/// spindle output it asks for and whether it is the program's end (parsed on a copy of the
/// parser; a line the parser refuses waits for nothing and gets its error from the tape as
/// usual). M2/M30 stops the spindle. Loader task.
fn sync_line<B: LoaderBoard>(
    tape: &Tape,
    line_no: u32,
    line: &str,
    applied: (Spindle, u32),
) -> Option<(Spindle, u32, bool)> {
    if !line.bytes().any(|b| matches!(b, b'M' | b'm' | b'S' | b's')) {
        return None;
    }
    let mut probe = tape.parser().clone();
    let (out, end) = match probe.line(line_no, line) {
        Ok(Parsed::End) => ((Spindle::Off, 0), true),
        Ok(_) => match probe.modes().spindle {
            Spindle::Off => ((Spindle::Off, 0), false),
            s => ((s, probe.spindle_rpm()), false),
        },
        Err(_) => return None,
    };
    (end || (B::SPINDLE && out != applied)).then_some((out.0, out.1, end))
}

/// Queues the look-ahead's held block, if there is one, before the next line has come (logged
/// as such, so the host's replay flushes it at the same place). Loader task.
fn run_held<const Q: usize, const R: usize>(
    tape: &mut Tape,
    log: &mut impl LoaderBoard,
    blocks: &mut Producer<'static, Block, Q>,
    replan: &mut Replan<R>,
    status: &Status,
    last_feed: &mut u32,
) {
    if tape.holds_a_block() {
        log.log_flush();
        tape.flush(|b| enqueue(blocks, replan, status, b, last_feed));
    }
}

/// Soft reset or jog cancel: the frame stops at once and drops every queued block (the abort
/// bit, one block per frame), then the operator's word is restored. Returns the position (BLU)
/// and SIGN lines where the machine stopped, for the parser. Loader task.
fn abort<const Q: usize>(
    blocks: &mut Producer<'static, Block, Q>,
    status: &Status,
    board: &mut impl LoaderBoard,
) -> ([i32; 3], u8) {
    let word = status.operator.load(Relaxed);
    status.operator.store(word | operator::ABORT, Relaxed);
    // The frame pops one block per frame and publishes idle and the position in the frames
    // without pulses: wait for both.
    while blocks.len() != 0 || !status.idle.load(Relaxed) {
        board.wait();
    }
    status.operator.store(word & !operator::ABORT, Relaxed);
    (status.position(), status.next_signs.load(Relaxed))
}

/// Queues a block through the re-plan's record (see `crate::rt::replan`), remembering its
/// programmed feed (for the status report). The loader takes a line only with room for it and
/// nothing waiting in the record, so the record has room and this does not wait.
fn enqueue<const Q: usize, const R: usize>(
    blocks: &mut Producer<'static, Block, Q>,
    replan: &mut Replan<R>,
    status: &Status,
    b: Block,
    feed: &mut u32,
) {
    *feed = match b.motion {
        Motion::Linear(l) => l.f,
        Motion::Arc(a) => a.f,
        _ => *feed,
    };
    replan.enqueue(blocks, b, status, core::hint::spin_loop);
}

/// Queues a block, waiting while the queue is full (the frame drains it). Loader task, both modes.
pub fn enqueue_block<const Q: usize>(blocks: &mut Producer<'static, Block, Q>, b: Block) {
    while blocks.enqueue(b).is_err() {
        core::hint::spin_loop();
    }
}
