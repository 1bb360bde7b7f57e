//! Splits one G-code line into words (loader task; host tests): whitespace and comments are
//! skipped anywhere (as grbl does), letters are case-insensitive, numbers are read exactly, G and
//! M codes are sorted into modal groups, repeated words and same-group codes are rejected.

use super::error::{Construct, ErrorKind};
use super::number::{Decimal, DecimalReader, NumError};

/// Value word letters, indices into [`Words::values`].
pub const LETTERS: [char; 16] = [
    'F', 'S', 'P', 'R', 'X', 'Y', 'Z', 'I', 'J', 'K', 'N', 'T', 'Q', 'L', 'H', 'D',
];
pub const F: usize = 0;
pub const S: usize = 1;
pub const P: usize = 2;
pub const R: usize = 3;
/// X, Y, Z are `AXES + axis`.
pub const AXES: usize = 4;
/// I, J, K are `OFFSETS + axis`.
pub const OFFSETS: usize = 7;
pub const N: usize = 10;
pub const T: usize = 11;
pub const Q: usize = 12;
pub const L: usize = 13;
pub const H: usize = 14;
pub const D: usize = 15;

pub use super::error::Code;

/// The tenths of a code: `G43.1` is `code(43, 1)`.
pub const fn code(whole: u16, tenth: u16) -> Code {
    whole * 10 + tenth
}

/// G modal groups (indices into [`Words::g`]), as RS274/NGC and grbl number them.
/// Group 0, non-modal: G4 G10 G28 G28.1 G30 G30.1 G53 G92 G92.1 G92.2 G92.3.
pub const G_NON_MODAL: usize = 0;
/// Motion: G0 G1 G2 G3, G80 (cancel) and the canned cycles G73 G81 G82 G83 G85 G89.
pub const G_MOTION: usize = 1;
pub const G_PLANE: usize = 2;
pub const G_DISTANCE: usize = 3;
/// G93 inverse time, G94 units per minute.
pub const G_FEED_MODE: usize = 4;
pub const G_UNITS: usize = 5;
/// Cutter radius compensation: G40 (off; G41/G42 are refused by the line's semantics).
pub const G_CUTTER: usize = 6;
/// Tool length offset: G43, G43.1, G49.
pub const G_TOOL_LENGTH: usize = 7;
/// Canned cycle return level: G98, G99.
pub const G_RETURN: usize = 8;
/// Work coordinate system: G54..G59.
pub const G_COORD: usize = 9;
/// Path control: G61, G61.1, G64.
pub const G_PATH: usize = 10;
/// Arc distance mode: G91.1 (I J K from the start, the only mode millac has: accepted, nothing
/// to do; grbl's, and what UGS sends when it restores the modal state). G90.1 is refused.
pub const G_ARC_DISTANCE: usize = 11;
const G_GROUPS: usize = 12;

/// M modal groups (indices into [`Words::m`]).
/// Stopping: M0 M1 M2 M30.
pub const M_STOP: usize = 0;
/// Tool change: M6.
pub const M_TOOL: usize = 1;
pub const M_SPINDLE: usize = 2;
/// M7 M8 M9 (one per line, as grbl).
pub const M_COOLANT: usize = 3;
const M_GROUPS: usize = 4;

/// The modal group of a G code (in tenths), or None when millac does not know it.
const fn g_group(c: Code) -> Option<usize> {
    Some(match c {
        40 | 100 | 280 | 281 | 300 | 301 | 530 | 920..=923 => G_NON_MODAL,
        0 | 10 | 20 | 30 | 382..=385 | 730 | 800 | 810 | 820 | 830 | 850 | 890 => G_MOTION,
        170 | 180 | 190 => G_PLANE,
        900 | 910 => G_DISTANCE,
        930 | 940 => G_FEED_MODE,
        200 | 210 => G_UNITS,
        400 | 410 | 420 => G_CUTTER,
        430 | 431 | 490 => G_TOOL_LENGTH,
        980 | 990 => G_RETURN,
        540 | 550 | 560 | 570 | 580 | 590 => G_COORD,
        610 | 611 | 640 => G_PATH,
        911 => G_ARC_DISTANCE,
        _ => return None,
    })
}

/// The modal group of an M code (in tenths), or None when millac does not know it.
const fn m_group(c: Code) -> Option<usize> {
    Some(match c {
        0 | 10 | 20 | 300 => M_STOP,
        60 => M_TOOL,
        30 | 40 | 50 => M_SPINDLE,
        70 | 80 | 90 => M_COOLANT,
        _ => return None,
    })
}

/// The words of one line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Words {
    /// The G code given per group, in tenths.
    pub g: [Option<Code>; G_GROUPS],
    /// The M code given per group, in tenths.
    pub m: [Option<Code>; M_GROUPS],
    /// Value words by [`LETTERS`] index.
    pub values: [Option<Decimal>; 16],
}

impl Words {
    pub fn value(&self, i: usize) -> Option<Decimal> {
        self.values.get(i).copied().flatten()
    }

    /// True when the line has an X, Y or Z word.
    pub fn has_axes(&self) -> bool {
        (0..3).any(|k| self.value(AXES + k).is_some())
    }

    fn add_code(&mut self, letter: char, d: Decimal) -> Result<(), ErrorKind> {
        let unsupported = if letter == 'G' {
            ErrorKind::UnsupportedG(d)
        } else {
            ErrorKind::UnsupportedM(d)
        };
        // The code in tenths, exactly (G43.1 = 431; G43.15 is no code). A parsed decimal has no
        // trailing fractional zeros, so a scale of 0 or 1 is all a code can have.
        let tenths = match d.scale {
            0 => d.mantissa.checked_mul(10),
            1 => Some(d.mantissa),
            _ => None,
        };
        let code = match tenths.map(Code::try_from) {
            Some(Ok(c)) => c,
            _ => return Err(unsupported),
        };
        let (slots, group): (&mut [Option<Code>], Option<usize>) = if letter == 'G' {
            (&mut self.g, g_group(code))
        } else {
            (&mut self.m, m_group(code))
        };
        let Some(group) = group else {
            return Err(match (letter, code) {
                ('G', 591..=593) => ErrorKind::NotInDialect(Construct::G59Extended),
                _ => unsupported,
            });
        };
        match slots.get_mut(group) {
            Some(Some(first)) => Err(ErrorKind::ModalConflict {
                letter,
                first: *first,
                second: code,
            }),
            Some(slot) => {
                *slot = Some(code);
                Ok(())
            }
            None => Err(unsupported),
        }
    }
}

/// Characters of a line with whitespace and comments removed.
struct Stream<'a> {
    chars: core::str::Chars<'a>,
    peeked: Option<Option<char>>,
}

impl<'a> Stream<'a> {
    fn raw_next(&mut self) -> Result<Option<char>, ErrorKind> {
        loop {
            match self.chars.next() {
                None => return Ok(None),
                Some(' ' | '\t' | '\r' | '\n') => {}
                Some('(') => loop {
                    match self.chars.next() {
                        None => return Err(ErrorKind::UnclosedComment),
                        Some(')') => break,
                        Some(_) => {}
                    }
                },
                Some(';') => {
                    self.chars = "".chars();
                    return Ok(None);
                }
                Some(c) => return Ok(Some(c)),
            }
        }
    }

    fn peek(&mut self) -> Result<Option<char>, ErrorKind> {
        match self.peeked {
            Some(c) => Ok(c),
            None => {
                let c = self.raw_next()?;
                self.peeked = Some(c);
                Ok(c)
            }
        }
    }

    fn next(&mut self) -> Result<Option<char>, ErrorKind> {
        let c = self.peek()?;
        self.peeked = None;
        Ok(c)
    }
}

fn number(s: &mut Stream<'_>, letter: char) -> Result<Decimal, ErrorKind> {
    let mut r = DecimalReader::default();
    while let Some(c) = s.peek()? {
        if !r.accepts(c) {
            break;
        }
        s.next()?;
        r.push(c).map_err(|e| num_error(e, letter))?;
    }
    if !r.started() {
        return match s.peek()? {
            None => Err(ErrorKind::MissingNumber(letter)),
            Some(c) if c.is_ascii_alphabetic() => Err(ErrorKind::MissingNumber(letter)),
            Some('#') => Err(ErrorKind::NotInDialect(Construct::Parameter)),
            Some('[') => Err(ErrorKind::NotInDialect(Construct::Expression)),
            Some(c) => Err(ErrorKind::UnexpectedCharacter(c)),
        };
    }
    r.finish().map_err(|e| num_error(e, letter))
}

fn num_error(e: NumError, letter: char) -> ErrorKind {
    match e {
        NumError::Malformed => ErrorKind::MalformedNumber(letter),
        NumError::TooLarge => ErrorKind::NumberTooLarge(letter),
        NumError::TooManyDecimals => ErrorKind::TooManyDecimals(letter),
    }
}

/// Reads all words of `text`.
pub fn lex(text: &str) -> Result<Words, ErrorKind> {
    let mut s = Stream {
        chars: text.chars(),
        peeked: None,
    };
    let mut w = Words::default();
    // `%` alone on a line (a comment may follow) is the tape's start or end delimiter.
    if s.peek()? == Some('%') {
        s.next()?;
        return match s.next()? {
            None => Ok(w),
            Some(c) => Err(ErrorKind::UnexpectedCharacter(c)),
        };
    }
    while let Some(c) = s.next()? {
        let construct = match c {
            '#' => Some(Construct::Parameter),
            '[' => Some(Construct::Expression),
            'o' | 'O' => Some(Construct::OWord),
            '@' | '^' => Some(Construct::Polar),
            _ => None,
        };
        if let Some(c) = construct {
            return Err(ErrorKind::NotInDialect(c));
        }
        if !c.is_ascii_alphabetic() {
            return Err(ErrorKind::UnexpectedCharacter(c));
        }
        let letter = c.to_ascii_uppercase();
        if letter == 'G' || letter == 'M' {
            let d = number(&mut s, letter)?;
            w.add_code(letter, d)?;
            continue;
        }
        let i = LETTERS
            .iter()
            .position(|&l| l == letter)
            .ok_or(ErrorKind::UnsupportedLetter(letter))?;
        let d = number(&mut s, letter)?;
        match w.values.get_mut(i) {
            Some(Some(_)) => return Err(ErrorKind::RepeatedWord(letter)),
            Some(slot) => *slot = Some(d),
            None => return Err(ErrorKind::UnsupportedLetter(letter)),
        }
    }
    Ok(w)
}
