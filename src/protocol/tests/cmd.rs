//! Host tests of the `$` commands: help, the settings hook, `$G`, `$#`, `$I`, `$N`, `$H`, unknown
//! commands, state checks, and `$J=` jogging (parse, errors, plan without changing the parser).

extern crate std;
use super::super::*;
use super::util::{Ev, Rig};
use crate::gcode::number::parse_decimal;
use crate::gcode::{Distance, Units};
use std::string::String;

fn dec(s: &str) -> Decimal {
    parse_decimal(s).unwrap()
}

fn answer(r: &mut Rig, line: &str) -> String {
    r.feed(std::format!("{line}\n").as_bytes());
    r.take()
}

#[test]
fn help_settings_hook_and_unknown_commands() {
    let mut r = Rig::new();
    assert_eq!(
        answer(&mut r, "$"),
        "[HLP:$$ $# $G $I $N $x=val $T $Tn=words $J=line $C $X $H ~ ! ? ctrl-x]\r\nok\r\n"
    );
    assert_eq!(answer(&mut r, "$$"), "$10=1\r\n$13=0\r\nok\r\n");
    assert_eq!(answer(&mut r, "$10=3"), "ok\r\n");
    assert_eq!(answer(&mut r, " $ 1 3 = 1 (inch)"), "ok\r\n");
    assert_eq!(answer(&mut r, "$120=0.5"), "ok\r\n");
    assert_eq!(answer(&mut r, "$$"), "$10=3\r\n$13=1\r\n$120=0.5\r\nok\r\n");
    assert_eq!(r.table.other.get(&120), Some(&dec("0.5")));
    // The table's own refusals pass through; bad numbers are grbl's 2, bad statements 3.
    assert_eq!(answer(&mut r, "$99=1"), "error:3\r\n");
    assert_eq!(answer(&mut r, "$10=1.5"), "error:2\r\n");
    assert_eq!(answer(&mut r, "$10=abc"), "error:2\r\n");
    assert_eq!(answer(&mut r, "$10="), "error:2\r\n");
    assert_eq!(answer(&mut r, "$=1"), "error:3\r\n");
    assert_eq!(answer(&mut r, "$99999=1"), "error:3\r\n");
    // `$n` alone: the hook's default answers as grbl 1.1 does.
    assert_eq!(answer(&mut r, "$10"), "error:3\r\n");
    for bad in [
        "$Q", "$SLP", "$GG", "$I=name", "$N0=G20", "$RST=*", "$RST=", "$XX",
    ] {
        assert_eq!(answer(&mut r, bad), "error:3\r\n", "{bad}");
    }
    assert_eq!(answer(&mut r, "$N"), "$N0=\r\n$N1=\r\nok\r\n");
}

/// `$H`, `$HX`, `$HY`, `$HZ` (any case, spaces) hand the homing cycle to the loader with the
/// axes' mask; it answers (the rig at once). Other `$H...` are `error:3`.
#[test]
fn homing_commands_go_to_the_loader_with_their_axes() {
    let mut r = Rig::new();
    for (cmd, mask) in [
        ("$H", 0b111),
        ("$HX", 0b001),
        ("$hy", 0b010),
        ("$H Z", 0b100),
    ] {
        assert_eq!(
            r.feed(std::format!("{cmd}\n").as_bytes()),
            [Ev::Home(mask)],
            "{cmd}"
        );
        assert_eq!(r.take(), "ok\r\n");
    }
    for bad in ["$HXY", "$HA", "$H=1"] {
        assert_eq!(answer(&mut r, bad), "error:3\r\n", "{bad}");
    }
    // In Alarm too (that is how a machine locked at power-up is homed).
    r.p.alarm(11, &mut r.out);
    r.take();
    assert_eq!(r.feed(b"$H\n"), [Ev::Home(0b111)]);
    r.take();
    // While it homes the state is Home (grbl's), not the lock's Alarm, and `$X` waits for it.
    r.state = State::Home;
    assert_eq!(r.p.state(r.state), State::Home);
    assert_eq!(answer(&mut r, "$X"), "error:8\r\n");
    // A reset's banner says the homing lock again.
    r.state = State::Idle;
    r.feed(&[0x18]);
    let banner = r.take();
    assert!(
        banner.ends_with("ALARM:11\r\n[MSG:'$H'|'$X' to unlock]\r\n"),
        "{banner}"
    );
}

#[test]
fn commands_that_need_idle() {
    let mut r = Rig::new();
    r.state = State::Run;
    for cmd in ["$$", "$#", "$I", "$N", "$H", "$10=0", "$C", "$J=X1F10"] {
        assert_eq!(answer(&mut r, cmd), "error:8\r\n", "{cmd}");
    }
    // Always allowed.
    assert!(answer(&mut r, "$G").ends_with("]\r\nok\r\n"));
    assert_eq!(answer(&mut r, "$X"), "ok\r\n");
    r.state = State::Hold { complete: true };
    assert_eq!(answer(&mut r, "$$"), "error:8\r\n");
    // Alarm allows the settings commands, but not jogs.
    r.state = State::Idle;
    r.p.alarm(3, &mut r.out);
    r.take();
    assert_eq!(answer(&mut r, "$10=2"), "ok\r\n");
    assert_eq!(answer(&mut r, "$J=G91X1F10"), "error:8\r\n");
    assert_eq!(answer(&mut r, "$$"), "$10=2\r\n$13=0\r\nok\r\n");
}

#[test]
fn parser_state_offsets_and_build_info() {
    let mut r = Rig::new();
    assert_eq!(
        answer(&mut r, "$G"),
        "[GC:G0 G54 G17 G20 G90 G94 G40 G49 G98 G61 M5 M9 T0 F0 S0]\r\nok\r\n"
    );
    // F100 mm/min is feed number 394 (3.94 ipm at 0.01 ipm), which runs at 39400 BLU/min:
    // 100.076 mm/min -> 100; in inches 3.94 -> 3.9.
    r.feed(b"G21 G91 G18 F100 S600\nG1 X1\n");
    assert_eq!(r.responses(), ["ok", "ok"]);
    assert_eq!(
        answer(&mut r, "$G"),
        "[GC:G1 G54 G18 G21 G91 G94 G40 G49 G98 G61 M5 M9 T0 F100 S600]\r\nok\r\n"
    );
    // The spindle word as the parser stands.
    r.feed(b"M4\n");
    assert_eq!(r.responses(), ["ok"]);
    assert!(answer(&mut r, "$G").contains(" M4 M9 "));
    r.feed(b"M3\n");
    assert_eq!(r.responses(), ["ok"]);
    assert!(answer(&mut r, "$G").contains(" M3 M9 "));
    r.feed(b"M5\n");
    assert_eq!(r.responses(), ["ok"]);
    r.table.inches = true;
    assert_eq!(
        answer(&mut r, "$g"),
        "[GC:G1 G54 G18 G21 G91 G94 G40 G49 G98 G61 M5 M9 T0 F3.9 S600]\r\nok\r\n"
    );
    assert_eq!(
        answer(&mut r, "$#"),
        "[G54:0.0000,0.0000,0.0000]\r\n[G55:0.0000,0.0000,0.0000]\r\n\
         [G56:0.0000,0.0000,0.0000]\r\n[G57:0.0000,0.0000,0.0000]\r\n\
         [G58:0.0000,0.0000,0.0000]\r\n[G59:0.0000,0.0000,0.0000]\r\n\
         [G28:0.0000,0.0000,0.0000]\r\n[G30:0.0000,0.0000,0.0000]\r\n\
         [G92:0.0000,0.0000,0.0000]\r\n[TLO:0.0000]\r\n[PRB:0.0000,0.0000,0.0000:0]\r\nok\r\n"
    );
    r.table.inches = false;
    assert!(answer(&mut r, "$#").starts_with("[G54:0.000,0.000,0.000]\r\n"));
    // The offsets as the parser holds them: G55 at (1 in, 2 mm, -3 mm), G28 where the machine
    // stood (0.5 in, in X), G92 X0 there (G54 in force), a tool 12.5 mm long by G43.1.
    r.feed(
        b"G20 G10 L2 P2 X1\nG21 G10 L2 P2 Y2 Z-3\nG20 G90 G0 X0.5\nG28.1\nG92 X0\nG21 G43.1 Z12.5\n",
    );
    assert_eq!(r.responses(), ["ok"; 6]);
    assert_eq!(
        answer(&mut r, "$#"),
        "[G54:0.000,0.000,0.000]\r\n[G55:25.400,2.000,-3.000]\r\n\
         [G56:0.000,0.000,0.000]\r\n[G57:0.000,0.000,0.000]\r\n\
         [G58:0.000,0.000,0.000]\r\n[G59:0.000,0.000,0.000]\r\n\
         [G28:12.700,0.000,0.000]\r\n[G30:0.000,0.000,0.000]\r\n\
         [G92:12.700,0.000,0.000]\r\n[TLO:12.500]\r\n[PRB:0.000,0.000,0.000:0]\r\nok\r\n"
    );
    assert_eq!(
        answer(&mut r, "$I"),
        "[VER:1.1h.millac:]\r\n[OPT:V,15,128]\r\nok\r\n"
    );
}

#[test]
fn build_info_has_the_frame_line_only_when_measured() {
    let mut r = Rig::new();
    let plain = "[VER:1.1h.millac:]\r\n[OPT:V,15,128]\r\nok\r\n";
    r.p.set_core_hz(180_000_000);
    assert_eq!(answer(&mut r, "$I"), plain);
    // 180 MHz at a 200 kHz rapid rate: 900 cycles per rapid period.
    r.machine.rapid_hz = 200_000;
    r.frame_cycles = Some((96, 412));
    assert_eq!(
        answer(&mut r, "$I"),
        "[VER:1.1h.millac:]\r\n[OPT:V,15,128]\r\n[FRAME:96,412,900]\r\nok\r\n"
    );
    // Without the core clock the budget is 0.
    let mut r = Rig::new();
    r.frame_cycles = Some((96, 412));
    assert!(answer(&mut r, "$I").contains("\r\n[FRAME:96,412,0]\r\nok\r\n"));
    r.frame_cycles = None;
    assert_eq!(answer(&mut r, "$I"), plain);
}

#[test]
fn banner_names_millac_and_its_version() {
    let mut r = Rig::new();
    r.p.start(&mut r.out);
    assert_eq!(
        r.take(),
        std::format!(
            "\r\nGrbl 1.1h ['$' for help]\r\n[MSG:millac {} NC + adaptive control]\r\n",
            env!("CARGO_PKG_VERSION")
        )
    );
}

/// A jog's absolute targets are work coordinates, as any line's (grbl); with G53 machine
/// coordinates; its F is per minute even when the program runs in inverse time (G93).
#[test]
fn jogs_go_to_work_or_machine_coordinates() {
    let mut r = Rig::new();
    for l in ["G20 G10 L2 P2 X1", "G55 G93"] {
        r.parser.line(1, l).unwrap();
    }
    let jog = |text: &str| JogRequest::parse(text).unwrap();
    assert_eq!(jog("X0 F10").plan(&r.parser).unwrap().end, [10_000, 0, 0]);
    assert_eq!(
        jog("G53 X0.5 F10").plan(&r.parser).unwrap().end,
        [5_000, 0, 0]
    );
    assert!(jog("G53 X0.5 F10").machine);
    assert_eq!(JogRequest::parse("G54 X0 F10"), Err(GrblError::INVALID_JOG));
}

#[test]
fn jog_is_parsed_planned_and_leaves_the_parser_alone() {
    let mut r = Rig::new();
    let ev = r.feed(b"$j = g91 x1 (right) f100\n");
    let want = JogRequest {
        target: [Some(dec("1")), None, None],
        feed: dec("100"),
        units: None,
        distance: Some(Distance::Incremental),
        machine: false,
    };
    assert_eq!(ev, [Ev::Jog(want)]);
    assert_eq!(r.responses(), ["ok"]);
    let mut g = String::new();
    want.write_gcode(&mut g).unwrap();
    assert_eq!(g, "G1 G91 X1 F100");
    let plan = want.plan(&r.parser).unwrap();
    assert_eq!(plan.end, [10_000, 0, 0]);
    assert!(plan.block.is_some());
    assert_eq!(r.parser.modes(), crate::gcode::Modes::POWER_UP);
    assert_eq!(r.parser.position(), [0, 0, 0]);
    // Units for this jog only: 25.4 mm = 1 in.
    let j = JogRequest::parse("G21G90Y-25.4Z0F500").unwrap();
    assert_eq!(j.units, Some(Units::Mm));
    assert_eq!(j.plan(&r.parser).unwrap().end, [0, -10_000, 0]);
    // Nothing moves: no block.
    assert_eq!(
        JogRequest::parse("X0F10")
            .unwrap()
            .plan(&r.parser)
            .unwrap()
            .block,
        None
    );
    // Beyond the soft limits: error 15 (no alarm, as grbl's jog).
    r.feed(b"$J=G90 X20 F10\n");
    assert_eq!(r.responses(), ["error:15"]);
}

#[test]
fn bad_jogs_get_grbl_errors() {
    let cases = [
        ("$J=G91 X1", "error:22"),
        ("$J=G91 X1 F0", "error:22"),
        ("$J=G91 X1 F-5", "error:4"),
        ("$J=G0 X1 F10", "error:16"),
        ("$J=G91 G2 X1 F10", "error:16"),
        ("$J=X1 F10 M3", "error:16"),
        ("$J=X1 F10 S100", "error:36"),
        ("$J=X1 F10 I1", "error:36"),
        ("$J=G91 F10", "error:26"),
        ("$J=X1 X2 F10", "error:25"),
        ("$J=X1 F1..0", "error:2"),
        ("$J=X1 F10 Q", "error:2"),
        ("$J=X1 F10 A1", "error:20"),
        ("$J X1 F10", "error:3"),
        ("$J=G20 G21 X1 F10", "error:21"),
        ("$J=N5 G91 X0.1 F10", "ok"),
    ];
    for (line, want) in cases {
        let mut r = Rig::new();
        r.feed(std::format!("{line}\n").as_bytes());
        assert_eq!(r.responses(), [want], "{line}");
    }
}

/// `$X` while the board says its e-stop is still active: refused before anything
/// else is said (no "Unlocked"), the alarm stays; once the interlock clears, `$X` unlocks.
#[test]
fn unlock_is_refused_while_the_interlock_is_active() {
    let mut r = Rig::new();
    r.p.alarm(10, &mut r.out);
    r.take();
    r.interlock = Some(10);
    assert_eq!(
        answer(&mut r, "$X"),
        "[MSG:E-stop still active]\r\nerror:9\r\n"
    );
    assert_eq!(r.p.alarm_code(), Some(10));
    r.interlock = None;
    assert_eq!(answer(&mut r, "$X"), "[MSG:Caution: Unlocked]\r\nok\r\n");
    assert_eq!(r.p.alarm_code(), None);
    // Without an alarm the interlock changes nothing.
    r.interlock = Some(10);
    assert_eq!(answer(&mut r, "$X"), "ok\r\n");
}
