//! Why a G-code line was rejected: [`ErrorKind`] with the offending values, formatted without
//! allocation. Built by the G-code parser (loader task), displayed by the host tool and the tests.

use super::number::Decimal;
use core::fmt;

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
    /// Two G or M codes of the same modal group on one line (e.g. two motion modes).
    ModalConflict { letter: char, first: u8, second: u8 },
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
    /// M2/M30 on a line that also moves or dwells.
    EndWithMotion,
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
    /// G2/G3 moving the axis normal to the plane.
    HelicalArc,
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
            ErrorKind::EndWithMotion => "M2/M30 with motion",
            ErrorKind::TargetOverflow { .. } => "overflow",
            ErrorKind::MoveTooLong => "move too long",
            ErrorKind::SoftLimit { .. } => "soft limit",
            ErrorKind::ArcNeedsCentre { .. } => "arc without centre or radius",
            ErrorKind::ArcRadiusAndOffsets => "arc with both R and I/J/K",
            ErrorKind::HelicalArc => "helical arcs are not supported",
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
                write!(f, "{letter}{first} is given twice")
            }
            ErrorKind::ModalConflict { letter, first, second } => {
                if letter == 'G' && first <= 3 && second <= 3 {
                    write!(f, "two motion commands on one line (G{first} and G{second})")
                } else {
                    write!(f, "{letter}{first} and {letter}{second} cannot be on one line (same modal group)")
                }
            }
            ErrorKind::NegativeValue(c) => write!(f, "{c} must not be negative"),
            ErrorKind::NoFeed { code } => write!(f, "G{code} needs a feed rate (F) greater than zero"),
            ErrorKind::DwellNeedsP => f.write_str("G4 needs a dwell time P (seconds)"),
            ErrorKind::DwellWithAxes => f.write_str("G4 cannot be combined with an axis move"),
            ErrorKind::UnusedWord(c) => write!(
                f,
                "the word {c} is not used by this line (I/J/K/R only with G2/G3 in their plane, P only with G4)"
            ),
            ErrorKind::EndWithMotion => f.write_str("M2/M30 must not be on a line that moves or dwells"),
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
            ErrorKind::HelicalArc => f.write_str("helical arcs are not supported"),
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
