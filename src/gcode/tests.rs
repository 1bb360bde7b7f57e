//! Host tests of the G-code parser: words, modes, units, feed, blocks, every error class, the
//! look-ahead rule.
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
    let mut reference = before;
    for follow in ["X0.05 Y0.025", "G91 G1 X0.01 F1", "Y-0.02"] {
        assert_eq!(
            p.line(43, follow),
            reference.line(43, follow),
            "{bad:?} then {follow:?}"
        );
    }
}

/// A parser in a non-power-up state: mm, incremental, feed set, G1, moved.
fn busy() -> Parser {
    let mut p = parser();
    block(&mut p, "G21 G91 G1 F100 X1 Y2 S500 M3");
    p
}

fn wide() -> Settings {
    Settings {
        soft_min: [i32::MIN; 3],
        soft_max: [i32::MAX; 3],
        ..Settings::default()
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
    let l = linear(&mut p, "G91 Z0.0001");
    assert_eq!((l.steps, l.signs, l.q), ([0, 0, 1], 0b100, 1));
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
    let m = p.modes();
    assert_eq!(
        (m.units, m.distance, m.plane),
        (Units::Mm, Distance::Incremental, Plane::ZX)
    );
    assert_eq!(p.line(1, "G17 M4 M9 S0.5"), Ok(Parsed::Nothing));
    assert_eq!(p.spindle_rpm(), 1);
    assert_eq!(p.modes().plane, Plane::XY);
    assert_eq!(p.line(1, "G19 M5 G20 G90"), Ok(Parsed::Nothing));
    assert_eq!(
        (p.modes().plane, p.modes().units, p.modes().distance),
        (Plane::YZ, Units::Inch, Distance::Absolute)
    );
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

// ---- every error class: kind + unchanged state ----

#[test]
fn err_unexpected_character() {
    assert_rejected(&mut busy(), "G1 X1 #", ErrorKind::UnexpectedCharacter('#'));
    assert_rejected(&mut busy(), "X1 )", ErrorKind::UnexpectedCharacter(')'));
    assert_rejected(&mut busy(), "X#1", ErrorKind::UnexpectedCharacter('#'));
    assert_rejected(&mut busy(), "X1 é", ErrorKind::UnexpectedCharacter('é'));
}

#[test]
fn err_unclosed_comment() {
    assert_rejected(&mut busy(), "G1 X1 (oops", ErrorKind::UnclosedComment);
}

#[test]
fn err_unsupported_letter() {
    assert_rejected(&mut busy(), "X1 A5", ErrorKind::UnsupportedLetter('A'));
    assert_rejected(&mut busy(), "t1", ErrorKind::UnsupportedLetter('T'));
}

#[test]
fn err_missing_number() {
    assert_rejected(&mut busy(), "G1 X Y1", ErrorKind::MissingNumber('X'));
    assert_rejected(&mut busy(), "Y1 X", ErrorKind::MissingNumber('X'));
    assert_rejected(&mut busy(), "G", ErrorKind::MissingNumber('G'));
}

#[test]
fn err_malformed_number() {
    for bad in ["X1.2.3", "X-", "X.", "X+-1", "X1-2", "X--1", "Y1 X+."] {
        assert_rejected(&mut busy(), bad, ErrorKind::MalformedNumber('X'));
    }
}

#[test]
fn err_number_too_large() {
    assert_rejected(&mut busy(), "G20 X300000", ErrorKind::NumberTooLarge('X'));
    assert_rejected(
        &mut busy(),
        "X123456789012345678901",
        ErrorKind::NumberTooLarge('X'),
    );
    assert_rejected(
        &mut busy(),
        "G2 X1 I-99999999",
        ErrorKind::NumberTooLarge('I'),
    );
    assert_rejected(&mut busy(), "S4294967296", ErrorKind::NumberTooLarge('S'));
    assert_rejected(&mut busy(), "G4 P1000000", ErrorKind::NumberTooLarge('P'));
    assert_rejected(
        &mut busy(),
        "F99999999999999999999.999999999999999999",
        ErrorKind::NumberTooLarge('F'),
    );
}

#[test]
fn err_too_many_decimals() {
    assert_rejected(
        &mut busy(),
        "X0.0000000000000000001",
        ErrorKind::TooManyDecimals('X'),
    );
    // Trailing zeros do not count.
    let mut p = busy();
    assert!(p.line(1, "X0.100000000000000000000000").is_ok());
}

#[test]
fn err_unsupported_g() {
    let g = |s: &str| ErrorKind::UnsupportedG(number::parse_decimal(s).unwrap());
    assert_rejected(&mut busy(), "G5 X1", g("5"));
    assert_rejected(&mut busy(), "G1.5", g("1.5"));
    assert_rejected(&mut busy(), "G-1", g("-1"));
    assert_rejected(&mut busy(), "G300", g("300"));
    assert_rejected(&mut busy(), "G28", g("28"));
}

#[test]
fn err_unsupported_m() {
    assert_rejected(&mut busy(), "M6", ErrorKind::UnsupportedM(Decimal::int(6)));
}

#[test]
fn err_repeated_word() {
    assert_rejected(&mut busy(), "X1 X2", ErrorKind::RepeatedWord('X'));
    assert_rejected(&mut busy(), "F1 y1 f2", ErrorKind::RepeatedWord('F'));
    assert_rejected(&mut busy(), "N1 N2", ErrorKind::RepeatedWord('N'));
}

#[test]
fn err_modal_conflict() {
    assert_rejected(
        &mut busy(),
        "G0 G1 X1",
        ErrorKind::ModalConflict {
            letter: 'G',
            first: 0,
            second: 1,
        },
    );
    assert_rejected(
        &mut busy(),
        "G2 G3 X1 I1",
        ErrorKind::ModalConflict {
            letter: 'G',
            first: 2,
            second: 3,
        },
    );
    assert_rejected(
        &mut busy(),
        "G1 G01 X1",
        ErrorKind::ModalConflict {
            letter: 'G',
            first: 1,
            second: 1,
        },
    );
    assert_rejected(
        &mut busy(),
        "G20 G21",
        ErrorKind::ModalConflict {
            letter: 'G',
            first: 20,
            second: 21,
        },
    );
    assert_rejected(
        &mut busy(),
        "M3 M5",
        ErrorKind::ModalConflict {
            letter: 'M',
            first: 3,
            second: 5,
        },
    );
}

#[test]
fn err_negative_value() {
    assert_rejected(&mut busy(), "F-1", ErrorKind::NegativeValue('F'));
    assert_rejected(&mut busy(), "S-1", ErrorKind::NegativeValue('S'));
    assert_rejected(&mut busy(), "G4 P-0.1", ErrorKind::NegativeValue('P'));
}

#[test]
fn err_no_feed() {
    assert_rejected(&mut parser(), "G1 X1", ErrorKind::NoFeed { code: 1 });
    assert_rejected(&mut parser(), "G1", ErrorKind::NoFeed { code: 1 });
    assert_rejected(&mut parser(), "G2 X1 I1", ErrorKind::NoFeed { code: 2 });
    assert_rejected(&mut busy(), "X1 F0", ErrorKind::NoFeed { code: 1 });
    let mut p = busy();
    assert_eq!(p.line(1, "G0 F0"), Ok(Parsed::Nothing));
    assert_rejected(&mut p, "G3 X1 I1", ErrorKind::NoFeed { code: 3 });
}

#[test]
fn err_dwell_needs_p() {
    assert_rejected(&mut busy(), "G4", ErrorKind::DwellNeedsP);
}

#[test]
fn err_dwell_with_axes() {
    assert_rejected(&mut busy(), "G4 P1 X1", ErrorKind::DwellWithAxes);
}

#[test]
fn err_unused_word() {
    assert_rejected(&mut busy(), "X1 I1", ErrorKind::UnusedWord('I'));
    assert_rejected(&mut busy(), "G0 X1 R1", ErrorKind::UnusedWord('R'));
    assert_rejected(&mut busy(), "P1", ErrorKind::UnusedWord('P'));
    assert_rejected(&mut busy(), "J1", ErrorKind::UnusedWord('J'));
    assert_rejected(&mut busy(), "G17 G2 X1 I1 K1", ErrorKind::UnusedWord('K'));
    assert_rejected(&mut busy(), "G18 G2 X1 I1 J1", ErrorKind::UnusedWord('J'));
    assert_rejected(&mut busy(), "G19 G2 Y1 J1 I1", ErrorKind::UnusedWord('I'));
    assert_rejected(&mut busy(), "G4 P1 I1", ErrorKind::UnusedWord('I'));
    assert_rejected(&mut busy(), "M2 P1", ErrorKind::UnusedWord('P'));
}

#[test]
fn err_end_with_motion() {
    assert_rejected(&mut busy(), "G0 X1 M2", ErrorKind::EndWithMotion);
    assert_rejected(&mut busy(), "G4 P1 M30", ErrorKind::EndWithMotion);
}

#[test]
fn err_target_overflow() {
    let mut p = Parser::new(wide());
    block(&mut p, "X214748.3647");
    assert_eq!(p.position()[0], i32::MAX);
    assert_rejected(
        &mut p,
        "G91 X0.0001",
        ErrorKind::TargetOverflow { axis: 'X' },
    );
}

#[test]
fn err_move_too_long() {
    let mut p = Parser::new(wide());
    block(&mut p, "X-214748 Y-214748 Z-214748 F1");
    assert_rejected(&mut p, "G1 X214748 Y214748 Z214748", ErrorKind::MoveTooLong);
    // A rapid of the same size is fine (no q).
    assert!(matches!(
        motion(&mut p, "G0 X214748 Y214748 Z214748"),
        Motion::Rapid(_)
    ));
}

#[test]
fn err_soft_limit() {
    let sl = |axis, value, min, max| ErrorKind::SoftLimit {
        axis,
        value,
        min,
        max,
    };
    assert_rejected(
        &mut busy(),
        "G20 G90 G0 X10.0001",
        sl('X', 100_001, -100_000, 100_000),
    );
    assert_rejected(
        &mut busy(),
        "G20 G90 G1 Y-10.0001",
        sl('Y', -100_001, -100_000, 100_000),
    );
    assert_rejected(
        &mut busy(),
        "G20 G90 Z-4.0001",
        sl('Z', -40_001, -40_000, 40_000),
    );
    let mut p = parser();
    assert!(p.line(1, "G0 X10 Y-10 Z4").is_ok());
}

#[test]
fn err_arc_needs_centre() {
    assert_rejected(
        &mut busy(),
        "G2 X1 Y1",
        ErrorKind::ArcNeedsCentre { code: 2 },
    );
    assert_rejected(&mut busy(), "G3", ErrorKind::ArcNeedsCentre { code: 3 });
}

#[test]
fn err_arc_radius_and_offsets() {
    assert_rejected(&mut busy(), "G2 X1 I1 R1", ErrorKind::ArcRadiusAndOffsets);
}

#[test]
fn err_helical() {
    assert_rejected(&mut busy(), "G2 X1 Z1 I0.5", ErrorKind::HelicalArc);
    assert_rejected(&mut busy(), "G18 G2 X1 Y1 I0.5", ErrorKind::HelicalArc);
    let mut p = parser();
    assert!(
        p.line(1, "G17 G2 F1 X1 Y0 Z0 I0.5").is_ok(),
        "Z word without Z motion is planar"
    );
}

#[test]
fn err_arc_full_circle_radius() {
    assert_rejected(&mut busy(), "G2 X0 R1", ErrorKind::ArcFullCircleRadius);
}

#[test]
fn err_arc_zero_radius() {
    assert_rejected(&mut busy(), "G2 X0 I0", ErrorKind::ArcZeroRadius);
    assert_rejected(&mut busy(), "G2 X1 R0", ErrorKind::ArcZeroRadius);
    assert_rejected(&mut busy(), "G2 X0 I0.0001", ErrorKind::ArcZeroRadius); // 0.0001 mm = 0 BLU
}

#[test]
fn err_arc_radius_too_small() {
    // Half chord 5000 BLU, R 4000 BLU.
    assert_rejected(
        &mut parser(),
        "G2 F1 X1 R0.4",
        ErrorKind::ArcRadiusTooSmall {
            radius: 4000,
            half_chord: 5000,
        },
    );
    // Within tolerance (2 BLU): a half circle.
    let mut p = parser();
    assert!(p.line(1, "G2 F1 X1 R0.4999").is_ok());
}

#[test]
fn err_arc_end_not_on_circle() {
    assert_rejected(
        &mut parser(),
        "G2 F1 X1 I0.6",
        ErrorKind::ArcEndNotOnCircle {
            start: 6000,
            end: 4000,
        },
    );
    // 0.001 r tolerance for large radii, at most 0.5 mm.
    let mut p = parser();
    assert!(p.line(1, "G2 F1 X0.0005 Y0 I5").is_ok()); // start 50000, end 49995: 5 <= 50
    assert_rejected(
        &mut parser(),
        "G2 F1 X0.0051 Y0 I5",
        ErrorKind::ArcEndNotOnCircle {
            start: 50_000,
            end: 49_949,
        },
    );
}

#[test]
fn err_arc_end_unreachable() {
    // Centre (-1000, 0), start (1000, 0) relative; end (-1, 1001) relative lies past the +b
    // crossing (0, 1000) but outside the circle: b would have to rise again after the crossing.
    assert_rejected(
        &mut parser(),
        "G3 F1 X-0.1001 Y0.1001 I-0.1",
        ErrorKind::ArcEndUnreachable {
            start: 1000,
            end: 1001,
        },
    );
}

#[test]
fn err_arc_too_large() {
    let mut p = Parser::new(wide());
    block(&mut p, "X-214748.3647 F1");
    assert_rejected(
        &mut p,
        "G3 X214748.3647 I214748.3647",
        ErrorKind::ArcTooLarge,
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
