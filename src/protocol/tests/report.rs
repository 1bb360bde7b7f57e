//! Host tests of the reports: status report with `$10` / `$13` variants, WCO cadence, the `AC:`
//! field, fixed-point rounding, alarm and message formatting, the alarm numbers of AC holds.

extern crate std;
use super::super::report::*;
use super::super::*;
use super::util::Rig;
use crate::ac::{Alarm, Sensor, SensorFault};
use std::string::String;

fn data() -> StatusData {
    StatusData {
        state: State::Idle,
        position: [12345, -1, 0],
        feed_blu_per_min: 0,
        spindle_rpm: 0,
        blocks_free: 15,
        tool: 0,
        ac: None,
        frame_cycles: None,
        wco_pm: [0; 3],
        pins: 0,
    }
}

/// grbl's `Pn:` field: the probe and the limit switches active now, in grbl's order (P, X, Y,
/// Z), after `FS:`; none active, no field.
#[test]
fn the_pins_field_names_the_active_inputs() {
    let mut r = Rig::new();
    let d = StatusData {
        pins: 0b1101,
        ..data()
    };
    assert_eq!(
        status(&mut r, &d),
        "<Idle|MPos:31.356,-0.003,0.000|FS:0,0|Pn:PXZ|WCO:0.000,0.000,0.000|Ov:100,100,100>\r\n"
    );
    let d = StatusData {
        pins: 0b0010,
        ..data()
    };
    assert!(status(&mut r, &d).contains("|FS:0,0|Pn:Y|Ov:"));
}

fn status(r: &mut Rig, d: &StatusData) -> String {
    let opts = r.table.report_options();
    r.p.status_report(d, opts, Blu::TenthMil, &mut r.out);
    r.take()
}

#[test]
fn status_report_mm_inch_wpos_buffer_and_wco() {
    let mut r = Rig::new();
    let d = data();
    // 12345 BLU = 31.3563 mm; -1 BLU = -2.54 um -> -0.003 mm.
    assert_eq!(
        status(&mut r, &d),
        "<Idle|MPos:31.356,-0.003,0.000|FS:0,0|WCO:0.000,0.000,0.000|Ov:100,100,100>\r\n"
    );
    assert_eq!(
        status(&mut r, &d),
        "<Idle|MPos:31.356,-0.003,0.000|FS:0,0|Ov:100,100,100>\r\n"
    );
    r.table.inches = true;
    assert_eq!(
        status(&mut r, &d),
        "<Idle|MPos:1.2345,-0.0001,0.0000|FS:0.0,0|Ov:100,100,100>\r\n"
    );
    // $10=2: WPos (equal to MPos: no work offsets) and the buffer field; bytes waiting in the
    // ring reduce the free count.
    r.table.mask = 2;
    r.table.inches = false;
    r.push(b"G0 X");
    assert_eq!(
        status(&mut r, &d),
        "<Idle|WPos:31.356,-0.003,0.000|Bf:15,124|FS:0,0|Ov:100,100,100>\r\n"
    );
    // WCO again after 30 reports while idle, and in the first report after a reset.
    let wco = (0..29)
        .filter(|_| status(&mut r, &d).contains("WCO:"))
        .count();
    assert_eq!(wco, 1);
    r.push(&[rx::byte::RESET]);
    r.run();
    r.take();
    assert!(status(&mut r, &d).contains("|WCO:0.000,0.000,0.000|"));
    // A work offset (G55 at X 1 in, Z -2.5 mm): WPos is MPos minus it, and a changed offset is
    // reported at once (then not again until the cadence).
    let d = StatusData {
        wco_pm: [25_400_000_000, 0, -2_500_000_000],
        ..data()
    };
    assert_eq!(
        status(&mut r, &d),
        "<Idle|WPos:5.956,-0.003,2.500|Bf:15,128|FS:0,0|WCO:25.400,0.000,-2.500|Ov:100,100,100>\r\n"
    );
    assert!(!status(&mut r, &d).contains("WCO:"));
    r.table.inches = true;
    assert!(status(&mut r, &d).starts_with("<Idle|WPos:0.2345,-0.0001,0.0984|"));
}

#[test]
fn states_feed_overrides_and_the_ac_field() {
    let mut r = Rig::new();
    status(&mut r, &data());
    // 30 ipm = feed number 3000 = 300000 BLU/min = 762 mm/min = 30.0 in/min.
    let feed = feed_blu_per_min(&r.machine, 3000);
    assert_eq!(feed, 300_000);
    let mut d = StatusData {
        state: State::Run,
        feed_blu_per_min: feed,
        spindle_rpm: 600,
        ac: Some(AcReport {
            feed_share_pct: 87,
            f_ratio_milli: 968,
            t_ratio_milli: 412,
            state: AcState::Run,
        }),
        ..data()
    };
    r.push(&[0x91, 0x96, 0x9B]);
    r.run();
    assert_eq!(
        status(&mut r, &d),
        "<Run|MPos:31.356,-0.003,0.000|FS:762,600|Ov:110,50,90|AC:87,0.968,0.412,run>\r\n"
    );
    d.state = State::Hold { complete: true };
    d.ac = Some(AcReport {
        feed_share_pct: 0,
        f_ratio_milli: 1234,
        t_ratio_milli: 5,
        state: AcState::Hold(codes::alarm::AC_OVERLOAD),
    });
    r.table.inches = true;
    assert_eq!(
        status(&mut r, &d),
        "<Hold:0|MPos:1.2345,-0.0001,0.0000|FS:30.0,600|Ov:110,50,90|AC:0,1.234,0.005,hold:100>\r\n"
    );
    for (s, name) in [
        (State::Hold { complete: false }, "<Hold:1|"),
        (State::Jog, "<Jog|"),
        (State::Alarm, "<Alarm|"),
        (State::Check, "<Check|"),
    ] {
        d.state = s;
        assert!(status(&mut r, &d).starts_with(name), "{name}");
    }
    // The alarm lock and check mode override the caller's state.
    d.state = State::Idle;
    r.p.alarm(1, &mut r.out);
    r.take();
    assert!(status(&mut r, &d).starts_with("<Alarm|"));
}

#[test]
fn fixed_point_rounding() {
    let s = |f: &dyn Fn(&mut String) -> core::fmt::Result| {
        let mut o = String::new();
        f(&mut o).unwrap();
        o
    };
    // Half away from zero: 25 BLU = 63.5 um.
    assert_eq!(s(&|o| write_length(o, 25, Blu::TenthMil, false)), "0.064");
    assert_eq!(s(&|o| write_length(o, -25, Blu::TenthMil, false)), "-0.064");
    assert_eq!(s(&|o| write_length(o, -1, Blu::Micron, false)), "-0.001");
    // 127 um = 0.005 in exactly; 1 um rounds to zero, printed without a sign.
    assert_eq!(s(&|o| write_length(o, 127, Blu::Micron, true)), "0.0050");
    assert_eq!(s(&|o| write_length(o, -1, Blu::Micron, true)), "0.0000");
    assert_eq!(
        s(&|o| write_length(o, i32::MIN, Blu::TenthMil, false)),
        "-5454608.466"
    );
    // 1500 BLU/min = 0.15 in/min -> 0.2; 0.381 mm/min -> 0.
    assert_eq!(s(&|o| write_rate(o, 1500, Blu::TenthMil, true)), "0.2");
    assert_eq!(s(&|o| write_rate(o, 1500, Blu::TenthMil, false)), "4");
    assert_eq!(s(&|o| write_fixed(o, -5, 3)), "-0.005");
    assert_eq!(s(&|o| write_fixed(o, 1000, 3)), "1.000");
    assert_eq!(s(&|o| write_fixed(o, 7, 0)), "7");
}

#[test]
fn ac_helpers_alarms_and_messages() {
    assert_eq!(AcReport::feed_share(870, 1000), 87);
    assert_eq!(AcReport::feed_share(5000, 1000), 100);
    assert_eq!(AcReport::feed_share(0, 1000), 0);
    assert_eq!(AcReport::feed_share(10, 0), 100);
    assert_eq!(AcReport::ratio_milli(3480.0, 3600.0), 967);
    assert_eq!(AcReport::ratio_milli(f32::NAN, 3600.0), 0);
    assert_eq!(AcReport::ratio_milli(1.0, 0.0), 0);
    assert_eq!(AcReport::ratio_milli(1e9, 1.0), u16::MAX);
    let sensor = |f| codes::ac_alarm(&Alarm::Sensor(f));
    assert_eq!(
        sensor(SensorFault::Stuck {
            sensor: Sensor::Torque,
            code: 4095
        }),
        101
    );
    assert_eq!(codes::ac_alarm(&Alarm::NoSamples), 105);
    let mut r = Rig::new();
    r.p.alarm(codes::ac_alarm(&Alarm::NoSamples), &mut r.out);
    r.p.message(&mut r.out, format_args!("{}", Alarm::NoSamples));
    r.p.message(&mut r.out, format_args!("a]b\r\nc"));
    assert_eq!(
        r.take(),
        "ALARM:105\r\n[MSG:sensor hold: no fresh samples in an AC period]\r\n[MSG:a)b  c]\r\n"
    );
}

#[test]
fn the_frame_cycles_field_appears_only_when_measured() {
    let mut r = Rig::new();
    status(&mut r, &data());
    assert!(!status(&mut r, &data()).contains("FC:"));
    let d = StatusData {
        frame_cycles: Some((96, 1234)),
        ..data()
    };
    assert_eq!(
        status(&mut r, &d),
        "<Idle|MPos:31.356,-0.003,0.000|FS:0,0|Ov:100,100,100|FC:96,1234>\r\n"
    );
    // After the AC field, the last one.
    let d = StatusData {
        ac: Some(AcReport {
            feed_share_pct: 100,
            f_ratio_milli: 500,
            t_ratio_milli: 250,
            state: AcState::Run,
        }),
        ..d
    };
    assert!(status(&mut r, &d).ends_with("|AC:100,0.500,0.250,run|FC:96,1234>\r\n"));
    // The tool in the spindle, once fitted, before the AC field.
    let d = StatusData { tool: 12, ..d };
    assert!(
        status(&mut r, &d).ends_with("|Ov:100,100,100|T:12|AC:100,0.500,0.250,run|FC:96,1234>\r\n")
    );
}

#[test]
fn status_frame_cycles_are_none_until_both_are_written() {
    use crate::rt::Status;
    // The wrapper may write either word first: a report between the two stores shows nothing.
    for min_first in [true, false] {
        let s = Status::new();
        let w = s.split().cycles;
        assert_eq!(s.frame_cycles(), None);
        if min_first {
            w.set_min(96);
        } else {
            w.set_max(1234);
        }
        assert_eq!(s.frame_cycles(), None, "{min_first}");
        if min_first {
            w.set_max(1234);
        } else {
            w.set_min(96);
        }
        assert_eq!(s.frame_cycles(), Some((96, 1234)));
    }
}
