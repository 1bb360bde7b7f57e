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
    run_at(p, t0, a, b, ipm, RATE)
}

/// [`run`] sampled at `rate` Hz.
fn run_at(
    p: &mut Process,
    t0: f64,
    a: [i64; 3],
    b: [i64; 3],
    ipm: f64,
    rate: f64,
) -> Vec<(f64, Sample)> {
    let d: Vec<f64> = (0..3).map(|k| (b[k] - a[k]) as f64).collect();
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let blu_s = ipm / 60.0 * 10_000.0;
    let n = (len / blu_s * rate).ceil() as usize;
    (0..=n)
        .map(|i| {
            let f = ((i as f64 / rate) * blu_s / len).min(1.0);
            let pos = [0, 1, 2].map(|k| a[k] + (d[k] * f).round() as i64);
            (pos[0] as f64 / 1e4, p.sample(t0 + i as f64 / rate, pos))
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
    // Along the slot to its round end (a wall of the tool's radius just ahead at the end: the
    // material beyond it is not cut).
    let second = run(
        &mut p,
        0.0,
        [-5000, 15000, -2000],
        [20000, 15000, -2000],
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

/// The envelope (the optimiser's guard): holes, pockets and terraces filled to the stock's top,
/// nothing added outside the blanks.
#[test]
fn the_envelope_fills_every_blank_cell_to_the_top() {
    let st = Stock::parse(
        "blank X0 Y0 W1 H1 Z0\nblank X1 Y0 W1 H1 Z-0.2\nhole X0.5 Y0.5 D0.4 Z-0.5\npocket X1.2 Y0.2 W0.5 H0.5 Z-0.4",
    )
    .unwrap();
    let e = st.envelope();
    assert_eq!(e.dims(), st.dims());
    for (x, y) in [(0.5, 0.5), (1.5, 0.5), (1.3, 0.3), (0.1, 0.9)] {
        assert_eq!(e.top_at(x * 25.4, y * 25.4), 0.0, "({x}, {y})");
    }
    assert!(st.top_at(0.5 * 25.4, 0.5 * 25.4) < 0.0);
    let outside = Stock::parse("blank X0 Y0 W1 H1 Z0\nblank X1.5 Y0 W0.5 H1 Z0").unwrap();
    assert_eq!(
        outside.envelope().top_at(1.25 * 25.4, 0.5 * 25.4),
        f64::NEG_INFINITY
    );
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

/// Acceleration of the test paths, ipm/s (the paper's fdot_m).
const ACCEL_IPM_S: f64 = 750.0;

fn line(a: [i64; 3], b: [i64; 3], step: i64, ipm: f64) -> Vec<OraclePoint> {
    let n = (b[0] - a[0]).abs().max((b[1] - a[1]).abs()) / step;
    (0..=n)
        .map(|i| OraclePoint {
            pos_blu: [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * i / n),
            feed_ipm: ipm,
            accel_ipm_s: ACCEL_IPM_S,
            step_mm: None,
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
            assert!(dv2 <= 2.0 * path[i].accel_ipm_s * 60.0 * ds_in * (1.0 + 1e-9) + 1e-9);
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
        // Constant feed over the 2.15 in (plus, from rest, the ramps up and down).
        let ramps = if rest { v_const / ACCEL_IPM_S } else { 0.0 };
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

/// Straight plunge (XY fixed) from above the stock to `z_end` (BLU) at `ipm`, at X2.5 Y1.5 in.
fn plunge(p: &mut Process, z_end: i64, ipm: f64) -> Vec<(f64, Sample)> {
    let s = run(p, 0.0, [25000, 15000, 1000], [25000, 15000, z_end], ipm);
    // `run` reports X; the plunge's samples are told apart by time: the tip is in material after
    // 0.1 in of travel plus one tooth period.
    let t_in = 0.1 / (ipm / 60.0) + 0.05;
    s.into_iter()
        .enumerate()
        .filter(|(i, _)| *i as f64 / RATE > t_in)
        .map(|(_, s)| s)
        .collect()
}

/// End face, hand calculation: a full plunge of the 0.5 in four-flute end mill in steel at
/// 10 ipm, 600 rpm: c_z = 4.2333 mm/s / 40 teeth/s = 0.10583 mm; each end tooth cuts over
/// w = R = 6.35 mm, torque Ks c_z R^2 / 2 per tooth, T = 4 x 2000 x 0.10583 x 6.35^2 / 2 =
/// 17.07 N*m; Fa = Ka sum Ft = 0.5 x 4 x 2000 x 0.10583 x 6.35 = 2688 N; the radial forces of the
/// symmetric teeth cancel. Half the plunge feed, half the torque.
#[test]
fn plunge_into_solid_stock_makes_torque_proportional_to_the_plunge_feed() {
    let steady = |ipm: f64| {
        let mut p = steel(blank(), 1);
        let s = plunge(&mut p, -3000, ipm);
        // While plunging (the last tooth period slows down).
        let n = s.len();
        let inside = &s[..n - 60];
        assert!(inside.len() > 500, "{}", inside.len());
        (
            mean(inside.iter().map(|(_, s)| s.t_true_nm)),
            mean(inside.iter().map(|(_, s)| s.fa_n)),
            inside.iter().map(|(_, s)| s.f_true_n).fold(0.0, f64::max),
            inside
                .iter()
                .map(|(_, s)| s.t_true_nm)
                .fold(f64::INFINITY, f64::min),
        )
    };
    let cz = 10.0 * 25.4 / 60.0 / 40.0;
    let t_hand = 4.0 * 2000.0 * cz * 6.35 * 6.35 / 2.0 / 1000.0;
    let fa_hand = 0.5 * 4.0 * 2000.0 * cz * 6.35;
    let (t10, fa10, f10, t10_min) = steady(10.0);
    assert!((t10 / t_hand - 1.0).abs() < 0.03, "T {t10} vs {t_hand}");
    assert!(
        (fa10 / fa_hand - 1.0).abs() < 0.03,
        "Fa {fa10} vs {fa_hand}"
    );
    assert!(
        f10 < 0.02 * fa_hand,
        "radial force {f10} N in a full plunge"
    );
    // Every sample in the material sees the torque (no gaps between Z steps).
    assert!(t10_min > 0.8 * t_hand, "min T {t10_min}");
    let (t5, ..) = steady(5.0);
    assert!((t10 / t5 - 2.0).abs() < 0.04, "ratio {}", t10 / t5);
    // Slow plunge, fewer Z steps than samples: the torque does not drop between the steps.
    let (t2, _, _, t2_min) = steady(2.0);
    assert!((t2 / (t_hand / 5.0) - 1.0).abs() < 0.05, "T {t2}");
    assert!(t2_min > 0.5 * t2, "min T {t2_min} vs mean {t2}");
}

#[test]
fn plunge_into_air_or_a_drilled_hole_cuts_nothing() {
    // A hole deeper than the plunge, as wide as the tool.
    let st = Stock::parse("blank X0 Y0 W5 H3 Z0\nhole X2.5 Y1.5 D0.5 Z-0.4").unwrap();
    let mut p = steel(st, 1);
    let s = plunge(&mut p, -3000, 10.0);
    assert!(s
        .iter()
        .all(|(_, s)| s.t_true_nm == 0.0 && s.fa_n == 0.0 && s.f_true_n == 0.0));
    // The same plunge into the blank does cut (the test can fail).
    let mut p = steel(blank(), 1);
    let s = plunge(&mut p, -3000, 10.0);
    assert!(s.iter().any(|(_, s)| s.t_true_nm > 10.0));
    // Landing on the bottom of a hole of the same depth: nothing either.
    let st = Stock::parse("blank X0 Y0 W5 H3 Z0\nhole X2.5 Y1.5 D0.5 Z-0.3").unwrap();
    let mut p = steel(st, 1);
    let s = plunge(&mut p, -3000, 10.0);
    assert!(s.iter().all(|(_, s)| s.t_true_nm == 0.0 && s.fa_n == 0.0));
    // A hole half the tool's width: the rest of the end face cuts, with a net radial force.
    let st = Stock::parse("blank X0 Y0 W5 H3 Z0\nhole X2.5 Y1.5 D0.25 Z-0.4").unwrap();
    let mut p = steel(st, 1);
    let s = plunge(&mut p, -3000, 10.0);
    let t = s.iter().map(|(_, s)| s.t_true_nm).fold(0.0, f64::max);
    assert!(t > 10.0 && t < 18.0, "{t}");
}

/// A ramp (X and Z together) into the blank gets the side and the end-face contributions: the
/// axial force of the end face with the Z share of the feed, and side forces.
#[test]
fn a_ramp_cuts_with_the_side_and_the_end_face() {
    let mut p = steel(blank(), 1);
    // 1 in along X while going down 0.1 in, at 12 ipm.
    let s = run(&mut p, 0.0, [2000, 15000, 0], [12000, 15000, -1000], 12.0);
    let f = s.iter().map(|(_, s)| s.f_true_n).fold(0.0, f64::max);
    assert!(f > 100.0, "side force {f}");
    // The end-face part alone: c_z = 12 ipm x (0.1 / 1.005) / 40 per tooth.
    let cz = 12.0 * 25.4 / 60.0 * (0.1 / 1.01f64.sqrt()) / 40.0;
    let fa_hand = 0.5 * 4.0 * 2000.0 * cz * 6.35;
    let fa_mean = mean(
        s.iter()
            .filter(|(x, _)| (0.5..1.0).contains(x))
            .map(|(_, s)| s.fa_n),
    );
    assert!(
        (fa_mean / fa_hand - 1.0).abs() < 0.03,
        "{fa_mean} vs {fa_hand}"
    );
}

fn z_line(x: i64, y: i64, z0: i64, z1: i64, ipm: f64) -> Vec<OraclePoint> {
    let step = if z1 < z0 { -1 } else { 1 };
    (0..=(z1 - z0).abs())
        .map(|i| OraclePoint {
            pos_blu: [x, y, z0 + step * i],
            feed_ipm: ipm,
            accel_ipm_s: ACCEL_IPM_S,
            step_mm: None,
        })
        .collect()
}

/// The oracle limits a plunge into solid stock by T0: 17.07 N*m at 10 ipm (the hand calculation
/// above), so T0 = 72 N*m allows 42.2 ipm; into the drilled hole the programmed feed.
#[test]
fn oracle_limits_a_plunge_by_t0() {
    let tool = Tool::default();
    let lim = OracleLimits::for_tool(&tool);
    let path = z_line(25000, 15000, 1000, -3000, 100.0);
    let r = oracle_time(blank(), &tool, &Material::STEEL, 600.0, &path, &lim).unwrap();
    check_oracle(&path, &r, &lim);
    let cz10 = 10.0 * 25.4 / 60.0 / 40.0;
    let t10 = 4.0 * 2000.0 * cz10 * 6.35 * 6.35 / 2.0 / 1000.0;
    let hand = 10.0 * 72.0 / t10;
    let deep = r.limit_ipm[3000];
    assert!((deep / hand - 1.0).abs() < 0.03, "{deep} vs {hand}");
    assert_eq!(r.limit_ipm[500], 100.0); // above the stock
    let st = Stock::parse("blank X0 Y0 W5 H3 Z0\nhole X2.5 Y1.5 D0.5 Z-0.4").unwrap();
    let r = oracle_time(st, &tool, &Material::STEEL, 600.0, &path, &lim).unwrap();
    assert!(r.limit_ipm.iter().all(|&l| l == 100.0));
}

/// Kienzle's Ks(h): doubling the feed multiplies the force by 2^(1 - m) (side and end face).
#[test]
fn kienzle_force_grows_as_feed_to_the_one_minus_m() {
    let m = Material::STEEL_KIENZLE;
    let proc_ = |st: Stock| Process::new(st, Tool::default(), m, DEFAULT_RPM, 1, quiet()).unwrap();
    let f_at = |ipm: f64| {
        let mut p = proc_(blank());
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
    let expect = 2f64.powf(1.0 - m.ks_exponent);
    let r = f_at(12.0) / f_at(6.0);
    assert!((r / expect - 1.0).abs() < 0.01, "ratio {r} vs {expect}");
    assert!((r - 2.0).abs() > 0.2);
    let t_at = |ipm: f64| {
        let mut p = proc_(blank());
        let s = plunge(&mut p, -3000, ipm);
        mean(s[..s.len() - 60].iter().map(|(_, s)| s.t_true_nm))
    };
    let r = t_at(10.0) / t_at(5.0);
    assert!(
        (r / expect - 1.0).abs() < 0.02,
        "plunge ratio {r} vs {expect}"
    );
    // m = 0 is today's constant Ks; the Ks at 0.1 mm is the preset's.
    assert_eq!(Material::STEEL.ks_at(0.02), 2000.0);
    assert!((m.ks_at(0.1) - 2000.0).abs() < 1e-9);
    assert_eq!(m.ks_at(0.001), m.ks_at(H_MIN_MM));
    let bad = Material {
        ks_exponent: 1.0,
        ..Material::STEEL
    };
    assert!(Process::new(blank(), Tool::default(), bad, 600.0, 1, quiet()).is_err());
}

/// With Kienzle's Ks(h) the oracle's schedule keeps F <= F0 and T <= T0 at its points when
/// re-evaluated at the scheduled feeds (check_oracle), on the Fig. 1 cuts A and b and on a
/// plunge into solid stock; and the process at the oracle's slot limit peaks at F0.
#[test]
fn kienzle_oracle_stays_within_the_limits() {
    let tool = Tool::default();
    let m = Material::STEEL_KIENZLE;
    let lim = OracleLimits::for_tool(&tool);
    let mut path = line([12500, 15000, -6000], [22500, 15000, -6000], 10, 12.0);
    path.extend(line([22500, 15000, -4500], [32500, 15000, -4500], 10, 16.0));
    let r = oracle_time(Stock::default(), &tool, &m, 600.0, &path, &lim).unwrap();
    check_oracle(&path, &r, &lim);
    let plunge_path = z_line(25000, 15000, 1000, -3000, 100.0);
    let r = oracle_time(blank(), &tool, &m, 600.0, &plunge_path, &lim).unwrap();
    check_oracle(&plunge_path, &r, &lim);
    assert!(r.t_peak_nm.iter().any(|&t| t > 0.99 * lim.t0_nm));
    // Slot: the limit, run in the process, peaks at F0 (1 kHz samples: within a few percent).
    let path = line([-5000, 15000, -2000], [20000, 15000, -2000], 10, 60.0);
    let r = oracle_time(blank(), &tool, &m, 600.0, &path, &lim).unwrap();
    let v = r.limit_ipm[path.len() / 2];
    assert!(v < 60.0);
    let mut p = Process::new(blank(), tool, m, 600.0, 1, quiet()).unwrap();
    let s = run(&mut p, 0.0, [-5000, 15000, -2000], [20000, 15000, -2000], v);
    let f = s
        .iter()
        .filter(|(x, _)| (0.6..1.9).contains(x))
        .map(|(_, s)| s.f_true_n)
        .fold(0.0, f64::max);
    assert!(
        f <= lim.f0_n * 1.001 && f > 0.97 * lim.f0_n,
        "{f} vs {}",
        lim.f0_n
    );
}

// Run-out and damaged teeth (crate::teeth).

/// The chip of tooth `n` (cutting order) for an intact-tool chip `cc`, with `teeth` at `t_s`.
fn chip_of(teeth: &Teeth, z: u32, t_s: f64, n: u32, cc: f64) -> f64 {
    let mut d = [0.0; teeth::MAX_FLUTES];
    teeth.offsets(z, t_s, &mut d);
    teeth::chip_mm(((z - n) % z) as usize, z as usize, cc, &d[..z as usize])
}

/// Hand calculation of the run-out model on four teeth at an intact chip of 0.1 mm: +10 um of
/// run-out on tooth 1 gives it 0.11 mm and tooth 2 (the next) 0.09 mm; tooth 1 broken gives it 0
/// and tooth 2 0.2 mm; a 0.05 mm chip on tooth 1 gives it 0.05 and tooth 2 0.15 mm. Where the
/// intact chip (0.004 mm) is thinner than the run-out, tooth 1 takes the surface of tooth 0
/// (0.014 mm) and tooth 2 nothing.
#[test]
fn runout_and_damage_chip_hand_calculation() {
    let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
    let intact = Teeth::default();
    for n in 0..4 {
        assert_eq!(chip_of(&intact, 4, 0.0, n, 0.1), 0.1);
    }
    let mut ro = Teeth::default();
    ro.set_runout(4, &[0.0, 0.010, 0.0, 0.0]).unwrap();
    let h: Vec<f64> = (0..4).map(|n| chip_of(&ro, 4, 0.0, n, 0.1)).collect();
    assert!(
        close(h[0], 0.1) && close(h[1], 0.11) && close(h[2], 0.09) && close(h[3], 0.1),
        "{h:?}"
    );
    let thin: Vec<f64> = (0..4).map(|n| chip_of(&ro, 4, 0.0, n, 0.004)).collect();
    assert!(close(thin[1], 0.014) && thin[2] == 0.0, "{thin:?}");
    // The sum over a revolution is z c cos(alpha) whatever the offsets.
    assert!(close(thin.iter().sum(), 0.016), "{thin:?}");
    let mut br = Teeth::default();
    br.add(
        4,
        ToothEvent {
            tooth: 1,
            t_s: 2.0,
            damage: Damage::Broken,
        },
    )
    .unwrap();
    assert_eq!(chip_of(&br, 4, 1.999, 2, 0.1), 0.1, "before the break");
    let h: Vec<f64> = (0..4).map(|n| chip_of(&br, 4, 2.0, n, 0.1)).collect();
    assert_eq!(h, vec![0.1, 0.0, 0.2, 0.1]);
    let mut ch = Teeth::default();
    ch.add(
        4,
        ToothEvent {
            tooth: 1,
            t_s: 0.0,
            damage: Damage::Chipped { depth_mm: 0.05 },
        },
    )
    .unwrap();
    let h: Vec<f64> = (0..4).map(|n| chip_of(&ch, 4, 0.0, n, 0.1)).collect();
    assert!(
        close(h[0], 0.1) && close(h[1], 0.05) && close(h[2], 0.15) && close(h[3], 0.1),
        "{h:?}"
    );
    // Two teeth broken in a row: the next intact one takes three chips.
    let mut two = br.clone();
    two.add(
        4,
        ToothEvent {
            tooth: 2,
            t_s: 0.0,
            damage: Damage::Broken,
        },
    )
    .unwrap();
    let h: Vec<f64> = (0..4).map(|n| chip_of(&two, 4, 2.0, n, 0.1)).collect();
    assert!(close(h[3], 0.3) && h[1] == 0.0 && h[2] == 0.0, "{h:?}");
}

fn two_flutes(seed: u64) -> Process {
    Process::new(
        blank(),
        Tool {
            flutes: 2,
            ..Tool::default()
        },
        Material::STEEL,
        DEFAULT_RPM,
        seed,
        quiet(),
    )
    .unwrap()
}

/// Start of [`slot`]: half a sample, so the samples of a tooth period sit symmetrically about
/// the angles where teeth enter and leave the cut (the entering and the leaving tooth's halves
/// of a period are sampled alike).
const SLOT_T0: f64 = 0.5 / RATE;

/// A full-width slot at 12 ipm, 0.2 in deep (as `full_slot_matches_hand_calculation`) from
/// to X1.5 in (10 s), sampled from [`SLOT_T0`].
fn slot(p: &mut Process) -> Vec<(f64, Sample)> {
    run(
        p,
        SLOT_T0,
        [-5000, 15000, -2000],
        [15000, 15000, -2000],
        12.0,
    )
}

/// Per tooth period (start time, tooth that entered the cut in it, mean of `v`) of the complete
/// periods of a [`slot`], with the tool fully in the cut (X in
/// 0.4..1.4 in). The tooth n (cutting order, at the world angle -theta + n 2 pi / z) enters at
/// +90 degrees, so in period floor(z (theta / 2 pi + 1/4)).
fn tooth_periods(s: &[(f64, Sample)], z: u32, v: impl Fn(&Sample) -> f64) -> Vec<(f64, u32, f64)> {
    let mut out: Vec<(i64, f64, f64, usize)> = Vec::new();
    for (i, (x, smp)) in s.iter().enumerate() {
        if !(0.4..1.4).contains(x) {
            continue;
        }
        let t = SLOT_T0 + i as f64 / RATE;
        let q = DEFAULT_RPM / 60.0 * t + 0.25;
        let period = (z as f64 * q).floor() as i64;
        match out.last_mut() {
            Some(o) if o.0 == period => {
                o.2 += v(smp);
                o.3 += 1;
            }
            _ => out.push((period, t, v(smp), 1)),
        }
    }
    let full = (RATE * 60.0 / DEFAULT_RPM / z as f64).round() as usize;
    out.into_iter()
        .filter(|o| o.3 == full)
        .map(|(p, t, sum, n)| (t, p.rem_euclid(z as i64) as u32, sum / n as f64))
        .collect()
}

/// The thesis' section 3.2 on a two-flute cutter (one tooth in the cut at a time): before the
/// break every tooth period's mean resultant force is the intact tool's; from the break of tooth 1
/// at 7 s on, tooth 1's periods carry no force and tooth 0's (the tooth after it) twice the intact
/// force ("the next tooth has to remove the material the damaged tooth left").
#[test]
fn a_broken_tooth_cuts_nothing_and_the_next_takes_twice_its_chip() {
    let t_break = 7.0;
    let intact = tooth_periods(&slot(&mut two_flutes(1)), 2, |s| s.f_true_n);
    let mut p = two_flutes(1).break_tooth(1, t_break).unwrap();
    let broken = tooth_periods(&slot(&mut p), 2, |s| s.f_true_n);
    assert_eq!(intact.len(), broken.len());
    assert!(intact.len() > 80, "{}", intact.len());
    let (mut before, mut zero, mut twice) = (0, 0, 0);
    for (a, b) in intact.iter().zip(&broken) {
        assert_eq!((a.0, a.1), (b.0, b.1));
        assert!(a.2 > 500.0, "intact period {a:?}");
        let end = a.0 + 0.05;
        if end <= t_break {
            assert_eq!(a.2, b.2, "before the break {a:?} {b:?}");
            before += 1;
        } else if a.0 >= t_break && a.1 == 1 {
            assert!(b.2 < 1e-9 * a.2, "broken tooth's period {a:?} {b:?}");
            zero += 1;
        } else if a.0 >= t_break {
            assert!((b.2 / a.2 - 2.0).abs() < 0.01, "next tooth {a:?} {b:?}");
            twice += 1;
        }
    }
    assert!(
        before > 20 && zero > 20 && twice > 20,
        "{before} {zero} {twice}"
    );
}

/// A tooth that breaks mid-pass stops cutting at once, and the tooth after it takes the chip
/// only from the angle where the broken tooth stopped cutting on, a tooth period later: no sample
/// of the tooth period after the break is above the intact tool's, and the doubled chip comes in
/// the tooth period after that. Before the causal model (the break's offsets applied to every
/// tooth at once), the next tooth's chip doubled in the very sample of the break: 2400 N above
/// the intact force at once on the pocket's slot, a jump no fracture makes.
#[test]
fn a_tooth_broken_mid_pass_leaves_its_chip_a_tooth_period_later() {
    let intact = slot(&mut steel(blank(), 1));
    // 600 rpm, 4 teeth: 25 ms tooth periods; breaks at several phases of a pass.
    for phase in [0.0, 0.007, 0.013, 0.019] {
        let t_break = 7.0 + phase;
        let mut p = steel(blank(), 1).break_tooth(1, t_break).unwrap();
        let broken = slot(&mut p);
        let (mut rise_first, mut rise_second) = (f64::MIN, f64::MIN);
        for (i, ((_, a), (_, b))) in intact.iter().zip(&broken).enumerate() {
            let t = SLOT_T0 + i as f64 / RATE;
            let d = b.f_true_n - a.f_true_n;
            if t >= t_break && t < t_break + 0.025 {
                rise_first = rise_first.max(d / a.f_true_n);
            } else if t >= t_break + 0.025 && t < t_break + 0.05 {
                rise_second = rise_second.max(d / a.f_true_n);
            }
        }
        assert!(
            rise_first <= 0.01,
            "break at {t_break}: {rise_first} in the first tooth period"
        );
        assert!(
            rise_second > 0.3,
            "break at {t_break}: {rise_second} in the second"
        );
    }
}

/// On four flutes two teeth share each tooth period (the one entering, the one leaving, each
/// carrying half of the period's torque in a slot): with tooth 1 broken the periods in which
/// teeth 1, 2, 3, 0 enter carry 0.5, 1, 1.5 and 1 times the intact torque (tooth 2, the one after
/// the broken tooth, takes its chip), and the mean torque over a revolution is unchanged (the same
/// material is removed).
#[test]
fn a_broken_tooth_of_four_passes_its_chip_to_the_tooth_after_it() {
    let intact = tooth_periods(&slot(&mut steel(blank(), 1)), 4, |s| s.t_true_nm);
    let mut p = steel(blank(), 1).break_tooth(1, 0.0).unwrap();
    let broken = tooth_periods(&slot(&mut p), 4, |s| s.t_true_nm);
    let expect = [1.0, 0.5, 1.0, 1.5];
    assert!(intact.len() > 150);
    for (a, b) in intact.iter().zip(&broken) {
        let r = b.2 / a.2;
        assert!(
            (r - expect[a.1 as usize]).abs() < 0.02,
            "tooth {} entering: {r}",
            a.1
        );
    }
    let revs = intact.len() / 4 * 4;
    let sum = |v: &[(f64, u32, f64)]| v[..revs].iter().map(|o| o.2).sum::<f64>();
    let r = sum(&broken) / sum(&intact);
    assert!((r - 1.0).abs() < 1e-3, "revolution mean ratio {r}");
}

/// Mean over a tooth's engagement (-90..90 degrees) of min(d, c cos(alpha)), mm: what a radius
/// offset d moves from one tooth to the next at feed per tooth c (the whole d where c cos(alpha)
/// exceeds it, beyond alpha0 = acos(d / c) the thinner chip).
fn moved_mm(d: f64, c: f64) -> f64 {
    let a0 = (d / c).acos();
    (2.0 * a0 * d + 2.0 * c * (1.0 - a0.sin())) / std::f64::consts::PI
}

/// Per tooth period, the mean torque of `p`'s slot minus the intact tool's, with the tooth in cut.
fn torque_change(p: Process) -> Vec<(u32, f64)> {
    let intact = tooth_periods(&slot(&mut two_flutes(1)), 2, |s| s.t_true_nm);
    let mut p = p;
    let other = tooth_periods(&slot(&mut p), 2, |s| s.t_true_nm);
    intact
        .iter()
        .zip(&other)
        .map(|(a, b)| (a.1, b.2 - a.2))
        .collect()
}

/// Two flutes, c = 5.08 mm/s / (2 x 10 rev/s) = 0.254 mm, a = 5.08 mm: +10 um of run-out on tooth
/// 0 raises its chip by 10 um and lowers tooth 1's (the next) by as much, where the chip is
/// thicker than 10 um; over a period the mean moves by `moved_mm(0.010, 0.254)` = 9.97 um, the
/// torque by R Ks a 9.97 um = 0.643 N*m.
#[test]
fn runout_of_ten_microns_moves_ten_microns_of_chip_to_the_tooth_that_runs_out() {
    let d = 0.010;
    let expect = 6.35e-3 * 2000.0 * 5.08 * moved_mm(d, 0.254);
    let ch = torque_change(two_flutes(1).with_runout(&[d, 0.0]).unwrap());
    assert_moved(&ch, expect);
}

/// Every tooth period's torque change (tooth, N*m) is +`expect` for tooth 0 and -`expect` for
/// tooth 1, within 2 %, over more than 80 periods.
fn assert_moved(ch: &[(u32, f64)], expect: f64) {
    assert!(ch.len() > 80, "{}", ch.len());
    for &(tooth, dt) in ch {
        let sign = if tooth == 0 { 1.0 } else { -1.0 };
        assert!(
            (dt / (sign * expect) - 1.0).abs() < 0.02,
            "tooth {tooth}: {dt} N*m vs {}",
            sign * expect
        );
    }
}

/// A 0.05 mm chip on tooth 1 from the start: its chip loses 0.05 mm (less where the chip is
/// thinner) and tooth 0, the next, gains it: `moved_mm(0.05, 0.254)` = 46.9 um on average, the
/// torque R Ks a x 46.9 um = 3.02 N*m.
#[test]
fn a_chipped_tooth_loses_its_chip_depth_to_the_next_tooth() {
    let d = 0.05;
    let expect = 6.35e-3 * 2000.0 * 5.08 * moved_mm(d, 0.254);
    let ch = torque_change(two_flutes(1).chip_tooth(1, 0.0, d).unwrap());
    assert_moved(&ch, expect);
}

fn sample_bits(s: &[(f64, Sample)]) -> Vec<u64> {
    s.iter()
        .flat_map(|(_, s)| {
            [s.f_true_n, s.t_true_nm, s.fu_n, s.fv_n, s.fa_n]
                .map(f64::to_bits)
                .into_iter()
                .chain(s.codes.map(u64::from))
        })
        .collect()
}

/// The intact tool without run-out stated explicitly (zero run-out, a zero-depth chip, damage
/// after the cut) gives the bytes of the default process: the default model is untouched.
#[test]
fn intact_teeth_without_runout_give_the_default_bytes() {
    let noisy = |seed| {
        Process::new(
            blank(),
            Tool::default(),
            Material::STEEL_KIENZLE,
            DEFAULT_RPM,
            seed,
            Transducer::default(),
        )
        .unwrap()
    };
    let base = sample_bits(&slot(&mut noisy(5)));
    let mut p = noisy(5)
        .with_runout(&[0.0; 4])
        .unwrap()
        .chip_tooth(2, 0.0, 0.0)
        .unwrap()
        .break_tooth(3, 100.0)
        .unwrap();
    assert_eq!(sample_bits(&slot(&mut p)), base);
    let mut q = noisy(5).break_tooth(3, 5.0).unwrap();
    assert_ne!(sample_bits(&slot(&mut q)), base, "a break must show");
}

/// Run-out, a chip and a break with noise: the same seed gives the same bytes.
#[test]
fn damaged_teeth_are_deterministic() {
    let make = || {
        Process::new(
            blank(),
            Tool::default(),
            Material::STEEL_KIENZLE,
            DEFAULT_RPM,
            9,
            Transducer::default(),
        )
        .unwrap()
        .with_runout(&[0.01, -0.005, 0.0, 0.002])
        .unwrap()
        .chip_tooth(0, 3.0, 0.05)
        .unwrap()
        .break_tooth(2, 6.0)
        .unwrap()
    };
    let a = sample_bits(&slot(&mut make()));
    let b = sample_bits(&slot(&mut make()));
    assert_eq!(a, b);
}

/// A full plunge at 10 ipm with tooth 1 broken: the end teeth remove the same material (the mean
/// torque stays the hand calculation's 17.07 N*m of the intact plunge), but no longer
/// symmetrically: a radial force appears (tooth 2 takes twice its end chip, tooth 1 none).
#[test]
fn a_broken_tooth_passes_its_end_chip_to_the_next() {
    let steady = |p: Process| {
        let mut p = p;
        let s = plunge(&mut p, -3000, 10.0);
        let inside = &s[..s.len() - 60];
        (
            mean(inside.iter().map(|(_, s)| s.t_true_nm)),
            mean(inside.iter().map(|(_, s)| s.f_true_n)),
        )
    };
    let (t_intact, f_intact) = steady(steel(blank(), 1));
    let (t_broken, f_broken) = steady(steel(blank(), 1).break_tooth(1, 0.0).unwrap());
    assert!(
        (t_broken / t_intact - 1.0).abs() < 0.01,
        "{t_broken} vs {t_intact}"
    );
    // Two of the four end teeth's tangential forces no longer cancel: Ft = Ks c_z R per tooth,
    // the resultant of 2 Ft at one angle and Ft at +-90 degrees from it: |2 - 1| Ft... at least Ft.
    let ft = 2000.0 * (10.0 * 25.4 / 60.0 / 40.0) * 6.35;
    assert!(f_intact < 0.02 * ft, "{f_intact}");
    assert!(f_broken > 0.9 * ft, "{f_broken} vs Ft {ft}");
}

#[test]
fn tooth_arguments_are_checked() {
    let err = |r: Result<Process, CutError>| r.unwrap_err().0;
    assert!(err(steel(blank(), 1).break_tooth(4, 1.0)).contains("tooth 4 does not exist"));
    assert!(err(steel(blank(), 1).chip_tooth(0, -1.0, 0.05)).contains("time"));
    assert!(err(steel(blank(), 1).chip_tooth(0, f64::NAN, 0.05)).contains("time"));
    assert!(err(steel(blank(), 1).chip_tooth(0, 1.0, -0.01)).contains("depth"));
    assert!(err(steel(blank(), 1).chip_tooth(0, 1.0, f64::INFINITY)).contains("depth"));
    assert!(err(steel(blank(), 1).with_runout(&[0.0; 3])).contains("one value per tooth"));
    assert!(err(steel(blank(), 1).with_runout(&[0.0, 0.0, f64::NAN, 0.0])).contains("finite"));
    assert!(err(steel(blank(), 1).with_runout(&[0.0, 2.0, 0.0, 0.0])).contains("within"));
    assert!(steel(blank(), 1)
        .with_runout(&[0.0, -0.02, 0.0, 0.01])
        .is_ok());
}

/// The thesis' table 3.2 preset's tool in a process: a slot in an aluminium blank at `depth_mm`,
/// the preset's feed per tooth, with the process's sound; the sound codes of the last 0.5 s of
/// a 2 s cut, and the process's peak true force over it.
fn preset_slot(depth_mm: f64, modes: Option<crate::lobes::Mode>) -> (Vec<u16>, f64) {
    use crate::chatter::{thesis_table_3_2 as t, Microphone};
    let tool = Tool {
        diameter_mm: t::DIAMETER_MM,
        flutes: t::FLUTES,
        ..Tool::default()
    };
    let z_blu = -(depth_mm / MM_PER_BLU).round() as i64;
    let mut p = Process::new(blank(), tool, Material::ALUMINIUM, t::RPM, 1, quiet()).unwrap();
    if let Some(m) = modes {
        p = p
            .with_tool_modes(&[m], &[m], Microphone::default(), 5000.0, 3)
            .unwrap();
    }
    let ipm = t::FEED_PER_TOOTH_MM * f64::from(t::FLUTES) * t::RPM / 25.4;
    // From air at X -0.5 in into the blank along Y 1.5 in: 2 s of cut after the entry.
    let samples = run(
        &mut p,
        0.0,
        [-5000, 15000, z_blu],
        [5000, 15000, z_blu],
        ipm,
    );
    let n = samples.len();
    let peak = samples[n - 500..]
        .iter()
        .map(|(_, s)| s.f_true_n)
        .fold(0.0, f64::max);
    let sound = p.take_sound();
    let tail = sound[sound.len().saturating_sub(2500)..].to_vec();
    (tail, peak)
}

fn rms_about(codes: &[u16], offset: f64) -> f64 {
    (codes
        .iter()
        .map(|&c| (f64::from(c) - offset).powi(2))
        .sum::<f64>()
        / codes.len() as f64)
        .sqrt()
}

/// Issue 10: the flexible tool inside the process. The table 3.2 preset's cut chatters at
/// 8.89 mm (the microphone's vibration far above its noise, the force peaks far above the rigid
/// tool's) and not at 2.54 mm (the sound at the noise, the force as the rigid tool's), as the
/// standalone time-domain model (`chatter::tests`) says for the same mode.
#[test]
fn the_flexible_tool_chatters_in_the_process_as_the_model_says() {
    use crate::chatter::thesis_table_3_2 as t;
    let (quiet_sound, stable_peak) = preset_slot(2.54, Some(t::MODE));
    let (_, rigid_peak) = preset_slot(2.54, None);
    let (loud_sound, chatter_peak) = preset_slot(8.89, Some(t::MODE));
    let (_, rigid_deep) = preset_slot(8.89, None);
    let (q, l) = (
        rms_about(&quiet_sound, 2048.0),
        rms_about(&loud_sound, 2048.0),
    );
    eprintln!(
        "sound RMS {q:.1} / {l:.1} codes; peaks 2.54 mm {stable_peak:.0} N (rigid {rigid_peak:.0}), \
         8.89 mm {chatter_peak:.0} N (rigid {rigid_deep:.0})"
    );
    assert!(q < 5.0, "2.54 mm: {q} codes RMS");
    assert!(l > 50.0, "8.89 mm: {l} codes RMS");
    assert!(
        (stable_peak / rigid_peak - 1.0).abs() < 0.1,
        "{stable_peak} vs {rigid_peak}"
    );
    assert!(
        chatter_peak > 1.3 * rigid_deep,
        "{chatter_peak} vs {rigid_deep}"
    );
}

/// A very stiff flexible tool cuts as the rigid one: the same forces within rounding.
#[test]
fn a_stiff_flexible_tool_cuts_like_the_rigid_one() {
    use crate::chatter::thesis_table_3_2 as t;
    let stiff = crate::lobes::Mode {
        k_n_m: 1e13,
        ..t::MODE
    };
    let (_, flex) = preset_slot(5.0, Some(stiff));
    let (_, rigid) = preset_slot(5.0, None);
    assert!((flex / rigid - 1.0).abs() < 1e-3, "{flex} vs {rigid}");
}

// The chip a tooth takes, limited by the material there: hand calculations for a tool in a hole
// of its own size, coming back along its own slot, along a straight wall and into an inside
// corner. The grid is the default 0.25 mm: a cell is material or air as its centre is, so a wall
// that does not lie on a cell boundary is seen up to half a cell (0.125 mm across, half the
// diagonal 0.177 mm along an oblique line) off; the tolerances below say where that enters.

/// Cell of the default grid, mm.
const CELL_MM: f64 = 0.25;
/// The default tool's radius, mm.
const R_MM: f64 = 6.35;
/// Feed per tooth at 30 ipm, 600 rpm, four teeth: 12.7 mm/s / 40 teeth/s, mm.
const C_30IPM: f64 = 0.3175;
/// Step of the edge angles the chips are read at, deg.
const STEP_DEG: f64 = 0.25;

/// BLU of a length in mm.
fn blu(mm: f64) -> i64 {
    (mm / MM_PER_BLU).round() as i64
}

/// The side chip (mm) at each edge angle alpha (deg, from the feed direction +X, positive to its
/// left, +Y) from -90 to 90 deg in [`STEP_DEG`] steps, with the tip at `tip_blu` moving along +X
/// at feed per tooth `c`: the plant's own side-tooth geometry on the stock as cut so far, the
/// chip `min(c, extent) cos(alpha)` the forces use (0 where the tooth cuts nothing).
fn chips(p: &Process, tip_blu: [i64; 3], c: f64) -> Vec<(f64, f64)> {
    let tip = tip_blu.map(|v| v as f64 * MM_PER_BLU);
    let n = (180.0 / STEP_DEG) as i64;
    (0..=n)
        .map(|i| {
            let alpha = -90.0 + i as f64 * STEP_DEG;
            let chip = p
                .cutter()
                .side_tooth(p.stock(), tip, alpha.to_radians(), [1.0, 0.0], c)
                .map_or(0.0, |t| c.min(t.extent) * t.cos_a);
            (alpha, chip)
        })
        .collect()
}

/// The engaged arc (deg: the edge angles with a chip) and the integral of the chip over the edge
/// angle (mm rad).
fn engagement(ch: &[(f64, f64)]) -> (f64, f64) {
    let n = ch.iter().filter(|(_, h)| *h > 0.0).count();
    let sum: f64 = ch.iter().map(|(_, h)| h).sum();
    (n as f64 * STEP_DEG, sum * STEP_DEG.to_radians())
}

/// Integral over the edge angle (mm rad) of a hand-calculated chip `h(alpha)` (alpha in rad), by
/// the midpoint rule at 0.01 deg.
fn integral(h: impl Fn(f64) -> f64) -> f64 {
    let d = 0.01f64.to_radians();
    (0..18_000)
        .map(|i| h((-90.0f64).to_radians() + (i as f64 + 0.5) * d) * d)
        .sum()
}

/// Issue 20's reproduction in the plant. The default stock's start hole has the tool's diameter;
/// the tool plunges into it at F5, goes out along +X to X1.49 at F30 and comes back to X1.25 at
/// F30, 0.25 in deep. Hand calculation: in the hole nothing is cut (F = T = 0). Going out, once
/// the tool is one feed per tooth (c = 0.3175 mm) into the wall, every tooth facing the feed is
/// in a full chip (the grid sees the hole's wall up to a cell off where it crosses a tooth's
/// line obliquely, near the tool's sides: checked from one cell further): a full slot, whose
/// force is constant,
/// F = Ks a c sqrt(1 + Kr^2) = 2000 x 6.35 x 0.3175 x 1.044 = 4210 N (the formula of
/// `full_slot_matches_hand_calculation`), and never more. Coming back along the slot just cut,
/// everything ahead is air: F = T = 0 once the outward motion has left the tooth period over
/// which the feed per tooth is taken. (Before the chip was limited by the material there, the
/// return read 1.0 to 4.2 kN at X1.285 to 1.26: the probe found the hole's far wall, which the
/// tool never reaches.)
#[test]
fn no_force_coming_back_along_the_own_slot_into_a_hole_of_the_tools_size() {
    let mut p = steel(Stock::default(), 1);
    let (x0, y0, z) = (12500, 15000, -2500);
    let plunge = run(&mut p, 0.0, [x0, y0, 1000], [x0, y0, z], 5.0);
    assert!(plunge
        .iter()
        .all(|(_, s)| s.f_true_n == 0.0 && s.t_true_nm == 0.0));
    let t1 = plunge.len() as f64 / RATE;
    let out = run(&mut p, t1, [x0, y0, z], [14900, y0, z], 30.0);
    let f_hand = 2000.0 * 6.35 * C_30IPM * 1.09f64.sqrt();
    let into = |x_in: f64| (x_in - 1.25) * 25.4;
    for (x, s) in &out {
        assert!(s.f_true_n <= f_hand * 1.001, "X{x}: {} N", s.f_true_n);
        if into(*x) >= C_30IPM + CELL_MM {
            assert!(
                (s.f_true_n / f_hand - 1.0).abs() < 0.01,
                "X{x}: {} N vs {f_hand} N",
                s.f_true_n
            );
        }
    }
    let t2 = t1 + out.len() as f64 / RATE;
    let back = run(&mut p, t2, [14900, y0, z], [x0, y0, z], 30.0);
    // One tooth period (25 ms) of the return still averages the outward motion into the feed.
    for (x, s) in back.iter().skip(25) {
        assert!(
            s.f_true_n == 0.0 && s.t_true_nm == 0.0,
            "X{x}: {} N, {} N*m where everything ahead is air",
            s.f_true_n,
            s.t_true_nm
        );
    }
}

/// The oracle reads the same chip: on the reproduction's path (out of the hole of the tool's size
/// along +X to X1.49, back along the slot just cut, point by point) the return cuts nothing (no
/// force limit, the ceiling's feed everywhere), the exit from the hole is limited only once the
/// tool is in the wall and, in the full slot, to 30 x 3600 / 4210 = 25.65 ipm (the hand force of
/// the reproduction test at the ceiling's 30 ipm); the schedule stays within F0 and T0 also where
/// the chips are limited by the material (re-evaluated at the scheduled feed).
#[test]
fn the_oracle_sees_no_cut_coming_back_along_the_own_slot() {
    let tool = Tool::default();
    let lim = OracleLimits::for_tool(&tool);
    let mut path = line([12500, 15000, -2500], [14900, 15000, -2500], 1, 30.0);
    let n_out = path.len();
    path.extend(
        line([14900, 15000, -2500], [12500, 15000, -2500], 1, 30.0)
            .into_iter()
            .skip(1),
    );
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
    for (p, v) in path.iter().zip(&r.cut_limit_ipm).skip(n_out) {
        assert!(
            v.is_infinite(),
            "X{}: limited to {v} ipm in air",
            p.pos_blu[0]
        );
    }
    assert!(r.cut_limit_ipm[0].is_infinite());
    let f_hand = 2000.0 * 6.35 * C_30IPM * 1.09f64.sqrt();
    let full = 30.0 * lim.f0_n / f_hand;
    for (p, v) in path.iter().zip(&r.cut_limit_ipm).take(n_out) {
        assert!(*v >= full * 0.999, "X{}: {v} ipm", p.pos_blu[0]);
        if (p.pos_blu[0] - 12500) as f64 * MM_PER_BLU >= C_30IPM + CELL_MM {
            assert!((v / full - 1.0).abs() < 0.01, "X{}: {v} ipm", p.pos_blu[0]);
        }
    }
}

/// A straight wall along X: material at Y >= `wall_mm` (top Z0), a pocket below it 0.5 in deep;
/// the tool (tip 0.2 in deep) fed along +X at 30 ipm from outside the blank to X32 mm with the
/// wall on its left at radial depth `ae_mm` (the path at Y = wall - R + ae), sampled at 1 kHz
/// and over its last revolution (1.27 mm) at 20 kHz. Returns the process, the end of the path
/// (BLU), the last revolution's samples and the radial depth of the path as rounded to BLU.
fn along_wall(wall_mm: f64, ae_mm: f64) -> (Process, [i64; 3], Vec<(f64, Sample)>, f64) {
    let st = Stock::parse(&format!(
        "blank X0 Y0 W2 H1.5 Z0\npocket X0 Y0 W2 H{} Z-0.5",
        wall_mm / 25.4
    ))
    .unwrap();
    let mut p = steel(st, 1);
    let y = blu(wall_mm - R_MM + ae_mm);
    let ae = y as f64 * MM_PER_BLU - (wall_mm - R_MM);
    let (mid, end) = ([blu(32.0 - 1.27), y, -2000], [blu(32.0), y, -2000]);
    let s = run(&mut p, 0.0, [blu(-R_MM - 0.5), y, -2000], mid, 30.0);
    let t0 = s.len() as f64 / RATE;
    let mut rev = run_at(&mut p, t0, mid, end, 30.0, 20.0 * RATE);
    rev.truncate(2000);
    (p, end, rev, ae)
}

/// Along a straight wall at radial depths of 5, 25, 50 and 100 % of the diameter D = 12.7 mm
/// (the wall on a cell boundary, Y = 12.5 mm), 0.2 in deep, c = 0.3175 mm. Hand calculation
/// (textbook side milling): engagement angle phi = acos(1 - 2 ae / D) (25.84, 60, 90 and 180
/// deg); the chip c cos(alpha) over the engaged edge angles, its mean h_mean = c (1 - cos phi) /
/// phi (0.0704, 0.1516, 0.2021, 0.2021 mm); mean torque over a revolution T = z Ks a c ae /
/// (2 pi) (the removal rate times Ks over the spindle's angular speed: 1.30, 6.51, 13.03 and
/// 26.06 N*m). Tolerances: the edge angles are read at 0.25 deg steps and the wall lies on the
/// grid, so the engaged arc within 0.3 deg and the mean chip within 1 %; the torque is the mean
/// of one revolution's samples at 20 kHz (0.18 deg of spindle angle apart: at the AC's 1 kHz,
/// 3.6 deg apart, the mean of a 26 deg engagement is off by up to 14 % with the phase), within
/// 2 % (the feed per tooth from positions in whole BLU: 125 BLU per tooth, +-1).
/// With the wall off the grid (Y = 12.7 mm) the grid moves it to the nearest cell boundary, up to
/// half a cell: the arc lies between the hand values for ae -+ 0.125 mm.
#[test]
fn along_a_straight_wall_the_chip_is_the_textbook_side_milling_chip() {
    let d = 2.0 * R_MM;
    let c = C_30IPM;
    for pct in [5.0, 25.0, 50.0, 100.0] {
        // The full slot: the tool wholly in the material, 2 mm clear of the wall.
        let ae_mm = pct / 100.0 * d + if pct == 100.0 { 2.0 } else { 0.0 };
        let (p, end, s, ae) = along_wall(12.5, ae_mm);
        let ae = ae.min(d);
        let phi = (1.0 - 2.0 * ae / d).acos();
        let (arc, sum) = engagement(&chips(&p, end, c));
        let h_mean = sum / arc.to_radians();
        let h_hand = c * (1.0 - phi.cos()) / phi;
        assert!(
            (arc - phi.to_degrees()).abs() <= 0.3,
            "{pct} %: engaged {arc} deg, hand {} deg",
            phi.to_degrees()
        );
        assert!(
            (h_mean / h_hand - 1.0).abs() < 0.01,
            "{pct} %: mean chip {h_mean} mm, hand {h_hand} mm"
        );
        let t_hand = 4.0 * 2000.0 * 5.08 * c * ae / std::f64::consts::TAU / 1000.0;
        let t_mean = mean(s.iter().map(|(_, s)| s.t_true_nm));
        assert!(
            (t_mean / t_hand - 1.0).abs() < 0.02,
            "{pct} %: mean torque {t_mean} N*m, hand {t_hand} N*m"
        );
    }
    // Off the grid: 5 % of D with the wall at Y = 12.7 mm, between cell boundaries.
    let ae_mm = 0.05 * d;
    let (p, end, _, ae) = along_wall(12.7, ae_mm);
    let (arc, _) = engagement(&chips(&p, end, c));
    let phi = |ae: f64| (1.0 - 2.0 * ae / d).acos().to_degrees();
    let h = 0.5 * CELL_MM;
    assert!(
        arc >= phi(ae - h) - 0.3 && arc <= phi(ae + h) + 0.3,
        "off the grid: engaged {arc} deg, hand {} deg ({} .. {})",
        phi(ae),
        phi(ae - h),
        phi(ae + h)
    );
}

/// Into an inside corner: the wall of the straight-wall test (Y >= 12.5 mm, radial depth 25 %:
/// 60 deg engaged, edge angles 30 to 90 deg) and a second wall across the path (material at
/// X >= 30 mm), the tool fed along +X into it at 30 ipm. Hand calculation, with the tool's axis
/// `d` short of the second wall: edge angles within beta = acos(d / R) of the feed reach past it,
/// the edge at R cos(alpha) ahead of the axis, so a tooth there takes the material between the
/// wall and its edge, `min(c, R cos(alpha) - d) cos(alpha)`; from 30 to 90 deg it takes the side
/// wall's full chip c cos(alpha). The engaged arc rises from 60 deg (d > R) to 150 deg (d =
/// R / 2: from -60 to 90 deg) and 180 deg (d = 0). Tolerance: a tooth cuts once the tool has
/// lowered a cell on its line (the grid knows material at cell centres only): the first cell
/// past the wall in the line's row of cells, whose centre is half a cell (h) past the wall and up
/// to h off the line sideways, is inside the tool's disc once the edge is
/// `e_min = R cos(alpha) + h - sqrt(R^2 - (R |sin(alpha)| + h)^2)` past the wall (h at the front,
/// h (1 + tan |alpha|) to first order towards the sides). The arc and the chip's integral lie
/// between the hand values without that threshold and with it (and the 0.25 deg step of the
/// edge angles, 1 % on the integral).
#[test]
fn into_an_inside_corner_the_engagement_rises_as_the_geometry_says() {
    let c = C_30IPM;
    let (wall_y, wall_x, ae) = (12.5, 30.0, 0.25 * 2.0 * R_MM);
    let st = Stock::parse(&format!(
        "blank X0 Y0 W1.5 H1.5 Z0\npocket X0 Y0 W{} H{} Z-0.5",
        wall_x / 25.4,
        wall_y / 25.4
    ))
    .unwrap();
    let mut p = steel(st, 1);
    let y = blu(wall_y - R_MM + ae);
    let mut from = [blu(-R_MM - 0.5), y, -2000];
    let mut t0 = 0.0;
    let side = 30f64.to_radians();
    // The hand chip at edge angle a (rad) with the tool's axis d short of the second wall, the
    // tooth cutting once its edge is past it by more than `late(a)`.
    let chip = |a: f64, d: f64, late: &dyn Fn(f64) -> f64| {
        let e = R_MM * a.cos() - d;
        if a >= side {
            c * a.cos()
        } else if e > late(a) {
            e.min(c) * a.cos()
        } else {
            0.0
        }
    };
    let h = 0.5 * CELL_MM;
    let e_min = |a: f64| {
        let q = R_MM * R_MM - (R_MM * a.sin().abs() + h).powi(2);
        if q > 0.0 {
            R_MM * a.cos() + h - q.sqrt()
        } else {
            f64::INFINITY
        }
    };
    let hand = |d: f64, late: &dyn Fn(f64) -> f64| {
        let arc = integral(|a| if chip(a, d, late) > 0.0 { 1.0 } else { 0.0 });
        (arc.to_degrees(), integral(|a| chip(a, d, late)))
    };
    let mut arcs = Vec::new();
    for d in [R_MM + 0.5, 0.5 * R_MM, 0.0] {
        let to = [blu(wall_x - d), y, -2000];
        let s = run(&mut p, t0, from, to, 30.0);
        t0 += s.len() as f64 / RATE;
        from = to;
        let (arc, sum) = engagement(&chips(&p, to, c));
        let (arc_hi, sum_hi) = hand(d, &|_| 0.0);
        let (arc_lo, sum_lo) = hand(d, &e_min);
        assert!(
            arc >= arc_lo - 0.3 && arc <= arc_hi + 0.3,
            "d = {d} mm: engaged {arc} deg, hand {arc_lo} .. {arc_hi} deg"
        );
        assert!(
            sum >= sum_lo * 0.99 && sum <= sum_hi * 1.01,
            "d = {d} mm: chip integral {sum} mm rad, hand {sum_lo} .. {sum_hi}"
        );
        arcs.push(arc);
    }
    assert!(arcs.windows(2).all(|w| w[1] > w[0]), "{arcs:?}");
}

/// Entering a wall the material limits a damaged tool's chips too: the tooth after a broken one
/// takes what lies behind its edge, not twice the feed per tooth (the teeth model's doubled
/// chip). A wall across the path on a cell boundary (material at X >= 30 mm), the tool fed along
/// +X at 30 ipm 0.15 mm into it: behind every engaged edge lies at most the 0.15 mm the tool went
/// in (R cos(alpha) - R + 0.15), less than c = 0.3175 mm, so with tooth 1 broken the peak torque
/// over the spindle's turn is at most the intact tool's (each tooth's chip `extent cos(alpha)`
/// either way, the broken one's share going nowhere); 3 mm further on, in the full slot, the
/// next tooth takes the doubled chip and the peak torque rises by half or more.
#[test]
fn entering_a_wall_the_tooth_after_a_broken_one_takes_what_is_there() {
    let st = Stock::parse(&format!(
        "blank X0 Y0 W2 H1 Z0\npocket X0 Y0 W{} H1 Z-0.5",
        30.0 / 25.4
    ))
    .unwrap();
    let mut p = steel(st, 1);
    let (y, z) = (blu(12.7), -2000);
    let peak_t = |p: &Process, tip_blu: [i64; 3], teeth: Option<&[f64]>| {
        let tip = tip_blu.map(|v| v as f64 * MM_PER_BLU);
        (0..360)
            .map(|i| {
                let f = p.cutter().forces(
                    p.stock(),
                    tip,
                    (i as f64).to_radians(),
                    [1.0, 0.0],
                    C_30IPM,
                    C_30IPM,
                    crate::process::EndCut::NONE,
                    teeth,
                    None,
                );
                f.t
            })
            .fold(0.0, f64::max)
    };
    let mut teeth = Teeth::default();
    let broken = ToothEvent {
        tooth: 1,
        t_s: 0.0,
        damage: Damage::Broken,
    };
    teeth.add(4, broken).unwrap();
    let mut d = [0.0; crate::teeth::MAX_FLUTES];
    assert!(teeth.offsets(4, 1.0, &mut d));
    let into = [blu(30.0 - R_MM + 0.15), y, z];
    let s = run(&mut p, 0.0, [blu(10.0), y, z], into, 30.0);
    let (intact, damaged) = (peak_t(&p, into, None), peak_t(&p, into, Some(&d[..4])));
    assert!(intact > 0.0);
    assert!(
        damaged <= intact * (1.0 + 1e-12),
        "entering: {damaged} N*m with tooth 1 broken, {intact} N*m intact"
    );
    let deep = [blu(30.0 - R_MM + 3.0), y, z];
    run(&mut p, s.len() as f64 / RATE, into, deep, 30.0);
    let (intact, damaged) = (peak_t(&p, deep, None), peak_t(&p, deep, Some(&d[..4])));
    assert!(
        damaged > 1.5 * intact,
        "in the slot: {damaged} N*m with tooth 1 broken, {intact} N*m intact"
    );
}

/// The teeth's contacts read once ([`crate::process::Cutter::contacts`], the oracle's searches)
/// and summed at a feed give the same bytes as [`crate::process::Cutter::forces`] reading the
/// stock: a slot cut into the Fig. 1 blank, then tips around its end (ahead in the material,
/// on the wall, over the floor, plunging), every spindle angle of a turn, side and end cuts,
/// the intact tool, a broken tooth and a flexible tool's wave.
#[test]
fn forces_from_contacts_are_the_forces_read_from_the_stock() {
    let mut p = steel(Stock::default(), 1);
    let z = blu(-3.0);
    run(
        &mut p,
        0.0,
        [blu(20.0), blu(38.1), z],
        [blu(40.0), blu(38.1), z],
        30.0,
    );
    let cut = *p.cutter();
    let mut teeth = Teeth::default();
    let broken = ToothEvent {
        tooth: 1,
        t_s: 0.0,
        damage: Damage::Broken,
    };
    teeth.add(4, broken).unwrap();
    let mut d = [0.0; crate::teeth::MAX_FLUTES];
    assert!(teeth.offsets(4, 1.0, &mut d));
    let mut contacts = [crate::process::Contact::default(); 4];
    let mut checked = 0;
    for (x, y, zt) in [
        (40.0, 38.1, -3.0),
        (40.3, 38.1, -3.0),
        (41.0, 39.0, -2.0),
        (38.0, 40.0, -3.0),
        (40.0, 38.1, -3.5),
        (30.0, 36.0, -1.0),
    ] {
        let tip = [x, y, zt];
        for (u, reach) in [([1.0, 0.0], C_30IPM), ([0.6, 0.8], 0.1), ([0.0, 0.0], 0.0)] {
            for hold in [false, true] {
                let end = crate::process::EndCut::new(0.05, zt, hold);
                for i in 0..360 {
                    let theta = (i as f64).to_radians();
                    let end_ok = cut.contacts(
                        p.stock(),
                        tip,
                        theta,
                        u,
                        reach,
                        Some(end.z_min),
                        cut.near_top(p.stock(), tip),
                        Some(&p.stock().disc_mask(tip[0], tip[1], cut.r_mm, end.z_min)),
                        &mut contacts,
                    );
                    for c in [0.0, 0.05, C_30IPM, 1.0] {
                        for e in [end, crate::process::EndCut::NONE] {
                            for t in [None, Some(&d[..4])] {
                                for wave in [None, Some([0.001, -0.002])] {
                                    let a =
                                        cut.forces(p.stock(), tip, theta, u, c, reach, e, t, wave);
                                    let b = cut.forces_of(&contacts, end_ok, c, e, t, wave);
                                    let bits = |f: crate::process::Forces| {
                                        [f.fx, f.fy, f.t, f.fa].map(f64::to_bits)
                                    };
                                    assert_eq!(bits(a), bits(b), "{tip:?} {u:?} {theta} {c}");
                                    assert_eq!(a, b);
                                    checked += usize::from(a.t != 0.0);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    assert!(checked > 1000, "only {checked} loaded cases");
}

/// A raster of `passes` unit-step passes across the blank, each lower than the one before, with
/// three moves per pass at different feeds and accelerations (the last move's steps given as
/// path lengths, as the walk over a pulse staircase gives them).
fn raster_path(passes: i64) -> Vec<OraclePoint> {
    let mut path = Vec::new();
    let mut pos = [-3000i64, 2000, 500];
    for pass in 0..passes {
        let x = if pass % 2 == 0 { 15000 } else { -3000 };
        let target = [x, 2000 + pass * 3000, -1500 - 100 * pass];
        for k in 0..3i64 {
            let t = [0, 1, 2].map(|a| pos[a] + (target[a] - pos[a]) * (k + 1) / 3);
            let n = (0..3).map(|a| (t[a] - pos[a]).abs()).max().unwrap().max(1);
            for i in 1..=n {
                path.push(OraclePoint {
                    pos_blu: [0, 1, 2].map(|a| pos[a] + (t[a] - pos[a]) * i / n),
                    feed_ipm: [30.0, 60.0, 15.0][((pass + k) % 3) as usize],
                    accel_ipm_s: if k == 1 { 300.0 } else { ACCEL_IPM_S },
                    step_mm: (k == 2).then_some(0.0027),
                });
            }
            pos = t;
        }
    }
    path
}

/// The oracle as a stream holds a window of the path, not the path (the most it holds over a
/// raster of 12 passes is what it holds over 3: about twice the braking distance from the
/// fastest ceiling, a small part of either), and its schedule is, to the bit, the acceleration
/// passes run over the whole path at once on its own limits: forward from rest, backward from
/// rest at the end, each point's feed the smallest of its limit and its neighbours' reach.
#[test]
fn the_streamed_oracle_holds_a_window_and_its_schedule_is_the_whole_paths() {
    let tool = Tool::default();
    let kienzle = Material {
        ks_exponent: 0.25,
        ..Material::STEEL
    };
    for (m, stride) in [
        (Material::STEEL, oracle::ORACLE_STRIDE_MM),
        (Material::STEEL, 0.0),
        (kienzle, oracle::ORACLE_STRIDE_MM),
    ] {
        let lim = OracleLimits {
            stride_mm: stride,
            ..OracleLimits::for_tool(&tool)
        };
        let stream = |path: &[OraclePoint]| {
            let mut stream = OracleStream::new(blank(), &tool, &m, 600.0, &lim).unwrap();
            let (mut out, mut most) = (Vec::new(), 0);
            let mut take = |i: usize, o: OracleOut| {
                assert_eq!(i, out.len(), "in order, each once");
                out.push(o);
            };
            for p in path {
                stream.push(*p, &mut take).unwrap();
                most = most.max(stream.held());
            }
            let (time_s, _) = stream.finish(&mut take);
            assert_eq!(out.len(), path.len());
            (out, most, time_s)
        };
        let (_, most_short, _) = stream(&raster_path(3));
        let path = raster_path(12);
        let (out, most, time_s) = stream(&path);
        assert!(
            most <= most_short && most * 50 < path.len(),
            "held {most} of {} points (of a quarter of the path: {most_short})",
            path.len()
        );
        // The passes over the whole path, on the stream's own limits.
        let mm = |p: &OraclePoint| p.pos_blu.map(|v| v as f64 * MM_PER_BLU);
        let s: Vec<f64> = (0..path.len())
            .map(|i| match i {
                0 => 0.0,
                _ => path[i].step_mm.unwrap_or_else(|| {
                    let (a, b) = (mm(&path[i - 1]), mm(&path[i]));
                    (0..3).map(|k| (b[k] - a[k]).powi(2)).sum::<f64>().sqrt()
                }),
            })
            .collect();
        let a2 = |i: usize| 2.0 * path[i].accel_ipm_s * 60.0 * s[i] / 25.4;
        let mut v: Vec<f64> = out.iter().map(|o| o.limit_ipm).collect();
        let n = v.len();
        v[0] = 0.0;
        v[n - 1] = 0.0;
        for i in 1..n {
            v[i] = v[i].min((v[i - 1] * v[i - 1] + a2(i)).sqrt());
        }
        for i in (0..n - 1).rev() {
            v[i] = v[i].min((v[i + 1] * v[i + 1] + a2(i + 1)).sqrt());
        }
        let mut t = 0.0;
        for i in 1..n {
            if s[i] > 0.0 {
                t += 2.0 * s[i] / ((v[i - 1] + v[i]) * MM_S_PER_IPM);
            }
        }
        let feeds: Vec<f64> = out.iter().map(|o| o.feed_ipm).collect();
        assert!(feeds == v, "stride {stride}, m {}", m.ks_exponent);
        assert_eq!(time_s, t);
        // Something was cut and limited below its ceiling: not trivially the ceilings' passes.
        assert!(out.iter().zip(&path).any(|(o, p)| o.limit_ipm < p.feed_ipm));
        println!(
            "m {} stride {stride}: {} points, at most {most} held ({most_short} of a quarter), \
             {time_s:.3} s",
            m.ks_exponent,
            path.len()
        );
    }
}

/// A process in steel (no noise) at 600 rpm with `tool` on `stock`.
fn steel_with(stock: Stock, tool: Tool) -> Process {
    Process::new(stock, tool, Material::STEEL, DEFAULT_RPM, 1, quiet()).unwrap()
}

/// A plunge at X2.5 Y1.5 in from 0.1 in above the blank's top to 0.4 in (10.16 mm) deep at
/// `ipm`: every sample, from the start (the tip meets the top after 0.1 in).
fn plunge_deep(p: &mut Process, ipm: f64) -> Vec<(f64, Sample)> {
    run(p, 0.0, [25000, 15000, 1000], [25000, 15000, -4000], ipm)
}

/// A ball end mill of diameter `d_mm` with `flutes`.
fn ball(d_mm: f64, flutes: u32) -> Tool {
    Tool {
        diameter_mm: d_mm,
        flutes,
        shape: Shape::Ball,
        ..Tool::default()
    }
}

/// A twist drill of 10 mm, two lips, 118 degree point, in steel at 600 rpm fed 4 ipm: feed per
/// revolution f = 1.6933 mm/s / 10 rev/s = 0.16933 mm. Textbook (Sandvik's, Kienzle's) drilling
/// torque `Mc = kc f D^2 / 8` = 2000 x 0.16933 x 100 / 8 = 4.233 N*m once the whole cone is in
/// the hole; thrust from the lips' tangential forces `Fa = Ka kc f D / 2` = 0.5 x 2000 x 0.16933
/// x 5 = 846.7 N; no radial force (the lips are symmetric). With the cone only part way in (depth
/// d below its first contact, the cone's height R / tan(59 deg) = 3.004 mm) the lips cut out to
/// r = d tan(59 deg): the torque is (r / R)^2 of the whole.
#[test]
fn a_drill_cuts_the_textbook_torque_and_thrust() {
    let tool = Tool {
        diameter_mm: 10.0,
        flutes: 2,
        shape: Shape::Drill { point_deg: 118.0 },
        ..Tool::default()
    };
    let mut p = steel_with(blank(), tool);
    let s = plunge_deep(&mut p, 4.0);
    let f_rev = 4.0 * 25.4 / 60.0 / 10.0;
    let t_hand = 2000.0 * f_rev * 100.0 / 8.0 / 1000.0;
    let fa_hand = 0.5 * 2000.0 * f_rev * 10.0 / 2.0;
    // The tip meets the top at t = 1.5 s (0.1 in at 4 ipm); deep: the cone (3 mm) long in.
    let depth_at = |t: f64| (t - 1.5) * 4.0 * 25.4 / 60.0;
    let deep: Vec<&Sample> = s
        .iter()
        .enumerate()
        .filter(|(i, _)| (5.0..9.0).contains(&depth_at(*i as f64 / RATE)))
        .map(|(_, (_, s))| s)
        .collect();
    assert!(deep.len() > 1000, "{}", deep.len());
    let t = mean(deep.iter().map(|s| s.t_true_nm));
    let fa = mean(deep.iter().map(|s| s.fa_n));
    let f = deep.iter().map(|s| s.f_true_n).fold(0.0, f64::max);
    assert!((t / t_hand - 1.0).abs() < 0.03, "T {t} vs {t_hand}");
    assert!((fa / fa_hand - 1.0).abs() < 0.03, "Fa {fa} vs {fa_hand}");
    // The lips' edges cross the 0.25 mm cells unevenly: a small net radial force remains.
    assert!(f < 0.08 * fa_hand, "radial force {f} N from symmetric lips");
    // Half the cone in: a quarter of the torque.
    let cone = 5.0 / (59f64).to_radians().tan();
    let at_half: Vec<f64> = s
        .iter()
        .enumerate()
        .filter(|(i, _)| (depth_at(*i as f64 / RATE) - cone / 2.0).abs() < 0.1)
        .map(|(_, (_, s))| s.t_true_nm)
        .collect();
    assert!(!at_half.is_empty());
    let q = mean(at_half.into_iter()) / t_hand;
    assert!(
        (q - 0.25).abs() < 0.04,
        "half the cone in: {q} of the torque"
    );
    // The hole's bottom is the cone: at 2 mm from the axis, 2 / tan(59 deg) above the tip.
    let tip = -4000.0 * MM_PER_BLU;
    let st = p.stock();
    let (x, y) = (2.5 * MM_PER_IN, 1.5 * MM_PER_IN);
    let at2 = st.top_at(x + 2.0, y);
    let want = tip + 2.0 / (59f64).to_radians().tan();
    assert!(
        (at2 - want).abs() < 0.15,
        "cone at r = 2 mm: {at2} vs {want}"
    );
    assert!(
        st.top_at(x + 6.0, y) == 0.0,
        "outside the hole the top is untouched"
    );
}

/// The tip of a ball end mill in a plunge: the end edges cut where the sphere meets material
/// below it, so at a depth d (< R) into the blank the engaged radius is r(d) = sqrt(d (2R - d))
/// and the torque z Ks c_z r(d)^2 / 2 (the flat end mill's whole-face torque with R -> r(d)): it
/// grows with the depth until the hemisphere is in, then it is the flat end mill's (the same end
/// chip over the same radius). 0.5 in ball, four flutes, 10 ipm: c_z = 0.10583 mm.
#[test]
fn a_ball_end_plunge_cuts_with_the_sphere_under_it() {
    let mut p = steel_with(blank(), ball(12.7, 4));
    let s = plunge_deep(&mut p, 10.0);
    let cz = 10.0 * 25.4 / 60.0 / 40.0;
    let r = 6.35;
    let t_of = |re: f64| 4.0 * 2000.0 * cz * re * re / 2.0 / 1000.0;
    // The tip meets the top at 0.6 s.
    let depth_at = |i: usize| (i as f64 / RATE - 0.6) * 10.0 * 25.4 / 60.0;
    for d in [1.0, 2.0, 4.0] {
        let near: Vec<f64> = s
            .iter()
            .enumerate()
            .filter(|(i, _)| (depth_at(*i) - d).abs() < 0.05)
            .map(|(_, (_, s))| s.t_true_nm)
            .collect();
        let want = t_of((d * (2.0 * r - d)).sqrt());
        let got = mean(near.into_iter());
        assert!(
            (got / want - 1.0).abs() < 0.05,
            "depth {d} mm: T {got} vs {want}"
        );
    }
    let deep: Vec<f64> = s
        .iter()
        .enumerate()
        .filter(|(i, _)| (8.0..9.0).contains(&depth_at(*i)))
        .map(|(_, (_, s))| s.t_true_nm)
        .collect();
    let got = mean(deep.into_iter());
    assert!(
        (got / t_of(r) - 1.0).abs() < 0.03,
        "deep: {got} vs {}",
        t_of(r)
    );
}

/// The sides of a ball end mill cut in slices up the sphere: a full slot `a` deep (a < R) fed
/// along X. Each slice's tangential force is Ks c cos(alpha) dz (the chip c cos(alpha)
/// sin(kappa) over an edge dz / sin(kappa) long) at its own radius, so the force against the
/// feed is the flat end mill's (Ks c a, the same for a full slot whatever the radius), and the
/// mean torque is z Ks c / pi times the integral of r(z) = sqrt(z (2R - z)) over the depth
/// instead of R a: the lower edges have the shorter lever. The slot's bottom is the sphere's
/// section: R - sqrt(R^2 - y^2) above the tip at y from the path.
#[test]
fn a_ball_end_slot_loads_its_edges_by_their_radius() {
    let (r, a) = (6.35, 3.0);
    let mut p = steel_with(blank(), ball(2.0 * r, 4));
    let z_tip = -((a / MM_PER_BLU).round() as i64);
    let s = run(
        &mut p,
        0.0,
        [-5000, 15000, z_tip],
        [20000, 15000, z_tip],
        12.0,
    );
    let steady: Vec<&Sample> = s
        .iter()
        .filter(|(x, _)| (0.6..1.9).contains(x))
        .map(|(_, s)| s)
        .collect();
    let c = 12.0 * 25.4 / 60.0 / 40.0;
    let a = -(z_tip as f64) * MM_PER_BLU;
    // The integral of sqrt(z (2R - z)) from 0 to a, by a fine midpoint rule.
    let n = 10_000;
    let lever: f64 = (0..n)
        .map(|i| {
            let z = (i as f64 + 0.5) * a / n as f64;
            (z * (2.0 * r - z)).sqrt() * a / n as f64
        })
        .sum();
    let t_hand = 4.0 * 2000.0 * c * lever / std::f64::consts::PI / 1000.0;
    let t_flat = 4.0 * 2000.0 * c * r * a / std::f64::consts::PI / 1000.0;
    let t = mean(steady.iter().map(|s| s.t_true_nm));
    assert!((t / t_hand - 1.0).abs() < 0.03, "T {t} vs {t_hand}");
    assert!(t < 0.8 * t_flat, "T {t} vs a flat end mill's {t_flat}");
    // Against the feed (world -X... the tooth forces' Y sum for a full slot is Ks c a).
    let fy = mean(steady.iter().map(|s| s.f_true_n));
    assert!(fy > 2000.0 * a * c * 0.97, "F {fy} vs {}", 2000.0 * a * c);
    // The groove's bottom, at the centre of the cell holding y0 + y (the blank's grid starts
    // at Y0).
    let st = p.stock();
    let (y0, cell) = (1.5 * MM_PER_IN, st.cell_mm());
    for y in [0.0, 1.0, 2.0, 3.0, 5.0, 6.0] {
        let yc = (((y0 + y) / cell).floor() + 0.5) * cell - y0;
        let want = (-a + r - (r * r - yc * yc).sqrt()).min(0.0);
        let got = st.top_at(1.0 * MM_PER_IN, y0 + y);
        assert!(
            (got - want).abs() < 1e-9,
            "groove at y {yc}: {got} vs {want}"
        );
    }
}

/// The grid a small ball end mill needs: a 3 mm two-flute ball end cutting a 1 mm deep slot and
/// a 0.5 mm deep pass along a wall, on cells of 0.125 mm and of 0.0625 mm (halved). The mean
/// force and torque and their peaks change by less than 5 % (the grid millac's jobs state for
/// such a tool is 0.0625 mm: R / 24).
#[test]
fn halving_the_grid_moves_a_small_ball_ends_forces_less_than_five_percent() {
    let figures = |cell: f64, depth_blu: i64, y_blu: i64| {
        let st = Stock::parse(&format!("cell {cell}\nblank X0 Y0 W1.2 H0.6 Z0")).unwrap();
        let mut p = steel_with(st, ball(3.0, 2));
        let s = run(
            &mut p,
            0.0,
            [-1000, y_blu, -depth_blu],
            [11000, y_blu, -depth_blu],
            4.0,
        );
        let steady: Vec<&Sample> = s
            .iter()
            .filter(|(x, _)| (0.3..0.9).contains(x))
            .map(|(_, s)| s)
            .collect();
        let f = mean(steady.iter().map(|s| s.f_true_n));
        let t = mean(steady.iter().map(|s| s.t_true_nm));
        let f_pk = steady.iter().map(|s| s.f_true_n).fold(0.0, f64::max);
        let t_pk = steady.iter().map(|s| s.t_true_nm).fold(0.0, f64::max);
        [f, t, f_pk, t_pk]
    };
    // A slot mid-block; a pass 1 mm into the block's edge (Y0 wall: the tool's axis 0.5 mm out).
    for (depth, y) in [(394, 3000), (197, -197)] {
        let coarse = figures(0.125, depth, y);
        let fine = figures(0.0625, depth, y);
        assert!(coarse[0] > 1.0, "the tool cuts: {coarse:?}");
        for k in 0..4 {
            let d = (coarse[k] / fine[k] - 1.0).abs();
            assert!(d < 0.05, "figure {k}: {} vs {} ({d})", coarse[k], fine[k]);
        }
    }
}
