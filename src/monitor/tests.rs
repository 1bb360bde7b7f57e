//! Host tests of the breakage detector (host tests): synthetic tooth-period forces from a
//! per-tooth model (base load x engagement x (1 + run-out of the tooth) x the tooth's share of its
//! chip, a broken tooth's lost share cut by the next tooth), fed per tooth period and per sample
//! (tooth-pass pulses in the rotating frame); steady cuts, whole programs with entries, exits,
//! holes and corners, breaks and chips, garbage input, settings validation.
use super::*;
use proptest::prelude::*;

const Z: u32 = 4;
/// Run-out of the four teeth (fraction of the chip): +-5 %, larger than a good holder's.
const RUNOUT: [f32; 4] = [0.05, -0.02, 0.03, -0.05];
const BASE_N: f32 = 1000.0;

/// A deterministic noise in [-1, 1) (LCG), so the tests are repeatable.
struct Noise(u32);
impl Noise {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (self.0 >> 8) as f32 / (1u32 << 23) as f32 - 1.0
    }
}

/// The per-tooth model. `chip`: (tooth, fraction of its chip lost, from tooth period).
#[derive(Clone, Copy)]
struct Model {
    base: f32,
    chip: Option<(u32, f32, u32)>,
    /// Relative noise on each tooth period's average (1 % default) plus 2 N.
    noise_rel: f32,
}

impl Model {
    fn new() -> Self {
        Model {
            base: BASE_N,
            chip: None,
            noise_rel: 0.01,
        }
    }

    /// The average force of tooth period j at engagement `eng` (0..).
    fn fa(&self, j: u32, eng: f32, noise: &mut Noise) -> f32 {
        let k = j % Z;
        let prev = (k + Z - 1) % Z;
        let mut share = 1.0;
        if let Some((tooth, c, from)) = self.chip {
            if j >= from && k == tooth {
                share -= c;
            }
            // The next tooth cuts what the damaged one left (from the next tooth period on).
            if j > from && prev == tooth {
                share += c;
            }
        }
        let r = RUNOUT[k as usize];
        let f = self.base * eng * (1.0 + r) * share;
        f * (1.0 + self.noise_rel * noise.next()) + 2.0 * noise.next()
    }
}

fn det(mode: ThresholdMode) -> BreakageDetector {
    det_with(
        BreakageSettings {
            mode,
            ..BreakageSettings::default()
        },
        600.0,
        Z as u8,
    )
}

/// A detector with settings `s` at `rpm` with `flutes`.
fn det_with(s: BreakageSettings, rpm: f32, flutes: u8) -> BreakageDetector {
    let mut d = BreakageDetector::new(s.validated().expect("valid settings"));
    d.set_spindle(rpm, flutes);
    d
}

/// Runs `eng(j)` through the model for `n` tooth periods; the first declaration (tooth period).
fn run(d: &mut BreakageDetector, m: &Model, n: u32, eng: impl Fn(u32) -> f32) -> Option<Breakage> {
    let mut noise = Noise(12345);
    let mut first = None;
    for j in 1..=n {
        let b = d.tooth_period(m.fa(j, eng(j), &mut noise));
        first = first.or(b);
    }
    first
}

/// Linear from a to b over [j0, j1].
fn ramp(j: u32, j0: u32, j1: u32, a: f32, b: f32) -> f32 {
    if j <= j0 {
        a
    } else if j >= j1 {
        b
    } else {
        a + (b - a) * (j - j0) as f32 / (j1 - j0) as f32
    }
}

/// A whole program with a sound tool: air, an entry over 3 revolutions, a hole (engagement dips
/// to 40 % within 2 teeth for 3 revolutions), a corner (a step of engagement 1 -> 1.6 in one
/// tooth period, and back 60 revolutions later), a slow depth change, an exit, air, and a second
/// entry that is abrupt (one tooth period).
fn program(j: u32) -> f32 {
    match j {
        0..=20 => 0.0,
        21..=400 => ramp(j, 20, 32, 0.0, 1.0),
        401..=600 => 1.0 - ramp(j, 400, 402, 0.0, 0.6) + ramp(j, 414, 416, 0.0, 0.6),
        601..=840 => {
            if j < 700 {
                1.0
            } else if j < 940 {
                1.6
            } else {
                1.0
            }
        }
        841..=1300 => {
            let base = if j < 940 { 1.6 } else { 1.0 };
            base * ramp(j, 1000, 1200, 1.0, 0.7)
        }
        1301..=1340 => 0.7 * ramp(j, 1300, 1306, 1.0, 0.0),
        1341..=1400 => 0.0,
        _ => 0.8,
    }
}

// ---------------------------------------------------------------- (a) steady cut with run-out

#[test]
fn steady_cut_with_runout_never_alarms() {
    for mode in [ThresholdMode::Adaptive, ThresholdMode::Thesis] {
        let mut d = det(mode);
        let b = run(&mut d, &Model::new(), 20_000, |_| 1.0);
        assert_eq!(b, None, "{mode:?}");
        assert!(!d.learning());
    }
}

#[test]
fn runout_is_removed_by_the_second_filter() {
    // Without noise the once-per-revolution residual of a steady cut with run-out is ~0 while
    // the first-difference residual carries the run-out pattern.
    let mut d = det(ThresholdMode::Adaptive);
    let m = Model {
        noise_rel: 0.0,
        ..Model::new()
    };
    let mut noise = Noise(1);
    let mut max1 = 0.0f32;
    let mut max2 = 0.0f32;
    for j in 1..=400 {
        let fa = m.fa(j, 1.0, &mut noise);
        d.tooth_period(fa);
        if j > 40 {
            let (_, _) = d.thresholds();
            max1 = max1.max(d.f1_last_abs());
            max2 = max2.max(d.f2_last_abs());
        }
    }
    assert!(max1 > 30.0, "e1 carries the run-out: {max1}");
    assert!(max2 < 6.0, "e2 is free of it: {max2}");
}

// ---------------------------------------------------------------- (b) whole programs

#[test]
fn whole_program_with_entries_exits_holes_corners_never_alarms() {
    let mut d = det(ThresholdMode::Adaptive);
    assert_eq!(run(&mut d, &Model::new(), 3000, program), None);
    // The same program at other load levels and noise seeds.
    for (base, seed) in [(300.0, 7), (3000.0, 99), (1500.0, 2024)] {
        let mut d = det(ThresholdMode::Adaptive);
        let m = Model {
            base,
            ..Model::new()
        };
        let mut noise = Noise(seed);
        for j in 1..=3000 {
            assert_eq!(
                d.tooth_period(m.fa(j, program(j), &mut noise)),
                None,
                "{base} {j}"
            );
        }
    }
}

#[test]
fn thesis_rule_false_alarms_on_the_corner() {
    // The reason for the adaptive rule: the thesis' fixed thresholds, learned on a gentle entry,
    // take the corner's step for a breakage.
    let mut d = det(ThresholdMode::Thesis);
    let b = run(&mut d, &Model::new(), 3000, program).expect("the thesis' rule alarms");
    assert!((401..=720).contains(&b.tooth_period), "{b:?}");
}

#[test]
fn adaptive_thresholds_learn_after_the_entry_and_thesis_thresholds_across_it() {
    // An abrupt step in the entry (40 % -> 100 % in one tooth period): the thesis learns it
    // (th1 above the step, for good), the adaptive learning restarts on it and learns the steady
    // cut (run-out and noise: th1 a few % of the load) as soon as it ends.
    let entry = |j: u32| if j < 3 { 0.4 } else { 1.0 };
    let mut a = det(ThresholdMode::Adaptive);
    let mut t = det(ThresholdMode::Thesis);
    let m = Model::new();
    let mut na = Noise(5);
    let mut nt = Noise(5);
    let mut a0 = None;
    let mut t0 = None;
    for j in 1..=1000 {
        a.tooth_period(m.fa(j, entry(j), &mut na));
        t.tooth_period(m.fa(j, entry(j), &mut nt));
        if a0.is_none() && !a.learning() {
            a0 = Some((j, a.thresholds()));
        }
        if t0.is_none() && !t.learning() {
            t0 = Some(t.thresholds());
        }
    }
    let (ja, (a0, _)) = a0.expect("learnt");
    let (t0, _) = t0.expect("learnt");
    let (t1, _) = t.thresholds();
    assert!(
        t0 > 1000.0,
        "the entry's step is in the thesis' learning: {t0}"
    );
    assert_eq!(t0, t1, "thesis th1 stays");
    assert!(a0 < 0.25 * BASE_N, "adaptive th1 from the steady cut: {a0}");
    // One revolution for dmFa, then 5 steady ones.
    assert!(ja <= 3 + Z * 6 + 1, "learnt at {ja}");
}

// ---------------------------------------------------------------- (c), (d) breaks and chips

/// Break times (tooth periods after an entry at j = 1), spread over the steady cut.
const BREAK_AT: [u32; 6] = [40, 61, 137, 250, 401, 1503];

/// Delay (tooth periods from the chip to the declaration) or None, for a chip of size c.
fn delay(tooth: u32, c: f32, from: u32) -> Option<u32> {
    let mut d = det(ThresholdMode::Adaptive);
    let m = Model {
        chip: Some((tooth, c, from)),
        ..Model::new()
    };
    // From the steady cut with run-out (the entry is abrupt at j = 1).
    let b = run(&mut d, &m, from + 40, |_| 1.0)?;
    Some(b.tooth_period.saturating_sub(from))
}

#[test]
fn broken_tooth_detected_within_two_revolutions() {
    let mut worst = 0;
    for from in BREAK_AT {
        for tooth in 0..Z {
            let got = delay(tooth, 1.0, from);
            let dl = got.unwrap_or_else(|| panic!("tooth {tooth} broken at {from} not detected"));
            assert!(dl <= 2 * Z, "tooth {tooth} at {from}: delay {dl}");
            worst = worst.max(dl);
        }
    }
    println!("broken tooth: worst delay {worst} tooth periods");
}

/// Smallest chip (fraction of a tooth's chip moved to the next tooth) detected at every break
/// time and tooth of [`BREAK_AT`], within two revolutions.
const SMALLEST_CHIP: f32 = 0.18;

#[test]
fn chipped_tooth_detected_down_to_the_smallest_chip() {
    for c in [SMALLEST_CHIP, 0.25, 0.3, 0.5, 0.75] {
        let mut worst = 0;
        for from in BREAK_AT {
            for tooth in 0..Z {
                let dl = delay(tooth, c, from)
                    .unwrap_or_else(|| panic!("chip {c} at tooth {tooth}, {from} not detected"));
                assert!(dl <= 2 * Z, "chip {c} tooth {tooth} at {from}: delay {dl}");
                worst = worst.max(dl);
            }
        }
        println!("chip {c}: worst delay {worst} tooth periods");
    }
}

/// How many of 100 000 random programs (the property's, [`sound_programs`], from proptest's
/// deterministic runner) a sound tool is declared broken on: the property's rate, measured over
/// more programs than the suite runs.
#[test]
#[ignore = "a sweep that prints the false alarms on random programs"]
fn false_alarm_sweep() {
    use proptest::strategy::ValueTree;
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let n = 100_000;
    let mut alarms = 0;
    for _ in 0..n {
        let (segs, seed, base) = sound_programs()
            .new_tree(&mut runner)
            .expect("a program")
            .current();
        let len: u32 = segs.iter().map(|s| s.0 + s.2).sum::<u32>() + 100;
        if sound_tool_alarm(&segs, base, seed, len).is_some() {
            alarms += 1;
        }
    }
    println!("false alarms on {alarms} of {n} random programs");
}

#[test]
#[ignore = "a sweep that prints the detection rate by chip size"]
fn chip_size_sweep() {
    for c100 in (2..=100).step_by(2) {
        let c = c100 as f32 / 100.0;
        let mut hit = 0;
        let mut n = 0;
        let mut worst = 0;
        for from in BREAK_AT {
            for tooth in 0..Z {
                n += 1;
                if let Some(dl) = delay(tooth, c, from).filter(|&dl| dl <= 2 * Z) {
                    hit += 1;
                    worst = worst.max(dl);
                }
            }
        }
        println!("chip {c:.2}: {hit}/{n} detected, worst delay {worst}");
    }
}

#[test]
fn too_small_a_chip_is_not_detected() {
    // Below the floor (5 % of the force) and the run-out residuals: not a detection. Shows the
    // detection tests above can fail.
    for from in BREAK_AT {
        assert_eq!(delay(1, 0.03, from), None, "{from}");
    }
}

#[test]
fn the_detector_latches_until_reset() {
    let mut d = det(ThresholdMode::Adaptive);
    let m = Model {
        chip: Some((2, 1.0, 100)),
        ..Model::new()
    };
    let b = run(&mut d, &m, 400, |_| 1.0).expect("detected");
    assert_eq!(d.breakage(), Some(b));
    assert_eq!(d.tooth_period(1000.0), None, "reported once");
    assert_eq!(d.breakage(), Some(b), "latched");
    d.reset();
    assert_eq!(d.breakage(), None);
    assert!(d.learning());
    let s = std::format!("{b}");
    assert!(s.starts_with("tool breakage at tooth period "), "{s}");
    assert!(s.contains(&std::format!("{:.1}", b.th1)), "{s}");
    assert_eq!(b.message(), "tool breakage: tooth force pattern changed");
}

#[test]
fn no_decisions_without_spindle_or_in_air() {
    // A broken tooth while the spindle is unknown: nothing.
    let mut d = BreakageDetector::new(BreakageSettings::default().validated().expect("valid"));
    let m = Model {
        chip: Some((1, 1.0, 100)),
        ..Model::new()
    };
    assert_eq!(run(&mut d, &m, 400, |_| 1.0), None);
    d.set_spindle(0.0, 4);
    assert!(!d.spindle_known());
    assert_eq!(run(&mut d, &m, 400, |_| 1.0), None);
    // Air restarts the learning.
    d.set_spindle(600.0, 4);
    assert!(d.spindle_known());
    run(&mut d, &Model::new(), 100, |_| 1.0);
    assert!(!d.learning());
    // One low tooth period is judged (a tooth that lost its chip), a revolution of them is air.
    d.tooth_period(10.0);
    assert!(!d.learning());
    for _ in 1..Z {
        d.tooth_period(10.0);
    }
    assert!(d.learning());
}

#[test]
fn a_spindle_change_restarts_the_learning() {
    let mut d = det(ThresholdMode::Adaptive);
    run(&mut d, &Model::new(), 100, |_| 1.0);
    d.set_spindle(600.0, 4);
    assert!(!d.learning(), "same speed: no change");
    d.set_spindle(800.0, 4);
    assert!(d.learning());
    assert_eq!(d.period_samples(), 18.75);
}

// ---------------------------------------------------------------- per sample

/// Samples of a cut at `rpm` with the model's tooth loads as tooth-pass pulses (half-sine over
/// 60 % of the tooth period, mean = the tooth's load) in the rotating frame, fed to `d` through
/// `sample_uv`; the tooth pulses start `offset` samples after the detector's first period.
fn run_samples(
    d: &mut BreakageDetector,
    m: &Model,
    rpm: f32,
    seconds: f32,
    offset: f32,
) -> Option<Breakage> {
    let fs = 1000.0;
    let tooth_s = 60.0 / (rpm * Z as f32);
    let mut noise = Noise(77);
    let mut first = None;
    let n = (seconds * fs) as u32;
    for i in 0..n {
        let t = (i as f32 - offset) / fs;
        let j = libm::floorf(t / tooth_s);
        let phase = t / tooth_s - j;
        let j = (j.max(0.0) as u32) + 1;
        let load = m.fa(j, 1.0, &mut Noise(j)) / 1.0;
        let pulse = if phase < 0.6 {
            core::f32::consts::PI / 2.0 / 0.6 * libm::sinf(core::f32::consts::PI * phase / 0.6)
        } else {
            0.0
        };
        let f = load * pulse + 5.0 * noise.next();
        let ang = 2.0 * core::f32::consts::PI * rpm / 60.0 * t;
        let b = d.sample_uv(f * libm::cosf(ang + 0.3), f * libm::sinf(ang + 0.3));
        first = first.or(b);
    }
    first
}

#[test]
fn per_sample_steady_cut_and_break_at_600_and_610_rpm() {
    for rpm in [600.0, 610.0] {
        let mut d = BreakageDetector::new(BreakageSettings::default().validated().expect("valid"));
        d.set_spindle(rpm, Z as u8);
        assert_eq!(
            run_samples(&mut d, &Model::new(), rpm, 60.0, 7.0),
            None,
            "{rpm}"
        );
        // A tooth broken 5 s into the cut.
        let tooth_s = 60.0 / (rpm * Z as f32);
        let from = (5.0 / tooth_s) as u32;
        let mut d = BreakageDetector::new(BreakageSettings::default().validated().expect("valid"));
        d.set_spindle(rpm, Z as u8);
        let m = Model {
            chip: Some((3, 1.0, from)),
            ..Model::new()
        };
        let b = run_samples(&mut d, &m, rpm, 10.0, 7.0).expect("detected");
        let dl = b.tooth_period as i64 - from as i64;
        assert!((0..=2 * Z as i64).contains(&dl), "{rpm}: {b:?} from {from}");
    }
}

// ---------------------------------------------------------------- (e) garbage and settings

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn garbage_never_panics(
        rpm in prop_oneof![Just(0.0f32), Just(f32::NAN), Just(-600.0), Just(f32::INFINITY),
                           Just(1.0e-30), Just(1.0e30), 1.0f32..100_000.0],
        flutes in 0u8..=255,
        xs in proptest::collection::vec(
            prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(f32::NEG_INFINITY),
                        Just(f32::MAX), Just(-f32::MAX), Just(0.0), -1.0e6f32..1.0e6], 0..600),
    ) {
        let mut d = det(ThresholdMode::Adaptive);
        d.set_spindle(rpm, flutes);
        for &x in &xs {
            d.sample(x);
            d.sample_uv(x, -x);
            d.tooth_period(x);
        }
        let (a, b) = d.thresholds();
        prop_assert!(a.is_finite() && b.is_finite());
        d.set_spindle(600.0, 4);
        for &x in &xs {
            if let Some(b) = d.tooth_period(x) {
                prop_assert!(b.th1.is_finite() && b.th2.is_finite());
            }
        }
    }
}

#[test]
fn settings_validation_names_the_setting() {
    use BreakageSettingsError as E;
    let ok = BreakageSettings::default();
    assert_eq!(ok.validate(), Ok(()));
    let bad: [(BreakageSettings, E); 9] = [
        (
            BreakageSettings {
                sample_hz: 50,
                ..ok
            },
            E::SampleRate,
        ),
        (BreakageSettings { lambda: 1.0, ..ok }, E::Lambda),
        (
            BreakageSettings {
                lambda: f32::NAN,
                ..ok
            },
            E::Lambda,
        ),
        (
            BreakageSettings {
                learn_revs: 0,
                ..ok
            },
            E::LearnRevs,
        ),
        (BreakageSettings { factor: 0.5, ..ok }, E::Factor),
        (
            BreakageSettings {
                decay_revs: f32::INFINITY,
                ..ok
            },
            E::DecayRevs,
        ),
        (
            BreakageSettings {
                floor_fraction: -0.1,
                ..ok
            },
            E::FloorFraction,
        ),
        (
            BreakageSettings {
                min_threshold_n: 0.0,
                ..ok
            },
            E::MinThreshold,
        ),
        (
            BreakageSettings {
                air_floor_n: f32::NAN,
                ..ok
            },
            E::AirFloor,
        ),
    ];
    for (s, e) in bad {
        assert_eq!(s.validate(), Err(e));
        assert_eq!(s.validated().err(), Some(e));
        assert!(!e.message().is_empty());
    }
}

// ---------------------------------------------------------------- cost and size

#[test]
fn state_size() {
    // The host build keeps the last residuals for the figures (two f32 the firmware has not).
    let n = core::mem::size_of::<BreakageDetector>() - core::mem::size_of::<(f32, f32)>();
    println!("BreakageDetector: {n} bytes in the firmware's build");
    // The trip's force ring, and the rest (the feed notices of the last ten tooth periods, 64
    // bytes, took it past 512).
    let ring = core::mem::size_of::<f32>() * crate::monitor::breakage::REV_RING;
    assert!(n <= ring + 576, "{n}");
}

#[test]
#[ignore = "host timing, run with --release --ignored --nocapture"]
fn cost_on_the_host() {
    let mut d = det(ThresholdMode::Adaptive);
    let n = 10_000_000u32;
    let t = std::time::Instant::now();
    let mut acc = 0u32;
    for i in 0..n {
        let f = 1000.0 + (i % 25) as f32;
        acc += d.sample(core::hint::black_box(f)).is_some() as u32;
    }
    let per_sample = t.elapsed().as_nanos() as f64 / n as f64;
    let mut d = det(ThresholdMode::Adaptive);
    let t = std::time::Instant::now();
    for i in 0..n {
        let f = 1000.0 + (i % 4) as f32 * 10.0;
        acc += d.tooth_period(core::hint::black_box(f)).is_some() as u32;
    }
    let per_tooth = t.elapsed().as_nanos() as f64 / n as f64;
    println!("host: {per_sample:.2} ns per sample (incl. 1/25 tooth period), {per_tooth:.2} ns per tooth period ({acc})");
}

#[test]
fn breaks_inside_the_program_are_detected_within_two_revolutions() {
    // The whole program with a tooth broken at times in its steady parts: after the entry, in
    // the corner's wider engagement, during the slow depth change, after the second entry.
    for from in [300, 380, 480, 760, 900, 1100, 1250, 1500, 2000] {
        for tooth in 0..Z {
            let mut d = det(ThresholdMode::Adaptive);
            let m = Model {
                chip: Some((tooth, 1.0, from)),
                ..Model::new()
            };
            let b = run(&mut d, &m, from + 40, program)
                .unwrap_or_else(|| panic!("tooth {tooth} broken at {from}: not detected"));
            let dl = b.tooth_period as i64 - from as i64;
            assert!(
                (0..=2 * Z as i64).contains(&dl),
                "tooth {tooth} at {from}: {b:?}"
            );
        }
    }
}

/// A tooth broken on a slow entry ramp (0 -> 1 over 20 revolutions), 10 revolutions into it:
/// the learning (steady revolutions only) has not ended, and the chip-transfer test sees the
/// break within two revolutions, for every tooth and for chips down to half a tooth's load;
/// the same ramp with a sound tool is judged by the random-program property.
#[test]
fn break_on_an_entry_ramp_while_learning_is_detected_within_two_revolutions() {
    for c in [1.0, 0.5] {
        for tooth in 0..Z {
            let from = 60 + tooth;
            let mut d = det(ThresholdMode::Adaptive);
            let m = Model {
                chip: Some((tooth, c, from)),
                ..Model::new()
            };
            let eng = |j| ramp(j, 20, 100, 0.0, 1.0);
            let mut noise = Noise(12345);
            let mut first = None;
            for j in 1..=from + 20 {
                let learning = d.learning();
                if let Some(b) = d.tooth_period(m.fa(j, eng(j), &mut noise)) {
                    first = Some((b, learning));
                    break;
                }
            }
            let (b, learning) =
                first.unwrap_or_else(|| panic!("chip {c} tooth {tooth}: not detected"));
            assert!(learning, "chip {c} tooth {tooth}: learning had ended");
            let dl = b.tooth_period as i64 - from as i64;
            assert!(
                (0..=2 * Z as i64).contains(&dl),
                "chip {c} tooth {tooth}: {b:?}"
            );
        }
    }
}

/// The first alarm of the adaptive detector on a sound tool cutting `segs` (see
/// [`random_program`]) at `base` N per unit engagement with noise seed `seed`, over `n` tooth
/// periods.
fn sound_tool_alarm(segs: &[(u32, f32, u32)], base: f32, seed: u32, n: u32) -> Option<Breakage> {
    let mut d = det(ThresholdMode::Adaptive);
    let m = Model {
        base,
        ..Model::new()
    };
    let eng = random_program(segs);
    let mut noise = Noise(seed);
    (1..=n).find_map(|j| d.tooth_period(m.fa(j, eng(j), &mut noise)))
}

/// Random programs for a sound tool: segments (see [`random_program`]), the noise seed, the force
/// per unit engagement in N.
fn sound_programs() -> impl Strategy<Value = (std::vec::Vec<(u32, f32, u32)>, u32, f32)> {
    (
        proptest::collection::vec(
            (10u32..200, prop_oneof![Just(0.0f32), 0.2f32..1.8], 1u32..40),
            1..12,
        ),
        0u32..1000,
        200.0f32..3000.0,
    )
}

/// A random program: segments (hold length in tooth periods, engagement, transition length;
/// engagement 0 is air).
fn random_program(segs: &[(u32, f32, u32)]) -> impl Fn(u32) -> f32 + '_ {
    move |j| {
        let mut t0 = 0;
        let mut from = 0.0;
        for &(hold, to, trans) in segs {
            let t1 = t0 + trans + hold;
            if j < t1 {
                return ramp(j, t0, t0 + trans, from, to);
            }
            t0 = t1;
            from = to;
        }
        from
    }
}

/// A light cut (166 N) that fades out over 19 tooth periods, as the tool leaves the stock: once
/// declared a breakage at tooth period 374 by the curvature confirmation (the sensor's 2 N of
/// noise at 50 N bent the same slot by 0.1 twice, over the 0.06 the episode took at 166 N). The
/// random-program property found it with another seed (one in about 80 000 programs).
#[test]
fn a_light_cuts_exit_is_not_a_breakage() {
    let segs = [
        (160u32, 0.0f32, 26u32),
        (79, 0.0, 31),
        (42, 0.267_691_58, 22),
        (10, 0.0, 19),
    ];
    assert_eq!(sound_tool_alarm(&segs, 621.2721, 188, 480), None);
}

/// A steady cut, then a step of the engagement to 2.3 times over six tooth periods (1.5
/// revolutions) and a short hold: once declared a breakage at tooth period 136 (e1 164 N over its
/// threshold 150 N, e2 -143 N over 86 N: the suspicion at the step's tail, where every tooth
/// still gained on its last revolution, confirmed by the revolution after it at the new level).
/// The random-program property found it (`false_alarm_sweep`: 87 false alarms in 100 000
/// programs before a suspicion asked for a loss, 1 after); the property runs a fixed sample,
/// the same every run, and this case stays as its witness.
#[test]
fn a_fast_step_after_a_steady_cut_is_not_a_breakage() {
    let segs = [(94u32, 0.638_034_7f32, 29u32), (10, 1.494_978_5, 6)];
    assert_eq!(sound_tool_alarm(&segs, 1133.218, 53, 239), None);
}

proptest! {
    // A fixed sample (seed 1): the same programs every run (a random one could find a case
    // nobody has seen in a CI run; look for them with other seeds and more cases).
    #![proptest_config(ProptestConfig {
        cases: 2000,
        rng_seed: proptest::test_runner::RngSeed::Fixed(1),
        ..ProptestConfig::default()
    })]
    #[test]
    fn random_programs_with_a_sound_tool_never_alarm((segs, seed, base) in sound_programs()) {
        let n: u32 = segs.iter().map(|s| s.0 + s.2).sum::<u32>() + 100;
        prop_assert_eq!(sound_tool_alarm(&segs, base, seed, n), None);
    }
}

/// A corner's deceleration (the frame's exponential slow-down at a block end) and the
/// acceleration after it, as the pocket under QEMU with the AC showed it at 16.45 s (Fa per tooth
/// period 1887, 1405, 554, 722, 1360, 1883, 2098, 2168, 2112, 2034 N from a level of 1939 N):
/// the force dips to a third for two tooth periods and comes back a little above where it was,
/// the whole revolution alike. Told of the feed step (`feed_step`, as the AC period does when
/// the feed of one period differs from the last by more than 30 %), the detector declares
/// nothing, wherever the dip falls in the revolution and however deep; the same cuts without the
/// notice are declared (the suspicion at the recovery, confirmed a revolution later), which is
/// why the AC period tells it.
#[test]
fn a_corners_dip_and_recovery_is_not_a_breakage() {
    let dip = [
        0.973, 0.725, 0.286, 0.372, 0.701, 0.971, 1.082, 1.118, 1.089, 1.049,
    ];
    let mut declared_without = 0;
    for told in [true, false] {
        for shift in 0..Z {
            for depth in [1.0f32, 0.8, 1.2] {
                let mut d = det(ThresholdMode::Adaptive);
                let m = Model::new();
                let mut noise = Noise(12345);
                let start = 160 + shift;
                let mut first = None;
                for j in 1..=start + 60 {
                    let k = j.saturating_sub(start) as usize;
                    let f = if j < start {
                        1.0
                    } else {
                        dip.get(k).copied().unwrap_or(1.049)
                    };
                    let f = if (1..5).contains(&k) {
                        1.0 - (1.0 - f) * depth
                    } else {
                        f
                    };
                    // The AC period sees the feed step in the periods of the dip's fall and rise.
                    if told && (1..6).contains(&k) {
                        d.feed_step(FeedChange {
                            kept_pct: 50,
                            up: k > 3,
                            hold: true,
                        });
                    }
                    first = first.or(d.tooth_period(m.fa(j, 1.9 * f, &mut noise)));
                }
                if told {
                    assert_eq!(first, None, "shift {shift}, depth {depth}");
                } else if first.is_some() {
                    declared_without += 1;
                }
            }
        }
    }
    assert!(
        declared_without > 0,
        "the dip alone is never declared: the test shows nothing"
    );
}

/// A feed notice that lowered the feed to `kept_pct` % of what it was.
fn lower(kept_pct: u8) -> FeedChange {
    FeedChange {
        kept_pct,
        up: false,
        hold: true,
    }
}

/// A feed notice that raised the feed from `kept_pct` % of what it is now.
fn raise(kept_pct: u8) -> FeedChange {
    FeedChange {
        kept_pct,
        up: true,
        hold: true,
    }
}

/// A sampled cut for the sampler trip's signature ([`BreakageDetector::chip_moved`]): 4 teeth at
/// 600 rpm and 1 kHz (25 samples per tooth period), each tooth's pass a half-sine over the first
/// `pass` samples of its period, starting `phase` samples into the detector's tooth period. From
/// sample `broken` on, tooth 0 cuts nothing and tooth 1 cuts its chip too (`None`: a sound tool);
/// every tooth's load is scaled by `load(sample)` (a feed change or a deeper cut: all teeth
/// alike), and the AC period tells the detector of a feed step at each sample in `notices`
/// (`FeedChange`: the share of the feed it kept, %, and whether it rose).
/// Returns whether the first sample above `trip` N was judged a breakage, and that sample's
/// index (None: no crossing).
fn trip_verdict(
    phase: usize,
    pass: usize,
    broken: Option<usize>,
    load: impl Fn(usize) -> f32,
    notices: &[(usize, FeedChange)],
    trip: f32,
) -> Option<(usize, bool)> {
    let mut d = det(ThresholdMode::Adaptive);
    let mut noise = Noise(777);
    for i in 0..3000usize {
        if let Some(&(_, change)) = notices.iter().find(|(at, _)| *at == i) {
            d.feed_step(change);
        }
        let at = (i + 100 - phase) % 100;
        let (tooth, k) = (at / 25, at % 25);
        let shape = if k < pass {
            libm::sinf(core::f32::consts::PI * k as f32 / pass as f32)
        } else {
            0.0
        };
        let share = match broken {
            Some(b) if i >= b && tooth == 0 => 0.0,
            Some(b) if i >= b + 25 && tooth == 1 => 2.0,
            _ => 1.0,
        };
        let f = 2000.0 * shape * share * load(i) + 5.0 * noise.next();
        if f > trip {
            return Some((i, d.chip_moved().is_some()));
        }
        let _ = d.sample(f);
    }
    None
}

/// The sampler trip tells a broken tooth from an overload wherever the tooth periods' boundaries
/// fall: the doubled chip's crossing comes right after the broken tooth's missing pass, which the
/// per-sample comparison with the revolution before sees even when the tooth period holding it
/// is not complete (phases where the tooth-period test alone, `dm` of the last two complete
/// periods, misses it: before `REV_LOSS_MIN`, 11 of the 24 simulated breaks under the AC were
/// told). A deeper cut crossing the same level is an overload at every phase.
#[test]
fn the_trip_tells_a_broken_tooth_from_an_overload_at_every_phase() {
    for phase in 0..25 {
        for pass in [8, 15, 24] {
            let broken = trip_verdict(phase, pass, Some(1550), |_| 1.0, &[], 2100.0);
            let (at, told) = broken.expect("the doubled chip crosses");
            assert!(at >= 1575, "phase {phase} pass {pass}: crossed at {at}");
            assert!(
                told,
                "phase {phase} pass {pass}: the break held as an overload"
            );
            // A deeper cut: the load rises by 0.1 % a sample from sample 1550 on.
            let deeper = |i: usize| 1.0 + 0.001 * i.saturating_sub(1550) as f32;
            let over = trip_verdict(phase, pass, None, deeper, &[], 2100.0);
            let (_, told) = over.expect("the deeper cut crosses");
            assert!(
                !told,
                "phase {phase} pass {pass}: an overload called a breakage"
            );
        }
    }
}

/// A trip right after a feed change is an overload, not a breakage: the AC lowers the feed for
/// a tooth period (every tooth's chip falls alike), then raises it past the load it had, and the
/// crossing comes with the raise. Against the revolution before, the lowered tooth period looks
/// like a broken tooth's missing pass followed by the next tooth's doubled chip; the AC period
/// told the detector of both feed steps, so the loss is the feed's. Without the notices the same
/// force is judged a breakage at some phases (why the notice is needed: on a 3 mm end mill whose
/// AC moved the feed every few periods near its limit, the trip held with a tool breakage).
#[test]
fn a_trip_right_after_a_told_feed_change_is_an_overload() {
    // Lowered to 0.5 for 30 samples (a 10 ms AC period is 10 samples at 1 kHz: three periods),
    // then 1.1: 2200 N peaks against the 2100 N trip.
    let dip = |i: usize| match i {
        0..1550 => 1.0,
        1550..1580 => 0.5,
        _ => 1.1,
    };
    let mut without = 0;
    for phase in 0..25 {
        for pass in [8, 15, 24] {
            let told = trip_verdict(
                phase,
                pass,
                None,
                dip,
                &[(1550, lower(50)), (1580, raise(45))],
                2100.0,
            );
            let (at, breakage) = told.expect("the raised feed crosses");
            assert!(at >= 1580, "phase {phase} pass {pass}: crossed at {at}");
            assert!(
                !breakage,
                "phase {phase} pass {pass}: a feed change called a breakage"
            );
            let untold = trip_verdict(phase, pass, None, dip, &[], 2100.0);
            if untold.is_some_and(|(_, b)| b) {
                without += 1;
            }
        }
    }
    assert!(
        without > 0,
        "the dip alone never reads as a breakage: the test shows nothing"
    );
}

/// A broken tooth right after a feed step is still a breakage: the step (a corner's
/// deceleration kept 60 % of the feed, told half a tooth period before the break) explains a
/// loss of 40 % of a tooth period's force, not the broken tooth's whole chip.
#[test]
fn a_break_right_after_a_feed_step_is_still_a_breakage() {
    let slower = |i: usize| if i < 1538 { 1.0 } else { 0.6 };
    for phase in 0..25 {
        for pass in [8, 15, 24] {
            let r = trip_verdict(
                phase,
                pass,
                Some(1550),
                slower,
                &[(1538, lower(60))],
                2100.0,
            );
            let (at, told) = r.expect("the doubled chip crosses");
            assert!(at >= 1575, "phase {phase} pass {pass}: crossed at {at}");
            assert!(
                told,
                "phase {phase} pass {pass}: the break held as an overload"
            );
        }
    }
}

/// A detector at `rpm` with `flutes` and the default settings but `curvature`.
fn det_for(rpm: f32, flutes: u8, curvature: bool) -> BreakageDetector {
    det_with(
        BreakageSettings {
            curvature,
            ..BreakageSettings::default()
        },
        rpm,
        flutes,
    )
}

/// The tooth periods `fa` through `d`; the first declaration.
fn feed_periods(d: &mut BreakageDetector, fa: &[f32]) -> Option<Breakage> {
    fa.iter()
        .fold(None, |first, &f| first.or(d.tooth_period(f)))
}

/// The Fig. 1 job's 6 mm three-flute corner end mill (1200 rpm) entering a corner under QEMU,
/// from air (Fa per tooth period, N, as the firmware's detector formed them at one phase of its
/// tooth periods): the engagement grows in steps about a revolution apart, and four periods'
/// once-per-revolution changes (those before the last) (17, 8, 172, 97 N at a level of 248 N) meet the
/// chip-transfer test's three tolerances, the jump made by the next step alone. The suspected
/// period lost nothing against the period before (8 against 17 N): not a broken tooth's lost
/// chip ([`TRANSFER_LOSS`]); and the cut rose by 0.35 of the jump per revolution
/// ([`TRANSFER_RISE`]). It was declared a breakage.
#[test]
fn a_staircase_of_steps_a_revolution_apart_is_not_a_chip_transfer() {
    let fa = [
        13.3, 20.8, 29.9, 24.6, 33.5, 48.9, 60.9, 76.1, 71.4, 84.2, 102.9, 129.2, 144.0, 132.9,
        164.8, 142.6, 202.8, 202.0, 215.1, 237.7, 241.5, 250.6, 316.0, 280.0, 223.9, 125.6, 129.1,
        130.4, 139.8, 126.4, 135.9, 152.1, 152.3, 154.4, 150.1, 152.8, 155.1, 167.2, 154.3, 164.9,
        179.2, 181.7, 164.1, 193.6, 179.6, 174.4, 211.0, 187.2, 346.3, 308.0, 274.3,
    ];
    let mut d = det_for(1200.0, 3, true);
    assert_eq!(feed_periods(&mut d, &fa), None);
    // The same cut with a tooth whose chip (80 N, a jump of 324 N: the cut's rise of 57 N per
    // revolution is within [`TRANSFER_RISE`] of it) moved from the suspected period to the next
    // is a breakage.
    let mut broken = fa;
    if let Some(f) = broken.get_mut(47) {
        *f -= 80.0;
    }
    if let Some(f) = broken.get_mut(48) {
        *f += 80.0;
    }
    let mut d = det_for(1200.0, 3, true);
    assert!(feed_periods(&mut d, &broken).is_some());
}

/// A jump after a period that lost nothing against the one before ([`TRANSFER_LOSS`]): a steady
/// 1000 N cut whose force falls by 150 N at period s-1 and 180 N at s (against the revolution
/// before), then jumps by 600 N at s+1 and is 120 N above s-1's at s+2. The flanks, their mean,
/// the cut's rise and the pair all meet their tolerances; but period s lost 30 N (0.05 of the
/// jump) against s-1: no tooth's chip went to the next. (Also its stair-shaped twin below.)
#[test]
fn a_jump_after_a_period_that_lost_nothing_is_not_a_chip_transfer() {
    let mut fa = vec![1000.0f32; 30];
    fa.extend([850.0, 820.0, 1420.0, 970.0]);
    let mut d = det_for(1200.0, 3, true);
    assert_eq!(feed_periods(&mut d, &fa), None);
    // s losing 150 N more (0.2 of a 750 N jump) is a chip that moved.
    if let Some(f) = fa.get_mut(31) {
        *f -= 150.0;
    }
    let mut d = det_for(1200.0, 3, true);
    assert!(feed_periods(&mut d, &fa).is_some());
}

/// The Fig. 1 job's 10 mm two-flute ball end mill (800 rpm) finishing a raster across the steps
/// the roughing left, from air, under QEMU: its tooth passes meet different parts of the
/// surface, and the pattern of its two tooth periods bends the same way two revolutions running
/// while the load falls (283, 247, 263, 227, 233 N): the curvature confirmation declared a
/// breakage. A ball end mill's detector runs without it ([`BreakageSettings::curvature`],
/// `AcSettings::breakage_settings_for`).
#[test]
fn a_ball_end_mills_tooth_passes_on_a_stepped_surface_are_not_a_breakage() {
    let fa = [
        13.6, 6.3, 5.3, 15.9, 56.3, 84.5, 124.5, 232.5, 257.6, 289.3, 307.6, 319.6, 333.0, 332.4,
        334.5, 331.2, 338.3, 331.0, 332.6, 323.3, 323.3, 314.5, 312.6, 306.9, 305.5, 311.4, 299.4,
        291.7, 283.2, 247.5, 263.0, 226.8, 233.4,
    ];
    let mut flat = det_for(800.0, 2, true);
    assert!(feed_periods(&mut flat, &fa).is_some(), "the premise");
    let mut ball = det_for(800.0, 2, false);
    assert_eq!(feed_periods(&mut ball, &fa), None);
}

/// The same corner end mill entering another corner, on the host (the Fig. 1 job at one phase of
/// its tooth periods, from air): the last four periods' once-per-revolution changes (44, -2,
/// 187, 123 N at a level of 180 N) meet the three tolerances and the loss (0.24 of the jump),
/// but the cut itself rises by 0.44 of the jump per revolution: a staircase, not a broken tooth,
/// whose doubled chip would make the AC lower the feed ([`TRANSFER_RISE`]). It was declared a
/// breakage.
#[test]
fn a_corner_entrys_rising_staircase_is_not_a_chip_transfer() {
    let fa = [
        6.5, 10.9, 11.1, 13.4, 10.1, 28.2, 20.0, 32.6, 26.7, 40.5, 44.6, 46.1, 67.0, 57.8, 81.8,
        81.1, 89.6, 81.1, 84.6, 104.8, 98.5, 119.2, 121.7, 121.8, 135.6, 140.8, 62.1, 52.4, 55.3,
        53.9, 53.2, 56.8, 57.0, 59.6, 63.9, 69.2, 76.7, 73.8, 75.3, 81.9, 68.3, 74.3, 83.8, 76.1,
        81.3, 95.8, 77.7, 116.4, 92.9, 86.1, 115.2, 127.7, 129.7, 112.8, 314.7, 252.4,
    ];
    let mut d = det_for(1200.0, 3, true);
    assert_eq!(feed_periods(&mut d, &fa), None);
}
