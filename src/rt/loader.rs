//! The loader (idle task of every board; host tests): the one state machine between a line
//! source and the block queue, in both modes. Its [`Console`] (`crate::rt::console`) gives the
//! lines and words the answers: [`crate::rt::console::Serial`], G-code streamed by a sender over
//! the board's serial line (the QEMU board's UART0, the Nucleo's USART2) through the grbl 1.1
//! protocol core (`crate::protocol`): the banner, one `ok` or `error:N` per line (grbl's numbers),
//! `$` commands and settings (`$$`; `$N=value` stored at once through the settings storage,
//! effective at the next start for the NC and AC settings), `?` status reports, `$C` check mode,
//! `$X`; or [`crate::rt::program::Program`], a program file run unattended (the QEMU board's
//! `program.nc`: its first refused line ends the reading, its end ends the run once everything
//! has run, see [`Finished`]). Each G-code line runs through the tape (`Tape::line`: an error
//! refuses that line only) into the block queue; the look-ahead's held block runs as soon as no
//! next line has come and the machine would otherwise stop. The RX interrupt (the app's serial
//! task) pushes every byte into the protocol's ring (`RxIsr::push_byte`), which takes the
//! realtime bytes out at once.//!
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
//! The loader is a state machine: [`Loader`] keeps what it must remember between turns (the tape,
//! the operator's hold, a line waiting for the machine, the spindle as applied, ...); each turn
//! ([`Loader::turn`]) gathers the news in a fixed order (the frame's overruns, a tool breakage,
//! the AC's holds, the re-planner's events, the operator's buttons, the machine standing, then the
//! line source: a G-code line, a jog, a realtime request, a reset or a trip, `$X`) and hands each
//! to [`Loader::step`] as a [`Step`]: one match arm per event.
//!
//! The loader never blocks: while the block queue has no room for a line's blocks it polls the
//! realtime requests only (`Console::poll` without room: `Protocol::poll_realtime`), so `?`, `!`, `~` and a reset are served at
//! once whatever the queue holds, and a hold with a full queue cannot stall it.

use crate::ac::strength::{self, Strength};
use crate::ac::AcSettings;
use crate::ac::{Alarm, FeedCeiling};
use crate::gcode::tape::{finish_block, Tape, TapeError};
use crate::nc::{operator, FrameConfig, Motion, Sealed};
use crate::ports::{Board, SettingsStorage};
use crate::protocol::codes::{ac_alarm, alarm, GrblError};
use crate::protocol::report::{feed_blu_per_min, AcReport, AcState, State, StatusData};
use crate::protocol::rx::{Overrides, Pending};
use crate::protocol::table::Persistent;
use crate::protocol::{Context, Event, SettingsTable};
use crate::rt::ac::AC_RUN;
use crate::rt::console::{trip_alarm, Console, News, Refused};
use crate::rt::homing::{self, Step as HomingStep};
use crate::rt::replan::{self, Replan};
use crate::rt::status::{FittedTool, LoaderWriter};
use crate::rt::toolchange::{self, Ended as ChangeEnded, Step as ChangeStep};
use crate::settings::Settings;
use heapless::spsc::{Consumer, Producer};

use crate::gcode::{Decimal, Parsed, Probe, Spindle, Stop, ToolLength};
use crate::inputs::{Events, Trip};
use crate::protocol::jog::JogRequest;
use crate::protocol::LINE_MAX;

/// Free queue slots a line needs before the loader takes it: the look-ahead's held block and the
/// line's own (at most two: G28/G30 through an intermediate point).
const ROOM_PER_LINE: usize = 3;

/// What the loader needs of a board: its serial line (in serial mode), and optionally a session
/// log, a spindle output and operator inputs (the defaults: none). Loader task.
pub trait LoaderBoard {
    /// Sets up the serial line (115200 8N1, receive interrupts on) before the banner.
    fn start(&mut self);

    /// The session log (the QEMU board writes `serve.nc`, see `session`): every accepted G-code
    /// line, in the order the loader fed its tape.
    fn log_gcode(&mut self, _line: &str) {}
    /// A jog that was queued.
    fn log_jog(&mut self, _jog: &JogRequest) {}
    /// The look-ahead's held block ran before the next line came.
    fn log_flush(&mut self) {}
    /// Soft reset.
    fn log_reset(&mut self) {}
    /// A move the loader planned itself (homing, the tool change): `line`, planned on a copy
    /// of the parser without soft limits.
    fn log_move(&mut self, _line: &str) {}
    /// The parser stands at `at` with `signs`: after a soft reset, an axis homed, or (`cut`)
    /// the machine stopped mid-move.
    fn log_stop(&mut self, _at: [i32; 3], _signs: u8, _cut: bool) {}

    /// What the board is (its `Board::SPINDLE`: a line that changes M3/M4/M5 or S waits until
    /// the motion queued before it has finished, grbl's buffer sync, then
    /// [`LoaderBoard::spindle`] applies it, and only then does the line's own motion queue; its
    /// `ok` comes after that).
    type Board: Board;
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
    /// `$X`: clears the latch; false while the e-stop is still active (a limit switch still
    /// closed is let be until it opens, so the machine can be jogged off it).
    fn acknowledge(&mut self) -> bool {
        true
    }
    /// The limit switches closed now (bit k: axis k), for the homing cycle. Default: none.
    fn limits(&mut self) -> u8 {
        0
    }
    /// The probe input is active (as wired; `$6` inverts it in the loader). Default: never.
    fn probe(&mut self) -> bool {
        false
    }
    /// The operator has fitted `tool` at a tool change and pressed cycle start (or, unattended,
    /// the change went on without one): a board with a tool changer, or a simulated machine,
    /// takes it. Default: nothing (the operator did it).
    fn tool_fitted(&mut self, _tool: u8) {}
    /// Whether a closing limit switch trips the alarm latch: off while the homing cycle seeks
    /// the switches, and with `$21=0`; on otherwise (the default, and at power-up).
    fn limit_trips(&mut self, _on: bool) {}
    /// The alarm is latched and the e-stop is still active (`$X` would be refused: the protocol
    /// answers it with `error:9` before saying anything else).
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

/// A line that waits for the machine to stop: one that changes the spindle (see
/// [`LoaderBoard::SPINDLE`]), ends the program (M2/M30, as grbl syncs its buffer there) or stops
/// it (M0, M6).
struct Deferred {
    line: heapless::String<LINE_MAX>,
    no: u32,
    sync: Sync,
}

/// Why a line waits for the machine (see [`sync_line`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Sync {
    /// The spindle output the line asks for.
    spindle: Spindle,
    rpm: u32,
    /// The program's end: once it has run, the AC starts the next job afresh
    /// (`Status::ac_new_job`).
    end: bool,
    /// M0 or M6: once the machine stands, it holds (a serial line: `~` resumes) and says why.
    stop: Option<Stop>,
    /// G38.x: a probing move, watched until the probe changes.
    probe: Option<Probe>,
    /// G4: a dwell, answered once it has run (grbl's G4 waits for the motion before it and
    /// answers after the dwell: senders use it to wait for the machine, CNCjs's `%wait`).
    dwell: bool,
}

/// What the loader works with, from the board's init: the block queue's producer, the re-plan's
/// record, the settings table (loaded, and started the frame with) and its storage, an enabled
/// AC's feed ceiling (None: no AC, or a measure-only one), the protocol and the transmit queue,
/// the AC task's holds, the status words.
pub struct Parts<'r, const Q: usize, const A: usize, const R: usize, S: SettingsStorage> {
    pub blocks: &'r mut Producer<'static, Sealed, Q>,
    pub replan: &'r mut Replan<R>,
    pub table: &'r mut Persistent<S>,
    pub ceiling: Option<FeedCeiling>,
    pub console: &'r mut dyn Console,
    pub ac_alarms: &'r mut Consumer<'static, Alarm, A>,
    pub status: &'r LoaderWriter<'r>,
}

/// What happens to the loader: each turn of its loop gathers the news (the frame's, the AC's, the
/// re-planner's, the inputs', the line source's) and [`Loader::step`]s through them in this
/// order. Adding an event is adding a variant and its arm.
pub enum Step<'l> {
    /// A frame took longer than the board allows (`Some((cycles, limit))`) or found the last
    /// pulse still on the pins (None; `overruns` so far): hold, `ALARM:111`.
    FrameLate {
        long: Option<(u32, u32)>,
        overruns: u32,
    },
    /// The AC task asked for the spindle to stop: a tool breakage.
    Breakage,
    /// An AC verdict (a hold; told, and an alarm unless it is re-planned).
    AcAlarm(Alarm),
    /// The re-planner's news: a re-plan, a spindle speed, a refusal.
    Replan(replan::Event),
    /// The operator's buttons (a trip comes as [`Step::Reset`]).
    Buttons { feed_hold: bool, cycle_start: bool },
    /// A cancelled jog has stopped: drop it.
    JogStopped,
    /// The machine is idle: a line that waits for it (a spindle change, the program's end) runs.
    MachineIdle { idle: bool },
    /// A G-code line from the line source (`check`: `$C`, parse only).
    Line { line: &'l str, check: bool },
    /// A `$J=` jog.
    Jog(JogRequest),
    /// `$H` (mask 0b111) or `$HX`/`$HY`/`$HZ`: the homing cycle.
    Home(u8),
    /// Realtime requests (`?` `!` `~`, jog cancel, overrides).
    Realtime(Pending),
    /// A soft reset, or an input trip (`trip`): stop at once, drop everything queued.
    Reset { trip: Option<Trip> },
    /// `$X`.
    Unlock,
    /// The receive ring lost bytes.
    RxOverflow { lost: u32 },
    /// Nothing came from the line source (`room`: it may have taken a line, and `idle`: the
    /// machine stands): the look-ahead's held block runs.
    NoLine { room: bool, idle: bool },
    /// The line source has no more lines (a program file's end, or its first refused line): the
    /// look-ahead's held block runs, and the run ends once the machine stands.
    End,
}

/// The loader: the state it keeps between turns, and the parts it works on. Loader
/// task (the idle loop); [`run`] turns it while the board runs.
pub struct Loader<
    'r,
    const Q: usize,
    const A: usize,
    const R: usize,
    S: SettingsStorage,
    B: LoaderBoard,
> {
    blocks: &'r mut Producer<'static, Sealed, Q>,
    replan: &'r mut Replan<R>,
    table: &'r mut Persistent<S>,
    /// [`Persistent::work_epoch`] as the parser last took the table's work offsets.
    work_epoch: u32,
    console: &'r mut dyn Console,
    ac_alarms: &'r mut Consumer<'static, Alarm, A>,
    status: &'r LoaderWriter<'r>,
    board: &'r mut B,
    /// The frame's configuration and the parser's, fixed at init: a `$N=value` the table stores
    /// (and `$$` lists) at once takes effect for the NC settings at the next start.
    settings: Settings,
    cfg: FrameConfig,
    /// The AC's limits F0, T0 for the `AC:` field: the tool's in the spindle
    /// (`rt::ac::tool_settings`), before any M6 those the AC task started with (`ac_base`).
    ac_settings: AcSettings,
    ac_base: AcSettings,
    /// The tool in the spindle has limits (none fitted since power-up: the settings' tool has):
    /// without, the AC measures only.
    tool_limited: bool,
    /// The AC caps the feed (the boards give the ceiling only then): the status report's `AC:`
    /// field is about that, so a measure-only AC has none.
    ac_enabled: bool,
    tape: Tape,
    line_no: u32,
    /// The programmed feed of the block the loader queued last (the AC field's feed share).
    last_feed: u32,
    /// A jog is queued and has not finished yet (the state is Jog until the machine is idle).
    jogging: bool,
    /// The operator's feed hold, and a jog cancel waiting for the jog to stop.
    hold: bool,
    cancel_jog: bool,
    overrides: Overrides,
    /// The spindle output as last applied, and a line waiting to change it.
    spindle: (Spindle, u32),
    deferred: Option<Deferred>,
    /// A tool breakage stopped the job: until a reset, `$X` is refused and the spindle stays off.
    broken: bool,
    /// The longest frame already reported over the board's limit (said again only when a longer
    /// one comes).
    overrun: u32,
    /// Frames that overran their period (pulses held back), as last reported.
    overruns: u32,
    /// The AC's hold as last published into the operator's word.
    ac_hold_published: bool,
    /// This turn's view of the machine, taken before the line source is polled.
    now: Now,
    /// The console has no more lines ([`Event::End`]).
    ended: bool,
    /// The homing cycle, while it runs.
    homing: Option<HomingRun>,
    /// The axes homed since power-up (bit k: axis k); a lost position clears them all.
    homed: u8,
    /// A probing move under way (its `ok` waits for it), and where it ended and whether the
    /// probe changed, once it has (the answer waits for the machine to stand).
    probing: Option<Probe>,
    probe_end: Option<([i32; 3], bool)>,
    /// Where the last probing move stopped (machine BLU) and whether the probe changed.
    last_probe: ([i32; 3], bool),
    /// The tool change (`$341` = 1, 2), while it runs.
    change: Option<ChangeRun>,
    /// Where the tool in the spindle touched the tool setter (machine Z, BLU), once measured;
    /// forgotten when the position is lost or a tool comes in unmeasured.
    setter_ref: Option<i32>,
    /// The probe touched at the last turn (probe protection acts on a new contact).
    probe_was: bool,
    /// A G4 line runs: its `ok` comes when the machine stands again.
    dwelling: bool,
    /// The tool length offset the last guided tool change set (and how): the tool in the
    /// spindle's, kept through a soft reset (the tool has not changed).
    tool_tlo: Option<(i64, ToolLength)>,
}

/// A running tool change: its sequence, the M6 line's number, the step under way and the
/// spindle to restore.
struct ChangeRun {
    change: toolchange::Change,
    line: u32,
    under_way: Option<ChangeWait>,
    spindle: (Spindle, u32),
}

/// What a tool change step waits for.
#[derive(Clone, Copy, PartialEq, Eq)]
enum ChangeWait {
    /// A rapid: the machine standing.
    Move,
    /// A probing move: the probe's contact, or the move's end.
    Probe,
    /// The operator's cycle start (the hold released) after fitting this tool.
    Fit(u8),
}

/// A running homing cycle: its sequence, the axes asked for, and the step under way.
struct HomingRun {
    cycle: homing::Cycle,
    mask: u8,
    /// The move or pause under way: the axis whose switch it watches, and whether the switch
    /// stops it. None: the next step is due.
    under_way: Option<(usize, bool)>,
}

/// How a loader's run ended (a console that ends: a program file).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Finished {
    /// Every line has run: the machine stands idle.
    Done,
    /// The machine holds (unattended: a frame overrun) and stands.
    Held,
}

/// The machine as a turn of the loader sees it.
#[derive(Clone, Copy)]
struct Now {
    /// Nothing queued, nothing held for a re-plan, the frame idle.
    idle: bool,
    /// The state for the protocol and the status report.
    state: State,
    /// An enabled AC holds the machine (a measure-only AC's verdict holds nothing).
    ac_held: bool,
}

/// Loader task: runs while [`LoaderBoard::running`] and until the console's lines have all run
/// (a serial line's never end: the operator ends the session by resetting the machine), or an
/// unattended run holds. None: the board stopped it.
pub fn run<
    'r,
    const Q: usize,
    const A: usize,
    const R: usize,
    S: SettingsStorage,
    B: LoaderBoard,
>(
    parts: Parts<'r, Q, A, R, S>,
    board: &'r mut B,
) -> Option<Finished> {
    let mut loader = Loader::new(parts, board);
    while loader.board.running() {
        loader.turn();
        if let Some(f) = loader.finished() {
            return Some(f);
        }
    }
    None
}

impl<'r, const Q: usize, const A: usize, const R: usize, S, B> Loader<'r, Q, A, R, S, B>
where
    S: SettingsStorage,
    B: LoaderBoard,
{
    /// Starts the serial line and says the banner.
    pub fn new(parts: Parts<'r, Q, A, R, S>, board: &'r mut B) -> Self {
        let Parts {
            blocks,
            replan,
            table,
            ceiling,
            console,
            ac_alarms,
            status,
        } = parts;
        board.start();
        console.start();
        let settings = table.settings.nc;
        let ac_enabled = ceiling.is_some();
        if !ac_enabled {
            replan.without_reactions();
        }
        let mut tape = match ceiling {
            Some(c) => Tape::with_ac_ceiling(settings, c),
            None => Tape::new(settings),
        };
        // The work offsets, G28/G30 and the tool table the settings record kept.
        tape.set_work(&table.settings.work);
        let work_epoch = table.work_epoch;
        let overrides = console.overrides();
        let loader = Loader {
            work_epoch,
            blocks,
            replan,
            ac_settings: table.settings.ac,
            ac_base: table.settings.ac,
            tool_limited: true,
            table,
            console,
            ac_alarms,
            status,
            board,
            settings,
            cfg: FrameConfig::from_settings(&settings),
            ac_enabled,
            tape,
            line_no: 0,
            last_feed: 0,
            jogging: false,
            hold: false,
            cancel_jog: false,
            overrides,
            spindle: (Spindle::Off, 0),
            deferred: None,
            broken: false,
            overrun: 0,
            overruns: status.frame_overruns.get(),
            ac_hold_published: status.feed_cap.get() == 0,
            now: Now {
                idle: true,
                state: State::Idle,
                ac_held: false,
            },
            ended: false,
            homing: None,
            homed: 0,
            probing: None,
            probe_end: None,
            last_probe: ([0; 3], false),
            change: None,
            setter_ref: None,
            probe_was: false,
            dwelling: false,
            tool_tlo: None,
        };
        loader
            .board
            .limit_trips(loader.table.settings.setup.hard_limits);
        // With homing on, an operator's machine starts locked until `$H` (`ALARM:11`): it does
        // not know where it is. A program run starts where the machine stands.
        if loader.table.settings.setup.homing && loader.console.attended() {
            loader.console.say(News::HomingRequired);
        }
        loader.publish();
        loader
    }

    /// The operator's word, held also while the AC holds (a cap of 0 stops only the feed: with
    /// the hold a rapid walks its ladder down and no block starts, see `operator::with_ac_hold`).
    fn publish(&self) {
        let (ov, status) = (self.overrides, self.status);
        status.set_operator(operator::with_ac_hold(
            operator::word(ov.feed, ov.rapid, self.hold, false),
            status.feed_cap.get(),
        ));
    }

    /// Whether the run has ended: the console has no more lines and everything it gave has run
    /// (the machine idle, nothing held or waiting), or, unattended, the machine holds and stands.
    pub fn finished(&self) -> Option<Finished> {
        let status = self.status;
        if self.ended
            && self.deferred.is_none()
            && !self.tape.pending()
            && !self.tape.holds_a_block()
            && self.blocks.len() == 0
            && status.idle.get()
            && !self.replan.pending()
            && !self.replan.aborting()
        {
            Some(Finished::Done)
        } else if !self.console.attended() && self.hold && status.stopped() {
            Some(Finished::Held)
        } else {
            None
        }
    }

    /// One turn of the loader's loop: the news in order, each a [`Step`].
    pub fn turn(&mut self) {
        let status = self.status;
        // `$RST=#` or `$RST=*` (answered by the protocol last turn) cleared the work offsets.
        if self.table.work_epoch != self.work_epoch {
            self.work_epoch = self.table.work_epoch;
            self.tape.set_work(&self.table.settings.work);
        }
        if (status.feed_cap.get() == 0) != self.ac_hold_published {
            self.ac_hold_published = !self.ac_hold_published;
            self.publish();
        }
        // A frame too long for the running settings (a board that measures its frame: said
        // again only when a longer one comes), or a frame that found the last pulse still on the
        // pins (the interrupts take longer than the period: no pulse was lost, the frame held
        // them back, but the motion no longer keeps its timing; said once per hold, overruns
        // while already held are not news).
        let n = status.frame_overruns.get();
        let late = core::mem::replace(&mut self.overruns, n) != n && !self.hold;
        let long = match (self.board.frame_limit_cycles(), status.frame_cycles()) {
            (Some(limit), Some((_, max))) if max > limit && max > self.overrun => {
                self.overrun = max;
                Some((max, limit))
            }
            _ => None,
        };
        if late || long.is_some() {
            self.step(Step::FrameLate { long, overruns: n });
        }
        if status.take_spindle_stop() {
            self.step(Step::Breakage);
        }
        while let Some(a) = self.ac_alarms.dequeue() {
            self.step(Step::AcAlarm(a));
        }
        // Chatter suppression: a chatter hold that has stopped the machine is re-planned (the
        // frame drops the queue, waited for here).
        let mut event = self.replan.poll(self.blocks, status);
        while self.replan.aborting() {
            self.board.wait();
            event = self.replan.poll(self.blocks, status);
        }
        self.step(Step::Replan(event));
        // Operator inputs: the buttons as `!` and `~`; an e-stop or a limit switch stops at
        // once like a soft reset (below) and raises its alarm.
        let inputs = self.board.inputs();
        let tripped = inputs.tripped.then(|| {
            self.board.latched().unwrap_or(Trip {
                estop: true,
                limits: 0,
            })
        });
        self.step(Step::Buttons {
            feed_hold: inputs.feed_hold,
            cycle_start: inputs.cycle_start,
        });
        let idle = self.blocks.len() == 0 && status.idle.get() && !self.replan.pending();
        self.now.idle = idle;
        if idle {
            self.jogging = false;
        }
        if self.cancel_jog && status.stopped() {
            self.step(Step::JogStopped);
        }
        // A line that changes the spindle runs once everything before it has run (not in the
        // turn of a trip: the trip drops it below).
        if self.deferred.is_some() && tripped.is_none() && !self.broken {
            self.step(Step::MachineIdle { idle });
        }
        if let Some(trip) = tripped {
            self.step(Step::Reset { trip: Some(trip) });
            return;
        }
        // A measure-only AC's verdict holds nothing (its state is only logged).
        let ac_held = self.ac_applied() && status.ac_state.get() > AC_RUN;
        let state = if self.homing.is_some() {
            State::Home
        } else if self.hold || ac_held {
            State::Hold {
                complete: status.stopped(),
            }
        } else {
            match (idle, self.jogging) {
                (true, _) => State::Idle,
                (false, true) => State::Jog,
                (false, false) => State::Run,
            }
        };
        self.now = Now {
            idle,
            state,
            ac_held,
        };
        self.probe_protection(idle);
        if self.dwelling && self.stands() {
            self.dwelling = false;
            self.console.reply(Ok(()));
        }
        if self.homing.is_some() {
            self.homing_turn(self.stands());
        }
        if self.probing.is_some() {
            self.probe_turn(self.stands());
        }
        if self.change.is_some() {
            self.change_turn(self.stands());
        }
        // A cycle that ended this turn: the reports and the `$` commands of this turn see the
        // machine as it is now (a `?` right after `$H`'s `ok` says Idle, not Home).
        if self.homing.is_none() && self.now.state == State::Home {
            self.now.state = if self.stands() {
                State::Idle
            } else {
                State::Run
            };
        }
        let state = self.now.state;
        // A canned cycle still expanding fills the queue as it empties; no line is taken until
        // it is done.
        if self.tape.pending() && !self.replan.pending() {
            let room = Q - 1 - self.blocks.len();
            let (blocks, replan, status, last_feed) = (
                &mut *self.blocks,
                &mut *self.replan,
                self.status,
                &mut self.last_feed,
            );
            self.tape
                .pump(room, |b| enqueue(blocks, replan, status, b, last_feed));
        }
        // A probing move or a tool change holds the next line until it ends (a serial line's
        // protocol waits for the answer anyway; a program file's console does not).
        let room = Q - 1 - self.blocks.len() >= ROOM_PER_LINE
            && self.deferred.is_none()
            && self.probing.is_none()
            && self.change.is_none()
            && !self.dwelling
            && !self.tape.pending()
            && !self.replan.pending();
        // The line source's news. A G-code line is copied out of the protocol's buffer (the
        // protocol answers it after the step).
        let mut line = heapless::String::<LINE_MAX>::new();
        let unhomed = self.table.settings.setup.homing && self.homed != 0b111;
        let polled = {
            let mut cx: Context<'_, dyn SettingsTable + '_> = Context {
                table: &mut *self.table,
                modes: self.tape.parser().modes(),
                offsets: crate::protocol::report::OffsetsReport {
                    offsets: *self.tape.parser().offsets(),
                    tlo_pm: self.tape.parser().modes().tlo_pm,
                    probe: self.last_probe,
                },
                machine: &self.settings,
                state,
                frame_cycles: status.frame_cycles(),
                // After a tool breakage the tool is still in the cut and broken: `$X` alone would
                // resume the feed there. A reset first (the queue dropped, the spindle off); then
                // `$X`, jog clear, change the tool and restart the program.
                interlock: if self.broken {
                    Some(alarm::AC_BREAKAGE)
                } else if self.board.latch_active() {
                    self.board.latched().map(|t| trip_alarm(&t))
                } else if unhomed {
                    // The position is not known (power-up, or lost): only `$H` unlocks.
                    Some(alarm::HOMING_REQUIRED)
                } else {
                    None
                },
            };
            match self.console.poll(&mut cx, room) {
                Event::None => Some(Step::NoLine { room, idle }),
                Event::Gcode { line: l, check } => {
                    // At most LINE_MAX bytes: the protocol refuses longer lines.
                    let _ = line.push_str(l);
                    return self.step(Step::Line {
                        line: line.as_str(),
                        check,
                    });
                }
                Event::Jog(jog) => Some(Step::Jog(jog)),
                Event::Home(mask) => Some(Step::Home(mask)),
                Event::Realtime(p) => Some(Step::Realtime(p)),
                Event::Reset => Some(Step::Reset { trip: None }),
                Event::Unlock => Some(Step::Unlock),
                Event::RxOverflow { lost } => Some(Step::RxOverflow { lost }),
                Event::End => Some(Step::End),
                Event::Replied | Event::CheckMode(_) => None,
            }
        };
        if let Some(step) = polled {
            self.step(step);
        }
    }

    /// What the loader does with each piece of news.
    pub fn step(&mut self, step: Step<'_>) {
        match step {
            Step::FrameLate { long, overruns } => self.frame_late(long, overruns),
            Step::Breakage => self.breakage(),
            Step::AcAlarm(a) => self.ac_alarm(a),
            Step::Replan(e) => self.replanned(e),
            Step::Buttons {
                feed_hold,
                cycle_start,
            } => {
                if feed_hold {
                    self.hold = true;
                    self.publish();
                }
                // An alarm (a frame overrun, a trip) keeps the hold until `$X`.
                if cycle_start && self.hold && self.console.alarm_code().is_none() {
                    self.hold = false;
                    self.publish();
                }
            }
            Step::JogStopped => {
                // The jog has stopped: drop it and any jog queued behind it. The parser keeps its
                // modes (a jog changes none) and stands where the machine stopped.
                self.stop_here();
                self.cancel_jog = false;
                self.jogging = false;
                self.hold = false;
                self.publish();
            }
            Step::MachineIdle { idle } => self.run_deferred(idle),
            Step::NoLine { room, idle } => {
                // Nothing more has come: let the held block run once the machine would stop.
                if room && idle {
                    self.run_held();
                }
            }
            Step::Line { line, check } => self.line(line, check),
            Step::Jog(jog) => self.jog(jog),
            Step::Home(mask) => self.home(mask),
            Step::Realtime(p) => self.realtime(p),
            Step::Reset { trip } => self.reset(trip),
            Step::Unlock => self.unlock(),
            Step::RxOverflow { lost } => self.console.say(News::RxOverflow { lost }),
            Step::End => {
                self.ended = true;
                self.run_held();
            }
        }
    }

    /// Hold with `ALARM:111`.
    fn frame_late(&mut self, long: Option<(u32, u32)>, overruns: u32) {
        self.hold = true;
        self.publish();
        self.console.say(News::FrameLate { long, overruns });
    }

    /// A tool breakage (the AC task's request): the spindle stops at once and stays off; the
    /// job ends: only a reset (which drops the queue) leads on, then `$X` (see `interlock`), as
    /// grbl's hard limit. No waiting spindle line is applied meanwhile.
    fn breakage(&mut self) {
        self.broken = true;
        if self.spindle.0 != Spindle::Off {
            self.spindle = (Spindle::Off, 0);
            self.board
                .spindle(Spindle::Off, 0, self.table.settings.spindle_max_rpm);
            self.console.say(News::SpindleStopped);
        }
    }

    /// An AC hold: said once, as it comes. A chatter hold with a depth step or a spindle speed
    /// reaction set is answered (by the re-planner), not an alarm, unless the reaction is
    /// refused.
    fn ac_alarm(&mut self, a: Alarm) {
        if !self.ac_applied() {
            // A measure-only AC holds nothing: what it would have held for is told, and the
            // machine goes on unlocked (an alarm would refuse the sender's next line). The AC's
            // controller entered its hold with the verdict: with an operator it resumes at once,
            // so the next verdict is told too (unattended, its log keeps the hold).
            self.console.say(News::AcHold {
                alarm: &a,
                lock: None,
                measure_only: true,
            });
            if self.console.attended() {
                self.status.ask_resume();
            }
            return;
        }
        let replanned = matches!(a, Alarm::Chatter { .. }) && self.replan.reacts();
        let lock = (!matches!(a, Alarm::Overload { .. }) && !replanned).then(|| ac_alarm(&a));
        self.console.say(News::AcHold {
            alarm: &a,
            lock,
            measure_only: false,
        });
    }

    /// Chatter suppression's news: the detour and the copies are queued, or the spindle turns at
    /// the lobe's speed, or the reaction is refused (`ALARM:109`).
    fn replanned(&mut self, event: replan::Event) {
        match event {
            replan::Event::None => {}
            replan::Event::Replanned(r) => self.console.say(News::Replanned(&r)),
            replan::Event::Speed(s) => {
                // The spindle turns at the lobe's speed until the program commands another (in
                // its state: a stopped spindle stays stopped; a simulated one turns anyway); the
                // AC resumes once it is applied.
                self.spindle.1 = s.to;
                self.board
                    .spindle(self.spindle.0, s.to, self.table.settings.spindle_max_rpm);
                self.replan.speed_applied(self.status, s.to);
                self.console.say(News::Speed(&s));
            }
            replan::Event::Refused { at, why } => self.console.say(News::NotReplanned { at, why }),
        }
    }

    /// The waiting line (a spindle change, the program's end) runs once the machine is idle and
    /// the look-ahead holds nothing; while the look-ahead holds a block, that runs first.
    fn run_deferred(&mut self, idle: bool) {
        if !idle {
            return;
        }
        if self.tape.holds_a_block() {
            self.run_held();
            return;
        }
        let Some(d) = self.deferred.take() else {
            return;
        };
        let sync = d.sync;
        if B::Board::SPINDLE && (sync.spindle, sync.rpm) != self.spindle {
            self.board
                .spindle(sync.spindle, sync.rpm, self.table.settings.spindle_max_rpm);
            self.spindle = (sync.spindle, sync.rpm);
            if sync.rpm != 0 {
                self.status.set_spindle_rpm(sync.rpm);
            }
        }
        if let Some(p) = sync.probe {
            return self.probe_start(p, d.no, &d.line);
        }
        let result = self.queue_line(d.no, &d.line);
        let ok = result.is_ok();
        if let Some(Stop::ToolChange { tool }) = sync.stop.filter(|_| ok) {
            // Whatever the mode, the next cut is a new tool's: the AC takes its limits and
            // starts it afresh.
            self.fit_tool(tool);
            self.status.ask_new_job();
            if self.table.settings.setup.tool_change != 0 {
                self.say_tool(tool);
                // The M6's `ok` comes when the change is done.
                return self.change_start(tool, d.no);
            }
            // Fitted by hand, measured nowhere: the setter's reference is the old tool's, and
            // the change's length offset no longer the spindle's.
            self.setter_ref = None;
            self.tool_tlo = None;
        }
        let end = sync.end && ok;
        if end {
            self.status.ask_new_job();
        }
        if sync.dwell && ok {
            // Answered once the dwell has run (see `Loader::turn`).
            self.run_held();
            self.dwelling = true;
            return;
        }
        self.console.reply(result);
        if end {
            self.console.say(News::ProgramEnd);
        }
        if let Some(stop) = sync.stop.filter(|_| ok) {
            // An operator presses cycle start (the hold is grbl's M0 feed hold); a program run
            // unattended has nobody to: the stop is told and the run goes on.
            if self.console.attended() {
                self.hold = true;
                self.publish();
            }
            self.console.say(News::Stop { stop, line: d.no });
            if let Stop::ToolChange { tool } = stop {
                self.say_tool(tool);
            }
        }
    }

    /// Parses a line through the tape and queues its blocks (logged when accepted).
    fn queue_line(&mut self, no: u32, line: &str) -> Result<(), Refused> {
        let (blocks, replan, status, last_feed) = (
            &mut *self.blocks,
            &mut *self.replan,
            self.status,
            &mut self.last_feed,
        );
        // A canned cycle emits what the queue has room for; the rest is pumped turn by turn.
        let room = Q - 1 - blocks.len();
        let result = self
            .tape
            .line_within(no, line, room, |b| {
                enqueue(blocks, replan, status, b, last_feed)
            })
            .map_err(Refused::Tape);
        if result.is_ok() {
            self.board.log_gcode(line);
            // G10, G28.1, G30.1 changed what the settings record keeps: stored at once, as grbl
            // writes its EEPROM (a refused store: error:7, the line has taken effect).
            if self.tape.take_work_changed() {
                let work = self.tape.parser().work();
                if let Err(e) = self.table.set_work(work) {
                    self.work_epoch = self.table.work_epoch;
                    return Err(Refused::Grbl(GrblError(e.code())));
                }
                self.work_epoch = self.table.work_epoch;
            }
        }
        result
    }

    /// A G-code line: checked only (`$C`), deferred until the machine stands (a spindle change,
    /// the program's end), or parsed and queued at once.
    fn line(&mut self, line: &str, check: bool) {
        self.line_no = self.line_no.wrapping_add(1);
        let line_no = self.line_no;
        if check {
            // `$C`: parse and validate on a copy; nothing is queued.
            let mut probe = self.tape.parser().clone();
            let result = probe
                .line(line_no, line)
                .map(|_| ())
                .map_err(|e| Refused::Tape(TapeError::Gcode(e)));
            self.console.reply(result);
        } else if let Some(sync) = sync_line::<B>(&self.tape, line_no, line, self.spindle) {
            // Wait for the machine (the `ok` comes when the line has run).
            let mut text = heapless::String::new();
            if text.push_str(line).is_ok() {
                self.run_held();
                self.deferred = Some(Deferred {
                    line: text,
                    no: line_no,
                    sync,
                });
            } else {
                self.console.reply(Err(Refused::Grbl(GrblError::OVERFLOW)));
            }
        } else {
            let result = self.queue_line(line_no, line);
            self.console.reply(result);
        }
    }

    /// A `$J=` jog: the look-ahead's held block goes first (the parser already stands at its
    /// end, where the jog is planned from). Planned on a copy of the parser (validated like any
    /// block, soft limits included); queued as it is (no AC ceiling: a jog is the operator's
    /// feed); the parser then stands at its end, its modes unchanged.
    fn jog(&mut self, jog: JogRequest) {
        self.run_held();
        let result = jog.plan(self.tape.parser()).map(|plan| {
            if let Some(b) = plan.block {
                let signs = match b.motion {
                    Motion::Linear(l) => l.signs,
                    _ => self.tape.parser().signs(),
                };
                let b = finish_block(b, None, &self.cfg, self.settings.q0);
                self.board.log_jog(&jog);
                enqueue(
                    self.blocks,
                    self.replan,
                    self.status,
                    b,
                    &mut self.last_feed,
                );
                self.tape.jogged_to(plan.end, signs);
                self.jogging = true;
            }
        });
        self.console.reply(result.map_err(Refused::Grbl));
    }

    /// `$H`: the homing cycle starts (`error:5` with homing off, `$22=0`). Its `ok` comes when
    /// every axis asked for is home; the protocol takes no line meanwhile.
    fn home(&mut self, mask: u8) {
        let setup = self.table.settings.setup;
        if !setup.homing {
            self.console
                .reply(Err(Refused::Grbl(GrblError::SETTING_DISABLED)));
            return;
        }
        self.board.limit_trips(false);
        self.homing = Some(HomingRun {
            cycle: homing::Cycle::new(mask, &setup, &self.settings),
            mask,
            under_way: None,
        });
        self.homing_turn(true);
    }

    /// One turn of the homing cycle (`idle`: the machine stands): a move that watches a switch
    /// stops at once when it closes; a step that has ended gives the next.
    fn homing_turn(&mut self, idle: bool) {
        let Some(run) = self.homing.as_mut() else {
            return;
        };
        let closed = |board: &mut B, axis: usize| board.limits() & (1 << axis) != 0;
        let switch = match run.under_way {
            None => false,
            Some((axis, true)) if !idle && closed(self.board, axis) => {
                self.stop_here();
                true
            }
            Some(_) if !idle => return,
            Some((axis, _)) => closed(self.board, axis),
        };
        loop {
            let Some(run) = self.homing.as_mut() else {
                return;
            };
            let step = run.cycle.next(switch);
            match step {
                HomingStep::Move {
                    axis,
                    um,
                    rate_um_min,
                    until_switch,
                } => {
                    run.under_way = Some((axis, until_switch));
                    let here = self.tape.parser().position();
                    let to = here.get(axis).and_then(|&p| {
                        p.checked_add(crate::gcode::fine::blu_of_um(&self.settings, um)?)
                    });
                    let mut target = [None; 3];
                    if let (Some(t), Some(to)) = (target.get_mut(axis), to) {
                        *t = Some(to);
                    }
                    // A move beyond the counters' range: the switch is not where it can be.
                    if to.is_none() || self.machine_move(target, Some(rate_um_min), true).is_err() {
                        return self.homing_ended(HomingStep::Fail(alarm::HOMING_NO_SWITCH));
                    }
                    return;
                }
                HomingStep::Pause { ms } => {
                    run.under_way = Some((0, false));
                    let mut line: heapless::String<24> = heapless::String::new();
                    let _ = core::fmt::Write::write_fmt(
                        &mut line,
                        format_args!(
                            "G4 P{}",
                            Decimal {
                                mantissa: i128::from(ms),
                                scale: 3,
                            }
                        ),
                    );
                    let _ = self.direct_line(&line, true);
                    return;
                }
                HomingStep::Home { axis } => {
                    let home =
                        homing::home_position(axis, &self.table.settings.setup, &self.settings);
                    let raw = self.status.position().get(axis).copied().unwrap_or(0);
                    self.status.set_origin(axis, home.wrapping_sub(raw));
                    run.under_way = None;
                    let at = self.status.machine_position();
                    self.stand_at(at, self.status.next_signs.get(), false);
                }
                HomingStep::Done | HomingStep::Fail(_) => return self.homing_ended(step),
            }
        }
    }

    /// The homing cycle is done (`ok`, the alarm lock cleared) or failed (its alarm; every axis
    /// unhomed).
    fn homing_ended(&mut self, step: HomingStep) {
        let Some(run) = self.homing.take() else {
            return;
        };
        self.board
            .limit_trips(self.table.settings.setup.hard_limits);
        if let HomingStep::Fail(code) = step {
            if !self.now.idle || self.blocks.len() != 0 {
                self.stop_here();
            }
            self.homed = 0;
            self.console.say(News::HomingFailed(code));
            self.console
                .reply(Err(Refused::Grbl(GrblError::GCODE_LOCK)));
        } else {
            self.homed |= run.mask;
            // The lock goes once every axis is home (a `$HX` alone leaves it).
            if self.homed == 0b111 {
                self.console.say(News::Homed);
            }
            self.console.reply(Ok(()));
        }
        self.publish();
    }

    /// The machine stands now: nothing queued, nothing held for a re-plan, the frame idle (read
    /// afresh: a step of this turn may have queued a block).
    fn stands(&self) -> bool {
        self.blocks.len() == 0 && self.status.idle.get() && !self.replan.pending()
    }

    /// Whether the probe touches now (`$6` applied).
    fn probe_contact(&mut self) -> bool {
        self.board.probe() != self.table.settings.setup.probe_invert
    }

    /// A G38 line, the machine standing: refused with `ALARM:4` when the probe is not as the move
    /// expects it (touching before a G38.2/.3, clear before a G38.4/.5); else queued and watched
    /// ([`Self::probe_turn`]), its answer kept until it ends.
    fn probe_start(&mut self, p: Probe, no: u32, line: &str) {
        // Touching before a move toward the work, or clear before one away from it.
        if self.probe_contact() == p.toward {
            return self.probe_failed(alarm::PROBE_INITIAL);
        }
        match self.queue_line(no, line) {
            Ok(()) => self.probing = Some(p),
            Err(e) => self.console.reply(Err(e)),
        }
    }

    /// One turn of a probing move (`idle`: the machine stands): the probe's change stops it at
    /// once; once the machine stands, `[PRB:...]` and its answer (`ALARM:5` when a G38.2/.4
    /// ended without the change). As grbl's G38, which returns after the motion has stopped: the
    /// line after the `ok` (`$#`, any `$` command that needs Idle) finds the machine Idle.
    fn probe_turn(&mut self, idle: bool) {
        let Some(p) = self.probing else {
            return;
        };
        if self.probe_end.is_none() {
            let Some(end) = self.probe_move_ended(p.toward, idle) else {
                return;
            };
            self.probe_end = Some(end);
        }
        if !idle {
            return;
        }
        let Some((at, changed)) = self.probe_end.take() else {
            return;
        };
        self.probing = None;
        self.last_probe = (at, changed);
        self.console.say(News::Probed {
            at,
            ok: changed,
            unit: self.settings.blu,
            inches: self.table.settings.report.inches,
        });
        if !changed && p.must_change {
            self.probe_failed(alarm::PROBE_NO_CONTACT);
        } else {
            self.console.reply(Ok(()));
        }
    }

    /// Whether a probing move (toward the work: `toward`) has ended: the probe changed (the move
    /// stopped at once, here) or the move ran out (`idle`). Then where it stands and whether the
    /// probe changed; None while it moves unchanged. G38 and the tool setter's probes.
    fn probe_move_ended(&mut self, toward: bool, idle: bool) -> Option<([i32; 3], bool)> {
        let changed = self.probe_contact() == toward;
        if !changed && !idle {
            return None;
        }
        let at = if idle {
            self.status.machine_position()
        } else {
            self.stop_here()
        };
        Some((at, changed))
    }

    /// A probing line failed with `code` (4, 5): the alarm, then the line's answer: `ok` on a
    /// serial line, as grbl's (the alarm locks what follows), refused in a program file (its
    /// run ends there).
    fn probe_failed(&mut self, code: u8) {
        self.console.say(News::ProbeFailed(code));
        let answer = if self.console.attended() {
            Ok(())
        } else {
            Err(Refused::Grbl(GrblError::GCODE_LOCK))
        };
        self.console.reply(answer);
    }

    /// Stops the machine at once (the queue dropped) and stands the parser and the re-plan's
    /// record where it stopped (a cancelled jog, a homing switch, a probe's contact). Returns
    /// that position (machine BLU).
    fn stop_here(&mut self) -> [i32; 3] {
        let (at, signs) = abort(self.blocks, self.status, self.board);
        self.stand_at(at, signs, true);
        at
    }

    /// The re-plan's record and the parser stand at `at` with `signs` (logged; `cut`: a move was
    /// stopped short): after a stop, or when an axis is homed (its coordinates changed).
    fn stand_at(&mut self, at: [i32; 3], signs: u8, cut: bool) {
        self.replan.restart(at);
        self.tape.jogged_to(at, signs);
        self.board.log_stop(at, signs, cut);
    }

    /// Queues a move to machine coordinates `target` (BLU; the axes given only): a rapid, or
    /// a feed move at `rate_um_min`. Planned as `G21 G53 G0`/`G1` on a copy of the parser (soft
    /// limits checked as for any line, unless `free`: the homing cycle's), so the modes stay; the
    /// parser stands at its end.
    fn machine_move(
        &mut self,
        target: [Option<i32>; 3],
        rate_um_min: Option<u32>,
        free: bool,
    ) -> Result<(), Refused> {
        let nm = i128::from(self.settings.blu.nm());
        let mm = |v: i128, scale: u8| Decimal { mantissa: v, scale };
        let mut line: heapless::String<LINE_MAX> = heapless::String::new();
        let mut w = |args: core::fmt::Arguments| {
            core::fmt::Write::write_fmt(&mut line, args)
                .map_err(|_| Refused::Grbl(GrblError::OVERFLOW))
        };
        match rate_um_min {
            None => w(format_args!("G21G53G0"))?,
            Some(r) => w(format_args!("G21G53G1F{}", mm(i128::from(r), 3)))?,
        }
        for (k, t) in target.iter().enumerate() {
            if let Some(t) = t {
                let axis = ['X', 'Y', 'Z'].get(k).copied().unwrap_or('Z');
                w(format_args!("{}{}", axis, mm(i128::from(*t) * nm, 6)))?;
            }
        }
        self.direct_line(&line, free)
    }

    /// Queues `line` (a move or a dwell the loader makes itself) as planned on a copy of the
    /// parser (without soft limits when `free`), logged as such; the modes stay, the parser
    /// stands at its end.
    fn direct_line(&mut self, line: &str, free: bool) -> Result<(), Refused> {
        let (block, end, signs) = self
            .tape
            .parser()
            .plan_aside(line, free)
            .map_err(|e| Refused::Tape(TapeError::Gcode(e)))?;
        // Nothing to queue when the machine is already there.
        if let Some(b) = block {
            self.queue_direct(b);
            self.tape.jogged_to(end, signs);
            self.board.log_move(line);
        }
        Ok(())
    }

    /// The AC caps the feed: enabled, and the tool in the spindle has limits.
    fn ac_applied(&self) -> bool {
        self.ac_enabled && self.tool_limited
    }

    /// The limits of tool `tool` in the table as it stands: its own, or from its geometry
    /// (`crate::ac::strength::of_tool`).
    fn limits_of(&self, tool: u8) -> Option<(strength::Limits, strength::Source)> {
        let entry = self.tape.parser().tools().get(u32::from(tool))?;
        strength::of_tool(entry, &Strength::HSS)
    }

    /// An M6 fits `tool`: its limits, flutes and number go to the AC task, the sampler and the
    /// status report through the status words.
    fn fit_tool(&mut self, tool: u8) {
        let fitted = FittedTool::of(tool, self.tape.parser().tools().get(u32::from(tool)));
        self.status.set_tool(&fitted);
        let s = crate::rt::ac::tool_settings(&self.ac_base, &fitted);
        self.tool_limited = s.is_some();
        self.ac_settings = s.map_or(self.ac_base, |s| s.get());
    }

    /// Says the limits the AC holds the fitted `tool` to, or that it has none.
    fn say_tool(&mut self, tool: u8) {
        let limits = self.limits_of(tool).filter(|_| self.tool_limited);
        self.console.say(News::ToolFitted {
            tool,
            limits,
            torque_nm: self.ac_settings.torque_limit_nm,
        });
    }

    /// An M6 with `$341` = 1 or 2 has been parsed (the machine stands): the spindle stops and
    /// the change's first step runs ([`toolchange`]).
    fn change_start(&mut self, tool: u8, line: u32) {
        let parser = self.tape.parser();
        let table_pm = parser
            .tools()
            .get(u32::from(tool))
            .map_or(0, |t| t.length_pm);
        let change = toolchange::Change::new(
            tool,
            self.status.machine_position(),
            parser.offsets().g30,
            parser.modes().tlo_pm,
            table_pm,
            self.setter_ref,
            &self.table.settings.setup,
            &self.settings,
        );
        let spindle = self.spindle;
        if spindle.0 != Spindle::Off {
            self.spindle = (Spindle::Off, spindle.1);
            self.board
                .spindle(Spindle::Off, 0, self.table.settings.spindle_max_rpm);
        }
        self.change = Some(ChangeRun {
            change,
            line,
            under_way: None,
            spindle,
        });
        self.change_turn(true);
    }

    /// One turn of the tool change (`idle`: the machine stands): a probing move stops at once
    /// at the probe's contact; the operator's cycle start ends the wait; a step that has ended
    /// gives the next.
    fn change_turn(&mut self, idle: bool) {
        let Some(run) = self.change.as_ref() else {
            return;
        };
        let mut ended = match run.under_way {
            None => ChangeEnded::Done,
            Some(ChangeWait::Move) if !idle => return,
            Some(ChangeWait::Move) => ChangeEnded::Done,
            Some(ChangeWait::Probe) => match self.probe_move_ended(true, idle) {
                None => return,
                Some((at, contact)) => ChangeEnded::Probed(contact.then_some(at[2])),
            },
            Some(ChangeWait::Fit(_)) if self.hold => return,
            Some(ChangeWait::Fit(tool)) => {
                self.board.tool_fitted(tool);
                ChangeEnded::Done
            }
        };
        loop {
            let Some(run) = self.change.as_mut() else {
                return;
            };
            run.under_way = None;
            let step = run.change.next(ended);
            ended = ChangeEnded::Done;
            let moved = match step {
                ChangeStep::Rapid(target) => self.machine_move(target, None, false),
                ChangeStep::Probe { blu, rate_um_min } => {
                    if self.probe_contact() {
                        // Touching before the probe moves: the setter or the tool is not where
                        // the change expects it.
                        return self.change_ended(Err(alarm::PROBE_INITIAL));
                    }
                    let z = self.status.machine_position()[2];
                    let floor = self.settings.soft_min[2];
                    let target = z.saturating_sub(blu).max(floor);
                    self.machine_move([None, None, Some(target)], Some(rate_um_min), false)
                        .map(|()| {
                            if let Some(run) = self.change.as_mut() {
                                run.under_way = Some(ChangeWait::Probe);
                            }
                        })
                }
                ChangeStep::Fit { tool } => {
                    if !self.console.attended() {
                        // Nobody to fit it: the machine (or a program's simulation) has.
                        self.board.tool_fitted(tool);
                        continue;
                    }
                    let line = run.line;
                    run.under_way = Some(ChangeWait::Fit(tool));
                    self.hold = true;
                    self.publish();
                    self.console.say(News::Stop {
                        stop: Stop::ToolChange { tool },
                        line,
                    });
                    return;
                }
                ChangeStep::Length { tlo_pm, table } => {
                    let how = if table {
                        ToolLength::Table(self.tape.parser().loaded_tool())
                    } else {
                        ToolLength::Dynamic
                    };
                    self.tape.set_tool_length(tlo_pm, how);
                    self.tool_tlo = Some((tlo_pm, how));
                    continue;
                }
                ChangeStep::Spindle => {
                    let (state, rpm) = run.spindle;
                    if state != Spindle::Off {
                        self.spindle = (state, rpm);
                        self.board
                            .spindle(state, rpm, self.table.settings.spindle_max_rpm);
                    }
                    continue;
                }
                ChangeStep::Done => return self.change_ended(Ok(())),
                ChangeStep::Fail(code) => return self.change_ended(Err(code)),
            };
            match moved {
                Err(e) => {
                    // A move the soft limits refuse (the G30 position, the setter or the way
                    // back outside them): the change stops here, the M6 refused.
                    self.change = None;
                    self.console.reply(Err(e));
                    return;
                }
                Ok(()) => {
                    if let Some(run) = self.change.as_mut() {
                        if run.under_way.is_none() {
                            run.under_way = Some(ChangeWait::Move);
                        }
                    }
                    if !self.stands() {
                        return;
                    }
                }
            }
        }
    }

    /// The tool change is done (the M6's `ok`) or failed (its alarm, the M6 refused).
    fn change_ended(&mut self, result: Result<(), u8>) {
        let Some(run) = self.change.take() else {
            return;
        };
        self.setter_ref = run.change.reference();
        match result {
            Ok(()) => self.console.reply(Ok(())),
            Err(code) => {
                self.setter_ref = None;
                self.console.say(News::ProbeFailed(code));
                self.console
                    .reply(Err(Refused::Grbl(GrblError::GCODE_LOCK)));
            }
        }
    }

    /// Probe protection: the probe touching anew while the machine moves outside a probing
    /// move (a jog or a program's move ran it into the work or the setter) holds the feed with
    /// `ALARM:13`. A probe that stays in contact from a probing move's end is no news.
    fn probe_protection(&mut self, idle: bool) {
        let contact = self.probe_contact();
        let probing = self.probing.is_some()
            || self
                .change
                .as_ref()
                .is_some_and(|c| c.under_way == Some(ChangeWait::Probe));
        let new = contact && !core::mem::replace(&mut self.probe_was, contact);
        if new && !idle && !probing && self.homing.is_none() {
            self.hold = true;
            self.publish();
            self.console.say(News::ProbeProtection);
        }
    }

    /// Queues a block planned outside the tape (the homing cycle's moves and pauses).
    fn queue_direct(&mut self, b: crate::nc::Block) {
        let b = finish_block(b, None, &self.cfg, self.settings.q0);
        enqueue(
            self.blocks,
            self.replan,
            self.status,
            b,
            &mut self.last_feed,
        );
    }

    /// Realtime requests: hold, resume, jog cancel, overrides, the status report.
    fn realtime(&mut self, p: Pending) {
        let ac_held = self.now.ac_held;
        if p.hold() || p.door() {
            self.hold = true;
        }
        if p.resume() && self.console.alarm_code().is_none() {
            self.hold = false;
            if ac_held {
                self.status.ask_resume();
            }
        }
        if p.jog_cancel() && self.jogging {
            self.hold = true;
            self.cancel_jog = true;
        }
        if p.overrides() {
            self.overrides = self.console.overrides();
        }
        self.publish();
        if p.status() {
            self.status_report();
        }
    }

    /// `?`: the status report.
    fn status_report(&mut self) {
        let status = self.status;
        let Now { idle, state, .. } = self.now;
        let options = self.table.report_options();
        let v = status.velocity_q8.get();
        let ac = match status.ac_state.get() {
            _ if !self.ac_applied() => None,
            0 => None,
            n => {
                let (f, t) = status.ac_measured();
                Some(AcReport {
                    feed_share_pct: AcReport::feed_share(status.feed_cap.get(), self.last_feed),
                    f_ratio_milli: AcReport::ratio_milli(f, self.ac_settings.f0_n()),
                    t_ratio_milli: AcReport::ratio_milli(t, self.ac_settings.t0_nm()),
                    state: if n > AC_RUN {
                        AcState::Hold(n)
                    } else {
                        AcState::Run
                    },
                })
            }
        };
        let data = StatusData {
            // A block the look-ahead holds is a move about to start (queued at the loader's next
            // turn when no next line comes): the report says `Run`, so a sender that polls after
            // its last `ok` does not take the job for done. (The protocol still takes a jog
            // behind it as in Idle.)
            state: match state {
                State::Idle if self.tape.holds_a_block() => State::Run,
                s => s,
            },
            position: status.machine_encoder(),
            feed_blu_per_min: if idle {
                0
            } else {
                feed_blu_per_min(&self.settings, v >> 8)
            },
            spindle_rpm: self.tape.parser().spindle_rpm(),
            blocks_free: (Q - 1 - self.blocks.len()) as u16,
            tool: status.fitted_tool().map_or(0, |t| t.1.number),
            ac,
            wco_pm: self.tape.parser().work_origin_pm(),
            frame_cycles: status.frame_cycles(),
            pins: self.board.limits() | u8::from(self.probe_contact()) << 3,
        };
        self.console
            .status_report(&data, options, self.settings.blu);
    }

    /// A soft reset (the protocol has answered it) or an input trip: stop at once, drop the
    /// queue and the held block; the parser stands where the machine stopped. A reset during
    /// motion is an alarm, as in grbl (the position is exact here, and reported); a trip is
    /// always one.
    fn reset(&mut self, trip: Option<Trip>) {
        let status = self.status;
        let moving = !self.now.idle && !status.stopped();
        // The spindle first (the parser goes back to power-up modes, M5), then the queue.
        self.spindle = (Spindle::Off, 0);
        self.broken = false;
        self.board
            .spindle(Spindle::Off, 0, self.table.settings.spindle_max_rpm);
        self.board.log_reset();
        // A soft reset ends the job: the AC starts the next one afresh.
        status.ask_new_job();
        let (at, signs) = abort(self.blocks, status, self.board);
        self.replan.restart(at);
        self.tape.abort(at, signs);
        self.board.log_stop(at, signs, moving);
        // The parser's modes are at power-up (G49), but the tool in the spindle is the one the
        // last guided change measured: its length offset stays.
        if let Some((pm, how)) = self.tool_tlo {
            self.tape.set_tool_length(pm, how);
        }
        // A stop in motion loses the position (the drives may not have followed an abrupt
        // stop): homing, when on, is required again. A homing cycle under way fails (ALARM:6
        // after a soft reset; a trip says its own alarm).
        let homing = self.homing.take();
        let probing = self.probing.take();
        self.probe_end = None;
        let changing = self.change.take();
        if moving || homing.is_some() {
            self.homed = 0;
            self.setter_ref = None;
        }
        if homing.is_some() {
            self.board
                .limit_trips(self.table.settings.setup.hard_limits);
        }
        // A line waiting for the spindle: a soft reset discards it with the stream (the protocol
        // has done so); after a trip it is answered, refused.
        let waiting = self.deferred.take().is_some() || core::mem::take(&mut self.dwelling);
        self.hold = false;
        self.cancel_jog = false;
        self.jogging = false;
        self.overrides = self.console.overrides();
        self.publish();
        match trip {
            Some(t) => {
                self.console.say(News::Tripped(t));
                if waiting {
                    self.console
                        .reply(Err(Refused::Grbl(GrblError::GCODE_LOCK)));
                }
            }
            None if homing.is_some() => self.console.say(News::HomingFailed(alarm::HOMING_RESET)),
            None if moving => self.console.say(News::AbortCycle),
            None => {}
        }
        if (homing.is_some() || probing.is_some() || changing.is_some()) && trip.is_some() {
            // The `$H` awaits its answer (a soft reset discards it with the stream).
            self.console
                .reply(Err(Refused::Grbl(GrblError::GCODE_LOCK)));
        }
    }

    /// `$X` (the protocol has cleared its alarm): refused while the e-stop is still active (a
    /// limit switch still closed is let be: jog off it); also clears an AC sensor hold (the AC
    /// resumes from f_min).
    fn unlock(&mut self) {
        if let Some(t) = self.board.latched() {
            if !self.board.acknowledge() {
                // The e-stop is still active: the alarm stays.
                self.console.say(News::StillActive(t));
                return;
            }
        }
        if self.now.ac_held {
            self.status.ask_resume();
        }
    }

    /// Queues the look-ahead's held block, if there is one, before the next line has come (logged
    /// as such, so the host's replay flushes it at the same place).
    fn run_held(&mut self) {
        if self.tape.holds_a_block() {
            self.board.log_flush();
            let (blocks, replan, status, last_feed) = (
                &mut *self.blocks,
                &mut *self.replan,
                self.status,
                &mut self.last_feed,
            );
            self.tape
                .flush(|b| enqueue(blocks, replan, status, b, last_feed));
        }
    }
}

/// Whether a G-code line waits for the machine to stop before it runs: it ends the program
/// (M2/M30, on every board), stops it (M0, M6), changes what the settings record keeps (G10,
/// G28.1, G30.1: stored once the machine stands, as grbl syncs its buffer before writing its
/// EEPROM; a flash store stalls the F446's interrupts) or, on a board with a spindle, changes the
/// spindle output. Returns the spindle output it asks for, whether it is the program's end and
/// its stop (parsed on a copy of the parser; a line the parser refuses waits for nothing and gets
/// its error from the tape as usual). M2/M30 stops the spindle. Loader task.
fn sync_line<B: LoaderBoard>(
    tape: &Tape,
    line_no: u32,
    line: &str,
    applied: (Spindle, u32),
) -> Option<Sync> {
    let letters = line.bytes().any(|b| matches!(b, b'M' | b'm' | b'S' | b's'));
    let probe = line.as_bytes().windows(2).any(|w| w == b"38");
    if !letters && !probe && !may_store(line) && !may_dwell(line) {
        return None;
    }
    let mut probe = tape.parser().clone();
    let parsed = probe.line(line_no, line).ok()?;
    let stores = probe.take_work_changed();
    let (spindle, rpm) = match (parsed, probe.modes().spindle) {
        (Parsed::End, _) | (_, Spindle::Off) => (Spindle::Off, 0),
        (_, s) => (s, probe.spindle_rpm()),
    };
    let sync = Sync {
        spindle,
        rpm,
        end: parsed == Parsed::End,
        stop: match parsed {
            Parsed::Stop(s) => Some(s),
            _ => None,
        },
        probe: match parsed {
            Parsed::Probe(_, p) => Some(p),
            _ => None,
        },
        dwell: matches!(parsed, Parsed::Block(b) if matches!(b.motion, Motion::Dwell(_))),
    };
    (sync.end
        || sync.stop.is_some()
        || sync.probe.is_some()
        || sync.dwell
        || stores
        || (B::Board::SPINDLE && (spindle, rpm) != applied))
        .then_some(sync)
}

/// Whether a line may hold G4 (a G, zeros, then a 4 that no digit or point follows; spaces
/// ignored as the parser ignores them): only such lines are parsed on a copy to find out.
pub(crate) fn may_dwell(line: &str) -> bool {
    let mut b = line.bytes().filter(|b| !b.is_ascii_whitespace()).peekable();
    while let Some(c) = b.next() {
        if c.eq_ignore_ascii_case(&b'G') {
            while b.peek() == Some(&b'0') {
                b.next();
            }
            if b.peek() == Some(&b'4') {
                b.next();
                if !b.peek().is_some_and(|n| n.is_ascii_digit() || *n == b'.') {
                    return true;
                }
            }
        }
    }
    false
}

/// Whether a line may hold G10, G28.1 or G30.1 (its digits "10", "28.1" or "30.1", spaces
/// ignored as the parser ignores them): only such lines are parsed on a copy to find out.
fn may_store(line: &str) -> bool {
    let mut last = [0u8; 3];
    for b in line.bytes().filter(|b| !b.is_ascii_whitespace()) {
        let hit = matches!((last, b), ([_, b'1', b'0'], _) if b != b'.' && !b.is_ascii_digit())
            || matches!(
                (last, b),
                ([b'2', b'8', b'.'], b'1') | ([b'3', b'0', b'.'], b'1')
            );
        if hit {
            return true;
        }
        last = [last[1], last[2], b];
    }
    last[1..] == *b"10"
}

/// Soft reset or jog cancel: the frame stops at once and drops every queued block (the abort
/// bit, one block per frame), then the operator's word is restored. Returns the position (BLU)
/// and SIGN lines where the machine stopped, for the parser. Loader task.
fn abort<const Q: usize>(
    blocks: &mut Producer<'static, Sealed, Q>,
    status: &LoaderWriter,
    board: &mut impl LoaderBoard,
) -> ([i32; 3], u8) {
    status.operator_bits(operator::ABORT, true);
    // The frame pops one block per frame and publishes idle and the position in the frames
    // without pulses: wait for both.
    while blocks.len() != 0 || !status.idle.get() {
        board.wait();
    }
    status.operator_bits(operator::ABORT, false);
    (status.machine_position(), status.next_signs.get())
}

/// Queues a block through the re-plan's record (see `crate::rt::replan`), remembering its
/// programmed feed (for the status report). The loader takes a line only with room for it and
/// nothing waiting in the record, so the record has room and this does not wait.
fn enqueue<const Q: usize, const R: usize>(
    blocks: &mut Producer<'static, Sealed, Q>,
    replan: &mut Replan<R>,
    status: &LoaderWriter,
    b: Sealed,
    feed: &mut u32,
) {
    *feed = match b.motion {
        Motion::Linear(l) => l.f,
        Motion::Arc(a) => a.f,
        _ => *feed,
    };
    replan.enqueue(blocks, b, status, core::hint::spin_loop);
}
