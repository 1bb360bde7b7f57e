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
    /// Contacts per angle ([`Cutter::edges`]: per tooth, per slice).
    flutes: usize,
    /// Per angle, per tooth (and slice).
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
        let flutes = cut.edges();
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

/// One point's figures as [`OracleStream`] settles them (the per-point entries of
/// [`OracleResult`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleOut {
    /// The schedule's feed, ipm.
    pub feed_ipm: f64,
    /// The largest feed force, torque and the ceiling allow (before the acceleration passes);
    /// force and torque alone (infinite where nothing is cut), ipm.
    pub limit_ipm: f64,
    pub cut_limit_ipm: f64,
    /// Peak force (N) and torque (N*m) at the scheduled feed.
    pub f_peak_n: f64,
    pub t_peak_nm: f64,
}

/// A point the stream holds: its input, what the first walk found there and, once the forward
/// pass has reached it, its forward feed.
struct Held {
    p: OraclePoint,
    mm: [f64; 3],
    /// Length of the segment arriving here, mm.
    s: f64,
    /// `2 a s` of the segment arriving here (ipm^2: v^2 changes by at most this over it), and
    /// its sum from the first point to this one (the backward pass's reach).
    a2: f64,
    cum: f64,
    /// (F per c, T per c, multiplier), constant Ks.
    per_c: (f64, f64, f64),
    capped: bool,
    limit: f64,
    cut_limit: f64,
    /// The key point whose figures this point takes (its own index for a key point).
    key_of: usize,
    /// A key point's cut and, where its peaks are re-evaluated at the schedule's feed, what they
    /// read of the stock (the same contacts a second walk of the path would read).
    key: Option<(PointCut, Option<Contacts>)>,
    /// Forward pass, then (settled) the schedule's feed.
    v: f64,
    /// The peaks at the schedule's feed, once settled (a point between key points whose peaks
    /// are not linear in c takes its key point's instead).
    peaks: (f64, f64),
}

/// The oracle as a stream (host): points go in one at a time ([`OracleStream::push`]) and come
/// out settled, in order, as soon as nothing further along the path can change them
/// ([`OracleStream::finish`] settles the rest), so the memory it holds is its window, not the
/// path: the points since the last key point and the direction window behind the newest, and
/// the points the backward acceleration pass can still lower (those within braking distance of
/// the newest point with a forward feed, `v^2 <= sum 2 a s` ahead of them). The same figures,
/// to the bit, as running the passes over the whole path: every pass is the same arithmetic in
/// the same order, and the backward pass's value at a point is the smallest of the chains
/// `sqrt(v_j^2 + 2 a s ...)` from every point ahead of it (each step is monotone, so the
/// minimum passes through it exactly); a point is settled only when the chains from beyond the
/// window are above its forward feed with a margin far above the roundings.
pub struct OracleStream {
    cut: Cutter,
    stock: Stock,
    limits: OracleLimits,
    teeth_hz: f64,
    kienzle: bool,
    expo: f64,
    stride: f64,
    /// Points from global index `base` on.
    held: std::collections::VecDeque<Held>,
    base: usize,
    /// Points pushed; evaluated (each waits for the next, which gives the first point its
    /// direction and says whether it is the last); with a forward feed (up to the last key
    /// point); settled; put out.
    pushed: usize,
    evaluated: usize,
    forward: usize,
    settled: usize,
    emitted: usize,
    /// The largest forward feed squared over the points not settled.
    vmax2: f64,
    last_key: Option<usize>,
    cut_to: usize,
    since: f64,
    end_engaged: bool,
    /// The settled feed of the last point put out, and the time so far.
    prev_v: f64,
    time_s: f64,
}

/// Margin of the settling rule: a point is settled when the backward pass's reach ahead of it
/// exceeds its forward feed squared by this factor plus [`SETTLE_MARGIN_IPM2`].
const SETTLE_FACTOR: f64 = 1.001;
const SETTLE_MARGIN_IPM2: f64 = 1.0;

impl OracleStream {
    /// A stream cutting `stock` (taken by value: it is cut along the way) with `tool`,
    /// `material` at `spindle_rpm` within `limits`.
    pub fn new(
        stock: Stock,
        tool: &Tool,
        material: &Material,
        spindle_rpm: f64,
        limits: &OracleLimits,
    ) -> Result<OracleStream, CutError> {
        validate(tool, material, spindle_rpm)?;
        let l = *limits;
        if !(l.f0_n > 0.0 && l.t0_nm > 0.0) {
            return Err(CutError("oracle limits F0 and T0 must be > 0".into()));
        }
        Ok(OracleStream {
            cut: Cutter::new(tool, material, &stock),
            stock,
            limits: l,
            teeth_hz: tool.flutes as f64 * spindle_rpm / 60.0,
            kienzle: material.ks_exponent > 0.0,
            expo: 1.0 / (1.0 - material.ks_exponent),
            stride: if l.stride_mm > 0.0 { l.stride_mm } else { 0.0 },
            held: std::collections::VecDeque::new(),
            base: 0,
            pushed: 0,
            evaluated: 0,
            forward: 0,
            settled: 0,
            emitted: 0,
            vmax2: 0.0,
            last_key: None,
            cut_to: 0,
            since: 0.0,
            end_engaged: false,
            prev_v: 0.0,
            time_s: 0.0,
        })
    }

    fn at(&self, i: usize) -> &Held {
        &self.held[i - self.base]
    }

    fn at_mut(&mut self, i: usize) -> &mut Held {
        &mut self.held[i - self.base]
    }

    /// The points held now (the window; for the memory tests).
    pub fn held(&self) -> usize {
        self.held.len()
    }

    /// The next point of the path; `out` gets every point settled by it (index along the path
    /// and figures), in order.
    pub fn push(
        &mut self,
        p: OraclePoint,
        out: &mut impl FnMut(usize, OracleOut),
    ) -> Result<(), CutError> {
        if !(p.feed_ipm >= 0.0 && p.feed_ipm.is_finite()) {
            return Err(CutError(format!(
                "oracle: programmed feed must be finite and >= 0, got {} at {:?}",
                p.feed_ipm, p.pos_blu
            )));
        }
        if !(p.accel_ipm_s > 0.0 && p.accel_ipm_s.is_finite()) {
            return Err(CutError(format!(
                "oracle: acceleration must be finite and > 0, got {} ipm/s at {:?}",
                p.accel_ipm_s, p.pos_blu
            )));
        }
        self.held.push_back(Held {
            p,
            mm: p.pos_blu.map(|v| v as f64 * MM_PER_BLU),
            s: 0.0,
            a2: 0.0,
            cum: 0.0,
            per_c: (0.0, 0.0, 0.0),
            capped: false,
            limit: 0.0,
            cut_limit: f64::INFINITY,
            key_of: self.pushed,
            key: None,
            v: 0.0,
            peaks: (0.0, 0.0),
        });
        self.pushed += 1;
        if self.pushed >= 2 {
            self.evaluate(false);
            self.settle(false, out);
        }
        Ok(())
    }

    /// The end of the path: settles and puts out the rest; the schedule's time (infinite when
    /// some limit is 0 on a segment of length > 0) and the stock as the path left it.
    pub fn finish(mut self, out: &mut impl FnMut(usize, OracleOut)) -> (f64, Stock) {
        if self.evaluated < self.pushed {
            self.evaluate(true);
        }
        self.settle(true, out);
        (self.time_s, self.stock)
    }

    /// The first walk at the next point (`last`: no point follows it).
    fn evaluate(&mut self, last: bool) {
        let i = self.evaluated;
        self.evaluated += 1;
        let n_known = self.pushed;
        let l = self.limits;
        let p = self.at(i).mm;
        // Direction: the segment arriving here (the first point looks at the next one).
        let (a, b) = if i > 0 {
            (self.at(i - 1).mm, p)
        } else if n_known > 1 {
            (p, self.at(1).mm)
        } else {
            (p, p)
        };
        let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if i > 0 {
            let s = self.at(i).p.step_mm.unwrap_or(len);
            let a2 = 2.0 * self.at(i).p.accel_ipm_s * 60.0 * s / 25.4;
            let cum = self.at(i - 1).cum + a2;
            let h = self.at_mut(i);
            h.s = s;
            h.a2 = a2;
            h.cum = cum;
        }
        if let (Some(k), true) = (self.last_key, self.stride > 0.0 && !last) {
            self.since += self.at(i).s;
            let (cur, prev) = (self.at(i).p, self.at(i - 1).p);
            let same_move = cur.feed_ipm == prev.feed_ipm && cur.accel_ipm_s == prev.accel_ipm_s;
            let w = self.at(k).mm;
            let chord = [p[0] - w[0], p[1] - w[1], p[2] - w[2]];
            if self.since < self.stride
                && same_move
                && on_chord(&a, &w, &chord)
                && on_chord(&self.at((k + i) / 2).mm, &w, &chord)
            {
                return;
            }
        }
        self.since = 0.0;
        let cut = self.cut;
        // The stock cut up to the point before this one: along the chord from the last point
        // cut (the points between lie on it).
        if i > 0 && self.cut_to + 1 < i {
            let from = self.at(self.cut_to).mm;
            self.stock.cut_shaped(from, a, cut.r_mm, cut.shape);
        }
        // Descending over the window: the window's direction.
        let mut dir = d;
        if i > 0 {
            let (mut j, mut acc) = (i, 0.0);
            while j > 0 && acc < DIR_WINDOW_MM {
                acc += self.at(j).s;
                j -= 1;
            }
            let w = self.at(j).mm;
            let dw = [p[0] - w[0], p[1] - w[1], p[2] - w[2]];
            if dw[2] < 0.0 && straight(&self.at((i + j) / 2).mm, &w, &dw) {
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
        let hold = self.end_engaged && i > 0 && a[2] == p[2];
        let teeth_hz = self.teeth_hz;
        let c_of = |v_ipm: f64| v_ipm * MM_S_PER_IPM / teeth_hz;
        let feed_ipm = self.at(i).p.feed_ipm;
        let c_ceil = c_of(feed_ipm);
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
        let (mut per_c, mut capped) = ((0.0, 0.0, 0.0), false);
        // What the peaks read of the stock here, read once for all the feeds tried.
        let contacts = (dxy > 0.0 || share_z > 0.0).then(|| pc.contacts(&cut, &self.stock));
        if !self.kienzle {
            let (pk, mult) = match &contacts {
                Some(ct) if share_z > 0.0 => (pc.peak(&cut, ct, 1.0), 1.0),
                Some(ct) => (peak(&cut, ct, 1.0, EndCut::NONE), share),
                None => (Peak::default(), share),
            };
            self.end_engaged = pk.engaged;
            if let (true, Some(ct)) = (pk.capped, &contacts) {
                // Not linear in c: searched, and re-evaluated at the schedule's feed.
                capped = true;
                let c = pc.limit_c(&cut, ct, c_ceil, l.f0_n, l.t0_nm);
                v = c * teeth_hz / MM_S_PER_IPM;
            } else {
                let (fc, tc) = (pk.f, pk.t);
                per_c = (fc, tc, mult);
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
            self.end_engaged = pk.engaged;
            let mut steps = 0;
            while (f > l.f0_n || t > l.t0_nm) && steps < 50 {
                let ratio = (l.f0_n / f).min(l.t0_nm / t);
                v *= ratio.powf(self.expo) * (1.0 - 1e-12);
                let pk = pc.peak(&cut, ct, c_of(v));
                (f, t) = (pk.f, pk.t);
                steps += 1;
            }
            if f > l.f0_n || t > l.t0_nm {
                v = 0.0;
            }
        } else {
            self.end_engaged = false;
        }
        // The peaks at the schedule's feed are re-evaluated from the same contacts.
        let keep = (self.kienzle || capped).then_some(contacts).flatten();
        let h = self.at_mut(i);
        h.per_c = per_c;
        h.capped = capped;
        h.cut_limit = v;
        h.limit = v.min(feed_ipm);
        h.key = Some((pc, keep));
        // The points since the last key point take the figures of the one that allows less.
        if let Some(k) = self.last_key {
            let from = if self.at(k).cut_limit <= v { k } else { i };
            let (cl, pcf, cp) = {
                let f = self.at(from);
                (f.cut_limit, f.per_c, f.capped)
            };
            for j in k + 1..i {
                let h = self.at_mut(j);
                h.key_of = from;
                h.cut_limit = cl;
                h.limit = cl.min(h.p.feed_ipm);
                h.per_c = pcf;
                h.capped = cp;
            }
        }
        self.last_key = Some(i);
        let from = if i > 0 { a } else { p };
        self.stock.cut_shaped(from, p, cut.r_mm, cut.shape);
        self.cut_to = i;
        // The forward pass up to this key point (v^2 grows by at most 2 a s).
        for j in self.forward..=i {
            let mut v = self.at(j).limit;
            if l.from_rest && (j == 0 || (last && j == i)) {
                v = 0.0;
            }
            if j > 0 {
                let prev = self.at(j - 1).v;
                v = v.min((prev * prev + self.at(j).a2).sqrt());
            }
            self.vmax2 = self.vmax2.max(v * v);
            self.at_mut(j).v = v;
        }
        self.forward = i + 1;
    }

    /// The backward pass over the points with a forward feed, settling those it can (all of
    /// them at the end), then putting out those whose key point is settled.
    fn settle(&mut self, end: bool, out: &mut impl FnMut(usize, OracleOut)) {
        if self.forward > self.settled {
            let f = self.forward - 1;
            let reach = |s: &Self, j: usize| s.at(f).cum - s.at(j).cum;
            // Sweep when the window is twice what settles its front: amortised, each sweep
            // settles about half of what it walks.
            let due = end
                || reach(self, self.settled)
                    >= 2.0 * (SETTLE_FACTOR * self.vmax2 + SETTLE_MARGIN_IPM2);
            if due {
                // The backward pass from the newest forward point: its chain values.
                let mut bw = Vec::with_capacity(f + 1 - self.settled);
                let mut next = self.at(f).v;
                bw.push(next);
                for j in (self.settled..f).rev() {
                    next = self.at(j).v.min((next * next + self.at(j + 1).a2).sqrt());
                    bw.push(next);
                }
                bw.reverse();
                let mut upto = self.settled;
                for (k, &v) in bw.iter().enumerate() {
                    let j = self.settled + k;
                    let fw = self.at(j).v;
                    if !end && reach(self, j) < SETTLE_FACTOR * fw * fw + SETTLE_MARGIN_IPM2 {
                        break;
                    }
                    self.at_mut(j).v = v;
                    upto = j + 1;
                }
                // Settled points: their peaks at the schedule's feed (linear in c; a key point's
                // whose chip is not, re-evaluated from its contacts).
                for j in self.settled..upto {
                    let (v, per_c) = (self.at(j).v, self.at(j).per_c);
                    let c = v * MM_S_PER_IPM * per_c.2 / self.teeth_hz;
                    let mut pk = (per_c.0 * c, per_c.1 * c);
                    if let Some((pc, Some(ct))) = &self.at(j).key {
                        if v > 0.0 {
                            let r = pc.peak(&self.cut, ct, v * MM_S_PER_IPM / self.teeth_hz);
                            pk = (r.f, r.t);
                        }
                    }
                    let h = self.at_mut(j);
                    h.peaks = pk;
                    // What the points between key points need of it kept, the contacts not.
                    if let Some((_, ct)) = &mut h.key {
                        *ct = None;
                    }
                }
                self.settled = upto;
                self.vmax2 = (self.settled..self.forward)
                    .map(|j| self.at(j).v * self.at(j).v)
                    .fold(0.0, f64::max);
            }
        }
        // Out in order, each point once its key point's peaks are known.
        while self.emitted < self.settled && self.at(self.emitted).key_of < self.settled {
            let j = self.emitted;
            let (k, capped, v, own) = {
                let h = self.at(j);
                (h.key_of, h.capped, h.v, h.peaks)
            };
            let (f_peak_n, t_peak_nm) = if k != j && (self.kienzle || capped) {
                self.at(k).peaks
            } else {
                own
            };
            let h = self.at(j);
            let (s, limit, cut_limit) = (h.s, h.limit, h.cut_limit);
            if j > 0 && s > 0.0 {
                let vm = (self.prev_v + v) * MM_S_PER_IPM;
                self.time_s += if vm > 0.0 {
                    2.0 * s / vm
                } else {
                    f64::INFINITY
                };
            }
            self.prev_v = v;
            out(
                j,
                OracleOut {
                    feed_ipm: v,
                    limit_ipm: limit,
                    cut_limit_ipm: cut_limit,
                    f_peak_n,
                    t_peak_nm,
                },
            );
            self.emitted += 1;
        }
        self.trim();
    }

    /// Lets go of the points nothing will read again: behind the points not yet put out (and
    /// their key points), the last key point and the direction window of the next point.
    fn trim(&mut self) {
        let mut keep = self.emitted.min(self.evaluated.saturating_sub(1));
        if self.emitted < self.pushed && self.emitted < self.evaluated {
            keep = keep.min(self.at(self.emitted).key_of);
        }
        if let Some(k) = self.last_key {
            keep = keep.min(k);
        }
        // The direction window: from the newest evaluated point back over DIR_WINDOW_MM.
        if self.evaluated > 0 {
            let (mut j, mut acc) = (self.evaluated - 1, 0.0);
            while j > self.base && acc < DIR_WINDOW_MM {
                acc += self.at(j).s;
                j -= 1;
            }
            keep = keep.min(j);
        }
        while self.base < keep {
            self.held.pop_front();
            self.base += 1;
        }
    }
}

/// The fastest schedule along `path` cutting `stock` (taken by value: it is cut along the way):
/// [`OracleStream`] over the whole path, its figures gathered per point.
pub fn oracle_time(
    stock: Stock,
    tool: &Tool,
    material: &Material,
    spindle_rpm: f64,
    path: &[OraclePoint],
    limits: &OracleLimits,
) -> Result<OracleResult, CutError> {
    let mut stream = OracleStream::new(stock, tool, material, spindle_rpm, limits)?;
    let n = path.len();
    let mut r = OracleResult {
        time_s: 0.0,
        feed_profile: Vec::with_capacity(n),
        limit_ipm: Vec::with_capacity(n),
        cut_limit_ipm: Vec::with_capacity(n),
        f_peak_n: Vec::with_capacity(n),
        t_peak_nm: Vec::with_capacity(n),
        stock: Stock::default(),
    };
    let mut gather = |_: usize, o: OracleOut| {
        r.feed_profile.push(o.feed_ipm);
        r.limit_ipm.push(o.limit_ipm);
        r.cut_limit_ipm.push(o.cut_limit_ipm);
        r.f_peak_n.push(o.f_peak_n);
        r.t_peak_nm.push(o.t_peak_nm);
    };
    for p in path {
        stream.push(*p, &mut gather)?;
    }
    let (time_s, stock) = stream.finish(&mut gather);
    r.time_s = time_s;
    r.stock = stock;
    Ok(r)
}
