//! grbl 1.1 push messages formatted without floats or allocation (loader task, host tests): the
//! banner, the status report `<...>` with millac's `AC:` and `FC:` fields, `$G`, `$#`, `$I` (with
//! millac's `[FRAME:...]` line), `ALARM:N`, `[MSG:...]`.
//!
//! millac's additions are safe for grbl senders: grbl 1.1's interface document tells them to
//! ignore status report fields and `[...]` push messages they do not know (UGS, CNCjs, bCNC and
//! Candle do), so `AC:`, `FC:` and `[FRAME:...]` only inform the operators who look for them.
//!
//! Numbers: positions and rates are integers (BLU, BLU per minute) converted once by exact
//! rational arithmetic and rounded half away from zero to grbl's decimals: positions 3 decimals
//! in mm, 4 in inches; feed rates 0 decimals in mm/min, 1 in in/min; rpm 0 decimals. So 12345 BLU
//! of 0.0001 in report as `31.356` mm (31.3563) or `1.2345` in. A value that rounds to zero
//! prints without a sign (`0.000`, where grbl's printFloat could print `-0.000`).

use super::rx::Overrides;
use crate::gcode::number::div_round;
use crate::gcode::{Distance, FeedMode, Modes, PathMode, Retract, Spindle, ToolLength, Units};
use crate::nc::Plane;
use crate::settings::{Blu, Settings};
use core::fmt::{self, Write};

/// The grbl version millac speaks.
pub const GRBL_VERSION: &str = "1.1h";
/// millac's version, from Cargo.
pub const MILLAC_VERSION: &str = env!("CARGO_PKG_VERSION");

/// `$10` status report mask and `$13` report inches, as the settings table holds them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReportOptions {
    /// `$10`: bit 0 set = `MPos`, clear = `WPos`; bit 1 set = `Bf:` buffer field.
    pub status_mask: u8,
    /// `$13`: report positions and rates in inches.
    pub inches: bool,
}

impl ReportOptions {
    /// grbl's defaults: `$10=1` (MPos, no buffer field), `$13=0` (mm).
    pub const DEFAULT: ReportOptions = ReportOptions {
        status_mask: 1,
        inches: false,
    };
}

/// Machine state as the status report names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    Idle,
    Run,
    /// Feed hold: `complete` (`Hold:0`, stopped, ready to resume) or decelerating (`Hold:1`).
    Hold {
        complete: bool,
    },
    Jog,
    /// The homing cycle runs (`$H`).
    Home,
    Alarm,
    Check,
}

impl State {
    pub const fn name(self) -> &'static str {
        match self {
            State::Idle => "Idle",
            State::Run => "Run",
            State::Hold { complete: true } => "Hold:0",
            State::Hold { complete: false } => "Hold:1",
            State::Jog => "Jog",
            State::Home => "Home",
            State::Alarm => "Alarm",
            State::Check => "Check",
        }
    }
}

/// The adaptive controller's state in the `AC:` field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AcState {
    /// Adapting the feed (`run`).
    Run,
    /// Feed held by the controller, with the `ALARM:N` number of its reason (`hold:N`, see
    /// [`super::codes::alarm`]).
    Hold(u8),
}

/// millac's extra status field `AC:feed_share,F/F0,T/T0,state`, e.g. `AC:87,0.968,0.412,run`:
/// - `feed_share`: the feed the controller allows as a percentage of the programmed feed, 0..=100
///   (100: the programmed feed binds, 0: held), see [`AcReport::feed_share`];
/// - `F/F0`, `T/T0`: measured force and torque over their optimal values F0, T0, 3 decimals
///   (1.000 = at the set point; the permissible limit is 1/0.9 = 1.111 at the defaults);
/// - `state`: `run` or `hold:N` with N the hold's alarm number.
///
/// The field is present only when the controller is enabled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AcReport {
    pub feed_share_pct: u8,
    /// F/F0 in thousandths.
    pub f_ratio_milli: u16,
    /// T/T0 in thousandths.
    pub t_ratio_milli: u16,
    pub state: AcState,
}

impl AcReport {
    /// min(cap, programmed) / programmed in percent, rounded (feed numbers; no feed = 100).
    pub fn feed_share(cap: u32, programmed: u32) -> u8 {
        if programmed == 0 {
            return 100;
        }
        let share = div_round(cap.min(programmed) as i128 * 100, programmed as i128);
        share.unwrap_or(0) as u8
    }

    /// x / base in thousandths, rounded and saturated (NaN, negative or base <= 0 give 0).
    pub fn ratio_milli(x: f32, base: f32) -> u16 {
        if base > 0.0 && x > 0.0 {
            // `as` saturates; +0.5 rounds a positive value.
            (x / base * 1000.0 + 0.5) as u16
        } else {
            0 // also NaN
        }
    }
}

/// What the caller knows about the machine for one status report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StatusData {
    pub state: State,
    /// Machine position X, Y, Z in BLU.
    pub position: [i32; 3],
    /// Current feed along the path in BLU per minute (see [`feed_blu_per_min`]).
    pub feed_blu_per_min: u32,
    pub spindle_rpm: u32,
    /// Free blocks in the block queue (the `Bf:` field's first value).
    pub blocks_free: u16,
    /// The tool in the spindle (the last M6's `T`): the `T:` field; 0: none fitted since
    /// power-up, no field.
    pub tool: u8,
    /// The `AC:` field, when the adaptive control is enabled.
    pub ac: Option<AcReport>,
    /// The frame ISR's (fewest, most) CPU cycles for the `FC:` field, when the board measures
    /// them ([`crate::rt::Status::frame_cycles`]).
    pub frame_cycles: Option<(u32, u32)>,
    /// The work coordinate offset (the parser's program origin in machine coordinates,
    /// picometres): `WCO:`, and WPos = MPos - WCO.
    pub wco_pm: [i64; 3],
    /// The inputs active now, grbl's `Pn:` field (only when one is): bits 0-2 the X, Y, Z limit
    /// switches, bit 3 the probe (after `$6`).
    pub pins: u8,
}

/// The feed of feed number `f` in BLU per minute: f * W0 * 60 / q0, rounded.
pub fn feed_blu_per_min(machine: &Settings, f: u32) -> u32 {
    let n = f as i128 * machine.frame_hz as i128 * 60;
    div_round(n, machine.q0.max(1) as i128).unwrap_or(0) as u32
}

/// Writes `v / 10^decimals` with exactly `decimals` decimals (no sign for zero).
pub fn write_fixed(out: &mut dyn Write, v: i64, decimals: u32) -> fmt::Result {
    let p = 10u64.pow(decimals);
    let a = v.unsigned_abs();
    if v < 0 {
        out.write_char('-')?;
    }
    write!(out, "{}", a / p)?;
    if decimals > 0 {
        write!(out, ".{:0w$}", a % p, w = decimals as usize)?;
    }
    Ok(())
}

/// A length in BLU in report units: (scaled value, decimals).
fn length(blu: i32, unit: Blu, inches: bool) -> (i64, u32) {
    let nm = unit.nm() as i128;
    // mm: thousandths = nm / 1000; inch: ten-thousandths = nm / 2540.
    let (den, d) = if inches { (2540, 4) } else { (1000, 3) };
    (div_round(blu as i128 * nm, den).unwrap_or(0) as i64, d)
}

/// Writes a length in BLU in mm (3 decimals) or inches (4 decimals).
pub fn write_length(out: &mut dyn Write, blu: i32, unit: Blu, inches: bool) -> fmt::Result {
    let (v, d) = length(blu, unit, inches);
    write_fixed(out, v, d)
}

/// Writes a rate in BLU/min in mm/min (0 decimals) or in/min (1 decimal).
pub fn write_rate(out: &mut dyn Write, blu_per_min: u32, unit: Blu, inches: bool) -> fmt::Result {
    let nm = unit.nm() as i128;
    let (den, d) = if inches {
        (2_540_000, 1)
    } else {
        (1_000_000, 0)
    };
    let v = div_round(blu_per_min as i128 * nm, den).unwrap_or(0) as i64;
    write_fixed(out, v, d)
}

fn write_axes(out: &mut dyn Write, p: [i32; 3], unit: Blu, inches: bool) -> fmt::Result {
    for (k, v) in p.iter().enumerate() {
        if k > 0 {
            out.write_char(',')?;
        }
        write_length(out, *v, unit, inches)?;
    }
    Ok(())
}

/// The welcome banner after power-up and every reset: `Grbl 1.1h ['$' for help]` and a line
/// naming millac and its version.
pub fn write_banner(out: &mut dyn Write) -> fmt::Result {
    write!(
        out,
        "\r\nGrbl {GRBL_VERSION} ['$' for help]\r\n[MSG:millac {MILLAC_VERSION} NC + adaptive control]\r\n"
    )
}

/// Everything a status report needs besides the caller's [`StatusData`].
pub struct StatusContext {
    pub options: ReportOptions,
    pub unit: Blu,
    pub overrides: Overrides,
    /// Free bytes in the receive ring.
    pub rx_free: usize,
    /// Include `WCO:` (first report after a reset or a change of the offset, then every 10th
    /// while busy / 30th idle).
    pub wco: bool,
}

/// `<State|MPos:x,y,z|Bf:b,r|FS:f,s|WCO:..|Ov:f,r,s|T:n|AC:..|FC:min,max>` and its line end.
/// `T:n`: the tool in the spindle, once an M6 has fitted one.
/// `FC:min,max`: the frame ISR's fewest and most CPU cycles, only when measured.
pub fn write_status(out: &mut dyn Write, d: &StatusData, cx: &StatusContext) -> fmt::Result {
    let inches = cx.options.inches;
    write!(out, "<{}", d.state.name())?;
    if cx.options.status_mask & 1 != 0 {
        out.write_str("|MPos:")?;
        write_axes(out, d.position, cx.unit, inches)?;
    } else {
        // WPos = MPos - WCO, exact in picometres, rounded once for the report.
        let pm = pm_per_blu(cx.unit);
        out.write_str("|WPos:")?;
        write_pm_axes(
            out,
            [0, 1, 2].map(|k| d.position[k] as i64 * pm - d.wco_pm[k]),
            inches,
        )?;
    }
    if cx.options.status_mask & 2 != 0 {
        write!(out, "|Bf:{},{}", d.blocks_free, cx.rx_free)?;
    }
    out.write_str("|FS:")?;
    write_rate(out, d.feed_blu_per_min, cx.unit, inches)?;
    write!(out, ",{}", d.spindle_rpm)?;
    if d.pins & 0b1111 != 0 {
        out.write_str("|Pn:")?;
        for (bit, c) in [(8, 'P'), (1, 'X'), (2, 'Y'), (4, 'Z')] {
            if d.pins & bit != 0 {
                out.write_char(c)?;
            }
        }
    }
    if cx.wco {
        out.write_str("|WCO:")?;
        write_pm_axes(out, d.wco_pm, inches)?;
    }
    let o = cx.overrides;
    write!(out, "|Ov:{},{},{}", o.feed, o.rapid, o.spindle)?;
    if d.tool != 0 {
        write!(out, "|T:{}", d.tool)?;
    }
    if let Some(ac) = d.ac {
        write!(out, "|AC:{},", ac.feed_share_pct)?;
        write_fixed(out, ac.f_ratio_milli as i64, 3)?;
        out.write_char(',')?;
        write_fixed(out, ac.t_ratio_milli as i64, 3)?;
        match ac.state {
            AcState::Run => out.write_str(",run")?,
            AcState::Hold(n) => write!(out, ",hold:{n}")?,
        }
    }
    if let Some((min, max)) = d.frame_cycles {
        write!(out, "|FC:{min},{max}")?;
    }
    out.write_str(">\r\n")
}

/// `$G`: every modal group as the parser stands, in grbl's order with grblHAL's additions:
/// `[GC:G0 G54 G17 G21 G90 G94 G40 G49 G98 G61 M5 M9 T0 F0 S0]` (motion, coordinate system,
/// plane, units, distance, feed mode, cutter compensation, tool length offset (G43 with H, G43.1
/// or G49), return level, path control, spindle, coolant (M7, M8, both, or M9), the last T, the
/// modal feed as the machine runs it (the feed number, so clamped to FRM) in `$13` units, S).
pub fn write_modes(
    out: &mut dyn Write,
    m: &Modes,
    machine: &Settings,
    inches: bool,
) -> fmt::Result {
    let plane = match m.plane {
        Plane::XY => 17,
        Plane::ZX => 18,
        Plane::YZ => 19,
    };
    let units = match m.units {
        Units::Inch => 20,
        Units::Mm => 21,
    };
    let distance = match m.distance {
        Distance::Absolute => 90,
        Distance::Incremental => 91,
    };
    let feed_mode = match m.feed_mode {
        FeedMode::PerMinute => 94,
        FeedMode::InverseTime => 93,
    };
    let spindle = match m.spindle {
        Spindle::Off => 5,
        Spindle::Cw => 3,
        Spindle::Ccw => 4,
    };
    let tool_length = match m.tool_length {
        ToolLength::Off => "G49",
        ToolLength::Table(_) => "G43",
        ToolLength::Dynamic => "G43.1",
    };
    let retract = match m.retract {
        Retract::Initial => 98,
        Retract::RPlane => 99,
    };
    let path = match m.path {
        PathMode::ExactPath => "G61",
        PathMode::ExactStop => "G61.1",
        PathMode::Blend => "G64",
    };
    let coolant = match (m.coolant.mist, m.coolant.flood) {
        (true, true) => "M7 M8",
        (true, false) => "M7",
        (false, true) => "M8",
        (false, false) => "M9",
    };
    write!(
        out,
        "[GC:G{} G{} G{plane} G{units} G{distance} G{feed_mode} G40 {tool_length} G{retract} \
         {path} M{spindle} {coolant} T{} F",
        crate::gcode::motion_code(m.motion),
        54 + m.coord as u32,
        m.tool
    )?;
    write_rate(out, feed_blu_per_min(machine, m.feed), machine.blu, inches)?;
    write!(out, " S{}]\r\n", m.spindle_rpm)
}

/// What `$#` reports: the offsets in picometres of machine coordinates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OffsetsReport {
    pub offsets: crate::gcode::Offsets,
    /// The tool length offset in force (Z).
    pub tlo_pm: i64,
    /// The last probing move's stop, machine coordinates in BLU, and whether the probe changed
    /// ([0; 3], false before any).
    pub probe: ([i32; 3], bool),
}

/// `$#`: the six coordinate systems, G28, G30, G92 (as applied), the tool length offset, and the
/// last probe ([`write_probe`]), in `$13` units like every position.
pub fn write_offsets(
    out: &mut dyn Write,
    r: &OffsetsReport,
    unit: Blu,
    inches: bool,
) -> fmt::Result {
    let o = &r.offsets;
    let mut row = |name: &str, p: [i64; 3]| -> fmt::Result {
        write!(out, "[{name}:")?;
        write_pm_axes(out, p, inches)?;
        out.write_str("]\r\n")
    };
    for (name, p) in ["G54", "G55", "G56", "G57", "G58", "G59"]
        .iter()
        .zip(o.systems.iter())
    {
        row(name, *p)?;
    }
    row("G28", o.g28)?;
    row("G30", o.g30)?;
    row("G92", o.g92_applied())?;
    out.write_str("[TLO:")?;
    write_pm(out, r.tlo_pm, inches)?;
    out.write_str("]\r\n")?;
    write_probe(out, r.probe.0, r.probe.1, unit, inches)
}

/// `[PRB:x,y,z:s]`: where a probing move stopped (machine coordinates, `$13` units) and whether
/// the probe changed (1) or the move ended without (0). After every G38 line, before its answer,
/// and in `$#`.
pub fn write_probe(
    out: &mut dyn Write,
    at: [i32; 3],
    ok: bool,
    unit: Blu,
    inches: bool,
) -> fmt::Result {
    out.write_str("[PRB:")?;
    write_axes(out, at, unit, inches)?;
    write!(out, ":{}]\r\n", u8::from(ok))
}

/// Picometres per BLU (exact: 2 540 000 or 1 000 000).
pub const fn pm_per_blu(unit: Blu) -> i64 {
    let (num, den) = unit.per_mm();
    1_000_000_000 * den / num
}

/// A length in picometres in mm (3 decimals) or inches (4), rounded half away from zero.
fn write_pm(out: &mut dyn Write, pm: i64, inches: bool) -> fmt::Result {
    let (den, decimals) = if inches {
        (2_540_000u64, 4)
    } else {
        (1_000_000u64, 3)
    };
    let q = (pm.unsigned_abs() + den / 2) / den;
    let v = if pm < 0 { -(q as i64) } else { q as i64 };
    write_fixed(out, v, decimals)
}

fn write_pm_axes(out: &mut dyn Write, p: [i64; 3], inches: bool) -> fmt::Result {
    for (k, v) in p.iter().enumerate() {
        if k > 0 {
            out.write_char(',')?;
        }
        write_pm(out, *v, inches)?;
    }
    Ok(())
}

/// The frame ISR's measured cost for `$I`, in CPU cycles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameCycles {
    /// Fewest and most cycles of one frame.
    pub min: u32,
    pub max: u32,
    /// Cycles per rapid period (core clock / rapid rate, the shortest frame period); 0 = the core
    /// clock is not known.
    pub budget: u32,
}

/// `$I`: `[VER:1.1h.millac:]` and `[OPT:V,<blocks>,<rx bytes>]` (V: the S word is kept, so the
/// status report has `FS:`), then `[FRAME:min,max,budget]` when the frame is measured
/// ([`FrameCycles`]).
pub fn write_build_info(
    out: &mut dyn Write,
    blocks: u16,
    rx: usize,
    frame: Option<FrameCycles>,
) -> fmt::Result {
    write!(
        out,
        "[VER:{GRBL_VERSION}.millac:]\r\n[OPT:V,{blocks},{rx}]\r\n"
    )?;
    if let Some(f) = frame {
        write!(out, "[FRAME:{},{},{}]\r\n", f.min, f.max, f.budget)?;
    }
    Ok(())
}

/// `[HLP:...]`, the commands millac implements.
pub fn write_help(out: &mut dyn Write) -> fmt::Result {
    out.write_str("[HLP:$$ $# $G $I $N $x=val $T $Tn=words $J=line $C $X $H ~ ! ? ctrl-x]\r\n")
}

/// `ALARM:N`.
pub fn write_alarm(out: &mut dyn Write, code: u8) -> fmt::Result {
    write!(out, "ALARM:{code}\r\n")
}

/// `[MSG:text]`: line ends in the text become spaces and `]` becomes `)`, so the message stays
/// one well-formed line.
pub fn write_message(out: &mut dyn Write, text: fmt::Arguments<'_>) -> fmt::Result {
    struct Clean<'w>(&'w mut dyn Write);
    impl Write for Clean<'_> {
        fn write_str(&mut self, s: &str) -> fmt::Result {
            for c in s.chars() {
                let c = match c {
                    '\r' | '\n' => ' ',
                    ']' => ')',
                    c => c,
                };
                self.0.write_char(c)?;
            }
            Ok(())
        }
    }
    out.write_str("[MSG:")?;
    Clean(out).write_fmt(text)?;
    out.write_str("]\r\n")
}
