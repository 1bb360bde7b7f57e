//! Host tests of the G-code parser: one test per error class, each checking the error kind and
//! that the parser state is unchanged afterwards.
extern crate std;

use super::super::*;
use super::{assert_rejected, block, motion, parser};
use crate::nc::Motion;

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
fn err_unexpected_character() {
    assert_rejected(&mut busy(), "G1 X1 $", ErrorKind::UnexpectedCharacter('$'));
    assert_rejected(&mut busy(), "X1 )", ErrorKind::UnexpectedCharacter(')'));
    assert_rejected(&mut busy(), "X1 % 2", ErrorKind::UnexpectedCharacter('%'));
    assert_rejected(&mut busy(), "X1 é", ErrorKind::UnexpectedCharacter('é'));
}

#[test]
fn err_unclosed_comment() {
    assert_rejected(&mut busy(), "G1 X1 (oops", ErrorKind::UnclosedComment);
}

#[test]
fn err_unsupported_letter() {
    assert_rejected(&mut busy(), "X1 A5", ErrorKind::UnsupportedLetter('A'));
    assert_rejected(&mut busy(), "e1", ErrorKind::UnsupportedLetter('E'));
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
    assert_rejected(&mut busy(), "G33 Z-1 K1", g("33"));
    assert_rejected(&mut busy(), "G95", g("95"));
    assert_rejected(&mut busy(), "G43.2", g("43.2"));
    // Tapping and back boring are not among the canned cycles.
    assert_rejected(&mut busy(), "G84 X1 Z-1 R1", g("84"));
    assert_rejected(&mut busy(), "G87 X1 Z-1 R1", g("87"));
}

#[test]
fn err_unsupported_m() {
    assert_rejected(
        &mut busy(),
        "M60",
        ErrorKind::UnsupportedM(Decimal::int(60)),
    );
    assert_rejected(
        &mut busy(),
        "M62 P1",
        ErrorKind::UnsupportedM(Decimal::int(62)),
    );
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
            second: 10,
        },
    );
    assert_rejected(
        &mut busy(),
        "G2 G3 X1 I1",
        ErrorKind::ModalConflict {
            letter: 'G',
            first: 20,
            second: 30,
        },
    );
    assert_rejected(
        &mut busy(),
        "G1 G01 X1",
        ErrorKind::ModalConflict {
            letter: 'G',
            first: 10,
            second: 10,
        },
    );
    assert_rejected(
        &mut busy(),
        "G20 G21",
        ErrorKind::ModalConflict {
            letter: 'G',
            first: 200,
            second: 210,
        },
    );
    assert_rejected(
        &mut busy(),
        "M3 M5",
        ErrorKind::ModalConflict {
            letter: 'M',
            first: 30,
            second: 50,
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
    assert_rejected(
        &mut busy(),
        "G0 X1 M2",
        ErrorKind::StopWithMotion { code: 20 },
    );
    assert_rejected(
        &mut busy(),
        "G4 P1 M30",
        ErrorKind::StopWithMotion { code: 300 },
    );
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

/// A line longer than the linear DDA's registers hold (q > 2^31: r_k + |d_k| would pass 2^32 and
/// the line end short) is refused; the longest one that fits is accepted (see `Q_MAX`).
#[test]
fn err_line_beyond_the_dda_registers() {
    let q_max = crate::nc::Q_MAX as i64;
    let mut p = Parser::new(wide());
    block(&mut p, "G1 F1 X-214748.3648");
    assert_eq!(p.position()[0] as i64, -(1 << 31));
    // To X = 0: exactly Q_MAX BLU, accepted.
    match motion(&mut p, "X0") {
        Motion::Linear(l) => assert_eq!(l.q as i64, q_max),
        m => panic!("{m:?}"),
    }
    // One BLU further: Q_MAX + 1, refused; every longer line too.
    for bad in ["X0.0001", "X214748.3647", "X214748 Y1"] {
        let mut p = Parser::new(wide());
        block(&mut p, "G1 F1 X-214748.3648");
        assert_rejected(&mut p, bad, ErrorKind::MoveTooLong);
    }
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
fn err_arc_too_large() {
    let mut p = Parser::new(wide());
    block(&mut p, "X-214748.3647 F1");
    assert_rejected(
        &mut p,
        "G3 X214748.3647 I214748.3647",
        ErrorKind::ArcTooLarge,
    );
}
