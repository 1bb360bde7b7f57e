//! Side-by-side machining figures of a program on the simulated process (host): with the paper's AC,
//! at the programmed constant feeds, at the largest constant feed safe for the whole program, and the
//! oracle (the fastest schedule within F0, T0 and fdot_m, computed with full knowledge of the stock).
//! Also the ac.csv text and the plot. Used by the `run`/demo commands and the benchmark.
use crate::analysis::ProgBlock;
use crate::host::acsim::{self, AcRow, Cut, HostRun, LoadFigures, ToolRun};
use anyhow::{Context, Result};
use millac::ac::AcSettings;
use millac::gcode::tape::finish_block;
use millac::nc::{FrameConfig, Motion};
use millac::Settings;
use millac_plant::oracle::{OracleLimits, OracleOut, OraclePoint, OracleStream};
use serde_json::{json, Value};

/// The comparison runs (all on the host, same process model and seed).
#[derive(Clone, Debug)]
pub struct Comparison {
    /// The runs' load figures (`HostRun::load`) are against the AC's F0.
    pub programmed: HostRun,
    /// The largest constant feed safe for the whole program, and for each tool's part (one
    /// part without tool changes); the safe run cuts each part at its own.
    pub safe_feed_ipm: f64,
    pub safe_parts_ipm: Vec<f64>,
    pub safe: HostRun,
    pub oracle_time_s: f64,
    /// The oracle's time of each tool's part (`BoundSummary::parts_s`).
    pub oracle_parts_s: Vec<f64>,
}

fn is_feed(b: &ProgBlock) -> bool {
    matches!(b.block.motion, Motion::Linear(_) | Motion::Arc(_))
}

/// The programmed path length of a feed block, BLU: a line's straight length, an arc's (its
/// commands, one per BLU of arc) with its helix.
fn path_length_blu(b: &ProgBlock) -> f64 {
    match b.block.motion {
        Motion::Arc(a) => f64::from(a.length).hypot(f64::from(a.helix)),
        _ => dist_blu(b.start.map(i64::from), b.end.map(i64::from)),
    }
}

/// The straight distance between two positions, BLU.
fn dist_blu(a: [i64; 3], b: [i64; 3]) -> f64 {
    let d = [0, 1, 2].map(|k| (b[k] - a[k]) as f64);
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// The feed blocks of `prog` as the AC with `acs` runs them: its ceiling applied (the programmed
/// feed, or FRM with [`millac::ac::FeedCeiling::Frm`]) and sealed, by the firmware's own
/// `finish_block`. One rule for every compared schedule: the oracle's ceilings and the safe
/// constant feed's blocks come from these, so no schedule runs above a ceiling the AC honours.
pub fn ceiling_blocks(prog: &[ProgBlock], settings: &Settings, acs: &AcSettings) -> Vec<ProgBlock> {
    let cfg = FrameConfig::from_settings(settings);
    prog.iter()
        .map(|b| ProgBlock {
            block: finish_block(b.block.into_block(), Some(acs.ceiling), &cfg, settings.q0),
            ..*b
        })
        .collect()
}

/// One point of the oracle's walk ([`Walker`]): a pulse of a feed block (or the first block's
/// start point of a run of feed blocks) with the oracle's figures there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkPoint {
    /// Index of the block in the program.
    pub block: usize,
    pub pos_blu: [i64; 3],
    /// The schedule's feed, ipm; the largest the force, torque and ceiling allow before the
    /// acceleration passes; the largest force and torque alone allow (infinite in air).
    pub feed_ipm: f64,
    pub limit_ipm: f64,
    pub cut_limit_ipm: f64,
    /// Peak force (N) and torque (N*m) at the scheduled feed.
    pub f_peak_n: f64,
    pub t_peak_nm: f64,
}

/// A term of the walk's time, in the program's order: a run of feed blocks' oracle time, or the
/// programmed span of a rapid or dwell block (known when the pulses have all been put out).
enum Term {
    Run(f64),
    Span(usize),
}

/// The oracle along a program, block by block as the pulses of its programmed run come
/// ([`Walker::block`]): each run of consecutive feed blocks scheduled by
/// [`millac_plant::OracleStream`] on the stock as the blocks before it left it, with each
/// block's ceiling `ceiling_ipm[i]` and acceleration; rapids and dwells take their programmed
/// run's time. Its points go out as the stream settles them, so it holds a window of the path,
/// not the path. A program's tool changes (`Cut::changes`) end the run before them; the runs
/// after a change are scheduled for the tool it fits (its geometry, speed and limits: F0 and T0
/// the same fraction of its limits as `limits` are of the cut's tool's). Host: the bound
/// ([`bound_summary`]) and the offline optimiser (`crate::evaluation::optimise`).
pub struct Walker<'a> {
    prog: &'a [ProgBlock],
    settings: &'a Settings,
    cut: &'a Cut,
    /// The tool cutting, its speed and limits, and the next of the cut's changes.
    tool: millac_plant::Tool,
    rpm: f64,
    limits: OracleLimits,
    base_limits: OracleLimits,
    next_change: usize,
    ceiling_ipm: &'a [f64],
    /// The stock between runs (inside the stream during one).
    stock: Option<millac_plant::Stock>,
    /// The run being walked: its first point until a second one starts the stream; the blocks
    /// and positions of the points pushed and not yet put out.
    first: Option<(OraclePoint, usize)>,
    stream: Option<OracleStream>,
    pending: std::collections::VecDeque<(usize, [i64; 3])>,
    pos: [i64; 3],
    /// The terms with the tool's part they belong to (0 before the first change, k after the
    /// k-th).
    terms: Vec<(usize, Term)>,
}

impl<'a> Walker<'a> {
    pub fn new(
        prog: &'a [ProgBlock],
        settings: &'a Settings,
        cut: &'a Cut,
        limits: &OracleLimits,
        ceiling_ipm: &'a [f64],
    ) -> Walker<'a> {
        Walker {
            prog,
            settings,
            cut,
            tool: cut.tool,
            rpm: cut.spindle_rpm,
            limits: *limits,
            base_limits: *limits,
            next_change: 0,
            ceiling_ipm,
            stock: Some(cut.stock.clone()),
            first: None,
            stream: None,
            pending: std::collections::VecDeque::new(),
            pos: [0; 3],
            terms: Vec::new(),
        }
    }

    /// Block `i` with its pulses `pts` (the programmed run's positions after each of its pulsed
    /// frames); `out` gets the walk's points as they settle, in order.
    pub fn block(
        &mut self,
        i: usize,
        pts: &[[i64; 3]],
        out: &mut impl FnMut(WalkPoint),
    ) -> Result<()> {
        let Some(b) = self.prog.get(i) else {
            return Ok(());
        };
        // A tool change before this block: the run before it ends (the machine stands).
        while let Some(c) = self
            .cut
            .changes
            .get(self.next_change)
            .filter(|c| c.at_block <= i)
        {
            self.flush(out)?;
            let (base, to) = (&self.cut.tool, &c.plant);
            self.limits = OracleLimits {
                f0_n: self.base_limits.f0_n / base.f_max_n * to.f_max_n,
                t0_nm: self.base_limits.t0_nm / base.t_max_nm * to.t_max_nm,
                ..self.base_limits
            };
            self.tool = c.plant;
            self.rpm = c.rpm;
            self.next_change += 1;
        }
        let pos = self.pos;
        if is_feed(b) {
            let point = |pos_blu, step_mm| OraclePoint {
                pos_blu,
                feed_ipm: self.ceiling_ipm.get(i).copied().unwrap_or(0.0),
                accel_ipm_s: acsim::ramp_ipm_s(self.settings, &b.block),
                step_mm,
            };
            if self.first.is_none() && self.stream.is_none() {
                self.first = Some((point(pos, None), i));
            }
            // The pulse positions are a staircase: each step's length is scaled so that the
            // block's steps add up to its programmed path (the schedule runs along the path, as
            // the frame's feed does).
            let stair: f64 = pts
                .iter()
                .scan(pos, |prev, p| {
                    Some(dist_blu(std::mem::replace(prev, *p), *p))
                })
                .sum();
            let scale = if stair > 0.0 {
                path_length_blu(b) / stair
            } else {
                1.0
            };
            let mut prev = pos;
            for p in pts {
                let step = dist_blu(std::mem::replace(&mut prev, *p), *p);
                self.push(
                    point(*p, Some(step * scale * millac_plant::MM_PER_BLU)),
                    i,
                    out,
                )?;
            }
        } else {
            self.flush(out)?;
            self.terms.push((self.next_change, Term::Span(i)));
            // Rapids cut nothing in a sane program; keep the stock in step anyway.
            let mm = |v: [i64; 3]| v.map(|c| c as f64 * millac_plant::MM_PER_BLU);
            if let (Some(last), Some(stock)) = (pts.last(), self.stock.as_mut()) {
                stock.cut_capsule(mm(pos), mm(*last), self.tool.diameter_mm / 2.0);
            }
        }
        if let Some(last) = pts.last() {
            self.pos = *last;
        }
        Ok(())
    }

    /// The next point of the run of feed blocks.
    fn push(
        &mut self,
        p: OraclePoint,
        block: usize,
        out: &mut impl FnMut(WalkPoint),
    ) -> Result<()> {
        if self.stream.is_none() {
            let stock = self.stock.take().context("the walk's stock")?;
            let material = &self.cut.material;
            let mut stream = OracleStream::new(stock, &self.tool, material, self.rpm, &self.limits)
                .map_err(|e| anyhow::anyhow!("oracle: {}", e.0))?;
            if let Some((q, b)) = self.first.take() {
                self.pending.push_back((b, q.pos_blu));
                stream
                    .push(q, &mut |_, _| {})
                    .map_err(|e| anyhow::anyhow!("oracle: {}", e.0))?;
            }
            self.stream = Some(stream);
        }
        self.pending.push_back((block, p.pos_blu));
        let (stream, pending) = (
            self.stream.as_mut().context("the walk's stream")?,
            &mut self.pending,
        );
        stream
            .push(p, &mut |_, o| emit(pending, o, out))
            .map_err(|e| anyhow::anyhow!("oracle: {}", e.0))
    }

    /// The end of a run of feed blocks: the rest of its points, its time, the stock it left.
    fn flush(&mut self, out: &mut impl FnMut(WalkPoint)) -> Result<()> {
        self.first = None;
        if let Some(stream) = self.stream.take() {
            let pending = &mut self.pending;
            let (time_s, stock) = stream.finish(&mut |_, o| emit(pending, o, out));
            self.terms.push((self.next_change, Term::Run(time_s)));
            self.stock = Some(stock);
        }
        Ok(())
    }

    /// The end of the program: the last run's points; the schedule's time, the oracle's over
    /// the feed runs and the programmed run's `spans` over rapids and dwells.
    pub fn finish(
        self,
        spans: &[(usize, u64, u64)],
        out: &mut impl FnMut(WalkPoint),
    ) -> Result<f64> {
        self.finish_parts(spans, out).map(|(t, _)| t)
    }

    /// [`Walker::finish`], with the time of each tool's part (0 before the first change, k
    /// after the k-th: `Cut::changes.len() + 1` parts).
    pub fn finish_parts(
        mut self,
        spans: &[(usize, u64, u64)],
        out: &mut impl FnMut(WalkPoint),
    ) -> Result<(f64, Vec<f64>)> {
        self.flush(out)?;
        let mut time_s = 0.0;
        let mut parts = vec![0.0; self.cut.changes.len() + 1];
        for &(part, ref t) in &self.terms {
            let s = match *t {
                Term::Run(s) => s,
                Term::Span(i) => match spans.get(i) {
                    Some(&(_, t0, t1)) => (t1 - t0) as f64 * 1e-9,
                    None => continue,
                },
            };
            time_s += s;
            if let Some(p) = parts.get_mut(part) {
                *p += s;
            }
        }
        Ok((time_s, parts))
    }
}

/// One settled point of the stream out as a walk point (its block and position from `pending`).
fn emit(
    pending: &mut std::collections::VecDeque<(usize, [i64; 3])>,
    o: OracleOut,
    out: &mut impl FnMut(WalkPoint),
) {
    if let Some((block, pos_blu)) = pending.pop_front() {
        out(WalkPoint {
            block,
            pos_blu,
            feed_ipm: o.feed_ipm,
            limit_ipm: o.limit_ipm,
            cut_limit_ipm: o.cut_limit_ipm,
            f_peak_n: o.f_peak_n,
            t_peak_nm: o.t_peak_nm,
        });
    }
}

/// The pulses of `prog` at its programmed feeds ([`acsim::pulses_to`], the frames alone, on a
/// thread of their own) given to `f` block by block: every block of the program in order with
/// the positions of its pulsed frames (none for a block that pulsed none). Returns the frames'
/// run (its spans; no path kept). Stops early on a signal, as the walks it feeds.
pub fn by_block(
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    mut f: impl FnMut(usize, &[[i64; 3]]) -> Result<()>,
) -> Result<HostRun> {
    // Batches of pulses: the frames run ahead of the walk by at most a few of them.
    const BATCH: usize = 8192;
    let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<([i64; 3], usize)>>(4);
    std::thread::scope(|s| {
        let frames = s.spawn(move || {
            let mut batch = Vec::with_capacity(BATCH);
            let r = acsim::pulses_to(prog, settings, cut, &mut |p, b| {
                batch.push((p, b));
                if batch.len() == BATCH {
                    // A closed channel: the walk stopped; the frames run on to their end.
                    let _ = tx.send(std::mem::replace(&mut batch, Vec::with_capacity(BATCH)));
                }
            });
            let _ = tx.send(batch);
            r
        });
        let walked = (|| -> Result<()> {
            let (mut next, mut pts) = (0usize, Vec::new());
            for batch in rx.iter() {
                for (p, b) in batch {
                    while next < b && next < prog.len() {
                        crate::progress::update(next, f64::NAN);
                        f(next, &pts)?;
                        pts.clear();
                        next += 1;
                        // A signal: the caller discards the walk (it runs beside the AC's run).
                        if crate::interrupt::received().is_some() {
                            return Ok(());
                        }
                    }
                    if b == next {
                        pts.push(p);
                    }
                }
            }
            while next < prog.len() {
                f(next, &pts)?;
                pts.clear();
                next += 1;
            }
            Ok(())
        })();
        drop(rx);
        let frames = frames
            .join()
            .unwrap_or_else(|p| std::panic::resume_unwind(p));
        walked?;
        frames
    })
}

/// The bound's figures over a program: its time and the smallest force or torque limit along
/// it (infinite where nothing is cut), the largest constant feed safe everywhere.
#[derive(Clone, Debug, PartialEq)]
pub struct BoundSummary {
    pub time_s: f64,
    pub min_cut_limit_ipm: f64,
    /// The time and the smallest limit of each tool's part ([`Walker::finish_parts`]).
    pub parts_s: Vec<f64>,
    pub parts_min_cut_limit_ipm: Vec<f64>,
}

/// The ceilings the AC with `acs` honours ([`ceiling_blocks`]) as feeds, ipm, per block.
pub fn bound_ceilings(prog: &[ProgBlock], settings: &Settings, acs: &AcSettings) -> Vec<f64> {
    ceiling_blocks(prog, settings, acs)
        .iter()
        .map(|c| acsim::programmed_ipm(settings, &c.block))
        .collect()
}

/// The bound's walk of `prog` over its programmed pulses ([`by_block`]) with `limits` and the
/// ceilings the AC with `acs` honours ([`bound_ceilings`]): its time and smallest limit, the
/// points not kept.
pub fn bound_summary(
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    acs: &AcSettings,
    limits: &OracleLimits,
) -> Result<BoundSummary> {
    let ceiling_ipm = bound_ceilings(prog, settings, acs);
    let mut walker = Walker::new(prog, settings, cut, limits, &ceiling_ipm);
    let mut min_cut_limit_ipm = f64::INFINITY;
    let mut parts_min_cut_limit_ipm = vec![f64::INFINITY; cut.changes.len() + 1];
    let mut take = |p: WalkPoint| {
        min_cut_limit_ipm = min_cut_limit_ipm.min(p.cut_limit_ipm);
        if let Some(m) = parts_min_cut_limit_ipm.get_mut(cut.part_of(p.block)) {
            *m = m.min(p.cut_limit_ipm);
        }
    };
    let frames = by_block(prog, settings, cut, |i, pts| {
        walker.block(i, pts, &mut take)
    })?;
    let (time_s, parts_s) = walker.finish_parts(&frames.spans, &mut take)?;
    Ok(BoundSummary {
        time_s,
        min_cut_limit_ipm,
        parts_s,
        parts_min_cut_limit_ipm,
    })
}

/// The bound's limits: F0 and T0, the controller's fraction of the tool's true limits.
pub fn bound_limits(cut: &Cut, acs: &AcSettings) -> OracleLimits {
    let fraction = f64::from(acs.optimal_fraction);
    OracleLimits {
        f0_n: fraction * cut.tool.f_max_n,
        t0_nm: fraction * cut.tool.t_max_nm,
        ..OracleLimits::for_tool(&cut.tool)
    }
}

/// The largest constant feed (the frame's feed number) that is safe everywhere along a walk
/// whose smallest force or torque limit is `min_limit_ipm` (FRM where nothing is cut).
pub fn safe_feed(min_limit_ipm: f64, settings: &Settings) -> u32 {
    let max_f = settings.q0;
    if min_limit_ipm.is_finite() {
        ((min_limit_ipm / acsim::feed_ipm(settings, 1)).floor() as u32).clamp(1, max_f)
    } else {
        max_f
    }
}

/// Runs the constant-feed references and the oracle.
///
/// The bound (the oracle) and the safe constant feed honour the same ceilings as the AC run
/// ([`ceiling_blocks`]); the oracle changes the feed at most at each move's acceleration ramp,
/// the fastest the frame lets any schedule change it.
pub fn compare(
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    acs: &AcSettings,
) -> Result<Comparison> {
    compare_recorded(prog, settings, cut, acs, acsim::Record::ALL)
}

/// As [`compare`], its runs keeping what `record` says (their load against the AC's F0).
pub fn compare_recorded(
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    acs: &AcSettings,
    record: acsim::Record,
) -> Result<Comparison> {
    let record = acsim::Record {
        load_fraction: f64::from(acs.optimal_fraction),
        ..record
    };
    let run = |p: &[ProgBlock]| acsim::run_recorded(p, settings, cut, None, &[], record, None);
    // The programmed feeds cut on a thread of their own: the bound walks the pulses of the same
    // path (the frames alone), and the safe constant feed needs only the bound.
    let (programmed, (oracle_s, oracle_parts_s, safe_f, part_f, safe)) = std::thread::scope(|s| {
        let programmed = s.spawn(|| run(prog));
        let bound = (|| -> Result<_> {
            crate::progress::stage("oracle (bound)");
            let limits = bound_limits(cut, acs);
            let b = bound_summary(prog, settings, cut, acs, &limits)?;
            let (oracle_s, safe_f) = (b.time_s, safe_feed(b.min_cut_limit_ipm, settings));
            let ceilings = ceiling_blocks(prog, settings, acs);
            // Each tool's part at the largest constant feed safe for it (one part: the whole
            // program at one feed).
            let part_f: Vec<u32> = b
                .parts_min_cut_limit_ipm
                .iter()
                .map(|&l| safe_feed(l, settings))
                .collect();
            let parts = b.parts_s;
            let f_of = |i: usize| part_f.get(cut.part_of(i)).copied().unwrap_or(safe_f);
            let safe_prog = acsim::with_constant_feeds(&ceilings, f_of, settings);
            crate::progress::stage("safe constant feed");
            let safe = run(&safe_prog)?;
            Ok((oracle_s, parts, safe_f, part_f, safe))
        })();
        let programmed = programmed
            .join()
            .unwrap_or_else(|p| std::panic::resume_unwind(p));
        Ok::<_, anyhow::Error>((programmed?, bound?))
    })?;
    Ok(Comparison {
        programmed,
        safe_feed_ipm: acsim::feed_ipm(settings, safe_f),
        safe_parts_ipm: part_f
            .iter()
            .map(|&f| acsim::feed_ipm(settings, f))
            .collect(),
        safe,
        oracle_time_s: oracle_s,
        oracle_parts_s,
    })
}

fn r3(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

/// The `ac` object of summary.json (stable keys), from the AC run's time and samples.
pub fn ac_json(time_s: f64, load: &LoadFigures, c: &Comparison) -> Value {
    json!({
        "time_s": r3(time_s),
        "time_constant_programmed_s": r3(c.programmed.machining_time_s),
        "time_constant_safe_s": r3(c.safe.machining_time_s),
        "time_oracle_s": r3(c.oracle_time_s),
        "peak_force_ratio": r3(load.peak_force_ratio),
        "peak_torque_ratio": r3(load.peak_torque_ratio),
        "time_above_f0_s": r3(load.time_above_f0_s),
        "time_above_limit_s": r3(load.time_above_limit_s),
        "safe_constant_feed_ipm": r3(c.safe_feed_ipm),
        "programmed_peak_force_ratio": r3(c.programmed.load.peak_force_ratio),
        "programmed_time_above_limit_s": r3(c.programmed.load.time_above_limit_s),
    })
}

/// The AFC-style log of a multi-tool run (Heidenhain's AFC keeps one per tool): for each tool's
/// part of the AC run, its blocks, its time, the programmed feeds' time of the same part and the
/// difference in %, the time in the cut and the part of it the AC controlled (slower than
/// programmed), the highest F/Fmax and T/Tmax against its own limits, the time above them, the
/// lowest feed in the cut, the holds and the first alarm. `programmed`: the programmed feeds'
/// run of the same program (its parts in the same order). Empty for a one-tool program.
pub fn tool_log(tools: &[ToolRun], c: &Comparison) -> Vec<Value> {
    // The same tool's part of another run.
    fn same<'a>(r: &'a HostRun, t: &ToolRun) -> Option<&'a ToolRun> {
        r.tools.iter().find(|p| p.part == t.part)
    }
    tools
        .iter()
        .map(|t| {
            let time = t.time_s();
            let prog = same(&c.programmed, t);
            // Compared only when the AC's part ran all its blocks.
            let whole = prog.is_some_and(|p| p.blocks == t.blocks);
            let prog = prog.map(ToolRun::time_s);
            json!({
                "tool": t.tool,
                "blocks": t.blocks,
                "ac": t.limited,
                "time_s": r3(time),
                "time_programmed_s": prog.map(r3),
                "time_safe_s": same(&c.safe, t).map(ToolRun::time_s).map(r3),
                "safe_feed_ipm": c.safe_parts_ipm.get(t.part).copied().map(r3),
                "time_bound_s": c.oracle_parts_s.get(t.part).copied().map(r3),
                "vs_programmed_pct": prog
                    .filter(|p| *p > 0.0 && whole)
                    .map(|p| r3((time / p - 1.0) * 100.0)),
                "cutting_s": r3(t.cutting_s),
                "controlled_s": r3(t.controlled_s),
                "peak_force_ratio": r3(t.load.peak_force_ratio),
                "peak_torque_ratio": r3(t.load.peak_torque_ratio),
                "time_above_limit_s": r3(t.load.time_above_limit_s),
                "lowest_feed_ipm": t.lowest_feed_ipm.map(r3),
                "holds": t.holds,
                "alarm": t.alarm.map(|a| a.to_string()),
            })
        })
        .collect()
}

/// Each tool's figure, `out/ac-T<n>.svg`: its periods of `rows` (feed, F/F0 and T/T0) against
/// its own F0 and T0 (`ac.svg` draws the machine's), for every tool `cut` changes to that has
/// periods; the names written.
pub fn plot_tools(
    out: &std::path::Path,
    rows: &[crate::host::acsim::AcRow],
    cut: &crate::host::acsim::Cut,
    acs: &millac::ac::AcSettings,
    settings: &millac::Settings,
) -> anyhow::Result<Vec<String>> {
    let mut figures = Vec::new();
    for c in &cut.changes {
        let n = c.fitted.number;
        let name = format!("ac-T{n}.svg");
        let mine: Vec<_> = rows.iter().filter(|r| r.tool == n).cloned().collect();
        if mine.is_empty() || figures.contains(&name) {
            continue;
        }
        let s = millac::rt::ac::tool_settings(acs, &c.fitted).map_or(*acs, |s| s.get());
        plot_against(&out.join(&name), &mine, &s, settings)?;
        figures.push(name);
    }
    Ok(figures)
}

/// [`plot`] of `rows` against the F0, T0 and limits of `acs`, the feed axis up to the machine's
/// fastest feed (FRM): `ac.svg` with the machine's, `ac-T<n>.svg` with a tool's.
pub fn plot_against(
    path: &std::path::Path,
    rows: &[AcRow],
    acs: &AcSettings,
    settings: &Settings,
) -> Result<()> {
    plot(
        path,
        rows,
        acs.f0_n() as f64,
        acs.t0_nm() as f64,
        1.0 / acs.optimal_fraction as f64,
        crate::host::acsim::feed_ipm(settings, settings.q0),
    )
}

/// Says which per-tool figures a run wrote (none: nothing).
pub fn print_figures(out: &std::path::Path, figures: &[String]) {
    if !figures.is_empty() {
        println!(
            "  wrote {}/{} (each tool's feed, F/F0 and T/T0 against its own limits)",
            out.display(),
            figures.join(", ")
        );
    }
}

/// Prints [`tool_log`] as a table.
pub fn print_tool_log(log: &[Value]) {
    if log.is_empty() {
        return;
    }
    println!("  per tool (AFC log)  blocks  AC    time s  programmed s  vs prog %  safe feed s  bound s  cutting s  controlled s  peak F/Fmax  peak T/Tmax  above limit s  lowest ipm  holds");
    let num = |v: &Value, w: usize, d: usize| match v.as_f64() {
        // A difference that rounds to nothing is 0, not -0.
        Some(x) if (x * 10f64.powi(d as i32)).round() == 0.0 => format!("{:>w$.d$}", 0.0),
        Some(x) => format!("{x:>w$.d$}"),
        None => format!("{:>w$}", "-"),
    };
    for t in log {
        println!(
            "  T{:<18} {:>6}  {:<4} {} {} {} {} {} {} {} {} {} {} {} {:>6}",
            t["tool"].as_u64().unwrap_or(0),
            t["blocks"].as_u64().unwrap_or(0),
            if t["ac"].as_bool() == Some(true) {
                "on"
            } else {
                "off"
            },
            num(&t["time_s"], 8, 2),
            num(&t["time_programmed_s"], 13, 2),
            num(&t["vs_programmed_pct"], 10, 1),
            num(&t["time_safe_s"], 12, 2),
            num(&t["time_bound_s"], 8, 2),
            num(&t["cutting_s"], 10, 2),
            num(&t["controlled_s"], 13, 2),
            num(&t["peak_force_ratio"], 12, 3),
            num(&t["peak_torque_ratio"], 12, 3),
            num(&t["time_above_limit_s"], 14, 3),
            num(&t["lowest_feed_ipm"], 11, 2),
            t["holds"].as_u64().unwrap_or(0),
        );
    }
}

/// The AC row's name in the side-by-side table for the run's feed law.
pub fn ac_label(strategy: millac::ac::law::Strategy) -> &'static str {
    use millac::ac::law::Strategy;
    match strategy {
        Strategy::Paper => "AC (paper's FRC, anti-windup, held peak)",
        Strategy::Integral => "AC (integral law, anti-windup, held peak)",
        Strategy::Mrac => "AC (MRAC, anti-windup, held peak)",
        Strategy::Gpc => "AC (GPC, anti-windup, held peak)",
    }
}

/// Prints the side-by-side table. `unfinished`: why the AC run did not finish (e.g. `held at
/// line 3`); its row then says so instead of a ratio to the oracle. `strategy` names the AC row.
pub fn print_table(
    time_s: f64,
    load: &LoadFigures,
    c: &Comparison,
    unfinished: Option<&str>,
    strategy: millac::ac::law::Strategy,
) {
    println!("  adaptive control on the simulated cut        time s   vs oracle  peak F/Fmax  peak T/Tmax  above F0 s  above limit s");
    let row = |name: &str, t: f64, l: Option<&LoadFigures>, unfinished: Option<&str>| {
        let (pf, pt, a0, al) = l.map_or(("-".into(), "-".into(), "-".into(), "-".into()), |l| {
            (
                format!("{:.3}", l.peak_force_ratio),
                format!("{:.3}", l.peak_torque_ratio),
                format!("{:.3}", l.time_above_f0_s),
                format!("{:.3}", l.time_above_limit_s),
            )
        });
        let (ratio, note) = match unfinished {
            None => (format!("{:.3}", t / c.oracle_time_s), String::new()),
            Some(why) => ("-".to_string(), format!("  did not finish: {why}")),
        };
        println!(
            "  {name:<44} {t:>7.2}   {ratio:>8}  {pf:>11}  {pt:>11}  {a0:>10}  {al:>13}{note}"
        );
    };
    row(ac_label(strategy), time_s, Some(load), unfinished);
    row(
        "constant, programmed feeds",
        c.programmed.machining_time_s,
        Some(&c.programmed.load),
        None,
    );
    row(
        &match c.safe_parts_ipm.len() {
            0 | 1 => format!("constant, safe feed {:.2} ipm", c.safe_feed_ipm),
            _ => "constant per tool, each its safe feed".to_string(),
        },
        c.safe.machining_time_s,
        Some(&c.safe.load),
        None,
    );
    row("oracle (bound)", c.oracle_time_s, None, None);
}

/// Room for the x axis's tick labels and its description under them, and for the y axis's tick
/// labels and its (turned) description left of them (pixels).
const LABELS_X: u32 = 40;
const LABELS_Y: u32 = 64;

/// Writes the plot (SVG): feed, F/F0 and T/T0 against time with the limits, and the tool path in XY
/// coloured by feed.
pub fn plot(
    path: &std::path::Path,
    rows: &[AcRow],
    f0: f64,
    t0: f64,
    f_max_ratio: f64,
    feed_max: f64,
) -> Result<()> {
    use plotters::prelude::*;
    let root = SVGBackend::new(path, (1200, 900)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(520);
    let t_end = rows
        .last()
        .map_or(1.0, |r| r.t_ms as f64 / 1000.0)
        .max(0.01);
    let (feed_area, load_area) = top.split_vertically(240);
    let mut c = ChartBuilder::on(&feed_area)
        .caption("feed (ipm)", ("sans-serif", 18))
        .margin(8)
        .x_label_area_size(LABELS_X)
        .y_label_area_size(LABELS_Y)
        .build_cartesian_2d(0.0..t_end, 0.0..feed_max * 1.1)?;
    c.configure_mesh()
        .x_desc("t (s)")
        .y_desc("feed (ipm)")
        .draw()?;
    c.draw_series(LineSeries::new(
        rows.iter().map(|r| (r.t_ms as f64 / 1000.0, r.feed_ipm)),
        &BLUE,
    ))?;
    let mut c = ChartBuilder::on(&load_area)
        .caption(
            "true F/F0 (red), T/T0 (green), peaks over 30 ms; F0 = 1, permissible = dashed",
            ("sans-serif", 18),
        )
        .margin(8)
        .x_label_area_size(LABELS_X)
        .y_label_area_size(LABELS_Y)
        .build_cartesian_2d(0.0..t_end, 0.0..1.4)?;
    c.configure_mesh()
        .x_desc("t (s)")
        .y_desc("ratio to F0, T0")
        .draw()?;
    // The envelope a person reads: each row's peak is over its 10 ms period, shorter than a tooth
    // period at 600 rpm, so the plot takes the peak over three periods (ac.csv keeps the raw rows).
    let envelope = |v: fn(&AcRow) -> f64, scale: f64| {
        rows.iter().enumerate().map(move |(i, r)| {
            let w = &rows[i.saturating_sub(2)..=i];
            (
                r.t_ms as f64 / 1000.0,
                w.iter().map(v).fold(0.0, f64::max) / scale,
            )
        })
    };
    c.draw_series(LineSeries::new(envelope(|r| r.f_true_n, f0), &RED))?;
    c.draw_series(LineSeries::new(envelope(|r| r.t_true_nm, t0), &GREEN))?;
    c.draw_series(LineSeries::new(
        [(0.0, 1.0), (t_end, 1.0)],
        BLACK.stroke_width(2),
    ))?;
    c.draw_series(DashedLineSeries::new(
        [(0.0, f_max_ratio), (t_end, f_max_ratio)],
        6,
        4,
        BLACK.into(),
    ))?;
    // Tool path in XY, coloured by feed.
    let xs = rows.iter().map(|r| r.pos_blu[0] as f64 / 10_000.0);
    let ys = rows.iter().map(|r| r.pos_blu[1] as f64 / 10_000.0);
    let (x0, x1) = xs.fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    let (y0, y1) = ys.fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    // No AC period at all (a run stopped before its first): the origin, not an inverted range
    // (plotters never returns from one).
    let [(x0, x1), (y0, y1)] =
        [(x0, x1), (y0, y1)].map(|(a, b)| if a <= b { (a, b) } else { (0.0, 0.0) });
    let mut c = ChartBuilder::on(&bottom)
        .caption(
            "tool path (in), colour = feed: blue slow .. red fast",
            ("sans-serif", 18),
        )
        .margin(8)
        .x_label_area_size(LABELS_X)
        .y_label_area_size(LABELS_Y)
        .build_cartesian_2d((x0 - 0.2)..(x1 + 0.2), (y0 - 0.2)..(y1 + 0.2))?;
    c.configure_mesh()
        .x_desc("X (in)")
        .y_desc("Y (in)")
        .draw()?;
    c.draw_series(rows.windows(2).map(|w| {
        let v = (w[1].feed_ipm / feed_max).clamp(0.0, 1.0);
        let colour = RGBColor((255.0 * v) as u8, 40, (255.0 * (1.0 - v)) as u8);
        PathElement::new(
            [
                (
                    w[0].pos_blu[0] as f64 / 10_000.0,
                    w[0].pos_blu[1] as f64 / 10_000.0,
                ),
                (
                    w[1].pos_blu[0] as f64 / 10_000.0,
                    w[1].pos_blu[1] as f64 / 10_000.0,
                ),
            ],
            colour.stroke_width(3),
        )
    }))?;
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    /// A run with no AC period (stopped before its first, e.g. by a signal) still gets its plot.
    /// Before, the path chart's range was inverted (f64::MAX..f64::MIN) and plotters never
    /// returned.
    #[test]
    fn a_run_with_no_rows_is_plotted() {
        let dir = std::env::temp_dir().join(format!("millac-plot-empty-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let svg = dir.join("ac.svg");
        super::plot(&svg, &[], 3600.0, 72.0, 1.111, 30.0).unwrap();
        assert!(std::fs::metadata(&svg).unwrap().len() > 0);
    }

    /// No text of the plot overlaps another (the axis descriptions sat on the tick labels).
    #[test]
    fn the_plots_labels_are_clear_of_each_other() {
        let dir = std::env::temp_dir().join(format!("millac-plot-labels-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let svg = dir.join("ac.svg");
        let rows: Vec<_> = (0..6000u64)
            .map(|i| crate::host::acsim::AcRow {
                t_ms: i * 10,
                pos_blu: [(i as i64 * 7) % 40_000, (i as i64 * 3) % 20_000, 0],
                feed_ipm: 10.0 + (i % 20) as f64,
                f_meas_n: 0.0,
                t_meas_nm: 0.0,
                f_true_n: 3000.0,
                t_true_nm: 30.0,
                e: 0.0,
                state: "run".into(),
                feed_cap: u32::MAX,
                estimates: None,
                tool: 0,
            })
            .collect();
        super::plot(&svg, &rows, 3600.0, 72.0, 1.111, 30.0).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        let boxes = crate::evaluation::plot::text_boxes(&text);
        assert!(boxes.iter().any(|b| b.text == "t (s)"), "{boxes:?}");
        let clashes = crate::evaluation::plot::overlapping_texts(&text);
        assert!(clashes.is_empty(), "{clashes:?}");
    }
}
