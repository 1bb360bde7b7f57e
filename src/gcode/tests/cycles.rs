//! Host tests of the canned cycles: the moves of each cycle, G98/G99, G91 and L, sticky words,
//! the refusals, and the parser's position after a cycle.
use super::*;
use crate::gcode::cycles::PECK_CLEARANCE;
use crate::gcode::error::CycleError;
use std::vec::Vec;

/// A move of the expansion: (rapid, feed or dwell) and its end in BLU.
#[derive(Debug, PartialEq, Eq)]
enum M {
    Rapid([i32; 3]),
    Feed([i32; 3]),
    Dwell(u32),
}

/// The moves of a cycle line, from the parser's position before it.
fn expand(p: &mut Parser, line: &str) -> Vec<M> {
    let st = *p.settings();
    let mut at = p.position();
    let mut c = match p.line(1, line) {
        Ok(Parsed::Expand(crate::gcode::Expansion::Cycle(c))) => c,
        other => panic!("{line}: {other:?}"),
    };
    let mut out = Vec::new();
    while let Some(b) = c.next_block(&st) {
        let mut end = |steps: [u32; 3], signs: u8| {
            for k in 0..3 {
                let d = steps[k] as i32;
                at[k] += if signs & (1 << k) != 0 { d } else { -d };
            }
            at
        };
        out.push(match b.motion {
            Motion::Rapid(r) => M::Rapid(end(r.steps, r.signs)),
            Motion::Linear(l) => {
                assert_eq!(l.f, p.modes().feed);
                M::Feed(end(l.steps, l.signs))
            }
            Motion::Dwell(d) => M::Dwell(d.frames),
            m => panic!("{m:?}"),
        });
    }
    assert!(c.done());
    assert_eq!(
        at,
        p.position(),
        "{line}: the parser stands where the cycle ends"
    );
    out
}

/// BLU of inches (0.0001 in).
fn b(x: f64, y: f64, z: f64) -> [i32; 3] {
    [x, y, z].map(|v| (v * 10_000.0).round() as i32)
}

#[test]
fn g81_drills_and_retracts_to_the_initial_level_or_r() {
    let mut p = parser();
    run(&mut p, "G20 G0 X0 Y0 Z1");
    run(&mut p, "F10");
    // G98 (the power-up mode): back to Z1, where the series began.
    assert_eq!(
        expand(&mut p, "G81 X1 Y2 Z-0.5 R0.1"),
        [
            M::Rapid(b(1.0, 2.0, 1.0)),
            M::Rapid(b(1.0, 2.0, 0.1)),
            M::Feed(b(1.0, 2.0, -0.5)),
            M::Rapid(b(1.0, 2.0, 1.0)),
        ]
    );
    // The next hole of the series: X alone, R and Z sticky; G99 back to R only.
    assert_eq!(
        expand(&mut p, "G99 X2"),
        [
            M::Rapid(b(2.0, 2.0, 1.0)),
            M::Rapid(b(2.0, 2.0, 0.1)),
            M::Feed(b(2.0, 2.0, -0.5)),
            M::Rapid(b(2.0, 2.0, 0.1)),
        ]
    );
    // From R (G99), the XY move stays at R.
    assert_eq!(
        expand(&mut p, "X3"),
        [
            M::Rapid(b(3.0, 2.0, 0.1)),
            M::Feed(b(3.0, 2.0, -0.5)),
            M::Rapid(b(3.0, 2.0, 0.1)),
        ]
    );
    // G80 ends the series: the next G81 needs its R and Z again.
    run(&mut p, "G80");
    assert_rejected(
        &mut p,
        "G81 X1",
        ErrorKind::MissingWord {
            code: 810,
            letter: 'R',
        },
    );
}

#[test]
fn below_r_the_tool_rises_first() {
    let mut p = parser();
    run(&mut p, "G20 G0 X0 Y0 Z-0.2 F10");
    assert_eq!(
        expand(&mut p, "G98 G81 X1 Y0 Z-0.5 R0.1"),
        [
            M::Rapid(b(0.0, 0.0, 0.1)),
            M::Rapid(b(1.0, 0.0, 0.1)),
            M::Feed(b(1.0, 0.0, -0.5)),
            M::Rapid(b(1.0, 0.0, 0.1)),
        ]
    );
}

#[test]
fn g83_pecks_out_to_r_and_g73_backs_off() {
    let mut p = parser();
    run(&mut p, "G20 G0 X0 Y0 Z0.1 F10");
    let c = PECK_CLEARANCE / (crate::gcode::fine::FINE_PER_INCH / 10_000);
    assert_eq!(c, 100, "0.010 in");
    // Pecks of 0.2 from R 0.1 to -0.45: feeds to -0.1, -0.3, then the bottom.
    let z = |v: f64| b(1.0, 0.0, v);
    assert_eq!(
        expand(&mut p, "G99 G83 X1 Y0 Z-0.45 R0.1 Q0.2"),
        [
            M::Rapid(z(0.1)),
            M::Feed(z(-0.1)),
            M::Rapid(z(0.1)),
            M::Rapid(z(-0.09)),
            M::Feed(z(-0.3)),
            M::Rapid(z(0.1)),
            M::Rapid(z(-0.29)),
            M::Feed(z(-0.45)),
            M::Rapid(z(0.1)),
        ]
    );
    run(&mut p, "G0 X0");
    assert_eq!(
        expand(&mut p, "G73 X1 Z-0.45 R0.1 Q0.2"),
        [
            M::Rapid(z(0.1)),
            M::Feed(z(-0.1)),
            M::Rapid(z(-0.09)),
            M::Feed(z(-0.3)),
            M::Rapid(z(-0.29)),
            M::Feed(z(-0.45)),
            M::Rapid(z(0.1)),
        ]
    );
}

#[test]
fn dwells_and_bores() {
    let st = Settings::default();
    let frames = st.frame_hz / 2;
    let mut p = parser();
    run(&mut p, "G20 G0 X0 Y0 Z0.1 F10");
    let z = |v: f64| b(0.0, 0.0, v);
    assert_eq!(
        expand(&mut p, "G99 G82 Z-0.3 R0.1 P0.5"),
        [M::Feed(z(-0.3)), M::Dwell(frames), M::Rapid(z(0.1))]
    );
    assert_eq!(
        expand(&mut p, "G85 Z-0.3 R0.1"),
        [M::Feed(z(-0.3)), M::Feed(z(0.1))]
    );
    assert_eq!(
        expand(&mut p, "G89 Z-0.3 R0.1 P0.5"),
        [M::Feed(z(-0.3)), M::Dwell(frames), M::Feed(z(0.1))]
    );
}

#[test]
fn incremental_repeats_step_from_hole_to_hole() {
    let mut p = parser();
    run(&mut p, "G20 G0 X0 Y0 Z0.5 F10");
    // G91: R is 0.4 below the start (Z 0.1), Z 0.3 below R; three holes 1 in apart in X.
    let moves = expand(&mut p, "G91 G99 G81 X1 Z-0.3 R-0.4 L3");
    let feeds: Vec<&M> = moves.iter().filter(|m| matches!(m, M::Feed(_))).collect();
    assert_eq!(
        feeds,
        [
            &M::Feed(b(1.0, 0.0, -0.2)),
            &M::Feed(b(2.0, 0.0, -0.2)),
            &M::Feed(b(3.0, 0.0, -0.2)),
        ]
    );
    assert_eq!(p.position(), b(3.0, 0.0, 0.1));
}

#[test]
fn cycle_refusals() {
    let mut p = parser();
    run(&mut p, "G20 G0 X0 Y0 Z0.5 F10");
    assert_rejected(
        &mut p,
        "G81 X1 Z-0.3",
        ErrorKind::MissingWord {
            code: 810,
            letter: 'R',
        },
    );
    assert_rejected(
        &mut p,
        "G81 X1 R0.1",
        ErrorKind::MissingWord {
            code: 810,
            letter: 'Z',
        },
    );
    assert_rejected(
        &mut p,
        "G83 X1 Z-0.3 R0.1",
        ErrorKind::MissingWord {
            code: 830,
            letter: 'Q',
        },
    );
    assert_rejected(
        &mut p,
        "G83 X1 Z-0.3 R0.1 Q0",
        ErrorKind::Cycle(CycleError::Peck),
    );
    assert_rejected(
        &mut p,
        "G81 X1 Z0.3 R0.1",
        ErrorKind::Cycle(CycleError::RBelowZ),
    );
    assert_rejected(
        &mut p,
        "G81 X1 Z-0.3 R0.1 L0",
        ErrorKind::Cycle(CycleError::Repeats),
    );
    assert_rejected(
        &mut p,
        "G18 G81 X1 Z-0.3 R0.1",
        ErrorKind::Cycle(CycleError::NotXy),
    );
    assert_rejected(&mut p, "G81 X1 Z-0.3 R0.1 Q1", ErrorKind::UnusedWord('Q'));
    // A hole beyond the soft limits (X +-10 in) is refused before anything moves.
    assert!(matches!(
        p.line(1, "G91 G81 X4 Z-0.3 R0.1 L3").unwrap_err().kind,
        ErrorKind::SoftLimit { axis: 'X', .. }
    ));
    run(&mut p, "G90");
    assert!(matches!(
        p.line(1, "G81 X1 Z-5 R0.1").unwrap_err().kind,
        ErrorKind::SoftLimit { axis: 'Z', .. }
    ));
}

/// The tape expands a cycle within the room it is given and keeps the rest pending; pumped, the
/// blocks are the same as emitted at once.
#[test]
fn the_tape_pumps_a_long_cycle_within_its_room() {
    use crate::gcode::tape::Tape;
    let program = ["G20 G0 X0 Y0 Z0.1 F10", "G99 G83 X1 Z-1 R0.1 Q0.01"];
    let mut all = Vec::new();
    let mut t = Tape::new(Settings::default());
    for l in program {
        t.line(1, l, |b| all.push(b)).unwrap();
    }
    t.flush(|b| all.push(b));
    assert!(all.len() > 300, "{} blocks", all.len());
    let mut pumped = Vec::new();
    let mut t = Tape::new(Settings::default());
    t.line_within(1, program[0], 3, |b| pumped.push(b)).unwrap();
    t.line_within(2, program[1], 3, |b| pumped.push(b)).unwrap();
    assert!(t.pending() && pumped.len() <= 3);
    while t.pending() {
        let before = pumped.len();
        t.pump(5, |b| pumped.push(b));
        assert!(pumped.len() - before <= 5);
    }
    t.flush(|b| pumped.push(b));
    assert_eq!(pumped.len(), all.len());
    let moves = |v: &[crate::nc::Sealed]| v.iter().map(|b| b.motion).collect::<Vec<_>>();
    assert_eq!(moves(&pumped), moves(&all));
}

fn run(p: &mut Parser, l: &str) {
    p.line(1, l).unwrap_or_else(|e| panic!("{l}: {e}"));
}
