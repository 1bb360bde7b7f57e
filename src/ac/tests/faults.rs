//! Host tests of the AC program's fault detectors (host tests): a real load step against a lone
//! spike (issue 6, D4), a frozen sensor while the axes feed (D6), and the force/torque plausibility
//! check that catches a gain fault (G).
use super::super::*;
use super::{codes, ctl, MID};

/// A live transducer's codes: `k` plus a small deterministic dither (+-2 codes, period 4), as noise.
fn live(k: [u16; 3], i: usize) -> [u16; 3] {
    let d = [0i32, 2, 0, -2][i % 4];
    k.map(|c| (c as i32 + d).clamp(0, 4095) as u16)
}

/// `n` live samples of `k` starting at dither phase `i0`.
fn feed_live(c: &mut AcController, k: [u16; 3], i0: usize, n: usize) {
    for i in i0..i0 + n {
        c.sample(live(k, i));
    }
}

/// The codes of a cut at force F (N; Fu = -0.9 F, so that Fu + 3000 codes stays on the scale) with
/// the torque F*R/ratio (R = 6.35 mm, the default tool).
fn cut_codes(f_n: f32, ratio: f32) -> [u16; 3] {
    let t = f_n * 0.00635 / ratio;
    codes(t, -0.9 * f_n, 0.435_89 * f_n)
}

// ---------------------------------------------------------------- D4: step against spike

/// The reproducer of issue 6 (D4): a full-depth entry at F30 steps Fu from about 2049 to 3978 in one
/// sample (F = 5052 N, T = 30.7 N*m: a physical load, F*R/T = 1.04) and the step persists. That is
/// an overload, not a sensor jump, wherever in the window the step lands.
#[test]
fn real_load_step_that_persists_is_an_overload_not_a_jump() {
    let s = AcSettings::default();
    let air = [MID, 2049, MID];
    // Fu 3978 (4825 N), Fv 1497 N: F = 5052 N; T 30.75 N*m.
    let load = [MID + 615, 3978, MID + 599];
    for at in 0..10 {
        let mut c = ctl(s);
        feed_live(&mut c, air, 0, 30);
        assert_eq!(c.period().state, AcState::Run);
        // `at` samples of air, then the step, which persists.
        feed_live(&mut c, air, 0, at);
        let mut first_hold = None;
        for p in 0..3 {
            let n = if p == 0 { 10 - at } else { 10 };
            feed_live(&mut c, load, 0, n);
            let out = c.period();
            if out.alarm.is_some() {
                first_hold = Some((p, out));
                break;
            }
        }
        let (p, out) = first_hold.expect("the overload holds");
        assert!(p <= 1, "within one period after the step (at {at}): {p}");
        let Some(Alarm::Overload { f_n, t_nm, e, .. }) = out.alarm else {
            panic!("step at sample {at}: expected an overload, got {out:?}");
        };
        assert!(f_n > 5000.0 && t_nm > 30.0 && e < s.overload_e, "{out:?}");
        assert_eq!(out.feed_cap, 0);
        assert!(format!("{}", out.alarm.unwrap()).starts_with("overload hold: F = "));
    }
}

/// A lone spike of +3000 codes on Fu that returns at the next sample is a sensor fault (the
/// `spike` fault of issue 6): `SensorFault::Jump`, and the spike sample never reaches the window.
#[test]
fn lone_spike_on_fu_is_a_jump_fault_kept_out_of_the_window() {
    let s = AcSettings::default();
    // In air and in a cut (F = 3000 N, T consistent), spike in the middle of a window.
    for base in [[MID, 1000, MID], cut_codes(3000.0, 0.9)] {
        let spike = [base[0], base[1] + 3000, base[2]];
        let mut c = ctl(s);
        let quiet = c.period(); // NoSamples hold, resume
        assert_eq!(quiet.alarm, Some(Alarm::NoSamples));
        c.resume();
        feed_live(&mut c, base, 0, 10);
        let before = c.period();
        assert_eq!(before.state, AcState::Run);
        feed_live(&mut c, base, 1, 4); // ends on phase 4: the undithered base
        c.sample(spike);
        c.sample(base);
        feed_live(&mut c, base, 2, 4);
        let out = c.period();
        let want = SensorFault::Jump {
            sensor: Sensor::ForceU,
            from: base[1],
            to: base[1] + 3000,
        };
        assert_eq!(out.alarm, Some(Alarm::Sensor(want)), "{base:?}");
        assert_eq!(out.feed_cap, 0);
        // The spike (F about 7500 N) stayed out: the window's peak is the base load.
        assert!(out.f_n < before.f_n + 20.0, "{out:?} vs {before:?}");
        assert_eq!(
            format!("{}", out.alarm.unwrap()),
            format!(
                "sensor hold: Fu jumped from code {} to {}",
                base[1],
                base[1] + 3000
            )
        );
    }
    // Fu alone cannot jump by 3000 codes in a cut: the torque contradicts it, so a spike as the
    // last sample of a window holds at the end of that very window.
    let base = [MID, 1000, MID];
    let mut c = ctl(s);
    feed_live(&mut c, base, 0, 9);
    c.sample([MID, 4000, MID]);
    let out = c.period();
    assert_eq!(
        out.alarm,
        Some(Alarm::Sensor(SensorFault::Jump {
            sensor: Sensor::ForceU,
            from: 1000,
            to: 4000
        }))
    );
    assert!(out.f_n < 2700.0, "{out:?}");
}

/// A spike of +3000 codes on Fu on a tool loaded near F0 with Fu positive (F*R/T 0.74, as the
/// Fig. 1 cavity at 7 s on the simulated cut) leaves the spiked sample's totals inside the band
/// (F*R/T about 1.2): the force rose with no torque, which no chip makes. A sensor fault, kept out
/// of the window; the alarm corpus (`millac_qemu::alarmlab`) held it as an overload before.
///
/// The same for the pocket's spike at 4.9 s: Fu at -3500 N, +3000 codes, reads +4000 N; F goes
/// from 3570 to 4090 N (over the overload level) and F*R/T stays 0.85, but the force vector
/// moved by 7500 N with no torque.
#[test]
fn a_force_spike_on_a_loaded_tool_is_a_jump_even_when_the_total_looks_like_a_cut() {
    for base in [codes(31.0, 3300.0, 1450.0), codes(30.6, -3500.0, 700.0)] {
        force_spike_on(base);
    }
}

fn force_spike_on(base: [u16; 3]) {
    let s = AcSettings::default();
    let spike = [base[0], (base[1] + 3000).min(4095), base[2]];
    let value = |k: [u16; 3]| {
        let (fu, fv) = (s.cal[1].value(k[1]), s.cal[2].value(k[2]));
        (ecr::force(fu, fv), s.cal[0].value(k[0]).abs())
    };
    // The premise: the spiked sample alone looks like a cut.
    let (f, t) = value(spike);
    assert_eq!(
        plaus::Band::new(&s).judge(f, t),
        Some(true),
        "{f} N {t} N*m"
    );
    let mut c = ctl(s);
    super::ease_in(&mut c, base);
    feed_live(&mut c, base, 0, 10);
    let before = c.period();
    assert_eq!(
        (before.state, before.alarm),
        (AcState::Run, None),
        "{before:?}"
    );
    feed_live(&mut c, base, 1, 4);
    c.sample(spike);
    c.sample(base);
    feed_live(&mut c, base, 2, 4);
    let out = c.period();
    assert_eq!(
        out.alarm,
        Some(Alarm::Sensor(SensorFault::Jump {
            sensor: Sensor::ForceU,
            from: base[1],
            to: spike[1],
        })),
        "{out:?}"
    );
    assert!(out.f_n < before.f_n + 20.0, "{out:?} vs {before:?}");
}

/// A jump that force and torque agree on (all channels together) is load at once, even when it
/// returns at the next sample (a one-sample pulse of a tooth meeting a wall is real).
#[test]
fn consistent_jump_is_load_even_for_one_sample() {
    let s = AcSettings::default();
    let base = cut_codes(800.0, 0.9);
    let high = cut_codes(5000.0, 0.9); // Fu jumps by 1512 codes, Fv by 732, T by 593
    assert!(base[1].abs_diff(high[1]) > s.jump_codes);
    let mut c = ctl(s);
    feed_live(&mut c, base, 0, 9);
    c.sample(high);
    let out = c.period();
    assert!(
        matches!(out.alarm, Some(Alarm::Overload { f_n, .. }) if f_n > 4900.0),
        "{out:?}"
    );
}

/// A jump too small for the force/torque judgement (here: the floor set above any load) is judged
/// by persistence: kept out of the window while it waits for the next sample; back at the next
/// sample it was a spike, still there it is load.
#[test]
fn unjudgeable_jump_that_returns_is_a_spike() {
    let s = AcSettings {
        ft_floor_nm: 1.0e7,
        ..AcSettings::default()
    };
    let base = cut_codes(800.0, 0.9);
    let high = cut_codes(5000.0, 0.9);
    let mut c = ctl(s);
    feed_live(&mut c, base, 0, 9); // ends on phase 8: the undithered base
    c.sample(high);
    let out = c.period();
    assert_eq!((out.state, out.alarm), (AcState::Run, None));
    assert!(out.f_n < 900.0, "the jumped sample is kept out: {out:?}");
    c.sample(base);
    feed_live(&mut c, base, 1, 9);
    let out = c.period();
    assert_eq!(
        out.alarm,
        Some(Alarm::Sensor(SensorFault::Jump {
            sensor: Sensor::ForceU,
            from: base[1],
            to: high[1]
        }))
    );
    // The same jump, persisting: load (here an overload, reported as such).
    let mut c = ctl(s);
    feed_live(&mut c, base, 0, 9);
    c.sample(high);
    assert_eq!(c.period().alarm, None);
    c.sample(high);
    let out = c.period();
    assert!(
        matches!(out.alarm, Some(Alarm::Overload { f_n, .. }) if f_n > 4900.0),
        "{out:?}"
    );
}

#[test]
fn plausibility_settings_validation() {
    let d = AcSettings::default();
    type Edit = fn(&mut AcSettings);
    let bad: [(Edit, AcSettingsError); 7] = [
        (|s| s.tool_radius_mm = 0.0, AcSettingsError::ToolRadius),
        (|s| s.tool_radius_mm = f32::NAN, AcSettingsError::ToolRadius),
        (|s| s.ft_ratio_min = 0.0, AcSettingsError::ForceTorqueBand),
        (|s| s.ft_ratio_max = 0.5, AcSettingsError::ForceTorqueBand),
        (
            |s| s.ft_ratio_max = f32::INFINITY,
            AcSettingsError::ForceTorqueBand,
        ),
        (|s| s.ft_floor_nm = 0.0, AcSettingsError::ForceTorqueFloor),
        (
            |s| s.ft_floor_nm = f32::NAN,
            AcSettingsError::ForceTorqueFloor,
        ),
    ];
    for (edit, e) in bad {
        let mut s = d;
        edit(&mut s);
        assert_eq!(s.validate(), Err(e));
        assert_eq!(s.validated().err(), Some(e));
        assert_eq!(format!("{e}"), e.message());
    }
}

// ---------------------------------------------------------------- D6: frozen sensor

/// Periods of the same codes `k` (`live` adds the dither) with the axes feeding at the cap.
fn feed_periods(c: &mut AcController, k: [u16; 3], live_noise: bool, periods: usize) -> AcOutput {
    let mut out = None;
    for p in 0..periods {
        for i in 0..10 {
            c.sample(if live_noise { live(k, p * 10 + i) } else { k });
        }
        let cap = c.feed_cap();
        c.set_achieved(cap);
        let o = c.period();
        if o.alarm.is_some() {
            return o;
        }
        out = Some(o);
    }
    out.expect("at least one period")
}

/// Issue 6, D6: a transducer frozen at mid-scale reads "no load" and the FRC opens the feed to
/// f_max. While the axes feed a live transducer always moves (noise, tooth pulsation), so a channel
/// that stays within `frozen_codes` for `frozen_samples` samples while feeding is a sensor fault.
#[test]
fn frozen_sensor_while_the_axes_feed_holds() {
    let s = AcSettings::default();
    let mut c = ctl(s);
    let out = feed_periods(&mut c, [MID; 3], false, 300);
    let want = SensorFault::Frozen {
        sensor: Sensor::Torque,
        code: MID,
        samples: s.frozen_samples,
    };
    assert_eq!(out.alarm, Some(Alarm::Sensor(want)), "{out:?}");
    assert_eq!(out.feed_cap, 0);
    assert_eq!(
        format!("{}", out.alarm.unwrap()),
        format!(
            "sensor hold: T frozen at code 2048 for {} samples",
            s.frozen_samples
        )
    );
    // One channel frozen among live ones (within +-1 code: still frozen).
    let mut c = ctl(s);
    let mut out = None;
    for p in 0..300 {
        for i in 0..10 {
            let mut k = live([MID + 100, 1500, MID + 300], p * 10 + i);
            k[1] = 1500 + (i % 2) as u16;
            c.sample(k);
        }
        c.set_achieved(1000);
        let o = c.period();
        if o.alarm.is_some() {
            out = Some((p, o));
            break;
        }
    }
    let (p, o) = out.expect("the frozen Fu holds");
    assert!(
        matches!(
            o.alarm,
            Some(Alarm::Sensor(SensorFault::Frozen {
                sensor: Sensor::ForceU,
                code: 1500,
                ..
            }))
        ),
        "{o:?}"
    );
    assert_eq!(
        p as u32 + 1,
        s.frozen_samples / 10,
        "detected in the period that completes the count"
    );
}

/// Quiet (noise-free) transducers on an idle machine are not a fault, nor are live ones while
/// feeding; without the achieved feed the check is off.
#[test]
fn frozen_check_needs_the_axes_to_feed() {
    let s = AcSettings::default();
    let mut c = ctl(s);
    for _ in 0..300 {
        for _ in 0..10 {
            c.sample([MID; 3]);
        }
        c.set_achieved(0);
        assert_eq!(c.period().alarm, None);
    }
    // Idle, then feeding: the count starts when the feed does.
    let out = feed_periods(&mut c, [MID; 3], false, s.frozen_samples as usize / 10 - 1);
    assert_eq!((out.state, out.alarm), (AcState::Run, None));
    let out = feed_periods(&mut c, [MID; 3], false, 1);
    assert!(matches!(
        out.alarm,
        Some(Alarm::Sensor(SensorFault::Frozen { .. }))
    ));
    // Live transducers while feeding: never.
    let mut c = ctl(s);
    let out = feed_periods(&mut c, [MID; 3], true, 300);
    assert_eq!((out.state, out.feed_cap), (AcState::Run, s.f_max));
    // No achieved feed given: the check is off (as the paper's loop, which knows no feed).
    let mut c = ctl(s);
    for _ in 0..300 {
        for _ in 0..10 {
            c.sample([MID; 3]);
        }
        assert_eq!(c.period().alarm, None);
    }
    // frozen_samples = 0 switches the check off.
    let mut c = ctl(AcSettings {
        frozen_samples: 0,
        ..s
    });
    assert_eq!(feed_periods(&mut c, [MID; 3], false, 300).alarm, None);
}

#[test]
fn frozen_settings_validation() {
    let d = AcSettings::default();
    type Edit = fn(&mut AcSettings);
    let bad: [(Edit, AcSettingsError); 3] = [
        (|s| s.frozen_codes = 1500, AcSettingsError::FrozenCodes),
        (|s| s.frozen_codes = 101, AcSettingsError::FrozenCodes),
        (
            |s| s.frozen_samples = 2_000_000,
            AcSettingsError::FrozenSamples,
        ),
    ];
    for (edit, e) in bad {
        let mut s = d;
        edit(&mut s);
        assert_eq!(s.validate(), Err(e));
        assert_eq!(format!("{e}"), e.message());
    }
}

// ---------------------------------------------------------------- G: gain fault

/// One period of a live cut at force F (N) with the torque for F*R/T = `ratio`; Fu, Fv scaled by
/// `gain` about mid-scale (a loose transducer reads `gain` x the true force).
fn cut_period(c: &mut AcController, f_n: f32, ratio: f32, gain: f32, p: usize) -> AcOutput {
    let k = cut_codes(f_n, ratio);
    let scale = |code: u16| (MID as f32 + gain * (code as f32 - MID as f32)).round() as u16;
    for i in 0..10 {
        let k = [k[0], scale(k[1]), scale(k[2])];
        c.sample(live(k, p * 10 + i));
    }
    c.set_achieved(c.feed_cap());
    c.period()
}

/// Issue 6, G: Fu and Fv read half the true force (a loose transducer). The force codes alone look
/// like a light cut, but the torque does not agree: F*R/T falls from the tool's band (0.74..1.04 in
/// the model) to about 0.45. Held after `ft_periods` periods, and the feed does not rise meanwhile.
#[test]
fn gain_fault_force_against_torque_holds() {
    let s = AcSettings::default();
    for (gain, t_scale) in [(0.5f32, 1.0f32), (1.0, 0.5)] {
        let mut c = ctl(s);
        // Honest cuts at the ends of the model's band, and in air (nothing to judge): no alarm.
        for p in 0..40 {
            let (f, ratio) = [(2000.0, 0.74), (3000.0, 1.04), (0.0, 1.0)][p % 3];
            let out = cut_period(&mut c, f, ratio, 1.0, p);
            assert_eq!(out.alarm, None, "honest cut, period {p}");
        }
        let before = c.feed_cap();
        let mut hold = None;
        for p in 0..20 {
            // The fault: F about 2400 N, ratio 0.9 in truth; the transducer halves one side.
            let out = cut_period(&mut c, 2400.0, 0.9 / t_scale, gain, p);
            if let Some(a) = out.alarm {
                hold = Some((p, a));
                break;
            }
            assert!(
                out.feed_cap <= before,
                "the feed does not rise while F and T disagree"
            );
        }
        let (p, a) = hold.expect("the gain fault holds");
        assert_eq!(p as u32 + 1, s.ft_periods, "held after ft_periods periods");
        let Alarm::ForceTorqueMismatch { ratio, .. } = a else {
            panic!("expected a force/torque mismatch, got {a:?}");
        };
        assert!(ratio < s.ft_ratio_min || ratio > s.ft_ratio_max, "{a:?}");
        let text = format!("{a}");
        assert!(
            text.starts_with("sensor hold: force and torque disagree: F*R/T = "),
            "{text}"
        );
        assert!(!a.message().contains(','), "ac.log field");
    }
}

#[test]
fn gain_check_settings_validation() {
    let s = AcSettings {
        ft_periods: 200_000,
        ..AcSettings::default()
    };
    assert_eq!(s.validate(), Err(AcSettingsError::ForceTorquePeriods));
    // 0 switches the periodic check off (the band still judges jumps).
    let mut c = ctl(AcSettings {
        ft_periods: 0,
        ..AcSettings::default()
    });
    for p in 0..50 {
        assert_eq!(cut_period(&mut c, 2400.0, 0.9, 0.5, p).alarm, None);
    }
}

/// After a gain-fault hold, a resume in air runs (nothing to judge: the feed opens), and the
/// next window out of the band holds again at once.
#[test]
fn gain_fault_after_resume_holds_at_the_next_window_out_of_the_band() {
    let s = AcSettings::default();
    let mut c = ctl(s);
    let mut p = 0;
    while cut_period(&mut c, 2400.0, 0.9, 0.5, p).alarm.is_none() {
        p += 1;
        assert!(p < 50, "the gain fault holds");
    }
    c.resume();
    for q in 0..5 {
        let out = cut_period(&mut c, 0.0, 1.0, 0.5, q);
        assert_eq!(out.alarm, None);
    }
    assert!(c.feed_cap() > s.f_min, "the feed opens in air");
    let out = cut_period(&mut c, 2400.0, 0.9, 0.5, 0);
    assert!(
        matches!(out.alarm, Some(Alarm::ForceTorqueMismatch { .. })),
        "{out:?}"
    );
}

/// The `rail` fault in a heavy cut: T goes to 4095 from less than `jump_codes` below it, so it is
/// no jump by size, and T = 102 N*m alone would read as an overload. Arriving at a rail is judged
/// like a jump: the force (3600 N, F*R/T = 0.22) does not confirm it, so it is a sensor fault.
/// A force that does confirm it (a real load beyond the transducer's range) is an overload.
#[test]
fn torque_arriving_at_the_rail_unconfirmed_is_a_sensor_fault() {
    let s = AcSettings::default();
    let base = cut_codes(3600.0, 0.45); // T = 50.8 N*m: code 3064, 1031 below the rail
    let mut c = ctl(s);
    for p in 0..3 {
        let _ = cut_period(&mut c, 3600.0, 0.45, 1.0, p); // out of band, below ft_periods
    }
    c.resume();
    feed_live(&mut c, base, 0, 9);
    c.sample([4095, base[1], base[2]]);
    feed_live(&mut c, [4095, base[1], base[2]], 0, 10);
    let out = c.period();
    assert!(
        matches!(
            out.alarm,
            Some(Alarm::Sensor(SensorFault::Jump {
                sensor: Sensor::Torque,
                to: 4095,
                ..
            }))
        ),
        "{out:?}"
    );
    // Confirmed by the force: an overload. (Fu at its lower rail, the way the cut's Fu points:
    // a Fu that flips from -2700 N to the upper rail would move the force vector by 7800 N with
    // T up 14 N*m, which no chip does.)
    let high = cut_codes(5000.0, 0.9);
    let mut c = ctl(s);
    feed_live(&mut c, cut_codes(3000.0, 0.9), 0, 10);
    c.period();
    c.sample([high[0], 0, high[2]]);
    c.sample([high[0], 0, high[2]]);
    let out = c.period();
    assert!(matches!(out.alarm, Some(Alarm::Overload { .. })), "{out:?}");
}

/// The `rail` fault while the tool feeds down in air (the Fig. 1 cavity at 1.5 s, Z going into the
/// start hole): T jumps from 0.3 to 102 N*m at its rail with no force. While plunging the band's
/// lower end is not judged (an end face makes torque without force), but a code at its rail is a
/// bound, not a value, and no end face reaches the torque's full scale within a sample: a sensor
/// fault, not load. With the plunge rule alone it entered the window and held as an overload
/// (hold_latency's rail row said "overload").
#[test]
fn torque_at_the_rail_while_plunging_in_air_is_a_sensor_fault() {
    let s = AcSettings::default();
    let air = codes(0.3, 10.0, -5.0);
    let mut c = ctl(s);
    feed_live(&mut c, air, 0, 10);
    c.set_z_down(true);
    assert_eq!(c.period().alarm, None);
    c.set_z_down(true);
    feed_live(&mut c, air, 1, 4);
    for _ in 0..6 {
        c.sample([4095, air[1], air[2]]);
    }
    let out = c.period();
    assert!(
        matches!(
            out.alarm,
            Some(Alarm::Sensor(SensorFault::Jump {
                sensor: Sensor::Torque,
                to: 4095,
                ..
            }))
        ),
        "{out:?}"
    );
}

/// A fault present from the very first sample (the injected `rail@0`, `spike@0`): judged as a
/// jump from the channels' zero-load codes, as the same fault later in the run is, so the hold is
/// the sensor alarm (`$X` to leave) and not an overload (which `~` resumes). Before, the first
/// sample had no jump reference: its rail or spike entered the window and read as an overload.
#[test]
fn a_fault_from_the_first_sample_is_a_sensor_fault_not_an_overload() {
    let s = AcSettings::default();
    let cases: [(&str, [u16; 3], Sensor); 3] = [
        ("T at the upper rail", [4095, MID, MID], Sensor::Torque),
        ("Fu at the lower rail", [MID, 0, MID], Sensor::ForceU),
        ("Fu spike", [MID, 4000, MID], Sensor::ForceU),
    ];
    for (what, first, sensor) in cases {
        let mut c = ctl(s);
        c.sample(first);
        feed_live(&mut c, [MID; 3], 0, 9);
        let out = c.period();
        assert!(
            matches!(out.alarm, Some(Alarm::Sensor(SensorFault::Jump { sensor: got, .. })) if got == sensor),
            "{what}: {out:?}"
        );
    }
    // A rail that stays from the first sample: the same jump fault at once (not, 1.5 s later, the
    // stuck alarm after an overload).
    let mut c = ctl(s);
    feed_live(&mut c, [4095, MID, MID], 0, 10);
    let out = c.period();
    assert!(
        matches!(out.alarm, Some(Alarm::Sensor(_))),
        "rail from the start: {out:?}"
    );
    // A machine that starts in a real cut (force and torque agree) is load, not a fault.
    let mut c = ctl(s);
    feed_live(&mut c, cut_codes(3000.0, 0.9), 0, 10);
    assert_eq!(c.period().alarm, None);
}

/// A plunge: the end face makes torque with almost no net radial force (F*R/T about 0.05). With
/// the Z axis feeding down the band's lower end is not judged: neither the step into the plunge
/// (a jump F does not follow) nor the windows after it are a sensor fault. Without the Z motion
/// the same codes are a gain fault (the check still catches a force that reads low in a side
/// cut), and in a plunge a force that reads double (F*R/T 2.0, above what any cut makes) is
/// still caught. Before, a plunge held as `ALARM:106` (or a torque jump, alarm 102).
#[test]
fn a_plunge_is_no_gain_fault_but_a_double_force_still_is() {
    let s = AcSettings::default();
    let plunge = cut_codes(300.0, 0.05); // T = 38 N*m, F = 300 N
    let run = |z_down: bool, k: [u16; 3]| {
        let mut c = ctl(s);
        feed_live(&mut c, [MID; 3], 0, 10);
        c.set_z_down(z_down);
        c.period();
        let mut first = None;
        for p in 0..20 {
            c.set_z_down(z_down);
            feed_live(&mut c, k, p * 10, 10);
            let out = c.period();
            if first.is_none() {
                first = out.alarm;
            }
        }
        first
    };
    assert_eq!(run(true, plunge), None, "a plunge held");
    assert!(
        matches!(
            run(false, plunge),
            Some(Alarm::ForceTorqueMismatch { .. } | Alarm::Sensor(SensorFault::Jump { .. }))
        ),
        "the same codes without the Z motion"
    );
    let double = cut_codes(2000.0, 2.0);
    assert!(
        matches!(
            run(true, double),
            Some(Alarm::ForceTorqueMismatch { .. } | Alarm::Sensor(SensorFault::Jump { .. }))
        ),
        "a double force in a plunge"
    );
}
