//! Program mode's console (loader task): a program file run unattended, as the one loader's line
//! source (`crate::rt::loader`): read through the board in chunks, split into numbered lines
//! (`crate::gcode::lines`), every line handed to the loader in order (empty ones too, so the
//! loader's line numbers are the file's); answers, alarms and chatter reactions become result
//! lines (`error: ...`, `alarm: ...`, `chatter: ...`; the formats the host tools parse, see
//! "Result file" in `crate::wire`). The first refused line ends the reading (the blocks before
//! it still run), as does the program's end (M2/M30) or the file's.
use core::fmt;

use crate::gcode::lines::{Ended, Lines};
use crate::gcode::tape::TapeError;
use crate::gcode::Stop;
use crate::protocol::report::{ReportOptions, StatusData};
use crate::protocol::rx::Overrides;
use crate::protocol::{Context, Event, SettingsTable};
use crate::rt::console::{Console, News, Refused};
use crate::settings::Blu;

/// Bytes read from the file at a time.
pub const CHUNK: usize = 256;

/// The kind of a result line: its first word.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Said {
    /// `error: <why>`: a refused line, or the file unreadable (the run fails).
    Error,
    /// `alarm: <what>`: the machine holds.
    Alarm,
    /// `chatter: <reaction>`: a re-plan, a spindle speed, or why there was none.
    Chatter,
    /// `stop: <what>`: M0 or M6 (unattended, the run goes on).
    Stop,
}

impl Said {
    /// The line's first word.
    pub const fn word(self) -> &'static str {
        match self {
            Said::Error => "error",
            Said::Alarm => "alarm",
            Said::Chatter => "chatter",
            Said::Stop => "stop",
        }
    }
}

/// What program mode needs of a board: the program file, and its result lines. Loader task.
pub trait ProgramFile {
    /// The file's name, for the messages.
    const NAME: &'static str;
    /// Reads the file's next bytes into `buf`: `Some(0)` at its end, None if it cannot be read.
    fn read(&mut self, buf: &mut [u8]) -> Option<usize>;
    /// One result line, `<kind's word>: <text>`, written at once.
    fn result(&mut self, kind: Said, text: fmt::Arguments);
}

/// Program mode's console over a board's [`ProgramFile`].
pub struct Program<F: ProgramFile> {
    file: F,
    chunk: [u8; CHUNK],
    /// The unread part of `chunk`: `pos..len`.
    pos: usize,
    len: usize,
    lines: Lines,
    /// Nothing more is read: the file's end, the program's, or a refusal.
    ended: bool,
    /// A line was refused, or the file could not be read.
    failed: bool,
}

impl<F: ProgramFile> Program<F> {
    pub fn new(file: F) -> Self {
        Program {
            file,
            chunk: [0; CHUNK],
            pos: 0,
            len: 0,
            lines: Lines::new(),
            ended: false,
            failed: false,
        }
    }

    /// False once a line was refused or the file could not be read (the run fails).
    pub fn ok(&self) -> bool {
        !self.failed
    }

    /// The board's file (to close it).
    pub fn into_file(self) -> F {
        self.file
    }

    fn refuse(&mut self, why: fmt::Arguments) {
        self.file.result(Said::Error, why);
        self.failed = true;
        self.ended = true;
    }

    /// A line [`Lines`] ended: handed to the loader, or refused here (too long, not UTF-8).
    fn give(&mut self, ended: Ended) -> Event<'_> {
        match ended.error {
            None => Event::Gcode {
                line: self.lines.text(),
                check: false,
            },
            Some(error) => {
                let e = TapeError::Line {
                    line: ended.no,
                    error,
                };
                self.refuse(format_args!("{}", e));
                Event::End
            }
        }
    }
}

impl<F: ProgramFile> Console for Program<F> {
    fn start(&mut self) {}

    fn poll<'s>(
        &'s mut self,
        _cx: &mut Context<'_, dyn SettingsTable + '_>,
        room: bool,
    ) -> Event<'s> {
        if !room {
            return Event::None;
        }
        loop {
            if self.ended {
                return Event::End;
            }
            if self.pos >= self.len {
                match self.file.read(&mut self.chunk) {
                    None => {
                        self.refuse(format_args!("cannot read {}", F::NAME));
                        return Event::End;
                    }
                    Some(0) => {
                        self.ended = true;
                        return match self.lines.end() {
                            Some(e) => self.give(e),
                            None => Event::End,
                        };
                    }
                    Some(n) => {
                        self.pos = 0;
                        self.len = n.min(CHUNK);
                    }
                }
            }
            let b = self.chunk.get(self.pos).copied().unwrap_or(b'\n');
            self.pos += 1;
            if let Some(e) = self.lines.push(b) {
                return self.give(e);
            }
        }
    }

    fn reply(&mut self, result: Result<(), Refused>) {
        match result {
            Ok(()) => {}
            Err(Refused::Tape(e)) => self.refuse(format_args!("{}", e)),
            Err(Refused::Grbl(e)) => self.refuse(format_args!("line refused (grbl error {})", e.0)),
        }
    }

    fn say(&mut self, news: News<'_>) {
        let f = &mut self.file;
        match news {
            News::FrameLate { overruns, .. } => f.result(
                Said::Alarm,
                format_args!(
                    "frame overrun: the interrupts took longer than the frame period ({} frames, \
                     no pulse lost): the CPU is too slow for these settings",
                    overruns
                ),
            ),
            News::Replanned(r) => f.result(Said::Chatter, format_args!("re-planned {}", r)),
            News::Speed(s) => f.result(Said::Chatter, format_args!("spindle {}", s)),
            News::NotReplanned { at, why } => f.result(
                Said::Chatter,
                format_args!(
                    "not re-planned at {},{},{}: {}",
                    at[0],
                    at[1],
                    at[2],
                    why.message()
                ),
            ),
            News::ProgramEnd => self.ended = true,
            News::Stop {
                stop: Stop::Pause,
                line,
            } => f.result(Said::Stop, format_args!("pause (M0) at line {line}")),
            News::Stop {
                stop: Stop::ToolChange { tool },
                line,
            } => f.result(
                Said::Stop,
                format_args!("tool change (M6) at line {line}: T{tool}"),
            ),
            News::ProbeFailed(code) => f.result(
                Said::Alarm,
                format_args!("probe failed (ALARM:{code}): no contact, or touching at the start"),
            ),
            News::ProbeProtection => f.result(
                Said::Alarm,
                format_args!("probe contact outside a probing move: held"),
            ),
            News::ToolFitted {
                tool,
                limits,
                torque_nm,
            } => f.result(
                Said::Stop,
                format_args!(
                    "{}",
                    crate::rt::console::ToolLimits {
                        tool,
                        limits,
                        torque_nm
                    }
                ),
            ),
            // The AC task writes its own holds (`alarm: ...`) as they come; no operator, no
            // trips, no serial line, no `$H`.
            News::AcHold { .. }
            | News::SpindleStopped
            | News::Tripped(_)
            | News::StillActive(_)
            | News::AbortCycle
            | News::RxOverflow { .. }
            | News::HomingRequired
            | News::Homed
            | News::HomingFailed(_)
            | News::Probed { .. } => {}
        }
    }

    fn status_report(&mut self, _: &StatusData, _: ReportOptions, _: Blu) {}

    fn alarm_code(&self) -> Option<u8> {
        None
    }

    fn overrides(&self) -> Overrides {
        Overrides::NONE
    }

    fn attended(&self) -> bool {
        false
    }
}
