//! Chatter suppression by depth reduction on the host (issue 10; Munasinghe 1994, sections 3.3,
//! 4.4.4 and 5.3.2): the thesis' table 3.2 cut at 8.89 mm, heard by the firmware's chatter
//! monitor, held within two detection cycles and re-planned by the firmware's loader code
//! (`millac::rt::replan`) in steps of `$276` until it is quiet, every programmed cell of the
//! stock removed as the programmed cut removes it; the same cut at 2.54 mm is never held.
use millac::ac::AcSettings;
use millac::Settings;
use millac_plant::chatter::thesis_table_3_2 as t;
use millac_plant::Stock;
use millac_qemu::acsim::{self, Cut, HostRun};
use millac_qemu::{analysis, chatterlab};

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
