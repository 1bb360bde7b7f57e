//! Property tests of the G-code parser (host tests): line blocks equal the coordinate deltas,
//! random arcs obey the segment rules the frame relies on, arbitrary text never panics and a
//! rejected line changes nothing, decimals read exactly, the 30 degree rule matches the angle.
extern crate std;
use std::format;
use std::string::String;
use std::vec::Vec;

use super::super::*;
use super::arc::{inch, run_arc, PLANES};
use super::parser;
use crate::nc::{Arc, Motion};
use core::f64::consts::PI;
use proptest::prelude::*;

fn angle(p: [i64; 2]) -> f64 {
    let t = libm::atan2(p[1] as f64, p[0] as f64);
    if t < 0.0 {
        t + 2.0 * PI
    } else {
        t
    }
}

/// Distance of an angle from the nearest multiple of 90 degrees.
fn off_axis(t: f64) -> f64 {
    let q = t / (PI / 2.0);
    (q - libm::round(q)).abs() * (PI / 2.0)
}

/// The segment rules (see `nc::Arc`): checks `a` for the arc from p0 to p1 (relative to the
/// centre) in the given direction; `sweep` is the travel angle in radians.
fn check_segments(a: &Arc, p0: [i64; 2], p1: [i64; 2], sweep: f64) -> Result<(), TestCaseError> {
    let n = a.n_targets as usize;
    prop_assert!((1..=5).contains(&n));
    prop_assert_eq!(a.start, [p0[0] as i32, p0[1] as i32]);
    let r = a.r as i64;
    let exact = libm::sqrt((p0[0] * p0[0] + p0[1] * p0[1]) as f64);
    prop_assert!((r as f64 - exact).abs() <= 0.5);
    let t: Vec<[i64; 2]> = a.targets[..n]
        .iter()
        .map(|p| [p[0] as i64, p[1] as i64])
        .collect();
    prop_assert_eq!(t[n - 1], p1, "last target is the end");
    for c in &t[..n - 1] {
        prop_assert!(
            (c[0] == 0 && c[1].abs() == r) || (c[1] == 0 && c[0].abs() == r),
            "crossing {:?} not on the circle r={}",
            c,
            r
        );
        prop_assert!(
            *c != p1,
            "a crossing equal to the end appears only as the end"
        );
    }
    for w in t[..n - 1].windows(2) {
        let rot = if a.ccw {
            [-w[0][1], w[0][0]]
        } else {
            [w[0][1], -w[0][0]]
        };
        prop_assert_eq!(w[1], rot, "crossings a quarter turn apart");
    }
    // The last segment may step back by the radius tolerance (an end a BLU or so outside the
    // start's circle, past a crossing); see `arc::plan`.
    let tol =
        (libm::ceil(super::super::arc::tolerance(&Settings::default(), r as f64)) as i64).max(1);
    let mut prev = p0;
    for (k, &q) in t.iter().enumerate() {
        let (da, db) = (q[0] - prev[0], q[1] - prev[1]);
        let slack = if k + 1 == n { tol } else { 0 };
        // Some closed quadrant holds both points, and in it the circle's direction of travel
        // (CCW: (-b, a), CW: (b, -a)) agrees with the signs of the deltas.
        let ok = [(1, 1), (-1, 1), (-1, -1), (1, -1)]
            .iter()
            .any(|&(sa, sb)| {
                let near = |v: i64, s: i64| v * s >= -slack;
                let inside =
                    prev[0] * sa >= 0 && prev[1] * sb >= 0 && near(q[0], sa) && near(q[1], sb);
                let (ga, gb) = if a.ccw { (-sb, sa) } else { (sb, -sa) };
                inside && da * ga >= -slack && db * gb >= -slack
            });
        prop_assert!(
            ok,
            "segment {:?} -> {:?} not monotone (ccw {})",
            prev,
            q,
            a.ccw
        );
        prev = q;
    }
    // Crossings counted from the angles, away from the axes.
    let (t0, t1) = (angle(p0), angle(p1));
    if off_axis(t0) > 1e-3 && off_axis(t1) > 1e-3 && sweep < 2.0 * PI - 1e-3 {
        let dir = if a.ccw { 1.0 } else { -1.0 };
        let k0 = libm::floor(dir * t0 / (PI / 2.0));
        let k1 = libm::floor(dir * (t0 + dir * sweep) / (PI / 2.0));
        prop_assert_eq!((k1 - k0) as usize, n - 1, "number of crossings");
    }
    let want = r as f64 * sweep;
    prop_assert!(
        (a.length as f64 - want).abs() <= 4.0,
        "length {} vs {}",
        a.length,
        want
    );
    Ok(())
}

fn point(r: f64, t: f64) -> [i64; 2] {
    [
        libm::round(r * libm::cos(t)) as i64,
        libm::round(r * libm::sin(t)) as i64,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn lines_give_the_deltas(
        moves in proptest::collection::vec(
            (any::<bool>(), any::<bool>(), [-100_000i64..=100_000, -100_000i64..=100_000, -40_000i64..=40_000]),
            1..12,
        )
    ) {
        let mut p = parser();
        p.line(1, "F10").unwrap();
        let mut signs_before = p.signs();
        for (feed, incremental, t) in moves {
            let before = p.position();
            let mode = if incremental { "G91" } else { "G90" };
            let words: [i64; 3] = if incremental {
                [t[0] - before[0] as i64, t[1] - before[1] as i64, t[2] - before[2] as i64]
            } else {
                t
            };
            let text = format!("{mode} G{} X{} Y{} Z{}", feed as u8, inch(words[0]), inch(words[1]), inch(words[2]));
            let got = p.line(5, &text).unwrap();
            let d = [t[0] - before[0] as i64, t[1] - before[1] as i64, t[2] - before[2] as i64];
            let steps = d.map(|x| x.unsigned_abs() as u32);
            // The moving axes' directions; an axis that does not move keeps its SIGN line (the
            // parser completes the byte). The proptest found a rapid with Z standing after a
            // move up: its Z bit stays set.
            let before_signs = signs_before;
            let moving = (0..3).filter(|&k| d[k] != 0).fold(0u8, |s, k| s | 1 << k);
            let signs = (0..3).filter(|&k| d[k] > 0).fold(0u8, |s, k| s | 1 << k)
                | (before_signs & !moving);
            match got {
                Parsed::Nothing => prop_assert_eq!(d, [0, 0, 0]),
                Parsed::Two(..)
                | Parsed::Expand(_)
                | Parsed::Stop(_)
                | Parsed::End
                | Parsed::Probe(..) => {
                    prop_assert!(false, "{got:?}")
                }
                Parsed::Block(b) => {
                    prop_assert_eq!(b.line, 5);
                    match b.motion {
                        Motion::Rapid(r) => {
                            prop_assert!(!feed);
                            prop_assert_eq!((r.steps, r.signs), (steps, signs));
                        }
                        Motion::Linear(l) => {
                            prop_assert!(feed);
                            prop_assert_eq!((l.steps, l.signs), (steps, signs));
                            let len2: u64 = d.iter().map(|x| (x * x) as u64).sum();
                            prop_assert_eq!(l.q as u64, crate::nc::isqrt(len2).max(1));
                            prop_assert_eq!(l.f, 1000);
                        }
                        m => prop_assert!(false, "{:?}", m),
                    }
                }
            }
            prop_assert_eq!(p.position(), [t[0] as i32, t[1] as i32, t[2] as i32]);
            signs_before = p.signs();
        }
    }

    #[test]
    fn random_arcs_obey_the_segment_rules(
        plane in 0usize..3,
        ccw in any::<bool>(),
        r in 1.0f64..15_000.0,
        t0 in 0.0f64..(2.0 * PI),
        sweep in 0.0f64..(2.0 * PI),
        full in proptest::bool::weighted(0.1),
        c in [-20_000i64..=20_000, -20_000i64..=20_000],
    ) {
        let plane = PLANES[plane];
        let p0 = point(r, t0);
        prop_assume!(p0 != [0, 0]);
        let p1 = if full {
            p0
        } else {
            let dir = if ccw { 1.0 } else { -1.0 };
            point(r, t0 + dir * sweep)
        };
        // The travel angle between the rounded points.
        let (m0, m1) = if ccw { (p0, p1) } else { ([p0[0], -p0[1]], [p1[0], -p1[1]]) };
        let cross = (m0[0] * m1[1] - m0[1] * m1[0]) as f64;
        let dot = (m0[0] * m1[0] + m0[1] * m1[1]) as f64;
        let same = cross == 0.0 && dot > 0.0;
        let mut s = libm::atan2(cross, dot);
        if s <= 0.0 {
            s += 2.0 * PI;
        }
        let s = if same { 2.0 * PI } else { s };
        let (parser_after, res) = run_arc(plane, ccw, c, p0, p1);
        match res {
            Ok(Parsed::Block(b)) => match b.motion {
                Motion::Arc(a) => {
                    prop_assert_eq!(a.plane, plane);
                    prop_assert_eq!(a.ccw, ccw);
                    check_segments(&a, p0, p1, s)?;
                    let (ia, ib) = plane.axes();
                    prop_assert_eq!(parser_after.position()[ia] as i64, c[0] + p1[0]);
                    prop_assert_eq!(parser_after.position()[ib] as i64, c[1] + p1[1]);
                }
                m => prop_assert!(false, "{:?}", m),
            },
            // Rounded end points can lie just outside the circle right past an axis (or right
            // past the start): only then may the arc be refused.
            Err(e) => {
                prop_assert!(matches!(e.kind, ErrorKind::ArcEndUnreachable { .. }), "{}", e);
                let rs = libm::sqrt((p0[0] * p0[0] + p0[1] * p0[1]) as f64);
                let near = libm::sqrt(rs) + 2.0;
                let chord = libm::sqrt(((p1[0] - p0[0]).pow(2) + (p1[1] - p0[1]).pow(2)) as f64);
                prop_assert!(
                    (p1[0].abs() as f64) <= near || (p1[1].abs() as f64) <= near || chord <= 2.0 * near,
                    "{} for an end point far from the axes and the start", e
                );
            }
            other => prop_assert!(false, "{:?}", other),
        }
    }

    #[test]
    fn never_panics_on_any_text(lines in proptest::collection::vec(".{0,300}", 1..6)) {
        let mut p = Parser::new(Settings { soft_min: [i32::MIN; 3], soft_max: [i32::MAX; 3], ..Settings::default() });
        for (i, l) in lines.iter().enumerate() {
            let _ = p.line(i as u32, l);
        }
    }

    #[test]
    fn never_panics_on_gcode_like_text_and_errors_change_nothing(
        lines in proptest::collection::vec("[GMXYZIJKRPFSNgxyz0-9 .+\\-();]{0,40}", 1..12),
        wide in any::<bool>(),
    ) {
        let st = if wide {
            Settings { soft_min: [i32::MIN; 3], soft_max: [i32::MAX; 3], ..Settings::default() }
        } else {
            Settings::default()
        };
        let mut p = Parser::new(st);
        let mut la = Lookahead::new();
        for (i, l) in lines.iter().enumerate() {
            let before = p.clone();
            match p.line(i as u32, l) {
                Err(e) => {
                    prop_assert_eq!(p.position(), before.position());
                    prop_assert_eq!(p.modes(), before.modes());
                    let msg = format!("{e}");
                    let prefix = format!("line {i}: ");
                    prop_assert!(msg.starts_with(&prefix));
                }
                Ok(Parsed::Block(b)) => {
                    let _ = la.push(b);
                }
                Ok(_) => {}
            }
        }
        let _ = la.flush();
    }

    #[test]
    fn decimals_read_exactly(m in any::<i64>(), scale in 0u8..=12) {
        let a = m.unsigned_abs() as u128;
        let p = 10u128.pow(scale as u32);
        let text: String = if scale == 0 {
            format!("{m}")
        } else {
            format!("{}{}.{:0w$}", if m < 0 { "-" } else { "" }, a / p, a % p, w = scale as usize)
        };
        let d = number::parse_decimal(&text).unwrap();
        // Same value: d.mantissa / 10^d.scale == m / 10^scale.
        prop_assert_eq!(d.mantissa * 10i128.pow(scale as u32), m as i128 * 10i128.pow(d.scale as u32));
        prop_assert_eq!(format!("{d}").parse::<f64>().unwrap(), text.parse::<f64>().unwrap());
    }

    /// The integer conversion to f32 is core's correctly rounded one (halfway cases: 2^24 + 1
    /// and + 3 are ties, to even; 0.1 and 1e-18 and 3.4e38 the usual ones), for any mantissa and scale
    /// (and the halfway cases core rounds to even).
    #[test]
    fn decimals_convert_to_the_nearest_f32(m in any::<i64>(), scale in 0u8..=18, wide in any::<bool>()) {
        let m = if wide { m as i128 * 1_000_003 } else { m as i128 };
        let d = Decimal { mantissa: m, scale };
        let want: f32 = format!("{d}").parse().unwrap();
        prop_assert_eq!(d.to_f32().map(f32::to_bits), Some((want + 0.0).to_bits()), "{}", d);
        for (m, s) in [(16_777_217i128, 0u8), (16_777_219, 0), (-16_777_217, 0), (1, 1), (1, 18), (34, 0)] {
            let d = Decimal { mantissa: m, scale: s };
            let want: f32 = format!("{d}").parse().unwrap();
            prop_assert_eq!(d.to_f32(), Some(want), "{}", d);
        }
    }

    #[test]
    fn thirty_degree_rule_matches_the_angle(
        u in [-1_000_000i64..=1_000_000, -1_000_000i64..=1_000_000, -1_000_000i64..=1_000_000],
        v in [-1_000_000i64..=1_000_000, -1_000_000i64..=1_000_000, -1_000_000i64..=1_000_000],
        scale in 0u32..=12,
    ) {
        let f = |x: [i64; 3]| libm::sqrt(x.iter().map(|a| (*a as f64) * (*a as f64)).sum::<f64>());
        let (nu, nv) = (f(u), f(v));
        prop_assume!(nu > 0.0 && nv > 0.0);
        let cos = u.iter().zip(v.iter()).map(|(a, b)| *a as f64 * *b as f64).sum::<f64>() / (nu * nv);
        let deg = libm::acos(cos.clamp(-1.0, 1.0)).to_degrees();
        prop_assume!((deg - 30.0).abs() > 0.01);
        let big = u.map(|a| a << scale);
        prop_assert_eq!(lookahead::sharp(big, v), deg > 30.0, "{} degrees", deg);
    }
}

#[test]
fn unreachable_arc_ends_are_rare() {
    // Deterministic sweep over start angles and radii: end points rounded from the exact circle
    // are almost always accepted.
    let mut rejected = 0;
    let mut total = 0;
    for i in 0..400 {
        let r = 1000.0 + (i * 37 % 9000) as f64;
        let t0 = i as f64 * 0.37;
        let p0 = point(r, t0);
        let p1 = point(r, t0 + 1.0 + (i % 7) as f64 * 0.6);
        for ccw in [true, false] {
            total += 1;
            if run_arc(crate::nc::Plane::XY, ccw, [0, 0], p0, p1)
                .1
                .is_err()
            {
                rejected += 1;
            }
        }
    }
    assert!(rejected * 100 <= total, "{rejected} of {total} rejected");
}

/// The case the proptest found (a rapid in Y with Z standing after a move up): the rapid keeps Z's
/// SIGN line high, only Y's line goes low.
#[test]
fn a_rapid_keeps_the_sign_line_of_an_axis_that_stands() {
    let mut p = parser();
    p.line(1, "F10").unwrap();
    let up = format!("G90 G0 X0 Y0 Z{}", inch(11918));
    p.line(2, &up).unwrap();
    let across = format!("G90 G0 X0 Y{} Z{}", inch(-1), inch(11918));
    let Parsed::Block(b) = p.line(3, &across).unwrap() else {
        panic!("no block for {across}")
    };
    let Motion::Rapid(r) = b.motion else {
        panic!("{:?}", b.motion)
    };
    assert_eq!((r.steps, r.signs), ([0, 1, 0], 0b100));
}
