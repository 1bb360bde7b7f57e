//! Analytic stability lobes of milling (host; the chatter model's check and the chatter
//! suppression's spindle-speed choice call it): Altintas and Budak's zero-order solution
//! ("Analytical prediction of stability lobes in milling", CIRP Annals 44/1, 1995; Altintas,
//! "Manufacturing Automation", ch. 4) for a tool flexible in X and Y, each direction a sum of
//! modes, cutting with straight flutes between an entry and an exit angle.
//!
//! The model:
//! - Tool modes: per direction, `Phi(iw) = sum 1 / (k (1 - r^2 + 2 i zeta r))`, `r = w / wn`
//!   (compliance, m/N).
//! - The dynamic chip regenerates between successive teeth; the time-varying directional
//!   coefficients are averaged over the tooth pitch (the zero-order term):
//!   `a_xx = 1/2 [cos 2p - 2 Kr p + Kr sin 2p]`, `a_xy = 1/2 [-sin 2p - 2p + Kr cos 2p]`,
//!   `a_yx = 1/2 [-sin 2p + 2p + Kr cos 2p]`, `a_yy = 1/2 [-cos 2p - 2 Kr p - Kr sin 2p]`,
//!   each evaluated from the entry angle to the exit angle (p measured clockwise from the +Y
//!   axis, the book's convention).
//! - At a chatter frequency `wc` the eigenvalue `L` of `det(I + L [a][Phi(i wc)]) = 0`, with
//!   `a0 L^2 + a1 L + 1 = 0`, `a0 = Phi_xx Phi_yy (a_xx a_yy - a_xy a_yx)`,
//!   `a1 = a_xx Phi_xx + a_yy Phi_yy` (no cross compliance), gives the critical depth
//!   `a_lim = -2 pi L_R / (N Kt) (1 + kappa^2)`, `kappa = L_I / L_R`, and the spindle speeds
//!   `n = 60 / (N T)`, `T = (eps + 2 k pi) / wc`, `eps = pi - 2 atan(kappa)`, lobe k = 0, 1, ...
//!
//! Units: N, m, s, rad (Kt in N/m^2 = Ks, the specific cutting pressure).
use num_complex::Complex64;
use std::f64::consts::PI;

/// One vibration mode of the tool in one direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mode {
    /// Natural frequency, Hz.
    pub fn_hz: f64,
    /// Damping ratio.
    pub zeta: f64,
    /// Modal stiffness, N/m.
    pub k_n_m: f64,
}

impl Mode {
    /// Compliance at `w` rad/s, m/N.
    pub fn frf(&self, w: f64) -> Complex64 {
        let r = w / (2.0 * PI * self.fn_hz);
        1.0 / (self.k_n_m * Complex64::new(1.0 - r * r, 2.0 * self.zeta * r))
    }
}

/// The cut: flutes, cutting coefficients and the engagement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LobeCut {
    pub flutes: u32,
    /// Tangential cutting coefficient (specific cutting pressure), N/m^2.
    pub kt: f64,
    /// Radial to tangential force ratio.
    pub kr: f64,
    /// Entry and exit angles, rad (clockwise from +Y): a full slot is 0 to pi; half immersion up
    /// milling 0 to pi/2, down milling pi/2 to pi.
    pub entry_rad: f64,
    pub exit_rad: f64,
}

/// The averaged directional coefficients [[a_xx, a_xy], [a_yx, a_yy]] of `cut`.
pub fn directional(cut: &LobeCut) -> [[f64; 2]; 2] {
    let kr = cut.kr;
    let at = |p: f64| {
        let (s2, c2) = (2.0 * p).sin_cos();
        [
            [
                0.5 * (c2 - 2.0 * kr * p + kr * s2),
                0.5 * (-s2 - 2.0 * p + kr * c2),
            ],
            [
                0.5 * (-s2 + 2.0 * p + kr * c2),
                0.5 * (-c2 - 2.0 * kr * p - kr * s2),
            ],
        ]
    };
    let (a, b) = (at(cut.exit_rad), at(cut.entry_rad));
    [
        [a[0][0] - b[0][0], a[0][1] - b[0][1]],
        [a[1][0] - b[1][0], a[1][1] - b[1][1]],
    ]
}

/// The summed compliance of `modes` at `w` rad/s (zero without modes: a rigid direction).
pub fn compliance(modes: &[Mode], w: f64) -> Complex64 {
    modes.iter().map(|m| m.frf(w)).sum()
}

/// One point of a lobe: spindle speed (rpm), critical axial depth (m), chatter frequency (Hz)
/// and lobe number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LobePoint {
    pub rpm: f64,
    pub a_lim_m: f64,
    pub chatter_hz: f64,
    pub lobe: u32,
}

/// The critical depth and the phase `eps` at chatter frequency `wc` (rad/s), from the eigenvalue
/// that gives the smallest positive depth; None where neither gives a positive one.
pub fn critical_at(cut: &LobeCut, x: &[Mode], y: &[Mode], wc: f64) -> Option<(f64, f64)> {
    let a = directional(cut);
    let (gx, gy) = (compliance(x, wc), compliance(y, wc));
    let a0 = gx * gy * (a[0][0] * a[1][1] - a[0][1] * a[1][0]);
    let a1 = a[0][0] * gx + a[1][1] * gy;
    let roots: Vec<Complex64> = if a0.norm() < 1e-30 * a1.norm().powi(2) {
        // One flexible direction (or a degenerate matrix): a1 L + 1 = 0.
        vec![-1.0 / a1]
    } else {
        let d = (a1 * a1 - 4.0 * a0).sqrt();
        vec![-(a1 + d) / (2.0 * a0), -(a1 - d) / (2.0 * a0)]
    };
    let n = f64::from(cut.flutes);
    roots
        .into_iter()
        .filter(|l| l.re.is_finite() && l.im.is_finite() && l.re != 0.0)
        .map(|l| {
            let kappa = l.im / l.re;
            let a_lim = -2.0 * PI * l.re / (n * cut.kt) * (1.0 + kappa * kappa);
            (a_lim, PI - 2.0 * kappa.atan())
        })
        .filter(|(a_lim, _)| *a_lim > 0.0)
        .min_by(|p, q| p.0.total_cmp(&q.0))
}

/// The stability lobes over chatter frequencies from `f_lo_hz` to `f_hi_hz` (`steps` points)
/// for lobes 0..`lobes`: one curve of points per lobe, ordered by chatter frequency.
pub fn lobes(
    cut: &LobeCut,
    x: &[Mode],
    y: &[Mode],
    (f_lo_hz, f_hi_hz): (f64, f64),
    steps: usize,
    lobes: u32,
) -> Vec<Vec<LobePoint>> {
    let n = f64::from(cut.flutes);
    (0..lobes)
        .map(|k| {
            (0..steps)
                .filter_map(|i| {
                    let f = f_lo_hz + (f_hi_hz - f_lo_hz) * i as f64 / (steps.max(2) - 1) as f64;
                    let wc = 2.0 * PI * f;
                    let (a_lim, eps) = critical_at(cut, x, y, wc)?;
                    let t = (eps + 2.0 * PI * f64::from(k)) / wc;
                    Some(LobePoint {
                        rpm: 60.0 / (n * t),
                        a_lim_m: a_lim,
                        chatter_hz: f,
                        lobe: k,
                    })
                })
                .collect()
        })
        .collect()
}

/// The critical depth at spindle speed `rpm`: the smallest depth of any lobe there (linear
/// interpolation between the computed points of each lobe), from `lobes(..)`'s curves. None when
/// no lobe covers the speed.
pub fn a_lim_at(curves: &[Vec<LobePoint>], rpm: f64) -> Option<f64> {
    curves
        .iter()
        .filter_map(|c| {
            c.windows(2).find_map(|w| {
                let (p, q) = (w[0], w[1]);
                let (lo, hi) = if p.rpm < q.rpm { (p, q) } else { (q, p) };
                (lo.rpm <= rpm && rpm <= hi.rpm).then(|| {
                    let s = if hi.rpm > lo.rpm {
                        (rpm - lo.rpm) / (hi.rpm - lo.rpm)
                    } else {
                        0.0
                    };
                    lo.a_lim_m + s * (hi.a_lim_m - lo.a_lim_m)
                })
            })
        })
        .min_by(|a, b| a.total_cmp(b))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A 2-flute slot in aluminium (the tests' cut, here and in `crate::chatter`).
    pub(crate) const SLOT: LobeCut = LobeCut {
        flutes: 2,
        kt: 800e6,
        kr: 0.3,
        entry_rad: 0.0,
        exit_rad: PI,
    };
    /// A 2000 Hz tool mode (the tests' tool, here and in `crate::chatter`).
    pub(crate) const TOOL: Mode = Mode {
        fn_hz: 2000.0,
        zeta: 0.03,
        k_n_m: 8e6,
    };

    /// A tool flexible in Y only, a full slot: a_yy = -Kr pi, and the eigenvalue is
    /// L = -1 / (a_yy G), so a_lim = 2 pi / (N Kt a_yy Re G) (positive where Re G < 0, above the
    /// resonance), whose smallest value is at min Re G = -1 / (4 k zeta (1 + zeta)):
    /// a_lim,min = 8 k zeta (1 + zeta) / (N Kt Kr).
    #[test]
    fn one_flexible_direction_matches_the_closed_form() {
        let a = directional(&SLOT);
        assert!((a[1][1] + SLOT.kr * PI).abs() < 1e-12, "{a:?}");
        let mut min = f64::INFINITY;
        for i in 0..20_000 {
            let f = 1500.0 + i as f64 * 0.05;
            let w = 2.0 * PI * f;
            let g = TOOL.frf(w);
            let want = 2.0 * PI / (2.0 * SLOT.kt * a[1][1] * g.re);
            match critical_at(&SLOT, &[], &[TOOL], w) {
                Some((got, _)) => {
                    assert!((got / want - 1.0).abs() < 1e-9, "{f} Hz: {got} vs {want}");
                    min = min.min(got);
                }
                None => assert!(want <= 0.0, "{f} Hz: none, closed form {want}"),
            }
        }
        let closed = 8.0 * TOOL.k_n_m * TOOL.zeta * (1.0 + TOOL.zeta) / (2.0 * SLOT.kt * SLOT.kr);
        assert!((min / closed - 1.0).abs() < 1e-3, "{min} vs {closed}");
    }

    /// At every computed lobe point the characteristic equation of the regenerative loop holds:
    /// det(I + L [a][Phi(i wc)]) = 0 with L = -(N / 4 pi) a_lim Kt (1 - e^(-i wc T)), T the tooth
    /// period of the point's speed. With two flexible directions (the quadratic's path) and one.
    #[test]
    fn every_lobe_point_solves_the_characteristic_equation() {
        let cases: [(&[Mode], &[Mode]); 2] = [(&[TOOL], &[TOOL]), (&[], &[TOOL])];
        for (x, y) in cases {
            let curves = lobes(&SLOT, x, y, (1800.0, 2600.0), 200, 4);
            let a = directional(&SLOT);
            let mut checked = 0;
            for p in curves.iter().flatten() {
                let wc = 2.0 * PI * p.chatter_hz;
                let t = 60.0 / (f64::from(SLOT.flutes) * p.rpm);
                let l = -(f64::from(SLOT.flutes) / (4.0 * PI))
                    * p.a_lim_m
                    * SLOT.kt
                    * (1.0 - Complex64::from_polar(1.0, -wc * t));
                let (gx, gy) = (compliance(x, wc), compliance(y, wc));
                let m = [[a[0][0] * gx, a[0][1] * gy], [a[1][0] * gx, a[1][1] * gy]];
                let det = (1.0 + l * m[0][0]) * (1.0 + l * m[1][1]) - l * l * m[0][1] * m[1][0];
                assert!(det.norm() < 1e-6, "{p:?}: det {det}");
                checked += 1;
            }
            assert!(checked > 100, "{checked} points");
        }
    }

    /// `a_lim_at` takes the lowest lobe at a speed, between the computed points.
    #[test]
    fn the_critical_depth_at_a_speed_is_the_lowest_lobe() {
        let curves = lobes(&SLOT, &[TOOL], &[TOOL], (1800.0, 2600.0), 400, 6);
        let rpm = 20_000.0;
        let a = a_lim_at(&curves, rpm).expect("covered");
        for c in &curves {
            for w in c.windows(2) {
                let (lo, hi) = (w[0].rpm.min(w[1].rpm), w[0].rpm.max(w[1].rpm));
                if lo <= rpm && rpm <= hi {
                    assert!(a <= w[0].a_lim_m.max(w[1].a_lim_m) + 1e-12);
                }
            }
        }
        assert!(a > 0.0 && a.is_finite());
    }
}
