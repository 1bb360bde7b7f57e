//! The semantics of one G-code line (loader task; host tests): modal words, unit conversion, work
//! offsets and tools, targets, soft limits and the blocks it produces. Runs on copies of the parser
//! state.
//!
//! The order within a line is RS274/NGC's (and grbl's): feed mode, F, S, T; the tool change M6;
//! the spindle and coolant; the dwell; plane, units, cutter compensation (G40 only), tool length
//! offset, coordinate system, path control, distance and return modes; the non-modal commands
//! G10, G28, G30, G92; the motion (G53 modifies it); the stop M0, M1, M2, M30. The axis words
//! belong to one command of the line: a motion, G10, G28/G30, G92 or G43.1.

use super::arc::{self, Centre};
use super::cycles::{Cycle, CycleKind};
use super::error::{axis_name, Construct, CycleError, ErrorKind};
use super::fine::{
    fine_of_blu, fine_of_pm, fine_to_blu, pm_of_fine, to_fine, FINE_PER_INCH, FINE_PER_MM,
};
use super::offsets::{Offsets, MAX_PM};
use super::tools::{Tool, ToolTable, MAX_TOOLS};
use super::words::{
    self, Code, Words, AXES, F, G_COORD, G_CUTTER, G_DISTANCE, G_FEED_MODE, G_MOTION, G_NON_MODAL,
    G_PATH, G_PLANE, G_RETURN, G_TOOL_LENGTH, G_UNITS, H, L, M_COOLANT, M_SPINDLE, M_STOP, M_TOOL,
    N, OFFSETS, P, Q, R, S, T,
};
use super::{
    feed_number, Distance, FeedMode, Modes, MotionMode, Parsed, PathMode, Probe, Retract, Spindle,
    Stop, ToolLength, Units,
};
use crate::nc::{isqrt, Block, Dwell, Linear, Motion, Plane, Rapid, Q_MAX};
use crate::settings::Settings;

/// A length word in BLU (rounded half away from zero); it must fit i32.
fn length(w: &Words, i: usize, per: (i64, i64)) -> Result<Option<i64>, ErrorKind> {
    let letter = words::LETTERS.get(i).copied().unwrap_or('?');
    match w.value(i) {
        None => Ok(None),
        Some(d) => match d
            .mul_ratio_round(per.0 as i128, per.1 as i128)
            .map(i32::try_from)
        {
            Some(Ok(v)) => Ok(Some(v as i64)),
            _ => Err(ErrorKind::NumberTooLarge(letter)),
        },
    }
}

/// The parser's position: the machine's in BLU and the programmed one, exact, in fine units.
pub struct Position<'a> {
    pub blu: &'a mut [i32; 3],
    pub fine: &'a mut [i128; 3],
}

fn check_soft(st: &Settings, target: [i32; 3]) -> Result<(), ErrorKind> {
    for (k, ((&t, &min), &max)) in target
        .iter()
        .zip(st.soft_min.iter())
        .zip(st.soft_max.iter())
        .enumerate()
    {
        if t < min || t > max {
            return Err(ErrorKind::SoftLimit {
                axis: axis_name(k),
                value: t as i64,
                min,
                max,
            });
        }
    }
    Ok(())
}

/// The value words a line's commands take: the rest are an error (grbl's rule, error 36).
#[derive(Clone, Copy, Default)]
struct Used(u32);

impl Used {
    fn take(&mut self, i: usize) {
        self.0 |= 1 << i;
    }

    /// The first value word of the line that no command took.
    fn check(self, w: &Words) -> Result<(), ErrorKind> {
        for (i, v) in w.values.iter().enumerate() {
            if v.is_some() && self.0 & (1 << i) == 0 {
                return Err(ErrorKind::UnusedWord(
                    words::LETTERS.get(i).copied().unwrap_or('?'),
                ));
            }
        }
        Ok(())
    }
}

/// How the line's length words convert: BLU per program unit (a ratio) and fine units per
/// program unit.
#[derive(Clone, Copy)]
struct Scale {
    per: (i64, i64),
    fine: i128,
}

/// The parser state one line may change: the caller's copies, committed only on `Ok`. The tool
/// table is read only: a G10 L1 leaves its entry in `tool_set` for the caller to commit.
pub struct State<'a> {
    pub modes: &'a mut Modes,
    pub pos: Position<'a>,
    pub offsets: &'a mut Offsets,
    /// The tool in the spindle (the last M6's; 0 = none).
    pub loaded: &'a mut u8,
    pub tools: &'a ToolTable,
    pub tool_set: &'a mut Option<(u32, Tool)>,
}

/// Which command of the line the axis words belong to.
#[derive(Clone, Copy, PartialEq, Eq)]
enum AxisCommand {
    None,
    Motion,
    /// G10 L2/L20/L1.
    Set,
    /// G28 / G30 (the intermediate point).
    Home(bool),
    /// G92.
    Origin,
    /// G43.1.
    ToolLength,
}

/// The semantics of one line on the parser's state (see the module's order). Returns what the
/// line produced; the state is the caller's copy.
pub fn execute(st: &Settings, s: State, line_no: u32, text: &str) -> Result<Parsed, ErrorKind> {
    let w = words::lex(text)?;
    let State {
        modes: m,
        pos,
        offsets,
        loaded,
        tools,
        tool_set,
    } = s;
    let mut used = Used::default();
    used.take(N);
    let non_modal = w.g[G_NON_MODAL];

    // The axis words' command, and the conflicts between the commands that take them.
    let axis_command = match (non_modal, w.g[G_TOOL_LENGTH]) {
        (Some(100), _) => AxisCommand::Set,
        (Some(280), _) => AxisCommand::Home(false),
        (Some(300), _) => AxisCommand::Home(true),
        (Some(920), _) => AxisCommand::Origin,
        (_, Some(431)) => AxisCommand::ToolLength,
        _ if w.has_axes() || w.g[G_MOTION].is_some() => AxisCommand::Motion,
        _ => AxisCommand::None,
    };
    let explicit_motion = w.g[G_MOTION].is_some();
    let two_axis_users = (non_modal.is_some_and(|g| matches!(g, 100 | 280 | 300 | 920))
        && w.g[G_TOOL_LENGTH] == Some(431))
        || (axis_command != AxisCommand::Motion
            && axis_command != AxisCommand::None
            && explicit_motion);
    if two_axis_users {
        return Err(ErrorKind::AxisCommandConflict);
    }
    // The axis words' command takes them (and refuses those it cannot use with its own error).
    for k in 0..3 {
        used.take(AXES + k);
    }

    // Feed mode first (F is read in it), then F, S, T.
    match w.g[G_FEED_MODE] {
        Some(930) if m.feed_mode != FeedMode::InverseTime => {
            m.feed_mode = FeedMode::InverseTime;
            m.feed = 0;
        }
        Some(940) if m.feed_mode != FeedMode::PerMinute => {
            // Back to units per minute: the feed is undefined until the next F (grbl, LinuxCNC).
            m.feed_mode = FeedMode::PerMinute;
            m.feed = 0;
        }
        _ => {}
    }
    // Modal words apply to the whole line, wherever they stand: the units before F.
    modal_words(&w, m, &mut used)?;
    let scale = match m.units {
        Units::Inch => Scale {
            per: st.blu.per_inch(),
            fine: FINE_PER_INCH,
        },
        Units::Mm => Scale {
            per: st.blu.per_mm(),
            fine: FINE_PER_MM,
        },
    };
    // Every axis word fits the machine's BLU range, whatever command takes it.
    for k in 0..3 {
        length(&w, AXES + k, scale.per)?;
    }
    feed_and_spindle(st, &w, m, scale, &mut used)?;
    if let Some(t) = w.value(T) {
        used.take(T);
        m.tool = tool_number(t, 'T')?;
    }
    let tool_change = w.m[M_TOOL].is_some();
    if tool_change {
        *loaded = m.tool;
    }
    tool_length(&w, m, *loaded, tools, scale, &mut used)?;
    if let Some(code) = w.m[M_COOLANT] {
        m.coolant = match code {
            70 => super::Coolant {
                mist: true,
                ..m.coolant
            },
            80 => super::Coolant {
                flood: true,
                ..m.coolant
            },
            _ => super::Coolant::OFF,
        };
    }

    let before = m.motion;
    let probe = w.g[G_MOTION].and_then(Probe::of_code);
    let motion_word = motion_mode(&w, m);
    let dwell = non_modal == Some(40);
    let moves = dwell
        || matches!(axis_command, AxisCommand::Motion | AxisCommand::Home(_))
            && (w.has_axes() || matches!(axis_command, AxisCommand::Home(_)));
    // M0, M2, M30 and M6 stand on a line without motion (M1 is ignored, as grbl ignores it: no
    // optional-stop switch).
    let stop_code = w.m[M_STOP]
        .filter(|&c| c != 10)
        .or(tool_change.then_some(60));
    if let Some(code) = stop_code.filter(|_| moves) {
        return Err(ErrorKind::StopWithMotion { code });
    }
    let stop = match (w.m[M_STOP], tool_change) {
        (Some(20 | 300), _) => Some(Parsed::End),
        (_, true) => Some(Parsed::Stop(Stop::ToolChange { tool: *loaded })),
        (Some(0), _) => Some(Parsed::Stop(Stop::Pause)),
        _ => None,
    };

    let parsed = if dwell {
        dwell_block(st, &w, line_no, &mut used)?
    } else {
        match axis_command {
            AxisCommand::Set => {
                set_offsets(&w, m, &pos, offsets, tools, tool_set, scale, &mut used)?;
                Parsed::Nothing
            }
            AxisCommand::Origin => {
                set_g92(&w, m, &pos, offsets, scale)?;
                Parsed::Nothing
            }
            AxisCommand::Home(g30) => home(st, &w, m, pos, offsets, scale, g30, line_no)?,
            AxisCommand::ToolLength | AxisCommand::None => {
                stored_positions(&w, non_modal, &pos, offsets)?;
                Parsed::Nothing
            }
            AxisCommand::Motion => {
                stored_positions(&w, non_modal, &pos, offsets)?;
                if let MotionMode::Cycle(kind) = m.motion {
                    let series = before == m.motion;
                    if w.has_axes() || motion_word.is_some() {
                        cycle(
                            st, &w, m, pos, offsets, scale, kind, series, line_no, &mut used,
                        )?
                    } else {
                        Parsed::Nothing
                    }
                } else if let Some(kind) = probe {
                    probe_move(st, &w, m, pos, offsets, scale, line_no, &mut used, kind)?
                } else {
                    motion(
                        st,
                        &w,
                        m,
                        pos,
                        offsets,
                        scale,
                        motion_word,
                        line_no,
                        &mut used,
                    )?
                }
            }
        }
    };
    used.check(&w)?;
    Ok(match stop {
        Some(stop) => stop,
        None => parsed,
    })
}

/// G28.1 / G30.1 (store the machine position), G92.1 / G92.2 / G92.3; G53 alone is nothing.
fn stored_positions(
    w: &Words,
    non_modal: Option<Code>,
    pos: &Position,
    offsets: &mut Offsets,
) -> Result<(), ErrorKind> {
    let code = match non_modal {
        Some(code @ (281 | 301 | 921 | 922 | 923)) => code,
        _ => return Ok(()),
    };
    if w.has_axes() {
        return Err(ErrorKind::AxisWordsUnused { code });
    }
    match code {
        281 => offsets.g28 = here_pm(pos)?,
        301 => offsets.g30 = here_pm(pos)?,
        921 => {
            offsets.g92 = [0; 3];
            offsets.g92_on = false;
        }
        922 => offsets.g92_on = false,
        _ => offsets.g92_on = true,
    }
    Ok(())
}

/// T, H and G10 L1's P: a whole tool number of the table (T0/H0: no tool).
fn tool_number(v: super::Decimal, letter: char) -> Result<u8, ErrorKind> {
    let n = v.as_integer().ok_or(ErrorKind::NotInteger(letter))?;
    match u8::try_from(n) {
        Ok(t) if (t as usize) <= MAX_TOOLS => Ok(t),
        _ => Err(ErrorKind::ToolNumber {
            value: u32::try_from(n.max(0)).unwrap_or(u32::MAX),
        }),
    }
}

/// G43 H (the table's length; without H the loaded tool's), G43.1 Z (a length given), G49.
fn tool_length(
    w: &Words,
    m: &mut Modes,
    loaded: u8,
    tools: &ToolTable,
    scale: Scale,
    used: &mut Used,
) -> Result<(), ErrorKind> {
    match w.g[G_TOOL_LENGTH] {
        Some(430) => {
            used.take(H);
            let h = match w.value(H) {
                Some(h) => tool_number(h, 'H')?,
                None => loaded,
            };
            m.tlo_pm = tools.get(h as u32).map_or(0, |t| t.length_pm);
            m.tool_length = ToolLength::Table(h);
        }
        Some(431) => {
            if w.value(AXES).is_some() || w.value(AXES + 1).is_some() {
                return Err(ErrorKind::ToolLengthAxis);
            }
            let z = w
                .value(AXES + 2)
                .ok_or(ErrorKind::NoAxisWords { code: 431 })?;
            m.tlo_pm = offset_pm(z, scale, 'Z')?;
            m.tool_length = ToolLength::Dynamic;
        }
        Some(_) => {
            m.tlo_pm = 0;
            m.tool_length = ToolLength::Off;
        }
        None => {}
    }
    Ok(())
}

/// A length word as an offset in picometres (exact to 1 pm), within +-[`MAX_PM`].
#[inline(never)]
fn offset_pm(v: super::Decimal, scale: Scale, letter: char) -> Result<i64, ErrorKind> {
    to_fine(v, scale.fine)
        .and_then(pm_of_fine)
        .filter(|p| p.unsigned_abs() <= MAX_PM as u64)
        .ok_or(ErrorKind::NumberTooLarge(letter))
}

/// The machine position in picometres.
#[inline(never)]
fn here_pm(pos: &Position) -> Result<[i64; 3], ErrorKind> {
    let mut p = [0i64; 3];
    for (k, v) in p.iter_mut().enumerate() {
        *v = pm_of_fine(pos.fine[k]).ok_or(ErrorKind::TargetOverflow { axis: axis_name(k) })?;
    }
    Ok(p)
}

/// G10 L2 Pn (a system's offset is the words), G10 L20 Pn (the offset that makes the machine's
/// position the words in that system), G10 L1 Pt Z R (tool t's length and radius). P0 is the
/// system in use. Absolute values whatever G90/G91 (grbl).
#[allow(clippy::too_many_arguments)]
fn set_offsets(
    w: &Words,
    m: &Modes,
    pos: &Position,
    offsets: &mut Offsets,
    tools: &ToolTable,
    tool_set: &mut Option<(u32, Tool)>,
    scale: Scale,
    used: &mut Used,
) -> Result<(), ErrorKind> {
    used.take(L);
    used.take(P);
    // L and P: whole numbers, both required.
    let whole = |i: usize, letter: char| {
        w.value(i)
            .ok_or(ErrorKind::MissingWord { code: 100, letter })?
            .as_integer()
            .ok_or(ErrorKind::NotInteger(letter))
    };
    let l = whole(L, 'L')?;
    let p = whole(P, 'P')?;
    if l == 1 {
        // The tool table: Z is the length, R the radius (LinuxCNC's and grblHAL's form).
        used.take(R);
        if w.value(AXES).is_some() || w.value(AXES + 1).is_some() {
            return Err(ErrorKind::NotInDialect(Construct::G10Form));
        }
        let n = tool_number(super::Decimal::int(p as i64), 'P')?;
        if n == 0 {
            return Err(ErrorKind::ToolNumber { value: 0 });
        }
        let mut tool = tools.get(n as u32).copied().unwrap_or_default();
        if let Some(z) = w.value(AXES + 2) {
            tool.length_pm = offset_pm(z, scale, 'Z')?;
        }
        if let Some(r) = w.value(R) {
            if r.is_negative() {
                return Err(ErrorKind::NegativeValue('R'));
            }
            tool.diameter_pm = offset_pm(r, scale, 'R')?
                .checked_mul(2)
                .ok_or(ErrorKind::NumberTooLarge('R'))?;
        }
        *tool_set = Some((n as u32, tool));
        return Ok(());
    }
    if l != 2 && l != 20 {
        return Err(ErrorKind::NotInDialect(Construct::G10Form));
    }
    let system = match p {
        0 => m.coord as usize,
        1..=6 => p as usize - 1,
        _ => return Err(ErrorKind::CoordinateSystem),
    };
    if !w.has_axes() {
        return Err(ErrorKind::NoAxisWords { code: 100 });
    }
    let here = here_pm(pos)?;
    let g92 = offsets.g92_applied();
    let Some(sys) = offsets.systems.get_mut(system) else {
        return Err(ErrorKind::CoordinateSystem);
    };
    for k in 0..3 {
        let Some(v) = w.value(AXES + k) else { continue };
        let v = offset_pm(v, scale, axis_name(k))?;
        sys[k] = if l == 2 {
            v
        } else {
            let tlo = if k == 2 { m.tlo_pm } else { 0 };
            let o = here[k] - g92[k] - tlo - v;
            if o.unsigned_abs() > MAX_PM as u64 {
                return Err(ErrorKind::NumberTooLarge(axis_name(k)));
            }
            o
        };
    }
    Ok(())
}

/// G92: the offset that makes the machine's position the words in the system in use (the axes
/// without a word keep theirs).
fn set_g92(
    w: &Words,
    m: &Modes,
    pos: &Position,
    offsets: &mut Offsets,
    scale: Scale,
) -> Result<(), ErrorKind> {
    if !w.has_axes() {
        return Err(ErrorKind::NoAxisWords { code: 920 });
    }
    let here = here_pm(pos)?;
    let mut g92 = offsets.g92_applied();
    let sys = offsets
        .systems
        .get(m.coord as usize)
        .copied()
        .unwrap_or([0; 3]);
    for k in 0..3 {
        let Some(v) = w.value(AXES + k) else { continue };
        let v = offset_pm(v, scale, axis_name(k))?;
        let tlo = if k == 2 { m.tlo_pm } else { 0 };
        let o = here[k] - sys[k] - tlo - v;
        if o.unsigned_abs() > MAX_PM as u64 {
            return Err(ErrorKind::NumberTooLarge(axis_name(k)));
        }
        g92[k] = o;
    }
    offsets.g92 = g92;
    offsets.g92_on = true;
    Ok(())
}

/// The origin of the program coordinates (machine, fine units) for this line: none for G53.
fn origin_fine(m: &Modes, offsets: &Offsets, machine: bool) -> [i128; 3] {
    if machine {
        return [0; 3];
    }
    offsets.origin(m.coord, m.tlo_pm).map(fine_of_pm)
}

/// G28 / G30: a rapid to the intermediate point of the axis words (if any, in program
/// coordinates, G90/G91 as in force), then a rapid to the stored position, of the axes named
/// (all axes when none is).
#[allow(clippy::too_many_arguments)]
fn home(
    st: &Settings,
    w: &Words,
    m: &Modes,
    pos: Position,
    offsets: &Offsets,
    scale: Scale,
    g30: bool,
    line_no: u32,
) -> Result<Parsed, ErrorKind> {
    let origin = origin_fine(m, offsets, false);
    let (mid, mid_fine) = targets(st, w, m.distance, &pos, scale, origin)?;
    check_soft(st, mid)?;
    let stored = if g30 { offsets.g30 } else { offsets.g28 };
    let mut end_fine = mid_fine;
    for k in 0..3 {
        if !w.has_axes() || w.value(AXES + k).is_some() {
            end_fine[k] = fine_of_pm(stored[k]);
        }
    }
    let mut end = [0i32; 3];
    for k in 0..3 {
        end[k] =
            fine_to_blu(st, end_fine[k]).ok_or(ErrorKind::TargetOverflow { axis: axis_name(k) })?;
    }
    check_soft(st, end)?;
    let rapid = |from: [i32; 3], to: [i32; 3]| {
        let (steps, signs) =
            crate::nc::steps_and_signs([0, 1, 2].map(|k| to[k] as i64 - from[k] as i64));
        (steps != [0; 3]).then_some(Block {
            line: line_no,
            motion: Motion::Rapid(Rapid { steps, signs }),
        })
    };
    let first = rapid(*pos.blu, mid);
    let second = rapid(mid, end);
    *pos.blu = end;
    *pos.fine = end_fine;
    Ok(match (first, second) {
        (Some(a), Some(b)) => Parsed::Two(a, b),
        (Some(b), None) | (None, Some(b)) => Parsed::Block(b),
        (None, None) => Parsed::Nothing,
    })
}

/// A canned cycle line (see [`super::cycles`]): the words (sticky within a series of the same
/// cycle), the levels and holes in machine coordinates, validated whole (soft limits at every
/// hole and level, the feed within the DDA); the parser then stands over the last hole at the
/// clear level.
#[allow(clippy::too_many_arguments)]
fn cycle(
    st: &Settings,
    w: &Words,
    m: &mut Modes,
    pos: Position,
    offsets: &Offsets,
    scale: Scale,
    kind: CycleKind,
    series: bool,
    line_no: u32,
    used: &mut Used,
) -> Result<Parsed, ErrorKind> {
    let code = kind.code() * 10;
    if m.plane != Plane::XY {
        return Err(ErrorKind::Cycle(CycleError::NotXy));
    }
    if m.feed_mode == FeedMode::InverseTime {
        return Err(ErrorKind::Cycle(CycleError::InverseTime));
    }
    if m.feed == 0 {
        return Err(ErrorKind::NoFeed {
            code: kind.code() as u8,
        });
    }
    used.take(R);
    used.take(L);
    let word = |i: usize, sticky: i128| -> Result<i128, ErrorKind> {
        let letter = words::LETTERS.get(i).copied().unwrap_or('?');
        match w.value(i) {
            Some(v) => to_fine(v, scale.fine).ok_or(ErrorKind::NumberTooLarge(letter)),
            None if series => Ok(sticky),
            None => Err(ErrorKind::MissingWord { code, letter }),
        }
    };
    let r_word = word(R, m.cycle.r)?;
    let z_word = word(AXES + 2, m.cycle.z)?;
    let mut q = m.cycle.q;
    if kind.pecks() {
        used.take(Q);
        q = word(Q, m.cycle.q)?;
        if q <= 0 {
            return Err(ErrorKind::Cycle(CycleError::Peck));
        }
    }
    let mut dwell_frames = m.cycle.dwell_frames;
    if kind.dwells() {
        used.take(P);
        dwell_frames = match w.value(P) {
            Some(pv) if pv.is_negative() => return Err(ErrorKind::NegativeValue('P')),
            Some(pv) => match pv
                .mul_ratio_round(st.frame_hz as i128, 1)
                .map(u32::try_from)
            {
                Some(Ok(v)) => v,
                _ => return Err(ErrorKind::NumberTooLarge('P')),
            },
            None if series => m.cycle.dwell_frames,
            None => return Err(ErrorKind::MissingWord { code, letter: 'P' }),
        };
    }
    let repeats = match w.value(L) {
        None => 1,
        Some(l) => match l.as_integer().map(u32::try_from) {
            Some(Ok(n)) if n >= 1 => n,
            Some(_) => return Err(ErrorKind::Cycle(CycleError::Repeats)),
            None => return Err(ErrorKind::NotInteger('L')),
        },
    };

    // The levels and holes, machine fine units.
    let here = *pos.fine;
    let old_cc = m.cycle.il.unwrap_or(here[2]);
    let origin = origin_fine(m, offsets, false);
    let overflow = |k: usize| ErrorKind::TargetOverflow { axis: axis_name(k) };
    let add = |a: i128, b: i128, k: usize| a.checked_add(b).ok_or(overflow(k));
    let (first, step, r, bottom) = match m.distance {
        Distance::Absolute => {
            let mut first = [here[0], here[1]];
            for (k, f) in first.iter_mut().enumerate() {
                if let Some(v) = w.value(AXES + k) {
                    *f = add(to_fine(v, scale.fine).ok_or(overflow(k))?, origin[k], k)?;
                }
            }
            (
                first,
                [0, 0],
                add(r_word, origin[2], 2)?,
                add(z_word, origin[2], 2)?,
            )
        }
        Distance::Incremental => {
            let mut step = [0i128; 2];
            for (k, s) in step.iter_mut().enumerate() {
                if let Some(v) = w.value(AXES + k) {
                    *s = to_fine(v, scale.fine).ok_or(overflow(k))?;
                }
            }
            let first = [add(here[0], step[0], 0)?, add(here[1], step[1], 1)?];
            let r = add(r_word, old_cc, 2)?;
            (first, step, r, add(r, z_word, 2)?)
        }
    };
    if r < bottom {
        return Err(ErrorKind::Cycle(CycleError::RBelowZ));
    }
    let clear = if m.retract == Retract::RPlane {
        r
    } else {
        old_cc.max(r)
    };
    let last = [0, 1].map(|k| {
        step[k]
            .checked_mul(repeats as i128 - 1)
            .and_then(|d| first[k].checked_add(d))
    });
    let [Some(lx), Some(ly)] = last else {
        return Err(ErrorKind::TargetOverflow { axis: 'X' });
    };
    // Every hole lies between the first and the last; every level between the top and the bottom.
    let top = here[2].max(r).max(clear);
    for (x, y) in [(first[0], first[1]), (lx, ly)] {
        for z in [top, bottom] {
            let mut t = [0i32; 3];
            for (k, f) in [x, y, z].into_iter().enumerate() {
                t[k] = fine_to_blu(st, f).ok_or(overflow(k))?;
            }
            check_soft(st, t)?;
        }
    }
    let depth =
        fine_to_blu(st, top).unwrap_or(0) as i64 - fine_to_blu(st, bottom).unwrap_or(0) as i64;
    if depth > Q_MAX as i64 {
        return Err(ErrorKind::MoveTooLong);
    }

    m.cycle.r = r_word;
    m.cycle.z = z_word;
    m.cycle.q = q;
    m.cycle.dwell_frames = dwell_frames;
    m.cycle.il = Some(old_cc);
    let c = Cycle::new(
        kind,
        line_no,
        first,
        step,
        repeats,
        [r, bottom, clear],
        q,
        dwell_frames,
        m.feed,
        here,
        *pos.blu,
    );
    let end = [lx, ly, clear];
    for (k, (b, f)) in pos.blu.iter_mut().zip(end).enumerate() {
        *b = fine_to_blu(st, f).ok_or(overflow(k))?;
    }
    *pos.fine = end;
    Ok(Parsed::Expand(super::Expansion::Cycle(c)))
}

/// A motion line: G0/G1/G2/G3 in the mode in force (G53: machine coordinates, G0/G1 in G90).
#[allow(clippy::too_many_arguments)]
fn motion(
    st: &Settings,
    w: &Words,
    m: &Modes,
    pos: Position,
    offsets: &Offsets,
    scale: Scale,
    motion_word: Option<Code>,
    line_no: u32,
    used: &mut Used,
) -> Result<Parsed, ErrorKind> {
    // G53: the axis words are machine coordinates whatever G90/G91 (grbl's absolute override;
    // the senders' tool-change routines send G53 moves in G91).
    let machine = w.g[G_NON_MODAL] == Some(530);
    if machine && !matches!(m.motion, MotionMode::Rapid | MotionMode::Linear) {
        return Err(ErrorKind::G53Motion);
    }
    // A motion runs when the line has axis words or names a motion mode (grbl).
    if !w.has_axes() && motion_word.is_none() {
        return Ok(Parsed::Nothing);
    }
    let code = motion_code(m.motion);
    if m.motion == MotionMode::None {
        if w.has_axes() {
            return Err(ErrorKind::AxisWordsUnused { code: 800 });
        }
        return Ok(Parsed::Nothing);
    }
    let inverse = m.feed_mode == FeedMode::InverseTime && m.motion != MotionMode::Rapid;
    if inverse {
        if w.value(F).is_none() {
            return Err(ErrorKind::InverseTimeNeedsF);
        }
    } else if code != 0 && m.feed == 0 {
        return Err(ErrorKind::NoFeed { code: code as u8 });
    }

    let origin = origin_fine(m, offsets, machine);
    let distance = if machine {
        Distance::Absolute
    } else {
        m.distance
    };
    let (target, target_fine) = targets(st, w, distance, &pos, scale, origin)?;
    let mut motion = match m.motion {
        MotionMode::ArcCw | MotionMode::ArcCcw => {
            match arc_motion(st, m, w, &pos, (target, target_fine), scale, used, line_no)? {
                ArcPlan::One(motion) => motion,
                ArcPlan::Turns(mut t, length) => {
                    if inverse {
                        // G93: the feed that runs the whole move (all its turns) in 1/F minutes.
                        let length = u32::try_from(length).map_err(|_| ErrorKind::ArcTooLarge)?;
                        let f = w.value(F).unwrap_or(super::Decimal::int(0));
                        t.set_feed(inverse_time_feed(st, f, length)?);
                    }
                    *pos.blu = target;
                    *pos.fine = target_fine;
                    return Ok(Parsed::Expand(super::Expansion::Turns(t)));
                }
            }
        }
        _ => match line_motion(st, m, *pos.blu, target)? {
            Some(motion) => motion,
            None => {
                // No machine motion, but the programmed position moves (an increment below
                // a BLU).
                *pos.fine = target_fine;
                return Ok(Parsed::Nothing);
            }
        },
    };
    if inverse {
        let f = w.value(F).unwrap_or(super::Decimal::int(0));
        match &mut motion {
            Motion::Linear(l) => l.f = inverse_time_feed(st, f, l.q)?,
            Motion::Arc(a) => a.f = inverse_time_feed(st, f, a.length)?,
            _ => {}
        }
    }
    *pos.blu = target;
    *pos.fine = target_fine;
    Ok(Parsed::Block(Block {
        line: line_no,
        motion,
    }))
}

/// G38.2-G38.5: a G1 move to the target (axis words and a feed required, a move of at least a
/// BLU), handed on as a probing move; the motion mode is then G80, so a following line of axis
/// words alone is refused where LinuxCNC and grbl would probe again (millac never moves a probe
/// without a G38 on the line).
#[allow(clippy::too_many_arguments)]
fn probe_move(
    st: &Settings,
    w: &Words,
    m: &mut Modes,
    pos: Position,
    offsets: &Offsets,
    scale: Scale,
    line_no: u32,
    used: &mut Used,
    kind: Probe,
) -> Result<Parsed, ErrorKind> {
    if !w.has_axes() {
        return Err(ErrorKind::NoAxisWords { code: 380 });
    }
    if m.feed_mode == FeedMode::PerMinute && m.feed == 0 {
        return Err(ErrorKind::NoFeed { code: 38 });
    }
    m.motion = MotionMode::Linear;
    let parsed = motion(st, w, m, pos, offsets, scale, Some(10), line_no, used);
    m.motion = MotionMode::None;
    match parsed? {
        Parsed::Block(b) => Ok(Parsed::Probe(b, kind)),
        _ => Err(ErrorKind::ProbeTarget),
    }
}

/// G93: the feed number that runs `length` BLU in 1/F minutes: f = round(L F q0 / (W0 60)),
/// clamped to 1..=q0 like every feed.
fn inverse_time_feed(st: &Settings, f: super::Decimal, length: u32) -> Result<u32, ErrorKind> {
    if f.is_negative() {
        return Err(ErrorKind::NegativeValue('F'));
    }
    if f.is_zero() {
        return Err(ErrorKind::NoFeed { code: 93 });
    }
    let num = length as i128 * st.q0 as i128;
    let den = st.frame_hz as i128 * 60;
    let v = f
        .mul_ratio_round(num, den)
        .ok_or(ErrorKind::NumberTooLarge('F'))?;
    Ok(v.clamp(1, st.q0 as i128) as u32)
}

/// G20/G21, G17/G18/G19, G90/G91, G40, G54..G59, G61/G61.1/G64 (G64's P and Q, LinuxCNC's
/// blending tolerances, are accepted and not used: the frame runs every block exactly),
/// G98/G99.
fn modal_words(w: &Words, m: &mut Modes, used: &mut Used) -> Result<(), ErrorKind> {
    match w.g[G_UNITS] {
        Some(200) => m.units = Units::Inch,
        Some(210) => m.units = Units::Mm,
        _ => {}
    }
    match w.g[G_PLANE] {
        Some(170) => m.plane = Plane::XY,
        Some(180) => m.plane = Plane::ZX,
        Some(190) => m.plane = Plane::YZ,
        _ => {}
    }
    match w.g[G_DISTANCE] {
        Some(900) => m.distance = Distance::Absolute,
        Some(910) => m.distance = Distance::Incremental,
        _ => {}
    }
    if let Some(410 | 420) = w.g[G_CUTTER] {
        return Err(ErrorKind::NotInDialect(Construct::CutterCompensation));
    }
    if let Some(g) = w.g[G_COORD] {
        m.coord = ((g - 540) / 10) as u8;
    }
    match w.g[G_PATH] {
        Some(610) => m.path = PathMode::ExactPath,
        Some(611) => m.path = PathMode::ExactStop,
        Some(640) => {
            used.take(P);
            used.take(Q);
            m.path = PathMode::Blend;
        }
        _ => {}
    }
    match w.g[G_RETURN] {
        Some(980) => m.retract = Retract::Initial,
        Some(990) => m.retract = Retract::RPlane,
        _ => {}
    }
    Ok(())
}

/// F (to the feed number, in the line's units; in G93 the line's own F), S (rpm) and M3/M4/M5.
fn feed_and_spindle(
    st: &Settings,
    w: &Words,
    m: &mut Modes,
    scale: Scale,
    used: &mut Used,
) -> Result<(), ErrorKind> {
    used.take(F);
    used.take(S);
    if let Some(fv) = w.value(F) {
        if fv.is_negative() {
            return Err(ErrorKind::NegativeValue('F'));
        }
        if m.feed_mode == FeedMode::PerMinute {
            m.feed = feed_number(st, fv, scale.per).ok_or(ErrorKind::NumberTooLarge('F'))?;
        }
    }
    if let Some(sv) = w.value(S) {
        if sv.is_negative() {
            return Err(ErrorKind::NegativeValue('S'));
        }
        m.spindle_rpm = match sv.mul_ratio_round(1, 1).map(u32::try_from) {
            Some(Ok(v)) => v,
            _ => return Err(ErrorKind::NumberTooLarge('S')),
        };
    }
    match w.m[M_SPINDLE] {
        Some(30) => m.spindle = Spindle::Cw,
        Some(40) => m.spindle = Spindle::Ccw,
        Some(50) => m.spindle = Spindle::Off,
        _ => {}
    }
    Ok(())
}

/// G0..G3, G80: sets the motion mode; returns the motion word of the line, if any.
fn motion_mode(w: &Words, m: &mut Modes) -> Option<Code> {
    let word = w.g[G_MOTION];
    match word {
        Some(0) => m.motion = MotionMode::Rapid,
        Some(10) => m.motion = MotionMode::Linear,
        Some(20) => m.motion = MotionMode::ArcCw,
        Some(30) => m.motion = MotionMode::ArcCcw,
        Some(800) => m.motion = MotionMode::None,
        Some(c) => {
            if let Some(k) = CycleKind::of_code(c) {
                m.motion = MotionMode::Cycle(k);
            }
        }
        None => {}
    }
    // A series of cycles ends with the cycle mode: its initial level is forgotten.
    if !matches!(m.motion, MotionMode::Cycle(_)) {
        m.cycle.il = None;
    }
    word
}

/// The G code number of a motion mode (for the error messages and `$G`).
pub const fn motion_code(mode: MotionMode) -> u16 {
    match mode {
        MotionMode::Rapid => 0,
        MotionMode::Linear => 1,
        MotionMode::ArcCw => 2,
        MotionMode::ArcCcw => 3,
        MotionMode::None => 80,
        MotionMode::Cycle(k) => k.code(),
    }
}

/// G4 P<seconds>: a dwell of P * W0 frames (none for zero frames).
fn dwell_block(
    st: &Settings,
    w: &Words,
    line_no: u32,
    used: &mut Used,
) -> Result<Parsed, ErrorKind> {
    if w.has_axes() {
        return Err(ErrorKind::DwellWithAxes);
    }
    used.take(P);
    let pv = w.value(P).ok_or(ErrorKind::DwellNeedsP)?;
    if pv.is_negative() {
        return Err(ErrorKind::NegativeValue('P'));
    }
    let frames = match pv
        .mul_ratio_round(st.frame_hz as i128, 1)
        .map(u32::try_from)
    {
        Some(Ok(v)) => v,
        _ => return Err(ErrorKind::NumberTooLarge('P')),
    };
    // A dwell of zero frames is no block (the frame never sees an empty dwell).
    if frames == 0 {
        return Ok(Parsed::Nothing);
    }
    Ok(Parsed::Block(Block {
        line: line_no,
        motion: Motion::Dwell(Dwell { frames }),
    }))
}

/// The programmed target, exact, and the machine target, its rounding (an axis without a word
/// stays where the machine is). An absolute word is a program coordinate: the machine's is the
/// word plus `origin` (fine units).
fn targets(
    st: &Settings,
    w: &Words,
    distance: Distance,
    position: &Position,
    scale: Scale,
    origin: [i128; 3],
) -> Result<([i32; 3], [i128; 3]), ErrorKind> {
    let mut target = *position.blu;
    let mut target_fine = *position.fine;
    for k in 0..3 {
        let Some(v) = w.value(AXES + k) else { continue };
        let overflow = ErrorKind::TargetOverflow { axis: axis_name(k) };
        let v = to_fine(v, scale.fine).ok_or(overflow)?;
        let t = match distance {
            Distance::Absolute => v.checked_add(origin[k]).ok_or(overflow)?,
            Distance::Incremental => target_fine[k].checked_add(v).ok_or(overflow)?,
        };
        target_fine[k] = t;
        target[k] = fine_to_blu(st, t).ok_or(overflow)?;
    }
    Ok((target, target_fine))
}

/// G0/G1 from `pos` to `target`: the rapid or line, or None when the machine does not move.
fn line_motion(
    st: &Settings,
    m: &Modes,
    pos: [i32; 3],
    target: [i32; 3],
) -> Result<Option<Motion>, ErrorKind> {
    check_soft(st, target)?;
    let (steps, signs) =
        crate::nc::steps_and_signs([0, 1, 2].map(|k| target[k] as i64 - pos[k] as i64));
    let sum: u128 = steps.iter().map(|&s| s as u128 * s as u128).sum();
    if sum == 0 {
        return Ok(None);
    }
    if m.motion == MotionMode::Rapid {
        return Ok(Some(Motion::Rapid(Rapid { steps, signs })));
    }
    // q = L must fit the DDA's 32-bit sums (see `Q_MAX`).
    let q = match u64::try_from(sum).map(isqrt) {
        Ok(q) if q <= Q_MAX as u64 => (q as u32).max(1),
        _ => return Err(ErrorKind::MoveTooLong),
    };
    Ok(Some(Motion::Linear(Linear {
        steps,
        signs,
        q,
        f: m.feed,
        decel: false,
        f_floor: 0,
        decel_below: 0,
        ramp: 0,
        dir: [1; 3],
    })))
}

/// G2/G3 from the position to `target` in the plane in force: the centre (R, or I/J/K from the
/// exact programmed start, rounded once), then the planned arc within the soft limits. The offset
/// along the axis normal to the plane must be absent or zero (FreeCAD's grbl post writes `K0` on
/// every G17 arc; grbl ignores any K there, LinuxCNC refuses every K: millac takes the zero, which
/// says nothing, and refuses another value, which would mean a centre off the plane). P is
/// the number of turns (LinuxCNC's): P1 the arc as programmed, P2 one full circle more, and so on.
#[allow(clippy::too_many_arguments)]
fn arc_motion(
    st: &Settings,
    m: &Modes,
    w: &Words,
    position: &Position,
    (target, end_fine): ([i32; 3], [i128; 3]),
    scale: Scale,
    used: &mut Used,
    line_no: u32,
) -> Result<ArcPlan, ErrorKind> {
    let pos = *position.blu;
    let (ia, ib) = m.plane.axes();
    let third = 3 - ia - ib;
    for i in [R, OFFSETS + ia, OFFSETS + ib] {
        used.take(i);
    }
    let turns = match w.value(P) {
        None => 1,
        Some(v) => {
            used.take(P);
            match v.as_integer() {
                Some(n) if (1..=crate::nc::MAX_TURNS as i128).contains(&n) => n as u32,
                _ => return Err(ErrorKind::ArcTurns),
            }
        }
    };
    if turns > 1 && w.value(R).is_some() {
        return Err(ErrorKind::ArcTurns);
    }
    match w.value(OFFSETS + third) {
        Some(v) if !v.is_zero() => {
            return Err(ErrorKind::UnusedWord(
                words::LETTERS.get(OFFSETS + third).copied().unwrap_or('?'),
            ))
        }
        _ => used.take(OFFSETS + third),
    }
    let has_offsets = w.value(OFFSETS + ia).is_some() || w.value(OFFSETS + ib).is_some();
    let centre = match (w.value(R).is_some(), has_offsets) {
        (true, true) => return Err(ErrorKind::ArcRadiusAndOffsets),
        (true, false) => {
            // The exact programmed start, end and radius, in BLU as floats.
            length(w, R, scale.per)?;
            let per_blu = fine_of_blu(st, 1) as f64;
            let blu = |f: i128| f as f64 / per_blu;
            let r = w.value(R).and_then(|v| to_fine(v, scale.fine)).unwrap_or(0);
            Centre::Radius {
                r: blu(r),
                chord: [ia, ib].map(|k| blu(end_fine[k] - position.fine[k])),
                start_off: [0, 1].map(|i| {
                    let k = [ia, ib][i];
                    blu(position.fine[k] - fine_of_blu(st, pos[k]))
                }),
            }
        }
        (false, true) => {
            // The centre is the programmed start plus I, J, K, exact, rounded once.
            let mut off = [0i64; 2];
            for (o, k) in off.iter_mut().zip([ia, ib]) {
                length(w, OFFSETS + k, scale.per)?;
                let letter = words::LETTERS.get(OFFSETS + k).copied().unwrap_or('?');
                let too_large = ErrorKind::NumberTooLarge(letter);
                let v = match w.value(OFFSETS + k) {
                    Some(v) => to_fine(v, scale.fine).ok_or(too_large)?,
                    None => 0,
                };
                let c = position.fine[k].checked_add(v).ok_or(too_large)?;
                let c = fine_to_blu(st, c).ok_or(ErrorKind::ArcTooLarge)?;
                *o = c as i64 - pos[k] as i64;
            }
            Centre::Offsets(off)
        }
        (false, false) => {
            return Err(ErrorKind::ArcNeedsCentre {
                code: motion_code(m.motion) as u8,
            })
        }
    };
    let ccw = m.motion == MotionMode::ArcCcw;
    check_soft(st, target)?;
    if let (true, Centre::Offsets(off)) = (turns > 1, centre) {
        let (t, length) =
            arc::Turns::new(st, m.plane, ccw, pos, target, off, m.feed, turns, line_no)?;
        return Ok(ArcPlan::Turns(t, length));
    }
    let a = arc::plan(st, m.plane, ccw, pos, target, centre, m.feed)?;
    Ok(ArcPlan::One(Motion::Arc(a)))
}

/// A G2/G3 line planned: one block, or P turns to expand (with the whole move's length in BLU).
enum ArcPlan {
    One(Motion),
    Turns(arc::Turns, u64),
}
