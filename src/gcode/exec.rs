//! The semantics of one G-code line (loader task; host tests): modal words, unit conversion,
//! targets, soft limits and the block it produces. Runs on copies of the parser state.

use super::arc::{self, Centre};
use super::error::{axis_name, ErrorKind};
use super::words::{
    self, Words, AXES, F, G_DISTANCE, G_DWELL, G_MOTION, G_PLANE, G_UNITS, M_SPINDLE, M_STOP,
    OFFSETS, P, R, S,
};
use super::{feed_number, Distance, Modes, MotionMode, Parsed, Spindle, Units};
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

/// Fine units per millimetre: 10^-19 mm is an exact common unit of every length word, in mm or in
/// inches (a word has at most 18 decimals, [`super::number::MAX_DECIMALS`], and an inch is 25.4 mm).
pub const FINE_PER_MM: i128 = 10_000_000_000_000_000_000;
/// Fine units per inch (25.4 mm).
pub const FINE_PER_INCH: i128 = 254 * 1_000_000_000_000_000_000;

/// The parser's position: the machine's in BLU and the programmed one, exact, in fine units.
pub struct Position<'a> {
    pub blu: &'a mut [i32; 3],
    pub fine: &'a mut [i128; 3],
}

/// Fine units of `v` program units (`per_fine`: fine units per unit), exact; None on overflow.
fn to_fine(v: super::Decimal, per_fine: i128) -> Option<i128> {
    let scale = super::number::pow10(v.scale as u32)?;
    v.mantissa.checked_mul(per_fine.checked_div(scale)?)
}

/// The machine coordinate of a fine position: BLU, rounded half away from zero (the same rounding
/// as a word converted directly), or None when it does not fit i32.
fn fine_to_blu(st: &Settings, fine: i128) -> Option<i32> {
    let (num, den) = st.blu.per_mm();
    let n = fine.checked_mul(num as i128)?;
    let d = (den as i128).checked_mul(FINE_PER_MM)?;
    i32::try_from(super::number::div_round(n, d)?).ok()
}

/// The fine position of a machine coordinate: exact (1 BLU = 2.54e16 or 1e16 fine units).
pub fn fine_of_blu(st: &Settings, blu: i32) -> i128 {
    let (num, den) = st.blu.per_mm();
    blu as i128 * FINE_PER_MM * den as i128 / num as i128
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

fn reject_words(w: &Words, list: &[usize]) -> Result<(), ErrorKind> {
    for &i in list {
        if w.value(i).is_some() {
            return Err(ErrorKind::UnusedWord(
                words::LETTERS.get(i).copied().unwrap_or('?'),
            ));
        }
    }
    Ok(())
}

const ARC_WORDS: [usize; 4] = [R, OFFSETS, OFFSETS + 1, OFFSETS + 2];

/// How the line's length words convert: BLU per program unit (a ratio) and fine units per
/// program unit.
#[derive(Clone, Copy)]
struct Scale {
    per: (i64, i64),
    fine: i128,
}

/// The semantics of one line on the parser's state: modal words, feed and spindle, then end,
/// dwell or motion. `m` and `position` are the caller's copies (committed only on `Ok`).
pub fn execute(
    st: &Settings,
    m: &mut Modes,
    position: Position,
    line_no: u32,
    text: &str,
) -> Result<Parsed, ErrorKind> {
    let w = words::lex(text)?;

    // Modal words first: they apply to the whole line, wherever they stand.
    modal_words(&w, m);
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
    feed_and_spindle(st, &w, m, scale)?;
    let motion_word = motion_mode(&w, m);

    let mut has_axes = false;
    for k in 0..3 {
        has_axes |= length(&w, AXES + k, scale.per)?.is_some();
    }
    let dwell = w.g[G_DWELL].is_some();

    if w.m[M_STOP].is_some() {
        return end(&w, has_axes || dwell);
    }
    if dwell {
        return dwell_block(st, &w, has_axes, line_no);
    }
    reject_words(&w, &[P])?;

    // A motion runs when the line has axis words or names a motion mode (grbl).
    if !has_axes && motion_word.is_none() {
        reject_words(&w, &ARC_WORDS)?;
        return Ok(Parsed::Nothing);
    }
    let code = motion_code(m.motion);
    if code != 0 && m.feed == 0 {
        return Err(ErrorKind::NoFeed { code });
    }

    let (target, target_fine) = targets(st, &w, m.distance, &position, scale)?;
    let motion = match m.motion {
        MotionMode::Rapid | MotionMode::Linear => {
            match line_motion(st, m, &w, *position.blu, target)? {
                Some(motion) => motion,
                None => {
                    // No machine motion, but the programmed position moves (an increment below
                    // a BLU).
                    *position.fine = target_fine;
                    return Ok(Parsed::Nothing);
                }
            }
        }
        MotionMode::ArcCw | MotionMode::ArcCcw => arc_motion(st, m, &w, &position, target, scale)?,
    };
    *position.blu = target;
    *position.fine = target_fine;
    Ok(Parsed::Block(Block {
        line: line_no,
        motion,
    }))
}

/// G20/G21, G17/G18/G19, G90/G91. (G94, feed per minute, is the only feed mode: nothing to do.)
fn modal_words(w: &Words, m: &mut Modes) {
    match w.g[G_UNITS] {
        Some(20) => m.units = Units::Inch,
        Some(21) => m.units = Units::Mm,
        _ => {}
    }
    match w.g[G_PLANE] {
        Some(17) => m.plane = Plane::XY,
        Some(18) => m.plane = Plane::ZX,
        Some(19) => m.plane = Plane::YZ,
        _ => {}
    }
    match w.g[G_DISTANCE] {
        Some(90) => m.distance = Distance::Absolute,
        Some(91) => m.distance = Distance::Incremental,
        _ => {}
    }
}

/// F (to the feed number, in the line's units), S (rpm) and M3/M4/M5.
fn feed_and_spindle(
    st: &Settings,
    w: &Words,
    m: &mut Modes,
    scale: Scale,
) -> Result<(), ErrorKind> {
    if let Some(fv) = w.value(F) {
        if fv.is_negative() {
            return Err(ErrorKind::NegativeValue('F'));
        }
        m.feed = feed_number(st, fv, scale.per).ok_or(ErrorKind::NumberTooLarge('F'))?;
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
        Some(3) => m.spindle = Spindle::Cw,
        Some(4) => m.spindle = Spindle::Ccw,
        Some(5) => m.spindle = Spindle::Off,
        _ => {}
    }
    Ok(())
}

/// G0..G3: sets the motion mode; returns the motion word of the line, if any.
fn motion_mode(w: &Words, m: &mut Modes) -> Option<u8> {
    let word = w.g[G_MOTION];
    match word {
        Some(0) => m.motion = MotionMode::Rapid,
        Some(1) => m.motion = MotionMode::Linear,
        Some(2) => m.motion = MotionMode::ArcCw,
        Some(3) => m.motion = MotionMode::ArcCcw,
        _ => {}
    }
    word
}

/// The G code number of a motion mode (for the error messages).
const fn motion_code(mode: MotionMode) -> u8 {
    match mode {
        MotionMode::Rapid => 0,
        MotionMode::Linear => 1,
        MotionMode::ArcCw => 2,
        MotionMode::ArcCcw => 3,
    }
}

/// M2/M30: the end of the program, on a line without motion.
fn end(w: &Words, moves: bool) -> Result<Parsed, ErrorKind> {
    if moves {
        return Err(ErrorKind::EndWithMotion);
    }
    reject_words(w, &[P, R, OFFSETS, OFFSETS + 1, OFFSETS + 2])?;
    Ok(Parsed::End)
}

/// G4 P<seconds>: a dwell of P * W0 frames (none for zero frames).
fn dwell_block(
    st: &Settings,
    w: &Words,
    has_axes: bool,
    line_no: u32,
) -> Result<Parsed, ErrorKind> {
    if has_axes {
        return Err(ErrorKind::DwellWithAxes);
    }
    reject_words(w, &ARC_WORDS)?;
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
/// stays where the machine is).
fn targets(
    st: &Settings,
    w: &Words,
    distance: Distance,
    position: &Position,
    scale: Scale,
) -> Result<([i32; 3], [i128; 3]), ErrorKind> {
    let mut target = *position.blu;
    let mut target_fine = *position.fine;
    for k in 0..3 {
        let Some(v) = w.value(AXES + k) else { continue };
        let overflow = ErrorKind::TargetOverflow { axis: axis_name(k) };
        let v = to_fine(v, scale.fine).ok_or(overflow)?;
        let t = match distance {
            Distance::Absolute => v,
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
    w: &Words,
    pos: [i32; 3],
    target: [i32; 3],
) -> Result<Option<Motion>, ErrorKind> {
    reject_words(w, &ARC_WORDS)?;
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
/// exact programmed start, rounded once), then the planned arc within the soft limits.
fn arc_motion(
    st: &Settings,
    m: &Modes,
    w: &Words,
    position: &Position,
    target: [i32; 3],
    scale: Scale,
) -> Result<Motion, ErrorKind> {
    let pos = *position.blu;
    let (ia, ib) = m.plane.axes();
    let third = 3 - ia - ib;
    reject_words(w, &[OFFSETS + third])?;
    let has_offsets = w.value(OFFSETS + ia).is_some() || w.value(OFFSETS + ib).is_some();
    let centre = match (w.value(R).is_some(), has_offsets) {
        (true, true) => return Err(ErrorKind::ArcRadiusAndOffsets),
        (true, false) => Centre::Radius(length(w, R, scale.per)?.unwrap_or(0)),
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
                code: motion_code(m.motion),
            })
        }
    };
    let a = arc::plan(
        st,
        m.plane,
        m.motion == MotionMode::ArcCcw,
        pos,
        target,
        centre,
        m.feed,
    )?;
    check_soft(st, target)?;
    Ok(Motion::Arc(a))
}
