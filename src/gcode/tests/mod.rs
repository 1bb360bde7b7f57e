//! Host tests of the G-code parser: words, modes, units, feed, blocks, the look-ahead rule.
//! look-ahead rule.

mod arc;
mod cycles;
mod dialect;
mod err;
mod incr;
mod prop;
extern crate std;
use std::format;
use std::string::ToString;

use super::*;
use crate::nc::{Motion, Plane};

pub(super) fn parser() -> Parser {
    Parser::new(Settings::default())
}

pub(super) fn block(p: &mut Parser, s: &str) -> Block {
    match p.line(3, s) {
        Ok(Parsed::Block(b)) => b,
        other => panic!("{s:?} gave {other:?}"),
    }
}

pub(super) fn motion(p: &mut Parser, s: &str) -> Motion {
    block(p, s).motion
}

fn linear(p: &mut Parser, s: &str) -> crate::nc::Linear {
    match motion(p, s) {
        Motion::Linear(l) => l,
        m => panic!("{s:?} gave {m:?}"),
    }
}

fn rapid(p: &mut Parser, s: &str) -> crate::nc::Rapid {
    match motion(p, s) {
        Motion::Rapid(r) => r,
        m => panic!("{s:?} gave {m:?}"),
    }
}

/// Asserts that `bad` fails with `kind` and changes nothing: position and modes are the same and
/// follow-up lines give the same results as on a parser that never saw `bad`.
pub(super) fn assert_rejected(p: &mut Parser, bad: &str, kind: ErrorKind) {
    let before = p.clone();
    let e = p.line(42, bad).expect_err(bad);
    assert_eq!(e.kind, kind, "{bad:?}: {e}");
    assert_eq!(e.line, 42);
    assert!(e.to_string().starts_with("line 42: "));
    assert_eq!(p.position(), before.position(), "{bad:?} moved");
    assert_eq!(p.modes(), before.modes(), "{bad:?} changed modes");
    assert_eq!(p.offsets(), before.offsets(), "{bad:?} changed offsets");
    assert_eq!(p.tools(), before.tools(), "{bad:?} changed the tool table");
    assert_eq!(
        p.loaded_tool(),
        before.loaded_tool(),
        "{bad:?} changed the tool"
    );
    let mut reference = before;
    for follow in ["X0.05 Y0.025", "G91 G1 X0.01 F1", "Y-0.02"] {
        assert_eq!(
            p.line(43, follow),
            reference.line(43, follow),
            "{bad:?} then {follow:?}"
        );
    }
}

#[test]
fn power_up_modes() {
    let p = parser();
    assert_eq!(p.modes(), Modes::POWER_UP);
    assert_eq!(p.modes().units, Units::Inch);
    assert_eq!(p.modes().motion, MotionMode::Rapid);
    assert_eq!(p.position(), [0, 0, 0]);
}

#[test]
fn axis_words_alone_use_power_up_rapid() {
    let mut p = parser();
    let r = rapid(&mut p, "X1 Y-0.5 Z0.25");
    assert_eq!(r.steps, [10_000, 5_000, 2_500]);
    assert_eq!(r.signs, 0b101);
    assert_eq!(p.position(), [10_000, -5_000, 2_500]);
}

#[test]
fn inch_conversion_is_exact() {
    let mut p = parser();
    block(&mut p, "G20 X1.2345");
    assert_eq!(p.position()[0], 12_345);
    block(&mut p, "X-0.00005"); // -0.5 BLU rounds away from zero
    assert_eq!(p.position()[0], -1);
    block(&mut p, "X0.00004999");
    assert_eq!(p.position()[0], 0);
}

#[test]
fn mm_conversion_is_exact() {
    let mut p = parser();
    block(&mut p, "G21 X25.4");
    assert_eq!(p.position()[0], 10_000);
    block(&mut p, "X1"); // 393.70...
    assert_eq!(p.position()[0], 394);
    block(&mut p, "X-0.00127"); // exactly -0.5 BLU
    assert_eq!(p.position()[0], -1);
    block(&mut p, "X0.00127");
    assert_eq!(p.position()[0], 1);
    assert_eq!(
        p.line(4, "X0.00126"),
        Ok(Parsed::Block(Block {
            line: 4,
            motion: Motion::Rapid(crate::nc::Rapid {
                steps: [1, 0, 0],
                signs: 0
            }),
        }))
    );
}

#[test]
fn micron_blu() {
    let mut p = Parser::new(Settings {
        blu: crate::Blu::Micron,
        ..Settings::default()
    });
    block(&mut p, "G21 X1.0005");
    assert_eq!(p.position()[0], 1001); // 1000.5 rounds up
    block(&mut p, "G20 X0.5");
    assert_eq!(p.position()[0], 12_700);
}

#[test]
fn incremental_and_absolute() {
    let mut p = parser();
    block(&mut p, "G91 X1");
    block(&mut p, "X1");
    assert_eq!(p.position(), [20_000, 0, 0]);
    let r = rapid(&mut p, "G90 X0.5");
    assert_eq!(r.steps, [15_000, 0, 0]);
    assert_eq!(r.signs, 0);
    assert_eq!(p.position(), [5_000, 0, 0]);
}

#[test]
fn feed_numbers_at_defaults() {
    let st = Settings::default();
    let f =
        |s: &str| feed_number(&st, number::parse_decimal(s).unwrap(), st.blu.per_inch()).unwrap();
    assert_eq!(f("30"), 3000);
    assert_eq!(f("1"), 100);
    assert_eq!(f("0.01"), 1);
    assert_eq!(f("0.001"), 1); // rounds to 0, nonzero F -> 1
    assert_eq!(f("12.345"), 1235); // 1234.5 rounds away from zero
    assert_eq!(f("45"), 3000); // clamped to q0
    assert_eq!(f("0"), 0);
    let mm =
        |s: &str| feed_number(&st, number::parse_decimal(s).unwrap(), st.blu.per_mm()).unwrap();
    assert_eq!(mm("254"), 1000);
    assert_eq!(mm("762"), 3000);
}

#[test]
fn feed_word_sets_f_of_linear_blocks() {
    let mut p = parser();
    assert_eq!(linear(&mut p, "G1 X1 F30").f, 3000);
    assert_eq!(linear(&mut p, "X2 F0.01").f, 1);
    assert_eq!(linear(&mut p, "X3 F45").f, 3000);
    assert_eq!(linear(&mut p, "X4 F12").f, 1200);
    assert_eq!(linear(&mut p, "X5").f, 1200, "feed is modal");
    // Switching units keeps the physical feed.
    assert_eq!(linear(&mut p, "G21 X0").f, 1200);
    assert_eq!(linear(&mut p, "F254 X1").f, 1000);
}

#[test]
fn linear_block_fields() {
    let mut p = parser();
    let l = linear(&mut p, "G1 F10 X0.0003 Y-0.0004");
    assert_eq!(l.steps, [3, 4, 0]);
    assert_eq!(l.signs, 0b001);
    assert_eq!(l.q, 5);
    assert!(!l.decel);
    // X and Y do not move: their sign bits repeat the lines as they stand (X+, Y-).
    let l = linear(&mut p, "G91 Z0.0001");
    assert_eq!((l.steps, l.signs, l.q), ([0, 0, 1], 0b101, 1));
    assert_eq!(p.signs(), 0b101);
    let l = linear(&mut p, "X1 Y1 Z1");
    assert_eq!(l.q, 17_320); // isqrt(3e8)
}

#[test]
fn motion_is_modal_and_rapid_has_no_feed() {
    let mut p = parser();
    linear(&mut p, "G1 F10 X1");
    linear(&mut p, "Y1");
    rapid(&mut p, "G0 Y2");
    rapid(&mut p, "Y3");
    assert_eq!(p.modes().motion, MotionMode::Rapid);
}

#[test]
fn zero_length_moves_are_nothing() {
    let mut p = parser();
    block(&mut p, "X1");
    assert_eq!(p.line(1, "X1"), Ok(Parsed::Nothing));
    assert_eq!(p.line(2, "G1 F1 X1 Y0"), Ok(Parsed::Nothing));
    assert_eq!(p.line(3, "G91 X0"), Ok(Parsed::Nothing));
    assert_eq!(p.position(), [10_000, 0, 0]);
    assert_eq!(p.modes().motion, MotionMode::Linear);
}

#[test]
fn block_line_is_line_number() {
    let mut p = parser();
    assert_eq!(
        p.line(12, "X1")
            .map(|r| matches!(r, Parsed::Block(Block { line: 12, .. }))),
        Ok(true)
    );
    assert_eq!(
        p.line(99, "X2")
            .map(|r| matches!(r, Parsed::Block(Block { line: 99, .. }))),
        Ok(true)
    );
}

#[test]
fn comments_case_and_spaces() {
    let mut p = parser();
    let l = linear(&mut p, "  n10 g1 (move (not nested x9) f1 x 1 . 5 y2;Y7 (");
    assert_eq!(l.steps, [15_000, 20_000, 0]);
    assert_eq!(p.line(1, "(only a comment)"), Ok(Parsed::Nothing));
    assert_eq!(p.line(1, "; only a comment"), Ok(Parsed::Nothing));
    assert_eq!(p.line(1, ""), Ok(Parsed::Nothing));
    assert_eq!(p.line(1, "   \t\r"), Ok(Parsed::Nothing));
    let mut q = p.clone();
    assert_eq!(p.line(1, "G01X+2Y02.0"), q.line(1, "G1 X2 Y2"));
}

#[test]
fn long_lines() {
    let mut p = parser();
    let pad = "(".to_string() + &"c".repeat(300) + ")";
    let text = format!("G1 {pad} F10 {pad} X1 {pad}");
    assert!(text.len() > 900);
    assert_eq!(linear(&mut p, &text).steps, [10_000, 0, 0]);
    let text = format!("G0 X0.{}1", "0".repeat(3)) + &" ".repeat(300) + "Y1";
    assert_eq!(rapid(&mut p, &text).steps, [9_999, 10_000, 0]);
}

#[test]
fn modal_words_are_accepted() {
    let mut p = parser();
    assert_eq!(
        p.line(1, "G94 G21 G91 G18 M3 M8 S12000.4"),
        Ok(Parsed::Nothing)
    );
    assert_eq!(p.spindle_rpm(), 12_000);
    assert_eq!(p.modes().spindle, Spindle::Cw);
    let m = p.modes();
    assert_eq!(
        (m.units, m.distance, m.plane),
        (Units::Mm, Distance::Incremental, Plane::ZX)
    );
    assert_eq!(p.line(1, "G17 M4 M9 S0.5"), Ok(Parsed::Nothing));
    assert_eq!(p.spindle_rpm(), 1);
    assert_eq!(p.modes().spindle, Spindle::Ccw);
    assert_eq!(p.modes().plane, Plane::XY);
    assert_eq!(p.line(1, "G19 M5 G20 G90"), Ok(Parsed::Nothing));
    assert_eq!(p.modes().spindle, Spindle::Off);
    assert_eq!(
        (p.modes().plane, p.modes().units, p.modes().distance),
        (Plane::YZ, Units::Inch, Distance::Absolute)
    );
    // A line without an M word keeps the spindle; the program end stops it.
    assert_eq!(p.line(1, "M3"), Ok(Parsed::Nothing));
    assert_eq!(p.line(1, "S200"), Ok(Parsed::Nothing));
    assert_eq!(p.modes().spindle, Spindle::Cw);
    assert_eq!(p.line(1, "M2"), Ok(Parsed::End));
    p.end_program();
    assert_eq!(p.modes().spindle, Spindle::Off);
    assert_eq!(p.line(1, "G1 F5"), Ok(Parsed::Nothing));
    assert_eq!(p.modes().motion, MotionMode::Linear);
    assert_eq!(p.settings(), &Settings::default());
}

#[test]
fn program_end() {
    let mut p = parser();
    assert_eq!(p.line(1, "M2"), Ok(Parsed::End));
    assert_eq!(p.line(1, "m30"), Ok(Parsed::End));
    assert_eq!(p.line(1, "G21 M30"), Ok(Parsed::End));
    assert_eq!(p.modes().units, Units::Mm);
}

/// After M2/M30 the units, F and S stay as the program left them (a sender showing `$G`'s units
/// must not switch to inches after a program in mm), and motion, plane, distance and spindle
/// return to G1 G17 G90 M5 (grbl 1.1 and NIST RS274/NGC); in inches as in mm.
#[test]
fn program_end_keeps_units_feed_and_speed() {
    for (units_word, units) in [("G21", Units::Mm), ("G20", Units::Inch)] {
        let mut p = parser();
        let setup = format!("{units_word} G91 G18 G0 M3 S300 F7");
        assert_eq!(p.line(1, &setup), Ok(Parsed::Nothing));
        assert_eq!(p.line(2, "M30"), Ok(Parsed::End));
        p.end_program();
        let m = p.modes();
        assert_eq!(m.units, units, "{units_word}");
        assert_eq!(m.spindle_rpm, 300);
        let before = parser();
        assert_ne!(m.feed, before.modes().feed);
        assert_eq!(
            (m.motion, m.plane, m.distance, m.spindle),
            (
                MotionMode::Linear,
                Plane::XY,
                Distance::Absolute,
                Spindle::Off
            )
        );
        // A soft reset returns every mode to power-up.
        p.reset_modes();
        assert_eq!(p.modes(), Modes::POWER_UP);
    }
}

#[test]
fn dwell() {
    let mut p = parser();
    assert_eq!(
        motion(&mut p, "G4 P0.5"),
        Motion::Dwell(crate::nc::Dwell { frames: 2500 })
    );
    assert_eq!(
        motion(&mut p, "G4 P0.0001"),
        Motion::Dwell(crate::nc::Dwell { frames: 1 })
    );
    assert_eq!(
        motion(&mut p, "G4 P0.00011"),
        Motion::Dwell(crate::nc::Dwell { frames: 1 })
    );
    assert_eq!(p.line(1, "G4 P0"), Ok(Parsed::Nothing));
    assert_eq!(p.line(1, "G4 P0.00009"), Ok(Parsed::Nothing)); // 0.45 frames
    assert_eq!(p.position(), [0, 0, 0]);
    // G4 does not touch the motion mode.
    assert_eq!(p.modes().motion, MotionMode::Rapid);
}

#[test]
fn display_format() {
    let mut p = parser();
    let e = p.line(12, "G1 X1").unwrap_err();
    assert_eq!(
        e.to_string(),
        "line 12: G1 needs a feed rate (F) greater than zero"
    );
    let e = p.line(7, "G1.5").unwrap_err();
    assert_eq!(e.to_string(), "line 7: G1.5 is not supported");
    let e = p.line(7, "G0 X11").unwrap_err();
    assert_eq!(
        e.to_string(),
        "line 7: axis X would go to 110000 BLU, outside the soft limits -100000..=100000 BLU"
    );
    assert_eq!(e.kind.message(), "soft limit");
    let e = p.line(8, "G0 G1").unwrap_err();
    assert_eq!(
        e.to_string(),
        "line 8: two motion commands on one line (G0 and G1)"
    );
}

// ---- look-ahead ----

fn lin(line: u32, v: [i64; 3]) -> Block {
    let mut signs = 0;
    for (k, x) in v.iter().enumerate() {
        if *x > 0 {
            signs |= 1 << k;
        }
    }
    Block {
        line,
        motion: Motion::Linear(crate::nc::Linear {
            steps: v.map(|x| x.unsigned_abs() as u32),
            signs,
            q: 1,
            f: 1,
            decel: false,
            f_floor: 0,
            decel_below: 0,
            ramp: 0,
            dir: [1; 3],
        }),
    }
}

fn decel(b: &Block) -> bool {
    match b.motion {
        Motion::Linear(l) => l.decel,
        Motion::Arc(a) => a.decel,
        _ => panic!("not a feed block"),
    }
}

#[test]
fn lookahead_straight_and_corners() {
    let mut la = Lookahead::new();
    assert_eq!(la.push(lin(1, [1000, 0, 0])), None);
    let b = la.push(lin(2, [2000, 0, 0])).unwrap();
    assert_eq!(b.line, 1);
    assert!(!decel(&b), "collinear: no decel");
    let b = la.push(lin(3, [1000, 554, 0])).unwrap(); // 28.99 degrees
    assert!(!decel(&b));
    let b = la.push(lin(4, [1000, 1155, 0])).unwrap(); // 28.99 -> 49.1: 20 degrees
    assert!(!decel(&b));
    let b = la.push(lin(5, [0, 0, -5])).unwrap(); // 90 degrees
    assert!(decel(&b));
    let b = la.push(lin(6, [0, 0, 5])).unwrap(); // reversal
    assert!(decel(&b));
    let b = la.push(lin(7, [1000, 0, 0])).unwrap();
    assert!(decel(&b));
    let b = la.push(lin(8, [1000, 601, 0])).unwrap(); // 31.0 degrees
    assert!(decel(&b));
    let last = la.flush().unwrap();
    assert_eq!(last.line, 8);
    assert!(decel(&last), "flush decelerates a feed block");
    assert_eq!(la.flush(), None);
}

#[test]
fn lookahead_rapid_and_dwell_force_decel() {
    let mut p = parser();
    let mut la = Lookahead::new();
    la.push(block(&mut p, "G1 F10 X1"));
    let b = la.push(block(&mut p, "G0 X2")).unwrap();
    assert!(decel(&b));
    let r = la.push(block(&mut p, "G1 X3")).unwrap();
    assert!(matches!(r.motion, Motion::Rapid(_)));
    let b = la.push(block(&mut p, "G4 P1")).unwrap();
    assert!(decel(&b));
    let d = la.flush().unwrap();
    assert!(matches!(d.motion, Motion::Dwell(_)));
}

#[test]
fn lookahead_arc_tangents() {
    // Line along +X into a CCW arc starting at the bottom of its circle: tangent +X, smooth.
    let mut p = parser();
    let mut la = Lookahead::new();
    la.push(block(&mut p, "G1 F10 X1"));
    let b = la.push(block(&mut p, "G3 X2 Y1 J1")).unwrap();
    assert!(!decel(&b));
    // The arc ends at (2, 1) going +Y; a line along +Y is smooth, along -X is not.
    let b = la.push(block(&mut p, "G1 Y2")).unwrap();
    assert!(!decel(&b));
    let mut p = parser();
    let mut la = Lookahead::new();
    la.push(block(&mut p, "G1 F10 X1"));
    // CW from the bottom of the circle goes -X: reversal.
    let b = la.push(block(&mut p, "G2 X0 Y1 J1")).unwrap();
    assert!(decel(&b));
    // It ends at (0, 1), relative (-1, 0), going +Y: a line along -X is a 90 degree corner.
    let b = la.push(block(&mut p, "G1 X-1")).unwrap();
    assert!(decel(&b));
    let b = la.push(block(&mut p, "G1 X-2 Y0.5")).unwrap(); // 26.6 degrees
    assert!(!decel(&b));
}
