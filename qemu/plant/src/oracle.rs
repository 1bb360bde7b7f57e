//! The oracle (host; the evaluation calls it with the path of a program): the fastest feed schedule
//! along a tool path that keeps the force F <= F0 and the torque T <= T0 everywhere, never exceeds
//! the programmed feed and changes the feed by at most fdot_m (750 ipm/s by default, up and down),
//! computed with full knowledge of the stock. Its time is the bound no honest adaptive controller
//! can beat.
//!
//! Algorithm:
//! 1. Walk the path once, cutting the stock as the process does (the removal does not depend on
//!    the feed, so the engagement is computed once). At each point, with the feed direction of
//!    the segment arriving there, scan the spindle angle over one tooth pitch (1 degree steps or
//!    finer) at unit feed per tooth and keep the peak resultant force and peak torque per mm of
//!    feed per tooth. F and T are linear in the feed per tooth in this model (constant Ks), so
//!    the safe feed at the point is `min(F0 / F_per_c, T0 / T_per_c) * z * rpm / 60`, divided by
//!    the XY share of the path direction; capped by the programmed feed of the point.
//! 2. Forward and backward passes of the classic velocity-profile algorithm:
//!    `v_i <= sqrt(v_{i-1}^2 + 2 a s_i)` and `v_i <= sqrt(v_{i+1}^2 + 2 a s_{i+1})`.
//! 3. Time: constant acceleration between points, `sum 2 s_i / (v_{i-1} + v_i)`.
//!
//! Approximations: limits are enforced at the path points only (fine spacing, e.g. 1..100 BLU,
//! keeps the error small); the peak is over continuous spindle angles (the AC sees 1 kHz samples,
//! so it can only do worse); the feed per tooth is taken from the instantaneous path direction
//! (the process averages it over one tooth period, which matters only at sharp corners); the
//! noise and the transducer quantisation are ignored.
use crate::process::Cutter;
use crate::{validate, CutError, Material, Stock, Tool, MM_PER_BLU, MM_S_PER_IPM};

/// One point of the tool path: tool tip position (BLU) and the programmed feed (ipm) of the move
/// arriving at it, the ceiling of the schedule there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OraclePoint {
    pub pos_blu: [i64; 3],
    pub feed_ipm: f64,
}

/// The constraints of the schedule.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleLimits {
    /// F0, N.
    pub f0_n: f64,
    /// T0, N*m.
    pub t0_nm: f64,
    /// fdot_m, ipm/s (feed change per second, up and down).
    pub fdot_m_ipm_s: f64,
    /// Start and end at rest (feed 0) instead of at the point limits.
    pub from_rest: bool,
}

impl OracleLimits {
    /// The paper's constraints for `tool`: F0, T0 = 0.9 x permissible ("around 90 percent"),
    /// fdot_m = 750 ipm/s, starting and ending at rest. (The AC core's defaults are the same
    /// numbers; millac-qemu's tests check it, the plant does not know the controller.)
    pub fn for_tool(tool: &Tool) -> OracleLimits {
        OracleLimits {
            f0_n: 0.9 * tool.f_max_n,
            t0_nm: 0.9 * tool.t_max_nm,
            fdot_m_ipm_s: 750.0,
            from_rest: true,
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
    /// Largest feed allowed by force, torque and the programmed feed at each point (before the
    /// acceleration passes), ipm.
    pub limit_ipm: Vec<f64>,
    /// Peak force and torque at each point at the scheduled feed, N and N*m.
    pub f_peak_n: Vec<f64>,
    pub t_peak_nm: Vec<f64>,
}

/// Peak force and torque per mm of feed per tooth over one tooth pitch of spindle angles.
fn peak_per_c(cut: &Cutter, stock: &Stock, tip: [f64; 3], u: [f64; 2]) -> (f64, f64) {
    let pitch = std::f64::consts::TAU / cut.flutes as f64;
    let steps = (360 / cut.flutes).max(8);
    let (mut f, mut t) = (0.0f64, 0.0f64);
    for i in 0..steps {
        let [fx, fy, tq] = cut.forces(stock, tip, pitch * i as f64 / steps as f64, u, 1.0);
        f = f.max(fx.hypot(fy));
        t = t.max(tq);
    }
    (f, t)
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
    if !(l.f0_n > 0.0 && l.t0_nm > 0.0 && l.fdot_m_ipm_s > 0.0 && l.fdot_m_ipm_s.is_finite()) {
        return Err(CutError(
            "oracle limits F0, T0 and fdot_m must be > 0".into(),
        ));
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
    let cut = Cutter::new(tool, material, &stock);
    let n = path.len();
    let mm = |p: &OraclePoint| p.pos_blu.map(|v| v as f64 * MM_PER_BLU);
    // Tooth passes per second: feed per tooth c = v / teeth_hz.
    let teeth_hz = tool.flutes as f64 * spindle_rpm / 60.0;
    let mut s = vec![0.0; n]; // length of the segment arriving at each point, mm
    let mut per_c = vec![(0.0, 0.0, 0.0); n]; // (F per c, T per c, XY share of the path)
    let mut limit = vec![0.0; n];
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
        let dxy = d[0].hypot(d[1]);
        if i > 0 {
            s[i] = len;
        }
        let (fc, tc) = if dxy > 0.0 {
            peak_per_c(&cut, &stock, p, [d[0] / dxy, d[1] / dxy])
        } else {
            (0.0, 0.0)
        };
        let share = if len > 0.0 { dxy / len } else { 0.0 };
        per_c[i] = (fc, tc, share);
        let mut v = path[i].feed_ipm;
        if fc * share > 0.0 {
            v = v.min(l.f0_n / (fc * share) * teeth_hz / MM_S_PER_IPM);
        }
        if tc * share > 0.0 {
            v = v.min(l.t0_nm / (tc * share) * teeth_hz / MM_S_PER_IPM);
        }
        limit[i] = v;
        let from = if i > 0 { mm(&path[i - 1]) } else { p };
        stock.cut_capsule(from, p, cut.r_mm);
    }
    // Acceleration passes, in ipm and ipm/s: v^2 grows by at most 2 a s with s in inches.
    let a2 = |s_mm: f64| 2.0 * l.fdot_m_ipm_s * 60.0 * s_mm / 25.4;
    let mut v = limit.clone();
    if n > 0 && l.from_rest {
        v[0] = 0.0;
        v[n - 1] = 0.0;
    }
    for i in 1..n {
        v[i] = v[i].min((v[i - 1] * v[i - 1] + a2(s[i])).sqrt());
    }
    for i in (0..n.saturating_sub(1)).rev() {
        v[i] = v[i].min((v[i + 1] * v[i + 1] + a2(s[i + 1])).sqrt());
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
    let c = |i: usize| v[i] * MM_S_PER_IPM * per_c[i].2 / teeth_hz;
    Ok(OracleResult {
        time_s,
        f_peak_n: (0..n).map(|i| per_c[i].0 * c(i)).collect(),
        t_peak_nm: (0..n).map(|i| per_c[i].1 * c(i)).collect(),
        feed_profile: v,
        limit_ipm: limit,
    })
}
