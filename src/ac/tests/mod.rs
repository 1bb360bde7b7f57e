//! Host tests of the AC program (host tests): the FRC curve of Fig. 7 point by point, the feed
//! update, clamps and dead zone, DRR calibration and window pick, ECR, overload and sensor holds
//! with resume, settings validation, and the closed loop on a toy static process F = k * f.

mod faults;
mod plan;
mod strength;

use super::frc::{dead_zone, fdot, next_feed};
use super::*;
use proptest::prelude::*;

pub(super) const MID: u16 = 2048;

/// The default settings with the paper's FRC as the feed law: the law these tests check.
pub(super) fn paper() -> AcSettings {
    AcSettings {
        strategy: law::Strategy::Paper,
        ..AcSettings::default()
    }
}

pub(super) fn ctl(s: AcSettings) -> AcController {
    AcController::new(s.validated().expect("valid settings"))
}

/// Codes for a torque (N*m) and force components (N) under the default calibration.
pub(super) fn codes(t_nm: f32, fu_n: f32, fv_n: f32) -> [u16; 3] {
    let s = AcSettings::default();
    let c = |v: f32, cal: Calibration| (cal.offset + v / cal.gain).round() as u16;
    [c(t_nm, s.cal[0]), c(fu_n, s.cal[1]), c(fv_n, s.cal[2])]
}

/// Ten samples (one default window) of the same codes, then one period.
/// Samples from the zero-load codes up to `k` in steps below the jump threshold (into the current
/// window): a synthetic load that is not a cut (force without torque) then reaches the window as a
/// ramp, not as a jump from no load the DRR would judge by F*R/T.
pub(super) fn ease_in(c: &mut AcController, k: [u16; 3]) {
    let step = (c.settings().jump_codes / 2).max(1) as i32;
    let from = [MID; 3].map(i32::from);
    let to = k.map(i32::from);
    let n = (0..3).map(|i| (to[i] - from[i]).abs()).max().unwrap_or(0) / step + 1;
    for j in 1..n {
        c.sample([0, 1, 2].map(|i| (from[i] + (to[i] - from[i]) * j / n) as u16));
    }
}

fn window(c: &mut AcController, k: [u16; 3]) -> AcOutput {
    for _ in 0..10 {
        c.sample(k);
    }
    c.period()
}

// ---------------------------------------------------------------- FRC (Fig. 7, Eq. 6-8)

#[test]
fn fig7_named_points() {
    assert_eq!(fdot(0.5, 750.0), 187.5);
    assert_eq!(fdot(-0.05, 750.0), -187.5);
    assert_eq!(fdot(1.0, 750.0), 750.0);
    assert_eq!(fdot(-0.1, 750.0), -750.0);
    assert_eq!(fdot(0.0, 750.0), 0.0);
    assert_eq!(fdot(0.25, 750.0), 46.875);
}

#[test]
fn fig7_curve_point_by_point() {
    // E from -0.1 to 1 in steps of 0.001 against Eq. 6 and Eq. 7 evaluated in f64.
    for i in -100..=1000 {
        let e = i as f32 / 1000.0;
        let ed = e as f64;
        let want = if ed >= 0.0 {
            750.0 * ed * ed
        } else {
            -750.0 * (10.0 * ed) * (10.0 * ed)
        };
        let got = fdot(e, 750.0) as f64;
        assert!(
            (got - want).abs() <= 1e-6 * want.abs().max(1.0),
            "E = {e}: {got} vs {want}"
        );
        // The curve is monotonic in E and continuous at 0.
        assert!(fdot(e, 750.0) <= fdot(e + 0.001, 750.0));
    }
}

#[test]
fn one_period_changes_f_by_fdot_dt() {
    // fdot in ipm/s * 0.01 s * 100 feed numbers per ipm, truncated toward zero.
    let s = paper();
    let step = s.step_per_period();
    assert_eq!(step, 750.0);
    for (e, d) in [
        (0.5f32, 187i64),
        (0.25, 46),
        (0.75, 421),
        (1.0, 750),
        (-0.0625, -292),
    ] {
        assert_eq!(
            next_feed(1500, e, step, 1, 1_000_000) as i64 - 1500,
            d,
            "E = {e}"
        );
    }
    for i in -100..=1000 {
        let e = i as f32 / 1000.0;
        let d = next_feed(2000, e, step, 1, 1_000_000) as i64 - 2000;
        let exact = fdot(e, 750.0) as f64 * 0.01 * 100.0;
        assert!(
            (d as f64 - exact).abs() < 1.0 && (d as f64).abs() <= exact.abs(),
            "E = {e}"
        );
    }
}

#[test]
fn clamps_at_f_min_and_f_max() {
    assert_eq!(next_feed(2900, 1.0, 750.0, 100, 3000), 3000);
    assert_eq!(next_feed(3000, 0.5, 750.0, 100, 3000), 3000);
    assert_eq!(next_feed(300, -0.1, 750.0, 100, 3000), 100);
    assert_eq!(next_feed(100, -0.09, 750.0, 100, 3000), 100);
    // Far beyond the paper's range of E the change saturates instead of wrapping.
    assert_eq!(next_feed(2000, -1.0e6, 750.0, 100, 3000), 100);
    assert_eq!(next_feed(2000, f32::NAN, 750.0, 100, 3000), 2000);
}

#[test]
fn dead_zone_leaves_f_unchanged() {
    let (lo, hi) = dead_zone(750.0);
    assert!((hi - 0.036_515).abs() < 1e-5 && (lo + 0.003_651_5).abs() < 1e-6);
    for i in 1..=360 {
        let e = i as f32 / 10_000.0; // 0.0001 ..= 0.036
        assert_eq!(next_feed(1000, e, 750.0, 1, 3000), 1000, "E = {e}");
        let e = -(i as f32) / 100_000.0; // -0.00001 ..= -0.0036
        assert_eq!(next_feed(1000, e, 750.0, 1, 3000), 1000, "E = {e}");
    }
    assert_eq!(next_feed(1000, 0.037, 750.0, 1, 3000), 1001);
    assert_eq!(next_feed(1000, -0.0037, 750.0, 1, 3000), 999);
}

// ---------------------------------------------------------------- DRR

#[test]
fn drr_calibration_to_engineering_units() {
    let d = Drr::new(&paper());
    assert_eq!(d.convert([MID; 3]), (0.0, 0.0, 0.0));
    assert_eq!(
        d.convert([MID + 200, MID + 400, MID - 300]),
        (10.0, 1000.0, -750.0)
    );
    assert_eq!(d.convert([4095, 0, 4095]), (102.35, -5120.0, 5117.5));
    let mut s = paper();
    s.cal[1] = Calibration {
        gain: -4.0,
        offset: 100.0,
    };
    let d = Drr::new(&s);
    assert_eq!(d.convert([MID, 350, MID]).1, -1000.0);
}

#[test]
fn drr_latest_and_peak() {
    let s = paper();
    let mut d = Drr::new(&s);
    // F per sample: 1000, 1000 (components swapped), 2000, 500; |T|: 5, 20 (negative), 1, 2.
    let samples = [
        codes(5.0, 1000.0, 0.0),
        codes(-20.0, 0.0, 1000.0),
        codes(1.0, 1200.0, 1600.0),
        codes(2.0, 300.0, -400.0),
    ];
    for k in samples {
        d.sample(k).unwrap();
    }
    let mut d2 = d.clone();
    let peak = d.take(Pick::Peak).unwrap();
    assert_eq!(peak.f_n, 2000.0);
    assert_eq!(peak.t_nm, 20.0);
    let latest = d2.take(Pick::Latest).unwrap();
    assert_eq!(latest.f_n, 500.0);
    assert_eq!(latest.t_nm, 2.0);
    // The peak is of F per sample, not of each component: the two quadrature samples of
    // 1000 N give a peak of 1000 N, not sqrt(2) * 1000.
    let mut d = Drr::new(&s);
    d.sample(codes(0.0, 1000.0, 0.0)).unwrap();
    d.sample(codes(0.0, 0.0, 1000.0)).unwrap();
    assert_eq!(d.take(Pick::Peak).unwrap().f_n, 1000.0);
    // The window restarts after take; the peak is held over `peak_windows` windows (default 3):
    // 1000 N is still the peak one and two windows later, then the 400 N windows are all that is left.
    assert_eq!(d.take(Pick::Peak), None);
    let mut peaks = Vec::new();
    for _ in 0..4 {
        d.sample(codes(0.0, 400.0, 0.0)).unwrap();
        peaks.push(d.take(Pick::Peak).unwrap().f_n);
    }
    assert_eq!(peaks, [1000.0, 1000.0, 400.0, 400.0]);
    // With one window (the paper's 10 ms window alone) the peak is the window's own.
    let one = AcSettings {
        peak_windows: 1,
        ..paper()
    };
    let mut d = Drr::new(&one);
    d.sample(codes(0.0, 1000.0, 0.0)).unwrap();
    assert_eq!(d.take(Pick::Peak).unwrap().f_n, 1000.0);
    d.sample(codes(0.0, 400.0, 0.0)).unwrap();
    assert_eq!(d.take(Pick::Peak).unwrap().f_n, 400.0);
    assert!(AcSettings {
        peak_windows: 0,
        ..one
    }
    .validate()
    .is_err());
    assert!(AcSettings {
        peak_windows: 9,
        ..one
    }
    .validate()
    .is_err());
}

#[test]
fn pick_setting_reaches_the_ecr() {
    let mut s = paper();
    let spike = codes(0.0, 3600.0, 0.0); // F0 exactly
    let base = codes(0.0, 1800.0, 0.0);
    for (pick, e) in [(Pick::Peak, 0.0f32), (Pick::Latest, 0.5)] {
        s.pick = pick;
        let mut c = ctl(s);
        for k in [base, base, spike, base, base] {
            c.sample(k);
        }
        let out = c.period();
        assert_eq!(out.e, e, "{pick:?}");
    }
}

// ---------------------------------------------------------------- ECR

#[test]
fn ecr_force_and_smaller_error() {
    assert_eq!(ecr::force(3.0, -4.0), 5.0);
    let e = ecr::errors(1800.0, 36.0, 3600.0, 72.0);
    assert_eq!((e.ef, e.et, e.e), (0.5, 0.5, 0.5));
    let e = ecr::errors(1800.0, 54.0, 3600.0, 72.0);
    assert_eq!((e.ef, e.et, e.e), (0.5, 0.25, 0.25));
    let e = ecr::errors(3780.0, 36.0, 3600.0, 72.0);
    assert_eq!(e.e, e.ef);
    assert!(e.e < 0.0);
    // Through the controller: a torque-limited cut runs on Et (not a cut the default 0.5 in tool
    // can make, F*R/T = 0.21: the force/torque check is off).
    let mut c = ctl(AcSettings {
        ft_periods: 0,
        ..paper()
    });
    let out = window(&mut c, codes(54.0, 1800.0, 0.0));
    assert_eq!(out.e, 0.25);
    assert_eq!(out.feed_cap, 100 + 46);
}

// ---------------------------------------------------------------- holds

fn settle(c: &mut AcController, k: [u16; 3], n: usize) -> AcOutput {
    let mut out = window(c, k);
    for _ in 1..n {
        out = window(c, k);
    }
    out
}

#[test]
fn overload_holds_within_one_period_and_resume_restarts_at_f_min() {
    // Force and torque set freely (F*R/T up to 2.7): the force/torque check is off.
    let s = AcSettings {
        ft_periods: 0,
        ..paper()
    };
    let mut c = ctl(s);
    let air = codes(1.0, 100.0, 0.0);
    let out = settle(&mut c, air, 10);
    assert_eq!((out.state, out.feed_cap), (AcState::Run, 3000));
    // E = -0.05: the strategy decelerates, no hold.
    let out = window(&mut c, codes(10.0, 3780.0, 0.0));
    assert_eq!((out.state, out.feed_cap), (AcState::Run, 3000 - 187));
    // F = 1.2 F0 in a single sample of the window (after a ramp the jump check accepts): held at
    // the end of this period.
    for _ in 0..8 {
        c.sample(air);
    }
    c.sample(codes(10.0, 2500.0, 0.0));
    c.sample(codes(10.0, 4320.0, 0.0));
    let out = c.period();
    assert_eq!(out.feed_cap, 0);
    let Some(
        a @ Alarm::Overload {
            f_n,
            t_nm,
            f0_n,
            force_limit_n,
            ..
        },
    ) = out.alarm
    else {
        panic!("expected an overload alarm, got {out:?}");
    };
    assert_eq!(out.state, AcState::Hold(a));
    assert_eq!(
        (f_n, t_nm, f0_n, force_limit_n),
        (4320.0, 10.0, 3600.0, 4000.0)
    );
    let text = format!("{a}");
    assert!(
        text.contains("F = 4320.0 N") && text.contains("limit 4000.0 N"),
        "{text}"
    );
    assert!(
        text.contains("T = 10.00 N*m") && text.contains("T0 72.00"),
        "{text}"
    );
    // Stays held (alarm only reported once) even when the load is gone.
    for _ in 0..5 {
        let out = window(&mut c, air);
        assert_eq!(
            (out.feed_cap, out.alarm, out.state),
            (0, None, AcState::Hold(a))
        );
    }
    c.resume();
    assert_eq!((c.state(), c.feed_cap()), (AcState::Run, 100));
    let out = window(&mut c, air);
    // E = 1 - 100/3600 = 0.9722: 750 * E^2 = 708.9 feed numbers.
    assert_eq!(out.feed_cap, 100 + 708);
    // Resume while the overload persists: held again at the next period.
    window(&mut c, codes(0.0, 4320.0, 0.0));
    c.resume();
    let out = window(&mut c, codes(0.0, 4320.0, 0.0));
    assert!(matches!(out.alarm, Some(Alarm::Overload { .. })));
    assert_eq!(out.feed_cap, 0);
}

#[test]
fn torque_overload_holds() {
    let mut c = ctl(paper());
    ease_in(&mut c, codes(80.0, 0.0, 0.0));
    let out = window(&mut c, codes(80.0, 0.0, 0.0)); // E = 1 - 80/72 = -0.11
    assert!(matches!(out.state, AcState::Hold(Alarm::Overload { t_nm, .. }) if t_nm == 80.0));
}

fn assert_sensor_hold(out: AcOutput, want: SensorFault) {
    assert_eq!(out.feed_cap, 0, "{out:?}");
    assert_eq!(out.alarm, Some(Alarm::Sensor(want)));
    assert_eq!(out.state, AcState::Hold(Alarm::Sensor(want)));
}

#[test]
fn stuck_at_rail_holds() {
    // Limits far above full scale, so that a rail reads as a load but not as an overload; the
    // force/torque judgement off (floor above any load), so arriving at the rail is judged by
    // persistence alone and the rail samples reach the stuck count.
    let s = AcSettings {
        force_limit_n: 1.0e5,
        torque_limit_nm: 1.0e4,
        ft_floor_nm: 1.0e7,
        ..paper()
    };
    for (ch, rail) in [(0usize, 4095u16), (1, 0), (2, 4095)] {
        let mut c = ctl(s);
        let ok = window(&mut c, [MID; 3]);
        assert_eq!(ok.state, AcState::Run);
        // Ramp to the rail within the plausible jump, then stay there.
        let mut k = [MID; 3];
        k[ch] = if rail == 0 { 1000 } else { 3000 };
        c.sample(k);
        k[ch] = rail;
        for _ in 0..s.stuck_samples - 1 {
            c.sample(k);
        }
        let out = c.period();
        assert_eq!(
            (out.state, out.alarm),
            (AcState::Run, None),
            "one short of the count"
        );
        c.sample(k);
        let sensor = Sensor::ALL[ch];
        assert_sensor_hold(c.period(), SensorFault::Stuck { sensor, code: rail });
        // A resume with the sensor still stuck holds again.
        c.resume();
        c.sample(k);
        assert_sensor_hold(c.period(), SensorFault::Stuck { sensor, code: rail });
    }
    // 0 switches the check off (and 4095 the jump judgement, which a rail arrival also gets).
    let mut c = ctl(AcSettings {
        stuck_samples: 0,
        jump_codes: 4095,
        ..s
    });
    for _ in 0..100 {
        c.sample([MID, 1000, MID]);
        c.sample([MID, 0, MID]);
    }
    assert_eq!(c.period().state, AcState::Run);
}

#[test]
fn no_fresh_samples_holds() {
    let mut c = ctl(paper());
    assert_eq!(window(&mut c, [MID; 3]).state, AcState::Run);
    let out = c.period();
    assert_eq!((out.feed_cap, out.alarm), (0, Some(Alarm::NoSamples)));
    assert_eq!(out.state, AcState::Hold(Alarm::NoSamples));
    // The last measurement is still reported.
    assert_eq!(out.e, 1.0);
    c.resume();
    assert_eq!(window(&mut c, [MID; 3]).feed_cap, 850);
}

#[test]
fn implausible_jump_holds() {
    let s = paper();
    let mut c = ctl(s);
    c.sample([MID; 3]);
    c.sample([MID, MID, MID + 1500]); // exactly the limit: no jump
    assert_eq!(c.period().state, AcState::Run);
    // A jump of 1501 codes down to F = 2.5 N: the window before had F = 3750 N without torque,
    // but the jumped sample is too small for the force/torque judgement: kept out and judged by
    // the next sample, which is back: a spike.
    c.sample([MID, MID, MID + 1500]);
    c.sample([MID, MID, MID - 1]);
    c.sample([MID, MID, MID + 1499]);
    let want = SensorFault::Jump {
        sensor: Sensor::ForceV,
        from: MID + 1500,
        to: MID - 1,
    };
    assert_sensor_hold(c.period(), want);
    let text = format!("{}", Alarm::Sensor(want));
    assert_eq!(text, "sensor hold: Fv jumped from code 3548 to 2047");
}

#[test]
fn code_out_of_range_holds() {
    let mut c = ctl(paper());
    c.sample([MID; 3]);
    c.sample([4096, MID, MID]);
    c.sample([MID; 3]);
    let want = SensorFault::Range {
        sensor: Sensor::Torque,
        code: 4096,
    };
    assert_sensor_hold(c.period(), want);
    assert_ne!(Alarm::Sensor(want).message(), Alarm::NoSamples.message());
}

#[test]
fn hold_keeps_the_feed_cap_at_zero_until_resume() {
    let mut c = ctl(paper());
    c.period(); // no samples: hold
    for _ in 0..20 {
        assert_eq!(window(&mut c, [MID; 3]).feed_cap, 0);
        assert_eq!(c.feed_cap(), 0);
    }
    c.resume();
    c.resume(); // idempotent
    assert_eq!(c.feed_cap(), 100);
}

// ---------------------------------------------------------------- settings

#[test]
fn settings_validation() {
    let d = AcSettings::default();
    assert_eq!(d.validate(), Ok(()));
    assert_eq!((d.f0_n(), d.t0_nm()), (3600.0, 72.0));
    type Edit = fn(&mut AcSettings);
    let nan_gain: Edit = |s| s.cal[2].gain = f32::NAN;
    let bad: [(Edit, AcSettingsError); 14] = [
        (|s| s.sample_hz = 50, AcSettingsError::SampleRate),
        (|s| s.period_ms = 0, AcSettingsError::Period),
        (
            |s| (s.sample_hz, s.period_ms) = (100, 5),
            AcSettingsError::SamplesPerPeriod,
        ),
        (nan_gain, AcSettingsError::Calibration),
        (|s| s.cal[0].offset = 5000.0, AcSettingsError::Calibration),
        (|s| s.force_limit_n = 0.0, AcSettingsError::Limits),
        (
            |s| s.torque_limit_nm = f32::INFINITY,
            AcSettingsError::Limits,
        ),
        (
            |s| s.optimal_fraction = 1.1,
            AcSettingsError::OptimalFraction,
        ),
        (|s| s.fdot_m = 50, AcSettingsError::FdotM),
        (|s| s.f_min = 0, AcSettingsError::FeedRange),
        (|s| s.f_min = 3001, AcSettingsError::FeedRange),
        (|s| s.overload_e = 0.0, AcSettingsError::OverloadLimit),
        (
            |s| s.stuck_samples = 2_000_000,
            AcSettingsError::StuckSamples,
        ),
        (|s| s.jump_codes = 0, AcSettingsError::JumpCodes),
    ];
    for (edit, e) in bad {
        let mut s = d;
        edit(&mut s);
        assert_eq!(s.validate(), Err(e));
        assert_eq!(s.validated().err(), Some(e));
        assert!(!e.message().is_empty());
        assert_eq!(format!("{e}"), e.message());
    }
}

// ---------------------------------------------------------------- closed loop, F = k * f

/// Runs the FRC and ECR on F = k * f (no torque) from `f_start`; returns the force per period.
fn toy_loop(k: f32, f_start: u32, periods: usize) -> Vec<(u32, f32)> {
    let s = paper();
    let mut f = f_start;
    let mut trace = Vec::new();
    for _ in 0..periods {
        let force = k * f as f32;
        let e = ecr::errors(force, 0.0, s.f0_n(), s.t0_nm()).e;
        trace.push((f, e));
        f = next_feed(f, e, s.step_per_period(), s.f_min, s.f_max);
    }
    trace
}

/// Settles from below to within 5 % of F0, never above F0, and stays put (no oscillation).
fn check_settles_from_below(trace: &[(u32, f32)]) {
    let (lo, hi) = dead_zone(750.0);
    let first = trace
        .iter()
        .position(|&(_, e)| e < hi)
        .expect("reaches the dead zone");
    // The parabola approaches like 1/t: about (f*/750) / E_dz = 110 periods for f* = 3000.
    assert!(first < 200, "settles within 2 s, took {first} periods");
    let (f_end, e_end) = trace[first];
    assert!(
        (0.0..=0.05).contains(&e_end),
        "within 5 % of F0 from below: E = {e_end}"
    );
    for w in trace[..first].windows(2) {
        assert!(w[1].0 >= w[0].0, "monotonic approach from below");
    }
    for &(f, e) in &trace[first..] {
        assert_eq!(f, f_end, "no motion inside the dead zone");
        assert!(e > lo && e < hi);
    }
    assert!(trace.iter().all(|&(_, e)| e >= 0.0), "never above F0");
}

#[test]
fn closed_loop_settles_for_a_few_k() {
    let f0 = paper().f0_n();
    for f_star in [800.0f32, 1200.0, 2000.0, 2750.0, 2999.0] {
        let k = f0 / f_star;
        check_settles_from_below(&toy_loop(k, 100, 400));
    }
    // A light cut whose optimum lies above f_max runs at f_max.
    let trace = toy_loop(f0 / 5000.0, 100, 50);
    assert_eq!(trace.last().unwrap().0, 3000);
    // Starting above the optimum (E = -0.05): one decelerating step, then from below.
    let trace = toy_loop(f0 / 2000.0, 2100, 400);
    assert!(trace[1].0 < 2000);
    check_settles_from_below(&trace[1..]);
}

#[test]
fn closed_loop_through_the_controller() {
    // The same toy process through the ADC codes (quantised by 2.5 N) and the whole controller.
    let s = paper();
    for f_star in [900.0f32, 1500.0, 2500.0] {
        let k = s.f0_n() / f_star;
        let mut c = ctl(s);
        let mut cap = c.feed_cap();
        let mut caps = Vec::new();
        for _ in 0..300 {
            // With the torque of the default tool (F*R/T = 0.9).
            let f = k * cap as f32;
            let out = window(&mut c, codes(f * 0.00635 / 0.9, f, 0.0));
            assert_eq!(out.state, AcState::Run);
            assert!(
                out.e > -0.001,
                "measured F at most one code above F0: {out:?}"
            );
            cap = out.feed_cap;
            caps.push(cap);
        }
        assert!(
            caps.windows(2).all(|w| w[1] >= w[0]),
            "monotonic, no oscillation"
        );
        let f_end = *caps.last().unwrap() as f32;
        assert!(k * f_end >= 0.95 * s.f0_n() && k * f_end <= s.f0_n() + 1.25);
        assert_eq!(caps[150], caps[299], "settled");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn closed_loop_settles_for_any_k(f_star in 800.0f32..3000.0, f_start in 100u32..700) {
        let k = paper().f0_n() / f_star;
        check_settles_from_below(&toy_loop(k, f_start, 300));
    }

    #[test]
    fn feed_stays_in_limits_for_any_codes(
        samples in proptest::collection::vec(
            (0u16..=4095, 0u16..=4095, 0u16..=4095, 0u8..12), 1..60)
    ) {
        let s = AcSettings { stuck_samples: 0, jump_codes: 4095, ..paper() };
        let mut c = ctl(s);
        for (t, u, v, n) in samples {
            for _ in 0..n {
                c.sample([t, u, v]);
            }
            let out = c.period();
            prop_assert!(out.e.is_finite() && out.f_n.is_finite() && out.t_nm.is_finite());
            match out.state {
                AcState::Run => prop_assert!((s.f_min..=s.f_max).contains(&out.feed_cap)),
                AcState::Hold(_) => {
                    prop_assert_eq!(out.feed_cap, 0);
                    c.resume();
                }
            }
        }
    }
}

#[test]
fn achieved_feed_in_frame_units() {
    let nc = crate::Settings::default();
    // 30 ipm = 5000 BLU/s = 50 BLU per 10 ms = feed number 3000 (f = 100 x FR).
    assert_eq!(achieved_feed([50, 0, 0], &nc, 10), 3000);
    assert_eq!(achieved_feed([30, -40, 0], &nc, 10), 3000);
    assert_eq!(achieved_feed([0, 0, -10], &nc, 10), 600);
    assert_eq!(achieved_feed([0, 0, 0], &nc, 10), 0);
    assert_eq!(achieved_feed([i64::MAX, i64::MAX, 0], &nc, 10), u32::MAX);
}

#[test]
fn anti_windup_keeps_f_one_step_above_the_achieved_feed() {
    let air = codes(0.0, 0.0, 0.0);
    // Without the achieved feed the FRC runs to f_max in air (the paper's behaviour).
    let mut free = ctl(paper());
    let out = settle(&mut free, air, 20);
    assert_eq!(out.feed_cap, paper().f_max);
    // With the programmed feed binding at 12 ipm, the cap stays one step (7.5 ipm) above it. The
    // axes feed, so the transducer must look alive (2 codes of noise), or it is frozen.
    let mut c = ctl(paper());
    let mut last = 0;
    for _ in 0..20 {
        c.set_achieved(1200);
        for i in 0..10u16 {
            c.sample([MID + 2 * (i % 2); 3]);
        }
        last = c.period().feed_cap;
        assert!(last <= 1200 + 750, "{last}");
    }
    assert_eq!(last, 1950);
    // The achieved feed is used once: the next period without it runs the plain FRC again.
    let next = window(&mut c, air).feed_cap;
    assert!(next > 1950);
}

/// `$251` picks the feed law: the controller built from the settings runs it.
#[test]
fn the_settings_strategy_picks_the_controllers_feed_law() {
    use super::law::{FeedLaw, Strategy};
    for (strategy, want) in [
        (Strategy::Paper, "Paper"),
        (Strategy::Integral, "Integral"),
        (Strategy::Mrac, "Mrac"),
        (Strategy::Gpc, "Gpc"),
    ] {
        let s = AcSettings {
            strategy,
            ..AcSettings::default()
        };
        let c = AcController::new(s.validated().unwrap());
        let name = match c.law {
            FeedLaw::Paper => "Paper",
            FeedLaw::Integral(_) => "Integral",
            FeedLaw::Mrac(_) => "Mrac",
            FeedLaw::Gpc(_) => "Gpc",
        };
        assert_eq!(name, want);
    }
}

/// One rule for every law: the feed rises by at most fdot_m x dt per period (the paper's FRC by
/// construction; the integral, MRAC and GPC laws ask for far more in air).
#[test]
fn every_law_raises_the_feed_by_at_most_one_frc_step_per_period() {
    use super::law::Strategy;
    let air = codes(0.0, 0.0, 0.0);
    for strategy in Strategy::ALL {
        let s = AcSettings {
            strategy,
            ..AcSettings::default()
        };
        let step = s.step_per_period() as u32;
        let mut c = ctl(s);
        let mut f = c.feed_cap();
        for k in 0..5 {
            let out = window(&mut c, air);
            assert!(
                out.feed_cap <= f + step,
                "{strategy:?} period {k}: {} after {f}",
                out.feed_cap
            );
            f = out.feed_cap;
        }
        // The paper's and the integral law ask for more than the limit in air: they rise at it.
        if matches!(strategy, Strategy::Paper | Strategy::Integral) {
            let want = (s.f_min + 5 * step).min(s.f_max);
            assert_eq!(f, want, "{strategy:?} rises at the limit in air");
        }
    }
}

/// The paper's FRC lowers the feed on the latest window: once the feed has cut an overload, a
/// window back under F0 leaves the feed where it is, although the held peak (3 windows) still
/// shows the overload. Before: the held peak drove two more tenfold decelerations (E = -0.08:
/// -480 feed numbers each), taking the feed to f_min in a limit cycle behind the servo drive's
/// lag (Fig. 1 with the servo: 64.74 s, 1.087 of the bound; 60.78 s after).
#[test]
fn the_frc_lowers_the_feed_on_the_latest_window_not_the_held_peak() {
    // Force without torque: the force/torque check off.
    let s = AcSettings {
        ft_periods: 0,
        ..paper()
    };
    assert_eq!(s.peak_windows, 3);
    let mut c = ctl(s);
    c.f = 2000;
    let f0 = s.f0_n();
    // One window 8 % above F0: the tenfold deceleration.
    ease_in(&mut c, codes(0.0, 1.08 * f0, 0.0));
    let over = window(&mut c, codes(0.0, 1.08 * f0, 0.0));
    let after_over = c.f;
    assert!(after_over < 2000 - 400, "decelerated to {after_over}");
    assert!(over.e < -0.07);
    // Two windows at 0.98 F0: the held peak still reads 1.08 F0 (E < 0), the latest does not.
    for _ in 0..2 {
        let out = window(&mut c, codes(0.0, 0.98 * f0, 0.0));
        assert!(out.e < -0.07, "the held peak: E = {}", out.e);
        assert_eq!(
            c.f, after_over,
            "the feed stays while the latest window is under F0"
        );
    }
    // A window above F0 again lowers it, by its own (smaller) error.
    window(&mut c, codes(0.0, 1.02 * f0, 0.0));
    assert!(c.f < after_over);
    // The other laws see the held peak, unchanged: the integral law lowers the feed on it.
    let mut c = ctl(AcSettings {
        strategy: law::Strategy::Integral,
        ..s
    });
    c.f = 2000;
    ease_in(&mut c, codes(0.0, 1.08 * f0, 0.0));
    window(&mut c, codes(0.0, 1.08 * f0, 0.0));
    let f1 = c.f;
    window(&mut c, codes(0.0, 0.98 * f0, 0.0));
    assert!(c.f < f1, "integral on the held peak: {} after {f1}", c.f);
}
