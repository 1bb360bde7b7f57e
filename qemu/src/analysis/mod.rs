//! The capture analyser (host): reads the pin events of any capture (ours from QEMU, or a VCD exported
//! from PulseView after a real logic-analyser capture) and checks them against the program: end point
//! of every block, deviation from the ideal line or arc, feed per block against the programmed feed,
//! minimum pulse width and sign setup time, and pulse-for-pulse equality with the host core.
pub mod sigrok;
pub mod vcd;

use crate::analysis::vcd::AXES;
use anyhow::Result;
use millac::gcode::lines::Lines;
use millac::gcode::tape::{Tape, TapeError};
use millac::gcode::Parsed;
use millac::nc::{sim::Sim, Frame, FrameConfig, Motion, Sealed};
use millac::Settings;
use std::collections::VecDeque;

/// A block of the program with its programmed start and end (machine BLU).
#[derive(Clone, Copy, Debug)]
pub struct ProgBlock {
    pub block: Sealed,
    pub start: [i32; 3],
    pub end: [i32; 3],
    /// Pulses per axis the block takes (position counters, summed over arc segments).
    pub pulses: [u64; 3],
}

/// Parses a whole program with the same tape reader as the firmware.
pub fn load_program(text: &str, settings: &Settings) -> Result<Vec<ProgBlock>, TapeError> {
    let mut blocks = Vec::new();
    let mut tape = Tape::new(*settings);
    let mut push = |b: Sealed| blocks.push(b);
    tape.feed(text.as_bytes(), &mut push)?;
    tape.finish(&mut push)?;
    Ok(program_of_blocks(blocks))
}

/// A line [`read_lines`] refused (`message` as `run`'s summary.json words it: `line N: why`).
#[derive(Clone, Debug)]
pub struct Refusal {
    pub line: u32,
    pub message: String,
}

/// A tool change (M6) a program asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolChange {
    pub line: u32,
    /// The tool to fit (0: none).
    pub tool: u8,
    /// How many blocks run before it.
    pub after_blocks: usize,
    /// The tool's entry in the table as the program left it at that line (G10 L1 sets it).
    pub entry: Option<millac::gcode::Tool>,
}

/// What [`read_lines`] read: the lines read, the accepted blocks in order, the refused lines, the
/// tool changes, and the work coordinate origin (picometres of machine coordinates) from each
/// line on where it changes (the first entry is line 0: the machine origin).
#[derive(Debug)]
pub struct Reading {
    pub lines: u32,
    pub blocks: Vec<Sealed>,
    pub refused: Vec<Refusal>,
    pub tool_changes: Vec<ToolChange>,
    pub origins: Vec<(u32, [i64; 3])>,
    /// The spindle speed (rpm) the parser holds from each line on where it changes.
    pub spindle: Vec<(u32, u32)>,
}

impl Reading {
    /// The work coordinate origin (picometres) in force for a block of line `line`.
    pub fn origin_of_line(&self, line: u32) -> [i64; 3] {
        let i = self.origins.partition_point(|(l, _)| *l <= line);
        self.origins
            .get(i.saturating_sub(1))
            .map_or([0; 3], |o| o.1)
    }
}

/// Reads `text` as the firmware's loader does, line by line (the firmware's line splitter and
/// tape), going on after a refused line (the parser as it was before it), so every refusal is
/// listed; the program's end (M2/M30) ends the reading. `check` and the rs274 comparison read
/// programs with it.
pub fn read_lines(text: &[u8], settings: &Settings) -> Reading {
    read_lines_with(text, settings, &millac::gcode::tools::ToolTable::default())
}

/// [`read_lines`] on a machine whose tool table is `tools` (as the settings record restores it
/// at start: the operator's `$T` lines), as the host's multi-tool runs read a program.
pub fn read_lines_with(
    text: &[u8],
    settings: &Settings,
    tools: &millac::gcode::tools::ToolTable,
) -> Reading {
    let mut tape = Tape::new(*settings);
    tape.set_work(&millac::gcode::Work {
        tools: *tools,
        ..Default::default()
    });
    let mut spindle = Vec::new();
    let mut blocks = Vec::new();
    let mut refused = Vec::new();
    let mut tool_changes = Vec::new();
    let mut origins = vec![(0, [0i64; 3])];
    let mut ended = false;
    let mut lines = Lines::new();
    let mut line = |n: u32, l: Result<&str, millac::gcode::lines::LineError>| -> bool {
        match l {
            Err(e) => refused.push(Refusal {
                line: n,
                message: format!("line {n}: {}", e.message()),
            }),
            Ok(l) => {
                // The program's end and its tool changes: parsed on a copy to know what the line is.
                let mut probe = tape.parser().clone();
                let parsed = probe.line(n, l);
                ended = matches!(parsed, Ok(Parsed::End));
                if let Ok(Parsed::Stop(millac::gcode::Stop::ToolChange { tool })) = parsed {
                    tool_changes.push(ToolChange {
                        line: n,
                        tool,
                        after_blocks: blocks.len() + usize::from(tape.holds_a_block()),
                        entry: probe.tools().get(tool as u32).copied(),
                    });
                }
                match tape.line(n, l, |b| blocks.push(b)) {
                    Err(e) => refused.push(Refusal {
                        line: e.line(),
                        message: e.to_string(),
                    }),
                    Ok(()) => {
                        let o = tape.parser().work_origin_pm();
                        if origins.last().map(|l| l.1) != Some(o) {
                            origins.push((n, o));
                        }
                        let rpm = tape.parser().spindle_rpm();
                        if spindle.last().map_or(0, |l: &(u32, u32)| l.1) != rpm {
                            spindle.push((n, rpm));
                        }
                    }
                }
            }
        }
        !ended
    };
    if lines.feed(text, &mut line) {
        lines.finish(&mut line);
    }
    tape.flush(|b| blocks.push(b));
    Reading {
        lines: lines.line_no(),
        blocks,
        refused,
        tool_changes,
        origins,
        spindle,
    }
}

/// The blocks in the order the frame runs them, each with its start, end and pulses, from the
/// machine origin (a program's, or a serial session's, see `serve::replay`).
pub fn program_of_blocks(blocks: Vec<Sealed>) -> Vec<ProgBlock> {
    let mut pos = [0i32; 3];
    blocks
        .into_iter()
        .map(|block| {
            let start = pos;
            let mut pulses = [0u64; 3];
            match block.motion {
                Motion::Rapid(m) => {
                    for k in 0..3 {
                        let d = m.steps[k] as i32;
                        pos[k] += if m.signs & (1 << k) != 0 { d } else { -d };
                        pulses[k] = m.steps[k] as u64;
                    }
                }
                Motion::Linear(m) => {
                    for k in 0..3 {
                        let d = m.steps[k] as i32;
                        pos[k] += if m.signs & (1 << k) != 0 { d } else { -d };
                        pulses[k] = m.steps[k] as u64;
                    }
                }
                Motion::Arc(c) => {
                    let (a, b) = c.plane.axes();
                    let mut p = c.start;
                    for t in c.targets.iter().take(c.n_targets as usize) {
                        pulses[a] += (t[0] - p[0]).unsigned_abs() as u64;
                        pulses[b] += (t[1] - p[1]).unsigned_abs() as u64;
                        p = *t;
                    }
                    pos[a] += p[0] - c.start[0];
                    pos[b] += p[1] - c.start[1];
                    pos[3 - a - b] += c.helix;
                    pulses[3 - a - b] = c.helix.unsigned_abs() as u64;
                }
                Motion::Dwell(_) => {}
            }
            ProgBlock {
                block,
                start,
                end: pos,
                pulses,
            }
        })
        .collect()
}

/// The spindle speed the program sets (its last S word), 0 when it sets none.
pub fn spindle_rpm(text: &str, settings: &Settings) -> u32 {
    let mut tape = Tape::new(*settings);
    let _ = tape.feed(text.as_bytes(), |_| {});
    let _ = tape.finish(|_| {});
    tape.parser().spindle_rpm()
}

/// One rising PULSE edge: time, axis, direction (+1/-1 from the SIGN line at the edge).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Edge {
    pub t_ns: u64,
    pub axis: usize,
    pub dir: i8,
}

/// Rising edges in time order (axes in X, Y, Z order at equal times), plus pulse timing minima.
pub struct Edges {
    pub edges: Vec<Edge>,
    /// (time, step mask, sign bits) of every pin write that raised at least one PULSE line.
    pub groups: Vec<(u64, u8, u8)>,
    pub min_pulse_width_ns: Option<u64>,
    pub min_sign_setup_ns: Option<u64>,
}

/// Extracts edges and timing from pin events (port B byte layout, see [`crate::analysis::vcd::WIRES`]).
pub fn edges(initial: u8, events: &[(u64, u8)]) -> Edges {
    let mut prev = initial;
    let mut rise: [Option<u64>; 3] = [None; 3];
    let mut sign_change: [Option<u64>; 3] = [None; 3];
    let (mut width, mut setup): (Option<u64>, Option<u64>) = (None, None);
    let mut out = Vec::new();
    let mut groups = Vec::new();
    for &(t, pins) in events {
        let mut mask = 0u8;
        for (k, &(step, sign)) in AXES.iter().enumerate() {
            let (s0, s1) = (prev >> step & 1, pins >> step & 1);
            if (prev ^ pins) >> sign & 1 != 0 {
                sign_change[k] = Some(t);
            }
            if s0 == 0 && s1 == 1 {
                mask |= 1 << k;
                rise[k] = Some(t);
                if let Some(c) = sign_change[k] {
                    setup = Some(setup.map_or(t - c, |m: u64| m.min(t - c)));
                }
                let dir = if pins >> sign & 1 != 0 { 1 } else { -1 };
                out.push(Edge {
                    t_ns: t,
                    axis: k,
                    dir,
                });
            } else if s0 == 1 && s1 == 0 {
                if let Some(r) = rise[k].take() {
                    width = Some(width.map_or(t - r, |m: u64| m.min(t - r)));
                }
            }
        }
        if mask != 0 {
            let signs = (pins >> 3) & 0b111;
            groups.push((t, mask, signs));
        }
        prev = pins;
    }
    Edges {
        edges: out,
        groups,
        min_pulse_width_ns: width,
        min_sign_setup_ns: setup,
    }
}

/// The frame of every edge (consecutive numbers from 0). A frame raises its PULSE lines in one
/// pin store, so in a QEMU capture its edges share one instant; a real board or logic analyser
/// may show them slightly apart. An edge therefore joins the frame of the edge before it when it
/// rises less than `window_ns` after that frame's first edge and its axis has not pulsed in that
/// frame yet (an axis pulses at most once per frame).
pub fn frame_of_edges(edges: &[Edge], window_ns: u64) -> Vec<usize> {
    let mut out = Vec::with_capacity(edges.len());
    let (mut frame, mut start, mut axes) = (0usize, 0u64, 0u8);
    for (i, e) in edges.iter().enumerate() {
        let joins = i > 0 && e.t_ns - start < window_ns && axes & (1 << e.axis) == 0;
        if joins {
            axes |= 1 << e.axis;
        } else {
            if i > 0 {
                frame += 1;
            }
            start = e.t_ns;
            axes = 1 << e.axis;
        }
        out.push(frame);
    }
    out
}

/// The window of [`frame_of_edges`] for `settings`: half the shortest (rapid) frame period.
pub fn frame_window_ns(settings: &Settings) -> u64 {
    500_000_000 / u64::from(settings.frame_hz.max(settings.rapid_hz).max(1))
}

/// Per-block result.
#[derive(Clone, Debug)]
pub struct BlockReport {
    pub line: u32,
    pub kind: &'static str,
    pub end_exact: bool,
    pub max_deviation_blu: f64,
    /// Programmed and measured feed (ipm or mm/min, the program's BLU unit per minute scaled), if
    /// the block is long enough to measure.
    pub feed: Option<(f64, f64)>,
    pub t_start_ns: u64,
    pub t_end_ns: u64,
    /// The block got all its pulses (false only for the block a hold stopped, see
    /// [`analyse_until`]); `end_exact` counts only for completed blocks.
    pub completed: bool,
}

/// The whole analysis.
#[derive(Clone, Debug)]
pub struct Report {
    pub blocks: Vec<BlockReport>,
    pub final_position: [i64; 3],
    pub programmed_end: [i32; 3],
    pub machining_time_s: f64,
    pub max_deviation_blu: f64,
    pub max_feed_error_pct: f64,
    pub min_pulse_width_ns: Option<u64>,
    pub min_sign_setup_ns: Option<u64>,
    /// The capture's pulses equal the host core's, frame by frame (None: not compared).
    pub pulses_match_host: Option<bool>,
    /// Every edge was assigned to a block and every block got exactly its pulses.
    pub counts_match: bool,
}

impl Report {
    /// Every edge went to a block that ran, every completed block got exactly its pulses and
    /// ended on its programmed point (a block a hold stopped is not checked for its end).
    pub fn end_points_exact(&self) -> bool {
        self.counts_match
            && self
                .blocks
                .iter()
                .filter(|b| b.completed)
                .all(|b| b.end_exact)
    }
}

/// Shortest block path (BLU) on which a feed is measured: shorter blocks are dominated by the
/// quantisation of the first and last pulse time.
pub const FEED_MIN_PATH_BLU: f64 = 200.0;

/// Analyses the pin events against the program (a run that completed every block).
pub fn analyse(
    prog: &[ProgBlock],
    settings: &Settings,
    initial: u8,
    events: &[(u64, u8)],
) -> Report {
    analyse_until(prog, settings, initial, events, prog.len())
}

/// Analyses a run that stopped after `done` completed blocks (a hold): blocks before `done` must
/// get exactly their pulses; block `done`, the one running when the run stopped, takes the
/// pulses that remain (any part of its own) and is reported with `completed` false unless it got
/// them all; blocks after it never ran and are not reported. `done` >= the program's length is
/// [`analyse`].
pub fn analyse_until(
    prog: &[ProgBlock],
    settings: &Settings,
    initial: u8,
    events: &[(u64, u8)],
    done: usize,
) -> Report {
    let e = edges(initial, events);
    let frames = frame_of_edges(&e.edges, frame_window_ns(settings));
    let mut pos = [0i64; 3];
    let mut reports = Vec::new();
    let mut it = e.edges.iter().zip(frames).peekable();
    let mut counts_match = true;
    let blu_per_unit = settings.blu.per_inch().0 as f64 / settings.blu.per_inch().1 as f64;
    let frm_ipm = settings.frame_hz as f64 * 60.0 / blu_per_unit;
    let k_decel = settings.decel_gain_q8() as f64 / 256.0;
    for (i, pb) in prog.iter().enumerate().take(done.saturating_add(1)) {
        let mut left = pb.pulses;
        // The position after every frame (the deviation is scored per frame, as the host core's:
        // within a frame the axes' pulses are simultaneous).
        let mut pts: Vec<(u64, [i64; 3])> = Vec::new();
        let mut last_frame = None;
        while left.iter().any(|&n| n > 0) {
            let Some((edge, frame)) = it.next_if(|(ed, _)| left[ed.axis] > 0) else {
                // Only the block a hold stopped may end short.
                counts_match &= i == done;
                break;
            };
            left[edge.axis] -= 1;
            pos[edge.axis] += edge.dir as i64;
            match pts.last_mut() {
                Some(p) if last_frame == Some(frame) => *p = (edge.t_ns, pos),
                _ => pts.push((edge.t_ns, pos)),
            }
            last_frame = Some(frame);
        }
        let end_exact = pos == pb.end.map(|v| v as i64);
        let (kind, dev, feed) = measure(pb, &pts, blu_per_unit, frm_ipm, k_decel, settings);
        reports.push(BlockReport {
            line: pb.block.line,
            kind,
            end_exact,
            max_deviation_blu: dev,
            feed,
            t_start_ns: pts.first().map_or(0, |p| p.0),
            t_end_ns: pts.last().map_or(0, |p| p.0),
            completed: left.iter().all(|&n| n == 0),
        });
    }
    if it.next().is_some() {
        counts_match = false;
    }
    let first = e.edges.first().map_or(0, |x| x.t_ns);
    let last = e.edges.last().map_or(0, |x| x.t_ns);
    let max_feed_error_pct = reports
        .iter()
        .filter_map(|r| r.feed)
        .map(|(p, m)| ((m - p) / p * 100.0).abs())
        .fold(0.0, f64::max);
    Report {
        max_deviation_blu: reports
            .iter()
            .map(|r| r.max_deviation_blu)
            .fold(0.0, f64::max),
        blocks: reports,
        final_position: pos,
        programmed_end: prog.last().map_or([0; 3], |b| b.end),
        machining_time_s: (last - first) as f64 * 1e-9,
        max_feed_error_pct,
        min_pulse_width_ns: e.min_pulse_width_ns,
        min_sign_setup_ns: e.min_sign_setup_ns,
        pulses_match_host: None,
        counts_match,
    }
}

/// Deviation and feed of one block from its pulse positions.
fn measure(
    pb: &ProgBlock,
    pts: &[(u64, [i64; 3])],
    blu_per_unit: f64,
    frm_ipm: f64,
    k_decel: f64,
    settings: &Settings,
) -> (&'static str, f64, Option<(f64, f64)>) {
    let q0 = settings.q0;
    // The acceleration head: the path a ramp from a stop to feed number f takes at the block's
    // ramp (Q8 feed numbers per frame): v = W0 f / q0 BLU/s, a = ramp W0^2 / (256 q0) BLU/s^2,
    // v^2 / 2a BLU. Left out of the feed window like the deceleration tail (a chained line that
    // starts at speed loses a little of its window, nothing else).
    let head = |f: u32, ramp: u32| {
        let w0 = settings.frame_hz as f64;
        let v = w0 * f as f64 / q0 as f64;
        let a = ramp.max(1) as f64 * w0 * w0 / (256.0 * q0 as f64);
        v * v / (2.0 * a) + 2.0
    };
    let s = pb.start.map(|v| v as f64);
    let e = pb.end.map(|v| v as f64);
    let f_of = |f: u32| f as f64 * frm_ipm / q0 as f64;
    // BLU over ns -> units per minute (FRM = W0 * 60 / BLU-per-unit at one BLU per frame).
    let per_min =
        |path_blu: f64, dt_ns: u64| path_blu / (dt_ns as f64 * 1e-9) * 60.0 / blu_per_unit;
    match pb.block.motion {
        Motion::Rapid(_) => ("rapid", 0.0, None),
        Motion::Dwell(_) => ("dwell", 0.0, None),
        Motion::Linear(l) => {
            let d = [e[0] - s[0], e[1] - s[1], e[2] - s[2]];
            let l2 = d.iter().map(|v| v * v).sum::<f64>();
            let len = l2.sqrt();
            let mut dev: f64 = 0.0;
            for (_, p) in pts {
                let v = [p[0] as f64 - s[0], p[1] as f64 - s[1], p[2] as f64 - s[2]];
                let t = (v.iter().zip(&d).map(|(a, b)| a * b).sum::<f64>() / l2).clamp(0.0, 1.0);
                let r2: f64 = v.iter().zip(&d).map(|(a, b)| (a - t * b).powi(2)).sum();
                dev = dev.max(r2.sqrt());
            }
            // Feed window: leave out the deceleration tail of a flagged block.
            let tail = if l.decel {
                l.f as f64 / k_decel + 2.0
            } else {
                0.0
            };
            let dist_left =
                |p: &[i64; 3]| ((0..3).map(|k| (e[k] - p[k] as f64).powi(2)).sum::<f64>()).sqrt();
            let from_start =
                |p: &[i64; 3]| ((0..3).map(|k| (p[k] as f64 - s[k]).powi(2)).sum::<f64>()).sqrt();
            let head = head(l.f, l.ramp);
            let win: Vec<_> = pts
                .iter()
                .filter(|(_, p)| dist_left(p) >= tail && from_start(p) >= head)
                .collect();
            let feed = match (win.first(), win.last()) {
                (Some(a), Some(b)) if len >= FEED_MIN_PATH_BLU && b.0 > a.0 => {
                    let path = ((0..3)
                        .map(|k| ((b.1[k] - a.1[k]) as f64).powi(2))
                        .sum::<f64>())
                    .sqrt();
                    (path >= FEED_MIN_PATH_BLU).then(|| (f_of(l.f), per_min(path, b.0 - a.0)))
                }
                _ => None,
            };
            ("line", dev, feed)
        }
        Motion::Arc(c) => {
            let (a, b) = c.plane.axes();
            let centre = [s[a] - c.start[0] as f64, s[b] - c.start[1] as f64];
            let last = c.targets[(c.n_targets as usize).saturating_sub(1)];
            let r0 = (c.start[0] as f64).hypot(c.start[1] as f64);
            let r1 = (last[0] as f64).hypot(last[1] as f64);
            let (lo, hi) = (r0.min(r1), r0.max(r1));
            let mut dev: f64 = 0.0;
            let mut arc_len = Vec::with_capacity(pts.len());
            let mut acc = 0.0;
            let mut prev_ang: Option<f64> = None;
            for (_, p) in pts {
                let (x, y) = (p[a] as f64 - centre[0], p[b] as f64 - centre[1]);
                let r = x.hypot(y);
                dev = dev.max(lo - r).max(r - hi);
                let ang = y.atan2(x);
                if let Some(pa) = prev_ang {
                    let mut d = ang - pa;
                    if d > std::f64::consts::PI {
                        d -= std::f64::consts::TAU;
                    } else if d < -std::f64::consts::PI {
                        d += std::f64::consts::TAU;
                    }
                    acc += d.abs() * r0;
                }
                prev_ang = Some(ang);
                arc_len.push(acc);
            }
            // A helix's path is longer than its plane's by sqrt(1 + (helix / plane)^2).
            if c.helix != 0 && acc > 0.0 {
                let scale = (acc * acc + (c.helix as f64).powi(2)).sqrt() / acc;
                arc_len.iter_mut().for_each(|l| *l *= scale);
                acc *= scale;
            }
            let total = acc;
            let tail = if c.decel {
                c.f as f64 / k_decel + 2.0
            } else {
                0.0
            };
            let head = head(c.f, c.ramp);
            let idx: Vec<usize> = (0..pts.len())
                .filter(|&i| total - arc_len[i] >= tail && arc_len[i] >= head)
                .collect();
            let feed = match (idx.first(), idx.last()) {
                (Some(&i), Some(&j)) if pts[j].0 > pts[i].0 => {
                    let path = arc_len[j] - arc_len[i];
                    (path >= FEED_MIN_PATH_BLU)
                        .then(|| (f_of(c.f), per_min(path, pts[j].0 - pts[i].0)))
                }
                _ => None,
            };
            ("arc", dev, feed)
        }
    }
}

/// Compares the capture's pulse groups with the host core's frames: same order, same axes, same
/// directions. Returns the index of the first difference, or None when they are equal.
pub fn compare_with_host(
    prog: &[ProgBlock],
    settings: &Settings,
    groups: &[(u64, u8, u8)],
) -> Option<usize> {
    let mut frame = Frame::new(FrameConfig::from_settings(settings));
    let mut host: VecDeque<(u8, u8)> =
        Sim::new(&mut frame, prog.iter().map(|b| b.block), u32::MAX, u64::MAX)
            .filter(|f| f.pulses.steps != 0)
            .map(|f| (f.pulses.steps, f.pulses.signs & f.pulses.steps))
            .collect();
    for (i, &(_, mask, signs)) in groups.iter().enumerate() {
        match host.pop_front() {
            Some(h) if h == (mask, signs & mask) => {}
            _ => return Some(i),
        }
    }
    if host.is_empty() {
        None
    } else {
        Some(groups.len())
    }
}
