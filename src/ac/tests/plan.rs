//! Host tests of the AC under the plan (`FeedCeiling::Plan`, issue 11): the plan ratio k's
//! first contact, lowering, raising, memory across air and its bounds, on a toy process whose
//! load is the plan's error x k x the plan's own profile (host tests).
use super::super::*;
use super::codes;
use crate::ports::PLAN_ONE;

fn plan() -> AcSettings {
    AcSettings {
        ceiling: FeedCeiling::Plan,
        ..AcSettings::default()
    }
}

/// The toy process: the window's peak load (F/F0) is `eps x k x p`, k the plan ratio the
/// controller set one period before (the chip lags the feed), p the plan's profile at this
/// period (1: a piece's peak, where the plan predicts F0; 0: air). Torque in proportion
/// (F R / T = 1, inside the plausibility band). Returns per period (load, k after it).
fn run(c: &mut AcController, eps: f32, profile: &[f32]) -> Vec<(f32, f32)> {
    let s = *c.settings();
    let f0 = s.f0_n();
    let mut out = Vec::new();
    for &p in profile {
        let k = c.feed_cap() as f32 / s.f_max as f32;
        let load = eps * k * p;
        let f = load * f0;
        let cs = codes(f * s.tool_radius_mm / 1000.0, f, 0.0);
        for _ in 0..s.samples_per_period() {
            c.sample(cs);
        }
        let o = c.period();
        assert_eq!(o.state, AcState::Run, "held at load {load}");
        out.push((load, c.feed_cap() as f32 / s.f_max as f32));
    }
    out
}

fn k_of(c: &AcController) -> f32 {
    c.feed_cap() as f32 / c.settings().f_max as f32
}

#[test]
fn the_frame_words_carry_k_under_the_plan_only() {
    let p = plan();
    assert_eq!(frame_words(p.f_max, &p), (p.f_max, PLAN_ONE));
    assert_eq!(frame_words(p.f_max / 2, &p), (p.f_max, PLAN_ONE / 2));
    // A hold is a cap of 0 whatever k was.
    assert_eq!(frame_words(0, &p).0, 0);
    // Rounded to the nearest 4096th, never above 1.
    assert_eq!(frame_words(1, &p), (p.f_max, 1));
    assert_eq!(frame_words(p.f_max + 7, &p), (p.f_max, PLAN_ONE));
    let d = AcSettings::default();
    assert_eq!(frame_words(1234, &d), (1234, PLAN_ONE));
    assert_eq!(frame_words(0, &d), (0, PLAN_ONE));
}

#[test]
fn a_right_plan_runs_at_k_1_after_the_first_contact() {
    let mut c = ctl_plan();
    assert!(
        (k_of(&c) - PLAN_START).abs() < 1e-3,
        "starts at {}",
        k_of(&c)
    );
    // Air, then the first entry (a step to the piece's peak), then the cut.
    let mut profile = vec![0.0; 20];
    profile.extend(vec![1.0; 50]);
    let r = run(&mut c, 1.0, &profile);
    assert!(r
        .iter()
        .all(|&(_, k)| (k - PLAN_START).abs() < 1e-3 || k > PLAN_START));
    assert!((k_of(&c) - 1.0).abs() < 2e-3, "k {}", k_of(&c));
    // In the cut at F0 (and within the tolerance) nothing changes any more.
    let r = run(&mut c, 1.0, &[1.0, 1.03, 1.0, 0.97, 1.04, 1.0]);
    assert!(r.iter().all(|&(_, k)| (k - 1.0).abs() < 2e-3), "{r:?}");
}

fn ctl_plan() -> AcController {
    AcController::new(plan().validated().expect("valid settings"))
}

#[test]
fn a_harder_material_is_met_below_the_overload_learnt_and_kept_across_air() {
    let s = plan();
    let overload = 1.0 - s.overload_e;
    let tol = plan_tolerance(&s);
    let eps = 1.15;
    let mut c = ctl_plan();
    // The entry's rising edge (the tooth not yet full) first, then the piece's peak.
    let mut profile = vec![0.0; 5];
    profile.push(0.85);
    profile.extend(vec![1.0; 40]);
    let r = run(&mut c, eps, &profile);
    assert!(r.iter().all(|&(l, _)| l < overload), "{r:?}");
    let learnt = k_of(&c);
    assert!((learnt * eps - 1.0).abs() < 0.01, "k {learnt}");
    // Air for a second, then the next entry at once: k kept, the entry within the tolerance.
    let mut profile = vec![0.0; 100];
    profile.extend(vec![1.0; 20]);
    let r = run(&mut c, eps, &profile);
    assert!(r.iter().all(|&(_, k)| (k - learnt).abs() < 2e-3), "{r:?}");
    assert!(r.iter().all(|&(l, _)| l <= 1.0 + tol), "{r:?}");
}

#[test]
fn an_overshoot_is_lowered_once_and_comes_back_where_the_plan_is_right() {
    let s = plan();
    let tol = plan_tolerance(&s);
    let mut c = ctl_plan();
    run(&mut c, 1.0, &[1.0; 20]);
    assert!((k_of(&c) - 1.0).abs() < 2e-3);
    // A hidden boss: the plan expected air, the guard's feed loads 1.056.
    let mut lowered = vec![k_of(&c)];
    let r = run(&mut c, 1.0, &[1.056; 12]);
    lowered.extend(r.iter().map(|&(_, k)| k));
    let k_boss = k_of(&c);
    assert!(
        (k_boss * 1.056 - (1.0 + 0.5 * tol)).abs() < 0.01,
        "k {k_boss}"
    );
    // Lowered once: the windows after the correction (the chip cut before it) do not lower again.
    assert!(
        lowered.windows(2).filter(|w| w[1] < w[0] - 1e-4).count() == 1,
        "{lowered:?}"
    );
    // Past the boss, the plan's next cut at F0: k comes back to 1.
    run(&mut c, 1.0, &[0.0; 30]);
    assert!((k_of(&c) - k_boss).abs() < 1e-4, "air keeps k");
    run(&mut c, 1.0, &[1.0; 20]);
    assert!((k_of(&c) - 1.0).abs() < 2e-3, "k {}", k_of(&c));
}

#[test]
fn a_light_falling_load_does_not_raise_k() {
    // A material 15 % harder, learnt; then a pass leaving the material: the plan's profile
    // falls from 1 to 0.5 while the controller might read its loads as the plan's error.
    let eps = 1.15;
    let mut c = ctl_plan();
    run(&mut c, eps, &[1.0; 30]);
    let learnt = k_of(&c);
    let falling: Vec<f32> = (0..100).map(|i| 1.0 - 0.005 * i as f32).collect();
    let r = run(&mut c, eps, &falling);
    let top = r.iter().map(|&(_, k)| k).fold(0.0, f32::max);
    assert!(top <= learnt * 1.01, "k rose from {learnt} to {top}");
    // And the next entry stays within the tolerance.
    let tol = plan_tolerance(c.settings());
    let r = run(&mut c, eps, &[0.0, 0.0, 1.0, 1.0, 1.0]);
    assert!(r.iter().all(|&(l, _)| l <= 1.0 + tol), "{r:?}");
}

#[test]
fn an_overload_under_the_plan_holds_and_resumes_at_a_lower_k() {
    let s = plan();
    let mut c = ctl_plan();
    let f0 = s.f0_n();
    let step = |c: &mut AcController, load: f32| {
        let f = load * f0;
        let cs = codes(f * s.tool_radius_mm / 1000.0, f, 0.0);
        for _ in 0..s.samples_per_period() {
            c.sample(cs);
        }
        c.period()
    };
    for _ in 0..20 {
        step(&mut c, 0.9);
    }
    let before = k_of(&c);
    let o = step(&mut c, 1.3);
    assert!(matches!(o.state, AcState::Hold(Alarm::Overload { .. })));
    assert_eq!(frame_words(o.feed_cap, &s).0, 0);
    c.resume();
    assert!(k_of(&c) <= before / 1.25, "{before} -> {}", k_of(&c));
}

/// A new job (the serial loader's M2/M30 or soft reset) starts the plan afresh: k back at
/// PLAN_START and the next first contact judged again, so a job whose plan was right (k = 1)
/// does not hand k = 1 to the next job's first entry, where a harder material would step to
/// the overload hold.
#[test]
fn a_new_job_meets_its_first_entry_at_plan_start_and_learns_its_own_k() {
    let s = plan();
    let overload = 1.0 - s.overload_e;
    let mut c = ctl_plan();
    run(&mut c, 1.0, &[1.0; 20]);
    assert!((k_of(&c) - 1.0).abs() < 2e-3, "k {}", k_of(&c));
    c.new_job();
    assert!(
        (k_of(&c) - PLAN_START).abs() < 1e-3,
        "the next job starts at {}",
        k_of(&c)
    );
    // The next job: a material 15 % harder than its plan, met at once from air.
    let eps = 1.15;
    let mut profile = vec![0.0; 10];
    profile.extend(vec![1.0; 40]);
    let r = run(&mut c, eps, &profile);
    assert!(r.iter().all(|&(l, _)| l < overload), "{r:?}");
    assert!((k_of(&c) * eps - 1.0).abs() < 0.01, "k {}", k_of(&c));
    // Its first contact was judged afresh: a right plan after a new job raises k to 1 again.
    c.new_job();
    run(&mut c, 1.0, &profile);
    assert!((k_of(&c) - 1.0).abs() < 2e-3, "k {}", k_of(&c));
}

/// Outside the plan a new job changes nothing.
#[test]
fn a_new_job_leaves_the_other_ceilings_alone() {
    let mut c = AcController::new(AcSettings::default().validated().expect("valid settings"));
    run(&mut c, 1.0, &[0.5; 10]);
    let before = c.feed_cap();
    assert_ne!(before, plan_start(c.settings()));
    c.new_job();
    assert_eq!(c.feed_cap(), before);
}
