//! End-to-end geometry of random valid programs (host): G-code text in through the tape, pulses out
//! of the frame, checked block by block against the geometry the program asks for (computed here
//! from exact positions, not by the parser): end points, distance from the ideal line or circle,
//! pulses per axis, and the feed the pulses run at.
mod common;

use common::*;
use millac::nc::Motion;
use millac::Settings;
use proptest::prelude::*;

/// Runs a program and returns its blocks' traces, after checking that the tape accepted it and
/// that the blocks came from exactly the lines that move the machine.
fn run_program(p: &Program) -> (Vec<millac::nc::Sealed>, Vec<Trace>) {
    let (blocks, err) = tape(&p.text("\n"), 64);
    assert_eq!(err, None, "valid program refused:\n{}", p.text("\n"));
    assert_eq!(
        lines_of(&blocks),
        p.expect.iter().map(|e| e.line).collect::<Vec<_>>(),
        "one block per moving line"
    );
    let frames = run(&blocks);
    let t = traces(&frames, blocks.len());
    (blocks, t)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Every block ends exactly on its programmed end point (the exact programmed position rounded
    /// once to BLU), and the program ends at the last programmed position.
    #[test]
    fn every_block_ends_on_its_programmed_end_point(p in programs(8)) {
        let (_, traces) = run_program(&p);
        for (e, t) in p.expect.iter().zip(&traces) {
            prop_assert_eq!(t.path[0], e.start, "line {} starts where the last ended", e.line);
            prop_assert_eq!(t.end(), e.end, "line {}: {}", e.line, p.lines[e.line as usize - 1]);
        }
        let last = traces.last().map_or([0; 3], Trace::end);
        prop_assert_eq!(last, p.end());
    }

    /// A line's pulses stay within 1 BLU of the ideal line; an arc's within 1.5 BLU of its circle
    /// (between the radii of its start and its end, which rounding may leave a BLU apart) and off
    /// its third axis.
    #[test]
    fn pulses_stay_on_the_programmed_path(p in programs(8)) {
        let (_, traces) = run_program(&p);
        for (e, t) in p.expect.iter().zip(&traces) {
            match e.shape {
                Shape::Rapid => {}
                Shape::Line => {
                    for q in &t.path {
                        let d = line_distance(*q, e.start, e.end);
                        prop_assert!(d <= 1.0, "line {}: {:?} is {} BLU off", e.line, q, d);
                    }
                }
                Shape::Arc { centre, axes: (a, b), .. } => {
                    let rad = |q: [i64; 3]| {
                        (((q[a] - centre[a]).pow(2) + (q[b] - centre[b]).pow(2)) as f64).sqrt()
                    };
                    let (r0, r1) = (rad(e.start), rad(e.end));
                    let (lo, hi) = (r0.min(r1), r0.max(r1));
                    let third = 3 - a - b;
                    for q in &t.path {
                        let r = rad(*q);
                        let d = (lo - r).max(r - hi).max(0.0);
                        prop_assert!(d <= 1.5, "arc line {}: {:?} is {} BLU off r {}..{}", e.line, q, d, lo, hi);
                        prop_assert_eq!(q[third], e.start[third]);
                    }
                }
            }
        }
    }

    /// The pulses per axis equal the programmed travel: |end - start| for lines and rapids, the
    /// sum of the monotone pieces between axis crossings for arcs.
    #[test]
    fn pulse_count_per_axis_is_the_programmed_travel(p in programs(8)) {
        let (_, traces) = run_program(&p);
        for (e, t) in p.expect.iter().zip(&traces) {
            match e.shape {
                Shape::Rapid | Shape::Line => {
                    let want = [0, 1, 2].map(|k| (e.end[k] - e.start[k]).unsigned_abs());
                    prop_assert_eq!(t.pulses, want, "line {}", e.line);
                }
                Shape::Arc { centre, axes: (a, b), ccw } => {
                    let rel = |q: [i64; 3]| [q[a] - centre[a], q[b] - centre[b]];
                    let (p0, p1) = (rel(e.start), rel(e.end));
                    // The frame's radius: sqrt(i^2 + j^2) of the start, rounded.
                    let r = (((p0[0] * p0[0] + p0[1] * p0[1]) as f64).sqrt()).round() as i64;
                    if let Some(want) = arc_travel(p0, p1, ccw, r) {
                        prop_assert_eq!([t.pulses[a], t.pulses[b]], want, "arc line {}", e.line);
                    }
                    prop_assert_eq!(t.pulses[3 - a - b], 0);
                }
            }
        }
    }
}

/// A random straight or circular path cut into pieces that meet without a corner (so no piece but
/// the last decelerates), each piece with its own feed.
#[derive(Clone, Debug)]
struct Chain {
    mm: bool,
    dir: [i64; 3],
    pieces: Vec<(u32, u32)>,
    arc: Option<(usize, bool, i64)>,
}

fn chain() -> impl Strategy<Value = Chain> {
    (
        any::<bool>(),
        [-1000i64..=1000, -1000i64..=1000, -300i64..=300],
        proptest::collection::vec((1u32..=4, 50u32..=300), 1..5),
        proptest::option::of((0usize..3, any::<bool>(), 2000i64..8000)),
    )
        .prop_map(|(mm, dir, pieces, arc)| Chain {
            mm,
            dir,
            pieces,
            arc,
        })
}

/// The chain as moves: collinear lines of `len * 1000` BLU along `dir`, or arcs of `len * 30`
/// degrees continuing one circle.
fn chain_moves(c: &Chain) -> Vec<RawMove> {
    let mut pos = [0i64; 3];
    let n: f64 = c
        .dir
        .iter()
        .map(|v| (v * v) as f64)
        .sum::<f64>()
        .sqrt()
        .max(1.0);
    let mut a0 = 0.3f64;
    c.pieces
        .iter()
        .map(|&(len, tenths)| {
            let kind = match c.arc {
                None => {
                    for (p, d) in pos.iter_mut().zip(c.dir) {
                        *p += (d as f64 / n * len as f64 * 1000.0).round() as i64;
                    }
                    Kind::Line
                }
                Some((plane, ccw, radius)) => {
                    let sweep = (len * 30) as f64 * std::f64::consts::PI / 180.0;
                    let k = Kind::Arc {
                        plane,
                        ccw,
                        radius,
                        a0,
                        sweep,
                    };
                    a0 += if ccw { sweep } else { -sweep };
                    k
                }
            };
            RawMove {
                kind,
                mm: c.mm,
                incremental: false,
                target: pos,
                omit: 0,
                feed_tenths: Some(tenths),
            }
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// The feed: a block that runs at its feed to the end takes L q0 / f frames at W0 (one
    /// interpolation command, 1 BLU of path, per q0 / f frames), f = q0 FR / FRM from its F word;
    /// within the DDA's phase, the load frames and 1 %. A block first ramps from the speed it
    /// starts with (a stop for an arc or a line after anything but a line; the feed the line
    /// before it ended with when chained) to its feed at its acceleration a (feed numbers per
    /// frame): from v1 to v2 that takes T = |v2 - v1| / a frames and costs T (v2 - v1) / (2 v2)
    /// frames against running at v2 throughout (a gain when it slows down).
    #[test]
    fn steady_blocks_run_at_w0_f_over_q0(c in chain()) {
        let p = program(&chain_moves(&c));
        let (blocks, traces) = run_program(&p);
        let q0 = Settings::default().q0 as f64;
        let mut checked = 0;
        for (i, ((e, b), t)) in p.expect.iter().zip(&blocks).zip(&traces).enumerate() {
            let chained = i > 0
                && matches!(blocks[i - 1].motion, Motion::Linear(_))
                && matches!(b.motion, Motion::Linear(_));
            let ramp = match b.motion {
                Motion::Linear(l) => l.ramp,
                Motion::Arc(a) => a.ramp,
                _ => 0,
            };
            let v1 = match (chained, blocks.get(i.wrapping_sub(1)).map(|b| b.motion)) {
                (true, Some(Motion::Linear(l))) if l.decel => l.f_floor as f64,
                (true, Some(Motion::Linear(l))) => l.f as f64,
                _ => 0.0,
            };
            let v2 = e.f as f64;
            let ramp_lost = (v2 - v1) * (v2 - v1).abs() / (2.0 * ramp as f64 / 256.0 * v2);
            let (length, loads) = match (e.shape, b.motion) {
                (Shape::Line, Motion::Linear(_)) => {
                    let d: f64 = (0..3).map(|k| ((e.end[k] - e.start[k]) as f64).powi(2)).sum();
                    (d.sqrt(), 1.0)
                }
                (Shape::Arc { centre, axes: (a, b2), ccw }, Motion::Arc(arc)) => {
                    let rel = |q: [i64; 3]| [q[a] - centre[a], q[b2] - centre[b2]];
                    let (p0, p1) = (rel(e.start), rel(e.end));
                    let r = (((p0[0] * p0[0] + p0[1] * p0[1]) as f64).sqrt()
                        + ((p1[0] * p1[0] + p1[1] * p1[1]) as f64).sqrt()) / 2.0;
                    (r * arc_sweep(p0, p1, ccw), 1.0 + arc.n_targets as f64)
                }
                other => panic!("unexpected block {other:?}"),
            };
            if !steady(b) {
                continue;
            }
            checked += 1;
            let per_command = q0 / e.f as f64;
            let want = length * per_command + ramp_lost;
            let tol = 0.01 * want + (loads + 1.0) * per_command + 2.0;
            prop_assert!(
                (t.frames as f64 - want).abs() <= tol,
                "line {}: {} frames for {:.1} BLU at f {}, want {:.0} +- {:.0}",
                e.line, t.frames, length, e.f, want, tol
            );
        }
        prop_assert_eq!(checked, p.expect.len().saturating_sub(1), "all but the last piece run steady");
    }
}
