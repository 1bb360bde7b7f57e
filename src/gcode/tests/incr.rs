//! Host tests of incremental programming (G91) and unit switches (G20/G21): the programmed position
//! is kept exactly and only the machine target is rounded, so N increments end where one move of
//! their sum would, for lines, rapids and arcs (issue 6, defect 1).
extern crate std;
use std::format;
use std::string::String;
use std::vec::Vec;

use super::super::*;
use super::parser;
use crate::nc::Motion;
use proptest::prelude::*;

/// Runs `lines` through a fresh parser; returns the parser's machine position and the position the
/// blocks' pulses reach (signed counters per axis, arcs by their last target), which must agree.
fn run(lines: &[String]) -> ([i32; 3], [i64; 3]) {
    let mut p = parser();
    let mut pulses = [0i64; 3];
    for (n, l) in lines.iter().enumerate() {
        match p.line(n as u32 + 1, l) {
            Ok(Parsed::Block(b)) => match b.motion {
                Motion::Linear(m) => add(&mut pulses, m.steps, m.signs),
                Motion::Rapid(m) => add(&mut pulses, m.steps, m.signs),
                Motion::Arc(c) => {
                    let (a, b) = c.plane.axes();
                    let end = c.targets[c.n_targets as usize - 1];
                    pulses[a] += (end[0] - c.start[0]) as i64;
                    pulses[b] += (end[1] - c.start[1]) as i64;
                }
                Motion::Dwell(_) => {}
            },
            Ok(_) => {}
            Err(e) => panic!("{l:?}: {e}"),
        }
    }
    (p.position(), pulses)
}

fn add(pos: &mut [i64; 3], steps: [u32; 3], signs: u8) {
    for k in 0..3 {
        let d = steps[k] as i64;
        pos[k] += if signs & (1 << k) != 0 { d } else { -d };
    }
}

fn repeat(head: &str, line: &str, n: usize) -> Vec<String> {
    let mut v: Vec<String> = head.lines().map(String::from).collect();
    v.extend(core::iter::repeat_n(String::from(line), n));
    v
}

/// The two cases: 100 x 0.01 mm and 1000 x 0.001 mm both end at 1 mm = round(393.7) BLU,
/// where rounding each increment gave 400 and 0.
#[test]
fn increments_end_where_their_sum_would() {
    let one_move = run(&repeat("G21 G91 G1 F100", "X1", 1));
    assert_eq!(one_move.0, [394, 0, 0]);
    for (line, n) in [("X0.01", 100), ("X0.001", 1000), ("G0 X0.1", 10)] {
        let (pos, pulses) = run(&repeat("G21 G91 G1 F100", line, n));
        assert_eq!(pos, one_move.0, "{n} x {line}");
        assert_eq!(pulses, [394, 0, 0], "{n} x {line}: pulses");
    }
}

/// Unit switches keep the exact position: +0.01 mm then -0.0002 in per pair, 500 pairs, end at
/// round(500 x 0.00492 mm) = round(968.5039) = 969 BLU (rounding each word gave 500 x (4 - 2)).
/// And +1 mm then -1/25.4 in (= -1 mm) per pair end exactly at 0.
#[test]
fn unit_switches_are_exact() {
    let mut v = vec![String::from("G91 G1 F10")];
    for _ in 0..500 {
        v.push("G21 X0.01".into());
        v.push("G20 X-0.0002".into());
    }
    // In units of 10^-5 mm: 0.01 mm = 1000, 0.0002 in = 508, one BLU = 254.
    let exact: i64 = 500 * (1000 - 508);
    let blu = ((2 * exact + 254) / (2 * 254)) as i32;
    assert_eq!(blu, 969);
    assert_eq!(run(&v), ([blu, 0, 0], [blu as i64, 0, 0]));
    let mut v = vec![String::from("G91 G1 F10")];
    for _ in 0..500 {
        v.push("G21 Y1".into());
        v.push("G20 Y-0.03937007874015748".into());
    }
    let (pos, _) = run(&v);
    // 1/25.4 in has no finite decimal: 18 decimals leave 500 x 2e-17 in, far below a BLU.
    assert_eq!(pos, [0; 3]);
}

/// Incremental arcs whose radius is not a whole number of BLU: 100 semicircles of 0.006 mm along X
/// end at round(0.6 mm) = 236 BLU (rounding each arc's end gave 100 x 2), and the centre of each arc
/// is the exact programmed start plus I (every arc is accepted: its end is on its circle).
#[test]
fn incremental_arcs_round_once() {
    let v = repeat("G21 G91 G1 F10", "G2 X0.006 I0.003", 100);
    let (pos, pulses) = run(&v);
    assert_eq!(pos, [236, 0, 0]);
    assert_eq!(pulses, [236, 0, 0]);
    // A full turn of four quarters, repeated, returns to its start exactly.
    let mut v = vec![String::from("G21 G91 G1 F10")];
    for _ in 0..100 {
        for l in [
            "G3 X-0.003 Y0.003 I-0.003 J0",
            "X-0.003 Y-0.003 I0 J-0.003",
            "X0.003 Y-0.003 I0.003 J0",
            "X0.003 Y0.003 I0 J0.003",
        ] {
            v.push(l.into());
        }
    }
    assert_eq!(run(&v), ([0; 3], [0; 3]));
}

proptest! {
    /// Any sequence of increments, in inches (4 decimals) or mm (3 decimals), ends at the rounding of
    /// its exact sum (computed here in units of 10^-5 mm: 0.0001 in = 254, 0.001 mm = 100).
    #[test]
    fn any_increments_round_once(steps in proptest::collection::vec((any::<bool>(), -2000i64..2000), 1..60)) {
        let mut v = vec![String::from("G91 G1 F10")];
        let mut exact = 0i64;
        for &(inch, n) in &steps {
            let (unit, text) = if inch {
                (254, format!("G20 X{}", Decimal { mantissa: n as i128, scale: 4 }))
            } else {
                (100, format!("G21 X{}", Decimal { mantissa: n as i128, scale: 3 }))
            };
            exact += n * unit;
            v.push(text);
        }
        // BLU = 0.0001 in = 254 units; round half away from zero.
        let blu = (2 * exact.abs() + 254) / (2 * 254) * exact.signum();
        let (pos, pulses) = run(&v);
        prop_assert_eq!(pos[0] as i64, blu);
        prop_assert_eq!(pulses[0], blu);
    }
}
