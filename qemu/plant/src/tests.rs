//! Host tests of the cutting process and the oracle (host): stock parsing, forces against the
//! model, noise, determinism, the oracle's schedule.
use super::*;

const RATE: f64 = 1000.0;

fn blank() -> Stock {
    Stock::parse("blank X0 Y0 W5 H3 Z0").unwrap()
}

fn quiet() -> Transducer {
    Transducer {
        noise_sigma_codes: 0.0,
        ..Transducer::default()
    }
}

/// Straight move from `a` to `b` (BLU) at `ipm`, sampled at 1 kHz from `t0`; returns the samples
/// with the X position (in) of each.
fn run(p: &mut Process, t0: f64, a: [i64; 3], b: [i64; 3], ipm: f64) -> Vec<(f64, Sample)> {
    let d: Vec<f64> = (0..3).map(|k| (b[k] - a[k]) as f64).collect();
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let blu_s = ipm / 60.0 * 10_000.0;
    let n = (len / blu_s * RATE).ceil() as usize;
    (0..=n)
        .map(|i| {
            let f = ((i as f64 / RATE) * blu_s / len).min(1.0);
            let pos = [0, 1, 2].map(|k| a[k] + (d[k] * f).round() as i64);
            (pos[0] as f64 / 1e4, p.sample(t0 + i as f64 / RATE, pos))
        })
        .collect()
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0), |(s, n), x| (s + x, n + 1));
    s / n as f64
}

fn steel(stock: Stock, seed: u64) -> Process {
    Process::new(
        stock,
        Tool::default(),
        Material::STEEL,
        DEFAULT_RPM,
        seed,
        quiet(),
    )
    .unwrap()
}

/// Full-width slot in steel, 0.5 in four-flute end mill, 600 rpm, depth a = 0.2 in = 5.08 mm,
/// feed 12 ipm = 5.08 mm/s. Hand calculation:
/// - feed per tooth c = 5.08 mm/s / (4 teeth x 10 rev/s) = 0.127 mm;
/// - K = Ks a c = 2000 x 5.08 x 0.127 = 1290.3 N (tangential force of a tooth at h = c);
/// - full immersion (0..180 deg) with 4 teeth: two teeth in cut at phi and phi + 90 deg; summing
///   eq. 3.3/3.4 gives Fx = -Kr K, Fy = K for every phi, so F = K sqrt(1 + Kr^2) = 1347.1 N,
///   constant;
/// - torque T = R K (sin phi + cos phi), mean over a revolution R z K / pi = 6.35e-3 x 4 x
///   1290.3 / pi = 10.43 N*m, between R K = 8.19 and sqrt(2) R K = 11.59 N*m.
#[test]
fn full_slot_matches_hand_calculation() {
    let mut p = steel(blank(), 1);
    let s = run(
        &mut p,
        0.0,
        [-5000, 15000, -2000],
        [20000, 15000, -2000],
        12.0,
    );
    let steady: Vec<&Sample> = s
        .iter()
        .filter(|(x, _)| (0.6..1.9).contains(x))
        .map(|(_, s)| s)
        .collect();
    assert!(steady.len() > 6000);
    let k = 2000.0 * 5.08 * 0.127;
    let f_hand = k * (1.0f64 + 0.09).sqrt();
    let f_mean = mean(steady.iter().map(|s| s.f_true_n));
    assert!(
        (f_mean / f_hand - 1.0).abs() < 0.02,
        "F {f_mean} vs {f_hand}"
    );
    for s in &steady {
        assert!(
            (s.f_true_n / f_hand - 1.0).abs() < 0.08,
            "F {} vs {f_hand}",
            s.f_true_n
        );
        assert!(s.t_true_nm > 0.95 * 6.35e-3 * k && s.t_true_nm < 1.03 * 6.35e-3 * k * 2f64.sqrt());
    }
    let t_mean = mean(steady.iter().map(|s| s.t_true_nm));
    let t_hand = 6.35e-3 * 4.0 * k / std::f64::consts::PI;
    assert!(
        (t_mean / t_hand - 1.0).abs() < 0.02,
        "T {t_mean} vs {t_hand}"
    );
    // Noise-free codes are the quantised values: code = value / gain + 2048.
    let c = steady[100];
    assert_eq!(c.codes[1], (c.fu_n / 2.5 + 2048.0).round() as u16);
    assert_eq!(c.codes[0], (c.t_true_nm / 0.05 + 2048.0).round() as u16);
}

#[test]
fn force_is_proportional_to_feed() {
    let f_at = |ipm: f64| {
        let mut p = steel(blank(), 1);
        let s = run(
            &mut p,
            0.0,
            [-5000, 15000, -2000],
            [15000, 15000, -2000],
            ipm,
        );
        mean(
            s.iter()
                .filter(|(x, _)| (0.6..1.4).contains(x))
                .map(|(_, s)| s.f_true_n),
        )
    };
    let r = f_at(12.0) / f_at(6.0);
    assert!((r - 2.0).abs() < 0.02, "ratio {r}");
}

#[test]
fn zero_force_in_air_and_in_the_drilled_hole() {
    // Above the stock.
    let mut p = steel(blank(), 1);
    let s = run(&mut p, 0.0, [0, 15000, 1000], [30000, 15000, 1000], 30.0);
    assert!(s
        .iter()
        .all(|(_, s)| s.f_true_n == 0.0 && s.t_true_nm == 0.0));
    // Fig. 1: plunge into the drilled start hole (XY fixed), then dwell.
    let mut p = steel(Stock::default(), 1);
    let s = run(
        &mut p,
        0.0,
        [12500, 15000, 1000],
        [12500, 15000, -6000],
        10.0,
    );
    assert!(s
        .iter()
        .all(|(_, s)| s.f_true_n == 0.0 && s.t_true_nm == 0.0));
    // Moving inside a hole wider than the tool.
    let st = Stock::parse("blank X0 Y0 W5 H3 Z0\nhole X2 Y1.5 D1.0 Z-0.6").unwrap();
    let mut p = steel(st, 1);
    let s = run(
        &mut p,
        0.0,
        [18500, 15000, -5000],
        [21500, 15000, -5000],
        12.0,
    );
    assert!(s.iter().all(|(_, s)| s.f_true_n == 0.0));
}

/// Thesis test TIIM (Table 5.6): Al 7075-T6, 25.4 mm four-flute end mill, 885 rpm, width of cut
/// 19 mm, depth stepping from 7.62 to 10.5 mm. The force rises by the depth ratio 1.378.
#[test]
fn depth_step_raises_force_by_the_depth_ratio() {
    let z_tip: f64 = -10.5 / 25.4; // in
    let low = z_tip + 7.62 / 25.4;
    let st = Stock::parse(&format!(
        "blank X0 Y0 W5 H3 Z0\npocket X0 Y0 W2.5 H3 Z{low}"
    ))
    .unwrap();
    let tool = Tool {
        diameter_mm: 25.4,
        ..Tool::default()
    };
    let mut p = Process::new(st, tool, Material::ALUMINIUM, 885.0, 1, quiet()).unwrap();
    // Width 19 mm: the tool edge overlaps the blank edge Y0 by 19 mm.
    let y = ((19.0 - 12.7) / MM_PER_BLU).round() as i64;
    let zb = (z_tip * 1e4).round() as i64;
    let s = run(&mut p, 0.0, [-6000, y, zb], [45000, y, zb], 20.0);
    let f1 = mean(
        s.iter()
            .filter(|(x, _)| (1.0..2.0).contains(x))
            .map(|(_, s)| s.f_true_n),
    );
    let f2 = mean(
        s.iter()
            .filter(|(x, _)| (3.2..4.2).contains(x))
            .map(|(_, s)| s.f_true_n),
    );
    let r = f2 / f1;
    assert!((r / (10.5 / 7.62) - 1.0).abs() < 0.02, "ratio {r}");
}

#[test]
fn second_pass_along_the_same_path_cuts_air() {
    let mut p = steel(blank(), 1);
    let first = run(
        &mut p,
        0.0,
        [-5000, 15000, -2000],
        [20000, 15000, -2000],
        12.0,
    );
    let v0 = p.stock().volume_above_mm3(-10.0);
    let mut p = steel(p.into_stock(), 2);
    // Along the slot, stopping 0.1 in short of its round end: within about the probe margin
    // (0.25 mm) of the end the probes read the material beyond it (see the process docs).
    let second = run(
        &mut p,
        0.0,
        [-5000, 15000, -2000],
        [19000, 15000, -2000],
        12.0,
    );
    let f1 = first.iter().map(|(_, s)| s.f_true_n).fold(0.0, f64::max);
    let f2 = second.iter().map(|(_, s)| s.f_true_n).fold(0.0, f64::max);
    assert!(f1 > 1000.0);
    assert!(f2 == 0.0, "second pass peak {f2} N, first {f1} N");
    assert_eq!(p.stock().volume_above_mm3(-10.0), v0);
    // The slot removed 2 in x 0.5 in x 0.2 in (+ the round end), about 3330 mm^3.
    let removed = blank().volume_above_mm3(-10.0) - v0;
    let expect = (50.8 * 12.7 + std::f64::consts::PI * 6.35 * 6.35 / 2.0) * 5.08;
    assert!(
        (removed / expect - 1.0).abs() < 0.02,
        "{removed} vs {expect}"
    );
}

#[test]
fn fu_fv_rotate_with_the_spindle_and_f_is_invariant() {
    let mut p = steel(blank(), 1);
    let s = run(
        &mut p,
        0.0,
        [-5000, 15000, -2000],
        [15000, 15000, -2000],
        12.0,
    );
    let steady: Vec<&Sample> = s
        .iter()
        .filter(|(x, _)| (0.6..1.4).contains(x))
        .map(|(_, s)| s)
        .collect();
    let f = steady[0].f_true_n;
    for s in &steady {
        assert!((s.fu_n.hypot(s.fv_n) - s.f_true_n).abs() < 1e-9 * f);
    }
    // One revolution = 100 samples: Fu sweeps from -F to +F (F itself is constant here).
    let rev = &steady[..100];
    let fu_max = rev.iter().map(|s| s.fu_n).fold(f64::MIN, f64::max);
    let fu_min = rev.iter().map(|s| s.fu_n).fold(f64::MAX, f64::min);
    assert!(
        fu_max > 0.95 * f && fu_min < -0.95 * f,
        "{fu_min} {fu_max} {f}"
    );
    // ... with the spindle period: 0.1 s at 600 rpm.
    for i in 0..steady.len() - 100 {
        assert!((steady[i].fu_n - steady[i + 100].fu_n).abs() < 0.1 * f);
    }
}

#[test]
fn same_seed_same_bytes_other_seed_other_noise() {
    let codes = |seed: u64| {
        let mut p = Process::new(
            blank(),
            Tool::default(),
            Material::STEEL,
            600.0,
            seed,
            Transducer::default(),
        )
        .unwrap();
        run(
            &mut p,
            0.0,
            [-5000, 15000, -2000],
            [5000, 15000, -2000],
            12.0,
        )
        .iter()
        .map(|(_, s)| s.codes)
        .collect::<Vec<_>>()
    };
    let a = codes(7);
    assert_eq!(a, codes(7));
    let b = codes(8);
    assert_ne!(a, b);
    // Noise sigma about 2 codes on the idle channel (before the cut).
    let d: Vec<f64> = a[..1000].iter().map(|c| c[2] as f64 - 2048.0).collect();
    let sd = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    assert!((1.7..2.3).contains(&sd), "sigma {sd}");
}

#[test]
fn transducer_codes_clamp_at_the_rails() {
    let mut p = Process::new(blank(), Tool::default(), Material::STEEL, 600.0, 1, quiet()).unwrap();
    let s = run(
        &mut p,
        0.0,
        [-5000, 15000, -15000],
        [5000, 15000, -15000],
        30.0,
    );
    assert!(s.iter().any(|(_, s)| s.codes[1] == 4095 || s.codes[1] == 0));
}

#[test]
fn stock_parse_and_errors() {
    let st = Stock::default();
    assert_eq!(st.dims(), (508, 305));
    assert_eq!(st.top_at(1.25 * 25.4, 1.5 * 25.4), -0.6 * 25.4);
    assert_eq!(st.top_at(3.0 * 25.4, 1.5 * 25.4), 0.0);
    assert_eq!(st.top_at(-1.0, 1.0), f64::NEG_INFINITY);
    let st =
        Stock::parse("# x\ncell 0.1 # fine\nBLANK x0 y0 w1 h1 z0 b-1\npocket X0 Y0 W0.5 H1 Z-0.5")
            .unwrap();
    assert_eq!(st.dims(), (254, 254));
    assert_eq!(st.floor_mm(), -25.4);
    assert_eq!(st.top_at(5.0, 5.0), -0.5 * 25.4);
    let err = |s: &str| Stock::parse(s).unwrap_err().to_string();
    assert_eq!(
        err("# nothing"),
        "stock: no blank: at least one 'blank X.. Y.. W.. H.. Z..' line is needed"
    );
    assert_eq!(
        err("blank X0 Y0 W5 H3"),
        "stock line 1: blank: missing word Z"
    );
    assert_eq!(
        err("blank X0 Y0 W5 H3 Z0\nhole X1 Y1 D0.5 Z-1 Q2"),
        "stock line 2: hole: unexpected word 'Q2' (allowed words: X Y D Z)"
    );
    assert_eq!(
        err("blank X0 X1 Y0 W5 H3 Z0"),
        "stock line 1: blank: word X given twice"
    );
    assert_eq!(
        err("blank X0 Y0 W5 H3 Zabc"),
        "stock line 1: blank: 'Zabc' is not Z followed by a number"
    );
    assert_eq!(
        err("blank X0 Y0 W-5 H3 Z0"),
        "stock line 1: width W and height H must be > 0 (inches)"
    );
    assert_eq!(
        err("cell 0.5\nblank X0 Y0 W5 H3 Z0"),
        "stock line 1: cell: expected one size in mm, 0 < size <= 0.25"
    );
    assert_eq!(
        err("slab X0"),
        "stock line 1: unknown statement 'slab' (expected blank, hole, pocket or cell)"
    );
    assert_eq!(
        err("blank X0 Y0 W5 H3 Z0 B1"),
        "stock line 1: blank: bottom B must be below the top Z"
    );
    assert!(err("blank X0 Y0 W5000 H3000 Z0").contains("larger than"));
    let bad = Tool {
        flutes: 0,
        ..Tool::default()
    };
    assert!(Process::new(blank(), bad, Material::STEEL, 600.0, 1, quiet()).is_err());
    assert!(Process::new(blank(), Tool::default(), Material::STEEL, 0.0, 1, quiet()).is_err());
}

fn line(a: [i64; 3], b: [i64; 3], step: i64, ipm: f64) -> Vec<OraclePoint> {
    let n = (b[0] - a[0]).abs().max((b[1] - a[1]).abs()) / step;
    (0..=n)
        .map(|i| OraclePoint {
            pos_blu: [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * i / n),
            feed_ipm: ipm,
        })
        .collect()
}

/// The slot of `full_slot_matches_hand_calculation`: 1347.1 N at 12 ipm, so F0 = 3600 N allows
/// 12 x 3600 / 1347.1 = 32.07 ipm; torque 11.59 N*m peak at 12 ipm allows 89 ipm.
#[test]
fn oracle_on_a_slot_finds_the_force_limited_feed() {
    let tool = Tool::default();
    let lim = OracleLimits::for_tool(&tool);
    let path = line([-5000, 15000, -2000], [20000, 15000, -2000], 10, 40.0);
    let r = oracle_time(blank(), &tool, &Material::STEEL, 600.0, &path, &lim).unwrap();
    let mid = r.limit_ipm[path.len() / 2];
    let hand = 12.0 * 3600.0 / (2000.0 * 5.08 * 0.127 * 1.09f64.sqrt());
    assert!((mid / hand - 1.0).abs() < 0.02, "{mid} vs {hand}");
    assert_eq!(r.limit_ipm[0], 40.0); // in air: the programmed feed
    check_oracle(&path, &r, &lim);
}

fn check_oracle(path: &[OraclePoint], r: &OracleResult, lim: &OracleLimits) {
    for i in 0..path.len() {
        assert!(r.feed_profile[i] <= r.limit_ipm[i] + 1e-9);
        assert!(r.feed_profile[i] <= path[i].feed_ipm + 1e-9);
        assert!(r.f_peak_n[i] <= lim.f0_n * (1.0 + 1e-9));
        assert!(r.t_peak_nm[i] <= lim.t0_nm * (1.0 + 1e-9));
        if i > 0 {
            let ds_in: f64 = (0..3)
                .map(|k| ((path[i].pos_blu[k] - path[i - 1].pos_blu[k]) as f64 / 1e4).powi(2))
                .sum::<f64>()
                .sqrt();
            let dv2 = (r.feed_profile[i].powi(2) - r.feed_profile[i - 1].powi(2)).abs();
            assert!(dv2 <= 2.0 * lim.fdot_m_ipm_s * 60.0 * ds_in * (1.0 + 1e-9) + 1e-9);
        }
    }
}

/// Fig. 1 cut A then cut b (depth 0.6 in, then 0.45 in): the oracle respects the limits and the
/// acceleration and is never slower than the safe constant feed.
#[test]
fn oracle_respects_limits_and_beats_the_safe_constant_feed() {
    let tool = Tool::default();
    let mut path = line([12500, 15000, -6000], [22500, 15000, -6000], 10, 12.0);
    path.extend(line([22500, 15000, -4500], [32500, 15000, -4500], 10, 16.0));
    for rest in [false, true] {
        let lim = OracleLimits {
            from_rest: rest,
            ..OracleLimits::for_tool(&tool)
        };
        let r = oracle_time(
            Stock::default(),
            &tool,
            &Material::STEEL,
            600.0,
            &path,
            &lim,
        )
        .unwrap();
        check_oracle(&path, &r, &lim);
        let v_const = r.limit_ipm.iter().cloned().fold(f64::INFINITY, f64::min);
        // Constant feed over the 2.15 in (plus, from rest, the ramps up and down at fdot_m).
        let ramps = if rest { v_const / 750.0 } else { 0.0 };
        let t_const = 2.15 / (v_const / 60.0) + ramps;
        assert!(r.time_s <= t_const, "{} vs {t_const}", r.time_s);
        assert!(r.time_s.is_finite() && r.time_s > 2.0 / (16.0 / 60.0));
    }
}

/// Per-sample cost over a Fig. 1 cut A (printed; run with --nocapture --release to measure).
#[test]
fn per_sample_cost() {
    let mut p = steel(Stock::default(), 1);
    let t = std::time::Instant::now();
    let s = run(
        &mut p,
        0.0,
        [12500, 15000, -6000],
        [22500, 15000, -6000],
        12.0,
    );
    let us = t.elapsed().as_secs_f64() * 1e6 / s.len() as f64;
    println!("per sample: {us:.2} us over {} samples", s.len());
    assert!(s.iter().any(|(_, s)| s.f_true_n > 3000.0));
}

/// Oracle cost over Fig. 1 cut A at 10 BLU spacing (printed).
#[test]
fn oracle_cost() {
    let tool = Tool::default();
    let path = line([12500, 15000, -6000], [22500, 15000, -6000], 10, 12.0);
    let t = std::time::Instant::now();
    let lim = OracleLimits::for_tool(&tool);
    let r = oracle_time(
        Stock::default(),
        &tool,
        &Material::STEEL,
        600.0,
        &path,
        &lim,
    )
    .unwrap();
    let us = t.elapsed().as_secs_f64() * 1e6 / path.len() as f64;
    println!(
        "oracle: {us:.2} us per point, {} points, {:.2} s",
        path.len(),
        r.time_s
    );
    // 4041 N at 12 ipm in the full 0.6 in slot: the safe feed is 12 x 3600 / 4041 = 10.7 ipm.
    let mid = r.feed_profile[path.len() / 2];
    assert!((mid / (12.0 * 3600.0 / 4041.0) - 1.0).abs() < 0.02, "{mid}");
}
