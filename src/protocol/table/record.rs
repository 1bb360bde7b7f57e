//! The persistent settings record: [`MachineSettings`] as a versioned byte image with a CRC-32,
//! written and read through the [`SettingsStorage`] port. Init calls [`load`] once; the loader task
//! calls [`store`] (through [`set_persistent`] for `$N=value`); host tests.
//!
//! Layout (little-endian), [`RECORD_LEN`] bytes:
//!
//! | offset | bytes | content |
//! | --- | --- | --- |
//! | 0 | 4 | magic `MLST` |
//! | 4 | 2 | version ([`VERSION`]) |
//! | 6 | 2 | payload length ([`PAYLOAD_LEN`]) |
//! | 8 | [`PAYLOAD_LEN`] | the settings, field by field in declaration order: integers as themselves, f32 as their bits, enums and bools as one byte; the set-up ([`Setup`]); then the work offsets (G54..G59, G28, G30: i64 picometres) and the tool table (per tool: length and diameter i64 picometres, flutes, kind, force and torque limits f32) |
//! | 8 + len | 4 | CRC-32 (IEEE 802.3, reflected 0xEDB88320, as zlib's) of everything before it |
//!
//! Any change of the payload bumps [`VERSION`] (6: the work offsets and tool table added; 7: the
//! set-up, homing, probe and tool change, after the AC's settings; 8: chatter detection's switch,
//! `$278`); a record
//! of another version loads as defaults with [`RecordError::Version`] (no migration yet). The CRC is computed bit by bit ([`crc32`]): the
//! record is about 200 bytes and checked once at start-up and once per store, so a table (1 KiB of
//! flash, or 16 KiB for the sliced tables of crc32fast) buys nothing, and 10 lines need no new
//! dependency. CRC-32 detects every error burst up to 32 bits, so every single-bit flip; the exact
//! length check detects every truncation.

use super::{AcStrategy, Invalid, MachineSettings, ReportSettings, SetError};
use crate::ac::settings::{AcSettings, Calibration, FeedCeiling, Pick};
use crate::gcode::number::Decimal;
use crate::gcode::{Tool, ToolKind, Work};
use crate::ports::SettingsStorage;
use crate::settings::{Blu, BoardLimits, Settings, Setup, Valid};

pub const MAGIC: [u8; 4] = *b"MLST";
pub const VERSION: u16 = 8;
pub const HEADER_LEN: usize = 8;
/// 208 bytes of settings and 41 of the set-up (`$6`, `$21`-`$27`, `$341`-`$346`), then the work
/// offsets (24 x i64) and the tool table (16 x 26 bytes).
pub const PAYLOAD_LEN: usize = 209 + 41 + 24 * 8 + 16 * 26;
pub const RECORD_LEN: usize = HEADER_LEN + PAYLOAD_LEN + 4;

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320, initial and final XOR 0xFFFFFFFF): the
/// check value of `b"123456789"` is 0xCBF43926.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = (c >> 1) ^ (0xEDB8_8320 & (c & 1).wrapping_neg());
        }
    }
    !c
}

/// Why a stored record was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordError {
    /// Shorter than its header says (a half-written record), or empty.
    Truncated,
    /// Longer than its header says.
    Length,
    /// Not a settings record.
    Magic,
    /// The CRC does not match.
    Checksum,
    /// A record of another version.
    Version(u16),
    /// An enum or bool byte with no meaning.
    Value,
    /// The settings fail validation.
    Invalid(Invalid),
}

impl RecordError {
    pub const fn message(self) -> &'static str {
        match self {
            RecordError::Truncated => "settings record truncated",
            RecordError::Length => "settings record has the wrong length",
            RecordError::Magic => "no settings record",
            RecordError::Checksum => "settings record checksum mismatch",
            RecordError::Version(_) => "settings record of another version",
            RecordError::Value => "settings record has an unknown value",
            RecordError::Invalid(_) => "stored settings fail validation",
        }
    }
}

/// What [`load`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoadStatus {
    /// A valid record: its settings.
    Loaded,
    /// Nothing stored (or erased storage, all 0xFF): defaults, no alarm.
    Missing,
    /// A record that was refused: defaults, and the caller reports the alarm.
    Refused(RecordError),
}

impl LoadStatus {
    /// Whether the caller must report an alarm (the defaults replace a refused record).
    pub const fn alarm(self) -> bool {
        matches!(self, LoadStatus::Refused(_))
    }
}

/// The settings [`load`] gives, and how it got them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Loaded {
    pub settings: Valid<MachineSettings>,
    pub status: LoadStatus,
}

struct Put<'a> {
    buf: &'a mut [u8],
    pos: usize,
}

impl Put<'_> {
    fn bytes<const N: usize>(&mut self, b: [u8; N]) {
        for (k, v) in b.into_iter().enumerate() {
            if let Some(d) = self.buf.get_mut(self.pos + k) {
                *d = v;
            }
        }
        self.pos += N;
    }
    fn u8(&mut self, v: u8) {
        self.bytes([v]);
    }
    fn u16(&mut self, v: u16) {
        self.bytes(v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.bytes(v.to_le_bytes());
    }
    fn i32(&mut self, v: i32) {
        self.bytes(v.to_le_bytes());
    }
    fn i64(&mut self, v: i64) {
        self.bytes(v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.u32(v.to_bits());
    }
}

struct Take<'a> {
    b: &'a [u8],
    pos: usize,
}

impl Take<'_> {
    fn bytes<const N: usize>(&mut self) -> Option<[u8; N]> {
        let s = self.b.get(self.pos..self.pos.checked_add(N)?)?;
        let mut a = [0u8; N];
        for (d, v) in a.iter_mut().zip(s) {
            *d = *v;
        }
        self.pos += N;
        Some(a)
    }
    fn u8(&mut self) -> Option<u8> {
        Some(self.bytes::<1>()?[0])
    }
    fn u16(&mut self) -> Option<u16> {
        Some(u16::from_le_bytes(self.bytes()?))
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.bytes()?))
    }
    fn i32(&mut self) -> Option<i32> {
        Some(i32::from_le_bytes(self.bytes()?))
    }
    fn i64(&mut self) -> Option<i64> {
        Some(i64::from_le_bytes(self.bytes()?))
    }
    fn f32(&mut self) -> Option<f32> {
        Some(f32::from_bits(self.u32()?))
    }
    fn bool(&mut self) -> Option<Option<bool>> {
        Some(match self.u8()? {
            0 => Some(false),
            1 => Some(true),
            _ => None,
        })
    }
}

/// The record image of `s` (not validated here: [`store`] validates).
pub fn encode(s: &MachineSettings) -> [u8; RECORD_LEN] {
    let mut img = [0u8; RECORD_LEN];
    let mut p = Put {
        buf: &mut img,
        pos: 0,
    };
    p.bytes(MAGIC);
    p.u16(VERSION);
    p.u16(PAYLOAD_LEN as u16);
    let n = &s.nc;
    p.u8(match n.blu {
        Blu::TenthMil => 0,
        Blu::Micron => 1,
    });
    for v in [n.frame_hz, n.q0, n.rapid_hz] {
        p.u32(v);
    }
    n.ptp_steps.into_iter().for_each(|v| p.u32(v));
    for v in [n.decel_tau_us, n.pulse_width_ns, n.sign_setup_ns] {
        p.u32(v);
    }
    n.soft_min.into_iter().for_each(|v| p.i32(v));
    n.soft_max.into_iter().for_each(|v| p.i32(v));
    n.accel_blu_s2.into_iter().for_each(|v| p.u32(v));
    p.u8(s.ac_enabled as u8);
    let a = &s.ac;
    p.u8(match a.strategy {
        AcStrategy::Paper => 0,
        AcStrategy::Integral => 1,
        AcStrategy::Mrac => 2,
        AcStrategy::Gpc => 3,
    });
    p.u32(a.sample_hz);
    p.u32(a.period_ms);
    for c in a.cal {
        p.f32(c.gain);
        p.f32(c.offset);
    }
    p.u8(match a.pick {
        Pick::Peak => 0,
        Pick::Latest => 1,
    });
    for v in [a.force_limit_n, a.torque_limit_nm, a.optimal_fraction] {
        p.f32(v);
    }
    for v in [a.fdot_m, a.f_min, a.f_max] {
        p.u32(v);
    }
    p.f32(a.overload_e);
    p.u32(a.stuck_samples);
    p.u16(a.jump_codes);
    p.u16(a.frozen_codes);
    p.u32(a.frozen_samples);
    for v in [
        a.tool_radius_mm,
        a.ft_ratio_min,
        a.ft_ratio_max,
        a.ft_floor_nm,
    ] {
        p.f32(v);
    }
    p.u32(a.ft_periods);
    p.u32(a.peak_windows);
    p.u8(match a.ceiling {
        FeedCeiling::Programmed => 0,
        FeedCeiling::Frm => 1,
        FeedCeiling::Plan => 2,
    });
    p.u8(s.report.status_mask);
    p.u8(s.report.inches as u8);
    p.u32(s.spindle_max_rpm);
    p.u32(s.ac.nominal_feed);
    p.f32(s.ac.gpc_lambda);
    p.u32(s.ac.flutes);
    p.u32(s.ac.monitor_rpm);
    p.f32(s.ac.chatter_threshold);
    p.u8(s.ac.breakage.code());
    p.f32(s.ac.chatter_step_mm);
    p.u32(s.ac.chatter_max_rpm);
    p.u8(s.ac.chatter as u8);
    let u = &s.setup;
    for b in [u.probe_invert, u.hard_limits, u.homing] {
        p.u8(b as u8);
    }
    p.u8(u.homing_dir_mask);
    for v in [
        u.homing_feed_um_min,
        u.homing_seek_um_min,
        u.homing_debounce_ms,
        u.homing_pulloff_um,
    ] {
        p.u32(v);
    }
    p.u8(u.tool_change);
    for v in [
        u.probe_distance_um,
        u.probe_slow_um_min,
        u.probe_seek_um_min,
    ] {
        p.u32(v);
    }
    u.setter_um.into_iter().for_each(|v| p.i32(v));
    let w = &s.work;
    for v in w.systems.iter().chain([&w.g28, &w.g30]).flatten() {
        p.i64(*v);
    }
    for (_, t) in w.tools.iter() {
        p.i64(t.length_pm);
        p.i64(t.diameter_pm);
        p.u8(t.flutes);
        p.u8(t.kind.code());
        p.f32(t.force_limit_n);
        p.f32(t.torque_limit_nm);
    }
    let end = p.pos;
    let crc = crc32(img.get(..end).unwrap_or(&[]));
    let mut p = Put {
        buf: &mut img,
        pos: end,
    };
    p.u32(crc);
    img
}

/// The settings of a record image, checked (length, magic, CRC, version, values, validation for
/// `board`): valid settings, checked here once.
pub fn decode(bytes: &[u8], board: &BoardLimits) -> Result<Valid<MachineSettings>, RecordError> {
    let mut t = Take { b: bytes, pos: 0 };
    let magic: [u8; 4] = t.bytes().ok_or(RecordError::Truncated)?;
    let version = t.u16().ok_or(RecordError::Truncated)?;
    let len = t.u16().ok_or(RecordError::Truncated)? as usize;
    if magic != MAGIC {
        return Err(RecordError::Magic);
    }
    let body = HEADER_LEN + len;
    if bytes.len() < body + 4 {
        return Err(RecordError::Truncated);
    }
    if bytes.len() > body + 4 {
        return Err(RecordError::Length);
    }
    let mut c = Take {
        b: bytes,
        pos: body,
    };
    let crc = c.u32().ok_or(RecordError::Truncated)?;
    if crc != crc32(bytes.get(..body).unwrap_or(&[])) {
        return Err(RecordError::Checksum);
    }
    if version != VERSION {
        return Err(RecordError::Version(version));
    }
    if len != PAYLOAD_LEN {
        return Err(RecordError::Length);
    }
    let s = payload(&mut t).ok_or(RecordError::Truncated)?;
    let s = s.ok_or(RecordError::Value)?;
    s.validated(board).map_err(RecordError::Invalid)
}

/// The payload's fields: None when short, Some(None) for a byte with no meaning.
fn payload(t: &mut Take) -> Option<Option<MachineSettings>> {
    let blu = match t.u8()? {
        0 => Some(Blu::TenthMil),
        1 => Some(Blu::Micron),
        _ => None,
    };
    let (frame_hz, q0, rapid_hz) = (t.u32()?, t.u32()?, t.u32()?);
    let ptp_steps = [t.u32()?, t.u32()?, t.u32()?];
    let (decel_tau_us, pulse_width_ns, sign_setup_ns) = (t.u32()?, t.u32()?, t.u32()?);
    let soft_min = [t.i32()?, t.i32()?, t.i32()?];
    let soft_max = [t.i32()?, t.i32()?, t.i32()?];
    let accel_blu_s2 = [t.u32()?, t.u32()?, t.u32()?];
    let ac_enabled = t.bool()?;
    let strategy = match t.u8()? {
        0 => Some(AcStrategy::Paper),
        1 => Some(AcStrategy::Integral),
        2 => Some(AcStrategy::Mrac),
        3 => Some(AcStrategy::Gpc),
        _ => None,
    };
    let (sample_hz, period_ms) = (t.u32()?, t.u32()?);
    let mut cal = [Calibration {
        gain: 0.0,
        offset: 0.0,
    }; 3];
    for c in cal.iter_mut() {
        c.gain = t.f32()?;
        c.offset = t.f32()?;
    }
    let pick = match t.u8()? {
        0 => Some(Pick::Peak),
        1 => Some(Pick::Latest),
        _ => None,
    };
    let (force_limit_n, torque_limit_nm, optimal_fraction) = (t.f32()?, t.f32()?, t.f32()?);
    let (fdot_m, f_min, f_max) = (t.u32()?, t.u32()?, t.u32()?);
    let overload_e = t.f32()?;
    let stuck_samples = t.u32()?;
    let (jump_codes, frozen_codes) = (t.u16()?, t.u16()?);
    let frozen_samples = t.u32()?;
    let (tool_radius_mm, ft_ratio_min) = (t.f32()?, t.f32()?);
    let (ft_ratio_max, ft_floor_nm) = (t.f32()?, t.f32()?);
    let (ft_periods, peak_windows) = (t.u32()?, t.u32()?);
    let ceiling = match t.u8()? {
        0 => Some(FeedCeiling::Programmed),
        1 => Some(FeedCeiling::Frm),
        2 => Some(FeedCeiling::Plan),
        _ => None,
    };
    let status_mask = t.u8()?;
    let inches = t.bool()?;
    let spindle_max_rpm = t.u32()?;
    let nominal_feed = t.u32()?;
    let gpc_lambda = t.f32()?;
    let (flutes, monitor_rpm) = (t.u32()?, t.u32()?);
    let chatter_threshold = t.f32()?;
    let breakage = crate::ac::Breakage::from_code(t.u8()?);
    let chatter_step_mm = t.f32()?;
    let chatter_max_rpm = t.u32()?;
    let chatter = t.bool()?;
    let (probe_invert, hard_limits, homing) = (t.bool()?, t.bool()?, t.bool()?);
    let homing_dir_mask = t.u8()?;
    let (homing_feed_um_min, homing_seek_um_min) = (t.u32()?, t.u32()?);
    let (homing_debounce_ms, homing_pulloff_um) = (t.u32()?, t.u32()?);
    let tool_change = t.u8()?;
    let (probe_distance_um, probe_slow_um_min, probe_seek_um_min) = (t.u32()?, t.u32()?, t.u32()?);
    let setter_um = [t.i32()?, t.i32()?];
    let mut work = Work::default();
    for v in work
        .systems
        .iter_mut()
        .chain([&mut work.g28, &mut work.g30])
        .flatten()
    {
        *v = t.i64()?;
    }
    let mut kinds_known = true;
    for n in 1..=crate::gcode::tools::MAX_TOOLS as u32 {
        let (length_pm, diameter_pm, flutes) = (t.i64()?, t.i64()?, t.u8()?);
        let kind = ToolKind::from_code(t.u8()?).unwrap_or_else(|| {
            kinds_known = false;
            ToolKind::Flat
        });
        let (force_limit_n, torque_limit_nm) = (t.f32()?, t.f32()?);
        work.tools.set(
            n,
            Tool {
                length_pm,
                diameter_pm,
                flutes,
                kind,
                force_limit_n,
                torque_limit_nm,
            },
        );
    }
    let build = || {
        if !kinds_known {
            return None;
        }
        Some(MachineSettings {
            nc: Settings {
                blu: blu?,
                frame_hz,
                q0,
                rapid_hz,
                ptp_steps,
                decel_tau_us,
                pulse_width_ns,
                sign_setup_ns,
                soft_min,
                soft_max,
                accel_blu_s2,
            },
            ac: AcSettings {
                sample_hz,
                period_ms,
                cal,
                pick: pick?,
                force_limit_n,
                torque_limit_nm,
                optimal_fraction,
                fdot_m,
                f_min,
                f_max,
                overload_e,
                stuck_samples,
                jump_codes,
                frozen_codes,
                frozen_samples,
                tool_radius_mm,
                ft_ratio_min,
                ft_ratio_max,
                ft_floor_nm,
                ft_periods,
                peak_windows,
                ceiling: ceiling?,
                strategy: strategy?,
                nominal_feed,
                gpc_lambda,
                flutes,
                monitor_rpm,
                chatter_threshold,
                breakage: breakage?,
                chatter_step_mm,
                chatter_max_rpm,
                chatter: chatter?,
            },
            ac_enabled: ac_enabled?,
            report: ReportSettings {
                status_mask,
                inches: inches?,
            },
            spindle_max_rpm,
            setup: Setup {
                probe_invert: probe_invert?,
                hard_limits: hard_limits?,
                homing: homing?,
                homing_dir_mask,
                homing_feed_um_min,
                homing_seek_um_min,
                homing_debounce_ms,
                homing_pulloff_um,
                tool_change,
                probe_distance_um,
                probe_slow_um_min,
                probe_seek_um_min,
                setter_um,
            },
            work,
        })
    };
    Some(build())
}

/// Reads the record at start-up: a valid record gives its settings (validated again, for
/// `board`: a record another board accepted but this one cannot run is refused); nothing stored
/// or erased storage gives the defaults; anything else (truncated, corrupt, another version,
/// invalid values) gives the defaults and [`LoadStatus::Refused`], which the caller reports as
/// an alarm. Never writes: the next store replaces a refused record. The defaults are validated
/// for `board` too: the error when the board cannot run them (the settings are checked once, here
/// or in [`decode`]).
pub fn load<S: SettingsStorage>(storage: &mut S, board: &BoardLimits) -> Result<Loaded, Invalid> {
    let mut buf = [0u8; RECORD_LEN + 64];
    let status = match storage.load(&mut buf) {
        None => LoadStatus::Missing,
        Some(n) => match buf.get(..n) {
            None => LoadStatus::Refused(RecordError::Length),
            Some(img) if !img.is_empty() && img.iter().all(|&b| b == 0xFF) => LoadStatus::Missing,
            Some(img) => match decode(img, board) {
                Ok(settings) => {
                    return Ok(Loaded {
                        settings,
                        status: LoadStatus::Loaded,
                    })
                }
                Err(e) => LoadStatus::Refused(e),
            },
        },
    };
    Ok(Loaded {
        settings: MachineSettings::default().validated(board)?,
        status,
    })
}

/// Stores valid settings (validated by whoever made the [`Valid`], for the board they are for):
/// [`SetError::Storage`] when the storage refused.
pub fn store<S: SettingsStorage>(
    storage: &mut S,
    s: &Valid<MachineSettings>,
) -> Result<(), SetError> {
    if storage.store(&encode(s)) {
        Ok(())
    } else {
        Err(SetError::Storage)
    }
}

/// `$N=value` made persistent, validated for `board`: set on a copy, store the copy, and only
/// then take it, so a refused value or a refused store (grbl error 7) changes neither the
/// settings nor the record.
pub fn set_persistent<S: SettingsStorage>(
    settings: &mut Valid<MachineSettings>,
    storage: &mut S,
    number: u16,
    value: Decimal,
    board: &BoardLimits,
) -> Result<(), SetError> {
    let mut new = *settings;
    new.set(number, value, board)?;
    store(storage, &new)?;
    *settings = new;
    Ok(())
}
