//! Arc planning for G2/G3 (loader task; host tests): centre (I/J/K or R form), radius check,
//! quadrant segmentation into the targets the frame's circular DDA runs, arc length, soft limits
//! of the arc's extent. Integers wherever the result reaches the frame; f64 (libm, identical on
//! host and target) only for the R-form centre before rounding, the radius tolerance and the sweep.

use super::error::{axis_name, ErrorKind};
use super::number::round_sqrt;
#[cfg(doc)]
use crate::nc::MAX_TURNS;
use crate::nc::{Arc, Plane, MAX_SEGMENTS, Q_MAX, R_MAX};
use crate::settings::Settings;

/// How the centre was programmed, in BLU in the plane's (a, b) axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Centre {
    /// Offsets of the centre from the start point (I/J/K, always incremental).
    Offsets([i64; 2]),
    /// R form, exact: the signed radius (positive = the arc of at most 180 degrees, negative =
    /// the larger one), the chord from the programmed start to the programmed end, and the
    /// programmed start's offset from the machine's start point, all in BLU as floats (the
    /// programmed values are not rounded to the lattice before the centre is found: rounding the
    /// ends first moves the centre of a short chord on a long radius by many BLU).
    Radius {
        r: f64,
        chord: [f64; 2],
        start_off: [f64; 2],
    },
}

/// The axis-crossing points (relative to the centre) in counter-clockwise order from +a.
const fn crossing(k: usize, r: i64) -> [i64; 2] {
    match k % 4 {
        0 => [r, 0],
        1 => [0, r],
        2 => [-r, 0],
        _ => [0, -r],
    }
}

/// Quadrant of a non-zero point, half-open counter-clockwise: 0 = [0, 90) degrees, 1 = [90, 180),
/// 2 = [180, 270), 3 = [270, 360).
pub(crate) const fn quadrant(p: [i64; 2]) -> usize {
    let [a, b] = p;
    if a > 0 && b >= 0 {
        0
    } else if a <= 0 && b > 0 {
        1
    } else if a < 0 && b <= 0 {
        2
    } else {
        3
    }
}

/// Counter-clockwise direction signs (a, b) of motion on the circle inside quadrant q.
const fn ccw_dirs(q: usize) -> [i64; 2] {
    match q % 4 {
        0 => [-1, 1],
        1 => [-1, -1],
        2 => [1, -1],
        _ => [1, 1],
    }
}

const fn cross(p: [i64; 2], q: [i64; 2]) -> i128 {
    p[0] as i128 * q[1] as i128 - p[1] as i128 * q[0] as i128
}

const fn dot(p: [i64; 2], q: [i64; 2]) -> i128 {
    p[0] as i128 * q[0] as i128 + p[1] as i128 * q[1] as i128
}

/// Mirror b: turns clockwise travel into counter-clockwise travel (and back).
const fn mirror(p: [i64; 2], cw: bool) -> [i64; 2] {
    if cw {
        [p[0], -p[1]]
    } else {
        p
    }
}

/// The grbl radius tolerance in BLU for a circle of radius `r` BLU:
/// min(max(0.005 mm, 0.001 r), 0.5 mm).
pub(crate) fn tolerance(st: &Settings, r: f64) -> f64 {
    let (num, den) = st.blu.per_mm();
    let mm = num as f64 / den as f64;
    let t = (0.005 * mm).max(0.001 * r);
    t.min(0.5 * mm)
}

fn check_soft(st: &Settings, axis: usize, value: i64) -> Result<(), ErrorKind> {
    let (min, max) = match (st.soft_min.get(axis), st.soft_max.get(axis)) {
        (Some(&a), Some(&b)) => (a, b),
        _ => return Err(ErrorKind::ArcTooLarge),
    };
    if value < min as i64 || value > max as i64 {
        return Err(ErrorKind::SoftLimit {
            axis: axis_name(axis),
            value,
            min,
            max,
        });
    }
    Ok(())
}

/// R form: the centre relative to the exact start, as grbl computes it (h = sqrt(4 r^2 - d^2)
/// along the chord's normal), not rounded. `chord` and `radius` in BLU.
fn centre_from_radius(
    st: &Settings,
    ccw: bool,
    chord: [f64; 2],
    radius: f64,
) -> Result<[f64; 2], ErrorKind> {
    let [x, y] = chord;
    let r = libm::fabs(radius);
    if libm::round(r) == 0.0 {
        return Err(ErrorKind::ArcZeroRadius);
    }
    let d2 = x * x + y * y;
    let chord_len = libm::sqrt(d2);
    let mut disc = 4.0 * r * r - d2;
    if disc < 0.0 {
        if chord_len / 2.0 - r > tolerance(st, r) {
            return Err(ErrorKind::ArcRadiusTooSmall {
                radius: libm::round(r) as i64,
                half_chord: libm::round(chord_len / 2.0) as i64,
            });
        }
        disc = 0.0;
    }
    // grbl: h_x2_div_d = -sqrt(4 r^2 - d^2) / d, negated for CCW and for negative R.
    let mut k = -libm::sqrt(disc) / chord_len;
    if ccw {
        k = -k;
    }
    if radius < 0.0 {
        k = -k;
    }
    let o = [0.5 * (x - y * k), 0.5 * (y + x * k)];
    if !(o[0].abs() < 1e15 && o[1].abs() < 1e15) {
        return Err(ErrorKind::ArcTooLarge);
    }
    Ok(o)
}

/// A G2/G3 with P turns (P > 1): P - 1 full circles about the same centre, then the programmed
/// arc, the third axis moving in proportion to the angle over all of them (LinuxCNC's P word).
/// Validated whole by [`Turns::new`]; expanded one block at a time by [`Turns::next_block`]
/// (the tape emits them as the queue has room, as a canned cycle's). Loader task; host.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Turns {
    line: u32,
    plane: Plane,
    ccw: bool,
    f: u32,
    /// The centre in machine BLU (a, b).
    centre: [i64; 2],
    /// The third axis at the start, its travel over the whole move, the programmed end.
    third0: i64,
    rise: i64,
    end: [i32; 3],
    /// Full circles to make, made so far; the whole angle in nanoradians (an integer, so that a
    /// parsed line compares exactly).
    full: u32,
    made: u32,
    angle_nrad: u64,
    /// Where the next block starts, and whether the last one (the programmed arc) is out.
    at: [i32; 3],
    finished: bool,
}

impl Turns {
    /// Validates a G2/G3 of `turns` (2..=[`MAX_TURNS`]) turns from `start` to `end` (machine
    /// BLU) about the start plus `offsets`: the first full circle (its extent against the soft
    /// limits) and the last arc are planned here, so the expansion cannot fail. Returns it and the
    /// length of the whole move in BLU (for G93's feed).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        st: &Settings,
        plane: Plane,
        ccw: bool,
        start: [i32; 3],
        end: [i32; 3],
        offsets: [i64; 2],
        f: u32,
        turns: u32,
        line: u32,
    ) -> Result<(Turns, u64), ErrorKind> {
        let (ia, ib) = plane.axes();
        let third = 3 - ia - ib;
        let get = |p: [i32; 3], k: usize| p.get(k).copied().unwrap_or(0) as i64;
        let mut t = Turns {
            line,
            plane,
            ccw,
            f,
            centre: [get(start, ia) + offsets[0], get(start, ib) + offsets[1]],
            third0: get(start, third),
            rise: get(end, third) - get(start, third),
            end,
            full: turns - 1,
            made: 0,
            angle_nrad: 0,
            at: start,
            finished: false,
        };
        // The last arc, planned from the start (the plane's geometry is the same after the full
        // circles): its angle is length / q (q x sweep commands, see `plan`), to a few
        // microradians.
        let last = t.arc_to(st, end)?;
        let tau = 2.0 * core::f64::consts::PI;
        let angle = t.full as f64 * tau + last.length as f64 / last.q.max(1) as f64;
        t.angle_nrad = libm::round(angle * 1e9) as u64;
        // The first full circle: its extent (every crossing) within the soft limits.
        t.at = start;
        let first = t.arc_to(st, t.circle_end(1)?)?;
        t.at = start;
        let length = first.length as u64 * t.full as u64 + last.length as u64;
        Ok((t, length))
    }

    /// Where full circle number `k` (1-based) ends: where it starts, the third axis at k full
    /// turns' share of the whole angle.
    fn circle_end(&self, k: u32) -> Result<[i32; 3], ErrorKind> {
        let (ia, ib) = self.plane.axes();
        let tau = 2.0 * core::f64::consts::PI;
        let angle = self.angle_nrad.max(1) as f64 * 1e-9;
        let rise = libm::round(self.rise as f64 * k as f64 * tau / angle) as i64;
        let z = i32::try_from(self.third0 + rise).map_err(|_| ErrorKind::ArcTooLarge)?;
        let mut target = self.at;
        if let Some(t) = target.get_mut(3 - ia - ib) {
            *t = z;
        }
        Ok(target)
    }

    /// The arc from where the expansion stands to `target` about the centre.
    fn arc_to(&mut self, st: &Settings, target: [i32; 3]) -> Result<Arc, ErrorKind> {
        let (ia, ib) = self.plane.axes();
        let get = |p: [i32; 3], k: usize| p.get(k).copied().unwrap_or(0) as i64;
        let off = [
            self.centre[0] - get(self.at, ia),
            self.centre[1] - get(self.at, ib),
        ];
        let arc = plan(
            st,
            self.plane,
            self.ccw,
            self.at,
            target,
            Centre::Offsets(off),
            self.f,
        )?;
        self.at = target;
        Ok(arc)
    }

    /// The next block: the full circles, then the programmed arc; `None` after it. Its feed is
    /// the line's (G93: set for the whole move by the parser).
    pub fn next_block(&mut self, st: &Settings) -> Option<crate::nc::Block> {
        let target = if self.made < self.full {
            self.made += 1;
            self.circle_end(self.made).ok()?
        } else if !self.finished {
            self.finished = true;
            self.end
        } else {
            return None;
        };
        let arc = self.arc_to(st, target).ok()?;
        Some(crate::nc::Block {
            line: self.line,
            motion: crate::nc::Motion::Arc(arc),
        })
    }

    /// Every block is out.
    pub fn done(&self) -> bool {
        self.finished
    }

    /// Sets the feed number of every block (G93: the whole move's).
    pub fn set_feed(&mut self, f: u32) {
        self.f = f;
    }
}

/// Plans one arc from `start` to `end` (machine BLU) and returns the block (decel false).
pub fn plan(
    st: &Settings,
    plane: Plane,
    ccw: bool,
    start: [i32; 3],
    end: [i32; 3],
    centre: Centre,
    f: u32,
) -> Result<Arc, ErrorKind> {
    let (ia, ib) = plane.axes();
    let third = 3 - ia - ib;
    let get = |p: [i32; 3], k: usize| p.get(k).copied().unwrap_or(0) as i64;
    // A helix: the third axis moves in proportion to the angle.
    let helix = get(end, third) - get(start, third);
    let s = [get(start, ia), get(start, ib)];
    let e = [get(end, ia), get(end, ib)];
    let off = match centre {
        Centre::Offsets(o) => o,
        Centre::Radius {
            r,
            chord,
            start_off,
        } => {
            if e == s {
                return Err(ErrorKind::ArcFullCircleRadius);
            }
            let o = centre_from_radius(st, ccw, chord, r)?;
            // The centre rounded once to the lattice, relative to the machine's start.
            [0, 1].map(|k| libm::round(start_off[k] + o[k]) as i64)
        }
    };
    let c = [s[0] + off[0], s[1] + off[1]];
    let p0 = [s[0] - c[0], s[1] - c[1]];
    let p1 = [e[0] - c[0], e[1] - c[1]];
    let fits = |v: i64| i32::try_from(v).is_ok();
    if !(fits(p0[0]) && fits(p0[1]) && fits(p1[0]) && fits(p1[1])) {
        return Err(ErrorKind::ArcTooLarge);
    }
    // |p| < 2^31 per coordinate: squares sum below 2^63.
    let sq = |v: i64| v.unsigned_abs() * v.unsigned_abs();
    let n0 = sq(p0[0]) + sq(p0[1]);
    let n1 = sq(p1[0]) + sq(p1[1]);
    let r = round_sqrt(n0) as i64;
    let r_end = round_sqrt(n1) as i64;
    if r == 0 {
        return Err(ErrorKind::ArcZeroRadius);
    }
    // The frame keeps e = i^2 + j^2 - r0^2 in 32 bits: |e| stays below a few R plus the end's
    // distance from the start's circle (see `nc::Arc`).
    if r > R_MAX as i64 || n1.abs_diff(n0) >= 1 << 30 {
        return Err(ErrorKind::ArcTooLarge);
    }
    let rs = libm::sqrt(n0 as f64);
    let re = libm::sqrt(n1 as f64);
    let tol = tolerance(st, rs);
    // In whole BLU, for the last segment's step back (below); at least the 1 BLU of rounding.
    let tol_blu = (libm::ceil(tol) as i64).max(1);
    if (re - rs).abs() > tol {
        return Err(ErrorKind::ArcEndNotOnCircle {
            start: r,
            end: r_end,
        });
    }

    // Segmentation in counter-clockwise space (clockwise arcs are mirrored in b).
    let cw = !ccw;
    let m0 = mirror(p0, cw);
    let m1 = mirror(p1, cw);
    let q0 = quadrant(m0);
    let q1 = quadrant(m1);
    let same_angle = q0 == q1 && cross(m0, m1) == 0;
    let after = q0 == q1 && cross(m0, m1) > 0;
    let quarter_steps = if after { 0 } else { (q1 + 4 - q0) % 4 };
    let quarter_steps = if quarter_steps == 0 && !after {
        4
    } else {
        quarter_steps
    };
    let end_on_axis = m1[0] == 0 || m1[1] == 0;
    let n_cross = if end_on_axis && quarter_steps > 0 {
        quarter_steps - 1
    } else {
        quarter_steps
    };

    let mut targets = [[0i32; 2]; MAX_SEGMENTS];
    let mut prev = m0;
    for t in 0..=n_cross {
        let (point, quad) = if t < n_cross {
            (crossing(q0 + t + 1, r), q0 + t)
        } else {
            (m1, q0 + n_cross)
        };
        let dirs = ccw_dirs(quad);
        // A segment runs monotonically along the circle. Only the last one may step back, by no
        // more than the radius tolerance: an end point that is off the start's circle (rounding,
        // or within grbl's tolerance) can lie a BLU or so outside the last crossing, and the
        // frame's segment counters still end it exactly (the DDA moves each axis towards the
        // target; the path stays in the band between the start and the end radius).
        let slack = if t == n_cross { tol_blu } else { 0 };
        let back = |d: i64, dir: i64| if d * dir < 0 { d.abs() } else { 0 };
        if back(point[0] - prev[0], dirs[0]) > slack || back(point[1] - prev[1], dirs[1]) > slack {
            return Err(ErrorKind::ArcEndUnreachable {
                start: r,
                end: r_end,
            });
        }
        let real = mirror(point, cw);
        if t < n_cross {
            check_soft(st, ia, c[0] + real[0])?;
            check_soft(st, ib, c[1] + real[1])?;
        }
        match (
            targets.get_mut(t),
            i32::try_from(real[0]),
            i32::try_from(real[1]),
        ) {
            (Some(slot), Ok(a), Ok(b)) => *slot = [a, b],
            _ => return Err(ErrorKind::ArcTooLarge),
        }
        prev = point;
    }

    let sweep = if same_angle {
        2.0 * core::f64::consts::PI
    } else {
        let a = libm::atan2(cross(m0, m1) as f64, dot(m0, m1) as f64);
        if a <= 0.0 {
            a + 2.0 * core::f64::consts::PI
        } else {
            a
        }
    };
    // The commands the arc takes, one BLU of path each: a helix's path is sqrt(plane^2 + helix^2),
    // and the DDA's modulus q = R x path / plane slows the plane to its share. The plane takes q x
    // sweep commands (q / max(|i|, |j|) per pulse of the faster axis), so the third axis's DDA
    // runs over that many: the two end together whatever q's rounding.
    let plane_len = r as f64 * sweep;
    let q = if helix == 0 {
        r as f64
    } else {
        let path = libm::sqrt(plane_len * plane_len + (helix * helix) as f64);
        libm::round(r as f64 * path / plane_len.max(1.0)).max(r as f64)
    };
    let length = libm::round(q * sweep)
        .max(helix.unsigned_abs() as f64)
        .max(1.0);
    if length > u32::MAX as f64 || q > Q_MAX as f64 {
        return Err(ErrorKind::ArcTooLarge);
    }
    let helix = i32::try_from(helix).map_err(|_| ErrorKind::ArcTooLarge)?;
    Ok(Arc {
        plane,
        ccw,
        start: [p0[0] as i32, p0[1] as i32],
        r: r as u32,
        q: q as u32,
        helix,
        targets,
        n_targets: (n_cross + 1) as u8,
        f,
        decel: false,
        f_floor: 0,
        decel_below: 0,
        ramp: 0,
        length: length as u32,
    })
}
