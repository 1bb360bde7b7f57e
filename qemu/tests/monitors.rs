//! The process monitors in the firmware under QEMU (host, issue 10): the AC task of the QEMU app
//! runs the breakage and chatter monitors its settings turn on (`$268`, `$266`; the record a
//! run writes), on the simulated cut's force and sound channels. A broken tooth holds the feed
//! with the breakage alarm within two revolutions, in the same AC period as the host
//! simulation of the same code; a sound tool cuts the slot to its end. The thesis' table 3.2
//! cut chatters at 8.89 mm and is held with the chatter alarm; at 2.54 mm it is not. No AC period
//! overruns its 10 ms with the monitors' work in it (the cost is printed: instructions of the AC
//! task per period).
use millac::ac::AcSettings;
use millac::rt::replan::Replanned;
use millac::Settings;
use millac_plant::chatter::thesis_table_3_2 as t;
use millac_qemu::evaluation::breaklab::{slot_cut, SLOT};
use millac_qemu::evaluation::chatterlab::{self, preset_slot as preset};
use millac_qemu::host::acsim::{self, Cut};
use millac_qemu::{analysis, emulator::runner};
use std::path::PathBuf;

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("millac-monitors-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// When tooth 1 breaks in the slot (s of virtual time; the tool is in the full slot from 0.5 s).
const BREAK_S: f64 = 6.0;

/// The firmware's run (QEMU) with the AC settings `acs`: its outcome.
fn qemu_run(name: &str, text: &str, cut: Cut, acs: AcSettings) -> runner::Outcome {
    let ac = runner::AcRun {
        cut,
        ac: true,
        faults: Vec::new(),
        settings: acs,
    };
    runner::run_with(text, &out_dir(name), 4, Some(&ac)).unwrap()
}

/// The AC task's instructions per period (SSI0) and the overrun count of the run's last period.
fn cost(o: &runner::Outcome, name: &str) {
    let cap = o.capture.as_ref().unwrap();
    eprintln!(
        "{name}: AC period instructions {} over {} periods; chatter monitor task {} over {} runs",
        runner::stats(&cap.handlers[3].1),
        o.ac_log.len(),
        runner::stats(&cap.handlers[4].1),
        cap.handlers[4].1.len(),
    );
    let last = o.ac_log.last().expect("AC periods ran");
    assert_eq!(last.overruns, 0, "{name}: AC periods overran");
}

/// The first held period of the firmware's AC log: its time and the hold's text.
fn first_hold(o: &runner::Outcome) -> Option<(u64, String)> {
    o.ac_log
        .iter()
        .find_map(|r| r.hold.clone().map(|h| (r.t_ms, h)))
}

/// The first held period (ms) of the host simulation of `text` on `cut` with `acs` (the
/// firmware's code on the host).
fn host_hold(text: &str, cut: &Cut, acs: AcSettings) -> Option<u64> {
    let s = Settings::default();
    let prog = analysis::load_program(text, &s).unwrap();
    acsim::run_with_faults(&prog, &s, cut, Some(acs), true, &[])
        .unwrap()
        .rows
        .iter()
        .find(|r| r.state.starts_with("hold"))
        .map(|r| r.t_ms)
}

#[test]
fn a_broken_tooth_is_held_by_the_firmware_within_two_revolutions_as_on_the_host() {
    let acs = AcSettings {
        breakage: millac::ac::Breakage::On,
        ..AcSettings::default()
    };
    // A sound tool: the whole slot, no alarm.
    let sound = qemu_run("sound", SLOT, slot_cut(None), acs);
    cost(&sound, "sound tool");
    assert_eq!(first_hold(&sound), None);
    assert_eq!(sound.summary["completed"], true, "{}", sound.summary);
    // Tooth 1 breaks: held with the breakage alarm, the residuals named.
    let broken = qemu_run("broken", SLOT, slot_cut(Some(BREAK_S)), acs);
    cost(&broken, "broken tooth");
    let (t_ms, text) = first_hold(&broken).expect("held");
    assert!(text.contains("tool breakage"), "{text}");
    let alarm = broken.summary["hold"]["alarm"]
        .as_str()
        .unwrap()
        .to_string();
    assert!(
        alarm.starts_with("breakage hold: tool breakage at tooth period")
            && alarm.contains("e1 =")
            && alarm.contains("e2 ="),
        "{alarm}"
    );
    // At 600 rpm a revolution is 100 ms.
    let delay_rev = (t_ms as f64 / 1000.0 - BREAK_S) / 0.1;
    eprintln!("broken at {BREAK_S} s, held at {t_ms} ms: {delay_rev:.2} revolutions; {alarm}");
    assert!(
        delay_rev > 0.0 && delay_rev <= 2.0,
        "{delay_rev} revolutions"
    );
    // The same code on the host holds in the same period.
    assert_eq!(host_hold(SLOT, &slot_cut(Some(BREAK_S)), acs), Some(t_ms));
}

#[test]
fn the_firmware_holds_the_chattering_cut_and_not_the_stable_one() {
    // The threshold by the thesis' rule on the host: twice the largest amplitude of a
    // chatter-free cut (2.54 mm) heard by the same detector.
    let s = Settings::default();
    let (text, cut) = preset(0.1, 2.0);
    let prog = analysis::load_program(&text, &s).unwrap();
    let listen = AcSettings {
        flutes: t::FLUTES,
        monitor_rpm: t::RPM as u32,
        ..AcSettings::default()
    };
    let threshold = chatterlab::thesis_threshold(&prog, &s, &cut, listen).unwrap();
    // Detection alone (`$276=0`): a chatter hold stays a hold, so the run stops and reports it
    // (the re-plan that follows with a step set: `chatter_suppression_in_the_firmware_as_on_the_host`).
    let acs = AcSettings {
        chatter_threshold: threshold,
        chatter_step_mm: 0.0,
        ..listen
    };
    // 2.54 mm under QEMU (a shorter slot): no alarm.
    let (text, cut) = preset(0.1, 0.8);
    let stable = qemu_run("stable", &text, cut, acs);
    cost(&stable, "2.54 mm");
    assert_eq!(first_hold(&stable), None);
    assert_eq!(stable.summary["completed"], true);
    // 8.89 mm: held with the chatter alarm near the tool's mode.
    let (text, cut) = preset(0.35, 2.0);
    let deep = qemu_run("deep", &text, cut, acs);
    cost(&deep, "8.89 mm");
    let (t_ms, hold) = first_hold(&deep).expect("held");
    let alarm = deep.summary["hold"]["alarm"].as_str().unwrap().to_string();
    eprintln!("threshold {:.2}: held at {t_ms} ms: {alarm}", threshold);
    assert!(hold.starts_with("chatter"), "{hold}");
    let hz: f32 = alarm
        .split(" at ")
        .nth(1)
        .and_then(|r| r.split(" Hz").next())
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("{alarm}"));
    assert!((hz / t::MODE.fn_hz as f32 - 1.0).abs() < 0.1, "{hz} Hz");
    // The same code on the host holds within one detection cycle (its verdict delayed as the
    // firmware's monitor task delays it). Not in the same period for sure: the firmware's AC task
    // applies the feed cap some microseconds after the host's period boundary, the feeds differ
    // by a pulse here and there, and the chatter's growth at the threshold amplifies that into a
    // record earlier or later (with a corrected plant probe tried in issue 10: 730 ms on the
    // firmware, 780 ms on the host).
    let (text, cut) = preset(0.35, 2.0);
    let host = host_hold(&text, &cut, acs).expect("the host holds");
    let cycle_ms = (1000 * millac::monitor::chatter::RECORD as u64).div_ceil(5000) + 10;
    assert!(
        host.abs_diff(t_ms) <= cycle_ms,
        "firmware {t_ms} ms, host {host} ms"
    );
}

/// A stiff mode for the default 0.5 in cutter (2500 Hz, 5 % damping, 4e8 N/m in X and Y): the
/// zero-order lobes put its full-slot limit in steel at 600 rpm near 10 mm, beyond the pocket's
/// 6.35 mm, so the pocket is a chatter-free cut the microphone still hears.
const STIFF: millac_plant::lobes::Mode = millac_plant::lobes::Mode {
    fn_hz: 2500.0,
    zeta: 0.05,
    k_n_m: 4.0e8,
};

/// The thesis' three functions together (its chapter 5): the pocket under QEMU with the AC,
/// breakage detection and chatter detection on, the tool with 5/0/-3/0 um of run-out, flexible
/// (a stiff mode) and heard: no false alarm of either monitor, the pocket completed, no AC
/// period overrun, and the same machining time as the host simulation of the same code.
#[test]
fn ac_breakage_and_chatter_together_on_the_pocket() {
    use millac_qemu::evaluation::bench;
    let s = Settings::default();
    let case = &bench::CASES[1];
    let prog = case.load(&s).unwrap();
    let cut = Cut {
        runout_mm: vec![0.005, 0.0, -0.003, 0.0],
        modes: Some((vec![STIFF], vec![STIFF])),
        ..case
            .cut(
                &s,
                millac_plant::DriveModel::Stepper,
                millac_plant::Material::STEEL,
            )
            .unwrap()
    };
    // The chatter threshold by the thesis' rule from this chatter-free cut on the host.
    let threshold = chatterlab::thesis_threshold(&prog, &s, &cut, AcSettings::default()).unwrap();
    let acs = AcSettings {
        chatter_threshold: threshold,
        breakage: millac::ac::Breakage::On,
        ..AcSettings::default()
    };
    let host = acsim::run_with_faults(&prog, &s, &cut, Some(acs), true, &[]).unwrap();
    let o = qemu_run("pocket", case.program, cut, acs);
    cost(&o, "pocket, three functions");
    eprintln!(
        "threshold {:.2} codes; machining time firmware {} s, host {:.3} s",
        threshold, o.summary["machining_time_s"], host.machining_time_s
    );
    assert_eq!(first_hold(&o), None);
    assert!(host.alarm.is_none(), "{:?}", host.alarm);
    assert_eq!(o.summary["completed"], true, "{}", o.summary);
    let fw = o.summary["machining_time_s"].as_f64().unwrap();
    assert!(
        (fw - host.machining_time_s).abs() < 0.2,
        "{fw} s against {}",
        host.machining_time_s
    );
}

/// Chatter suppression in the firmware (tape mode): the table 3.2 cut at 8.89 mm through the
/// block, `$276` = 1 mm: the loader re-plans every chatter hold at the same level, with the same
/// step, to the same end and as often as the host simulation of the same code, and the slot is
/// cut to its end (the firmware reports each re-plan in its result file).
#[test]
fn chatter_suppression_in_the_firmware_as_on_the_host() {
    let s = Settings::default();
    let (text, cut) = chatterlab::through_slot(0.1);
    let prog = analysis::load_program(&text, &s).unwrap();
    let listen = AcSettings {
        flutes: t::FLUTES,
        monitor_rpm: t::RPM as u32,
        chatter_step_mm: 1.0,
        ..AcSettings::default()
    };
    let acs = AcSettings {
        chatter_threshold: chatterlab::thesis_threshold(&prog, &s, &cut, listen).unwrap(),
        ..listen
    };
    let (text, cut) = chatterlab::through_slot(0.35);
    let prog = analysis::load_program(&text, &s).unwrap();
    let host = acsim::run_with_faults(&prog, &s, &cut, Some(acs), true, &[]).unwrap();
    let o = qemu_run("suppressed", &text, cut, acs);
    cost(&o, "8.89 mm suppressed");
    assert_eq!(o.summary["completed"], true, "{}", o.summary);
    let result = &o.capture.as_ref().unwrap().result;
    assert!(!result.contains("chatter: not re-planned"), "{result}");
    let fw: Vec<Replanned> = result
        .lines()
        .filter_map(|l| l.strip_prefix("chatter: re-planned "))
        .map(|l| parse_replanned(l).unwrap_or_else(|| panic!("{l}")))
        .collect();
    let host: Vec<Replanned> = host.replans.iter().map(|(_, r)| *r).collect();
    eprintln!("firmware re-plans: {fw:?}\nhost re-plans:     {host:?}");
    assert!(!host.is_empty());
    // The same re-plans: levels, steps, ends and count; the first stop within 2 BLU (the
    // firmware's AC task applies the hold a frame later or earlier than the host's period
    // boundary), the later ones within 0.05 in: the feeds then differ by a pulse here and there,
    // the chatter's growth past the threshold by a few records (51 BLU each at F6), measured up
    // to 450 BLU. The last, the shallowest level (4.9 mm), is nearest the stability limit: its
    // chatter grows so slowly that where it passes the threshold follows the feed's pulses
    // (3786 BLU in the firmware against 6996 on the host after the frame ISR's timing moved by
    // two instructions, issue 11): there only before the block's end.
    assert_eq!(fw.len(), host.len(), "{fw:?} {host:?}");
    for (k, (f, h)) in fw.iter().zip(&host).enumerate() {
        let tol = match k {
            0 => 2,
            k if k + 1 == host.len() => f.to[0] - f.at[0].min(h.at[0]) - 1,
            _ => 500,
        };
        let dx = (f.at[0] - h.at[0]).abs();
        assert!(dx <= tol && f.at[0] < f.to[0], "re-plan {k}: {f:?} {h:?}");
        assert_eq!(
            (f.at[1], f.at[2], f.to, f.lift, f.count),
            (h.at[1], h.at[2], h.to, h.lift, h.count)
        );
    }
}

/// The chatter reaction by spindle speed in the firmware (tape mode, `$277`): the table 3.2 tool
/// at 14 000 rpm, 4 mm (`chatterlab::high_speed_slot`): the firmware changes the simulated
/// spindle to the same lobes' speeds as the host simulation of the same code, re-plans nothing
/// and cuts the slot to its end.
#[test]
fn chatter_spindle_speed_in_the_firmware_as_on_the_host() {
    let s = Settings::default();
    let listen = AcSettings {
        flutes: t::FLUTES,
        monitor_rpm: 14_000,
        chatter_step_mm: 1.0,
        chatter_max_rpm: 30_000,
        ..AcSettings::default()
    };
    let (text, cut) = chatterlab::high_speed_slot(0.08, 14_000);
    let prog = analysis::load_program(&text, &s).unwrap();
    let acs = AcSettings {
        chatter_threshold: chatterlab::thesis_threshold(&prog, &s, &cut, listen).unwrap(),
        ..listen
    };
    let (text, cut) = chatterlab::high_speed_slot(0.157, 14_000);
    let prog = analysis::load_program(&text, &s).unwrap();
    let host = acsim::run_with_faults(&prog, &s, &cut, Some(acs), true, &[]).unwrap();
    let o = qemu_run("speed", &text, cut, acs);
    cost(&o, "4 mm at 14 000 rpm, spindle speed");
    assert_eq!(o.summary["completed"], true, "{}", o.summary);
    let result = &o.capture.as_ref().unwrap().result;
    assert!(
        !result.contains("chatter: re-planned") && !result.contains("not re-planned"),
        "{result}"
    );
    let fw: Vec<[u32; 4]> = result
        .lines()
        .filter_map(|l| l.strip_prefix("chatter: spindle "))
        .map(|l| parse_speed(l).unwrap_or_else(|| panic!("{l}")))
        .collect();
    let host: Vec<[u32; 4]> = host
        .speeds
        .iter()
        .map(|(_, c)| [c.from, c.to, c.chatter_hz, c.m])
        .collect();
    eprintln!(
        "firmware speeds (from, to, Hz, m): {fw:?}\nhost speeds:                       {host:?}"
    );
    assert!(!fw.is_empty());
    // The first change the same (the same record heard at the same speed); the firmware's
    // later holds may differ by a record where the chatter is marginal, so only the first is
    // compared exactly, and every change is the rule's.
    assert_eq!(fw[0], host[0]);
    for [from, to, hz, m] in &fw {
        assert!(from != to && *to <= 30_000);
        let tooth_hz = f64::from(*to) * f64::from(t::FLUTES) / 60.0;
        assert!(
            (tooth_hz * f64::from(*m) - f64::from(*hz)).abs() < 1.0,
            "{to} {hz} {m}"
        );
    }
}

/// A spindle change as the firmware writes it (`SpeedChange`'s `Display`): from, to, Hz, m.
fn parse_speed(l: &str) -> Option<[u32; 4]> {
    let w: Vec<&str> = l.split_whitespace().collect();
    match w[..] {
        [_count, speeds, "at", _at, hz, m, _line] => {
            let (from, to) = speeds.strip_prefix("S=")?.split_once("->")?;
            Some([
                from.parse().ok()?,
                to.parse().ok()?,
                hz.strip_prefix("chatter=")?.parse().ok()?,
                m.strip_prefix("m=")?.parse().ok()?,
            ])
        }
        _ => None,
    }
}

/// A re-plan as the firmware writes it (`Replanned`'s `Display`).
fn parse_replanned(l: &str) -> Option<Replanned> {
    let n = |v: &str| v.parse::<i32>().ok();
    let xyz = |v: &str| {
        let mut it = v.split(',').map(n);
        Some([it.next()??, it.next()??, it.next()??])
    };
    let w: Vec<&str> = l.split_whitespace().collect();
    match w[..] {
        [count, "at", at, "to", to, lift, line] => Some(Replanned {
            count: count.parse().ok()?,
            at: xyz(at)?,
            to: xyz(to)?,
            lift: lift.strip_prefix("lift=")?.parse().ok()?,
            line: line.strip_prefix("line=")?.parse().ok()?,
        }),
        _ => None,
    }
}
