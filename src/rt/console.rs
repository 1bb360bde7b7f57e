//! The loader's consoles (loader task): where its lines come from and where its answers go. The
//! [`Console`] trait is what the one loader (`crate::rt::loader`) needs of them; [`Serial`] is the
//! grbl 1.1 protocol on a board's serial line (an operator and a sender), and
//! `crate::rt::program::Program` a program file run unattended (answers into the board's result
//! lines). The loader holds its console as `&mut dyn Console`: one loader in the firmware's flash
//! whatever the mode.
use core::fmt;

use heapless::spsc::Producer;

use crate::ac::strength::{Limits, Source};
use crate::ac::Alarm;
use crate::gcode::tape::TapeError;
use crate::gcode::Stop;
use crate::inputs::Trip;
use crate::protocol::codes::{alarm, GrblError};
use crate::protocol::report::{ReportOptions, StatusData};
use crate::protocol::rx::Overrides;
use crate::protocol::{Context, Event, Protocol, SettingsTable};
use crate::rt::replan::{self, Replanned, SpeedChange};
use crate::settings::{Blu, Settings};

/// Why a line (or a jog) was refused: by the tape (the parser, or the line itself, with the
/// line's number), or for a reason of the protocol's (grbl's number).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refused {
    Tape(TapeError),
    Grbl(GrblError),
}

impl From<Refused> for GrblError {
    fn from(r: Refused) -> Self {
        match r {
            Refused::Tape(e) => GrblError::from(e),
            Refused::Grbl(e) => e,
        }
    }
}

/// What the machine has to say: the loader decides, the console words it (grbl's `ALARM:N` and
/// `[MSG:...]` on a serial line; `alarm: ...` and `chatter: ...` result lines for a program).
#[derive(Clone, Copy, Debug)]
pub enum News<'a> {
    /// A frame took longer than the board allows (`Some((cycles, limit))`) or overran its period
    /// (None; `overruns` so far): the machine holds.
    FrameLate {
        long: Option<(u32, u32)>,
        overruns: u32,
    },
    /// A tool breakage stopped a running spindle.
    SpindleStopped,
    /// An AC verdict: `lock` is the alarm it raises (None: an overload's feed hold, or a chatter
    /// hold the re-planner answers); `measure_only`: the AC holds nothing, this is only told.
    AcHold {
        alarm: &'a Alarm,
        lock: Option<u8>,
        measure_only: bool,
    },
    /// A chatter hold was re-planned (its detour and copies are queued).
    Replanned(&'a Replanned),
    /// A chatter hold is answered by this spindle speed (applied).
    Speed(&'a SpeedChange),
    /// A chatter hold could not be re-planned: it stays a hold.
    NotReplanned { at: [i32; 3], why: replan::Refusal },
    /// An e-stop or a limit switch tripped: the machine stopped at once.
    Tripped(Trip),
    /// `$X` refused: the e-stop or a limit switch is still active.
    StillActive(Trip),
    /// A soft reset stopped a moving machine (grbl's `ALARM:3`).
    AbortCycle,
    /// The receive ring lost bytes.
    RxOverflow { lost: u32 },
    /// The program's end (M2/M30) has run.
    ProgramEnd,
    /// M0 or M6 on line `line`: the machine stands (and, attended, holds until cycle start).
    Stop { stop: Stop, line: u32 },
    /// Homing is on (`$22`) and the machine does not know where it is: locked until `$H`
    /// (`ALARM:11`).
    HomingRequired,
    /// The homing cycle ended: every axis asked for is home (the alarm lock is cleared).
    Homed,
    /// The homing cycle failed with this alarm (6, 8, 9).
    HomingFailed(u8),
    /// A probing move ended at `at` (machine BLU): `ok`, the probe changed; reported in the BLU
    /// `unit`, in inches with `$13=1`.
    Probed {
        at: [i32; 3],
        ok: bool,
        unit: Blu,
        inches: bool,
    },
    /// A probing move failed with this alarm (4, 5).
    ProbeFailed(u8),
    /// The probe touched outside a probing move: the feed is held (`ALARM:13`).
    ProbeProtection,
    /// An M6 fitted `tool`: its limits and where they come from (None: it has none, the AC
    /// measures only), and the torque the AC holds it to (the tool's or the drive's `$255`,
    /// whichever is lower).
    ToolFitted {
        tool: u8,
        limits: Option<(Limits, Source)>,
        torque_nm: f32,
    },
}

/// The words of [`News::ToolFitted`], one text for every console: `T2: F max 226 N, T max 1.57
/// N*m (its geometry)`, or why the AC measures only.
pub struct ToolLimits {
    pub tool: u8,
    pub limits: Option<(Limits, Source)>,
    pub torque_nm: f32,
}

impl core::fmt::Display for ToolLimits {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let t = self.tool;
        match self.limits {
            Some((l, source)) => write!(
                f,
                "T{t}: F max {:.0} N, T max {:.2} N*m ({})",
                l.force_n,
                self.torque_nm,
                match source {
                    Source::Table => "its table entry",
                    Source::Geometry => "its geometry",
                }
            ),
            None => write!(
                f,
                "T{t} has no limits (give it a diameter or $T{t} F.. M..): the AC measures only"
            ),
        }
    }
}

/// What the loader needs of its line source and its voice. Loader task.
pub trait Console {
    /// Called once, before the first turn (the serial line's banner).
    fn start(&mut self);
    /// The line source's next news. `room`: the block queue can take a line's blocks (without
    /// it, a console may still give realtime requests, never a line); `cx`: for the protocol's
    /// `$` commands. A console with no more lines says [`Event::End`].
    fn poll<'s>(
        &'s mut self,
        cx: &mut Context<'_, dyn SettingsTable + '_>,
        room: bool,
    ) -> Event<'s>;
    /// The answer to the last line or jog [`Console::poll`] gave.
    fn reply(&mut self, result: Result<(), Refused>);
    /// What the machine says.
    fn say(&mut self, news: News<'_>);
    /// `?`: the status report (a console without an operator is never asked).
    fn status_report(&mut self, data: &StatusData, options: ReportOptions, unit: Blu);
    /// The alarm that locks the machine, if any (a resume is refused while it is set).
    fn alarm_code(&self) -> Option<u8>;
    /// The feed and rapid overrides the operator set (100 %: none).
    fn overrides(&self) -> Overrides;
    /// An operator watches and answers (a serial line): a measure-only AC's verdict is told and
    /// the AC goes on at once. Without one (a program run) the verdict stays in the AC's log as
    /// the hold it would have been, and a hold of the machine (a frame overrun) ends the run.
    fn attended(&self) -> bool;
}

/// The grbl 1.1 protocol on a board's serial line: lines from the protocol's receive ring,
/// answers, alarms and messages into the transmit queue. Loader task.
pub struct Serial<'a, const T: usize> {
    proto: &'a mut Protocol<'static>,
    out: Tx<'a, T>,
    /// For the chatter messages in mm.
    mm_per_blu: f32,
}

impl<'a, const T: usize> Serial<'a, T> {
    /// The protocol and its transmit queue (`kick` pends the serial interrupt so that it moves
    /// queued bytes out; it must not block), for a machine with `settings` (its BLU).
    pub fn new(
        proto: &'a mut Protocol<'static>,
        tx: &'a mut Producer<'static, u8, T>,
        kick: fn(),
        settings: &Settings,
    ) -> Self {
        let (num, den) = settings.blu.per_mm();
        Serial {
            proto,
            out: Tx { queue: tx, kick },
            mm_per_blu: den as f32 / num as f32,
        }
    }

    fn message(&mut self, text: fmt::Arguments) {
        self.proto.message(&mut self.out, text);
    }

    fn alarm(&mut self, code: u8) {
        self.proto.alarm(code, &mut self.out);
    }
}

/// The alarm an input trip raises: the e-stop grblHAL's 10, a limit switch grbl's 1 (hard limit).
pub fn trip_alarm(t: &Trip) -> u8 {
    if t.estop {
        alarm::ESTOP
    } else {
        alarm::HARD_LIMIT
    }
}

/// The writer's end of the transmit queue. Loader task.
struct Tx<'a, const N: usize> {
    queue: &'a mut Producer<'static, u8, N>,
    kick: fn(),
}

impl<const N: usize> core::fmt::Write for Tx<'_, N> {
    /// Queues the text, waiting while the queue is full (the serial interrupt drains it), and
    /// kicks the serial interrupt so that it starts sending.
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for b in s.bytes() {
            while self.queue.enqueue(b).is_err() {
                (self.kick)();
                core::hint::spin_loop();
            }
        }
        (self.kick)();
        Ok(())
    }
}

impl<const T: usize> Console for Serial<'_, T> {
    fn start(&mut self) {
        self.proto.start(&mut self.out);
    }

    fn poll<'s>(
        &'s mut self,
        cx: &mut Context<'_, dyn SettingsTable + '_>,
        room: bool,
    ) -> Event<'s> {
        if room {
            self.proto.poll(&mut self.out, cx)
        } else {
            self.proto.poll_realtime(&mut self.out)
        }
    }

    fn reply(&mut self, result: Result<(), Refused>) {
        self.proto
            .reply(result.map_err(GrblError::from), &mut self.out);
    }

    fn say(&mut self, news: News<'_>) {
        let mm_per_blu = self.mm_per_blu;
        let mm = |blu: i32| blu as f32 * mm_per_blu;
        match news {
            News::FrameLate { long, overruns } => {
                self.alarm(alarm::FRAME_OVERRUN);
                match long {
                    Some((max, limit)) => self.message(format_args!(
                        "Frame ISR took {max} cycles, the board allows {limit}: lower $201 or $110"
                    )),
                    None => self.message(format_args!(
                        "Frame overran its period ({overruns} frames so far, no pulse lost): \
                         lower $201 or $110"
                    )),
                }
            }
            News::SpindleStopped => self.message(format_args!("Spindle stopped")),
            News::AcHold {
                alarm,
                lock,
                measure_only,
            } => {
                if measure_only {
                    self.message(format_args!("AC (measure only) would hold: {}", alarm));
                } else {
                    self.message(format_args!("AC hold: {}", alarm));
                }
                if let Some(code) = lock {
                    self.alarm(code);
                }
            }
            News::Replanned(r) => self.message(format_args!(
                "Chatter: depth reduced by {:.3} mm from X{:.3} Y{:.3} Z{:.3}, the rest of line {} \
                 in two passes to X{:.3} Y{:.3} (re-plan {})",
                r.lift as f32 * mm_per_blu,
                mm(r.at[0]),
                mm(r.at[1]),
                mm(r.at[2]),
                r.line,
                mm(r.to[0]),
                mm(r.to[1]),
                r.count
            )),
            News::Speed(s) => self.message(format_args!(
                "Chatter: spindle speed S{} to S{} (chatter {} Hz, {} tooth periods per chatter \
                 period) at line {} (change {})",
                s.from, s.to, s.chatter_hz, s.m, s.line, s.count
            )),
            News::NotReplanned { why, .. } => {
                self.alarm(alarm::AC_CHATTER);
                self.message(format_args!("Chatter: not re-planned: {}", why.message()));
            }
            News::Tripped(t) => {
                self.alarm(trip_alarm(&t));
                if t.estop {
                    self.message(format_args!("E-stop"));
                } else {
                    self.message(format_args!("Limit switch {:03b} (ZYX)", t.limits));
                }
            }
            News::StillActive(t) => {
                self.alarm(trip_alarm(&t));
                self.message(format_args!("E-stop still active"));
            }
            News::AbortCycle => self.alarm(alarm::ABORT_CYCLE),
            News::RxOverflow { lost } => self.proto.rx_overflow(lost, &mut self.out),
            // A sender's next program starts on the same line.
            News::ProgramEnd => {}
            // No line number: a sender numbers its lines itself (millac's count of the lines
            // received would not match its file's).
            News::Stop {
                stop: Stop::Pause, ..
            } => self.message(format_args!("Pause (M0): cycle start resumes")),
            News::Stop {
                stop: Stop::ToolChange { tool },
                ..
            } => self.message(format_args!(
                "Tool change (M6): fit T{tool}, then cycle start"
            )),
            News::HomingRequired => {
                self.alarm(alarm::HOMING_REQUIRED);
                self.message(format_args!("Homing required: '$H'"));
            }
            News::Homed => self.proto.clear_alarm(),
            News::HomingFailed(code) | News::ProbeFailed(code) => self.alarm(code),
            News::ProbeProtection => {
                self.alarm(alarm::PROBE_PROTECTION);
                self.message(format_args!("Probe contact outside probing: held"));
            }
            News::Probed {
                at,
                ok,
                unit,
                inches,
            } => {
                let _ = crate::protocol::report::write_probe(&mut self.out, at, ok, unit, inches);
            }
            News::ToolFitted {
                tool,
                limits,
                torque_nm,
            } => self.message(format_args!(
                "{}",
                ToolLimits {
                    tool,
                    limits,
                    torque_nm
                }
            )),
        }
    }

    fn status_report(&mut self, data: &StatusData, options: ReportOptions, unit: Blu) {
        self.proto.status_report(data, options, unit, &mut self.out);
    }

    fn alarm_code(&self) -> Option<u8> {
        self.proto.alarm_code()
    }

    fn overrides(&self) -> Overrides {
        self.proto.overrides()
    }

    fn attended(&self) -> bool {
        true
    }
}
