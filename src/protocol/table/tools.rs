//! The tool table's `$T` commands (loader task, through the protocol's `$` hook; host tests): `$T`
//! lists every tool as the line that sets it, `$T<n>` lists tool n, `$T<n>=<words>` sets the
//! fields its words name and keeps the others.
//!
//! The words (any order, each at most once, spaces and comments ignored as in every `$` line):
//!
//! | word | field | values |
//! | --- | --- | --- |
//! | `L` | length offset (what G43 H applies), mm | signed |
//! | `D` | diameter, mm | >= 0 |
//! | `N` | flutes (cutting edges; 0: not known) | whole, 0..=[`MAX_FLUTES`] (32) |
//! | `K` | kind: 0 flat end mill, 1 ball end mill, 2 drill | whole |
//! | `F` | permissible cutting force, N (0: from its diameter and kind, `crate::ac::strength`) | >= 0 |
//! | `M` | permissible torque, N m (0: likewise; the AC holds it to `$255` at most) | >= 0 |
//!
//! Lengths are mm whatever `$13` says, as every `$` setting's; they are kept in picometres
//! exactly and listed exactly, and the limits are listed as the shortest decimal of their f32, so
//! a listed line set back gives the same tool. G10 L1 P<n> Z R sets the length and radius from a
//! program (in the program's units).
//!
//! Errors (grbl's numbers, as the `$N=value` table's): 2 a number that does not read, or a
//! fraction where a whole number is needed; 3 not one of the forms above, an unknown or repeated
//! word, or no word; 4 a negative value where none is allowed; 38 a tool number not 1..=16
//! (grblHAL's "illegal tool table entry", as T and G10 L1 give); 52 a value out of range; 7 the
//! record could not be stored. A refused line changes nothing.

use core::fmt::{self, Write};

use super::{Invalid, SetError};
use crate::gcode::number::{listable_f32, DecimalReader, NumError};
use crate::gcode::offsets::MAX_PM;
use crate::gcode::tools::MAX_FLUTES;
use crate::gcode::{Decimal, Tool, ToolKind, ToolTable};

/// Picometres per mm.
const PM_PER_MM: i128 = 1_000_000_000;

/// `$T...` with `cmd` what follows `$T` (compacted: upper case, no spaces or comments). A listing
/// is written to `out` and gives None; a set gives the tool's number and its new entry, for the
/// caller to validate and store.
pub fn command(
    tools: &ToolTable,
    cmd: &str,
    out: &mut dyn Write,
) -> Result<Option<(u32, Tool)>, SetError> {
    let (number, words) = match cmd.split_once('=') {
        Some((n, w)) => (n, Some(w)),
        None => (cmd, None),
    };
    if number.is_empty() && words.is_none() {
        for (n, t) in tools.iter() {
            let _ = write_tool(out, n, t);
        }
        return Ok(None);
    }
    if number.is_empty() || !number.bytes().all(|b| b.is_ascii_digit()) {
        return Err(SetError::Unsupported);
    }
    let n = number
        .parse::<u32>()
        .ok()
        .filter(|n| tools.get(*n).is_some())
        .ok_or(SetError::ToolNumber)?;
    let tool = tools.get(n).copied().unwrap_or_default();
    match words {
        None => {
            let _ = write_tool(out, n, &tool);
            Ok(None)
        }
        Some(w) => Ok(Some((n, edit(tool, w)?))),
    }
}

/// `tool` with the fields `words` name set.
fn edit(mut tool: Tool, words: &str) -> Result<Tool, SetError> {
    let range = SetError::Invalid(Invalid::Range);
    let mut seen = 0u32;
    let mut chars = words.chars().peekable();
    while let Some(letter) = chars.next() {
        let bit = match "LDNKFM".find(letter) {
            Some(i) => 1 << i,
            None => return Err(SetError::Unsupported),
        };
        if seen & bit != 0 {
            return Err(SetError::Unsupported);
        }
        seen |= bit;
        let mut r = DecimalReader::default();
        while let Some(&c) = chars.peek() {
            if !r.accepts(c) {
                break;
            }
            r.push(c).map_err(number_error)?;
            chars.next();
        }
        if !r.started() {
            return Err(SetError::BadNumber);
        }
        let v = r.finish().map_err(number_error)?;
        if v.is_negative() && letter != 'L' {
            return Err(SetError::Negative);
        }
        let whole = || -> Result<u8, SetError> {
            let i = v.as_integer().ok_or(SetError::BadNumber)?;
            u8::try_from(i).map_err(|_| range)
        };
        match letter {
            'L' => tool.length_pm = mm_to_pm(v)?,
            'D' => tool.diameter_pm = mm_to_pm(v)?,
            'N' => tool.flutes = Some(whole()?).filter(|f| *f <= MAX_FLUTES).ok_or(range)?,
            'K' => tool.kind = ToolKind::from_code(whole()?).ok_or(range)?,
            _ => {
                // F, M: the f32 nearest the decimal, listable exactly.
                let f = v.to_f32().filter(|f| listable_f32(*f)).ok_or(range)?;
                if letter == 'F' {
                    tool.force_limit_n = f;
                } else {
                    tool.torque_limit_nm = f;
                }
            }
        }
    }
    if seen == 0 {
        return Err(SetError::Unsupported);
    }
    Ok(tool)
}

fn number_error(e: NumError) -> SetError {
    match e {
        NumError::TooLarge => SetError::Invalid(Invalid::Range),
        NumError::Malformed | NumError::TooManyDecimals => SetError::BadNumber,
    }
}

/// mm to picometres, rounded half away from zero, within the offsets' range.
fn mm_to_pm(v: Decimal) -> Result<i64, SetError> {
    v.mul_ratio_round(PM_PER_MM, 1)
        .and_then(|pm| i64::try_from(pm).ok())
        .filter(|pm| pm.unsigned_abs() <= MAX_PM as u64)
        .ok_or(SetError::Invalid(Invalid::Range))
}

/// `$T<n>=L.. D.. N.. K.. F.. M.. (kind)` and the line end: the line that sets the tool as it is.
pub fn write_tool(out: &mut dyn Write, n: u32, t: &Tool) -> fmt::Result {
    write!(out, "$T{n}=L")?;
    write_mm(out, t.length_pm)?;
    out.write_str(" D")?;
    write_mm(out, t.diameter_pm)?;
    write!(
        out,
        " N{} K{} F{} M{} ({})\r\n",
        t.flutes,
        t.kind.code(),
        t.force_limit_n,
        t.torque_limit_nm,
        t.kind.name()
    )
}

/// Picometres as mm, exactly: the integer part, then the nine decimals without their trailing
/// zeros.
fn write_mm(out: &mut dyn Write, pm: i64) -> fmt::Result {
    let per_mm = PM_PER_MM as u64;
    let a = pm.unsigned_abs();
    let sign = if pm < 0 { "-" } else { "" };
    write!(out, "{sign}{}", a / per_mm)?;
    let (mut frac, mut digits) = (a % per_mm, 9usize);
    if frac == 0 {
        return Ok(());
    }
    while frac % 10 == 0 {
        frac /= 10;
        digits -= 1;
    }
    write!(out, ".{frac:0digits$}")
}

#[cfg(test)]
mod tests;
