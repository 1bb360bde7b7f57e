//! Splits one G-code line into words (loader task; host tests): whitespace and comments are
//! skipped anywhere (as grbl does), letters are case-insensitive, numbers are read exactly, G and
//! M codes are sorted into modal groups, repeated words and same-group codes are rejected.

use super::error::ErrorKind;
use super::number::{Decimal, DecimalReader, NumError};

/// Value word letters, indices into [`Words::values`].
pub const LETTERS: [char; 11] = ['F', 'S', 'P', 'R', 'X', 'Y', 'Z', 'I', 'J', 'K', 'N'];
pub const F: usize = 0;
pub const S: usize = 1;
pub const P: usize = 2;
pub const R: usize = 3;
/// X, Y, Z are `AXES + axis`.
pub const AXES: usize = 4;
/// I, J, K are `OFFSETS + axis`.
pub const OFFSETS: usize = 7;

/// G modal groups (indices into [`Words::g`]).
pub const G_MOTION: usize = 0;
pub const G_DWELL: usize = 1;
pub const G_PLANE: usize = 2;
pub const G_UNITS: usize = 3;
pub const G_DISTANCE: usize = 4;
pub const G_FEED_MODE: usize = 5;
/// M modal groups (indices into [`Words::m`]).
pub const M_STOP: usize = 0;
pub const M_SPINDLE: usize = 1;
pub const M_COOLANT: usize = 2;

/// The words of one line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Words {
    /// The G code given per group.
    pub g: [Option<u8>; 6],
    /// The M code given per group.
    pub m: [Option<u8>; 3],
    /// Value words by [`LETTERS`] index.
    pub values: [Option<Decimal>; 11],
}

impl Words {
    pub fn value(&self, i: usize) -> Option<Decimal> {
        self.values.get(i).copied().flatten()
    }

    fn add_code(&mut self, letter: char, d: Decimal) -> Result<(), ErrorKind> {
        let unsupported = if letter == 'G' {
            ErrorKind::UnsupportedG(d)
        } else {
            ErrorKind::UnsupportedM(d)
        };
        let code = match d.as_integer().map(u8::try_from) {
            Some(Ok(c)) => c,
            _ => return Err(unsupported),
        };
        let (slots, group): (&mut [Option<u8>], usize) = if letter == 'G' {
            let group = match code {
                0..=3 => G_MOTION,
                4 => G_DWELL,
                17..=19 => G_PLANE,
                20 | 21 => G_UNITS,
                90 | 91 => G_DISTANCE,
                94 => G_FEED_MODE,
                _ => return Err(unsupported),
            };
            (&mut self.g, group)
        } else {
            let group = match code {
                2 | 30 => M_STOP,
                3..=5 => M_SPINDLE,
                8 | 9 => M_COOLANT,
                _ => return Err(unsupported),
            };
            (&mut self.m, group)
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
    while let Some(c) = s.next()? {
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
