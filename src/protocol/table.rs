//! grbl-1.1-style settings: the table behind `$$` (list) and `$N=value` (set one, validated) over
//! all of millac's settings ([`MachineSettings`]: NC, adaptive control, reports), the persistent
//! record ([`record`]) and the table with its storage ([`Persistent`], serial mode's `$` hook).
//! Called by the loader task (the line protocol), init (loading the record) and the host tests.
//! No floats in the conversions of integer settings: values are exact decimals ([`Decimal`])
//! converted by rational arithmetic; the f32 settings of the AC take the f32 nearest the decimal
//! (core's correctly rounded parser) and are listed as the shortest decimal that gives the same
//! f32 back, so `$$` output set back line by line gives the same settings.
//!
//! Errors are grbl's numbers: 2 bad number (also a fraction where a whole number is needed), 3
//! unknown or unsupported setting (or no `=`), 4 negative value for a setting without a sign, 52
//! (grblHAL's "value out of range") a value outside the setting's range or settings that then fail
//! validation, 7 the record could not be stored. A refused set changes nothing.

use core::fmt::{self, Write};

use crate::ac::settings::{AcSettings, AcSettingsError};
use crate::gcode::number::{listable_f32, parse_decimal, Decimal, NumError};
use crate::settings::{Blu, BoardLimits, Settings, SettingsError, Valid};

mod entries;
mod persistent;
pub mod record;
#[cfg(test)]
mod tests;
pub mod tools;

pub use entries::{entry, Entry, TABLE};
use entries::{Kind, Unit};
pub use persistent::Persistent;

/// Report settings (grbl's `$10`, `$13`), kept for the status reports of the protocol.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReportSettings {
    /// `$10`: bit 0 = machine position (MPos, else WPos), bit 1 = buffer state. 0..=3, default 1.
    pub status_mask: u8,
    /// `$13`: positions and rates reported in inches. Default false (mm, as grbl).
    pub inches: bool,
}

impl Default for ReportSettings {
    fn default() -> Self {
        ReportSettings {
            status_mask: 1,
            inches: false,
        }
    }
}

/// Adaptive-control strategy (`$251`): the AC's feed law, `AcSettings::strategy` (codes 0 the
/// paper's FRC, 1 integral, 2 MRAC).
pub use crate::ac::law::Strategy as AcStrategy;

/// Everything the settings table and the persistent record hold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachineSettings {
    pub nc: Settings,
    pub ac: AcSettings,
    /// `$250`: adaptive control on. Default true.
    pub ac_enabled: bool,
    pub report: ReportSettings,
    /// `$30`: the spindle speed (rpm) of full PWM duty on a board with a spindle output (grbl's
    /// max spindle speed; S above it runs at full duty). Default 1000, as grbl's.
    pub spindle_max_rpm: u32,
    /// Hard limits, homing, the probe and the tool change (`$6`, `$21`-`$27`, `$341`-`$346`).
    pub setup: crate::settings::Setup,
    /// The work offsets, G28/G30 positions and tool table the parser keeps (set by G10, G28.1,
    /// G30.1; stored when a line changes them, as grbl writes its EEPROM; `$RST=#` clears them).
    pub work: crate::gcode::Work,
}

impl Default for MachineSettings {
    fn default() -> Self {
        MachineSettings {
            nc: Settings::default(),
            ac: AcSettings::default(),
            ac_enabled: true,
            report: ReportSettings::default(),
            spindle_max_rpm: 1000,
            setup: crate::settings::Setup::default(),
            work: crate::gcode::Work::default(),
        }
    }
}

/// Why settings are invalid (grbl error 52).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Invalid {
    /// Outside the setting's own range: does not fit its type, not one of its choices, `$111`/
    /// `$112` different from `$110`, an f32 not 0 and not within 1e-6..=1e12 in magnitude.
    Range,
    /// [`Settings::validate`] refused.
    Nc(SettingsError),
    /// [`AcSettings::validate`] refused.
    Ac(AcSettingsError),
    /// `$263=2` (the plan) on a board whose frame does not apply the plan ratio
    /// (`BoardLimits::plan_ratio`).
    PlanNotOnThisBoard,
    /// A work offset or tool table value out of range (`Work::valid`).
    Work,
    /// [`crate::settings::Setup::validate`] refused.
    Setup(crate::settings::SetupError),
}

impl Invalid {
    pub const fn message(self) -> &'static str {
        match self {
            Invalid::Range => "value out of the setting's range",
            Invalid::Nc(e) => e.message(),
            Invalid::Ac(e) => e.message(),
            Invalid::PlanNotOnThisBoard => {
                "feed ceiling 2 (the plan) needs a frame that applies the plan ratio: not on this board"
            }
            Invalid::Work => "a work offset or tool table value is out of range",
            Invalid::Setup(e) => e.message(),
        }
    }
}

/// Why `$N=value` was refused; [`SetError::code`] is the grbl error number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SetError {
    /// 2: not a number, or a fraction for a setting that takes whole numbers.
    BadNumber,
    /// 3: not `$N=value`, or no setting N (also grbl's `$1`..`$6`, which millac does not have).
    Unsupported,
    /// 4: a negative value for a setting that has no sign.
    Negative,
    /// 52: out of range, or the settings with the new value fail validation.
    Invalid(Invalid),
    /// 7: the storage refused the record (see [`record::set_persistent`]).
    Storage,
    /// 38 (grblHAL's "illegal tool table entry"): `$T<n>` with n not a tool of the table.
    ToolNumber,
}

impl SetError {
    pub const fn code(self) -> u8 {
        match self {
            SetError::BadNumber => 2,
            SetError::Unsupported => 3,
            SetError::Negative => 4,
            SetError::Invalid(_) => 52,
            SetError::Storage => 7,
            SetError::ToolNumber => 38,
        }
    }

    pub const fn message(self) -> &'static str {
        match self {
            SetError::BadNumber => "bad number format",
            SetError::Unsupported => "unsupported setting or statement",
            SetError::Negative => "negative value",
            SetError::Invalid(i) => i.message(),
            SetError::Storage => "settings could not be stored",
            SetError::ToolNumber => "no such tool in the table",
        }
    }
}

/// `internal x num / den` as an exact decimal (den divides 10^6 in every unit).
fn exact(internal: i64, (num, den): (i128, i128)) -> Option<Decimal> {
    let n = (internal as i128).checked_mul(num)?;
    let mut p: i128 = 1;
    for scale in 0..=18u8 {
        let m = n.checked_mul(p)?;
        if m % den == 0 {
            return Some(Decimal {
                mantissa: m / den,
                scale,
            });
        }
        p = p.checked_mul(10)?;
    }
    None
}

/// A fixed buffer for one listed line (or a number), no allocation.
#[derive(Clone, Copy)]
pub struct LineBuf {
    bytes: [u8; 64],
    len: usize,
}

impl LineBuf {
    pub const fn new() -> Self {
        LineBuf {
            bytes: [0; 64],
            len: 0,
        }
    }

    pub fn as_str(&self) -> &str {
        // Only whole &str are ever written.
        core::str::from_utf8(self.bytes.get(..self.len).unwrap_or(&[])).unwrap_or("")
    }
}

impl Default for LineBuf {
    fn default() -> Self {
        LineBuf::new()
    }
}

impl Write for LineBuf {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let end = self.len.checked_add(s.len()).ok_or(fmt::Error)?;
        let dst = self.bytes.get_mut(self.len..end).ok_or(fmt::Error)?;
        dst.copy_from_slice(s.as_bytes());
        self.len = end;
        Ok(())
    }
}

/// Length settings in BLU converted to another BLU: `round(v x from / to)`, toward zero when
/// `inward` (soft limits stay inside the old ones).
fn rescale(v: i64, from: Blu, to: Blu, inward: bool) -> Option<i64> {
    let n = (v as i128).checked_mul(from.nm() as i128)?;
    let d = to.nm() as i128;
    let r = if inward {
        n / d
    } else {
        crate::gcode::number::div_round(n, d)?
    };
    i64::try_from(r).ok()
}

/// Reads `$N=value` (the `$` may be left out; spaces around the number and the value are
/// ignored).
pub fn parse_assignment(stmt: &str) -> Result<(u16, Decimal), SetError> {
    let stmt = stmt.trim();
    let stmt = stmt.strip_prefix('$').unwrap_or(stmt);
    let (n, v) = stmt.split_once('=').ok_or(SetError::Unsupported)?;
    let n = n.trim();
    if n.is_empty() || n.len() > 5 || !n.bytes().all(|b| b.is_ascii_digit()) {
        return Err(SetError::Unsupported);
    }
    let number: u16 = n.parse().map_err(|_| SetError::Unsupported)?;
    let value = parse_decimal(v.trim()).map_err(|e| match e {
        NumError::TooLarge => SetError::Invalid(Invalid::Range),
        NumError::Malformed | NumError::TooManyDecimals => SetError::BadNumber,
    })?;
    Ok((number, value))
}

impl MachineSettings {
    /// The validation the firmware runs at start-up and every set runs, for `board` (the QEMU
    /// board and the host tools pass [`BoardLimits::GENERIC`]): [`Settings::validate`] with the
    /// board's limits, [`AcSettings::validate`], the report mask, and every f32 of the table
    /// listable exactly.
    pub fn validate(&self, board: &BoardLimits) -> Result<(), Invalid> {
        self.nc.validate(board).map_err(Invalid::Nc)?;
        self.ac.validate().map_err(Invalid::Ac)?;
        if self.ac.ceiling == crate::ac::FeedCeiling::Plan && !board.plan_ratio {
            return Err(Invalid::PlanNotOnThisBoard);
        }
        if self.report.status_mask > 3 || !(1..=1_000_000).contains(&self.spindle_max_rpm) {
            return Err(Invalid::Range);
        }
        if !self.work.valid() {
            return Err(Invalid::Work);
        }
        self.setup.validate(&self.nc).map_err(Invalid::Setup)?;
        for e in TABLE.iter() {
            if let Kind::Real { get, .. } = e.kind {
                if !listable_f32(get(self)) {
                    return Err(Invalid::Range);
                }
            }
        }
        Ok(())
    }

    /// [`MachineSettings::validate`] for `board`, and the settings as a [`Valid`] when they pass:
    /// what the settings table holds ([`Persistent`]) and what the boards start from.
    pub fn validated(self, board: &BoardLimits) -> Result<Valid<MachineSettings>, Invalid> {
        self.validate(board)?;
        Ok(Valid::checked(self))
    }

    /// `$N=value`: sets one setting on a copy, validates the copy for `board`, and only then
    /// takes it. Lengths and rates round to the nearest BLU, ns or us; `$200` (BLU) converts the
    /// settings listed in mm so that they keep their mm values (soft limits rounded inward).
    pub fn set(
        &mut self,
        number: u16,
        value: Decimal,
        board: &BoardLimits,
    ) -> Result<(), SetError> {
        *self = self.with(number, value, board)?.get();
        Ok(())
    }

    /// A copy with `$N=value` set, validated for `board` (what [`MachineSettings::set`] takes).
    fn with(
        &self,
        number: u16,
        value: Decimal,
        board: &BoardLimits,
    ) -> Result<Valid<MachineSettings>, SetError> {
        let e = entry(number).ok_or(SetError::Unsupported)?;
        let mut new = *self;
        new.assign(e, value)?;
        new.validated(board).map_err(SetError::Invalid)
    }

    /// A `$T<n>=<words>` line as an operator types it (spaces, comments and case as the protocol
    /// takes them), into the tool table as the protocol's `$T` sets it: the host's tool files.
    /// Err: grbl's error number, as the protocol would answer the line.
    pub fn tool_line(&mut self, line: &str) -> Result<(), u8> {
        let cmd = super::compact(line);
        let cmd = cmd
            .strip_prefix("$T")
            .filter(|c| c.contains('='))
            .ok_or(super::GrblError::INVALID_STATEMENT.0)?;
        <Self as super::SettingsTable>::tool(self, cmd, &mut NoListing)
    }

    /// [`parse_assignment`] then [`MachineSettings::set`].
    pub fn set_line(&mut self, stmt: &str) -> Result<(), SetError> {
        let (n, v) = parse_assignment(stmt)?;
        self.set(n, v, &crate::settings::BoardLimits::GENERIC)
    }

    fn assign(&mut self, e: &Entry, value: Decimal) -> Result<(), SetError> {
        let range = SetError::Invalid(Invalid::Range);
        match e.kind {
            Kind::Int {
                set, unit, signed, ..
            } => {
                if value.is_negative() && !signed {
                    return Err(SetError::Negative);
                }
                if unit == Unit::One && value.as_integer().is_none() {
                    return Err(SetError::BadNumber);
                }
                let (num, den) = unit.ratio(self.nc.blu);
                let v = value.mul_ratio_round(den, num).ok_or(range)?;
                let v = i64::try_from(v).map_err(|_| range)?;
                set(self, v).ok_or(range)
            }
            Kind::Real { set, signed, .. } => {
                if value.is_negative() && !signed {
                    return Err(SetError::Negative);
                }
                // The f32 nearest the decimal (correctly rounded, `Decimal::to_f32`).
                let v = value.to_f32().filter(|v| listable_f32(*v)).ok_or(range)?;
                set(self, v).ok_or(range)
            }
            Kind::Blu => {
                if value.is_negative() {
                    return Err(SetError::Negative);
                }
                // value x 10^6 must be exactly a whole number of nm, 2540 or 1000.
                let nm = value.mul_ratio_round(1_000_000, 1).ok_or(range)?;
                let back =
                    crate::gcode::number::pow10(value.scale as u32).and_then(|p| nm.checked_mul(p));
                let exact = matches!(
                    (back, value.mantissa.checked_mul(1_000_000)),
                    (Some(a), Some(b)) if a == b
                );
                let to = match nm {
                    2540 if exact => Blu::TenthMil,
                    1000 if exact => Blu::Micron,
                    _ => return Err(range),
                };
                self.change_blu(to).ok_or(range)
            }
        }
    }

    /// Converts the settings kept in BLU to a new BLU, keeping their mm values.
    fn change_blu(&mut self, to: Blu) -> Option<()> {
        let from = self.nc.blu;
        if from == to {
            return Some(());
        }
        let nc = &mut self.nc;
        for k in 0..3 {
            nc.soft_min[k] = i32::try_from(rescale(nc.soft_min[k] as i64, from, to, true)?).ok()?;
            nc.soft_max[k] = i32::try_from(rescale(nc.soft_max[k] as i64, from, to, true)?).ok()?;
            let a = rescale(nc.accel_blu_s2[k] as i64, from, to, false)?;
            nc.accel_blu_s2[k] = u32::try_from(a).ok()?;
        }
        nc.rapid_hz = u32::try_from(rescale(nc.rapid_hz as i64, from, to, false)?).ok()?;
        nc.blu = to;
        Some(())
    }

    /// Writes the value of a table entry as listed (no `$N=`, no line end).
    pub fn write_value<W: Write>(&self, e: &Entry, w: &mut W) -> fmt::Result {
        match e.kind {
            Kind::Int { get, unit, .. } => {
                let d = exact(get(self), unit.ratio(self.nc.blu)).ok_or(fmt::Error)?;
                write!(w, "{d}")
            }
            Kind::Real { get, .. } => write!(w, "{}", get(self)),
            Kind::Blu => match self.nc.blu {
                Blu::TenthMil => w.write_str("0.00254"),
                Blu::Micron => w.write_str("0.001"),
            },
        }
    }

    /// Line `index` of `$$` (`$N=value`, no line end), or None past the end.
    pub fn line(&self, index: usize) -> Option<LineBuf> {
        let e = TABLE.get(index)?;
        let mut b = LineBuf::new();
        write!(b, "${}=", e.number).ok()?;
        self.write_value(e, &mut b).ok()?;
        Some(b)
    }

    /// The whole `$$` listing, every line ended by `\r\n` as grbl's.
    pub fn list<W: Write>(&self, w: &mut W) -> fmt::Result {
        for e in TABLE.iter() {
            write!(w, "${}=", e.number)?;
            self.write_value(e, w)?;
            w.write_str("\r\n")?;
        }
        Ok(())
    }
}

impl Valid<MachineSettings> {
    /// The NC settings, valid for the board the whole was validated for (no second check:
    /// [`MachineSettings::validate`] runs [`Settings::validate`]).
    pub fn nc(&self) -> Valid<Settings> {
        Valid::checked(self.nc)
    }

    /// The AC settings, valid (no second check: [`MachineSettings::validate`] runs
    /// [`AcSettings::validate`]).
    pub fn ac(&self) -> Valid<AcSettings> {
        Valid::checked(self.ac)
    }

    /// The settings with adaptive control on or off (`$250`), still valid: no check depends on it.
    pub fn with_ac_enabled(self, on: bool) -> Self {
        Valid::checked(MachineSettings {
            ac_enabled: on,
            ..self.get()
        })
    }

    /// `$N=value` on the valid settings: set on a copy, the copy validated for `board`, and only
    /// then taken (a refused value changes nothing).
    pub fn set(
        &mut self,
        number: u16,
        value: Decimal,
        board: &BoardLimits,
    ) -> Result<(), SetError> {
        *self = self.with(number, value, board)?;
        Ok(())
    }
}

/// The `$` commands of the line protocol reach this table (`$$`, `$N=value`, `$N`), and the
/// status report takes `$10` and `$13` from it.
impl super::SettingsTable for MachineSettings {
    fn list(&self, out: &mut dyn Write) -> fmt::Result {
        let mut w = DynWrite(out);
        MachineSettings::list(self, &mut w)
    }

    fn set(&mut self, n: u16, value: Decimal) -> Result<(), u8> {
        MachineSettings::set(self, n, value, &crate::settings::BoardLimits::GENERIC)
            .map_err(|e| e.code())
    }

    fn get(&self, n: u16, out: &mut dyn Write) -> Result<(), u8> {
        let e = entry(n).ok_or(super::GrblError::INVALID_STATEMENT.0)?;
        let mut w = DynWrite(out);
        let r = write!(w, "${}=", e.number)
            .and_then(|_| self.write_value(e, &mut w))
            .and_then(|_| w.write_str("\r\n"));
        r.map_err(|_| super::GrblError::INVALID_STATEMENT.0)
    }

    /// `$T`: listed, or set in the table (validated; no storage here).
    fn tool(&mut self, cmd: &str, out: &mut dyn Write) -> Result<(), u8> {
        if let Some((n, t)) = tools::command(&self.work.tools, cmd, out).map_err(|e| e.code())? {
            let mut new = *self;
            new.work.tools.set(n, t);
            new.validate(&crate::settings::BoardLimits::GENERIC)
                .map_err(|e| SetError::Invalid(e).code())?;
            *self = new;
        }
        Ok(())
    }

    fn report_options(&self) -> super::report::ReportOptions {
        super::report::ReportOptions {
            status_mask: self.report.status_mask,
            inches: self.report.inches,
        }
    }
}

/// Nowhere to list to ([`MachineSettings::tool_line`] sets, never lists).
struct NoListing;

impl Write for NoListing {
    fn write_str(&mut self, _: &str) -> fmt::Result {
        Ok(())
    }
}

/// A `&mut dyn Write` as a sized `Write` (the table's writers are generic).
struct DynWrite<'a>(&'a mut dyn Write);

impl Write for DynWrite<'_> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        self.0.write_str(s)
    }
}

#[cfg(test)]
mod hook_tests {
    extern crate std;
    use super::super::SettingsTable;
    use super::*;
    use crate::gcode::number::parse_decimal;
    use std::string::String;

    /// The protocol's `$` hook on the real table: `$$` is the table's listing, `$N=value` is
    /// validated (a refused value changes nothing and gives its grbl error), `$N` lists one line,
    /// `$10`/`$13` reach the status report options.
    #[test]
    fn the_protocol_hook_is_the_table() {
        let mut m = MachineSettings::default();
        let (mut via_hook, mut direct) = (String::new(), String::new());
        SettingsTable::list(&m, &mut via_hook).unwrap();
        MachineSettings::list(&m, &mut direct).unwrap();
        assert_eq!(via_hook, direct);
        assert!(via_hook.contains("$0=5\r\n"), "{via_hook}");
        let before = m;
        assert_eq!(
            SettingsTable::set(&mut m, 201, parse_decimal("50").unwrap()),
            Err(52)
        );
        assert_eq!(m, before);
        assert_eq!(
            SettingsTable::set(&mut m, 999, parse_decimal("1").unwrap()),
            Err(3)
        );
        SettingsTable::set(&mut m, 13, parse_decimal("1").unwrap()).unwrap();
        SettingsTable::set(&mut m, 10, parse_decimal("3").unwrap()).unwrap();
        let o = m.report_options();
        assert!(o.inches && o.status_mask == 3);
        let mut one = String::new();
        SettingsTable::get(&m, 13, &mut one).unwrap();
        assert_eq!(one, "$13=1\r\n");
        assert_eq!(SettingsTable::get(&m, 999, &mut one), Err(3));
    }
}
