//! Host tests of line handling: line ends, empty lines, over-long and non-UTF-8 lines, grbl
//! error numbers from the real parser, exactly one answer per line, alarm lock, check mode.

extern crate std;
use super::super::rx::byte;
use super::super::*;
use super::util::{Ev, Rig};
use std::string::String;
use std::vec::Vec;

fn gcode(events: &[Ev]) -> Vec<String> {
    events
        .iter()
        .filter_map(|e| match e {
            Ev::Gcode(l, _) => Some(l.clone()),
            _ => None,
        })
        .collect()
}

/// CR, LF and CRLF each end one line (one answer), also byte by byte with polls in between;
/// LF CR is two line ends; an empty line gets `ok`.
#[test]
fn line_ends() {
    for sep in [&b"\r"[..], b"\n", b"\r\n"] {
        let bytes = [&b"G21"[..], sep, b"G0 X1", sep, b"", sep].concat();
        let mut r = Rig::new();
        assert_eq!(gcode(&r.feed(&bytes)), ["G21", "G0 X1"], "{sep:?}");
        assert_eq!(r.responses(), ["ok", "ok", "ok"], "{sep:?}");
        let mut r = Rig::new();
        let mut ev = Vec::new();
        for b in &bytes {
            ev.extend(r.feed(&[*b]));
        }
        assert_eq!(gcode(&ev), ["G21", "G0 X1"], "{sep:?} byte by byte");
        assert_eq!(r.responses().len(), 3, "{sep:?} byte by byte");
    }
    let mut r = Rig::new();
    r.feed(b"M5\n\rM5\n  \t \n");
    assert_eq!(r.responses(), ["ok", "ok", "ok", "ok"]);
}

/// A line of LINE_MAX bytes is handed over; one more byte is `error:11`, the rest of that line is
/// discarded up to its line end, and the next line is read normally. Never a panic.
#[test]
fn long_lines() {
    let mut r = Rig::new();
    let mut max = std::vec![b' '; LINE_MAX - 2];
    max.extend_from_slice(b"M5");
    max.push(b'\n');
    let ev = r.feed(&max);
    assert_eq!(gcode(&ev).len(), 1);
    assert_eq!(gcode(&ev)[0].len(), LINE_MAX);
    assert_eq!(r.responses(), ["ok"]);
    let mut long = std::vec![b'X'; LINE_MAX + 1];
    long.extend_from_slice(b"\r\nM5\n");
    assert_eq!(gcode(&r.feed(&long)), ["M5"]);
    assert_eq!(r.responses(), ["error:11", "ok"]);
    // A runaway line many times the limit: one error, at its end.
    let mut runaway = std::vec![b'Y'; 5 * LINE_MAX];
    runaway.extend_from_slice(b"\nG0 X1\n");
    assert_eq!(gcode(&r.feed(&runaway)), ["G0 X1"]);
    assert_eq!(r.responses(), ["error:11", "ok"]);
}

/// Bytes that are not UTF-8 make the line `error:1`, not a panic; a realtime byte inside a UTF-8
/// sequence is taken out (as grbl) and breaks the sequence.
#[test]
fn non_utf8_lines() {
    let mut r = Rig::new();
    r.feed(b"G0 X\xff1\n(caf\xc3\xa9)\n(\xc3\x84)\nG0 X\xe9\n");
    assert_eq!(r.responses(), ["error:1", "ok", "error:1", "error:1"]);
    // 0xC3 0x84 ("Ä"): 0x84 is the safety door byte.
    let mut r = Rig::new();
    let ev = r.feed("(Ä)\n".as_bytes());
    assert_eq!(ev[0], Ev::Realtime(Pending(Pending::DOOR)));
}

/// Refused words answer grbl's error numbers (the table in `codes`), through the real parser.
#[test]
fn bad_words_give_grbl_numbers() {
    let cases: &[(&str, &str)] = &[
        ("G0 X1 Q1", "error:36"),
        ("G0 X1 A1", "error:20"),
        ("#1=2", "error:20"),
        ("O100 sub", "error:20"),
        ("G41 D1", "error:20"),
        ("G1 X1 M0 F10", "error:20"),
        ("G10 L2.5 P1 X1", "error:23"),
        ("G92 G0 X1", "error:24"),
        ("G92", "error:26"),
        ("G10 L2 X1", "error:28"),
        ("G93 G1 X1", "error:28"),
        ("G10 L2 P7 X1", "error:29"),
        ("G53 G2 X1 I1", "error:30"),
        ("G80 X1", "error:31"),
        ("G28.1 X1", "error:31"),
        ("G43.1 X1", "error:37"),
        ("T17", "error:38"),
        ("G43 H99", "error:38"),
        ("G1 X1", "error:22"),
        ("G0 G1 X1", "error:21"),
        ("G0 X1 X2", "error:25"),
        ("G4", "error:28"),
        ("G1 X1 F-1", "error:4"),
        ("G0 X1.2.3", "error:2"),
        ("G0 X", "error:2"),
        ("G2 X1 Y1 F10", "error:35"),
        ("G0 X100", "error:15"),
        ("G0 X1 I1", "error:36"),
        ("G38.2 Z-1", "error:22"),
        ("G38.1 Z-1 F10", "error:20"),
        ("G0 X1 %", "error:1"),
        ("G2 X1 Y0 R0.1 F10", "error:34"),
        ("G2 X0.5 Y0 I0.1 J0 F10", "error:33"),
        ("G0 X0.1 Y0.1", "ok"),
    ];
    for &(line, want) in cases {
        let mut r = Rig::new();
        r.feed(std::format!("{line}\n").as_bytes());
        assert_eq!(r.responses(), [want], "{line}");
    }
}

/// The caller's reply is written once; a second reply writes nothing; no further line is handed
/// out before the reply, but realtime requests are.
#[test]
fn exactly_one_answer_per_line() {
    let mut r = Rig::new();
    r.push(b"G0 X1\nG0 X2\n?");
    let mut cx = Context {
        table: &mut r.table,
        modes: r.parser.modes(),
        offsets: Default::default(),
        machine: &r.machine,
        state: State::Idle,
        frame_cycles: None,
        interlock: None,
    };
    let mut out = String::new();
    assert_eq!(
        r.p.poll(&mut out, &mut cx),
        Event::Realtime(Pending(Pending::STATUS))
    );
    assert!(matches!(
        r.p.poll(&mut out, &mut cx),
        Event::Gcode {
            line: "G0 X1",
            check: false
        }
    ));
    assert_eq!(r.p.poll(&mut out, &mut cx), Event::None);
    r.isr.push_byte(b'!');
    assert_eq!(
        r.p.poll(&mut out, &mut cx),
        Event::Realtime(Pending(Pending::HOLD))
    );
    assert!(r.p.reply(Err(GrblError(33)), &mut out));
    assert!(!r.p.reply(Ok(()), &mut out));
    assert_eq!(out, "error:33\r\n");
    assert!(matches!(
        r.p.poll(&mut out, &mut cx),
        Event::Gcode { line: "G0 X2", .. }
    ));
}

/// An alarm locks G-code (`error:9`) until `$X`; `$` commands still work; a soft reset keeps
/// the lock and says how to unlock.
#[test]
fn alarm_lock() {
    let mut r = Rig::new();
    r.p.alarm(codes::alarm::AC_OVERLOAD, &mut r.out);
    assert_eq!(r.take(), "ALARM:100\r\n");
    r.feed(b"G0 X1\n$G\n");
    let resp = r.responses();
    assert_eq!(resp, ["error:9", "ok"]);
    r.push(&[byte::RESET]);
    assert_eq!(r.run(), [Ev::Reset]);
    assert!(r.take().ends_with("[MSG:'$H'|'$X' to unlock]\r\n"));
    assert_eq!(r.p.alarm_code(), Some(100));
    let ev = r.feed(b"$X\nG0 X1\n$X\n");
    assert_eq!(ev[0], Ev::Unlock);
    assert_eq!(gcode(&ev), ["G0 X1"]);
    assert_eq!(r.take(), "[MSG:Caution: Unlocked]\r\nok\r\nok\r\nok\r\n");
    // Jogging locks G-code too.
    r.state = State::Jog;
    r.feed(b"G0 X0\n");
    assert_eq!(r.responses(), ["error:9"]);
}

/// A settings record refused at start-up: the first banner and every banner of a soft reset until
/// `$X` are followed by `ALARM:120` and why, G-code is locked (`error:9`), the state is Alarm;
/// `$X` unlocks and the reason is not told again.
#[test]
fn a_refused_settings_record_locks_until_unlocked() {
    use crate::protocol::table::record::RecordError;
    let mut r = Rig::new();
    r.p.settings_refused(RecordError::Checksum);
    r.p.start(&mut r.out);
    let told = std::format!(
        "ALARM:{}\r\n[MSG:settings record checksum mismatch; defaults loaded]\r\n\
         [MSG:'$H'|'$X' to unlock]\r\n",
        codes::alarm::SETTINGS_DEFAULTS
    );
    let first = r.take();
    assert!(first.starts_with("\r\nGrbl 1.1h"), "{first}");
    assert!(first.ends_with(&told), "{first}");
    assert_eq!(r.p.alarm_code(), Some(120));
    assert_eq!(r.p.state(State::Idle), State::Alarm);
    assert!(gcode(&r.feed(b"G0 X1\n")).is_empty());
    assert_eq!(r.responses(), ["error:9"]);
    r.push(&[byte::RESET]);
    assert_eq!(r.run(), [Ev::Reset]);
    assert!(r.take().ends_with(&told));
    let ev = r.feed(b"$X\nG0 X1\n");
    assert_eq!(ev[0], Ev::Unlock);
    assert_eq!(gcode(&ev), ["G0 X1"]);
    assert_eq!(r.p.state(State::Idle), State::Idle);
    r.take();
    r.push(&[byte::RESET]);
    assert_eq!(r.run(), [Ev::Reset]);
    let after = r.take();
    assert!(after.ends_with("adaptive control]\r\n"), "{after}");
}

/// `$C` check mode: lines come with `check`, the state reads Check; `$C` again disables it with
/// a soft reset (grbl: `[MSG:Disabled]`, `ok`, banner).
#[test]
fn check_mode() {
    let mut r = Rig::new();
    let ev = r.feed(b"$C\nG0 X1\n");
    assert_eq!(ev[0], Ev::CheckMode(true));
    assert_eq!(ev[1], Ev::Gcode("G0 X1".into(), true));
    assert_eq!(r.take(), "[MSG:Enabled]\r\nok\r\nok\r\n");
    assert_eq!(r.p.state(State::Idle), State::Check);
    // Not idle in check mode: `$#` is refused as in grbl, `$J=` too.
    r.feed(b"$#\n$J=X1F10\n");
    assert_eq!(r.responses(), ["error:8", "error:8"]);
    let ev = r.feed(b"$C\n");
    assert_eq!(ev, [Ev::Reset]);
    let out = r.take();
    assert!(
        out.starts_with("[MSG:Disabled]\r\nok\r\n\r\nGrbl 1.1h"),
        "{out}"
    );
    assert!(!r.p.check_mode());
    // Enabling needs Idle.
    r.state = State::Run;
    r.feed(b"$C\n");
    assert_eq!(r.responses(), ["error:8"]);
}
