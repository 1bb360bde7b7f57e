//! G-code lines -> validated blocks (loader task). This is the only place where the program is
//! validated: the frame interrupt trusts every [`Block`] it gets.
//!
//! The dialect is grbl 1.1's with grblHAL's tool table: G0 G1 G2 G3 G4 G10 (L1, L2, L20) G17 G18
//! G19 G20 G21 G28 G28.1 G30 G30.1 G40 G43 G43.1 G49 G53 G54-G59 G61 G61.1 G64 G80 G90 G91
//! G92 G92.1 G92.2 G92.3 G93 G94 G98 G99, M0 M1 M2 M30 M3 M4 M5 M6 M7 M8 M9, `%` lines, words
//! F S T N X Y Z I J K R P Q L H. Comments `( )` and `;`, any case, whitespace anywhere.
//! Power-up modes as grbl: G0, G17, G54, G90, G94, G49, G40, but G20 (inch) and no feed.
//! LinuxCNC's macro language (`#`, `[...]`, O-words) and cutter compensation (G41/G42) are
//! refused with an error naming the construct ([`error::Construct`]). docs/user/gcode.md lists
//! every code with its behaviour and its error.
//!
//! Files: [`number`] exact decimals, [`words`] the lexer, `exec` the line semantics,
//! [`offsets`] work coordinates, [`tools`] the tool table, [`arc`] arc planning, [`lookahead`]
//! the deceleration rule, [`error`] the reasons.

pub mod arc;
pub mod cycles;
pub mod error;
mod exec;
pub mod fine;
pub mod lines;
pub mod lookahead;
pub mod number;
pub mod offsets;
pub mod tape;
pub mod tools;
pub mod words;

#[cfg(test)]
mod tests;

use crate::nc::{Block, Plane};
use crate::settings::Settings;

pub use error::ErrorKind;
pub use exec::motion_code;
pub use lookahead::Lookahead;
pub use number::Decimal;
pub use offsets::{Offsets, Work};
pub use tools::{Tool, ToolKind, ToolTable};

/// What one accepted line produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Parsed {
    /// A line with no motion (comment, modal words only, empty).
    Nothing,
    /// One validated block for the queue.
    Block(Block),
    /// Two blocks, in order (G28/G30 through an intermediate point).
    Two(Block, Block),
    /// A canned cycle or an arc of P turns: its blocks come from [`Expansion::next_block`].
    Expand(Expansion),
    /// M2 / M30: end of program.
    End,
    /// M0 or M6: the machine stops once the motion before it has run and waits for cycle start.
    Stop(Stop),
    /// G38.2-G38.5: a probing move, run once the machine stands and stopped where the probe
    /// input changes (the loader watches it).
    Probe(Block, Probe),
}

/// What a probing move waits for (G38.2-G38.5, as LinuxCNC and grbl).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Probe {
    /// G38.2, G38.3: stop on contact; G38.4, G38.5: stop on loss of contact.
    pub toward: bool,
    /// G38.2, G38.4: the move's end without the change is an alarm (`ALARM:5`); G38.3, G38.5:
    /// it is not (the report says `:0`).
    pub must_change: bool,
}

impl Probe {
    /// The probe of a G38 code in tenths (382..=385).
    pub const fn of_code(code: u16) -> Option<Probe> {
        match code {
            382..=385 => Some(Probe {
                toward: code <= 383,
                must_change: code % 2 == 0,
            }),
            _ => None,
        }
    }
}

/// A line that expands into more blocks than a line may queue at once: the tape emits them one at
/// a time as the queue has room (loader task; host).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Expansion {
    /// A canned cycle (G73, G81-G89).
    Cycle(cycles::Cycle),
    /// A G2/G3 of P turns.
    Turns(arc::Turns),
}

impl Expansion {
    /// The next block, `None` once all are out.
    pub fn next_block(&mut self, st: &Settings) -> Option<Block> {
        match self {
            Expansion::Cycle(c) => c.next_block(st),
            Expansion::Turns(t) => t.next_block(st),
        }
    }

    /// Every block is out.
    pub fn done(&self) -> bool {
        match self {
            Expansion::Cycle(c) => c.done(),
            Expansion::Turns(t) => t.done(),
        }
    }
}

/// Why a program stops and waits for the operator's cycle start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// M0: program pause.
    Pause,
    /// M6: fit tool `tool` (the last T word; 0 = take the tool out).
    ToolChange { tool: u8 },
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
    /// G80: no motion mode (axis words alone are an error).
    None,
    /// G73, G81, G82, G83, G85, G89.
    Cycle(cycles::CycleKind),
}

/// G93 inverse time / G94 units per minute.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FeedMode {
    PerMinute,
    InverseTime,
}

/// G61 exact path, G61.1 exact stop, G64 blending: accepted; the frame runs every block
/// exactly (see `exec::modal_words`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathMode {
    ExactPath,
    ExactStop,
    Blend,
}

/// G98 / G99: the canned cycles' return level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Retract {
    /// G98: back to the Z where the cycle began.
    Initial,
    /// G99: back to the R plane.
    RPlane,
}

/// G49 / G43 Hn / G43.1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToolLength {
    Off,
    Table(u8),
    Dynamic,
}

/// M7 (mist) and M8 (flood); M9 both off.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Coolant {
    pub mist: bool,
    pub flood: bool,
}

impl Coolant {
    pub const OFF: Coolant = Coolant {
        mist: false,
        flood: false,
    };
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
    /// G54..G59 as 0..5.
    pub coord: u8,
    pub feed_mode: FeedMode,
    /// The tool length offset in force (Z, picometres) and how it was set.
    pub tlo_pm: i64,
    pub tool_length: ToolLength,
    pub retract: Retract,
    pub path: PathMode,
    pub coolant: Coolant,
    /// The last T word (the tool the next M6 fits).
    pub tool: u8,
    /// The canned cycle's sticky words.
    pub cycle: cycles::CycleWords,
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
        coord: 0,
        feed_mode: FeedMode::PerMinute,
        tlo_pm: 0,
        tool_length: ToolLength::Off,
        retract: Retract::Initial,
        path: PathMode::ExactPath,
        coolant: Coolant::OFF,
        tool: 0,
        cycle: cycles::CycleWords {
            r: 0,
            z: 0,
            q: 0,
            dwell_frames: 0,
            il: None,
        },
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
    /// The programmed position, exact, in fine units (see [`fine::FINE_PER_MM`]): G91 increments
    /// and G20/G21 switches add up exactly, and only the machine target is rounded to a BLU, so N
    /// increments end where one move of their sum would.
    programmed: [i128; 3],
    modes: Modes,
    /// The SIGN lines as they stand after the last accepted block (bit k set = axis k positive).
    signs: u8,
    /// Work coordinate systems, G28/G30 positions and G92.
    offsets: Offsets,
    tools: ToolTable,
    /// The tool in the spindle (the last M6's).
    loaded: u8,
    /// A line changed what the settings record keeps ([`Work`]) since [`Parser::take_work_changed`].
    work_changed: bool,
}

impl Parser {
    pub fn new(settings: Settings) -> Self {
        Parser {
            settings,
            position: [0; 3],
            programmed: [0; 3],
            modes: Modes::POWER_UP,
            signs: 0,
            offsets: Offsets::default(),
            tools: ToolTable::default(),
            loaded: 0,
            work_changed: false,
        }
    }

    /// Parses one line. On `Err` no state changed (the line runs on a copy of the state that is
    /// committed only on success).
    pub fn line(&mut self, line_no: u32, text: &str) -> Result<Parsed, GcodeError> {
        let mut modes = self.modes;
        let mut position = self.position;
        let mut programmed = self.programmed;
        let mut offsets = self.offsets;
        let mut loaded = self.loaded;
        let mut tool_set = None;
        let state = exec::State {
            modes: &mut modes,
            pos: exec::Position {
                blu: &mut position,
                fine: &mut programmed,
            },
            offsets: &mut offsets,
            loaded: &mut loaded,
            tools: &self.tools,
            tool_set: &mut tool_set,
        };
        match exec::execute(&self.settings, state, line_no, text) {
            Ok(mut p) => {
                let o = &self.offsets;
                if tool_set.is_some()
                    || (o.systems, o.g28, o.g30) != (offsets.systems, offsets.g28, offsets.g30)
                {
                    self.work_changed = true;
                }
                self.modes = modes;
                self.position = position;
                self.programmed = programmed;
                self.offsets = offsets;
                self.loaded = loaded;
                if let Some((n, tool)) = tool_set {
                    self.tools.set(n, tool);
                }
                match &mut p {
                    Parsed::Block(b) | Parsed::Probe(b, _) => {
                        self.signs = carry_signs(&mut b.motion, self.signs)
                    }
                    Parsed::Expand(c) => {
                        // The SIGN lines after the expansion: its blocks run through once here.
                        let mut c = *c;
                        while let Some(mut b) = c.next_block(&self.settings) {
                            self.signs = carry_signs(&mut b.motion, self.signs);
                        }
                    }
                    Parsed::Two(a, b) => {
                        self.signs = carry_signs(&mut a.motion, self.signs);
                        self.signs = carry_signs(&mut b.motion, self.signs);
                    }
                    _ => {}
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
    /// defaults, as grbl 1.1 resets them: motion G1, plane G17, distance G90, feed mode G94,
    /// coordinate system G54, spindle M5, coolant M9. The units (G20/G21), the feed F, the speed
    /// S, the tool length offset and G92 stay, and so do the position (machine and programmed)
    /// and the SIGN lines. A sender that shows the units from `$G` keeps showing the program's.
    pub fn end_program(&mut self) {
        self.modes = Modes {
            motion: MotionMode::Linear,
            plane: Plane::XY,
            distance: Distance::Absolute,
            feed_mode: FeedMode::PerMinute,
            coord: 0,
            spindle: Spindle::Off,
            coolant: Coolant::OFF,
            ..self.modes
        };
    }

    /// Soft reset: every mode returns to power-up (grbl re-initialises its parser state: G54,
    /// G49, and the G92 offset cleared); the position, the SIGN lines, the stored offsets, the
    /// tool table and the tool in the spindle stay.
    pub fn reset_modes(&mut self) {
        self.modes = Modes::POWER_UP;
        self.offsets.g92 = [0; 3];
        self.offsets.g92_on = false;
    }

    /// A jog (grbl's `$J=`, planned on a copy of this parser) moved the machine to `end` (BLU):
    /// the machine and the programmed position follow it exactly (a BLU is a whole number of the
    /// fine units); the modes stay as they were, as grbl leaves them after a jog; the SIGN lines
    /// follow `signs`, the jog block's. Loader task.
    pub fn jogged_to(&mut self, end: [i32; 3], signs: u8) {
        self.position = end;
        self.programmed = end.map(|b| fine::fine_of_blu(&self.settings, b));
        self.signs = signs;
    }

    /// The tool change (`rt::toolchange`) set the new tool's length offset: as `G43 H<n>` (the
    /// table's) or `G43.1` (a measured one) would; nothing moves. Loader task.
    pub fn set_tool_length(&mut self, tlo_pm: i64, how: ToolLength) {
        self.modes.tlo_pm = tlo_pm;
        self.modes.tool_length = how;
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

    /// Work coordinate systems, G28/G30 positions and G92.
    pub fn offsets(&self) -> &Offsets {
        &self.offsets
    }

    /// Sets the stored offsets (restored from the settings record at start).
    pub fn set_offsets(&mut self, offsets: Offsets) {
        self.offsets = offsets;
    }

    /// A copy without soft limits: the homing cycle plans its moves on it (they run before the
    /// machine knows where it is, and toward the switches beyond the limits). Loader task.
    pub fn without_soft_limits(&self) -> Parser {
        let mut p = self.clone();
        p.settings.soft_min = [i32::MIN; 3];
        p.settings.soft_max = [i32::MAX; 3];
        p
    }

    /// Plans `text` on a copy of this parser (`free`: without soft limits), which is left as it
    /// was: the block the line makes (None: it makes none) and where the copy then stands, with
    /// its SIGN lines. Loader task (jogs, the homing cycle's and the tool change's moves); host
    /// (their replay).
    pub fn plan_aside(
        &self,
        text: &str,
        free: bool,
    ) -> Result<(Option<Block>, [i32; 3], u8), GcodeError> {
        let mut p = if free {
            self.without_soft_limits()
        } else {
            self.clone()
        };
        let block = match p.line(0, text)? {
            Parsed::Block(b) => Some(b),
            _ => None,
        };
        Ok((block, p.position, p.signs))
    }

    /// The tool table.
    pub fn tools(&self) -> &ToolTable {
        &self.tools
    }

    /// Sets the tool table (restored from the settings record at start).
    pub fn set_tools(&mut self, tools: ToolTable) {
        self.tools = tools;
    }

    /// What the settings record keeps: the systems, G28/G30 and the tool table.
    pub fn work(&self) -> Work {
        let o = &self.offsets;
        Work {
            systems: o.systems,
            g28: o.g28,
            g30: o.g30,
            tools: self.tools,
        }
    }

    /// Restores what the settings record kept (at start, and after `$RST=#` or `$RST=*`); G92
    /// stays as it is.
    pub fn set_work(&mut self, w: &Work) {
        self.offsets.systems = w.systems;
        self.offsets.g28 = w.g28;
        self.offsets.g30 = w.g30;
        self.tools = w.tools;
    }

    /// Whether a line changed [`Parser::work`] since the last call (G10, G28.1, G30.1): the
    /// loader then stores it, as grbl writes its EEPROM.
    pub fn take_work_changed(&mut self) -> bool {
        core::mem::replace(&mut self.work_changed, false)
    }

    /// The tool in the spindle (the last M6's; 0 = none).
    pub fn loaded_tool(&self) -> u8 {
        self.loaded
    }

    /// The origin of the program coordinates in machine coordinates, picometres (the active
    /// system, G92 and the tool length offset): the work coordinate offset, `WCO`.
    pub fn work_origin_pm(&self) -> [i64; 3] {
        self.offsets.origin(self.modes.coord, self.modes.tlo_pm)
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
            // A helix's third axis: set once, at the block's start (see `Frame::initiate`).
            let z = 1u8 << (3 - a - b);
            if c.helix > 0 {
                s |= z;
            } else if c.helix < 0 {
                s &= !z;
            }
            s
        }
        Motion::Dwell(_) => current,
    }
}
