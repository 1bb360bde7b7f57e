//! The serial protocol: the subset of grbl 1.1 that G-code senders (Universal G-code Sender,
//! CNCjs, bCNC, Candle, Python streamers) rely on. no_std, no allocation, no panics.
//! Contexts: [`rx::RxIsr::push_byte`] in the RX interrupt; [`Protocol`] (line assembly, `ok` /
//! `error:N`, `$` commands, reports) in the loader task; host tests drive both.
//!
//! The wire, as grbl 1.1 (doc/markdown/interface.md and commands.md of gnea/grbl):
//! - After power-up and every soft reset: `Grbl 1.1h ['$' for help]`, then
//!   `[MSG:millac <version> NC + adaptive control]`.
//! - Exactly one `ok` or `error:N` per received line (CR, LF or CRLF end a line; CRLF is one line
//!   end, where grbl would answer its LF as a second, empty line); an empty line gets `ok`.
//!   Numbers: [`codes`].
//! - Realtime bytes (`?` `!` `~` 0x18 0x84 0x85 0x90..0x97 0x99..0x9E 0xA0 0xA1) are taken out of
//!   the stream wherever they appear, also inside a line or a UTF-8 sequence, and never count
//!   against the receive buffer ([`rx`]).
//! - Receive buffer: 128 bytes for character-counting senders ([`rx::RX_BUFFER_SIZE`]). Lines
//!   longer than [`LINE_MAX`] bytes get `error:11` at their line end; their bytes are discarded.
//!   A line that is not UTF-8 gets `error:1`.
//! - `$` commands (whitespace and comments removed, any case, as grbl): `$` help, `$$` and `$n`,
//!   `$n=value` (through the [`SettingsTable`] hook), `$G`, `$#`, `$I`, `$N`, `$C`, `$X`, `$J=`,
//!   `$H` (`error:5`: no homing), `$RST=` and `$T` (the tool table, [`table::tools`]; through the
//!   hook). Others: `error:3`.
//! - Status report: [`report::write_status`], with millac's `AC:` field ([`report::AcReport`]) and,
//!   on a board that measures its frame ISR, `FC:min,max` (cycles, [`StatusData::frame_cycles`]).
//! - `$I` adds `[FRAME:min,max,budget]` on such a board: the frame's fewest and most cycles from
//!   [`Context::frame_cycles`] and the budget, CPU cycles per rapid period, from the core clock
//!   the board gives once at init ([`Protocol::set_core_hz`]) and `rapid_hz` of
//!   [`Context::machine`]. grbl senders ignore unknown status fields and `[...]` lines.
//!
//! How the loader uses it:
//! ```text
//! loop {
//!     match proto.poll(&mut uart, &mut Context { table, modes, machine, state, frame_cycles, interlock }) {
//!         Event::None => break,                      // nothing more now
//!         Event::Gcode { line, check } => {          // parse (and queue unless check)
//!             let r = feed_line(line, check);        // Result<(), GrblError>
//!             proto.reply(r, &mut uart);             // exactly one ok / error:N
//!         }
//!         Event::Jog(j) => proto.reply(queue_jog(j.plan(parser)), &mut uart),
//!         Event::Realtime(p) => { if p.status() { proto.status_report(&data, opts, blu, &mut uart) } ... }
//!         Event::Reset => { stop, flush the queue, new parser }
//!         Event::RxOverflow { lost } => proto.rx_overflow(lost, &mut uart), // ALARM:110
//!         Event::Replied | Event::Unlock | Event::CheckMode(_) => {}
//!     }
//! }
//! ```
//!
//! The settings table (`$$`, `$n`, `$n=value`, `$RST=`, and the `$10` / `$13` report options) is
//! not here: the loader passes any [`SettingsTable`] in the [`Context`]; the table module
//! implements the trait (one `impl` line at merge).

pub mod codes;
pub mod jog;
pub mod report;
pub mod rx;
pub mod table;

#[cfg(test)]
mod tests;

use crate::gcode::number::parse_decimal;
use crate::gcode::{Decimal, Modes};
use crate::settings::{Blu, Settings};
use core::fmt::{self, Write};

pub use codes::GrblError;
pub use jog::{JogPlan, JogRequest};
pub use report::{AcReport, AcState, FrameCycles, ReportOptions, State, StatusData};
pub use rx::{Overrides, Pending, Push, RxIsr, RxShared, RxTask, RX_BUFFER_SIZE};

/// Longest line in bytes, without its line end (as the tape reader's).
pub const LINE_MAX: usize = crate::gcode::lines::LINE_MAX;

/// The hook to the `$` settings table (implemented by the settings module). Called by the
/// loader task inside [`Protocol::poll`]; the protocol writes the final `ok` / `error:N`.
pub trait SettingsTable {
    /// `$$`: writes every setting as `$n=value\r\n`.
    fn list(&self, out: &mut dyn Write) -> fmt::Result;
    /// `$n=value`: stores one setting, or says why not with a grbl error number (3 unknown
    /// setting, 2 bad number, 4 negative value, ...).
    fn set(&mut self, n: u16, value: Decimal) -> Result<(), u8>;
    /// `$n`: writes the one setting as `$n=value\r\n`. grbl 1.1 has no such command: the default
    /// answers `error:3` as grbl does.
    fn get(&self, n: u16, out: &mut dyn Write) -> Result<(), u8> {
        let _ = (n, out);
        Err(GrblError::INVALID_STATEMENT.0)
    }
    /// `$RST=$`, `$RST=#`, `$RST=*` (`what` is the character after `=`). Default: `error:3`.
    fn restore(&mut self, what: u8) -> Result<(), u8> {
        let _ = what;
        Err(GrblError::INVALID_STATEMENT.0)
    }
    /// `$T...` (`cmd` is what follows `$T`): the tool table listed or one tool set
    /// ([`table::tools`]). Default: `error:3`.
    fn tool(&mut self, cmd: &str, out: &mut dyn Write) -> Result<(), u8> {
        let _ = (cmd, out);
        Err(GrblError::INVALID_STATEMENT.0)
    }
    /// `$10` (status report mask) and `$13` (report inches) as currently set.
    fn report_options(&self) -> ReportOptions;
}

/// What the loader passes to every [`Protocol::poll`].
pub struct Context<'a, T: SettingsTable + ?Sized> {
    /// The `$` settings table.
    pub table: &'a mut T,
    /// The parser's modal state (`$G`).
    pub modes: Modes,
    /// The parser's offsets (`$#`).
    pub offsets: report::OffsetsReport,
    /// The machine settings (BLU, feed DDA for rates in `$G`).
    pub machine: &'a Settings,
    /// What the machine is doing (Idle, Run, Hold, Jog; Alarm and Check are the protocol's own).
    pub state: State,
    /// The frame ISR's (fewest, most) cycles for `$I`, when the board measures them
    /// ([`crate::rt::Status::frame_cycles`]); None: no `[FRAME:...]` line.
    pub frame_cycles: Option<(u32, u32)>,
    /// An alarm `$X` cannot clear now (the board's e-stop or a limit switch still active, or a
    /// tool breakage not yet followed by a reset): `$X` answers `error:9` with `[MSG:...]` and
    /// the alarm stays. None: `$X` unlocks.
    pub interlock: Option<u8>,
}

/// What [`Protocol::poll`] found.
#[derive(Debug, PartialEq, Eq)]
pub enum Event<'a> {
    /// Nothing to do now.
    None,
    /// A line was answered by the protocol itself (empty line, `$` command, refused line): poll
    /// again.
    Replied,
    /// A G-code line (without its line end). Parse it (and queue its blocks unless `check`: `$C`
    /// check mode, nothing may move), then call [`Protocol::reply`] once. Until then, `poll`
    /// takes no further line (realtime requests still come).
    Gcode { line: &'a str, check: bool },
    /// A valid `$J=` jog: plan it ([`JogRequest::plan`]), queue it, then [`Protocol::reply`].
    Jog(JogRequest),
    /// `$H` (mask 0b111), `$HX`, `$HY`, `$HZ` (bit k: axis k), in Idle or Alarm: run the homing
    /// cycle, then [`Protocol::reply`] (`ok` once every axis asked for is home).
    Home(u8),
    /// Realtime requests (`?` `!` `~` 0x85 0x84, override changes).
    Realtime(Pending),
    /// Soft reset (0x18, or `$C` turned off): stop, flush the queue, re-initialise the parser.
    /// The lines before it are discarded unanswered and the banner is already sent (as grbl).
    Reset,
    /// `$X` cleared the alarm lock (`[MSG:Caution: Unlocked]` and `ok` sent).
    Unlock,
    /// `$C` turned check mode on (`[MSG:Enabled]` and `ok` sent). Off comes as [`Event::Reset`].
    CheckMode(bool),
    /// The receive ring refused `lost` bytes (a sender broke the character-counting contract).
    /// The line they belonged to gets `error:11`; whole lines among them get no answer, so the
    /// sender is out of step: raise [`codes::alarm::RX_OVERFLOW`] ([`Protocol::rx_overflow`]).
    /// Also right after an [`Event::Reset`] whose marker did not fit, for the bytes refused after
    /// the reset (the new session's first line lost its start).
    RxOverflow { lost: u32 },
    /// The line source has no more lines. Never from the protocol (a serial line does not end):
    /// a program file's console says it (`crate::rt::program`).
    End,
}

/// The loader's side of the protocol.
pub struct Protocol<'a> {
    rx: RxTask<'a>,
    line: heapless::Vec<u8, LINE_MAX>,
    /// The line being received is refused (too long, or bytes lost): `error:11` at its end.
    damaged: bool,
    after_cr: bool,
    /// An `Event::Gcode` / `Event::Jog` awaits its reply.
    awaiting: bool,
    check: bool,
    alarm: Option<u8>,
    /// Why the stored settings were refused at start-up ([`Protocol::settings_refused`]); told
    /// after every banner until `$X`.
    settings_refused: Option<table::record::RecordError>,
    /// Status reports until the next `WCO:` field (0: in the next one).
    wco_countdown: u8,
    /// The work coordinate offset of the last status report (a change is reported at once).
    last_wco: [i64; 3],
    queue_blocks: u16,
    /// The CPU clock in Hz for the `$I` frame budget (0: not known), [`Protocol::set_core_hz`].
    core_hz: u32,
    /// Data bytes refused after a soft reset whose marker did not fit, to report as
    /// [`Event::RxOverflow`] right after the [`Event::Reset`].
    lost_after_reset: u32,
}

impl<'a> Protocol<'a> {
    /// `queue_blocks`: capacity of the block queue (for `$I`).
    pub fn new(rx: RxTask<'a>, queue_blocks: u16) -> Self {
        Protocol {
            rx,
            line: heapless::Vec::new(),
            damaged: false,
            after_cr: false,
            awaiting: false,
            check: false,
            alarm: None,
            settings_refused: None,
            wco_countdown: 0,
            last_wco: [0; 3],
            queue_blocks,
            core_hz: 0,
            lost_after_reset: 0,
        }
    }

    /// The CPU clock in Hz (init, on a board that measures its frame ISR in cycles): `$I`'s
    /// `[FRAME:min,max,budget]` line gives budget = `hz / rapid_hz`, the cycles of the shortest
    /// frame period. Without it the budget is 0.
    pub fn set_core_hz(&mut self, hz: u32) {
        self.core_hz = hz;
    }

    /// Sends the banner (call once after power-up).
    pub fn start(&mut self, out: &mut dyn Write) {
        self.banner(out);
    }

    /// The settings record was refused at start-up and the defaults replace it (init, before
    /// [`Protocol::start`]): locks G-code with [`codes::alarm::SETTINGS_DEFAULTS`] until `$X`, so
    /// nothing moves on settings the operator did not choose. Every banner until then (the first
    /// one, and those of soft resets, which a sender connecting late sees) is followed by
    /// `ALARM:120` and `[MSG:<why>; defaults loaded]`.
    pub fn settings_refused(&mut self, why: table::record::RecordError) {
        self.alarm = Some(codes::alarm::SETTINGS_DEFAULTS);
        self.settings_refused = Some(why);
    }

    /// The override values the realtime bytes set.
    pub fn overrides(&self) -> Overrides {
        self.rx.overrides()
    }

    /// `$C` check mode.
    pub fn check_mode(&self) -> bool {
        self.check
    }

    /// The alarm that locks G-code, if any.
    pub fn alarm_code(&self) -> Option<u8> {
        self.alarm
    }

    /// Free bytes in the receive ring.
    pub fn rx_available(&self) -> usize {
        self.rx.available()
    }

    /// The state reports and command checks use: the homing cycle, then the alarm lock, then
    /// check mode, then the caller's.
    pub fn state(&self, machine: State) -> State {
        // The homing cycle runs in the alarm lock it is there to clear: `Home`, as grbl says.
        if machine == State::Home {
            State::Home
        } else if self.alarm.is_some() {
            State::Alarm
        } else if self.check {
            State::Check
        } else {
            machine
        }
    }

    /// Pushes `ALARM:N` and locks G-code (`error:9`) until `$X`. A soft reset keeps the lock.
    pub fn alarm(&mut self, code: u8, out: &mut dyn Write) {
        self.alarm = Some(code);
        let _ = report::write_alarm(out, code);
    }

    /// Raises the receive overflow alarm for [`Event::RxOverflow`]: `ALARM:110`, then
    /// `[MSG:receive overflow: N bytes lost]`, and locks G-code like [`Protocol::alarm`].
    pub fn rx_overflow(&mut self, lost: u32, out: &mut dyn Write) {
        self.alarm(codes::alarm::RX_OVERFLOW, out);
        self.message(out, format_args!("receive overflow: {lost} bytes lost"));
    }

    /// Clears the alarm lock without `$X` (a homing cycle that ended: the machine's position is
    /// known again, as grbl's `$H` unlocks).
    pub fn clear_alarm(&mut self) {
        self.alarm = None;
        self.settings_refused = None;
    }

    /// Pushes `[MSG:...]`.
    pub fn message(&mut self, out: &mut dyn Write, text: fmt::Arguments<'_>) {
        let _ = report::write_message(out, text);
    }

    /// Answers the line of the last `Event::Gcode` / `Event::Jog`: `ok` or `error:N`. Returns
    /// false (and writes nothing) when no line awaits an answer, so a line is never answered
    /// twice.
    pub fn reply(&mut self, result: Result<(), GrblError>, out: &mut dyn Write) -> bool {
        if !self.awaiting {
            return false;
        }
        self.awaiting = false;
        self.line.clear();
        respond(out, result);
        true
    }

    /// Answers a `?` with the status report. `data.state` is overridden by the alarm lock and check
    /// mode ([`Protocol::state`]).
    pub fn status_report(
        &mut self,
        data: &StatusData,
        options: ReportOptions,
        unit: Blu,
        out: &mut dyn Write,
    ) {
        let state = self.state(data.state);
        let wco = self.wco_countdown == 0 || data.wco_pm != self.last_wco;
        self.last_wco = data.wco_pm;
        self.wco_countdown = match (wco, state) {
            (false, _) => self.wco_countdown.saturating_sub(1),
            (true, State::Run | State::Hold { .. } | State::Jog | State::Home) => 9,
            (true, _) => 29,
        };
        let cx = report::StatusContext {
            options,
            unit,
            overrides: self.rx.overrides(),
            rx_free: self.rx.available(),
            wco,
        };
        let d = StatusData { state, ..*data };
        let _ = report::write_status(out, &d, &cx);
    }

    /// Takes the next event: a pending soft reset first, then realtime requests, then the next
    /// line (answered here, or handed to the caller).
    pub fn poll<'s, T: SettingsTable + ?Sized>(
        &'s mut self,
        out: &mut dyn Write,
        cx: &mut Context<'_, T>,
    ) -> Event<'s> {
        match self.poll_realtime(out) {
            Event::None => {}
            e => return e,
        }
        if self.awaiting {
            return Event::None;
        }
        self.poll_line(out, cx)
    }

    /// Takes a pending soft reset or realtime request only ([`Event::Reset`], [`Event::Realtime`]
    /// or [`Event::None`]); received lines stay in the ring. The loader polls this way while its
    /// block queue has no room for a line's blocks, so it never blocks and `?`, `!`, `~`, the
    /// overrides and a reset are served at once whatever the queue holds.
    pub fn poll_realtime(&mut self, out: &mut dyn Write) -> Event<'static> {
        if self.rx.resets_pending() {
            // Discard everything received before the reset: up to its marker, or all of it if
            // the marker did not fit.
            let mut lost = 0;
            loop {
                match self.rx.pop() {
                    Some(rx::byte::RESET) => {
                        self.rx.reset_done();
                        break;
                    }
                    Some(_) => {}
                    None => {
                        lost = self.rx.reset_flush();
                        break;
                    }
                }
            }
            self.soft_reset(out);
            // Bytes refused after the reset: the first line of the new session lost its start.
            self.lost_after_reset = lost;
            return Event::Reset;
        }
        if self.lost_after_reset != 0 {
            let lost = core::mem::take(&mut self.lost_after_reset);
            self.damaged = true;
            self.line.clear();
            return Event::RxOverflow { lost };
        }
        let pending = self.rx.take_pending();
        if pending.0 != 0 {
            return Event::Realtime(pending);
        }
        Event::None
    }

    /// The next line (answered here, or handed to the caller), after [`Self::poll_realtime`].
    fn poll_line<'s, T: SettingsTable + ?Sized>(
        &'s mut self,
        out: &mut dyn Write,
        cx: &mut Context<'_, T>,
    ) -> Event<'s> {
        loop {
            let Some(b) = self.rx.pop() else {
                if self.rx.poisoned() {
                    // Everything stored before the loss is processed; the line in progress lost
                    // bytes: refuse it at its end.
                    let lost = self.rx.clear_loss();
                    self.damaged = true;
                    self.line.clear();
                    return Event::RxOverflow { lost };
                }
                return Event::None;
            };
            if b == rx::byte::RESET {
                // A reset that arrived while this poll was reading: its marker is here.
                self.rx.reset_done();
                self.soft_reset(out);
                return Event::Reset;
            }
            let crlf = self.after_cr && b == b'\n';
            self.after_cr = b == b'\r';
            if crlf {
                continue;
            }
            if b == b'\n' || b == b'\r' {
                return self.end_line(out, cx);
            }
            if !self.damaged && self.line.push(b).is_err() {
                self.damaged = true;
                self.line.clear();
            }
        }
    }

    fn banner(&mut self, out: &mut dyn Write) {
        let _ = report::write_banner(out);
        if let (Some(code @ codes::alarm::SETTINGS_DEFAULTS), Some(why)) =
            (self.alarm, self.settings_refused)
        {
            let _ = report::write_alarm(out, code);
            let _ = report::write_message(out, format_args!("{}; defaults loaded", why.message()));
        }
        // The homing lock is said again after every banner (a sender that connects late, or
        // resets, learns why nothing moves).
        if self.alarm == Some(codes::alarm::HOMING_REQUIRED) {
            let _ = report::write_alarm(out, codes::alarm::HOMING_REQUIRED);
        }
        if self.alarm.is_some() {
            let _ = out.write_str("[MSG:'$H'|'$X' to unlock]\r\n");
        }
    }

    fn soft_reset(&mut self, out: &mut dyn Write) {
        self.line.clear();
        self.damaged = false;
        self.after_cr = false;
        self.awaiting = false;
        self.check = false;
        self.wco_countdown = 0;
        self.lost_after_reset = 0;
        self.banner(out);
    }

    fn end_line<'s, T: SettingsTable + ?Sized>(
        &'s mut self,
        out: &mut dyn Write,
        cx: &mut Context<'_, T>,
    ) -> Event<'s> {
        if core::mem::take(&mut self.damaged) {
            self.line.clear();
            respond(out, Err(GrblError::OVERFLOW));
            return Event::Replied;
        }
        let text = match core::str::from_utf8(&self.line) {
            Ok(t) => t.trim(),
            Err(_) => {
                self.line.clear();
                respond(out, Err(GrblError::EXPECTED_COMMAND_LETTER));
                return Event::Replied;
            }
        };
        if text.is_empty() {
            self.line.clear();
            respond(out, Ok(()));
            return Event::Replied;
        }
        if text.starts_with('$') {
            let cmd = compact(text);
            self.line.clear();
            return self.system(&cmd, out, cx);
        }
        if matches!(
            self.state(cx.state),
            State::Alarm | State::Jog | State::Home
        ) {
            self.line.clear();
            respond(out, Err(GrblError::GCODE_LOCK));
            return Event::Replied;
        }
        self.awaiting = true;
        match core::str::from_utf8(&self.line) {
            Ok(line) => Event::Gcode {
                line,
                check: self.check,
            },
            Err(_) => Event::None, // checked above
        }
    }

    /// A `$` command (compacted: no whitespace or comments, upper case).
    fn system<T: SettingsTable + ?Sized>(
        &mut self,
        cmd: &str,
        out: &mut dyn Write,
        cx: &mut Context<'_, T>,
    ) -> Event<'static> {
        let state = self.state(cx.state);
        let idle_or_alarm = matches!(state, State::Idle | State::Alarm);
        let opts = cx.table.report_options();
        let unit = cx.machine.blu;
        let r: Result<(), GrblError> = match cmd {
            "$" => sent(report::write_help(out)),
            "$G" => sent(report::write_modes(out, &cx.modes, cx.machine, opts.inches)),
            // The homing cycle clears the lock itself when it ends.
            "$X" if state == State::Home => Err(GrblError::IDLE_ERROR),
            "$X" if cx.interlock.is_some() && self.alarm.is_some() => {
                let _ = out.write_str(match cx.interlock {
                    Some(codes::alarm::AC_BREAKAGE) => {
                        "[MSG:Tool breakage: reset (Ctrl-X) first, then change the tool]\r\n"
                    }
                    Some(codes::alarm::HOMING_REQUIRED) => "[MSG:Homing required: '$H']\r\n",
                    _ => "[MSG:E-stop still active]\r\n",
                });
                Err(GrblError::GCODE_LOCK)
            }
            "$X" => {
                if self.alarm.take().is_some() {
                    self.settings_refused = None;
                    let _ = out.write_str("[MSG:Caution: Unlocked]\r\n");
                    respond(out, Ok(()));
                    return Event::Unlock;
                }
                Ok(())
            }
            "$C" => {
                if self.check {
                    let _ = out.write_str("[MSG:Disabled]\r\n");
                    respond(out, Ok(()));
                    self.soft_reset(out);
                    return Event::Reset;
                }
                if state != State::Idle {
                    Err(GrblError::IDLE_ERROR)
                } else {
                    self.check = true;
                    let _ = out.write_str("[MSG:Enabled]\r\n");
                    respond(out, Ok(()));
                    return Event::CheckMode(true);
                }
            }
            "$$" if matches!(state, State::Run | State::Hold { .. }) => Err(GrblError::IDLE_ERROR),
            "$$" => sent(cx.table.list(out)),
            _ if cmd.starts_with("$J") => {
                let Some(jog) = cmd.strip_prefix("$J=") else {
                    respond(out, Err(GrblError::INVALID_STATEMENT));
                    return Event::Replied;
                };
                if !matches!(state, State::Idle | State::Jog) {
                    Err(GrblError::IDLE_ERROR)
                } else {
                    match JogRequest::parse(jog) {
                        Ok(j) => {
                            self.awaiting = true;
                            return Event::Jog(j);
                        }
                        Err(e) => Err(e),
                    }
                }
            }
            _ if !idle_or_alarm => Err(GrblError::IDLE_ERROR),
            "$#" => sent(report::write_offsets(out, &cx.offsets, unit, opts.inches)),
            "$I" => {
                let frame = cx.frame_cycles.map(|(min, max)| FrameCycles {
                    min,
                    max,
                    budget: self.core_hz.checked_div(cx.machine.rapid_hz).unwrap_or(0),
                });
                sent(report::write_build_info(
                    out,
                    self.queue_blocks,
                    RX_BUFFER_SIZE,
                    frame,
                ))
            }
            "$N" => sent(out.write_str("$N0=\r\n$N1=\r\n")),
            _ if cmd.starts_with("$H") => {
                let mask = match cmd {
                    "$H" => 0b111,
                    "$HX" => 0b001,
                    "$HY" => 0b010,
                    "$HZ" => 0b100,
                    _ => {
                        respond(out, Err(GrblError::INVALID_STATEMENT));
                        return Event::Replied;
                    }
                };
                self.awaiting = true;
                return Event::Home(mask);
            }
            _ if cmd.starts_with("$T") => cx
                .table
                .tool(cmd.get(2..).unwrap_or(""), out)
                .map_err(GrblError),
            _ => {
                if let Some(what) = cmd.strip_prefix("$RST=") {
                    match what.as_bytes() {
                        [c] => cx.table.restore(*c).map_err(GrblError),
                        _ => Err(GrblError::INVALID_STATEMENT),
                    }
                } else {
                    setting(cmd, out, cx.table)
                }
            }
        };
        respond(out, r);
        Event::Replied
    }
}

/// `$n` or `$n=value`.
fn setting<T: SettingsTable + ?Sized>(
    cmd: &str,
    out: &mut dyn Write,
    table: &mut T,
) -> Result<(), GrblError> {
    let body = cmd.strip_prefix('$').unwrap_or(cmd);
    let (n, value) = match body.split_once('=') {
        Some((n, v)) => (n, Some(v)),
        None => (body, None),
    };
    if n.is_empty() || !n.bytes().all(|b| b.is_ascii_digit()) {
        return Err(GrblError::INVALID_STATEMENT);
    }
    let n: u16 = n.parse().map_err(|_| GrblError::INVALID_STATEMENT)?;
    match value {
        None => table.get(n, out).map_err(GrblError),
        Some(v) => {
            let v = parse_decimal(v).map_err(|_| GrblError::BAD_NUMBER_FORMAT)?;
            table.set(n, v).map_err(GrblError)
        }
    }
}

/// A report was written. Output errors are the writer's business (a UART writer does not fail):
/// the command succeeded and its `ok` follows.
fn sent(_: fmt::Result) -> Result<(), GrblError> {
    Ok(())
}

fn respond(out: &mut dyn Write, r: Result<(), GrblError>) {
    let _ = match r {
        Ok(()) => out.write_str("ok\r\n"),
        Err(GrblError(n)) => write!(out, "error:{n}\r\n"),
    };
}

/// A `$` line as grbl's pre-parser sees it: whitespace, control characters and comments
/// (`(...)`, `;` to the end) removed, letters upper case.
pub(crate) fn compact(text: &str) -> heapless::String<LINE_MAX> {
    let mut s = heapless::String::new();
    let mut paren = false;
    for c in text.chars() {
        if paren {
            paren = c != ')';
            continue;
        }
        match c {
            '(' => paren = true,
            ';' => break,
            c if c.is_whitespace() || c.is_control() => {}
            // The line has at most LINE_MAX bytes, so the compacted one fits.
            c => {
                let _ = s.push(c.to_ascii_uppercase());
            }
        }
    }
    s
}
