//! The AC's feed laws (strategies): how the feed of the next period follows from the load
//! measured in this one. Called from the AC period (`AcController::period`, AC task; the host
//! simulation runs the same code). The controller around a law keeps everything else as it is for
//! every law: the DRR and its sensor holds, the overload hold, the clamp to [f_min, f_max], the
//! anti-windup lead over the achieved feed, and the programmed-feed ceiling (the frame takes
//! min(programmed feed, cap)).
//!
//! The laws see the load as y = 1 - E, the critical one of F/F0 and T/T0 (the paper's E, Eq. 5),
//! so every law regulates y to its reference 1 (F = F0, or T = T0 where the torque binds), and the
//! feed as u = f / f_max (0..1), so their parameters do not depend on the feed unit.
//!
//! - [`Strategy::Paper`]: Tlusty, Koren and McNeil's FRC (Fig. 7, Eqs. 6-8, `frc`).
//! - [`Strategy::Integral`]: Ulsoy, Koren and Lauderbaugh's fixed-gain integral law (their Eq. 2),
//!   u(k) = u(k-1) + k_i (1 - y(k)), the gain by pole assignment for a nominal process
//!   y(k) = a y(k-1) + b u(k-1) (see [`IntegralLaw`]).
//! - [`Strategy::Mrac`]: their model reference adaptive law (Eqs. 3-4): reference model
//!   y_m(k+1) = 0.5 y_m(k) + 0.5, control u(k) = [y_m(k+1) - 0.5 y_m(k) - (p^ - 0.5) y(k)] / b^,
//!   the process parameters p^, b^ estimated on line by the constant-trace recursive least squares
//!   of [`Rls`] (the estimator the thesis' GPC uses; an equivalent of the Lozano-Landau adaptation
//!   the paper cites: a least-squares parameter adaptation with a bounded gain).
//! - [`Strategy::Gpc`]: Munasinghe's Generalized Predictive Control (thesis section 3.1.4, Eqs.
//!   3.32-3.42): the ARIMAX model A F = B f(t-1) + xi/Delta with A = 1 + a1 z^-1 + a2 z^-2,
//!   B = b0 + b1 z^-1 + b2 z^-2 identified on line by the constant-trace RLS with its dead zone
//!   (Eqs. 3.27-3.31), horizons N1 = 1, N2 = 4, Nu = 1, the control weight lambda a setting
//!   (`$265`). It regulates the peak resultant force of each AC period (millac's DRR window,
//!   10 ms), not of each spindle revolution as the thesis did: the AC period is the firmware's
//!   clock, and the DRR's held peak already spans several windows (see [`GpcLaw`]).

use super::frc;

/// Which feed law the AC runs (`$251`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Strategy {
    /// The paper's FRC (default).
    Paper,
    /// Fixed-gain integral control.
    Integral,
    /// Model reference adaptive control with an on-line estimate of the process.
    Mrac,
    /// Generalized predictive control on an ARIMAX model identified on line (the thesis').
    Gpc,
}

impl Strategy {
    /// Every strategy, in the order of their `$251` codes.
    pub const ALL: [Strategy; 4] = [
        Strategy::Paper,
        Strategy::Integral,
        Strategy::Mrac,
        Strategy::Gpc,
    ];

    /// The strategy's name on the host tool's command line and in summary.json (`ac.strategy`).
    pub const fn name(self) -> &'static str {
        match self {
            Strategy::Paper => "paper",
            Strategy::Integral => "integral",
            Strategy::Mrac => "mrac",
            Strategy::Gpc => "gpc",
        }
    }

    /// The strategy of a [`Strategy::name`].
    pub fn from_name(name: &str) -> Option<Strategy> {
        Strategy::ALL.into_iter().find(|s| s.name() == name)
    }
}

/// The process pole `a` the integral gain and the MRAC's initial estimate assume (Ulsoy, Koren and
/// Lauderbaugh's a1 = -0.1: y(k) = 0.1 y(k-1) + b u(k-1)).
pub const NOMINAL_POLE: f32 = 0.1;

/// The integral law's gain for a nominal process y(k) = a y(k-1) + b u(k-1) with the steady gain
/// y = 1 at u = `u_nominal` (b = (1 - a) / u_nominal).
///
/// Pole assignment: with u(k) = u(k-1) + k_i (1 - y(k)) the closed loop's characteristic
/// polynomial is z^2 - (1 + a - b k_i) z + a. One gain moves only the sum of the two poles (their
/// product is the process pole a); k_i = (1 + a) / b puts the sum at zero, the poles at
/// +-j sqrt(a): the fastest decay the law can have on the nominal process (|z| = 0.32 at a = 0.1).
/// On a process with n times the nominal b (n times the depth of cut) the sum is (1 + a)(1 - n):
/// at n = 2 a pole reaches -1 (sustained oscillation), above it the loop is unstable, the
/// behaviour of the paper's Fig. 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntegralLaw {
    pub ki: f32,
}

impl IntegralLaw {
    pub fn tuned(a: f32, u_nominal: f32) -> Self {
        let b = (1.0 - a) / u_nominal;
        IntegralLaw { ki: (1.0 + a) / b }
    }

    /// u(k) = u(k-1) + k_i (1 - y).
    pub fn next(&self, u: f32, y: f32) -> f32 {
        u + self.ki * (1.0 - y)
    }
}

/// Recursive least squares with a constant trace and a dead zone, for N parameters theta of a
/// model y = phi . theta: the thesis' estimator (section 3.1.3, Eqs. 3.27-3.31). After each update
/// the covariance is brought back to a constant trace, P = c1 P'/tr(P') + c2 I (c2 = c1 / 10^4,
/// the thesis' ratio), so the estimator keeps tracking a process that changes (a step in the
/// depth of cut) without the gain blowing up when nothing excites it (estimator windup); a
/// prediction error inside the dead zone updates nothing (the thesis' alpha = 0: noise and
/// quantisation do not make the estimates wander).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rls<const N: usize> {
    pub theta: [f32; N],
    p: [[f32; N]; N],
    trace: f32,
    dead_zone: f32,
}

impl<const N: usize> Rls<N> {
    pub fn new(theta: [f32; N], trace: f32, dead_zone: f32) -> Self {
        let mut p = [[0.0; N]; N];
        for (i, row) in p.iter_mut().enumerate() {
            if let Some(v) = row.get_mut(i) {
                *v = trace / N as f32;
            }
        }
        Rls {
            theta,
            p,
            trace,
            dead_zone,
        }
    }

    /// The model's prediction of y from the regressor phi.
    pub fn predict(&self, phi: &[f32; N]) -> f32 {
        self.theta.iter().zip(phi).map(|(t, x)| t * x).sum()
    }

    /// One update with the regressor phi and the measured y; returns the prediction error.
    pub fn update(&mut self, phi: &[f32; N], y: f32) -> f32 {
        let err = y - self.predict(phi);
        // Inside the dead zone, or not a number (a NaN updates nothing either).
        if err.is_nan() || err.abs() <= self.dead_zone {
            return err;
        }
        let mut pphi = [0.0f32; N];
        for (i, v) in pphi.iter_mut().enumerate() {
            *v = self.p[i].iter().zip(phi).map(|(a, x)| a * x).sum();
        }
        let den = 1.0 + phi.iter().zip(&pphi).map(|(x, q)| x * q).sum::<f32>();
        for (t, q) in self.theta.iter_mut().zip(&pphi) {
            *t += q / den * err;
        }
        // P' = P - P phi phi' P / den, then P = c1 P'/tr(P') + c2 I with c1 + N c2 = trace.
        let mut n = self.p;
        for (i, row) in n.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v -= pphi[i] * pphi[j] / den;
            }
        }
        let t: f32 = (0..N).map(|i| n[i][i]).sum();
        if t > 0.0 && t.is_finite() {
            let c2 = self.trace / (1.0e4 + N as f32);
            let c1 = 1.0e4 * c2;
            for (i, row) in n.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = c1 * *v / t + if i == j { c2 } else { 0.0 };
                }
            }
            self.p = n;
        }
        err
    }
}

/// The MRAC law's state: the reference model's output and the estimator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MracLaw {
    pub ym: f32,
    pub rls: Rls<2>,
    /// The smallest b^ the control divides by (a fraction of the nominal b): an estimate driven
    /// towards zero (air: load 0 at any feed) must not ask for an unbounded feed.
    b_min: f32,
    /// The last period's y, for the regressor.
    y_prev: f32,
}

/// The estimator's constant trace. The regressor [y, u] is of order 1 (load and feed both
/// normalised), so a trace of 20 gives gains close to those of a fresh least-squares estimate: a
/// step in the process gain is tracked within a few periods (`rls_with_a_constant_trace_...`);
/// with a trace of 2 it took hundreds.
pub const RLS_TRACE: f32 = 20.0;
/// The estimator's dead zone on the prediction error (1 % of the reference load).
pub const RLS_DEAD_ZONE: f32 = 0.01;

/// The reference model's pole (the paper's 0.5).
pub const MRAC_MODEL_POLE: f32 = 0.5;

impl MracLaw {
    /// Starts from the nominal process (a, b = (1 - a) / u_nominal) and y_m = 0.
    pub fn new(a: f32, u_nominal: f32) -> Self {
        let b = (1.0 - a) / u_nominal;
        MracLaw {
            ym: 0.0,
            rls: Rls::new([a, b], RLS_TRACE, RLS_DEAD_ZONE),
            b_min: 0.25 * b,
            y_prev: 0.0,
        }
    }

    /// One period: `y` measured now, `u_prev` the (normalised) feed the process had over the
    /// period that produced it. Updates the estimate, advances the reference model, returns u(k).
    pub fn next(&mut self, y: f32, u_prev: f32) -> f32 {
        if y.max(self.y_prev) >= EXCITATION_FLOOR {
            self.rls.update(&[self.y_prev, u_prev], y);
        }
        self.y_prev = y;
        let [p, b] = self.rls.theta;
        let b = if b > self.b_min { b } else { self.b_min };
        let ym_next = MRAC_MODEL_POLE * self.ym + (1.0 - MRAC_MODEL_POLE);
        // The error y - y_m decays with the model's pole: y(k+1) = y_m(k+1) + 0.5 (y(k) - y_m(k)).
        let u = (ym_next + MRAC_MODEL_POLE * (y - self.ym) - p * y) / b;
        self.ym = ym_next;
        u
    }
}

/// The GPC law's state: the estimator of theta = [a1, a2, b0, b1, b2] and the histories of the
/// load y (F/F0) and the normalised feed u.
///
/// Each period: the regressor phi = [-y(t-1), -y(t-2), u(t-1), u(t-2), u(t-3)] (u(t-1) the feed
/// the process actually had: the achieved feed) updates the estimate with y(t); the incremental
/// model Delta F(t+k) = -a1 Delta F(t+k-1) - a2 Delta F(t+k-2) + b0 Delta f(t+k-1) + ... gives
/// the free response over k = 1..4 (no further feed change: the ARIMAX integrator, so no
/// steady-state offset) and the step response g_k; with Nu = 1 the cost (Eq. 3.40) is minimised
/// by Delta f = sum g_k (1 - F_free(t+k)) / (sum g_k^2 + lambda) (Eq. 3.41 with one column).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpcLaw {
    pub rls: Rls<5>,
    /// The nominal parameters, used for the control while the estimate's steady gain is
    /// implausible (below a quarter of the nominal, or the model near an integrator).
    nominal: [f32; 5],
    /// y(t), y(t-1) after the last period: y(t-1), y(t-2) for the next.
    ys: [f32; 2],
    /// u(t-1), u(t-2) after the last period: u(t-2), u(t-3) for the next.
    us: [f32; 2],
    pub lambda: f32,
}

/// Below this load (F/F0 and T/T0) over the regressor's periods the tool is in air: the feed
/// makes no force, the data say nothing about the process gain, and the estimators (MRAC, GPC)
/// do not update (otherwise an air cut drives b^ to zero and the next entry to f_max).
pub const EXCITATION_FLOOR: f32 = 0.05;

/// The GPC estimator's constant trace (five parameters of order 1).
pub const GPC_TRACE: f32 = 50.0;
/// The output horizon N2 (N1 = 1, Nu = 1).
pub const GPC_N2: usize = 4;
/// Below this load (F/F0 or T/T0) a GPC estimate whose step response does not rise over the
/// horizon gives way to the nominal model (see [`GpcLaw::next`]): half the reference, where a law
/// that lowers the feed is wrong whatever its model says, and well below the loads at which the
/// nominal's larger step overshoots (the pocket behind the servo drive, `ac_bench`).
pub const GPC_LIGHT_LOAD: f32 = 0.5;

impl GpcLaw {
    /// Starts from the nominal first-order process (a1 = -a, b0 = (1 - a) / u_nominal).
    pub fn new(a: f32, u_nominal: f32, lambda: f32) -> Self {
        let b = (1.0 - a) / u_nominal;
        GpcLaw {
            rls: Rls::new([-a, 0.0, b, 0.0, 0.0], GPC_TRACE, RLS_DEAD_ZONE),
            nominal: [-a, 0.0, b, 0.0, 0.0],
            ys: [0.0; 2],
            us: [0.0; 2],
            lambda,
        }
    }

    /// One period: `y` measured now, `u_prev` the (normalised) feed the process had over the
    /// period that produced it. Returns u(t).
    pub fn next(&mut self, y: f32, u_prev: f32) -> f32 {
        let [y1, y2] = self.ys;
        let [u2, u3] = self.us;
        let learning = y.max(y1).max(y2) >= EXCITATION_FLOOR;
        if learning {
            self.rls.update(&[-y1, -y2, u_prev, u2, u3], y);
        }
        self.ys = [y, y1];
        self.us = [u_prev, u2];
        // The estimate drives the control only while it is one a cut can be: a positive steady
        // gain not far below the nominal's, not near an integrator, and, while the load is light
        // (below the excitation floor, where nothing updates it, or below half the reference), a
        // step response over the horizon that rises (the control divides by it). A stretch of
        // cutting can leave an estimate with b0 < 0 whose first steps fall: its sum of g_k is
        // then negative, and the control lowers the feed for a load far below the reference, down
        // to f_min, and stays there, the estimate frozen by the dead zone at a constant feed
        // (seen on a 3D raster: 40 s at 1 ipm and 2 % of F0; on the corner end mill of the
        // Fig. 1 job after a corner: 3.6 s at 0.6-1.2 ipm and 6 % of F0). The nominal model then
        // steers until the load nears the reference. (Near it the estimate keeps steering: the
        // estimator corrects it, and the nominal's larger step held the pocket behind the servo
        // drive.)
        let theta = {
            let [a1, a2, b0, b1, b2] = self.rls.theta;
            let [n1, n2, nb, _, _] = self.nominal;
            let (a_sum, b_sum) = (1.0 + a1 + a2, b0 + b1 + b2);
            let nominal_gain = nb / (1.0 + n1 + n2);
            let rises = |t: &[f32; 5]| step_response(t).iter().sum::<f32>();
            let loaded = learning && y >= GPC_LIGHT_LOAD;
            if a_sum > 0.05
                && b_sum / a_sum >= 0.25 * nominal_gain
                && (loaded || rises(&self.rls.theta) >= 0.25 * rises(&self.nominal))
            {
                self.rls.theta
            } else {
                self.nominal
            }
        };
        let [a1, a2, _, b1, b2] = theta;
        // Free response: Delta f = 0 from now on.
        let (mut df1, mut df2) = (u_prev - u2, u2 - u3);
        let (mut dy1, mut dy2) = (y - y1, y1 - y2);
        let mut free = [0.0f32; GPC_N2];
        let mut level = y;
        for f in free.iter_mut() {
            let dy = -a1 * dy1 - a2 * dy2 + b1 * df1 + b2 * df2;
            level += dy;
            *f = level;
            dy2 = dy1;
            dy1 = dy;
            df2 = df1;
            df1 = 0.0;
        }
        let g = step_response(&theta);
        let num: f32 = g.iter().zip(&free).map(|(gk, fk)| gk * (1.0 - fk)).sum();
        let den: f32 = g.iter().map(|gk| gk * gk).sum::<f32>() + self.lambda;
        let du = if den > 0.0 { num / den } else { 0.0 };
        u_prev + du
    }
}

/// The step response g_1..g_N2 of the load to a unit step of the feed at t, for the model
/// theta = [a1, a2, b0, b1, b2] (the GPC's, see [`GpcLaw`]).
fn step_response(theta: &[f32; 5]) -> [f32; GPC_N2] {
    let [a1, a2, b0, b1, b2] = *theta;
    let mut g = [0.0f32; GPC_N2];
    let (mut s1, mut s2) = (0.0f32, 0.0f32);
    let mut cum = 0.0;
    for (k, gk) in g.iter_mut().enumerate() {
        let input = match k {
            0 => b0,
            1 => b1,
            2 => b2,
            _ => 0.0,
        };
        let dy = -a1 * s1 - a2 * s2 + input;
        cum += dy;
        *gk = cum;
        s2 = s1;
        s1 = dy;
    }
    g
}

/// A feed law with its state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FeedLaw {
    Paper,
    Integral(IntegralLaw),
    Mrac(MracLaw),
    Gpc(GpcLaw),
}

impl FeedLaw {
    /// The law of `strategy` for a nominal feed `f_nominal` (feed number at which the nominal cut
    /// reaches the reference load) out of `f_max`.
    pub fn new(strategy: Strategy, f_nominal: u32, f_max: u32, gpc_lambda: f32) -> Self {
        let u_nom = f_nominal.max(1) as f32 / f_max.max(1) as f32;
        match strategy {
            Strategy::Paper => FeedLaw::Paper,
            Strategy::Integral => FeedLaw::Integral(IntegralLaw::tuned(NOMINAL_POLE, u_nom)),
            Strategy::Mrac => FeedLaw::Mrac(MracLaw::new(NOMINAL_POLE, u_nom)),
            Strategy::Gpc => FeedLaw::Gpc(GpcLaw::new(NOMINAL_POLE, u_nom, gpc_lambda)),
        }
    }

    /// The next feed number (before the controller's clamps) from the current one `f`, the
    /// critical error `e` and the feed the process achieved over the last period (`achieved`,
    /// the current feed when unknown). `step` is the FRC's fdot_m x dt.
    pub fn next(
        &mut self,
        f: u32,
        e: f32,
        achieved: u32,
        step: f32,
        f_min: u32,
        f_max: u32,
    ) -> u32 {
        let scale = f_max.max(1) as f32;
        let to_feed = |u: f32| {
            // `as` saturates and maps NaN to 0; the clamp keeps the law's range.
            let n = (u * scale) as i64;
            n.clamp(f_min as i64, f_max as i64) as u32
        };
        match self {
            FeedLaw::Paper => frc::next_feed(f, e, step, f_min, f_max),
            FeedLaw::Integral(l) => to_feed(l.next(f as f32 / scale, 1.0 - e)),
            FeedLaw::Mrac(l) => to_feed(l.next(1.0 - e, achieved as f32 / scale)),
            FeedLaw::Gpc(l) => to_feed(l.next(1.0 - e, achieved as f32 / scale)),
        }
    }

    /// The law's on-line estimates, for plots and logs (host): GPC's theta = [a1, a2, b0, b1, b2]
    /// (the thesis' Fig. 5.11), MRAC's [p^, b^, 0, 0, 0]; None for the fixed laws (paper,
    /// integral). Reads the state only: the control is the same with or without the call.
    pub fn estimates(&self) -> Option<[f32; 5]> {
        match self {
            FeedLaw::Gpc(l) => Some(l.rls.theta),
            FeedLaw::Mrac(l) => {
                let [p, b] = l.rls.theta;
                Some([p, b, 0.0, 0.0, 0.0])
            }
            FeedLaw::Paper | FeedLaw::Integral(_) => None,
        }
    }

    /// After a hold, the law restarts from the controller's f_min: the reference model from the
    /// load now (0: the machine stands), the estimate kept.
    pub fn resume(&mut self) {
        match self {
            FeedLaw::Mrac(l) => {
                l.ym = 0.0;
                l.y_prev = 0.0;
            }
            FeedLaw::Gpc(l) => {
                l.ys = [0.0; 2];
                l.us = [0.0; 2];
            }
            FeedLaw::Paper | FeedLaw::Integral(_) => {}
        }
    }
}

/// Ulsoy, Koren and Lauderbaugh's simulated process (their Figs. 2 and 3), host (the tests and
/// the figure of `ac_laws`): y(k) = 0.1 y(k-1) + b0 u(k-1) with b0 proportional to the depth of
/// cut, 1 -> 2 -> 3 mm at equal lengths of `periods_per_depth` AC periods; the law tuned for
/// 1 mm (steady y = 1 at f = 1500 of f_max = 3000, f_min = 1, the FRC's step 750). Calls
/// `each(y, f)` once per period with the load and the feed number the law commands next.
pub fn depth_step_model(
    strategy: Strategy,
    periods_per_depth: usize,
    mut each: impl FnMut(f32, u32),
) {
    let (f_min, f_max, f_nom) = (1u32, 3000u32, 1500u32);
    let b1 = (1.0 - NOMINAL_POLE) / (f_nom as f32 / f_max as f32);
    let mut law = FeedLaw::new(strategy, f_nom, f_max, 1.0);
    let (mut y, mut f) = (0.0f32, f_min);
    for depth in 1..=3 {
        for _ in 0..periods_per_depth {
            y = NOMINAL_POLE * y + depth as f32 * b1 * (f as f32 / f_max as f32);
            f = law.next(f, 1.0 - y, f, 750.0, f_min, f_max);
            each(y, f);
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    fn depth_steps(strategy: Strategy, periods_per_depth: usize) -> Vec<f32> {
        let mut out = Vec::new();
        super::depth_step_model(strategy, periods_per_depth, |y, _| out.push(y));
        out
    }

    fn spread(y: &[f32]) -> f32 {
        let max = y.iter().cloned().fold(f32::MIN, f32::max);
        let min = y.iter().cloned().fold(f32::MAX, f32::min);
        max - min
    }

    #[test]
    fn integral_tuned_at_1_mm_settles_there_and_oscillates_at_3_mm() {
        let n = 300;
        let y = depth_steps(Strategy::Integral, n);
        // 1 mm: settled on the reference.
        assert!(
            y[n - 50..n].iter().all(|v| (v - 1.0).abs() < 0.01),
            "{:?}",
            &y[n - 5..n]
        );
        // 3 mm: the oscillation does not die out (the unstable loop runs into the feed limits).
        let late = &y[3 * n - 100..3 * n];
        assert!(spread(late) > 1.0, "spread {}", spread(late));
        // ... and it is no start-up transient: just as large at the end as after the step.
        let early = &y[2 * n + 10..2 * n + 110];
        assert!(spread(late) >= 0.9 * spread(early));
    }

    /// The GPC law at the defaults (nominal feed half of f_max) with its estimate set to `theta`.
    fn gpc_from(theta: [f32; 5]) -> GpcLaw {
        let mut law = GpcLaw::new(
            NOMINAL_POLE,
            0.5,
            crate::ac::AcSettings::default().gpc_lambda,
        );
        law.rls.theta = theta;
        law
    }

    /// The estimate a 3D raster left after a plunge at the row's start (the alarm corpus,
    /// `millac_qemu::alarmlab`): a positive steady gain, but b0 < 0 and a step response whose sum
    /// over the horizon is negative. With a load of 1.5 % of the reference (too little to update
    /// the estimate) the law must raise the feed, not hold it at f_min, where it crawled at
    /// 1 ipm for 40 s and the breakage monitor then misread the tiny force.
    #[test]
    fn gpc_raises_the_feed_on_a_light_load_whatever_a_falling_estimate_says() {
        let theta = [
            -1.104_875_8,
            0.304_739_33,
            -0.139_098_99,
            0.113_709_53,
            0.132_812_47,
        ];
        let [a1, a2, b0, b1, b2] = theta;
        // The premise: the steady gain alone would accept it, the horizon falls.
        assert!((b0 + b1 + b2) / (1.0 + a1 + a2) > 0.0);
        assert!(step_response(&theta).iter().sum::<f32>() < 0.0);
        let mut law = gpc_from(theta);
        let mut u = 0.02f32;
        for _ in 0..20 {
            u = law.next(0.015, u).clamp(0.02, 1.0);
        }
        assert!(u > 0.3, "u = {u}");
        assert_eq!(law.rls.theta, theta, "a light load leaves the estimate");
    }

    /// The corner end mill of the Fig. 1 job meeting the roughing's corner radius
    /// (`millac-qemu host` on `millac-qemu job`'s program, T3 at 138.26 s): the law's state there
    /// (an estimate nearly an integrator, b0 < 0, its step response over the horizon falling)
    /// and the 48 periods of load and achieved feed that followed, replayed. The load is a
    /// twentieth to a third of the reference, enough to update the estimate, and the law must
    /// not ask for less feed than the machine achieves: with the estimate steering it asked for
    /// less in every period, the feed fell from 12 to 0.6 ipm at the machine's deceleration and
    /// stayed at the floor 3.6 s at 6 % of the reference, the estimate frozen.
    #[test]
    fn gpc_does_not_lower_the_feed_on_a_load_well_below_the_reference_whatever_a_falling_estimate_says(
    ) {
        let theta = [
            -1.114_431_5,
            0.183_744_73,
            -0.181_118_07,
            0.362_116_96,
            -0.136_657_77,
        ];
        // The premise: its step response falls over the horizon.
        assert!(step_response(&theta).iter().sum::<f32>() < 0.0);
        let mut law = gpc_from(theta);
        law.rls.p = [
            [
                1.750_869_3,
                -1.562_933_1,
                -1.502_304_9,
                1.626_025_2,
                -0.042_283_658,
            ],
            [
                -1.562_933_1,
                1.678_783_7,
                1.557_722_3,
                -1.645_637_8,
                0.105_295_345,
            ],
            [
                -1.502_304_9,
                1.557_722_3,
                11.147_64,
                -14.541_93,
                3.521_274_3,
            ],
            [
                1.626_025_2,
                -1.645_637_8,
                -14.541_93,
                26.558_93,
                -12.008_438,
            ],
            [
                -0.042_283_658,
                0.105_295_345,
                3.521_274_3,
                -12.008_438,
                8.863_772,
            ],
        ];
        law.ys = [0.172_200_5, 0.017_725_348];
        law.us = [0.4, 0.4];
        // (load y, achieved feed u) of each period, as the run gave them to the law.
        let periods = [
            (0.1722, 0.4),
            (0.2000, 0.4),
            (0.2000, 0.38),
            (0.2000, 0.38),
            (0.1692, 0.38),
            (0.3360, 0.36),
            (0.3360, 0.36),
            (0.3360, 0.34),
            (0.3606, 0.34),
            (0.3606, 0.32),
            (0.3606, 0.32),
            (0.3197, 0.3),
            (0.3197, 0.3),
            (0.3197, 0.3),
            (0.3193, 0.28),
            (0.3257, 0.28),
            (0.3321, 0.26),
            (0.3321, 0.26),
            (0.3692, 0.24),
            (0.3692, 0.24),
            (0.3692, 0.24),
            (0.3210, 0.22),
            (0.3210, 0.22),
            (0.3194, 0.2),
            (0.3194, 0.2),
            (0.3148, 0.2),
            (0.3131, 0.18),
            (0.3131, 0.18),
            (0.2876, 0.16),
            (0.2876, 0.16),
            (0.2757, 0.16),
            (0.2741, 0.14),
            (0.2741, 0.14),
            (0.2518, 0.12),
            (0.2518, 0.12),
            (0.2152, 0.12),
            (0.1810, 0.1),
            (0.2136, 0.1),
            (0.2136, 0.08),
            (0.2136, 0.08),
            (0.1629, 0.08),
            (0.1272, 0.06),
            (0.1272, 0.06),
            (0.1215, 0.04),
            (0.1215, 0.04),
            (0.0955, 0.04),
            (0.0633, 0.02),
            (0.0633, 0.04f32),
        ];
        for (k, (y, achieved)) in periods.into_iter().enumerate() {
            let u = law.next(y, achieved);
            assert!(
                u >= achieved,
                "period {k}: load {y}, achieved {achieved}, asks {u}"
            );
        }
    }

    #[test]
    fn mrac_stays_within_a_band_of_its_reference_at_every_depth() {
        let n = 300;
        let y = depth_steps(Strategy::Mrac, n);
        for depth in 0..3 {
            // After 20 periods of adaptation and the model's own rise, within 5 % of the
            // reference (the model's output has reached 1 within 1e-6 by then).
            let seg = &y[depth * n + 20..(depth + 1) * n];
            let worst = seg.iter().map(|v| (v - 1.0).abs()).fold(0.0, f32::max);
            assert!(worst < 0.05, "depth {}: {worst}", depth + 1);
        }
    }

    #[test]
    fn gpc_stays_within_a_band_of_its_reference_at_every_depth() {
        let n = 300;
        let y = depth_steps(Strategy::Gpc, n);
        for depth in 0..3 {
            let seg = &y[depth * n + 20..(depth + 1) * n];
            let worst = seg.iter().map(|v| (v - 1.0).abs()).fold(0.0, f32::max);
            assert!(worst < 0.05, "depth {}: {worst}", depth + 1);
        }
    }

    /// The thesis' plant form (Eq. 3.23): a second-order process with a delay, its gain doubling
    /// mid-run (a deeper cut). GPC, started from the first-order nominal model, identifies it
    /// and regulates the load to the reference without offset at both gains; the estimated
    /// steady gain B(1)/A(1) follows the process's.
    #[test]
    fn gpc_identifies_a_second_order_process_and_regulates_without_offset() {
        let (a1, a2, b0, b1, b2) = (-0.6f32, 0.08f32, 0.5f32, 0.3f32, 0.05f32);
        let mut law = GpcLaw::new(NOMINAL_POLE, 0.5, 1.0);
        let (mut y, mut y1, mut u1, mut u2, mut u3) = (0.0f32, 0.0, 0.0, 0.0, 0.0);
        let mut ys = Vec::new();
        for k in 0..600 {
            let gain = if k < 300 { 1.0 } else { 2.0 };
            let y_new = -a1 * y - a2 * y1 + gain * (b0 * u1 + b1 * u2 + b2 * u3);
            y1 = y;
            y = y_new;
            ys.push(y);
            let u = law.next(y, u1).clamp(0.0, 1.0);
            (u3, u2, u1) = (u2, u1, u);
            if k == 299 || k == 599 {
                let [ea1, ea2, eb0, eb1, eb2] = law.rls.theta;
                let est = (eb0 + eb1 + eb2) / (1.0 + ea1 + ea2);
                let real = gain * (b0 + b1 + b2) / (1.0 + a1 + a2);
                assert!(
                    (est - real).abs() < 0.1 * real,
                    "k {k}: gain {est} vs {real}"
                );
            }
        }
        for seg in [&ys[250..300], &ys[550..600]] {
            let worst = seg.iter().map(|v| (v - 1.0).abs()).fold(0.0, f32::max);
            assert!(worst < 0.02, "{worst}");
        }
    }

    /// The estimates a run can plot: the fixed laws have none; MRAC and GPC start at their
    /// nominal model and report the estimator's theta as it moves.
    #[test]
    fn estimates_are_the_estimators_theta() {
        let (f_nom, f_max) = (1500u32, 3000u32);
        let b = (1.0 - NOMINAL_POLE) / 0.5;
        for s in [Strategy::Paper, Strategy::Integral] {
            assert_eq!(FeedLaw::new(s, f_nom, f_max, 1.0).estimates(), None);
        }
        let mut mrac = FeedLaw::new(Strategy::Mrac, f_nom, f_max, 1.0);
        assert_eq!(mrac.estimates(), Some([NOMINAL_POLE, b, 0.0, 0.0, 0.0]));
        let mut gpc = FeedLaw::new(Strategy::Gpc, f_nom, f_max, 1.0);
        assert_eq!(gpc.estimates(), Some([-NOMINAL_POLE, 0.0, b, 0.0, 0.0]));
        // A process twice the nominal gain moves the estimates away from the nominal.
        let (mut y, mut f) = (0.0f32, f_nom);
        for _ in 0..50 {
            y = NOMINAL_POLE * y + 2.0 * b * (f as f32 / f_max as f32);
            f = mrac.next(f, 1.0 - y, f, 750.0, 1, f_max);
        }
        let FeedLaw::Mrac(l) = mrac else { panic!() };
        assert_eq!(mrac.estimates().unwrap()[..2], l.rls.theta);
        assert!(
            mrac.estimates().unwrap()[1] > 1.5 * b,
            "{:?}",
            mrac.estimates()
        );
        let (mut y, mut f) = (0.0f32, f_nom);
        for _ in 0..50 {
            y = NOMINAL_POLE * y + 2.0 * b * (f as f32 / f_max as f32);
            f = gpc.next(f, 1.0 - y, f, 750.0, 1, f_max);
        }
        let FeedLaw::Gpc(l) = gpc else { panic!() };
        assert_eq!(gpc.estimates(), Some(l.rls.theta));
        assert_ne!(l.rls.theta, [-NOMINAL_POLE, 0.0, b, 0.0, 0.0]);
    }

    #[test]
    fn strategy_names_round_trip() {
        for s in Strategy::ALL {
            assert_eq!(Strategy::from_name(s.name()), Some(s));
        }
        assert_eq!(Strategy::from_name("all"), None);
    }

    #[test]
    fn the_integral_gain_places_the_nominal_poles_at_plus_minus_j_sqrt_a() {
        let l = IntegralLaw::tuned(0.1, 0.5);
        let b = 0.9 / 0.5;
        // z^2 - (1 + a - b ki) z + a: the sum of the poles is zero.
        assert!((1.0 + 0.1 - b * l.ki).abs() < 1e-6);
    }

    #[test]
    fn rls_with_a_constant_trace_tracks_a_step_in_the_process_gain() {
        let mut r = Rls::new([0.1, 1.0], RLS_TRACE, 0.0);
        let (mut y, mut k) = (0.0f32, 0u32);
        for b in [1.8f32, 3.6] {
            for _ in 0..100 {
                // A varying feed: the regressor stays excited.
                k += 1;
                let u = 0.3 + 0.2 * ((k % 7) as f32 / 7.0);
                let y_new = 0.1 * y + b * u;
                r.update(&[y, u], y_new);
                y = y_new;
            }
            assert!(
                (r.theta[1] - b).abs() < 0.01 * b,
                "b^ {} for {b}",
                r.theta[1]
            );
            assert!((r.theta[0] - 0.1).abs() < 0.01, "p^ {}", r.theta[0]);
        }
        // The dead zone: errors inside it change nothing.
        let mut r = Rls::new([0.1, 1.0], RLS_TRACE, 0.05);
        let before = r.theta;
        r.update(&[0.5, 0.5], 0.1 * 0.5 + 1.0 * 0.5 + 0.04);
        assert_eq!(r.theta, before);
    }
}
