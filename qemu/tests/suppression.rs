//! Chatter suppression by depth reduction on the host (issue 10; Munasinghe 1994, sections 3.3,
//! 4.4.4 and 5.3.2): the thesis' table 3.2 cut at 8.89 mm, heard by the firmware's chatter
//! monitor, held within two detection cycles and re-planned by the firmware's loader code
//! (`millac::rt::replan`) in steps of `$276` until it is quiet, every programmed cell of the
//! stock removed as the programmed cut removes it; the same cut at 2.54 mm is never held.
use millac::ac::AcSettings;
use millac::Settings;
use millac_plant::chatter::thesis_table_3_2 as t;
use millac_plant::Stock;
use millac_qemu::host::acsim::{self, Cut, HostRun};
use millac_qemu::{analysis, evaluation::chatterlab};

/// The chatter monitor as the thesis sets it (twice the largest amplitude of the 2.54 mm cut),
/// with the depth step `step_mm`.
fn settings(step_mm: f32) -> AcSettings {
    let s = Settings::default();
    let listen = AcSettings {
        flutes: t::FLUTES,
        monitor_rpm: t::RPM as u32,
        chatter_step_mm: step_mm,
        ..AcSettings::default()
    };
    let (text, cut) = chatterlab::through_slot(0.1);
    let prog = analysis::load_program(&text, &s).unwrap();
    let threshold = chatterlab::thesis_threshold(&prog, &s, &cut, listen).unwrap();
    AcSettings {
        chatter_threshold: threshold,
        ..listen
    }
}

fn run(depth_in: f64, acs: Option<AcSettings>, rigid: bool) -> (HostRun, usize) {
    let s = Settings::default();
    let (text, cut) = chatterlab::through_slot(depth_in);
    let cut = if rigid {
        Cut { modes: None, ..cut }
    } else {
        cut
    };
    let prog = analysis::load_program(&text, &s).unwrap();
    let r = acsim::run_with_faults(&prog, &s, &cut, acs, true, &[]).unwrap();
    (r, prog.len())
}

/// Cells whose top differs between two stocks of the same grid, and of those the cells that are
/// not next to (8-neighbourhood) a cell where `programmed` changes height: a difference at the
/// edge of the programmed cut is within one cell.
fn differences(run: &Stock, programmed: &Stock) -> (usize, usize) {
    let (nx, ny) = run.dims();
    assert_eq!((nx, ny), programmed.dims());
    let (a, b) = (run.tops(), programmed.tops());
    let at = |t: &[f64], i: i64, j: i64| {
        { (0..nx as i64).contains(&i) && (0..ny as i64).contains(&j) }
            .then(|| t[j as usize * nx + i as usize])
    };
    let (mut differ, mut inside) = (0, 0);
    for i in 0..nx as i64 {
        for j in 0..ny as i64 {
            let p = at(b, i, j).unwrap();
            if at(a, i, j).unwrap() == p {
                continue;
            }
            differ += 1;
            let edge =
                (-1..=1).any(|di| (-1..=1).any(|dj| at(b, i + di, j + dj).is_some_and(|q| q != p)));
            if !edge {
                inside += 1;
            }
        }
    }
    (differ, inside)
}

#[test]
fn the_chattering_cut_is_held_within_two_cycles_and_cut_in_steps_to_the_programmed_stock() {
    let acs = settings(1.0);
    let (r, blocks) = run(0.35, Some(acs), false);
    let record_s = f64::from(millac::monitor::chatter::RECORD as u32) / acsim::SOUND_HZ;
    // Detection: the chatter's onset is the first of the records before the first detection
    // that show the tool's mode above the stable cut's largest amplitude (half the threshold)
    // without a break (the growth); the monitor says chatter within two records of it.
    let mode = |sp: &millac::monitor::chatter::Spectrum| {
        sp.peak_amplitude > acs.chatter_threshold / 2.0
            && (sp.peak_hz / t::MODE.fn_hz as f32 - 1.0).abs() < 0.1
    };
    let k = r
        .spectra
        .iter()
        .position(|(_, sp)| sp.chatter)
        .expect("the 8.89 mm cut is detected");
    let first = r.spectra[k].0;
    let grown = r.spectra[..=k]
        .iter()
        .rev()
        .take_while(|(_, sp)| mode(sp))
        .count();
    assert!(grown >= 1, "the detection is at the mode");
    let onset = r.spectra[k + 1 - grown].0;
    assert!(
        first - onset <= 2.0 * record_s + 1e-9,
        "onset {onset:.3} s, detected {first:.3} s"
    );
    // Suppression: re-planned step by step (each lift from the level the hold stopped at), never
    // refused; the program completes with its detours.
    assert!(r.refused.is_empty(), "{:?}", r.refused);
    assert!(!r.replans.is_empty());
    let lift = r.replans[0].1.lift as i32;
    assert_eq!(lift, 394, "1 mm in 0.0001 in");
    let z1 = r.replans[0].1.at[2];
    for (k, (_, p)) in r.replans.iter().enumerate() {
        assert_eq!(p.count as usize, k + 1);
        assert_eq!(
            p.at[2],
            z1 + k as i32 * lift,
            "re-plan {k} held at {:?}",
            p.at
        );
    }
    assert_eq!(r.blocks_done, blocks + 4 * r.replans.len());
    // Quiet once the depth is low enough: no chatter after the last re-plan's cycle.
    let (last, _) = *r.replans.last().unwrap();
    let late: Vec<f64> = r
        .spectra
        .iter()
        .filter(|(t, sp)| sp.chatter && *t > last + 2.0 * record_s)
        .map(|(t, _)| *t)
        .collect();
    assert!(late.is_empty(), "chatter after the last re-plan: {late:?}");
    // The stock is the programmed one: the same program cut by a rigid tool without AC.
    let (plain, _) = run(0.35, None, true);
    let (differ, inside) = differences(r.stock.as_ref().unwrap(), plain.stock.as_ref().unwrap());
    let depth_mm = 8.89 - r.replans.len() as f64;
    eprintln!(
        "onset {onset:.3} s, detected {first:.3} s; {} re-plans of 1 mm (the last pass {depth_mm:.2} mm deep), \
         machining {:.2} s (rigid {:.2} s); stock cells differing {differ}, {inside} of them away from the cut's edge",
        r.replans.len(),
        r.machining_time_s,
        plain.machining_time_s
    );
    assert_eq!(
        inside, 0,
        "{differ} cells differ, {inside} away from an edge"
    );
}

#[test]
fn the_stable_cut_is_never_held() {
    let acs = settings(1.0);
    let (r, blocks) = run(0.1, Some(acs), false);
    assert!(r.spectra.iter().all(|(_, sp)| !sp.chatter));
    assert!(r.replans.is_empty() && r.refused.is_empty());
    assert_eq!(r.blocks_done, blocks);
    assert!(!r.held);
}

#[test]
fn without_a_step_the_chattering_cut_stays_held() {
    let (r, blocks) = run(0.35, Some(settings(0.0)), false);
    assert!(r.held);
    assert!(r.replans.is_empty());
    assert!(r.blocks_done < blocks, "the run ends at the hold");
    assert!(matches!(r.alarm, Some(millac::ac::Alarm::Chatter { .. })));
}

/// The high-speed cut of the table 3.2 tool (`chatterlab::high_speed_slot`): the monitor's
/// threshold by the thesis' rule from the same slot at 2 mm, `$276` 1 mm and `$277` as given.
fn high_speed(depth_in: f64, max_rpm: u32, rigid: bool, ac: bool) -> (HostRun, usize, f32) {
    let s = Settings::default();
    let listen = AcSettings {
        flutes: t::FLUTES,
        monitor_rpm: HIGH_RPM,
        chatter_step_mm: 1.0,
        chatter_max_rpm: max_rpm,
        ..AcSettings::default()
    };
    let (text, cut) = chatterlab::high_speed_slot(0.08, HIGH_RPM);
    let prog = analysis::load_program(&text, &s).unwrap();
    let threshold = chatterlab::thesis_threshold(&prog, &s, &cut, listen).unwrap();
    let acs = AcSettings {
        chatter_threshold: threshold,
        ..listen
    };
    let (text, cut) = chatterlab::high_speed_slot(depth_in, HIGH_RPM);
    let cut = if rigid {
        Cut { modes: None, ..cut }
    } else {
        cut
    };
    let prog = analysis::load_program(&text, &s).unwrap();
    let r = acsim::run_with_faults(&prog, &s, &cut, ac.then_some(acs), true, &[]).unwrap();
    (r, prog.len(), threshold)
}

const HIGH_RPM: u32 = 14_000;

/// `$277`: the 4 mm slot at 14 000 rpm chatters; the spindle goes to the nearest stable lobe
/// (the rule's speed from the heard frequency) and the slot is cut in one pass, nothing
/// re-planned, every programmed cell removed, in less time than the depth steps take.
#[test]
fn a_spindle_speed_on_the_nearest_lobe_quiets_the_high_speed_cut() {
    let record_s = f64::from(millac::monitor::chatter::RECORD as u32) / acsim::SOUND_HZ;
    let (r, blocks, threshold) = high_speed(0.157, 30_000, false, true);
    let first = r
        .spectra
        .iter()
        .find(|(_, sp)| sp.chatter)
        .expect("the 4 mm cut at 14 000 rpm chatters")
        .0;
    assert!(!r.speeds.is_empty() && r.speeds.len() as u32 <= millac::rt::replan::SPEED_TRIES);
    let (t1, s1) = r.speeds[0];
    // The reaction follows the detection within one AC period and the stop.
    assert!(
        t1 - first < record_s,
        "detected {first:.3} s, changed {t1:.3} s"
    );
    assert_eq!(s1.from, HIGH_RPM);
    // The rule: m tooth periods in one chatter period at the new speed.
    let tooth_hz = f64::from(s1.to) * f64::from(t::FLUTES) / 60.0;
    assert!(
        (tooth_hz * f64::from(s1.m) - f64::from(s1.chatter_hz)).abs() < 1.0,
        "{s1:?}"
    );
    assert!(
        (11_750..=12_750).contains(&s1.to),
        "into the stable band: {s1:?}"
    );
    // The monitor heard the tool's mode.
    assert!((f64::from(s1.chatter_hz) / t::MODE.fn_hz - 1.0).abs() < 0.1);
    // Quiet at the new speed while the tool is in the full slot: no chatter record until the
    // tool's edge leaves the block (X 1 in - the radius, 0.6875 in = 6875 BLU; where the second
    // change, if any, is made).
    for (t, sp) in &r.spectra {
        if *t > t1 + 2.0 * record_s && sp.chatter {
            let (_, s2) = r
                .speeds
                .iter()
                .find(|(ts, _)| *ts > *t)
                .expect("a later detection is answered");
            assert!(
                s2.at[0] >= 6875,
                "chatter in the full slot at {t:.3} s: {s2:?}"
            );
        }
    }
    assert!(
        r.replans.is_empty() && r.refused.is_empty(),
        "{:?} {:?}",
        r.replans,
        r.refused
    );
    assert_eq!(r.blocks_done, blocks, "one pass");
    // The stock is the programmed one, and the depth steps take longer.
    let (rigid, _, _) = high_speed(0.157, 0, true, false);
    let (differ, inside) = differences(r.stock.as_ref().unwrap(), rigid.stock.as_ref().unwrap());
    assert_eq!(
        inside, 0,
        "{differ} cells differ, {inside} away from an edge"
    );
    let (depth, _, _) = high_speed(0.157, 0, false, true);
    assert!(depth.speeds.is_empty() && !depth.replans.is_empty());
    eprintln!(
        "threshold {threshold:.2}; detected {first:.3} s; speeds {:?}; machining {:.2} s (depth steps {:.2} s, rigid {:.2} s); cells differing {differ}",
        r.speeds.iter().map(|(t, s)| (format!("{t:.3}"), s.from, s.to, s.chatter_hz, s.m)).collect::<Vec<_>>(),
        r.machining_time_s,
        depth.machining_time_s,
        rigid.machining_time_s
    );
    assert!(r.machining_time_s < depth.machining_time_s);
}

/// `$277` on the thesis' cut: at 1500 rpm the 2-flute tool's lobes are 48 rpm apart, no speed is
/// stable at 8.89 mm; the two changes in the held block do not quiet it and the depth steps take
/// over, as without `$277`; the detour's passes go straight to further depth steps.
#[test]
fn at_the_thesis_speed_no_lobe_helps_and_the_depth_steps_take_over() {
    let acs = AcSettings {
        chatter_max_rpm: 2000,
        ..settings(1.0)
    };
    let (r, blocks) = run(0.35, Some(acs), false);
    assert_eq!(
        r.speeds.len() as u32,
        millac::rt::replan::SPEED_TRIES,
        "{:?}",
        r.speeds
    );
    for (_, s) in &r.speeds {
        // Lobe numbers about 32: the next lobe is about 3 % away.
        assert!(s.m > 25 && s.to.abs_diff(s.from) * 20 < s.from, "{s:?}");
    }
    assert!(r.speeds.iter().all(|(_, s)| s.line == r.speeds[0].1.line));
    let (t2, _) = r.speeds[1];
    assert!(
        !r.replans.is_empty() && r.replans[0].0 > t2,
        "{:?}",
        r.replans
    );
    assert!(r.refused.is_empty());
    assert_eq!(r.blocks_done, blocks + 4 * r.replans.len());
}
