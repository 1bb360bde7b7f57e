//! Host tests of G2/G3: quarter, half and full circles, quadrant crossings CW and CCW in all three
//! planes, R form, soft limits of the arc's extent. Helpers shared with the property tests.
extern crate std;
use std::format;
use std::string::String;

use super::super::*;
use super::{assert_rejected, block, motion, parser};
use crate::nc::{Arc, Motion, Plane};

pub(super) const PLANES: [Plane; 3] = [Plane::XY, Plane::ZX, Plane::YZ];

pub(super) fn arc_of(p: &mut Parser, s: &str) -> Arc {
    match block(p, s).motion {
        Motion::Arc(a) => a,
        m => panic!("{s:?} gave {m:?}"),
    }
}

/// Letters of the (a, b) axes, of their centre offsets, and the plane's G code.
pub(super) fn letters(plane: Plane) -> ([char; 2], [char; 2], &'static str) {
    match plane {
        Plane::XY => (['X', 'Y'], ['I', 'J'], "G17"),
        Plane::ZX => (['Z', 'X'], ['K', 'I'], "G18"),
        Plane::YZ => (['Y', 'Z'], ['J', 'K'], "G19"),
    }
}

/// BLU (0.0001 in) as an inch number with four decimals.
pub(super) fn inch(v: i64) -> String {
    let a = v.unsigned_abs();
    format!(
        "{}{}.{:04}",
        if v < 0 { "-" } else { "" },
        a / 10_000,
        a % 10_000
    )
}

/// Rapid to c + p0 in the plane (a, b), then the arc to c + p1 with I/J/K = -p0. Returns the
/// parser and the arc line's result.
pub(super) fn run_arc(
    plane: Plane,
    ccw: bool,
    c: [i64; 2],
    p0: [i64; 2],
    p1: [i64; 2],
) -> (Parser, Result<Parsed, GcodeError>) {
    let mut p = parser();
    let (ax, off, g) = letters(plane);
    let go = format!(
        "G0 {}{} {}{}",
        ax[0],
        inch(c[0] + p0[0]),
        ax[1],
        inch(c[1] + p0[1])
    );
    p.line(1, &go).unwrap();
    let text = format!(
        "{g} G{} F10 {}{} {}{} {}{} {}{}",
        if ccw { 3 } else { 2 },
        ax[0],
        inch(c[0] + p1[0]),
        ax[1],
        inch(c[1] + p1[1]),
        off[0],
        inch(-p0[0]),
        off[1],
        inch(-p0[1]),
    );
    let r = p.line(2, &text);
    (p, r)
}

fn ok_arc(plane: Plane, ccw: bool, c: [i64; 2], p0: [i64; 2], p1: [i64; 2]) -> Arc {
    match run_arc(plane, ccw, c, p0, p1) {
        (
            _,
            Ok(Parsed::Block(Block {
                motion: Motion::Arc(a),
                ..
            })),
        ) => a,
        (_, other) => panic!("{plane:?} ccw={ccw} {p0:?}->{p1:?}: {other:?}"),
    }
}

fn targets(a: &Arc) -> &[[i32; 2]] {
    &a.targets[..a.n_targets as usize]
}

#[test]
fn quarter_circle() {
    let mut p = parser();
    block(&mut p, "X1");
    let a = arc_of(&mut p, "G3 F10 X0 Y1 I-1");
    assert_eq!(
        (a.plane, a.ccw, a.start, a.r),
        (Plane::XY, true, [10_000, 0], 10_000)
    );
    assert_eq!(targets(&a), &[[0, 10_000]]);
    assert_eq!(a.length, 15_708);
    assert_eq!((a.f, a.decel), (1000, false));
    assert_eq!(p.position(), [0, 10_000, 0]);
}

#[test]
fn half_circle_cw() {
    let mut p = parser();
    block(&mut p, "X1");
    let a = arc_of(&mut p, "G2 F10 X-1 I-1");
    assert!(!a.ccw);
    assert_eq!(targets(&a), &[[0, -10_000], [-10_000, 0]]);
    assert_eq!(a.length, 31_416);
}

#[test]
fn full_circles() {
    let r = 10_000;
    let a = ok_arc(Plane::XY, true, [0, 0], [r, 0], [r, 0]);
    assert_eq!(
        targets(&a),
        &[[0, 10_000], [-10_000, 0], [0, -10_000], [10_000, 0]]
    );
    assert_eq!(a.length, 62_832);
    let a = ok_arc(Plane::XY, true, [0, 0], [6000, 8000], [6000, 8000]);
    assert_eq!(
        targets(&a),
        &[
            [0, 10_000],
            [-10_000, 0],
            [0, -10_000],
            [10_000, 0],
            [6000, 8000]
        ]
    );
    let a = ok_arc(Plane::XY, false, [0, 0], [6000, 8000], [6000, 8000]);
    assert_eq!(
        targets(&a),
        &[
            [10_000, 0],
            [0, -10_000],
            [-10_000, 0],
            [0, 10_000],
            [6000, 8000]
        ]
    );
    assert_eq!(a.length, 62_832);
    // Without axis words (G3 and the offset only) it is a full circle too.
    let mut p = parser();
    block(&mut p, "X1");
    let b = arc_of(&mut p, "G3 F1 I-1");
    assert_eq!(b.n_targets, 4);
    assert_eq!(p.position(), [10_000, 0, 0]);
}

#[test]
fn quadrant_crossings_all_planes_both_directions() {
    let c = [2000, -1000];
    let (p0, p1) = ([4000, 3000], [-3000, -4000]);
    for plane in PLANES {
        let a = ok_arc(plane, true, c, p0, p1);
        assert_eq!(a.plane, plane);
        assert_eq!(
            targets(&a),
            &[[0, 5000], [-5000, 0], [-3000, -4000]],
            "{plane:?} CCW"
        );
        // 36.87 -> 233.13 degrees: 196.26 degrees.
        assert_eq!(a.length, 17_127, "{plane:?}");
        let a = ok_arc(plane, false, c, p0, p1);
        assert_eq!(
            targets(&a),
            &[[5000, 0], [0, -5000], [-3000, -4000]],
            "{plane:?} CW"
        );
        assert_eq!(a.length, 14_289, "{plane:?}"); // 163.74 degrees
                                                   // The position moves in the plane's axes.
        let (mut p, r) = run_arc(plane, false, c, p0, p1);
        assert!(r.is_ok());
        let (ia, ib) = plane.axes();
        let mut want = [0; 3];
        want[ia] = (c[0] + p1[0]) as i32;
        want[ib] = (c[1] + p1[1]) as i32;
        assert_eq!(p.position(), want);
        assert!(p.line(3, "G0 X0 Y0 Z0").is_ok());
    }
}

#[test]
fn start_on_axis_is_not_a_target_and_end_on_axis_appears_once() {
    let a = ok_arc(Plane::XY, true, [0, 0], [0, 5000], [-4000, -3000]);
    assert_eq!(targets(&a), &[[-5000, 0], [-4000, -3000]]);
    let a = ok_arc(Plane::XY, true, [0, 0], [4000, 3000], [-5000, 0]);
    assert_eq!(targets(&a), &[[0, 5000], [-5000, 0]]);
    let a = ok_arc(Plane::ZX, false, [0, 0], [0, -5000], [5000, 0]);
    assert_eq!(targets(&a), &[[-5000, 0], [0, 5000], [5000, 0]]);
}

#[test]
fn tiny_arc() {
    let a = ok_arc(Plane::XY, true, [0, 0], [1, 0], [0, 1]);
    assert_eq!((a.r, a.length, targets(&a)), (1, 2, &[[0, 1]][..]));
}

#[test]
fn r_form_positive_and_negative() {
    // Chord 10000 along X, R = 10000: 60 degree arc (positive) or 300 degree arc (negative).
    let mut p = parser();
    let a = arc_of(&mut p, "G2 F10 X1 R1");
    assert_eq!(a.start, [-5000, 8660]); // centre (5000, -8660)
    assert_eq!(a.r, 10_000);
    assert_eq!(targets(&a), &[[0, 10_000], [5000, 8660]]);
    assert_eq!(a.length, 10_472);
    let mut p = parser();
    let a = arc_of(&mut p, "G2 F10 X1 R-1");
    assert_eq!(a.start, [-5000, -8660]); // centre (5000, 8660)
    assert_eq!(
        targets(&a),
        &[[-10_000, 0], [0, 10_000], [10_000, 0], [5000, -8660]]
    );
    assert_eq!(a.length, 52_360);
    // CCW mirrors the centres.
    let mut p = parser();
    let a = arc_of(&mut p, "G3 F10 X1 R1");
    assert_eq!(a.start, [-5000, -8660]);
    assert_eq!(targets(&a), &[[0, -10_000], [5000, -8660]]);
    // R exactly half the chord: a half circle.
    let mut p = parser();
    let a = arc_of(&mut p, "G2 F10 X1 R0.5");
    assert_eq!(a.start, [-5000, 0]);
    assert_eq!(targets(&a), &[[0, 5000], [5000, 0]]);
    assert_eq!(p.position(), [10_000, 0, 0]);
}

#[test]
fn arc_extent_soft_limits() {
    // Centre (9.6, 0) in, start (9.6, -0.5): the CCW half circle bulges to X = 10.1 in.
    let mut p = parser();
    block(&mut p, "X9.6 Y-0.5 F10");
    let kind = ErrorKind::SoftLimit {
        axis: 'X',
        value: 101_000,
        min: -100_000,
        max: 100_000,
    };
    assert_rejected(&mut p, "G3 X9.6 Y0.5 J0.5", kind);
    // The CW half circle stays inside.
    let mut p = parser();
    block(&mut p, "X9.6 Y-0.5 F10");
    assert!(p.line(2, "G2 X9.6 Y0.5 J0.5").is_ok());
}

/// An arc whose end lies just past an axis crossing and a BLU or two outside the start's circle
/// (rounding; within grbl's radius tolerance) is accepted, as grbl accepts it, and runs to its exact
/// end inside the band between the start and the end radius: its last segment steps back along the
/// crossing axis by at most the tolerance. (It was refused as "end unreachable".)
#[test]
fn end_just_outside_the_circle_past_a_crossing_is_accepted_and_exact() {
    use crate::nc::{sim::Sim, Frame, FrameConfig};
    // Centre (-1000, 0) BLU from the start (0, 0); end (-1, 1001) from the centre: past the +b
    // crossing (0, 1000), one BLU outside the circle.
    let mut p = parser();
    let b = block(&mut p, "G3 F30 X-0.1001 Y0.1001 I-0.1");
    let Motion::Arc(a) = b.motion else {
        panic!("{b:?}")
    };
    assert_eq!(a.targets[a.n_targets as usize - 1], [-1, 1001]);
    let cfg = FrameConfig::from_settings(&Settings::default());
    let b = b.seal(&cfg);
    let mut frame = Frame::new(cfg);
    let mut last = [0; 3];
    for f in Sim::new(&mut frame, [b].into_iter(), u32::MAX, 1 << 24) {
        let (x, y) = ((f.position[0] + 1000) as f64, f.position[1] as f64);
        let rad = (x * x + y * y).sqrt();
        assert!(
            (1000.0 - 1.5..=1001.5 + 1.5).contains(&rad),
            "{:?} at radius {rad}",
            f.position
        );
        last = f.position;
    }
    assert_eq!(last, [-1001, 1001, 0]);
    // The case the review found: from X5.5329 in, an arc in mm whose end rounds a BLU outside.
    let mut p = parser();
    block(&mut p, "G20 G1 F10 X5.5329");
    assert!(matches!(
        motion(&mut p, "G21 G3 X195.989 Y15.892 I25.510 J15.680"),
        Motion::Arc(_)
    ));
}

#[test]
fn helices_move_the_third_axis_along_the_arc() {
    // G17: Z is the third axis. A quarter circle of radius 1 in rising 0.5 in: the path is
    // sqrt(15 708^2 + 5000^2) = 16 485 BLU, the plane's modulus R x path / plane.
    let mut p = parser();
    block(&mut p, "X1");
    let a = arc_of(&mut p, "G3 F10 X0 Y1 Z0.5 I-1");
    assert_eq!((a.plane, a.r, a.helix), (Plane::XY, 10_000, 5000));
    assert_eq!(targets(&a), &[[0, 10_000]]);
    let path = (15_707.96f64.powi(2) + 5000f64.powi(2)).sqrt();
    let q = (10_000.0 * path / 15_707.96).round();
    assert_eq!(a.q as f64, q);
    assert_eq!(a.length as f64, (q * std::f64::consts::FRAC_PI_2).round());
    assert_eq!(p.position(), [0, 10_000, 5000]);
    // G18 moves Y, G19 moves X, either way round; a plane arc has no helix and q = R.
    let mut p = parser();
    block(&mut p, "Z1");
    let a = arc_of(&mut p, "G18 G2 F10 Z0 X1 Y-0.25 K-1");
    assert_eq!((a.plane, a.helix, a.ccw), (Plane::ZX, -2500, false));
    let mut p = parser();
    block(&mut p, "Y1");
    let a = arc_of(&mut p, "G19 G3 F10 Y0 Z1 X0.1 J-1");
    assert_eq!((a.plane, a.helix), (Plane::YZ, 1000));
    let mut p = parser();
    block(&mut p, "X1");
    let a = arc_of(&mut p, "G3 F10 X0 Y1 Z0 I-1");
    assert_eq!((a.helix, a.q, a.r), (0, 10_000, 10_000));
    // A helix in the R form, and one full turn down (CAM's helical ramp into a pocket).
    let mut p = parser();
    block(&mut p, "X1");
    let a = arc_of(&mut p, "G2 F10 X0 Y-1 Z-0.1 R1");
    assert_eq!((a.helix, a.r), (-1000, 10_000));
    let a = arc_of(&mut p, "G2 F10 X0 Y-1 Z-0.2 I0 J1");
    assert_eq!((a.helix, a.n_targets), (-1000, 4));
    assert_eq!(p.position(), [0, -10_000, -2000]);
}

#[test]
fn a_helix_beyond_the_soft_limits_is_refused() {
    let mut p = parser();
    block(&mut p, "X1");
    let err = p.line(2, "G3 F10 X0 Y1 Z10 I-1").unwrap_err();
    assert!(
        matches!(err.kind, ErrorKind::SoftLimit { axis: 'Z', .. }),
        "{err:?}"
    );
}

/// The blocks of a G2/G3 line of P turns, from the parser's position before it, with each
/// block's end point (BLU).
fn turns(p: &mut Parser, line: &str) -> std::vec::Vec<(Arc, [i32; 3])> {
    let st = *p.settings();
    let mut at = p.position();
    let mut t = match p.line(1, line) {
        Ok(Parsed::Expand(e @ crate::gcode::Expansion::Turns(_))) => e,
        other => panic!("{line}: {other:?}"),
    };
    let mut out = std::vec::Vec::new();
    while let Some(b) = t.next_block(&st) {
        let Motion::Arc(a) = b.motion else {
            panic!("{:?}", b.motion)
        };
        let d = crate::rt::replan::displacement(&b);
        at = [0, 1, 2].map(|k| at[k] + d[k]);
        out.push((a, at));
    }
    assert!(t.done());
    assert_eq!(
        at,
        p.position(),
        "{line}: the parser stands where the turns end"
    );
    out
}

#[test]
fn p_turns_add_full_circles_and_share_the_helix_by_angle() {
    // Two full circles and the half circle programmed (5 pi in all), 0.3 in down: the third axis
    // at 2 pi / 5 pi and 4 pi / 5 pi of the travel after each circle.
    let mut p = parser();
    let blocks = turns(&mut p, "G17 G2 F10 X1 Y0 Z-0.3 I0.5 J0 P3");
    let ends: std::vec::Vec<[i32; 3]> = blocks.iter().map(|b| b.1).collect();
    assert_eq!(ends, [[0, 0, -1200], [0, 0, -2400], [10_000, 0, -3000]]);
    for (a, _) in &blocks {
        assert_eq!((a.plane, a.ccw, a.r), (Plane::XY, false, 5000));
    }
    assert_eq!(blocks[0].0.helix, -1200);
    // P1 is the arc as programmed: one block.
    let mut p = parser();
    let a = arc_of(&mut p, "G17 G3 F10 X1 Y0 I0.5 P1");
    assert_eq!(a.helix, 0);
    // G93: one F for the whole move, all its turns: five times the half circle's feed number.
    let mut p = parser();
    let half = arc_of(&mut p, "G93 G17 G2 F1 X1 Y0 I0.5").f;
    let mut p = parser();
    let blocks = turns(&mut p, "G93 G17 G2 F1 X1 Y0 I0.5 P3");
    assert!(blocks.iter().all(|(a, _)| a.f == blocks[0].0.f));
    assert!(
        (blocks[0].0.f as f64 / half as f64 - 5.0).abs() < 0.01,
        "{half} {blocks:?}"
    );
    // A plane full circle twice over.
    let mut p = parser();
    let blocks = turns(&mut p, "G3 F10 X0 Y0 I0.5 P2");
    assert_eq!(blocks.len(), 2);
    assert!(blocks
        .iter()
        .all(|(a, e)| a.n_targets == 4 && *e == [0, 0, 0]));
}

#[test]
fn bad_p_turns_are_refused() {
    for line in [
        "G2 F10 X1 I0.5 P0",
        "G2 F10 X1 I0.5 P1.5",
        "G2 F10 X1 I0.5 P-2",
        "G2 F10 X1 I0.5 P10001",
        "G2 F10 X1 R0.5 P2",
    ] {
        assert_rejected(&mut parser(), line, ErrorKind::ArcTurns);
    }
    // The turns' extent is checked against the soft limits before anything is queued: a circle of
    // radius 6 in about X6 crosses X 12 in, beyond the default +10 in.
    let err = parser().line(1, "G2 F10 X0 Y0 I6 P2").unwrap_err();
    assert!(
        matches!(err.kind, ErrorKind::SoftLimit { axis: 'X', .. }),
        "{err:?}"
    );
}
