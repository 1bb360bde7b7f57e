//! The oracle (host; the evaluation calls it with the path of a program): the fastest feed schedule
//! along a tool path that keeps the force F <= F0 and the torque T <= T0 everywhere, never exceeds
//! the ceiling of each point (the programmed feed, or FRM when the AC's ceiling setting says so:
//! the caller gives it) and changes the feed by at most the machine's acceleration on each move
//! (up and down: the fastest any schedule can change it, since the frame ramps every feed change,
//! the AC's included, so an AC's fdot_m above it has no effect), computed with full knowledge of the stock. Its
//! time is the bound no schedule within F0, T0 and the ceilings can beat.
//!
//! Algorithm:
//! 1. Walk the path once, cutting the stock as the process does (the removal does not depend on
//!    the feed, so the engagement is computed once). At each point, with the feed direction of
//!    the segment arriving there, scan the spindle angle over one tooth pitch (1 degree steps or
//!    finer) and keep the peak resultant force and peak torque. The feed per tooth along the
//!    path `c = v / (z rpm / 60)` splits into the side chip `c_xy = c * XY share` and, moving
//!    down, the end-face chip `c_z = c * (-Z share)`; the peaks include the end teeth (see
//!    [`crate::process`]), so a plunge into material is limited by T0 (and by F0 where the end
//!    face is partly engaged). The side chips are the process' (`min(c, extent) cos(alpha)`,
//!    the material behind each edge measured up to the XY feed per tooth at the point's
//!    ceiling, the largest the schedule can take there). With a constant Ks every tooth's force
//!    is linear in `c` where no chip is limited by the material behind its edge, so the peaks
//!    are computed once at unit `c` and the safe feed at the point is
//!    `min(F0 / F_per_c, T0 / T_per_c) * z * rpm / 60`; capped by the programmed feed of the
//!    point. Where a chip is limited (a tooth entering a wall) the peaks grow more slowly than
//!    `c`: the point's limit is searched (the ceiling's `c` doubled until over a limit, then
//!    bisection) and its peaks are re-evaluated at the scheduled feed along a second walk (what
//!    the peaks read of the stock, each tooth's contact at each angle, does not depend on the
//!    feed: it is read once per point and summed at every feed tried). With Kienzle's Ks(h)
//!    (exponent m > 0) every tooth's force is `Ks1 a h^(1-m)` with
//!    `h` proportional to `c`, so all teeth scale by the same `c^(1-m)` except those whose chip
//!    is below the clamp [`crate::H_MIN_MM`] (near entry and exit angles), which scale linearly,
//!    faster than `c^(1-m)` going up. So the point's limit is found by evaluation: the peaks at
//!    the programmed feed; if over a limit, the `c^(1-m)` estimate of the feed that meets it,
//!    re-evaluated and lowered again (by the same rule: going down, every tooth's force falls by
//!    at least the factor `c^(1-m)` predicts, so the torque, a sum of positive tooth torques,
//!    meets T0 after one step; the resultant force is checked the same way, up to 50 steps)
//!    until the evaluated peaks are within F0 and T0. The reported peaks are re-evaluated at the
//!    scheduled feed along a second walk of the path.
//! 2. Forward and backward passes of the classic velocity-profile algorithm:
//!    `v_i <= sqrt(v_{i-1}^2 + 2 a_i s_i)` and `v_i <= sqrt(v_{i+1}^2 + 2 a_{i+1} s_{i+1})`, with
//!    `a_i` the acceleration of the move arriving at point i.
//! 3. Time: constant acceleration between points, `sum 2 s_i / (v_{i-1} + v_i)`.
//!
//! Direction: the segment arriving at the point (one pulse, as the path comes from the pulses),
//! except where the tip moved down along a straight stretch (its middle point within 2 BLU of the
//! chord) of the last [`DIR_WINDOW_MM`] of the path: there the direction is that of the window (a ramp's pulses alternate between the axes, so one pulse's
//! direction would see the whole feed in Z at one point and in XY at the next; the process
//! averages over one tooth period in the same way). Moves without Z descent keep the one-pulse
//! direction, so side-cutting figures are the same as before the end face was modelled.
//!
//! Approximations: limits are enforced at the path points only (fine spacing, e.g. 1..100 BLU,
//! keeps the error small); the peak is over continuous spindle angles (the AC sees 1 kHz samples,
//! so it can only do worse); the feed per tooth is taken from the path direction (the process
//! averages it over one tooth period, which matters only at sharp corners); the noise and the
//! transducer quantisation are ignored. No axial limit: the tool's strength is given as F (bending)
//! and T (twist) only, and the transducer does not measure the axial force. The frame's
//! exponential deceleration at the end of blocks with the paper's deceleration flag is not ramped
//! (it can slow down faster than the acceleration): it only slows a schedule at a block end, and
//! the bound does not slow there.
use crate::process::{Contact, Cutter, EndCut};
use crate::{validate, CutError, Material, Stock, Tool, MM_PER_BLU, MM_S_PER_IPM};

/// One point of the tool path: tool tip position (BLU), the ceiling of the schedule there (ipm:
/// the programmed feed of the move arriving at it, or FRM) and that move's acceleration limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OraclePoint {
    pub pos_blu: [i64; 3],
    pub feed_ipm: f64,
    /// The fastest feed change on the move arriving here, ipm/s (up and down): the machine's path
    /// acceleration in that direction.
    pub accel_ipm_s: f64,
    /// The length of the programmed path from the point before to this one, mm (None: the
    /// straight distance between the two positions). The positions of a pulse train are a
    /// staircase (at a low feed the axes step in different frames): its length exceeds the
    /// path's, by up to the sum of the axes' over the diagonal, and a schedule timed along it
    /// would be slower than the machine running the program.
    pub step_mm: Option<f64>,
}

/// The constraints of the schedule.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleLimits {
    /// F0, N.
    pub f0_n: f64,
    /// T0, N*m.
    pub t0_nm: f64,
    /// Start and end at rest (feed 0) instead of at the point limits.
    pub from_rest: bool,
    /// Path length between the points evaluated in full, mm (0: every point of the path). The
    /// points between, on a straight stretch of one move, take the figures of the key point
    /// before or after them, whichever allows the lower feed, and the stock is cut along the
    /// chord between key points; a corner, a change of move or the path's ends are always key
    /// points. [`ORACLE_STRIDE_MM`] by default.
    pub stride_mm: f64,
}

/// The default [`OracleLimits::stride_mm`]: 0.2 mm (79 BLU, under the stock's default cell of
/// 0.25 mm): about 15 to 35 times fewer points evaluated than every pulse (docs/dev/simulation.md,
/// "The bound", gives its error against every point; `qemu/tests/bound.rs` tests it).
pub const ORACLE_STRIDE_MM: f64 = 0.2;

impl OracleLimits {
    /// The paper's constraints for `tool`: F0, T0 = 0.9 x permissible ("around 90 percent"),
    /// starting and ending at rest. (The AC core's defaults are the same numbers; millac-qemu's
    /// tests check it, the plant does not know the controller.)
    pub fn for_tool(tool: &Tool) -> OracleLimits {
        OracleLimits {
            f0_n: 0.9 * tool.f_max_n,
            t0_nm: 0.9 * tool.t_max_nm,
            from_rest: true,
            stride_mm: ORACLE_STRIDE_MM,
        }
    }
}

/// The schedule. Per-point vectors have the length of the path.
#[derive(Clone, Debug, PartialEq)]
pub struct OracleResult {
    /// Time along the whole path, s (infinite when some limit is 0 on a segment of length > 0).
    pub time_s: f64,
    /// Feed at each point, ipm.
    pub feed_profile: Vec<f64>,
    /// Largest feed allowed by force, torque and the ceiling at each point (before the
    /// acceleration passes), ipm.
    pub limit_ipm: Vec<f64>,
    /// Largest feed allowed by force and torque alone at each point, ipm (infinite where the tool
    /// cuts nothing): the smallest is the largest constant feed safe along the whole path.
    pub cut_limit_ipm: Vec<f64>,
    /// Peak force and torque at each point at the scheduled feed, N and N*m.
    pub f_peak_n: Vec<f64>,
    pub t_peak_nm: Vec<f64>,
    /// The stock as the path left it.
    pub stock: Stock,
}

/// Path length over which a descending tip's direction is averaged, mm (see the module docs).
pub const DIR_WINDOW_MM: f64 = 0.25;

/// With Kienzle's Ks(h), the feed (ipm) the search for a point's force and torque limit starts
/// from: far above any feed a cut allows, so the limit does not depend on the ceiling.
const KIENZLE_PROBE_IPM: f64 = 10_000.0;

/// Peak resultant force (N) and peak torque (N*m) over one tooth pitch of spindle angles.
#[derive(Clone, Copy, Debug, Default)]
struct Peak {
    f: f64,
    t: f64,
    /// The end face met material.
    engaged: bool,
    /// Some side tooth's chip was limited by the material behind its edge (not linear in c).
    capped: bool,
}

/// The teeth's contacts with the stock at the spindle angles [`peak`] scans (one tooth pitch),
/// for one tip, feed direction, reach and end face: what the peaks read of the stock, which does
/// not depend on the feed, read once for a point's search over the feed (the same bytes as
/// reading the stock at every evaluation).
struct Contacts {
    flutes: usize,
    /// Per angle, per tooth.
    teeth: Vec<Contact>,
    /// The end face can cut (see [`Cutter::contacts`]).
    end_ok: bool,
    /// The end face's material test (None: no end cut at this point).
    z_min: Option<f64>,
}

impl Contacts {
    /// The contacts of the tool with its tip at `tip` moving along `u`, the side chip's extent
    /// measured up to `reach` (mm), the end face against the material above `z_min` (None: the
    /// peaks are asked for without an end cut).
    fn new(
        cut: &Cutter,
        stock: &Stock,
        tip: [f64; 3],
        u: [f64; 2],
        reach: f64,
        z_min: Option<f64>,
    ) -> Contacts {
        let flutes = cut.flutes as usize;
        let pitch = std::f64::consts::TAU / cut.flutes as f64;
        let steps = (360 / cut.flutes).max(8);
        let mut teeth = vec![Contact::default(); steps as usize * flutes];
        let mut end_ok = false;
        // What the teeth can read near the tool, once for all the angles.
        let near = cut.near_top(stock, tip);
        // The end face's cells read once for all the angles, where it can meet material.
        let mask = z_min
            .filter(|&z| z < near)
            .map(|z| stock.disc_mask(tip[0], tip[1], cut.r_mm, z));
        for (i, at) in teeth.chunks_exact_mut(flutes).enumerate() {
            let theta = pitch * i as f64 / steps as f64;
            end_ok = cut.contacts(stock, tip, theta, u, reach, z_min, near, mask.as_ref(), at);
        }
        Contacts {
            flutes,
            teeth,
            end_ok,
            z_min,
        }
    }
}

/// The peaks at side feed per tooth `c` (the chip's extent measured up to the contacts' reach,
/// mm) and end cut `end` (its `z_min` the contacts' when it cuts).
fn peak(cut: &Cutter, contacts: &Contacts, c: f64, end: EndCut) -> Peak {
    debug_assert!(end.cz <= 0.0 || contacts.z_min == Some(end.z_min));
    let mut pk = Peak::default();
    for at in contacts.teeth.chunks_exact(contacts.flutes) {
        let r = cut.forces_of(at, contacts.end_ok, c, end, None, None);
        if !surely_below(r.fx, r.fy, pk.f) {
            pk.f = pk.f.max(r.fx.hypot(r.fy));
        }
        pk.t = pk.t.max(r.t);
        pk.engaged |= r.end_engaged;
        pk.capped |= r.capped;
    }
    pk
}

/// Whether the peaks at side feed per tooth `c` and end cut `end` (see [`peak`]) are within `f0`
/// and `t0` (both > 0): the first angle over a limit answers (a NaN counts as within, as the
/// peaks' `f64::max` ignores it).
fn peak_within(cut: &Cutter, contacts: &Contacts, c: f64, end: EndCut, f0: f64, t0: f64) -> bool {
    debug_assert!(end.cz <= 0.0 || contacts.z_min == Some(end.z_min));
    contacts.teeth.chunks_exact(contacts.flutes).all(|at| {
        let r = cut.forces_of(at, contacts.end_ok, c, end, None, None);
        let over = |v: f64, limit: f64| v > limit;
        !over(r.t, t0) && (surely_below(r.fx, r.fy, f0) || !over(r.fx.hypot(r.fy), f0))
    })
}

/// Whether `hypot(x, y) <= f` is sure without computing it: `|x| + |y|`, which is at least the
/// hypotenuse, is below `f` by far more than the roundings of either.
#[inline]
fn surely_below(x: f64, y: f64, f: f64) -> bool {
    x.abs() + y.abs() <= f * (1.0 - 1e-12)
}

/// Whether `m` lies within 1 BLU of the chord from `w` to `w + d`: a point of the pulse train
/// that a capsule along the chord cuts as its own (a staircase along a straight line stays within
/// a BLU of it; an arc's points leave its chord where the sagitta grows past a BLU).
fn on_chord(m: &[f64; 3], w: &[f64; 3], d: &[f64; 3]) -> bool {
    off_line2(m, w, d, true) <= MM_PER_BLU * MM_PER_BLU
}

/// Whether `m` lies within 2 BLU of the line through `w` along `d` (a window of the path without
/// a corner: a plunge followed by a side move is not a ramp).
fn straight(m: &[f64; 3], w: &[f64; 3], d: &[f64; 3]) -> bool {
    off_line2(m, w, d, false) <= (2.0 * MM_PER_BLU).powi(2)
}

/// The squared distance (mm^2) of `m` from the line through `w` along `d`, or with `segment`
/// from the segment `w` to `w + d` (from `w` when `d` is zero).
fn off_line2(m: &[f64; 3], w: &[f64; 3], d: &[f64; 3], segment: bool) -> f64 {
    let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let e = [m[0] - w[0], m[1] - w[1], m[2] - w[2]];
    let s = if !segment {
        (e[0] * d[0] + e[1] * d[1] + e[2] * d[2]) / d2
    } else if d2 > 0.0 {
        ((e[0] * d[0] + e[1] * d[1] + e[2] * d[2]) / d2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (0..3).map(|k| (e[k] - s * d[k]).powi(2)).sum()
}

/// The cut at one point per mm of feed per tooth along the path: XY direction, XY share, -Z share
/// (> 0 moving down), the end face's material test and the side chip's reach (mm: the XY feed
/// per tooth at the point's ceiling, the largest a schedule can take there).
#[derive(Clone, Copy, Debug)]
struct PointCut {
    tip: [f64; 3],
    u: [f64; 2],
    share: f64,
    share_z: f64,
    hold: bool,
    reach: f64,
}

impl PointCut {
    /// The teeth's contacts with `stock` at this point (for [`PointCut::peak`]).
    fn contacts(&self, cut: &Cutter, stock: &Stock) -> Contacts {
        let z_min = (self.share_z > 0.0).then(|| EndCut::new(1.0, self.tip[2], self.hold).z_min);
        Contacts::new(cut, stock, self.tip, self.u, self.reach, z_min)
    }

    /// The end cut at feed per tooth `c` (mm) along the path.
    fn end(&self, c: f64) -> EndCut {
        if self.share_z > 0.0 {
            EndCut::new(c * self.share_z, self.tip[2], self.hold)
        } else {
            EndCut::NONE
        }
    }

    /// Peaks at feed per tooth `c` (mm) along the path, from the point's `contacts`.
    fn peak(&self, cut: &Cutter, contacts: &Contacts, c: f64) -> Peak {
        peak(cut, contacts, c * self.share, self.end(c))
    }

    /// The largest feed per tooth (mm, along the path) whose peaks are within `f0` and `t0`
    /// where some chip is limited by the material (the force is not linear in c there): the
    /// first of c_ceil, 2 c_ceil, 4 c_ceil, ... over a limit, then bisection (the peaks grow
    /// with c: every tooth's chip min(c, extent) does). Infinite if none is over within 2^40
    /// times the ceiling (only limited chips, all small).
    fn limit_c(&self, cut: &Cutter, contacts: &Contacts, c_ceil: f64, f0: f64, t0: f64) -> f64 {
        let within = |c: f64| peak_within(cut, contacts, c * self.share, self.end(c), f0, t0);
        let (mut lo, mut hi) = (0.0, c_ceil.max(1e-3));
        let mut doublings = 0;
        while within(hi) {
            if doublings == 40 {
                return f64::INFINITY;
            }
            lo = hi;
            hi *= 2.0;
            doublings += 1;
        }
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if within(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }
}

/// The fastest schedule along `path` cutting `stock` (taken by value: it is cut along the way).
pub fn oracle_time(
    mut stock: Stock,
    tool: &Tool,
    material: &Material,
    spindle_rpm: f64,
    path: &[OraclePoint],
    limits: &OracleLimits,
) -> Result<OracleResult, CutError> {
    validate(tool, material, spindle_rpm)?;
    let l = limits;
    if !(l.f0_n > 0.0 && l.t0_nm > 0.0) {
        return Err(CutError("oracle limits F0 and T0 must be > 0".into()));
    }
    if let Some(p) = path
        .iter()
        .find(|p| !(p.feed_ipm >= 0.0 && p.feed_ipm.is_finite()))
    {
        return Err(CutError(format!(
            "oracle: programmed feed must be finite and >= 0, got {} at {:?}",
            p.feed_ipm, p.pos_blu
        )));
    }
    if let Some(p) = path
        .iter()
        .find(|p| !(p.accel_ipm_s > 0.0 && p.accel_ipm_s.is_finite()))
    {
        return Err(CutError(format!(
            "oracle: acceleration must be finite and > 0, got {} ipm/s at {:?}",
            p.accel_ipm_s, p.pos_blu
        )));
    }
    let cut = Cutter::new(tool, material, &stock);
    let n = path.len();
    let mm = |p: &OraclePoint| p.pos_blu.map(|v| v as f64 * MM_PER_BLU);
    // Tooth passes per second: feed per tooth c = v / teeth_hz.
    let teeth_hz = tool.flutes as f64 * spindle_rpm / 60.0;
    let mut s = vec![0.0; n]; // length of the segment arriving at each point, mm
    let mut per_c = vec![(0.0, 0.0, 0.0); n]; // (F per c, T per c, multiplier), constant Ks
    let mut pcs = Vec::with_capacity(n);
    let mut limit = vec![0.0; n];
    let mut cut_limit = vec![f64::INFINITY; n];
    let kienzle = material.ks_exponent > 0.0;
    let expo = 1.0 / (1.0 - material.ks_exponent);
    let start_stock = stock.clone();
    let mut capped = vec![false; n];
    let c_of = |v_ipm: f64| v_ipm * MM_S_PER_IPM / teeth_hz;
    let mut end_engaged = false;
    // The points evaluated in full (see [`OracleLimits::stride_mm`]); every other point takes
    // the figures of the key point before or after it, whichever allows less.
    let stride = if l.stride_mm > 0.0 { l.stride_mm } else { 0.0 };
    let mut keys: Vec<usize> = Vec::new();
    let mut key_of = vec![0usize; n];
    // The stock is cut along the path up to this point; path length since the last key point.
    let (mut cut_to, mut since) = (0usize, 0.0);
    for i in 0..n {
        let p = mm(&path[i]);
        // Direction: the segment arriving here (the first point looks at the next one).
        let (a, b) = if i > 0 {
            (mm(&path[i - 1]), p)
        } else if n > 1 {
            (p, mm(&path[1]))
        } else {
            (p, p)
        };
        let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if i > 0 {
            s[i] = path[i].step_mm.unwrap_or(len);
        }
        if let (Some(&k), true) = (keys.last(), stride > 0.0 && i + 1 < n) {
            since += s[i];
            let same_move = path[i].feed_ipm == path[i - 1].feed_ipm
                && path[i].accel_ipm_s == path[i - 1].accel_ipm_s;
            let w = mm(&path[k]);
            let chord = [p[0] - w[0], p[1] - w[1], p[2] - w[2]];
            if since < stride
                && same_move
                && on_chord(&a, &w, &chord)
                && on_chord(&mm(&path[(k + i) / 2]), &w, &chord)
            {
                continue;
            }
        }
        since = 0.0;
        // The stock cut up to the point before this one: along the chord from the last point
        // cut (the points between lie on it).
        if i > 0 && cut_to + 1 < i {
            stock.cut_capsule(mm(&path[cut_to]), a, cut.r_mm);
        }
        // Descending over the window: the window's direction.
        let mut dir = d;
        if i > 0 {
            let (mut j, mut acc) = (i, 0.0);
            while j > 0 && acc < DIR_WINDOW_MM {
                acc += s[j];
                j -= 1;
            }
            let w = mm(&path[j]);
            let dw = [p[0] - w[0], p[1] - w[1], p[2] - w[2]];
            if dw[2] < 0.0 && straight(&mm(&path[(i + j) / 2]), &w, &dw) {
                dir = dw;
            }
        }
        let dlen = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
        let dxy = dir[0].hypot(dir[1]);
        let u = if dxy > 0.0 {
            [dir[0] / dxy, dir[1] / dxy]
        } else {
            [0.0; 2]
        };
        let (share, share_z) = if dlen > 0.0 {
            (dxy / dlen, (-dir[2]).max(0.0) / dlen)
        } else {
            (0.0, 0.0)
        };
        let hold = end_engaged && i > 0 && a[2] == p[2];
        let c_ceil = c_of(path[i].feed_ipm);
        let pc = PointCut {
            tip: p,
            u,
            share,
            share_z,
            hold,
            reach: c_ceil * share,
        };
        // The force and torque limit alone (infinite where nothing is cut), then the ceiling.
        let mut v = f64::INFINITY;
        // What the peaks read of the stock here, read once for all the feeds tried.
        let contacts = (dxy > 0.0 || share_z > 0.0).then(|| pc.contacts(&cut, &stock));
        if !kienzle {
            let (pk, mult) = match &contacts {
                Some(ct) if share_z > 0.0 => (pc.peak(&cut, ct, 1.0), 1.0),
                Some(ct) => (peak(&cut, ct, 1.0, EndCut::NONE), share),
                None => (Peak::default(), share),
            };
            end_engaged = pk.engaged;
            if let (true, Some(ct)) = (pk.capped, &contacts) {
                // Not linear in c: searched, and re-evaluated at the schedule's feed.
                capped[i] = true;
                let c = pc.limit_c(&cut, ct, c_ceil, l.f0_n, l.t0_nm);
                v = c * teeth_hz / MM_S_PER_IPM;
            } else {
                let (fc, tc) = (pk.f, pk.t);
                per_c[i] = (fc, tc, mult);
                if fc * mult > 0.0 {
                    v = v.min(l.f0_n / (fc * mult) * teeth_hz / MM_S_PER_IPM);
                }
                if tc * mult > 0.0 {
                    v = v.min(l.t0_nm / (tc * mult) * teeth_hz / MM_S_PER_IPM);
                }
            }
        } else if let Some(ct) = &contacts {
            // From a feed far above any cut's limit down by the c^(1-m) estimate.
            v = KIENZLE_PROBE_IPM;
            let pk = pc.peak(&cut, ct, c_of(v));
            let (mut f, mut t) = (pk.f, pk.t);
            if f == 0.0 && t == 0.0 {
                v = f64::INFINITY;
            }
            end_engaged = pk.engaged;
            let mut steps = 0;
            while (f > l.f0_n || t > l.t0_nm) && steps < 50 {
                let ratio = (l.f0_n / f).min(l.t0_nm / t);
                v *= ratio.powf(expo) * (1.0 - 1e-12);
                let pk = pc.peak(&cut, ct, c_of(v));
                (f, t) = (pk.f, pk.t);
                steps += 1;
            }
            if f > l.f0_n || t > l.t0_nm {
                v = 0.0;
            }
        } else {
            end_engaged = false;
        }
        pcs.push(pc);
        cut_limit[i] = v;
        limit[i] = v.min(path[i].feed_ipm);
        // The points since the last key point take the figures of the one that allows less.
        if let Some(&k) = keys.last() {
            let from = if cut_limit[k] <= v { k } else { i };
            for j in k + 1..i {
                key_of[j] = from;
                cut_limit[j] = cut_limit[from];
                limit[j] = cut_limit[from].min(path[j].feed_ipm);
                per_c[j] = per_c[from];
                capped[j] = capped[from];
            }
        }
        key_of[i] = i;
        keys.push(i);
        let from = if i > 0 { a } else { p };
        stock.cut_capsule(from, p, cut.r_mm);
        cut_to = i;
    }
    // Acceleration passes, in ipm and ipm/s: v^2 grows by at most 2 a s with s in inches; the
    // move arriving at point i has the acceleration of point i.
    let a2 = |i: usize| 2.0 * path[i].accel_ipm_s * 60.0 * s[i] / 25.4;
    let mut v = limit.clone();
    if n > 0 && l.from_rest {
        v[0] = 0.0;
        v[n - 1] = 0.0;
    }
    for i in 1..n {
        v[i] = v[i].min((v[i - 1] * v[i - 1] + a2(i)).sqrt());
    }
    for i in (0..n.saturating_sub(1)).rev() {
        v[i] = v[i].min((v[i + 1] * v[i + 1] + a2(i + 1)).sqrt());
    }
    let mut time_s = 0.0;
    for i in 1..n {
        if s[i] > 0.0 {
            let vm = (v[i - 1] + v[i]) * MM_S_PER_IPM;
            time_s += if vm > 0.0 {
                2.0 * s[i] / vm
            } else {
                f64::INFINITY
            };
        }
    }
    // Linear in c: scaled; otherwise (Kienzle's Ks, chips limited by the material)
    // re-evaluated at the scheduled feed along a second walk.
    let c = |i: usize| v[i] * MM_S_PER_IPM * per_c[i].2 / teeth_hz;
    let mut f_peak_n: Vec<f64> = (0..n).map(|i| per_c[i].0 * c(i)).collect();
    let mut t_peak_nm: Vec<f64> = (0..n).map(|i| per_c[i].1 * c(i)).collect();
    if kienzle || capped.iter().any(|&c| c) {
        // The same cuts as the first walk, the key points re-evaluated.
        let mut stock = start_stock;
        let mut cut_to = 0usize;
        for (pc, &i) in pcs.iter().zip(&keys) {
            let p = mm(&path[i]);
            let from = if i > 0 { mm(&path[i - 1]) } else { p };
            if i > 0 && cut_to + 1 < i {
                stock.cut_capsule(mm(&path[cut_to]), from, cut.r_mm);
            }
            if (kienzle || capped[i]) && v[i] > 0.0 {
                let pk = pc.peak(&cut, &pc.contacts(&cut, &stock), c_of(v[i]));
                (f_peak_n[i], t_peak_nm[i]) = (pk.f, pk.t);
            }
            stock.cut_capsule(from, p, cut.r_mm);
            cut_to = i;
        }
        // The points between take their key point's peaks (not linear in the feed: as they
        // are).
        for j in 0..n {
            let k = key_of[j];
            if k != j && (kienzle || capped[j]) {
                (f_peak_n[j], t_peak_nm[j]) = (f_peak_n[k], t_peak_nm[k]);
            }
        }
    }
    Ok(OracleResult {
        time_s,
        f_peak_n,
        t_peak_nm,
        feed_profile: v,
        limit_ipm: limit,
        cut_limit_ipm: cut_limit,
        stock,
    })
}
