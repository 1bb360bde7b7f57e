//! Why a G-code line was rejected: [`ErrorKind`] with the offending values, formatted without
//! allocation. Built by the G-code parser (loader task), displayed by the host tool and the tests.

use super::number::Decimal;
use core::fmt;

/// A G or M code in tenths: G1 = 10, G43.1 = 431, G92.3 = 923.
pub type Code = u16;

/// Writes a code in tenths as G-code writes it: `G43.1`, `M6`.
pub fn write_code(f: &mut dyn fmt::Write, letter: char, code: Code) -> fmt::Result {
    match code % 10 {
        0 => write!(f, "{letter}{}", code / 10),
        t => write!(f, "{letter}{}.{t}", code / 10),
    }
}

/// Why a canned cycle line was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CycleError {
    /// A cycle outside G17.
    NotXy,
    /// A cycle in G93.
    InverseTime,
    /// R below the bottom Z.
    RBelowZ,
    /// L not 1 or more.
    Repeats,
    /// Q not above zero.
    Peck,
}

impl CycleError {
    pub const fn describe(self) -> &'static str {
        match self {
            CycleError::NotXy => "canned cycles run in the XY plane only (G17)",
            CycleError::InverseTime => "canned cycles cannot run in inverse time (G93): use G94",
            CycleError::RBelowZ => "the cycle's R plane is below its bottom Z",
            CycleError::Repeats => "the cycle's repeat count L must be 1 or more",
            CycleError::Peck => "the peck depth Q must be greater than zero",
        }
    }
}

/// A construct of LinuxCNC's (or another control's) G-code that is outside millac's grbl dialect;
/// the error names it so that the machinist knows what to change in the CAM post.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Construct {
    /// `#` numbered or named parameters.
    Parameter,
    /// `[...]` expressions.
    Expression,
    /// O-words: subroutines and flow control.
    OWord,
    /// `@` and `^`: LinuxCNC's polar coordinates.
    Polar,
    /// G41/G42 (and G41.1/G42.1): cutter radius compensation.
    CutterCompensation,
    /// G59.1, G59.2, G59.3: coordinate systems beyond grbl's six.
    G59Extended,
    /// G10 L1/L10/L11 forms other than millac's tool table form, or an L that is not 1, 2, 20.
    G10Form,
}

impl Construct {
    pub const fn describe(self) -> &'static str {
        match self {
            Construct::Parameter => "parameters (#) are not supported: LinuxCNC's macro language is outside the grbl dialect; post the program without variables",
            Construct::Expression => "expressions ([...]) are not supported: LinuxCNC's macro language is outside the grbl dialect; post the program with plain numbers",
            Construct::OWord => "O-words (subroutines, loops, conditions) are not supported: LinuxCNC's macro language is outside the grbl dialect; post the program without them",
            Construct::Polar => "polar coordinates (@ radius, ^ angle) are not supported: post the program with X and Y",
            Construct::CutterCompensation => "cutter radius compensation (G41/G42) is not supported: let the CAM program the tool centre path (compensation 'in computer') and use G40",
            Construct::G59Extended => "G59.1-G59.3 are not supported: grbl has the six coordinate systems G54-G59",
            Construct::G10Form => "this G10 form is not supported: G10 L2 / L20 P0-P6 set a coordinate system, G10 L1 P<tool> Z<length> R<radius> a tool",
        }
    }
}

/// Axis letter of an axis index (X, Y, Z).
pub const fn axis_name(axis: usize) -> char {
    match axis {
        0 => 'X',
        1 => 'Y',
        _ => 'Z',
    }
}

/// The reason a line was rejected. Lengths and radii are in BLU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorKind {
    /// A character that cannot start a word (not a letter, comment or space).
    UnexpectedCharacter(char),
    /// `(` without `)`.
    UnclosedComment,
    /// A letter that is not a supported word.
    UnsupportedLetter(char),
    /// A letter not followed by a number.
    MissingNumber(char),
    /// A letter followed by something that is not a valid decimal number.
    MalformedNumber(char),
    /// A number that does not fit (in BLU for lengths, i32; or the feed, dwell, rpm ranges).
    NumberTooLarge(char),
    /// More than [`super::number::MAX_DECIMALS`] decimal places.
    TooManyDecimals(char),
    /// A G number this parser does not implement.
    UnsupportedG(Decimal),
    /// An M number this parser does not implement.
    UnsupportedM(Decimal),
    /// The same letter (not G/M) twice on one line.
    RepeatedWord(char),
    /// Two G or M codes of the same modal group on one line (e.g. two motion modes), in tenths.
    ModalConflict {
        letter: char,
        first: Code,
        second: Code,
    },
    /// A construct of another dialect (LinuxCNC's macros, cutter compensation, ...).
    NotInDialect(Construct),
    /// A word that must be a whole number (P of G10, L, H, T) is not.
    NotInteger(char),
    /// Two commands on one line that both use the axis words (e.g. G92 with G1).
    AxisCommandConflict,
    /// A command that needs axis words has none (G10, G92, G43.1).
    NoAxisWords { code: Code },
    /// A command needs a word that is missing (G10 without L or P, a cycle without R).
    MissingWord { code: Code, letter: char },
    /// G10's P or G54..: a coordinate system that is not P0..P6.
    CoordinateSystem,
    /// G53 outside G0/G1, or in G91.
    G53Motion,
    /// Axis words on a line whose command does not take them (G80, G28.1, ...).
    AxisWordsUnused { code: Code },
    /// G43.1 with an X or Y word (the tool length is along Z).
    ToolLengthAxis,
    /// T, H or G10 L1's P names no tool of the table (1..=`MAX_TOOLS`; T0 is no tool).
    ToolNumber { value: u32 },
    /// G93 (inverse time) motion without its F on the line.
    InverseTimeNeedsF,
    /// A canned cycle's words or state do not allow it.
    Cycle(CycleError),
    /// F, S or P below zero.
    NegativeValue(char),
    /// G1/G2/G3 with no feed rate programmed, or F0.
    NoFeed { code: u8 },
    /// G4 without P.
    DwellNeedsP,
    /// G4 with an axis word.
    DwellWithAxes,
    /// A word the line's command does not use (I/J/K/R outside G2/G3, P outside G4, an offset of
    /// the axis normal to the plane).
    UnusedWord(char),
    /// M0, M1, M2, M30 or M6 on a line that also moves or dwells (the code, in tenths).
    StopWithMotion { code: Code },
    /// The target of an axis does not fit i32 BLU.
    TargetOverflow { axis: char },
    /// The length of a line does not fit the 32-bit DDA (q = L).
    MoveTooLong,
    /// A target or arc extreme outside the soft limits.
    SoftLimit {
        axis: char,
        value: i64,
        min: i32,
        max: i32,
    },
    /// G2/G3 with neither I/J/K nor R.
    ArcNeedsCentre { code: u8 },
    /// R together with I/J/K.
    ArcRadiusAndOffsets,
    /// G2/G3's P (turns) not a whole number from 1 to `nc::MAX_TURNS`, or P > 1 in the R form.
    ArcTurns,
    /// A probing move (G38.x) of less than a BLU.
    ProbeTarget,
    /// R-form arc whose end point equals its start point.
    ArcFullCircleRadius,
    /// Arc radius (start radius or R) of zero.
    ArcZeroRadius,
    /// |R| smaller than half the chord beyond the tolerance.
    ArcRadiusTooSmall { radius: i64, half_chord: i64 },
    /// End radius differs from start radius beyond the tolerance.
    ArcEndNotOnCircle { start: i64, end: i64 },
    /// The end point lies off the circle in a way the quadrant segments cannot reach with
    /// monotone axis motion (outside the circle just past an axis crossing or the start).
    ArcEndUnreachable { start: i64, end: i64 },
    /// Radius, registers or arc length do not fit the 32-bit DDA.
    ArcTooLarge,
}

impl ErrorKind {
    /// A short fixed summary (no values), e.g. for a small display.
    pub const fn message(&self) -> &'static str {
        match self {
            ErrorKind::UnexpectedCharacter(_) => "unexpected character",
            ErrorKind::UnclosedComment => "comment not closed",
            ErrorKind::UnsupportedLetter(_) => "unsupported word letter",
            ErrorKind::MissingNumber(_) => "letter without a number",
            ErrorKind::MalformedNumber(_) => "malformed number",
            ErrorKind::NumberTooLarge(_) => "number too large",
            ErrorKind::TooManyDecimals(_) => "too many decimal places",
            ErrorKind::UnsupportedG(_) => "unsupported G code",
            ErrorKind::UnsupportedM(_) => "unsupported M code",
            ErrorKind::RepeatedWord(_) => "word given twice",
            ErrorKind::ModalConflict { .. } => "two codes of one modal group",
            ErrorKind::NegativeValue(_) => "negative value",
            ErrorKind::NoFeed { .. } => "no feed rate",
            ErrorKind::DwellNeedsP => "G4 without P",
            ErrorKind::DwellWithAxes => "G4 with axis words",
            ErrorKind::UnusedWord(_) => "unused word",
            ErrorKind::StopWithMotion { .. } => "stop or tool change with motion",
            ErrorKind::NotInDialect(_) => "outside the dialect",
            ErrorKind::NotInteger(_) => "value not an integer",
            ErrorKind::AxisCommandConflict => "two commands use the axis words",
            ErrorKind::NoAxisWords { .. } => "no axis words",
            ErrorKind::MissingWord { .. } => "value word missing",
            ErrorKind::CoordinateSystem => "unsupported coordinate system",
            ErrorKind::G53Motion => "G53 needs G0 or G1",
            ErrorKind::AxisWordsUnused { .. } => "axis words not used",
            ErrorKind::ToolLengthAxis => "G43.1 takes only Z",
            ErrorKind::ToolNumber { .. } => "no such tool",
            ErrorKind::InverseTimeNeedsF => "G93 motion without F",
            ErrorKind::Cycle(_) => "canned cycle refused",
            ErrorKind::TargetOverflow { .. } => "overflow",
            ErrorKind::MoveTooLong => "move too long",
            ErrorKind::SoftLimit { .. } => "soft limit",
            ErrorKind::ArcNeedsCentre { .. } => "arc without centre or radius",
            ErrorKind::ArcRadiusAndOffsets => "arc with both R and I/J/K",
            ErrorKind::ArcTurns => "arc turns (P)",
            ErrorKind::ProbeTarget => "probe target",
            ErrorKind::ArcFullCircleRadius => "R-form full circle",
            ErrorKind::ArcZeroRadius => "arc radius zero",
            ErrorKind::ArcRadiusTooSmall { .. } => "arc radius too small",
            ErrorKind::ArcEndNotOnCircle { .. } => "arc end point not on circle",
            ErrorKind::ArcEndUnreachable { .. } => "arc end point unreachable",
            ErrorKind::ArcTooLarge => "arc too large",
        }
    }
}

impl fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ErrorKind::UnexpectedCharacter(c) => {
                write!(f, "unexpected character {c:?} (expected a word letter, a comment or a space)")
            }
            ErrorKind::UnclosedComment => f.write_str("comment opened with '(' is not closed with ')'"),
            ErrorKind::UnsupportedLetter(c) => write!(f, "{c} words are not supported"),
            ErrorKind::MissingNumber(c) => write!(f, "the letter {c} has no number"),
            ErrorKind::MalformedNumber(c) => write!(f, "the number after {c} is malformed"),
            ErrorKind::NumberTooLarge(c) => write!(f, "the number after {c} is too large"),
            ErrorKind::TooManyDecimals(c) => write!(
                f,
                "the number after {c} has more than {} decimal places",
                super::number::MAX_DECIMALS
            ),
            ErrorKind::UnsupportedG(d) => write!(f, "G{d} is not supported"),
            ErrorKind::UnsupportedM(d) => write!(f, "M{d} is not supported"),
            ErrorKind::RepeatedWord(c) => write!(f, "the word {c} is given twice"),
            ErrorKind::ModalConflict { letter, first, second } if first == second => {
                write_code(f, letter, first)?;
                f.write_str(" is given twice")
            }
            ErrorKind::ModalConflict { letter, first, second } => {
                let motion = |c: Code| c <= 30;
                if letter == 'G' && motion(first) && motion(second) {
                    f.write_str("two motion commands on one line (")?;
                } else {
                    f.write_str("codes of one modal group on one line (")?;
                }
                write_code(f, letter, first)?;
                f.write_str(" and ")?;
                write_code(f, letter, second)?;
                f.write_str(")")
            }
            ErrorKind::NotInDialect(c) => f.write_str(c.describe()),
            ErrorKind::NotInteger(c) => write!(f, "the number after {c} must be a whole number"),
            ErrorKind::AxisCommandConflict => f.write_str(
                "two commands on one line use the axis words (a motion with G10, G28, G30 or G92)",
            ),
            ErrorKind::NoAxisWords { code } => {
                write_code(f, 'G', code)?;
                f.write_str(" needs at least one axis word")
            }
            ErrorKind::MissingWord { code, letter } => {
                write_code(f, 'G', code)?;
                write!(f, " needs the word {letter}")
            }
            ErrorKind::CoordinateSystem => {
                f.write_str("the coordinate system must be P0 (the one in use) or P1-P6 (G54-G59)")
            }
            ErrorKind::G53Motion => {
                f.write_str("G53 moves only with G0 or G1")
            }
            ErrorKind::AxisWordsUnused { code } => {
                write_code(f, 'G', code)?;
                f.write_str(" takes no axis words")
            }
            ErrorKind::ToolLengthAxis => {
                f.write_str("G43.1 sets the tool length along Z: X and Y are not allowed")
            }
            ErrorKind::ToolNumber { value } => write!(
                f,
                "tool {value} is not in the tool table (T0 is no tool, T1-T{} are the table's)",
                super::tools::MAX_TOOLS
            ),
            ErrorKind::InverseTimeNeedsF => {
                f.write_str("in inverse time mode (G93) every G1, G2 and G3 needs its own F")
            }
            ErrorKind::Cycle(c) => f.write_str(c.describe()),
            ErrorKind::NegativeValue(c) => write!(f, "{c} must not be negative"),
            ErrorKind::NoFeed { code } => write!(f, "G{code} needs a feed rate (F) greater than zero"),
            ErrorKind::DwellNeedsP => f.write_str("G4 needs a dwell time P (seconds)"),
            ErrorKind::DwellWithAxes => f.write_str("G4 cannot be combined with an axis move"),
            ErrorKind::UnusedWord(c) => write!(
                f,
                "the word {c} is not used by this line (I/J/K/R only with G2/G3 in their plane, P only with G4)"
            ),
            ErrorKind::StopWithMotion { code } => {
                write_code(f, 'M', code)?;
                f.write_str(" must be on a line that neither moves nor dwells")
            }
            ErrorKind::TargetOverflow { axis } => {
                write!(f, "the target of axis {axis} overflows the 32-bit position (overflow)")
            }
            ErrorKind::MoveTooLong => f.write_str("the move is too long for the 32-bit interpolator (overflow)"),
            ErrorKind::SoftLimit { axis, value, min, max } => write!(
                f,
                "axis {axis} would go to {value} BLU, outside the soft limits {min}..={max} BLU"
            ),
            ErrorKind::ArcNeedsCentre { code } => {
                write!(f, "G{code} needs a centre (I, J, K) or a radius (R)")
            }
            ErrorKind::ArcRadiusAndOffsets => f.write_str("an arc takes either R or I/J/K, not both"),
            ErrorKind::ArcTurns => write!(
                f,
                "an arc's P (turns) must be a whole number from 1 to {}, and more than 1 turn needs I/J/K",
                crate::nc::MAX_TURNS
            ),
            ErrorKind::ProbeTarget => {
                f.write_str("a probing move (G38.x) must move at least one BLU")
            }
            ErrorKind::ArcFullCircleRadius => {
                f.write_str("an R-form arc cannot be a full circle (end point equals start point); use I/J/K")
            }
            ErrorKind::ArcZeroRadius => f.write_str("the arc radius is zero"),
            ErrorKind::ArcRadiusTooSmall { radius, half_chord } => write!(
                f,
                "arc radius {radius} BLU is smaller than half the distance to the end point ({half_chord} BLU)"
            ),
            ErrorKind::ArcEndNotOnCircle { start, end } => write!(
                f,
                "arc end point is not on the circle (start radius {start}, end radius {end}, in BLU)"
            ),
            ErrorKind::ArcEndUnreachable { start, end } => write!(
                f,
                "arc end point lies outside the circle just past an axis crossing and cannot be \
                 reached (start radius {start}, end radius {end}, in BLU)"
            ),
            ErrorKind::ArcTooLarge => f.write_str("the arc is too large for the 32-bit interpolator (overflow)"),
        }
    }
}
