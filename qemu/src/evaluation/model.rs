//! The model-based method of Georgiev and Chetrokov ("Metal cutting machines strain behavior
//! mathematical models based adaptive control"; issue 11), host: a quadratic model of the
//! cutting force's effect y = b0 + b1 a + b2 f + b12 a f + b11 a^2 + b22 f^2 in the depth of cut
//! a and the feed f, fitted by least squares from a few test cuts and kept with its validity
//! range (a_min..a_max, f_min..f_max); solved for the feed that holds y at a chosen level at the
//! depth present (their Eqs. 2-3). The offline optimiser (`crate::evaluation::optimise`) can use it in
//! place of the full force model.
//!
//! Choices (the paper fits a lathe's strain; here the milling force):
//! - y is the peak resultant force (N), a the axial depth of cut (mm) and f the feed (ipm);
//! - the test cuts are full-width slots, the worst radial engagement at each depth, so the
//!   model is conservative where the cut is narrower (the difference is measured in the
//!   benchmark);
//! - outside a_min..a_max the model is not used (the caller says what it does there); within it
//!   the feed is the root of Eq. 2 in f_min..f_max, or f_max where y stays below the level there
//!   (the paper's Eq. 3 bounds the root); where even f_min exceeds the level there is no
//!   solution in the range and the model is not used either.
use anyhow::{bail, Result};
use nalgebra::{DMatrix, DVector};

/// The fitted model and its validity range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quadratic {
    /// b0, b1, b2, b12, b11, b22.
    pub b: [f64; 6],
    /// The range of the test cuts: depth (mm) and feed (ipm).
    pub a_range: (f64, f64),
    pub f_range: (f64, f64),
}

/// One test cut: depth a (mm), feed f (ipm) and the force's effect y (N).
pub type TestCut = (f64, f64, f64);

/// The regressors of one point.
fn row(a: f64, f: f64) -> [f64; 6] {
    [1.0, a, f, a * f, a * a, f * f]
}

impl Quadratic {
    /// Least squares over the test cuts `(a, f, y)`: at least six, spanning both factors (the
    /// six regressors must be independent: three depths and three feeds in a grid at least).
    pub fn fit(points: &[(f64, f64, f64)]) -> Result<Quadratic> {
        if points.len() < 6 {
            bail!(
                "the quadratic model needs at least 6 test cuts, got {}",
                points.len()
            );
        }
        if let Some(p) = points
            .iter()
            .find(|p| !(p.0.is_finite() && p.1.is_finite() && p.2.is_finite()))
        {
            bail!("a test cut is not finite: {p:?}");
        }
        let x = DMatrix::from_fn(points.len(), 6, |i, j| row(points[i].0, points[i].1)[j]);
        let y = DVector::from_iterator(points.len(), points.iter().map(|p| p.2));
        let svd = x.clone().svd(true, true);
        let s = &svd.singular_values;
        let (max, min) = (s.max(), s.min());
        if min.is_nan() || min <= max * 1e-10 {
            bail!(
                "the test cuts do not determine the model (three depths and three feeds at least)"
            );
        }
        let b = svd
            .solve(&y, max * 1e-12)
            .map_err(|e| anyhow::anyhow!("least squares: {e}"))?;
        let range = |k: usize| {
            points
                .iter()
                .map(|p| if k == 0 { p.0 } else { p.1 })
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v), hi.max(v))
                })
        };
        Ok(Quadratic {
            b: [b[0], b[1], b[2], b[3], b[4], b[5]],
            a_range: range(0),
            f_range: range(1),
        })
    }

    /// y at depth `a` and feed `f`.
    pub fn eval(&self, a: f64, f: f64) -> f64 {
        row(a, f).iter().zip(self.b).map(|(x, b)| x * b).sum()
    }

    /// The depth is within the test cuts' range.
    pub fn covers(&self, a: f64) -> bool {
        self.a_range.0 <= a && a <= self.a_range.1
    }

    /// The feed in f_min..f_max that holds y at `level` at depth `a` (Eqs. 2-3): the largest
    /// root of `b22 f^2 + (b2 + b12 a) f + (b0 + b1 a + b11 a^2 - level) = 0` in the range where
    /// y crosses the level; f_max where y stays below it up to f_max. None outside a_min..a_max,
    /// and where y is above the level already at f_min (the feed it needs is below the test
    /// cuts': the model is not used there either).
    pub fn feed_for(&self, a: f64, level: f64) -> Option<f64> {
        if !self.covers(a) || !level.is_finite() {
            return None;
        }
        let (lo, hi) = self.f_range;
        if self.eval(a, hi) <= level {
            return Some(hi);
        }
        if self.eval(a, lo) > level {
            // Even f_min makes more than the level: no solution within the model's range.
            return None;
        }
        // y(lo) < level < y(hi): a root in between; the quadratic's, or by bisection where the
        // closed form is ill-conditioned (b22 near 0).
        let [b0, b1, b2, b12, b11, b22] = self.b;
        let (qa, qb, qc) = (b22, b2 + b12 * a, b0 + b1 * a + b11 * a * a - level);
        if qa.abs() > 1e-12 * (qb.abs() + qc.abs()).max(1e-300) {
            let disc = qb * qb - 4.0 * qa * qc;
            if disc >= 0.0 {
                let r = disc.sqrt();
                let roots = [(-qb + r) / (2.0 * qa), (-qb - r) / (2.0 * qa)];
                if let Some(f) = roots
                    .into_iter()
                    .filter(|f| (lo..=hi).contains(f))
                    .fold(None, |m: Option<f64>, f| Some(m.map_or(f, |m| m.max(f))))
                {
                    return Some(f);
                }
            }
        }
        let (mut l, mut h) = (lo, hi);
        for _ in 0..100 {
            let m = 0.5 * (l + h);
            if self.eval(a, m) <= level {
                l = m;
            } else {
                h = m;
            }
        }
        Some(l)
    }
}

/// One test cut's program: a full-width slot at `depth_mm` and `feed_ipm` from outside a 3 x 2 in
/// blank (top at Z0) to X1.2 in (the tool fully in the cut from X0.25 in on).
pub fn test_cut(depth_mm: f64, feed_ipm: f64) -> String {
    format!(
        "(millac calibration cut: full slot {depth_mm:.3} mm deep at F{feed_ipm:.2})\nG20 G90\nG0 Z0.1\nG0 X-0.4 Y1\nG0 Z-{:.4}\nG1 X1.2 F{feed_ipm:.2}\nG0 Z0.1\nM2\n",
        depth_mm / millac_plant::MM_PER_IN
    )
}

/// The stock of the test cuts.
pub const TEST_STOCK: &str = "blank X0 Y0 W3 H2 Z0\n";

/// The steady part of a test cut ([`test_cut`]): the tool centre from X 0.5 to 1.1 in (BLU of
/// 0.0001 in), in the cut (Z below the top). The entry and the exit are left out.
const STEADY_X_BLU: std::ops::RangeInclusive<i64> = 5_000..=11_000;

/// y of one test cut from its run's ac.csv (`millac run`'s, or a real machine's log turned into
/// it: the columns `x_blu`, `z_blu` and `f_meas_n`, the force the AC measured): the largest
/// measured force of the steady part ([`STEADY_X_BLU`]), as [`calibrate`] takes the plant's.
/// Bad input (no such columns, a number that does not parse, no period in the steady part) is
/// an error naming what is missing.
pub fn y_from_ac_csv(text: &str) -> Result<f64> {
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| anyhow::anyhow!("ac.csv is empty"))?
        .split(',')
        .collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h.trim() == name)
            .ok_or_else(|| anyhow::anyhow!("ac.csv has no column {name}"))
    };
    let (x, z, f) = (col("x_blu")?, col("z_blu")?, col("f_meas_n")?);
    let mut y: Option<f64> = None;
    for (i, line) in lines.enumerate() {
        let v: Vec<&str> = line.split(',').collect();
        let get = |k: usize| -> Result<f64> {
            v.get(k)
                .and_then(|s| s.trim().parse::<f64>().ok())
                .filter(|n| n.is_finite())
                .ok_or_else(|| anyhow::anyhow!("ac.csv line {}: column {k} is not a number", i + 2))
        };
        let (xv, zv, fv) = (get(x)?, get(z)?, get(f)?);
        if STEADY_X_BLU.contains(&(xv as i64)) && zv < 0.0 {
            y = Some(y.map_or(fv, |m: f64| m.max(fv)));
        }
    }
    y.ok_or_else(|| {
        anyhow::anyhow!(
            "ac.csv has no period in a test cut's steady part (tool centre X 0.5..1.1 in, Z below 0): not a calibration cut's log"
        )
    })
}

/// The model from test cuts cut on a machine: (a mm, f ipm, its run's ac.csv text) each, as
/// `millac calibrate --log A,F,FILE` reads them (see [`y_from_ac_csv`]). Returns the model and
/// the test cuts (a, f, y N).
pub fn calibrate_from_logs(cuts: &[(f64, f64, String)]) -> Result<(Quadratic, Vec<TestCut>)> {
    let mut pts = Vec::new();
    for (a, f, text) in cuts {
        let y = y_from_ac_csv(text).map_err(|e| anyhow::anyhow!("test cut {a} mm F{f}: {e}"))?;
        pts.push((*a, *f, y));
    }
    Ok((Quadratic::fit(&pts)?, pts))
}

/// Calibrates the model on the simulated plant (the cut's tool, material and spindle speed; its
/// stock is replaced by the test block): a full slot at every depth and feed of the grid, y the
/// largest resultant force (N) of the steady part (tool centre X 0.5 to 1.1 in, [`test_cut_y`]),
/// as a real machine's ac.csv gives it ([`calibrate_from_logs`]). Returns the model and the test
/// cuts (a mm, f ipm, y N).
pub fn calibrate(
    cut: &crate::host::acsim::Cut,
    depths_mm: &[f64],
    feeds_ipm: &[f64],
) -> Result<(Quadratic, Vec<TestCut>)> {
    let mut pts = Vec::new();
    for &a in depths_mm {
        for &f in feeds_ipm {
            pts.push((a, f, test_cut_y(cut, a, f)?));
        }
    }
    Ok((Quadratic::fit(&pts)?, pts))
}

/// One test cut ([`test_cut`]) on the simulated plant (the cut's tool, material and speed on the
/// test block): y, the largest resultant force (N) of its steady part ([`STEADY_X_BLU`]).
pub fn test_cut_y(cut: &crate::host::acsim::Cut, a: f64, f: f64) -> Result<f64> {
    let settings = millac::Settings::default();
    let stock = millac_plant::Stock::parse(TEST_STOCK).map_err(|e| anyhow::anyhow!("{e}"))?;
    let text = test_cut(a, f);
    let prog = crate::analysis::load_program(&text, &settings)
        .map_err(|e| anyhow::anyhow!("test cut {a} mm F{f}: {e}"))?;
    let c = crate::host::acsim::Cut {
        stock,
        ..cut.clone()
    };
    let run = crate::host::acsim::run(&prog, &settings, &c, None)?;
    Ok(run
        .rows
        .iter()
        .filter(|r| STEADY_X_BLU.contains(&r.pos_blu[0]) && r.pos_blu[2] < 0)
        .map(|r| r.f_true_n)
        .fold(0.0, f64::max))
}

impl Quadratic {
    /// The model file (JSON, stable keys): coefficients, validity range and the test cuts it
    /// was fitted from.
    pub fn to_json(&self, cuts: &[(f64, f64, f64)]) -> String {
        let v = serde_json::json!({
            "model": "y = b0 + b1 a + b2 f + b12 a f + b11 a^2 + b22 f^2 (Georgiev and Chetrokov); y peak resultant force N, a axial depth mm, f feed ipm",
            "b": { "b0": self.b[0], "b1": self.b[1], "b2": self.b[2], "b12": self.b[3], "b11": self.b[4], "b22": self.b[5] },
            "a_min_mm": self.a_range.0,
            "a_max_mm": self.a_range.1,
            "f_min_ipm": self.f_range.0,
            "f_max_ipm": self.f_range.1,
            "test_cuts": cuts.iter().map(|c| serde_json::json!({"a_mm": c.0, "f_ipm": c.1, "y_n": c.2})).collect::<Vec<_>>(),
        });
        serde_json::to_string_pretty(&v).unwrap_or_default()
    }

    /// Reads a model file ([`Quadratic::to_json`]'s form).
    pub fn from_json(text: &str) -> Result<Quadratic> {
        let v: serde_json::Value = serde_json::from_str(text)?;
        let num = |x: &serde_json::Value, k: &str| {
            x.get(k)
                .and_then(serde_json::Value::as_f64)
                .filter(|v| v.is_finite())
                .ok_or_else(|| anyhow::anyhow!("model file: {k} missing or not a finite number"))
        };
        let b = v
            .get("b")
            .ok_or_else(|| anyhow::anyhow!("model file: b missing"))?;
        let m = Quadratic {
            b: [
                num(b, "b0")?,
                num(b, "b1")?,
                num(b, "b2")?,
                num(b, "b12")?,
                num(b, "b11")?,
                num(b, "b22")?,
            ],
            a_range: (num(&v, "a_min_mm")?, num(&v, "a_max_mm")?),
            f_range: (num(&v, "f_min_ipm")?, num(&v, "f_max_ipm")?),
        };
        if !(m.a_range.0 <= m.a_range.1 && 0.0 < m.f_range.0 && m.f_range.0 <= m.f_range.1) {
            bail!("model file: the range is empty or the feeds not positive");
        }
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Georgiev and Chetrokov's own model (their Eq. 4, a boring bar's strain in um at a_p in mm
    /// and f in mm/rev over 0.25..0.75 mm and 0.1..0.5 mm/rev) is recovered from noiseless
    /// points of it, and solved for a level back to the feed that makes it.
    #[test]
    fn the_fit_recovers_known_coefficients_and_the_feed_for_a_level() {
        let truth = Quadratic {
            b: [8.0, 71.4, 8.0, 925.0, -120.4, -219.0],
            a_range: (0.25, 0.75),
            f_range: (0.1, 0.5),
        };
        let mut pts = Vec::new();
        for i in 0..5 {
            for j in 0..10 {
                let (a, f) = (0.25 + 0.125 * i as f64, 0.1 + 0.4 * j as f64 / 9.0);
                pts.push((a, f, truth.eval(a, f)));
            }
        }
        let m = Quadratic::fit(&pts).unwrap();
        for (got, want) in m.b.iter().zip(truth.b) {
            assert!((got - want).abs() < 1e-8 * want.abs().max(1.0), "{:?}", m.b);
        }
        assert_eq!((m.a_range, m.f_range), (truth.a_range, truth.f_range));
        // The feed for a level within reach at a = 0.5: the one whose strain is the level.
        let f = m.feed_for(0.5, truth.eval(0.5, 0.3)).unwrap();
        assert!((f - 0.3).abs() < 1e-9, "{f}");
        // Below the level everywhere: f_max; above it already at f_min, or outside: None.
        assert_eq!(m.feed_for(0.5, 1e6), Some(0.5));
        assert_eq!(m.feed_for(0.5, 0.0), None);
        assert_eq!(m.feed_for(0.8, 100.0), None);
        assert_eq!(m.feed_for(0.5, f64::NAN), None);
    }

    /// Too few cuts, cuts that leave a regressor undetermined (one depth only) and garbage are
    /// refused with a message.
    #[test]
    fn test_cuts_that_do_not_determine_the_model_are_refused() {
        let few: Vec<_> = (0..5).map(|k| (1.0, k as f64, 1.0)).collect();
        assert!(Quadratic::fit(&few)
            .unwrap_err()
            .to_string()
            .contains("at least 6"));
        let one_depth: Vec<_> = (0..9).map(|k| (1.0, k as f64, 2.0 * k as f64)).collect();
        assert!(Quadratic::fit(&one_depth)
            .unwrap_err()
            .to_string()
            .contains("do not determine"));
        let mut nan: Vec<_> = (0..9)
            .map(|k| ((k % 3) as f64, (k / 3) as f64, 1.0))
            .collect();
        nan[4].2 = f64::NAN;
        assert!(Quadratic::fit(&nan)
            .unwrap_err()
            .to_string()
            .contains("not finite"));
    }
}
