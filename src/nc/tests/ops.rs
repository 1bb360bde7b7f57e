//! Host tests of the frame's acceleration ramps and the operator's word (host): ramps at the
//! configured acceleration per axis, feed hold and resume in lines, arcs, rapids and dwells, feed
//! and rapid overrides, the AC cap ramped, abort (soft reset). Position exact in every case.
use super::super::block::*;
use super::super::frame::{Frame, FrameConfig};
use super::super::isqrt;
use super::super::operator::{self, RUN};
use crate::settings::Settings;
use std::collections::VecDeque;
use std::vec::Vec;

fn settings() -> Settings {
    Settings::default()
}

fn cfg() -> FrameConfig {
    FrameConfig::from_settings(&settings())
}

fn line(d: [i64; 3], f: u32, decel: bool, cfg: &FrameConfig) -> Sealed {
    let steps = d.map(|v| v.unsigned_abs() as u32);
    let q = isqrt(d.iter().map(|v| (v * v) as u64).sum()).max(1) as u32;
    let signs = (0..3).filter(|&k| d[k] > 0).fold(0u8, |s, k| s | 1 << k);
    let b = Block {
        line: 1,
        motion: Motion::Linear(Linear {
            steps,
            signs,
            q,
            f,
            decel,
            f_floor: 0,
            decel_below: 0,
            ramp: 0,
            dir: [1; 3],
        }),
    };
    b.seal(cfg)
}

fn rapid(d: [i64; 3]) -> Sealed {
    Block {
        line: 1,
        motion: Motion::Rapid(Rapid {
            steps: d.map(|v| v.unsigned_abs() as u32),
            signs: (0..3).filter(|&k| d[k] > 0).fold(0u8, |s, k| s | 1 << k),
        }),
    }
    .seal(&cfg())
}

/// A frame, its queue and a record of every frame's pulses.
struct Rig {
    frame: Frame,
    q: VecDeque<Sealed>,
    /// Per frame: the step bits.
    steps: Vec<u8>,
    /// Pulses per axis with their signs.
    pulses: [i64; 3],
}

impl Rig {
    fn new(cfg: FrameConfig, blocks: &[Sealed]) -> Self {
        Rig {
            frame: Frame::new(cfg),
            q: blocks.iter().copied().collect(),
            steps: Vec::new(),
            pulses: [0; 3],
        }
    }
    /// Runs `n` frames with the AC cap `cap` and the operator word `op`.
    fn run(&mut self, n: usize, cap: u32, op: u32) {
        self.run_plan(n, cap, op, crate::ports::PLAN_ONE);
    }
    /// Runs `n` frames with the AC cap, the operator word and the AC's plan ratio (Q12).
    fn run_plan(&mut self, n: usize, cap: u32, op: u32, ratio: u32) {
        for _ in 0..n {
            let p = self.frame.tick(&mut self.q, (cap, op, ratio));
            for k in 0..3 {
                if p.steps & (1 << k) != 0 {
                    self.pulses[k] += if p.signs & (1 << k) != 0 { 1 } else { -1 };
                }
            }
            self.steps.push(p.steps);
        }
    }
    /// Runs until the queue is empty and the frame idle (at most `max` frames).
    fn finish(&mut self, cap: u32, op: u32, max: usize) {
        let mut n = 0;
        while (!self.q.is_empty() || !self.frame.idle()) && n < max {
            self.run(1, cap, op);
            n += 1;
        }
        assert!(n < max, "did not finish in {max} frames");
    }
    /// Frames with a pulse on any axis, from frame `from` on.
    fn pulsed(&self, from: usize) -> usize {
        self.steps[from..].iter().filter(|&&s| s != 0).count()
    }
}

/// Velocity change per frame of the default acceleration, in feed numbers: a q0 / W0^2.
fn accel_feed_per_frame(a: u32) -> f64 {
    let s = settings();
    a as f64 * s.q0 as f64 / (s.frame_hz as f64 * s.frame_hz as f64)
}

#[test]
fn a_line_starts_at_the_acceleration_and_then_runs_at_its_feed() {
    let s = settings();
    let f = 3000;
    let mut rig = Rig::new(cfg(), &[line([20_000, 0, 0], f, false, &cfg())]);
    rig.finish(u32::MAX, RUN, 1 << 20);
    assert_eq!(rig.pulses, [20_000, 0, 0]);
    // Ramp time f / (a q0 / W0^2) frames, ramp distance v^2 / 2a with v = W0 f / q0 BLU/s.
    let a = s.accel_blu_s2[0];
    let ramp_frames = f as f64 / accel_feed_per_frame(a);
    let v = s.frame_hz as f64 * f as f64 / s.q0 as f64;
    let ramp_blu = v * v / (2.0 * a as f64);
    let in_ramp = rig.steps[..=ramp_frames as usize]
        .iter()
        .filter(|&&x| x != 0)
        .count() as f64;
    assert!(
        (in_ramp - ramp_blu).abs() <= 3.0,
        "{in_ramp} pulses in the {ramp_frames} ramp frames, expected {ramp_blu}"
    );
    // The first pulses come slowly: fewer than a quarter of the frames in the first tenth of the
    // ramp pulse.
    let early = rig.steps[..(ramp_frames / 10.0) as usize]
        .iter()
        .filter(|&&x| x != 0)
        .count();
    assert!(early * 4 < (ramp_frames / 10.0) as usize, "{early}");
    // After the ramp: one pulse per frame (f = q0) to the end.
    let after = ramp_frames as usize + 2;
    assert_eq!(rig.pulsed(after), rig.steps.len() - after);
    // Total: the path plus the time lost in the ramp (half the ramp), plus the load frame.
    let ideal = 20_000.0 + ramp_frames / 2.0 + 1.0;
    assert!(
        (rig.steps.len() as f64 - ideal).abs() <= 3.0,
        "{}",
        rig.steps.len()
    );
}

#[test]
fn each_axis_stays_within_its_own_acceleration() {
    // X may accelerate 4 times as hard as Y: a line mostly along X is limited by Y's share.
    let mut s = settings();
    s.accel_blu_s2 = [200_000, 50_000, 100_000];
    let cfg = FrameConfig::from_settings(&s);
    for d in [
        [3000i64, 4000, 0],
        [4000, 1000, 0],
        [-1000, 0, 0],
        [0, 0, -2000],
    ] {
        let b = line(d, 3000, false, &cfg);
        let mut rig = Rig::new(cfg, &[b]);
        rig.finish(u32::MAX, RUN, 1 << 20);
        assert_eq!(rig.pulses, d);
        // Per axis: velocity from the pulses in windows of 100 frames (20 ms), acceleration
        // between successive windows.
        for k in 0..3 {
            let w = 100;
            let vel: Vec<f64> = rig
                .steps
                .chunks(w)
                .map(|c| c.iter().filter(|&&x| x & (1 << k) != 0).count() as f64)
                .map(|n| n * s.frame_hz as f64 / w as f64)
                .collect();
            if vel.iter().sum::<f64>() < 50.0 {
                continue;
            }
            let dt = w as f64 / s.frame_hz as f64;
            let a_max = vel
                .windows(2)
                .map(|p| (p[1] - p[0]) / dt)
                .fold(0.0f64, f64::max);
            let limit = s.accel_blu_s2[k] as f64;
            assert!(
                a_max <= limit * 1.1,
                "{d:?} axis {k}: {a_max:.0} BLU/s^2 over its limit {limit}"
            );
            // And the limiting axis uses most of its limit (the ramp is not needlessly slow).
            let lim_k = (0..3)
                .filter(|&j| d[j] != 0)
                .min_by(|&i, &j| {
                    let ri = s.accel_blu_s2[i] as f64 / d[i].abs() as f64;
                    let rj = s.accel_blu_s2[j] as f64 / d[j].abs() as f64;
                    ri.partial_cmp(&rj).unwrap()
                })
                .unwrap();
            if k == lim_k {
                assert!(a_max >= limit * 0.7, "{d:?} axis {k}: only {a_max:.0}");
            }
        }
    }
}

#[test]
fn chained_lines_keep_their_speed_at_the_junction() {
    let c = cfg();
    let blocks: Vec<Sealed> = (0..200)
        .map(|k| {
            line(
                if k % 2 == 0 { [10, 0, 0] } else { [10, 1, 0] },
                3000,
                false,
                &c,
            )
        })
        .collect();
    let commands = super::line_commands(&blocks);
    let mut rig = Rig::new(c, &blocks);
    rig.finish(u32::MAX, RUN, 1 << 20);
    let ramp_frames = 3000.0 / accel_feed_per_frame(settings().accel_blu_s2[0]);
    // One ramp at the start, none at the junctions.
    let ideal = commands as f64 + ramp_frames / 2.0 + 1.0;
    assert!(
        (rig.steps.len() as f64) <= ideal + 3.0,
        "{} frames, ideal {ideal}",
        rig.steps.len()
    );
}

#[test]
fn feed_hold_stops_at_the_acceleration_and_resume_ends_exactly() {
    let c = cfg();
    let d = [30_000i64, -12_000, 500];
    let mut rig = Rig::new(c, &[line(d, 3000, false, &c)]);
    rig.run(2000, u32::MAX, RUN);
    let before = rig.steps.len();
    let hold = operator::word(100, 100, true, false);
    rig.run(2000, u32::MAX, hold);
    // Stopped within the ramp time (plus a frame), stays stopped, and says so.
    let ramp_frames = (3000.0 / accel_feed_per_frame(settings().accel_blu_s2[0])) as usize;
    let last_pulse = rig.steps[before..].iter().rposition(|&s| s != 0).unwrap();
    assert!(
        last_pulse <= ramp_frames + 2,
        "last pulse {last_pulse} frames into the hold"
    );
    assert!(rig.frame.stopped());
    // It decelerated: pulses came ever more slowly (no stop from full speed).
    assert!(rig.pulsed(before) > ramp_frames / 4);
    let held_at = rig.pulses;
    rig.run(5000, u32::MAX, hold);
    assert_eq!(rig.pulses, held_at, "nothing moves during the hold");
    assert_eq!(rig.frame.position(), held_at.map(|v| v as i32));
    // Resume: accelerates again and ends on the programmed point.
    rig.finish(u32::MAX, RUN, 1 << 20);
    assert_eq!(rig.pulses, d);
    assert_eq!(rig.frame.blocks_done(), 1);
}

#[test]
fn a_hold_in_a_decelerating_chain_and_a_helix_loses_nothing() {
    let c = cfg();
    let arc = Block {
        line: 2,
        motion: Motion::Arc(Arc {
            plane: Plane::XY,
            ccw: true,
            start: [1000, 0],
            r: 1000,
            // A helix rising 300 BLU: q = R x path / plane, length = q x sweep (see the parser).
            q: 1018,
            helix: 300,
            targets: [[0, 1000], [0, 0], [0, 0], [0, 0], [0, 0]],
            n_targets: 1,
            f: 2000,
            decel: true,
            length: 1599,
            f_floor: 0,
            decel_below: 0,
            ramp: 0,
        }),
    };
    let arc = arc.seal(&c);
    let blocks = [
        line([500, 0, 0], 3000, false, &c),
        line([500, 500, 0], 3000, true, &c),
        arc,
        line([0, 0, -300], 1000, true, &c),
    ];
    // Hold and resume every 333 frames: the holds fall into every kind of frame.
    let mut rig = Rig::new(c, &blocks);
    let hold = operator::word(100, 100, true, false);
    for _ in 0..40 {
        rig.run(333, u32::MAX, RUN);
        rig.run(400, u32::MAX, hold);
    }
    rig.finish(u32::MAX, RUN, 1 << 20);
    // X: 500 + 500 - 1000 (the helix from (R, 0) to (0, R)), Y: 500 + 1000, Z: 300 - 300.
    assert_eq!(rig.pulses, [0, 1500, 0]);
    assert_eq!(rig.frame.blocks_done(), 4);
}

#[test]
fn overrides_scale_the_feed_and_the_ac_cap_is_ramped() {
    let c = cfg();
    // 50 %: half the pulse rate once the ramp is over; 200 % of f 1000: twice.
    for (pct, f, per_frame) in [
        (50u8, 3000u32, 0.5f64),
        (200, 1000, 2.0 / 3.0),
        (10, 3000, 0.1),
    ] {
        let mut rig = Rig::new(c, &[line([40_000, 0, 0], f, false, &c)]);
        rig.run(3000, u32::MAX, operator::word(pct, 100, false, false));
        let rate = rig.pulsed(1000) as f64 / 2000.0;
        // The factor is rounded to 1/256.
        assert!(
            (rate - per_frame).abs() < 0.005,
            "{pct} %: {rate} pulses per frame"
        );
    }
    // The AC's cap falls from none to a third: the velocity follows at the acceleration.
    let mut rig = Rig::new(c, &[line([40_000, 0, 0], 3000, false, &c)]);
    rig.run(1000, u32::MAX, RUN);
    rig.run(1000, 1000, RUN);
    let ramp_frames = (2000.0 / accel_feed_per_frame(settings().accel_blu_s2[0])) as usize;
    // During the ramp down more pulses than at the capped rate, after it exactly that rate.
    let during = rig.steps[1000..1000 + ramp_frames]
        .iter()
        .filter(|&&s| s != 0)
        .count();
    assert!(
        during as f64 > ramp_frames as f64 * 0.6,
        "{during} in {ramp_frames}"
    );
    let after = rig.pulsed(1000 + ramp_frames + 2) as f64 / (1000 - ramp_frames - 2) as f64;
    assert!((after - 1.0 / 3.0).abs() < 0.01, "{after}");
}

/// Under the plan (`FeedCeiling::Plan`) the frame feeds every block at its own programmed feed
/// times the AC's ratio k, so a change of the plan's feed at a block boundary takes effect in
/// the frame itself (the feed-forward), and the cap still binds.
#[test]
fn the_plan_ratio_scales_every_blocks_feed_and_the_cap_still_binds() {
    let c = cfg();
    // Two lines, the plan's feeds 3000 and 1500, k = 0.75: 0.75 and 0.375 pulses per frame.
    let blocks = [
        line([30_000, 0, 0], 3000, false, &c),
        line([30_000, 0, 0], 1500, false, &c),
    ];
    let mut rig = Rig::new(c, &blocks);
    let mut n = 0;
    while (!rig.q.is_empty() || !rig.frame.idle()) && n < 200_000 {
        rig.run_plan(1, u32::MAX, RUN, 3072);
        n += 1;
    }
    assert_eq!(rig.pulses, [60_000, 0, 0], "every pulse, whatever k");
    let rate = |r: std::ops::Range<usize>| {
        let len = r.len() as f64;
        rig.steps[r].iter().filter(|&&s| s != 0).count() as f64 / len
    };
    let first = rate(1000..11_000);
    assert!((first - 0.75).abs() < 0.005, "first block: {first}");
    let second = rate(n - 11_000..n - 1000);
    assert!((second - 0.375).abs() < 0.005, "second block: {second}");
    // k = 1 is the programmed feed exactly; a cap below f x k binds.
    for (ratio, cap, per_frame) in [
        (4096u32, u32::MAX, 1.0f64),
        (4096, 1000, 1.0 / 3.0),
        (2048, 1000, 1.0 / 3.0),
        (1024, 1000, 0.25),
    ] {
        let mut rig = Rig::new(c, &[line([40_000, 0, 0], 3000, false, &c)]);
        rig.run_plan(3000, cap, RUN, ratio);
        let rate = rig.pulsed(1000) as f64 / 2000.0;
        assert!(
            (rate - per_frame).abs() < 0.005,
            "k {ratio}, cap {cap}: {rate}"
        );
    }
}

#[test]
fn a_rapid_holds_down_its_ladder_and_the_rapid_override_slows_it() {
    let c = cfg();
    let s1 = settings().ptp_steps[0] as i64;
    let d = [20_000i64, 5_000, -3_000];
    let mut rig = Rig::new(c, &[rapid(d)]);
    rig.run(5000, u32::MAX, RUN);
    let before = rig.steps.len();
    let at = rig.pulses;
    let hold = operator::word(100, 100, true, false);
    rig.run(5000, u32::MAX, hold);
    assert!(rig.frame.stopped());
    // It stopped after fewer pulses than the ladder covers, not at once.
    let moved = (rig.pulses[0] - at[0]).abs();
    // As many pulses as the ladder at a rapid's end takes (s1), not more, and not a stop at once.
    assert!(
        moved > s1 / 2 && moved <= s1 + 1,
        "X moved {moved} in the hold"
    );
    let last = rig.steps[before..].iter().rposition(|&x| x != 0).unwrap();
    let held = rig.pulses;
    rig.run(1000, u32::MAX, hold);
    assert_eq!(rig.pulses, held);
    assert!(last < 2000);
    // Rapid override 25 %: a quarter of the pulse rate on a long axis.
    let start = rig.steps.len();
    rig.run(4000, u32::MAX, operator::word(100, 25, false, false));
    let x_rate = rig.steps[start + 2000..]
        .iter()
        .filter(|&&x| x & 1 != 0)
        .count() as f64
        / 2000.0;
    assert!((x_rate - 0.25).abs() < 0.01, "{x_rate}");
    rig.finish(u32::MAX, RUN, 1 << 22);
    assert_eq!(rig.pulses, d);
}

/// An AC hold (a cap of 0: overload, sensor fault, breakage, chatter), with the word the loaders
/// publish for it (`operator::with_ac_hold`), stops a running rapid down the same ladder as the
/// operator's hold, pulse for pulse, and keeps a rapid from starting; the rapid ends exactly once
/// the cap is back. Before, a rapid under an AC hold ran to its end (a rapid plunge into
/// unexpected material went on to full depth). The frame itself reads nothing more: its budget
/// (the F446's rapid frame grew by 9 instructions when it loaded the cap).
#[test]
fn an_ac_hold_stops_a_rapid_as_the_operators_hold_does() {
    let d = [20_000i64, 5_000, -3_000];
    let hold = operator::word(100, 100, true, false);
    let mut by_operator = Rig::new(cfg(), &[rapid(d)]);
    by_operator.run(3000, u32::MAX, RUN);
    by_operator.run(5000, u32::MAX, hold);
    // The AC's hold: a cap of 0, and the word the loaders publish with it.
    let ac = operator::with_ac_hold(RUN, 0);
    let mut by_ac = Rig::new(cfg(), &[rapid(d)]);
    by_ac.run(3000, u32::MAX, RUN);
    let at = by_ac.pulses;
    by_ac.run(5000, 0, ac);
    assert!(by_ac.frame.stopped());
    assert_ne!(
        by_ac.pulses, d,
        "the rapid ran to its end under the AC's hold"
    );
    assert!(by_ac.pulses[0] - at[0] <= settings().ptp_steps[0] as i64 + 1);
    assert_eq!(by_ac.steps, by_operator.steps, "not the operator's ladder");
    let held = by_ac.pulses;
    by_ac.run(2000, 0, ac);
    assert_eq!(by_ac.pulses, held, "nothing moves in the hold");
    by_ac.finish(u32::MAX, RUN, 1 << 22);
    assert_eq!(by_ac.pulses, d);
    // Under a cap of 0 a queued rapid does not start; it runs once the cap is back.
    let mut rig = Rig::new(cfg(), &[rapid(d)]);
    rig.run(3000, 0, ac);
    assert_eq!(rig.pulses, [0; 3]);
    rig.finish(u32::MAX, RUN, 1 << 22);
    assert_eq!(rig.pulses, d);
}

#[test]
fn a_hold_stops_a_dwell_and_keeps_the_next_block_from_starting() {
    let c = cfg();
    let blocks = [
        Block {
            line: 1,
            motion: Motion::Dwell(Dwell { frames: 1000 }),
        }
        .seal(&c),
        line([100, 0, 0], 3000, false, &c),
    ];
    let mut rig = Rig::new(c, &blocks);
    let hold = operator::word(100, 100, true, false);
    rig.run(500, u32::MAX, RUN);
    rig.run(3000, u32::MAX, hold);
    rig.run(400, u32::MAX, RUN);
    // 500 + 400 frames of the dwell's 1000 have run: nothing moved yet.
    assert_eq!(rig.pulses, [0; 3]);
    rig.run(300, u32::MAX, RUN);
    assert!(rig.pulses[0] > 0);
    // A hold while idle: the next block does not start.
    let mut rig = Rig::new(c, &[line([100, 0, 0], 3000, false, &c)]);
    rig.run(3000, u32::MAX, hold);
    assert_eq!(rig.pulses, [0; 3]);
    rig.finish(u32::MAX, RUN, 100_000);
    assert_eq!(rig.pulses, [100, 0, 0]);
}

#[test]
fn abort_stops_at_once_and_drops_the_queue_keeping_the_position() {
    let c = cfg();
    let blocks = [
        line([5000, 0, 0], 3000, false, &c),
        rapid([0, 3000, 0]),
        line([0, 0, 100], 3000, false, &c),
    ];
    let mut rig = Rig::new(c, &blocks);
    rig.run(1000, u32::MAX, RUN);
    let abort = operator::word(100, 100, false, true);
    rig.run(10, u32::MAX, abort);
    assert!(rig.frame.idle());
    assert!(rig.q.is_empty(), "one block dropped per frame");
    assert_eq!(rig.pulsed(1000), 0, "no pulse after the abort");
    assert_eq!(rig.frame.position(), rig.pulses.map(|v| v as i32));
    assert!(rig.pulses[0] > 0 && rig.pulses[0] < 5000);
    assert_eq!(rig.frame.blocks_done(), 0);
    // A new block after the abort starts from a stop.
    rig.q.push_back(line([-100, 0, 0], 3000, false, &c));
    let x = rig.pulses[0];
    rig.finish(u32::MAX, RUN, 100_000);
    assert_eq!(rig.pulses[0], x - 100);
}

/// A full circle of radius R as one sealed block in the XY plane, starting at (R, 0).
fn circle(r: i32, f: u32, cfg: &FrameConfig) -> Sealed {
    let b = Block {
        line: 1,
        motion: Motion::Arc(Arc {
            plane: Plane::XY,
            ccw: true,
            start: [r, 0],
            r: r as u32,
            q: r as u32,
            helix: 0,
            targets: [[0, r], [-r, 0], [0, -r], [r, 0], [r, 0]],
            n_targets: 4,
            f,
            decel: false,
            length: (std::f64::consts::TAU * r as f64).round() as u32,
            f_floor: 0,
            decel_below: 0,
            ramp: 0,
        }),
    };
    b.seal(cfg)
}

/// An arc's feed is capped so that its centripetal acceleration v^2 / R stays within the axes'
/// limit: a small circle at F30 runs at sqrt(a R), and the axes' accelerations measured from the
/// pulses stay within the limit; a large circle keeps its feed. (Before, the ramp limited only
/// the path's speed changes, and a 50-BLU circle at F30 asked 5 times the limit of each axis.)
#[test]
fn a_small_arc_runs_at_the_feed_its_centripetal_acceleration_allows() {
    let s = settings();
    let c = cfg();
    let a = s.accel_blu_s2[0] as f64;
    let w0 = s.frame_hz as f64;
    let q0 = s.q0 as f64;
    for (r, capped) in [(50i32, true), (5000, false)] {
        let b = circle(r, 3000, &c);
        let Motion::Arc(arc) = b.motion else {
            unreachable!()
        };
        let v_max = (a * r as f64).sqrt();
        let f_max = v_max * q0 / w0;
        if capped {
            assert!(
                (arc.f as f64 - f_max).abs() <= 1.0,
                "R {r}: f {} for sqrt(a R) = {f_max}",
                arc.f
            );
        } else {
            assert_eq!(arc.f, 3000, "R {r}");
            continue;
        }
        let mut rig = Rig::new(c, &[b]);
        rig.finish(u32::MAX, RUN, 1 << 22);
        assert_eq!(rig.pulses, [0, 0, 0]);
        // Axis velocity per 2 ms window and its change between windows: within the limit (with
        // the pulse quantisation of a window: one pulse in 2 ms is 500 BLU/s).
        let w = 10;
        let dt = w as f64 / w0;
        for k in 0..2 {
            let vel: Vec<f64> = rig
                .steps
                .chunks(w)
                .map(|ch| ch.iter().filter(|&&x| x & (1 << k) != 0).count() as f64 / dt)
                .collect();
            let smooth: Vec<f64> = vel
                .windows(5)
                .map(|v| v.iter().sum::<f64>() / 5.0)
                .collect();
            let a_max = smooth
                .windows(2)
                .map(|p| (p[1] - p[0]).abs() / dt)
                .fold(0.0f64, f64::max);
            assert!(
                a_max <= a * 1.5,
                "R {r} axis {k}: {a_max:.0} BLU/s^2 against {a}"
            );
        }
    }
}
