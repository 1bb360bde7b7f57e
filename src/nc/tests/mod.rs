//! Host tests of the frame (host): exact end points, path deviation, pulse rate, PTP steps and
//! deceleration, against blocks built here from geometry (the parser has its own tests).

mod ops;

use super::block::*;
use super::frame::{Frame, FrameConfig, Rate};
use super::isqrt;
use super::sim::Sim;
use crate::settings::Settings;
use proptest::prelude::*;

/// The paper's frame: no acceleration limit (the velocity reaches the feed in the first frame), so
/// the timing tests below see the feed DDA alone. The ramps have their own tests, with
/// [`cfg_accel`].
fn cfg() -> FrameConfig {
    FrameConfig {
        accel_q8: [RAMP_MAX; 3],
        ..cfg_accel()
    }
}

/// The default settings' frame, acceleration limits included.
fn cfg_accel() -> FrameConfig {
    FrameConfig::from_settings(&Settings::default())
}

fn signs_of(d: [i64; 3]) -> u8 {
    (0..3).filter(|&k| d[k] > 0).fold(0u8, |s, k| s | 1 << k)
}

fn line(d: [i64; 3], f: u32, decel: bool) -> Sealed {
    let steps = d.map(|v| v.unsigned_abs() as u32);
    let q = isqrt(d.iter().map(|v| (v * v) as u64).sum()).max(1) as u32;
    let b = Block {
        line: 1,
        motion: Motion::Linear(Linear {
            steps,
            signs: signs_of(d),
            q,
            f,
            decel,
            f_floor: 0,
            decel_below: 0,
            ramp: 0,
            dir: [1; 3],
        }),
    };
    b.seal(&cfg())
}

/// An arc in the XY plane with centre offset `c` from the start, `sweep` radians (sign = direction).
/// Segment targets follow the rule in block.rs: axis crossings at the rounded start radius, then the end.
fn arc(start: [i32; 2], r: f64, a0: f64, sweep: f64, f: u32) -> (Sealed, [i32; 2]) {
    let ccw = sweep > 0.0;
    let s = [(r * a0.cos()).round() as i32, (r * a0.sin()).round() as i32];
    let e = [
        (r * (a0 + sweep).cos()).round() as i32,
        (r * (a0 + sweep).sin()).round() as i32,
    ];
    let rr = {
        // round(sqrt(n)) with integers
        let n = s[0] as i64 * s[0] as i64 + s[1] as i64 * s[1] as i64;
        let fl = isqrt(n as u64) as i64;
        (if n - fl * fl > fl { fl + 1 } else { fl }) as i32
    };
    let mut targets = [[0; 2]; MAX_SEGMENTS];
    let mut n = 0usize;
    // Crossings strictly inside the sweep, in travel order.
    let quarter = std::f64::consts::FRAC_PI_2;
    let eps = 1e-9;
    let (lo, hi) = if ccw {
        (a0, a0 + sweep)
    } else {
        (a0 + sweep, a0)
    };
    let mut ks: Vec<i64> = (((lo / quarter).floor() as i64)..=((hi / quarter).ceil() as i64))
        .filter(|&k| {
            let ang = k as f64 * quarter;
            ang > lo + eps && ang < hi - eps
        })
        .collect();
    if !ccw {
        ks.reverse();
    }
    for k in ks {
        let p = match k.rem_euclid(4) {
            0 => [rr, 0],
            1 => [0, rr],
            2 => [-rr, 0],
            _ => [0, -rr],
        };
        if p != e {
            targets[n] = p;
            n += 1;
        }
    }
    targets[n] = e;
    n += 1;
    let length = (rr as f64 * sweep.abs()).round().max(1.0) as u32;
    let b = Block {
        line: 1,
        motion: Motion::Arc(Arc {
            plane: Plane::XY,
            ccw,
            start: s,
            r: rr.max(1) as u32,
            q: rr.max(1) as u32,
            helix: 0,
            targets,
            n_targets: n as u8,
            f,
            decel: false,
            f_floor: 0,
            decel_below: 0,
            ramp: 0,
            length,
        }),
    };
    let _ = start;
    (b.seal(&cfg()), [e[0] - s[0], e[1] - s[1]])
}

/// Perpendicular distance of point p from the line through 0 and d.
fn line_dist(p: [i32; 3], d: [i64; 3]) -> f64 {
    let (px, py, pz) = (p[0] as f64, p[1] as f64, p[2] as f64);
    let (dx, dy, dz) = (d[0] as f64, d[1] as f64, d[2] as f64);
    let l2 = dx * dx + dy * dy + dz * dz;
    let t = ((px * dx + py * dy + pz * dz) / l2).clamp(0.0, 1.0);
    let (ex, ey, ez) = (px - t * dx, py - t * dy, pz - t * dz);
    (ex * ex + ey * ey + ez * ez).sqrt()
}

/// Measured bound of the circular DDA's radial deviation (BLU); see `deviation_figures`.
const ARC_DEVIATION_BOUND: f64 = 0.5;

/// Runs one line; returns the end position, the largest distance from the ideal line and the frames.
fn run_line(d: [i64; 3], f: u32) -> ([i32; 3], f64, u64) {
    let mut frame = Frame::new(cfg());
    let (mut dev, mut frames, mut pos) = (0.0f64, 0u64, [0; 3]);
    for s in Sim::new(
        &mut frame,
        [line(d, f, false)].into_iter(),
        u32::MAX,
        100_000_000,
    ) {
        dev = dev.max(line_dist(s.position, d));
        frames = s.tick + 1;
        pos = s.position;
    }
    (pos, dev, frames)
}

/// Runs one arc; returns the end position, the programmed end offset and the largest radial distance
/// from the ideal path: the band between the start and the end radius (integer end points are never
/// exactly on the circle; the parser bounds the difference like grbl's error 33).
fn run_arc(r: f64, a0: f64, sweep: f64) -> ([i32; 3], [i32; 2], f64) {
    let (b, d) = arc([0, 0], r, a0, sweep, 3000);
    let Motion::Arc(c) = b.motion else {
        unreachable!()
    };
    let s = c.start;
    let e = c.targets[c.n_targets as usize - 1];
    let r0 = ((s[0] as f64).powi(2) + (s[1] as f64).powi(2)).sqrt();
    let r1 = ((e[0] as f64).powi(2) + (e[1] as f64).powi(2)).sqrt();
    let mut frame = Frame::new(cfg());
    let (mut dev, mut pos) = (0.0f64, [0; 3]);
    for f in Sim::new(&mut frame, [b].into_iter(), u32::MAX, 100_000_000) {
        pos = f.position;
        let (x, y) = ((s[0] + f.position[0]) as f64, (s[1] + f.position[1]) as f64);
        let rr = (x * x + y * y).sqrt();
        dev = dev.max(r0.min(r1) - rr).max(rr - r0.max(r1));
    }
    (pos, d, dev)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Lines: the end point is exact, every pulse stays within 1 BLU of the ideal line, and the
    /// block takes q * q0 / f frames (V = W0 f / q0 along the path).
    #[test]
    fn lines_end_exact_and_stay_on_the_line(
        dx in -3000i64..3000, dy in -3000i64..3000, dz in -300i64..300, f in 1u32..=3000,
    ) {
        prop_assume!(dx != 0 || dy != 0 || dz != 0);
        let d = [dx, dy, dz];
        let q = isqrt(d.iter().map(|v| (v * v) as u64).sum()).max(1);
        let (pos, dev, frames) = run_line(d, f);
        prop_assert_eq!(pos, [dx as i32, dy as i32, dz as i32]);
        prop_assert!(dev <= 1.0, "deviation {}", dev);
        // q commands at one command per q0/f frames (the feed DDA carries its remainder).
        let expect = q as f64 * 3000.0 / f as f64;
        prop_assert!((frames as f64 - expect).abs() <= 3000.0 / f as f64 + 1.0,
            "frames {} expected {}", frames, expect);
    }

    /// Arcs of any sweep and direction, crossing quadrants: exact end, deviation within the bound.
    #[test]
    fn arcs_end_exact_and_stay_on_the_circle(
        r in 5.0f64..4000.0, a0 in -7.0f64..7.0, sweep in 0.05f64..6.2, ccw in any::<bool>(),
    ) {
        let (pos, d, dev) = run_arc(r, a0, if ccw { sweep } else { -sweep });
        prop_assert_eq!([pos[0], pos[1]], d);
        prop_assert_eq!(pos[2], 0);
        prop_assert!(dev <= ARC_DEVIATION_BOUND, "deviation {}", dev);
    }
}

/// The figures quoted in docs/dev/nc-frame.md: largest deviation over 2000 seeded random lines and arcs.
/// `cargo test -p millac --lib deviation_figures -- --nocapture` prints them.
#[test]
fn deviation_figures() {
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut line_max, mut arc_max, mut helix_max, mut across_max) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for _ in 0..2000 {
        let d = [
            (rnd() * 8000.0 - 4000.0) as i64,
            (rnd() * 8000.0 - 4000.0) as i64,
            (rnd() * 800.0 - 400.0) as i64,
        ];
        if d == [0; 3] {
            continue;
        }
        let (pos, dev, _) = run_line(d, 3000);
        assert_eq!(pos, d.map(|v| v as i32));
        line_max = line_max.max(dev);
        let sweep = (0.05 + rnd() * 6.23) * if rnd() < 0.5 { 1.0 } else { -1.0 };
        let r = 5.0 + rnd() * 5000.0;
        let (pos, e, dev) = run_arc(r, rnd() * 14.0 - 7.0, sweep);
        assert_eq!([pos[0], pos[1]], e);
        arc_max = arc_max.max(dev);
        // A helix of slope up to 1 (third-axis travel per BLU of plane path) in any plane.
        let r = 50.0 + rnd() * 5000.0;
        let dz = ((rnd() * 2.0 - 1.0) * r * sweep.abs()) as i32;
        let plane = [Plane::XY, Plane::ZX, Plane::YZ][(rnd() * 3.0) as usize % 3];
        let (_, _, dev, across, _) = run_helix(plane, r, rnd() * 14.0 - 7.0, sweep, dz);
        helix_max = helix_max.max(dev);
        across_max = across_max.max(across);
    }
    println!("max deviation over 2000 lines: {line_max:.3} BLU; over 2000 arcs: {arc_max:.4} BLU");
    println!(
        "over 2000 helices (slope up to 1): radial {helix_max:.4} BLU, across the helix {across_max:.3} BLU"
    );
    assert!(line_max <= 1.0);
    assert!(arc_max <= ARC_DEVIATION_BOUND);
    assert!(helix_max <= ARC_DEVIATION_BOUND);
}

#[test]
fn pulse_rate_matches_w0_f_over_q0() {
    // FR = 30 ipm (f = 3000) gives one pulse per frame on a pure X move: 5000 pulses/s at W0 = 5 kHz.
    for (f, per_pulse) in [(3000u32, 1.0f64), (1500, 2.0), (300, 10.0), (100, 30.0)] {
        let mut frame = Frame::new(cfg());
        let ticks: Vec<u64> = Sim::new(
            &mut frame,
            [line([1000, 0, 0], f, false)].into_iter(),
            u32::MAX,
            1 << 30,
        )
        .filter(|s| s.pulses.steps != 0)
        .map(|s| s.tick)
        .collect();
        assert_eq!(ticks.len(), 1000);
        let mean = (ticks[999] - ticks[0]) as f64 / 999.0;
        assert!(
            (mean - per_pulse).abs() < 0.01,
            "f {f}: {mean} frames per pulse"
        );
    }
}

#[test]
fn feed_cap_limits_and_holds() {
    let mut frame = Frame::new(cfg());
    let n = Sim::new(
        &mut frame,
        [line([0, 600, 0], 3000, false)].into_iter(),
        0,
        10_000,
    )
    .filter(|s| s.pulses.steps != 0)
    .count();
    assert_eq!(n, 0, "feed cap 0 is a feed hold");
    let mut frame = Frame::new(cfg());
    let last = Sim::new(
        &mut frame,
        [line([0, 600, 0], 3000, false)].into_iter(),
        1500,
        1 << 20,
    )
    .last()
    .unwrap();
    assert!(
        (last.tick as i64 - 1200).abs() <= 2,
        "capped at half feed: {}",
        last.tick
    );
}

#[test]
fn decel_block_slows_exponentially_to_a_fifth() {
    let f = 3000;
    let mut frame = Frame::new(cfg());
    let ticks: Vec<u64> = Sim::new(
        &mut frame,
        [line([5000, 0, 0], f, true)].into_iter(),
        u32::MAX,
        1 << 30,
    )
    .filter(|s| s.pulses.steps != 0)
    .map(|s| s.tick)
    .collect();
    assert_eq!(ticks.len(), 5000);
    // Steady part: one pulse per frame.
    assert_eq!(ticks[1000] - ticks[999], 1);
    // Last pulses: 20 % of the feed, 5 frames per pulse.
    assert_eq!(ticks[4999] - ticks[4998], 5);
    // In between the interval grows smoothly (exponential decay of speed with distance):
    // speed is proportional to the distance left while above the floor.
    let k = Settings::default().decel_gain_q8() as f64 / 256.0; // f per BLU left
    for left in [90usize, 60, 40] {
        let idx = 5000 - left;
        let gap = (ticks[idx + 5] - ticks[idx]) as f64 / 5.0;
        let expect = 3000.0 / (k * left as f64).min(3000.0);
        assert!(
            (gap - expect).abs() / expect < 0.25,
            "left {left}: {gap} vs {expect}"
        );
    }
}

#[test]
fn ptp_runs_at_rapid_rate_with_three_deceleration_steps() {
    let s = Settings::default();
    let block = Block {
        line: 1,
        motion: Motion::Rapid(Rapid {
            steps: [5000, 300, 0],
            signs: 0b001,
        }),
    }
    .seal(&cfg());
    let mut frame = Frame::new(cfg());
    let frames: Vec<_> = Sim::new(&mut frame, [block].into_iter(), u32::MAX, 1 << 30).collect();
    assert!(frames.iter().skip(1).all(|f| f.rate == Rate::Rapid));
    let last = frames.last().unwrap();
    assert_eq!(last.position, [5000, -300, 0]);
    let x: Vec<u64> = frames
        .iter()
        .filter(|f| f.pulses.steps & 1 != 0)
        .map(|f| f.tick)
        .collect();
    // In the middle of the move X pulses every rapid frame: 26 333 pulses/s = 158 ipm.
    assert_eq!(x[2500] - x[2499], 1);
    // Approaching the end the interval is 2, 4, then 8 rapid frames: three steps.
    let gap = |i: usize| x[i + 1] - x[i];
    let [s1, s2, s3] = s.ptp_steps.map(|v| v as usize);
    assert_eq!(gap(5000 - s1 + 10), 2);
    assert_eq!(gap(5000 - s2 + 5), 4);
    assert_eq!(gap(5000 - s3 + 2), 8);
    // Axes are independent: Y (300 pulses) finishes long before X.
    let y_last = frames
        .iter()
        .filter(|f| f.pulses.steps & 2 != 0)
        .map(|f| f.tick)
        .max()
        .unwrap();
    assert!(y_last < x[2000]);
    // Sign lines: X positive, Y negative throughout.
    assert!(frames.iter().all(|f| f.pulses.signs & 0b011 == 0b001));
}

/// The longest line the parser accepts (q = Q_MAX = 2^31, |d_x| = q) pulses on every command from
/// the first one: the remainder sums stay below 2^32 (at q = 3 * 2^30 + 1 they would not, and the
/// first command would give no pulse).
#[test]
fn longest_line_pulses_on_every_command() {
    let q = Q_MAX;
    let b = Block {
        line: 1,
        motion: Motion::Linear(Linear {
            steps: [q, 1, 0],
            signs: 0b011,
            q,
            f: Settings::default().q0,
            decel: false,
            f_floor: 0,
            decel_below: 0,
            ramp: 0,
            dir: [1; 3],
        }),
    };
    let b = b.seal(&cfg());
    let mut frame = Frame::new(cfg());
    // Frame 0 loads, then one command per frame.
    let out: Vec<_> = Sim::new(&mut frame, [b].into_iter(), u32::MAX, 1001).collect();
    assert_eq!(out.len(), 1001);
    assert!(out[1..].iter().all(|f| f.pulses.steps & 1 == 1));
    assert_eq!(out[1000].position[0], 1000);
}

/// Interpolation commands of the lines among `blocks` (q each).
pub(super) fn line_commands(blocks: &[Sealed]) -> u64 {
    blocks
        .iter()
        .map(|b| match b.motion {
            Motion::Linear(l) => l.q as u64,
            _ => 0,
        })
        .sum()
}

/// A chain of lines costs no load frame (issue 6, defect 7): 1000 lines of 10 BLU (or 1 BLU) at
/// FRM take one frame per command plus the first block's load frame, so the path speed is the
/// programmed feed; each line still ends exactly. (Loading in a frame of its own made 10-BLU blocks
/// 10 % and 1-BLU blocks 50 % slow.)
#[test]
fn chained_lines_run_at_the_programmed_feed() {
    for (len, f) in [(10i64, 3000u32), (1, 3000), (10, 1000), (7, 2999)] {
        let d = |k: i64| match k % 3 {
            0 => [len, 0, 0],
            1 => [0, len, 0],
            _ => [-len, -len, 0],
        };
        let blocks: Vec<Sealed> = (0..1000).map(|k| line(d(k), f, false)).collect();
        let commands = line_commands(&blocks);
        let mut frame = Frame::new(cfg());
        let mut ends = Vec::new();
        // `block` counts the blocks done before a frame: when it moves, the frame before ended one.
        let mut last: Option<(u32, [i32; 3])> = None;
        for s in Sim::new(&mut frame, blocks.iter().copied(), u32::MAX, 1 << 30) {
            if let Some((prev, pos)) = last {
                if s.block != prev {
                    ends.push(pos);
                }
            }
            last = Some((s.block, s.position));
        }
        ends.extend(last.map(|l| l.1));
        let frames = frame.blocks_done();
        assert_eq!(frames, 1000);
        // Commands come at W0 f / q0: q0 / f frames each, plus one frame for the first load.
        let ideal = (commands * 3000).div_ceil(f as u64) + 1;
        let ticks = Sim::new(
            &mut Frame::new(cfg()),
            blocks.iter().copied(),
            u32::MAX,
            1 << 30,
        )
        .count() as u64;
        assert!(
            ticks <= ideal + 1,
            "{len} BLU at f {f}: {ticks} frames for {commands} commands (ideal {ideal})"
        );
        // Every block ended on its programmed point.
        let mut p = [0i64; 3];
        for (k, e) in ends.iter().enumerate() {
            let dk = d(k as i64);
            for a in 0..3 {
                p[a] += dk[a];
            }
            assert_eq!(e.map(|v| v as i64), p, "block {k}");
        }
    }
}

#[test]
fn dwell_waits_its_frames() {
    let blocks = [
        Block {
            line: 1,
            motion: Motion::Dwell(Dwell { frames: 500 }),
        }
        .seal(&cfg()),
        line([10, 0, 0], 3000, false),
    ];
    let mut frame = Frame::new(cfg());
    let first = Sim::new(&mut frame, blocks.into_iter(), u32::MAX, 1 << 20)
        .find(|s| s.pulses.steps != 0)
        .unwrap();
    assert!(
        (500..=502).contains(&first.tick),
        "first pulse at {}",
        first.tick
    );
}

#[test]
fn full_circle_returns_to_start_and_counts_blocks() {
    let (b, d) = arc([0, 0], 1000.0, 0.3, std::f64::consts::TAU - 1e-7, 3000);
    let Motion::Arc(c) = b.motion else {
        unreachable!()
    };
    assert_eq!(c.n_targets, 5);
    assert_eq!(d, [0, 0]);
    let mut frame = Frame::new(cfg());
    let n = Sim::new(&mut frame, [b, b].into_iter(), u32::MAX, 1 << 30).count();
    assert_eq!(frame.position(), [0, 0, 0]);
    assert_eq!(frame.blocks_done(), 2);
    assert!(n > 2 * 6000);
}

proptest! {
    #[test]
    fn isqrt_is_floor_sqrt(n in any::<u64>()) {
        let r = isqrt(n) as u128;
        prop_assert!(r * r <= n as u128);
        prop_assert!((r + 1) * (r + 1) > n as u128);
    }
}

/// A helix planned by the parser's arc planner (`gcode::arc::plan`): in `plane`, radius `r` from
/// angle `a0` through `sweep` radians (sign = direction), the third axis moving by `dz`, from
/// centre (0, 0) and third axis 0. Runs it; returns the block, the programmed end (a, b, third),
/// the largest radial distance from the band between the start and end radius, the largest
/// distance across the helix along the third axis (its error at the point's angle times the cosine
/// of the helix angle), and the commands.
fn run_helix(plane: Plane, r: f64, a0: f64, sweep: f64, dz: i32) -> (Arc, [i32; 3], f64, f64, u64) {
    use crate::gcode::arc::{plan, Centre};
    let st = Settings::default();
    let s2 = [(r * a0.cos()).round() as i32, (r * a0.sin()).round() as i32];
    let e2 = [
        (r * (a0 + sweep).cos()).round() as i32,
        (r * (a0 + sweep).sin()).round() as i32,
    ];
    let (ia, ib) = plane.axes();
    let third = 3 - ia - ib;
    let (mut start, mut end) = ([0i32; 3], [0i32; 3]);
    (start[ia], start[ib]) = (s2[0], s2[1]);
    (end[ia], end[ib], end[third]) = (e2[0], e2[1], dz);
    let off = Centre::Offsets([-s2[0] as i64, -s2[1] as i64]);
    let ccw = sweep > 0.0;
    let c = plan(&st, plane, ccw, start, end, off, 3000).expect("plans");
    let b = Block {
        line: 1,
        motion: Motion::Arc(c),
    }
    .seal(&cfg());
    let r0 = ((s2[0] as f64).powi(2) + (s2[1] as f64).powi(2)).sqrt();
    let r1 = ((e2[0] as f64).powi(2) + (e2[1] as f64).powi(2)).sqrt();
    let mut frame = Frame::new(cfg());
    let (mut dev, mut zdev, mut pos, mut commands) = (0.0f64, 0.0f64, [0; 3], 0u64);
    // The swept angle between the lattice ends (the rounded ends are not at a0 and a0 + sweep).
    let mut sweep = (s2[0] as f64 * e2[1] as f64 - s2[1] as f64 * e2[0] as f64)
        .atan2(s2[0] as f64 * e2[0] as f64 + s2[1] as f64 * e2[1] as f64);
    if ccw && sweep <= 0.0 {
        sweep += std::f64::consts::TAU;
    } else if !ccw && sweep >= 0.0 {
        sweep -= std::f64::consts::TAU;
    }
    let plane_len = r0 * sweep.abs();
    let across = plane_len / (plane_len * plane_len + (dz as f64).powi(2)).sqrt();
    let mut turned = 0.0f64;
    let mut last = (s2[1] as f64).atan2(s2[0] as f64);
    for f in Sim::new(&mut frame, [b].into_iter(), u32::MAX, 100_000_000) {
        pos = f.position;
        // One command per frame (f = q0, no ramp) but in the frames that load the block, its
        // segments and end it.
        commands += 1;
        // The frame counts from 0: the point is the start plus its travel.
        let (x, y) = ((s2[0] + pos[ia]) as f64, (s2[1] + pos[ib]) as f64);
        let rr = (x * x + y * y).sqrt();
        dev = dev.max(r0.min(r1) - rr).max(rr - r0.max(r1));
        // The angle swept so far (unwrapped), and the third axis's ideal value there.
        let ang = y.atan2(x);
        let mut d = ang - last;
        if d > std::f64::consts::PI {
            d -= std::f64::consts::TAU;
        } else if d < -std::f64::consts::PI {
            d += std::f64::consts::TAU;
        }
        turned += d;
        last = ang;
        let ideal = dz as f64 * (turned / sweep).clamp(0.0, 1.0);
        // The third axis's error at the point's angle, across the helix: times cos of the helix
        // angle (a steep coil's plane lattice is coarse in angle, not in distance).
        zdev = zdev.max((pos[third] as f64 - ideal).abs() * across);
    }
    commands = commands.saturating_sub(c.n_targets as u64 + 2);
    let mut got = [0; 3];
    (got[0], got[1], got[2]) = (s2[0] + pos[ia], s2[1] + pos[ib], pos[third]);
    assert_eq!(got, [e2[0], e2[1], dz], "end point");
    (c, got, dev, zdev, commands)
}

/// The measured bound of a helix's deviation across the helix along the third axis (BLU), see
/// `run_helix`: 1 BLU (the third axis's rounding and the plane's half BLU along its tangent),
/// plus half the slope (third-axis travel per BLU of plane path: the plane point's angle is on
/// the lattice), plus half a BLU per radius of third-axis travel (the plane's DDA runs on the
/// lattice point's register, up to half a BLU off the circle, so its rate per angle is off by up
/// to 0.5 / R locally, and the third axis, running evenly over the arc, leads or lags by that
/// share of its travel: measured 1.5 BLU for R = 9064 and 23 930 BLU of travel).
fn helix_bound(dz: i32, r: f64, sweep: f64) -> f64 {
    let dz = dz.unsigned_abs() as f64;
    1.0 + 0.5 * dz / (r * sweep.abs()) + 0.5 * dz / r
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Helices in every plane, of any pitch (a shallow ramp to a steep coil): the end point is
    /// exact, the plane's path stays within half a BLU of the circle, the third axis within
    /// [`helix_bound`] of the helix, and the arc takes its length in commands (one BLU of
    /// helical path each) to within 1 % (plus the lattice's share at radii of a few BLU).
    #[test]
    fn helices_end_exact_and_follow_the_helix(
        r in 5.0f64..3000.0, a0 in -7.0f64..7.0, sweep in 0.3f64..6.2, ccw in any::<bool>(),
        dz in -4000i32..4000, plane in 0usize..3,
    ) {
        let plane = [Plane::XY, Plane::ZX, Plane::YZ][plane];
        let sweep = if ccw { sweep } else { -sweep };
        let (c, _, dev, zdev, commands) = run_helix(plane, r, a0, sweep, dz);
        prop_assert!(dev <= ARC_DEVIATION_BOUND, "radial deviation {}", dev);
        prop_assert!(zdev <= helix_bound(dz, r, sweep), "third axis {} BLU off the helix", zdev);
        prop_assert_eq!(c.helix, dz);
        // Within 1 % and two commands, plus the lattice's share: the plane's DDA runs on the
        // lattice point's register, up to half a BLU off the circle, so its count is off by up
        // to 0.5 / R of the length; and its last lattice point may come up to about a BLU of
        // plane path early or late, which the third axis covers at slope BLU per BLU (one pulse
        // per command in its tail). Both matter only for radii of a few BLU.
        let n = c.length as f64;
        let slope = f64::from(dz.unsigned_abs()) / (r * sweep.abs());
        prop_assert!((commands as f64 - n).abs() <= n * (0.01 + 0.5 / r) + 2.0 + slope,
            "{} pulse commands for a length of {}", commands, n);
    }
}
