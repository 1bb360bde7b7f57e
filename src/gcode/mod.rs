//! G-code lines -> validated blocks (loader task). This is the only place where the program is
//! validated: the frame interrupt trusts every [`Block`] it gets.
//!
//! Supported words: G0 G1 G2 G3 G4 G17 G18 G19 G20 G21 G90 G91 G94, M2 M30 (end), M3 M4 M5
//! (the spindle's modal state, [`Spindle`]: no NC effect, a board with a spindle output applies
//! it), M8 M9 (accepted, no effect), N (ignored), F S X Y Z I J K R P. Comments `( )` and `;`, any case,
//! whitespace anywhere. Power-up modes as grbl: G0, G17, G90, G94, but G20 (inch) and no feed.
//!
//! Files: [`number`] exact decimals, [`words`] the lexer, `exec` the line semantics,
//! [`arc`] arc planning, [`lookahead`] the deceleration rule, [`error`] the reasons.

pub mod arc;
pub mod error;
mod exec;
pub mod lines;
pub mod lookahead;
pub mod number;
pub mod tape;
pub mod words;

#[cfg(test)]
mod tests;

use crate::nc::{Block, Plane};
use crate::settings::Settings;

pub use error::ErrorKind;
pub use lookahead::Lookahead;
pub use number::Decimal;

/// What one accepted line produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Parsed {
    /// A line with no motion (comment, modal words only, empty).
    Nothing,
    /// One validated block for the queue.
    Block(Block),
    /// M2 / M30: end of program.
    End,
}

/// A rejected line: its number and the reason. Display: "line N: reason".
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GcodeError {
    pub line: u32,
    pub kind: ErrorKind,
}

impl core::fmt::Display for GcodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "line {}: {}", self.line, self.kind)
    }
}

/// The modal motion (group 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotionMode {
    /// G0
    Rapid,
    /// G1
    Linear,
    /// G2
    ArcCw,
    /// G3
    ArcCcw,
}

/// Units of lengths and feeds in the program (G20 / G21).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Units {
    Inch,
    Mm,
}

/// G90 absolute / G91 incremental (X, Y, Z only; I, J, K are always incremental).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Distance {
    Absolute,
    Incremental,
}

/// The modal state of the parser.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Modes {
    pub motion: MotionMode,
    pub plane: Plane,
    pub units: Units,
    pub distance: Distance,
    /// Feed number f of the last F word (0 = none yet, or F0), see [`feed_number`].
    pub feed: u32,
    /// Spindle speed of the last S word (rpm, rounded).
    pub spindle_rpm: u32,
    /// M3 / M4 / M5. The frame does not see it: a board with a spindle output applies it when
    /// the motion queued before the line has finished (see `crate::rt::loader`).
    pub spindle: Spindle,
}

/// The spindle's modal state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Spindle {
    /// M5 (power-up, and after M2/M30).
    Off,
    /// M3: clockwise.
    Cw,
    /// M4: counter-clockwise.
    Ccw,
}

impl Modes {
    /// grbl's power-up modes, but inch units: G0 G17 G20 G90 G94, no feed, S0.
    pub const POWER_UP: Modes = Modes {
        motion: MotionMode::Rapid,
        plane: Plane::XY,
        units: Units::Inch,
        distance: Distance::Absolute,
        feed: 0,
        spindle_rpm: 0,
        spindle: Spindle::Off,
    };
}

/// The feed number f for a feed `value` in the given units per minute, where `per_unit` is BLU per
/// unit as a rational (`Blu::per_inch()` / `per_mm()`):
/// f = round(F_BLU_per_min * q0 / (frame_hz * 60)), i.e. f = q0 * FR / FRM (f = 100 * FR in ipm at
/// the paper's W0 = 5 kHz, q0 = 3000, BLU = 0.0001 in).
///
/// Clamp: f is at most q0, i.e. feeds above FRM = W0 * 60 BLU/min (the highest contouring feed,
/// 30 ipm at the defaults) run at FRM. A nonzero F that rounds to 0 gives f = 1. F0 gives 0
/// (which G1/G2/G3 refuse). `None` if the value is negative or absurdly large (overflow).
pub fn feed_number(st: &Settings, value: Decimal, per_unit: (i64, i64)) -> Option<u32> {
    if value.is_negative() {
        return None;
    }
    let num = (per_unit.0 as i128).checked_mul(st.q0 as i128)?;
    let den = (per_unit.1 as i128)
        .checked_mul(st.frame_hz as i128)?
        .checked_mul(60)?;
    let f = value.mul_ratio_round(num, den)?;
    if f == 0 && !value.is_zero() {
        return Some(1);
    }
    Some(f.min(st.q0 as i128) as u32)
}

/// Modal G-code state and the programmed position.
#[derive(Clone, Debug)]
pub struct Parser {
    settings: Settings,
    /// Machine position after the last accepted block, BLU: the rounded `programmed` position.
    position: [i32; 3],
    /// The programmed position, exact, in fine units (see [`exec::FINE_PER_MM`]): G91 increments
    /// and G20/G21 switches add up exactly, and only the machine target is rounded to a BLU, so N
    /// increments end where one move of their sum would.
    programmed: [i128; 3],
    modes: Modes,
    /// The SIGN lines as they stand after the last accepted block (bit k set = axis k positive).
    signs: u8,
}

impl Parser {
    pub fn new(settings: Settings) -> Self {
        Parser {
            settings,
            position: [0; 3],
            programmed: [0; 3],
            modes: Modes::POWER_UP,
            signs: 0,
        }
    }

    /// Parses one line. On `Err` no state changed (the line runs on a copy of the state that is
    /// committed only on success).
    pub fn line(&mut self, line_no: u32, text: &str) -> Result<Parsed, GcodeError> {
        let mut modes = self.modes;
        let mut position = self.position;
        let mut programmed = self.programmed;
        let pos = exec::Position {
            blu: &mut position,
            fine: &mut programmed,
        };
        match exec::execute(&self.settings, &mut modes, pos, line_no, text) {
            Ok(mut p) => {
                self.modes = modes;
                self.position = position;
                self.programmed = programmed;
                if let Parsed::Block(b) = &mut p {
                    self.signs = carry_signs(&mut b.motion, self.signs);
                }
                Ok(p)
            }
            Err(kind) => Err(GcodeError {
                line: line_no,
                kind,
            }),
        }
    }

    /// Program end (M2/M30): the modes the NIST RS274/NGC program-end rules name return to their
    /// defaults, as grbl 1.1 resets them: motion G1, plane G17, distance G90, spindle M5. The
    /// units (G20/G21), the feed F and the speed S stay, and so do the position (machine and
    /// programmed) and the SIGN lines. A sender that shows the units from `$G` keeps showing the
    /// program's.
    pub fn end_program(&mut self) {
        self.modes = Modes {
            motion: MotionMode::Linear,
            plane: Plane::XY,
            distance: Distance::Absolute,
            spindle: Spindle::Off,
            ..self.modes
        };
    }

    /// Soft reset: every mode returns to power-up (grbl re-initialises its parser state); the
    /// position and the SIGN lines stay.
    pub fn reset_modes(&mut self) {
        self.modes = Modes::POWER_UP;
    }

    /// A jog (grbl's `$J=`, planned on a copy of this parser) moved the machine to `end` (BLU):
    /// the machine and the programmed position follow it exactly (a BLU is a whole number of the
    /// fine units); the modes stay as they were, as grbl leaves them after a jog; the SIGN lines
    /// follow `signs`, the jog block's. Loader task.
    pub fn jogged_to(&mut self, end: [i32; 3], signs: u8) {
        self.position = end;
        self.programmed = end.map(|b| exec::fine_of_blu(&self.settings, b));
        self.signs = signs;
    }

    /// SIGN lines after the last accepted block (bit k set = axis k positive).
    pub fn signs(&self) -> u8 {
        self.signs
    }

    /// Programmed position after the last accepted block, machine BLU.
    pub fn position(&self) -> [i32; 3] {
        self.position
    }

    /// The current modal state.
    pub fn modes(&self) -> Modes {
        self.modes
    }

    /// Spindle speed of the last S word in rpm (0 before any S).
    pub fn spindle_rpm(&self) -> u32 {
        self.modes.spindle_rpm
    }

    /// The settings the parser validates against.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }
}

/// Completes the sign byte of a G0/G1 block: an axis that does not move keeps its SIGN line as it
/// stands (`current`), so the frame writes the block's byte as it is (no per-axis masking in the
/// interrupt). Returns the SIGN lines after the block; for an arc that is the direction of each plane
/// axis in the last segment that moves it, exactly as the frame sets them segment by segment.
pub fn carry_signs(motion: &mut crate::nc::Motion, current: u8) -> u8 {
    use crate::nc::Motion;
    let keep = |steps: &[u32; 3], signs: &mut u8| {
        let moving = (0..3)
            .filter(|&k| steps[k] != 0)
            .fold(0u8, |m, k| m | 1 << k);
        *signs = (*signs & moving) | (current & !moving);
        *signs
    };
    match motion {
        Motion::Rapid(r) => keep(&r.steps, &mut r.signs),
        Motion::Linear(l) => keep(&l.steps, &mut l.signs),
        Motion::Arc(c) => {
            let (a, b) = c.plane.axes();
            let mut s = current;
            let mut p = c.start;
            for t in c.targets.iter().take(c.n_targets as usize) {
                for (bit, d) in [(1u8 << a, t[0] - p[0]), (1u8 << b, t[1] - p[1])] {
                    if d > 0 {
                        s |= bit;
                    } else if d < 0 {
                        s &= !bit;
                    }
                }
                p = *t;
            }
            s
        }
        Motion::Dwell(_) => current,
    }
}
