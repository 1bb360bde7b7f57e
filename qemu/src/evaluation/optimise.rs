//! Offline feed optimisation by virtual machining (Karunakaran, Shringi and Singh, "Offline
//! adaptive control using virtual machining"; issue 11), host: `millac optimise PROGRAM --out
//! OPTIMISED.nc`. The program is machined virtually on the simulated stock (the plant's cutter
//! model and the oracle, `millac_plant::oracle`, the same as the simulated cut), its feed blocks
//! are split where the feed the cut allows changes by more than a set ratio (the paper's
//! segmentation into "sampling intervals" of length, its Fig. 7c), and each piece gets the
//! largest feed that keeps the peak force within F0 and the torque within T0 all along it,
//! within the machine's acceleration: air cuts up to the air-cut feed, entries slower. The
//! geometry is the program's: a straight block splits at pulses of its own path (its end points,
//! and so every axis' pulses, unchanged; the pieces' paths within 1 BLU of the original line), an
//! arc keeps its one block at the slowest feed along it. The result is written as G-code the
//! firmware's parser (and grbl) accepts, checked by parsing it back.
//!
//! Choices (the paper is a survey and leaves them open; documented in docs/user/optimisation.md):
//! - The feed of a piece is the smallest of the oracle's schedule over the piece's points (its
//!   start and end included): the frame reaches a lower feed after a piece boundary at its
//!   acceleration, and the schedule already slows before a binding point, so the step down is
//!   taken before the point that needs it.
//! - A new piece starts where the schedule leaves the band `[min, min x (1 + split)]` of the
//!   piece so far and the piece is at least `min_piece_mm` long; a shorter tail joins the piece
//!   before it.
//! - The machine's rapid rate FRM caps every feed; the air-cut feed caps the pieces that cut
//!   nothing anywhere along them.
use crate::analysis::{self, ProgBlock};
use crate::evaluation::acreport::{by_block, WalkPoint, Walker};
use crate::host::acsim::{self, Cut, HostRun};
use anyhow::{anyhow, bail, Context, Result};
use millac::nc::{Motion, Plane, X, Y, Z};
use millac::Blu;
use millac::Settings;
use millac_plant::oracle::OracleLimits;
use std::collections::VecDeque;
use std::fmt::Write as _;

/// How to optimise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// F0 and T0 as a fraction of the tool's permissible force and torque (the AC's `$256`,
    /// default 0.9, the paper's "around 90 percent").
    pub fraction: f64,
    /// Feed of the pieces that cut nothing, ipm (capped by FRM).
    pub air_feed_ipm: f64,
    /// A new piece where the schedule leaves the band of the piece so far by this ratio.
    pub split: f64,
    /// Shortest piece, mm.
    pub min_piece_mm: f64,
    /// Georgiev and Chetrokov's fitted model in place of the full force model (`crate::evaluation::model`):
    /// at every point that cuts, the feed that holds its y at F0 at the depth present; where the
    /// depth is outside the model's range, the full model's feed (the piece says so).
    pub model: Option<crate::evaluation::model::Quadratic>,
    /// The guard against a wrong stock description, as a fraction of the permissible force
    /// and torque (0: trust the description). Where the described stock is air but material
    /// could stand ([`millac_plant::Stock::envelope`]: the blanks filled to the stock's top,
    /// less what the program has cut before), the feed is at most the one at which that
    /// material would load the cutter to this fraction: met unexpectedly, the load steps to
    /// below the overload hold (1.1 F0 = 0.99 at the defaults) and the AC under the plan
    /// (`FeedCeiling::Plan`) brings it back to F0, where at the air-cut feed no 10 ms loop could
    /// act in time. Default 0.95.
    pub guard: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            fraction: 0.9,
            air_feed_ipm: f64::INFINITY,
            split: 0.03,
            min_piece_mm: 1.0,
            model: None,
            guard: 0.95,
        }
    }
}

/// One piece of a feed block in the optimised program.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece {
    /// The original block (index in the program) and its source line.
    pub block: usize,
    pub line: u32,
    /// Start and end (BLU).
    pub start: [i64; 3],
    pub end: [i64; 3],
    /// Distance along the feed moves to its start and its length, mm.
    pub at_mm: f64,
    pub length_mm: f64,
    /// The programmed feed and the piece's, ipm (the piece's as its F word gives it).
    pub programmed_ipm: f64,
    pub feed_ipm: f64,
    /// Cuts nothing anywhere along it.
    pub air: bool,
    /// The largest peak force the full model predicts along it at its feed, N.
    pub predicted_f_n: f64,
    /// With a fitted model: whether it set the feed everywhere along the piece (false: the depth
    /// left its range somewhere and the full model's feed was taken there). None without one.
    pub model: Option<bool>,
}

/// The optimised program and what was done.
#[derive(Clone, Debug)]
pub struct Optimised {
    /// The G-code (header comments, then the blocks).
    pub text: String,
    pub pieces: Vec<Piece>,
    /// F0 and T0 used, N and N*m.
    pub f0_n: f64,
    pub t0_nm: f64,
    /// The original program's run at its programmed feeds (the path the optimiser walked).
    pub programmed: HostRun,
}

/// Feed blocks of the output: a piece's feed as a feed number of the settings.
fn feed_number(settings: &Settings, ipm: f64) -> u32 {
    let per = acsim::feed_ipm(settings, 1);
    ((ipm / per).floor() as u32).clamp(1, settings.q0)
}

/// The number formats of the output: G20 with 4 decimals for 0.0001 in BLU, G21 with 3 for
/// microns: every BLU exact.
struct Units {
    g: &'static str,
    decimals: usize,
    /// BLU per program unit.
    per_unit: f64,
    /// ipm per program feed unit (F in ipm or mm/min).
    ipm_per_f: f64,
}

fn units(settings: &Settings) -> Units {
    match settings.blu {
        Blu::TenthMil => Units {
            g: "G20",
            decimals: 4,
            per_unit: 10_000.0,
            ipm_per_f: 1.0,
        },
        Blu::Micron => Units {
            g: "G21",
            decimals: 3,
            per_unit: 1000.0,
            ipm_per_f: 1.0 / 25.4,
        },
    }
}

impl Units {
    fn coord(&self, blu: i64) -> String {
        format!("{:.*}", self.decimals, blu as f64 / self.per_unit)
    }
    fn xyz(&self, p: [i64; 3]) -> String {
        format!(
            "X{} Y{} Z{}",
            self.coord(p[X]),
            self.coord(p[Y]),
            self.coord(p[Z])
        )
    }
    /// The F word of feed number `f`: enough decimals that the parser reads `f` back.
    fn feed(&self, settings: &Settings, f: u32) -> String {
        format!("F{:.4}", acsim::feed_ipm(settings, f) / self.ipm_per_f)
    }
}

/// Splits the points of one straight feed block into pieces (index ranges into `pts`, each
/// piece from its start point to its end point inclusive, consecutive pieces sharing a point).
fn split(pts: &[WalkPoint], split: f64, min_piece_mm: f64) -> Vec<(usize, usize)> {
    let mm = dist_mm;
    let mut out = Vec::new();
    let mut s = 0usize;
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for k in 0..pts.len() {
        let v = pts[k].feed_ipm;
        let (nlo, nhi) = (lo.min(v), hi.max(v));
        let long = mm(pts[s].pos_blu, pts[k].pos_blu) >= min_piece_mm;
        if k > s && nhi > nlo * (1.0 + split) && long {
            // The piece ends at the point before this one... at k - 1 it was in the band; end
            // there when it is long enough, else here.
            let e = if mm(pts[s].pos_blu, pts[k - 1].pos_blu) >= min_piece_mm {
                k - 1
            } else {
                k
            };
            out.push((s, e));
            s = e;
            lo = f64::INFINITY;
            hi = 0.0;
            // The band of the new piece: its points after the shared boundary point.
            for p in &pts[s + 1..=k] {
                lo = lo.min(p.feed_ipm);
                hi = hi.max(p.feed_ipm);
            }
            continue;
        }
        (lo, hi) = (nlo, nhi);
    }
    let last = pts.len().saturating_sub(1);
    let min_of = |a: usize, b: usize| {
        pts[a..=b]
            .iter()
            .map(|p| p.feed_ipm)
            .fold(f64::INFINITY, f64::min)
    };
    // A short tail joins the piece before it, unless it would slow that piece by more than the
    // band (a deceleration into the next block: the whole piece would take the tail's feed).
    let short_tail = mm(pts[s].pos_blu, pts[last].pos_blu) < min_piece_mm
        && out
            .last()
            .is_some_and(|p| min_of(s, last) * (1.0 + split) >= min_of(p.0, p.1));
    match out.last_mut() {
        Some(p) if short_tail => p.1 = last,
        _ => {
            if s < last || out.is_empty() {
                out.push((s, last));
            }
        }
    }
    out
}

/// The model's say over a piece's points: None without a model (or all in air), Some(true)
/// where it set every cutting point's feed, Some(false) where the depth left its range.
fn model_of(c: &[Option<bool>]) -> Option<bool> {
    c.iter()
        .flatten()
        .fold(None, |acc, &v| Some(acc.unwrap_or(true) && v))
}

/// The axial depth of cut (mm) at each walk point in turn: the highest material above the tip
/// under the tool's disc grown by one and a half cells (the stock is a grid of cells: the
/// crescent a point adds to the cut is narrower than a cell, so the disc alone, after the cut up
/// to the point before, would find nothing most of the time), the stock cut along the points as
/// they come.
struct Depths {
    stock: millac_plant::Stock,
    r: f64,
    prev: Option<[f64; 3]>,
}

impl Depths {
    fn new(cut: &Cut) -> Depths {
        Depths {
            stock: cut.stock.clone(),
            r: cut.tool.diameter_mm / 2.0,
            prev: None,
        }
    }

    fn next(&mut self, p: &WalkPoint) -> f64 {
        let cell = self.stock.cell_mm();
        let reach = self.r + 1.5 * cell;
        let t = p.pos_blu.map(|c| c as f64 * millac_plant::MM_PER_BLU);
        let n = (reach / cell).ceil() as i64;
        let mut top = f64::NEG_INFINITY;
        for i in -n..=n {
            for j in -n..=n {
                let (x, y) = (t[0] + i as f64 * cell, t[1] + j as f64 * cell);
                top = top.max(self.stock.top_in_disc(x, y, t[0], t[1], reach));
            }
        }
        if let Some(q) = self.prev {
            self.stock.cut_capsule(q, t, self.r);
        }
        self.prev = Some(t);
        (top - t[2]).max(0.0)
    }
}

/// The tooth period of a tool of `flutes` at `rpm`, s.
fn tooth_s(rpm: f64, flutes: u32) -> f64 {
    60.0 / (rpm * f64::from(flutes))
}

/// The path a feed of `v_ipm` covers in two tooth periods of `tooth_s`, mm: how far the chip lags
/// the feed (see [`lagged`]).
fn lag_mm(v_ipm: f64, tooth_s: f64) -> f64 {
    2.0 * v_ipm * millac_plant::MM_S_PER_IPM * tooth_s
}

/// The full model's largest peak force over `seg` at the feed `feed_ipm` (N): the oracle's peak
/// at its schedule, scaled as the chip, linearly or to the 1 - m of Kienzle's Ks (`expo`).
fn predicted_peak(seg: &[WalkPoint], feed_ipm: f64, expo: f64) -> f64 {
    seg.iter()
        .filter(|p| p.feed_ipm > 0.0)
        .map(|p| p.f_peak_n * (feed_ipm / p.feed_ipm).powf(expo))
        .fold(0.0, f64::max)
}

/// Distance between two points (BLU), mm.
fn dist_mm(a: [i64; 3], b: [i64; 3]) -> f64 {
    (0..3)
        .map(|k| ((b[k] - a[k]) as f64 * millac_plant::MM_PER_BLU).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The guard at one point (see [`Options::guard`]): where it cuts nothing on the described
/// stock but would cut on its envelope (`worst`, the same point walked on the envelope), the
/// schedule's feed at most the envelope's feed for F0 scaled by `scale` (the guard's fraction
/// over F0's, to the 1 / (1 - m) of Kienzle's m). Whether it lowered the feed.
fn guard(p: &mut WalkPoint, worst: &WalkPoint, scale: f64) -> bool {
    if p.cut_limit_ipm.is_infinite() && worst.cut_limit_ipm.is_finite() {
        let v = worst.cut_limit_ipm * scale;
        if v < p.feed_ipm {
            p.feed_ipm = v;
            return true;
        }
    }
    false
}

/// A piece's feed before the lag: the smallest of the schedule over its points, capped by the
/// air-cut feed where it cuts nothing and by FRM.
fn piece_feed(seg: &[WalkPoint], air_feed_ipm: f64, frm: f64) -> f64 {
    let v = seg.iter().map(|p| p.feed_ipm).fold(f64::INFINITY, f64::min);
    let air = seg.iter().all(|p| p.cut_limit_ipm.is_infinite());
    if air {
        v.min(air_feed_ipm).min(frm)
    } else {
        v.min(frm)
    }
}

/// The pieces of one straight block (`ranges` into `pts`, which start at `walk[base]`) with their
/// feeds, the chip's lag taken into account: the chip a tooth cuts is the feed of the last tooth
/// period, so a step down must be made before the point that needs it. A boundary where the feed
/// falls moves back by two tooth periods of travel at the faster feed; the block's last piece is
/// cut there too when the path after the block (the next block) is slower, its tail at the
/// slower feed (a tail shorter than the shortest piece: the lag is a fraction of a mm).
fn lagged(
    pts: &[WalkPoint],
    walk: &[WalkPoint],
    base: usize,
    mut ranges: Vec<(usize, usize)>,
    feed: &dyn Fn(&[WalkPoint]) -> f64,
    tooth_s: f64,
) -> Vec<(usize, usize, f64)> {
    let lag = |v: f64| lag_mm(v, tooth_s);
    // Moves a boundary e back by `mm`, keeping the piece from s at least one point long.
    let back = |s: usize, e: usize, mm: f64| {
        let mut k = e;
        while k > s + 1 && dist_mm(pts[k].pos_blu, pts[e].pos_blu) < mm {
            k -= 1;
        }
        k
    };
    let mut feeds: Vec<f64> = ranges.iter().map(|&(s, e)| feed(&pts[s..=e])).collect();
    for k in 0..ranges.len().saturating_sub(1) {
        if feeds[k + 1] < feeds[k] {
            let (s, e) = ranges[k];
            let e2 = back(s, e, lag(feeds[k]));
            ranges[k].1 = e2;
            ranges[k + 1].0 = e2;
            feeds[k + 1] = feeds[k + 1].min(feed(&pts[e2..=ranges[k + 1].1]));
        }
    }
    let mut out: Vec<(usize, usize, f64)> = ranges
        .iter()
        .zip(&feeds)
        .map(|(&(s, e), &v)| (s, e, v))
        .collect();
    if let Some(&(s, e, v)) = out.last() {
        let next = ahead(walk, base + e, lag(v));
        if next < v {
            let e2 = back(s, e, lag(v));
            if e2 > s && e2 < e {
                if let Some(last) = out.last_mut() {
                    last.1 = e2;
                }
                out.push((e2, e, next.min(feed(&pts[e2..=e]))));
            } else if let Some(last) = out.last_mut() {
                last.2 = next;
            }
        }
    }
    out
}

/// The smallest scheduled feed over the points after `points[from]` within `lag_mm` of it along
/// the path (stopping where the path jumps: the end of a run of feed blocks).
fn ahead(points: &[WalkPoint], from: usize, lag_mm: f64) -> f64 {
    let mut v = f64::INFINITY;
    let mut travelled = 0.0;
    for w in points.get(from..).unwrap_or(&[]).windows(2) {
        let d = dist_mm(w[0].pos_blu, w[1].pos_blu);
        // Consecutive pulses are at most a BLU per axis apart.
        if d > 2.0 * millac_plant::MM_PER_BLU || travelled >= lag_mm {
            break;
        }
        travelled += d;
        v = v.min(w[1].feed_ipm);
    }
    v
}

/// Optimises `text` for `cut` (its stock, tool, material and spindle speed) with `opts`.
pub fn optimise(text: &str, settings: &Settings, cut: &Cut, opts: &Options) -> Result<Optimised> {
    if !(opts.fraction > 0.0 && opts.fraction <= 1.0) {
        bail!("F0 fraction must be in (0, 1], got {}", opts.fraction);
    }
    if !(opts.split > 0.0 && opts.split.is_finite()) {
        bail!("split ratio must be finite and > 0, got {}", opts.split);
    }
    if !(opts.min_piece_mm >= 0.0 && opts.min_piece_mm.is_finite()) {
        bail!(
            "shortest piece must be finite and >= 0 mm, got {}",
            opts.min_piece_mm
        );
    }
    if opts.air_feed_ipm.is_nan() || opts.air_feed_ipm <= 0.0 {
        bail!("air-cut feed must be > 0, got {}", opts.air_feed_ipm);
    }
    if !(0.0..=1.0).contains(&opts.guard) {
        bail!(
            "guard must be a fraction of the permissible force in 0..=1 (0: off), got {}",
            opts.guard
        );
    }
    let prog = analysis::load_program(text, settings).map_err(|e| anyhow!("{e}"))?;
    // The program cut at its programmed feeds (for the caller's comparison) on a thread of its
    // own: the plan needs only its pulses.
    std::thread::scope(|s| {
        let programmed = s.spawn(|| {
            acsim::run_recorded(
                &prog,
                settings,
                cut,
                None,
                &[],
                acsim::Record::figures(opts.fraction),
                None,
            )
        });
        let plan = plan(text, &prog, settings, cut, opts);
        let programmed = programmed
            .join()
            .unwrap_or_else(|p| std::panic::resume_unwind(p))?;
        let o = Optimised {
            programmed,
            ..plan?
        };
        check(&prog, &o, settings)?;
        Ok(o)
    })
}

/// The plan of the blocks in order as the walk's points come (host, [`plan`]): `buf` holds the
/// points of the blocks not yet planned (and the last point before them, where the next block
/// starts); a block is planned once its points are all in and those after it reach as far as
/// the chip's lag can look ahead ([`ahead`]), then its points but the last are let go.
struct Planner<'a> {
    prog: &'a [ProgBlock],
    settings: &'a Settings,
    opts: &'a Options,
    /// The cut: its tool changes (`Cut::changes`) are written before the blocks they come
    /// before, and each tool's part is planned with its tooth period.
    cut: &'a Cut,
    /// The tool's part being planned (0 before the first change).
    part: usize,
    frm: f64,
    /// The tooth period of the tool cutting, s.
    tooth_s: f64,
    /// Kienzle's 1 - m.
    kienzle: f64,
    /// The farthest the chip's lag looks ahead (at FRM), mm.
    lag_max_mm: f64,
    u: Units,
    pieces: Vec<Piece>,
    body: String,
    at_mm: f64,
    plane: Plane,
    pos: [i64; 3],
    /// The next block to plan.
    next: usize,
    buf: Vec<WalkPoint>,
    cov: Vec<Option<bool>>,
}

impl Planner<'_> {
    /// Plans the blocks whose points are all in (every one when the walk has `ended`).
    fn ready(&mut self, ended: bool) {
        while self.next < self.prog.len() {
            let i = self.next;
            // The block's points: w0..w (the buffer starts with the point before, if any).
            let w0 = self
                .buf
                .iter()
                .position(|p| p.block >= i)
                .unwrap_or(self.buf.len());
            let w = w0 + self.buf[w0..].iter().take_while(|p| p.block == i).count();
            if !ended && (w == self.buf.len() || (w > w0 && !self.reaches(w - 1))) {
                break;
            }
            self.block(i, w0, w);
            // Keep the block's last point (the next block's start), let go of the rest.
            let keep = w.saturating_sub(1);
            self.buf.drain(..keep);
            self.cov.drain(..keep);
            self.next += 1;
        }
    }

    /// Whether the points after `buf[from]` reach as far as [`ahead`] can look: past the
    /// longest lag, or to where the path jumps.
    fn reaches(&self, from: usize) -> bool {
        let mut travelled = 0.0;
        for w in self.buf.get(from..).unwrap_or(&[]).windows(2) {
            let d = dist_mm(w[0].pos_blu, w[1].pos_blu);
            if d > 2.0 * millac_plant::MM_PER_BLU {
                return true;
            }
            travelled += d;
            if travelled >= self.lag_max_mm {
                return true;
            }
        }
        false
    }

    /// Block `i`, its points `buf[w0..w]`.
    fn block(&mut self, i: usize, w0: usize, w: usize) {
        // A tool change before this block: written as the program has it (the M6 and the
        // part's spindle speed), and the part planned with its tool's tooth period.
        let part = self.cut.part_of(i);
        if part != self.part {
            self.part = part;
            if let Some(c) = part.checked_sub(1).and_then(|k| self.cut.changes.get(k)) {
                let _ = writeln!(self.body, "T{} M6", c.fitted.number);
                let _ = writeln!(self.body, "S{} M3", c.rpm.round());
                self.tooth_s = tooth_s(c.rpm, c.plant.flutes);
            }
        }
        let (b, buf, cov) = (&self.prog[i], &self.buf[..], &self.cov[..]);
        // The block's points: from its start (the point before, or its own first) to its end.
        let base = if w0 > 0 && buf[w0 - 1].pos_blu == self.pos {
            w0 - 1
        } else {
            w0
        };
        let pts: &[WalkPoint] = &buf[base..w];
        let end = b.end.map(i64::from);
        match &b.block.motion {
            Motion::Rapid(_) => {
                let _ = writeln!(self.body, "G0 {}", self.u.xyz(end));
            }
            Motion::Dwell(d) => {
                let _ = writeln!(
                    self.body,
                    "G4 P{:.4}",
                    f64::from(d.frames) / f64::from(self.settings.frame_hz)
                );
            }
            Motion::Linear(l) => {
                let programmed_ipm = acsim::feed_ipm(self.settings, l.f);
                if pts.len() < 2 {
                    // No pulses seen (a block of zero length): as programmed.
                    let _ = writeln!(
                        self.body,
                        "G1 {} {}",
                        self.u.xyz(end),
                        self.u.feed(self.settings, l.f)
                    );
                }
                let plan = if pts.len() >= 2 {
                    let ranges = split(pts, self.opts.split, self.opts.min_piece_mm);
                    lagged(
                        pts,
                        buf,
                        base,
                        ranges,
                        &|seg: &[WalkPoint]| piece_feed(seg, self.opts.air_feed_ipm, self.frm),
                        self.tooth_s,
                    )
                } else {
                    Vec::new()
                };
                for (k, &(s, e, v)) in plan.iter().enumerate() {
                    let seg = &pts[s..=e];
                    let piece_end = if k + 1 == plan.len() {
                        end
                    } else {
                        seg[seg.len() - 1].pos_blu
                    };
                    let piece_start = if k == 0 { self.pos } else { seg[0].pos_blu };
                    let air = seg.iter().all(|p| p.cut_limit_ipm.is_infinite());
                    let f = feed_number(self.settings, v.min(self.frm));
                    let feed_ipm = acsim::feed_ipm(self.settings, f);
                    let predicted_f_n = predicted_peak(seg, feed_ipm, self.kienzle);
                    let length_mm = dist_mm(piece_start, piece_end);
                    let _ = writeln!(
                        self.body,
                        "G1 {} {}",
                        self.u.xyz(piece_end),
                        self.u.feed(self.settings, f)
                    );
                    self.pieces.push(Piece {
                        block: i,
                        line: b.block.line,
                        start: piece_start,
                        end: piece_end,
                        at_mm: self.at_mm,
                        length_mm,
                        programmed_ipm,
                        feed_ipm,
                        air,
                        predicted_f_n,
                        model: model_of(&cov[base + s..=base + e]),
                    });
                    self.at_mm += length_mm;
                }
            }
            Motion::Arc(c) => {
                let programmed_ipm = acsim::feed_ipm(self.settings, c.f);
                let air = pts.iter().all(|p| p.cut_limit_ipm.is_infinite());
                let mut v = piece_feed(pts, self.opts.air_feed_ipm, self.frm);
                if v.is_finite() && !pts.is_empty() {
                    v = v.min(ahead(
                        buf,
                        base + pts.len() - 1,
                        lag_mm(v.min(self.frm), self.tooth_s),
                    ));
                }
                let f = if v.is_finite() {
                    feed_number(self.settings, v.min(self.frm))
                } else {
                    c.f
                };
                let feed_ipm = acsim::feed_ipm(self.settings, f);
                let predicted_f_n = predicted_peak(pts, feed_ipm, self.kienzle);
                if c.plane != self.plane {
                    self.plane = c.plane;
                    let _ = writeln!(
                        self.body,
                        "{}",
                        match self.plane {
                            Plane::XY => "G17",
                            Plane::ZX => "G18",
                            Plane::YZ => "G19",
                        }
                    );
                }
                // The centre's offset from the start: -start (start is relative to the centre).
                let (a, bb) = c.plane.axes();
                let mut off = [0i64; 3];
                off[a] = -i64::from(c.start[0]);
                off[bb] = -i64::from(c.start[1]);
                let words = ["I", "J", "K"];
                let _ = writeln!(
                    self.body,
                    "{} {} {}{} {}{} {}",
                    if c.ccw { "G3" } else { "G2" },
                    self.u.xyz(end),
                    words[a],
                    self.u.coord(off[a]),
                    words[bb],
                    self.u.coord(off[bb]),
                    self.u.feed(self.settings, f)
                );
                let length_mm = pts
                    .windows(2)
                    .map(|p| dist_mm(p[0].pos_blu, p[1].pos_blu))
                    .sum::<f64>();
                self.pieces.push(Piece {
                    block: i,
                    line: b.block.line,
                    start: self.pos,
                    end,
                    at_mm: self.at_mm,
                    length_mm,
                    programmed_ipm,
                    feed_ipm,
                    air,
                    predicted_f_n,
                    model: model_of(&cov[base..w]),
                });
                self.at_mm += length_mm;
            }
        }
        self.pos = end;
    }
}

/// [`optimise`]'s plan of `prog`, the blocks of `text` (its `programmed` run left empty: the
/// caller's).
fn plan(
    text: &str,
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    opts: &Options,
) -> Result<Optimised> {
    crate::progress::set_total(prog.len());
    let limits = OracleLimits {
        f0_n: opts.fraction * cut.tool.f_max_n,
        t0_nm: opts.fraction * cut.tool.t_max_nm,
        // Each run of feed blocks from its limit at the first point, not from rest: the frame
        // starts a block at its feed (the piece takes the smallest over its points anyway).
        from_rest: false,
        ..OracleLimits::for_tool(&cut.tool)
    };
    let frm = acsim::feed_ipm(settings, settings.q0);
    let ceiling = vec![frm; prog.len()];
    crate::progress::stage("limits along the path");
    // The walk on the described stock and, for the guard, on its envelope: the same points.
    let envelope = (opts.guard > 0.0).then(|| acsim::Cut {
        stock: cut.stock.envelope(),
        ..cut.clone()
    });
    let mut walker = Walker::new(prog, settings, cut, &limits, &ceiling);
    let mut worst = envelope
        .as_ref()
        .map(|e| Walker::new(prog, settings, e, &limits, &ceiling));
    // Kienzle's 1 - m: force grows as the feed to it.
    let expo = 1.0 - cut.material.ks_exponent;
    let scale = (opts.guard / opts.fraction).powf(1.0 / expo);
    let mut depths = opts.model.map(|_| Depths::new(cut));
    let first = tooth_s(cut.spindle_rpm, cut.tool.flutes);
    // The chip's lag looks farthest with the slowest tooth of the job.
    let slowest = cut
        .changes
        .iter()
        .map(|c| tooth_s(c.rpm, c.plant.flutes))
        .fold(first, f64::max);
    let mut guarded = 0usize;
    let mut planner = Planner {
        prog,
        settings,
        opts,
        cut,
        part: 0,
        frm,
        tooth_s: first,
        kienzle: expo,
        lag_max_mm: lag_mm(frm, slowest),
        u: units(settings),
        pieces: Vec::new(),
        body: String::new(),
        at_mm: 0.0,
        plane: Plane::XY,
        pos: [0; 3],
        next: 0,
        buf: Vec::new(),
        cov: Vec::new(),
    };
    let (mut ours, mut theirs) = (VecDeque::new(), VecDeque::new());
    let guarding = worst.is_some();
    // The points of both walks, paired, through the guard and the model to the planner.
    let mut settle = |ours: &mut VecDeque<WalkPoint>,
                      theirs: &mut VecDeque<WalkPoint>,
                      planner: &mut Planner,
                      ended: bool|
     -> Result<()> {
        while let Some(mut p) = ours.front().copied() {
            if guarding {
                let Some(w) = theirs.pop_front() else { break };
                if (w.block, w.pos_blu) != (p.block, p.pos_blu) {
                    bail!("the envelope's walk has other points than the stock's");
                }
                guarded += usize::from(guard(&mut p, &w, scale));
            }
            ours.pop_front();
            // With a fitted model: its feed at every point that cuts, the full model's where it
            // does not cover the depth (remembered per point); the full model's peak scaled to
            // the new feed.
            let covered = match (opts.model, depths.as_mut()) {
                (Some(m), Some(d)) => {
                    let a = d.next(&p);
                    if p.cut_limit_ipm.is_infinite() {
                        None
                    } else if let Some(f) = m.feed_for(a, limits.f0_n) {
                        if p.feed_ipm > 0.0 {
                            p.f_peak_n *= (f / p.feed_ipm).powf(expo);
                        }
                        p.feed_ipm = f;
                        Some(true)
                    } else {
                        Some(false)
                    }
                }
                _ => None,
            };
            planner.buf.push(p);
            planner.cov.push(covered);
        }
        if ended && (!ours.is_empty() || !theirs.is_empty()) {
            bail!("the envelope's walk has other points than the stock's");
        }
        planner.ready(ended);
        Ok(())
    };
    let frames = by_block(prog, settings, cut, |i, pts| {
        walker.block(i, pts, &mut |p| ours.push_back(p))?;
        if let Some(w) = worst.as_mut() {
            w.block(i, pts, &mut |p| theirs.push_back(p))?;
        }
        settle(&mut ours, &mut theirs, &mut planner, false)
    })?;
    walker.finish(&frames.spans, &mut |p| ours.push_back(p))?;
    if let Some(w) = worst {
        w.finish(&frames.spans, &mut |p| theirs.push_back(p))?;
    }
    settle(&mut ours, &mut theirs, &mut planner, true)?;
    let Planner {
        pieces, body, u, ..
    } = planner;
    // The speed of the first tool's part (with tool changes, each part's is written at its M6).
    let rpm = if cut.changes.is_empty() {
        analysis::spindle_rpm(text, settings)
    } else {
        cut.spindle_rpm.round() as u32
    };
    let feed_blocks = prog
        .iter()
        .filter(|b| matches!(b.block.motion, Motion::Linear(_) | Motion::Arc(_)))
        .count();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "(millac optimise: offline feed optimisation by virtual machining, Karunakaran et al.)"
    );
    let _ = writeln!(
        out,
        "(each feed block split where the feed the cut allows changes by more than {:.0} %, pieces of at least {} mm;)",
        opts.split * 100.0,
        opts.min_piece_mm
    );
    let _ = writeln!(
        out,
        "(each piece at the largest feed keeping the model's peak force <= F0 = {:.0} N and torque <= T0 = {:.1} N*m,)",
        limits.f0_n, limits.t0_nm
    );
    let _ = writeln!(
        out,
        "(within the acceleration, air cuts up to {:.2} ipm, no feed above FRM {:.2} ipm; geometry unchanged)",
        opts.air_feed_ipm.min(frm),
        frm
    );
    let _ = writeln!(
        out,
        "(tool {:.3} mm, {} flutes, F_max {:.0} N, T_max {:.1} N*m; Ks {:.0} N/mm^2, m {}; spindle {:.0} rpm)",
        cut.tool.diameter_mm,
        cut.tool.flutes,
        cut.tool.f_max_n,
        cut.tool.t_max_nm,
        cut.material.ks_n_mm2,
        cut.material.ks_exponent,
        cut.spindle_rpm
    );
    for c in &cut.changes {
        let _ = writeln!(
            out,
            "(from line {}: T{}, {:.3} mm, {} flutes, F_max {:.0} N, T_max {:.1} N*m, spindle {:.0} rpm: F0, T0 the same fraction of its limits)",
            c.line, c.fitted.number, c.plant.diameter_mm, c.plant.flutes, c.plant.f_max_n, c.plant.t_max_nm, c.rpm
        );
    }
    if let Some(m) = opts.model {
        let _ = writeln!(
            out,
            "(feeds from the fitted model y = {:.2} + {:.3} a + {:.3} f + {:.4} a f + {:.4} a^2 + {:.5} f^2, Georgiev and Chetrokov,)",
            m.b[0], m.b[1], m.b[2], m.b[3], m.b[4], m.b[5]
        );
        let _ = writeln!(
            out,
            "(where the depth is within {}..{} mm and the feed within {}..{} ipm; elsewhere the full force model: {} of {} pieces)",
            m.a_range.0,
            m.a_range.1,
            m.f_range.0,
            m.f_range.1,
            pieces.iter().filter(|p| p.model == Some(false)).count(),
            pieces.len()
        );
    }
    if opts.guard > 0.0 {
        let _ = writeln!(
            out,
            "(guard: where the stock is described as air but could be material, at most the feed that loads such material to {:.0} % of F_max: {} points)",
            opts.guard * 100.0,
            guarded
        );
    } else {
        let _ = writeln!(out, "(no guard: the stock is trusted to be as described)");
    }
    let _ = writeln!(
        out,
        "({} feed blocks became {} pieces)",
        feed_blocks,
        pieces.len()
    );
    let _ = writeln!(out, "{} G90 G17", u.g);
    if rpm != 0 {
        let _ = writeln!(out, "S{rpm} M3");
    }
    out.push_str(&body);
    let _ = writeln!(out, "M2");
    Ok(Optimised {
        text: out,
        pieces,
        f0_n: limits.f0_n,
        t0_nm: limits.t0_nm,
        programmed: HostRun::default(),
    })
}

/// The optimised program parses, every original end point is reached in order, and every axis
/// takes the same pulses as in the original (checked on the parsed output, never assumed).
pub fn check(original: &[ProgBlock], o: &Optimised, settings: &Settings) -> Result<()> {
    let out = analysis::load_program(&o.text, settings)
        .map_err(|e| anyhow!("the optimised program does not parse: {e}"))?;
    let pulses = |p: &[ProgBlock]| {
        p.iter().fold([0u64; 3], |mut a, b| {
            for (s, q) in a.iter_mut().zip(b.pulses) {
                *s += q;
            }
            a
        })
    };
    if pulses(original) != pulses(&out) {
        bail!(
            "pulses per axis differ: original {:?}, optimised {:?}",
            pulses(original),
            pulses(&out)
        );
    }
    let mut ends = out.iter().map(|b| b.end);
    for b in original {
        if !ends.any(|e| e == b.end) {
            bail!(
                "the original end point {:?} (line {}) is not reached in order",
                b.end,
                b.block.line
            );
        }
    }
    Ok(())
}

/// The pieces as CSV (stable column names).
pub fn csv(o: &Optimised) -> String {
    let mut s = String::from(
        "line,at_mm,length_mm,x_end_blu,y_end_blu,z_end_blu,programmed_ipm,feed_ipm,air,predicted_f_n,model\n",
    );
    for p in &o.pieces {
        let _ = writeln!(
            s,
            "{},{:.3},{:.3},{},{},{},{:.3},{:.3},{},{:.1},{}",
            p.line,
            p.at_mm,
            p.length_mm,
            p.end[0],
            p.end[1],
            p.end[2],
            p.programmed_ipm,
            p.feed_ipm,
            p.air as u8,
            p.predicted_f_n,
            match p.model {
                None => "",
                Some(true) => "fitted",
                Some(false) => "out of range",
            }
        );
    }
    s
}

/// Feed before and after along the path (the feed moves' length), and the model's predicted peak
/// force per piece against F0.
pub fn plot(path: &std::path::Path, title: &str, o: &Optimised) -> Result<()> {
    use plotters::prelude::*;
    let root = SVGBackend::new(path, (1000, 650)).into_drawing_area();
    root.fill(&WHITE)?;
    let (upper, lower) = root.split_vertically(360);
    let end = o.pieces.last().map_or(1.0, |p| p.at_mm + p.length_mm);
    let steps = |f: &dyn Fn(&Piece) -> f64| {
        o.pieces
            .iter()
            .flat_map(|p| [(p.at_mm, f(p)), (p.at_mm + p.length_mm, f(p))])
            .collect::<Vec<_>>()
    };
    let top = o
        .pieces
        .iter()
        .map(|p| p.feed_ipm.max(p.programmed_ipm))
        .fold(1.0, f64::max)
        * 1.1;
    let mut chart = ChartBuilder::on(&upper)
        .caption(format!("{title}: feed along the path"), ("sans-serif", 15))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(55)
        .build_cartesian_2d(0f64..end, 0f64..top)?;
    chart
        .configure_mesh()
        .x_desc("path length of the feed moves, mm")
        .y_desc("feed, ipm")
        .draw()?;
    let grey = RGBColor(140, 140, 140);
    chart
        .draw_series(LineSeries::new(
            steps(&|p| p.programmed_ipm),
            grey.stroke_width(2),
        ))?
        .label("programmed")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey));
    chart
        .draw_series(LineSeries::new(
            steps(&|p| p.feed_ipm),
            BLUE.stroke_width(1),
        ))?
        .label("optimised")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    crate::evaluation::plot::legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    let f_top = o
        .pieces
        .iter()
        .map(|p| p.predicted_f_n)
        .fold(o.f0_n, f64::max)
        * 1.1;
    let mut chart = ChartBuilder::on(&lower)
        .caption(
            "model's peak force per piece at its feed",
            ("sans-serif", 15),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(0f64..end, 0f64..f_top)?;
    chart
        .configure_mesh()
        .x_desc("path length of the feed moves, mm")
        .y_desc("force, N")
        .draw()?;
    chart
        .draw_series(LineSeries::new(
            steps(&|p| p.predicted_f_n),
            BLUE.stroke_width(1),
        ))?
        .label("predicted peak F")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    chart
        .draw_series(LineSeries::new(
            [(0.0, o.f0_n), (end, o.f0_n)],
            BLACK.stroke_width(1),
        ))?
        .label("F0")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    crate::evaluation::plot::legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// The combined controller's figure (host; `predict_bench`): the peak force of every AC period
/// over F_max against time for each run (the plan alone, the plan under the AC), with F0 and
/// the limit, and below it the plan ratio k the AC set (the runs with AC). `fraction` is F0 /
/// F_max; `f_max` the AC's FRM feed number (k = logged feed number / f_max).
pub fn plot_combined(
    path: &std::path::Path,
    title: &str,
    runs: &[(&str, &acsim::HostRun)],
    tool_f_max_n: f64,
    fraction: f64,
    f_max: u32,
) -> Result<()> {
    use plotters::prelude::*;
    let root = SVGBackend::new(path, (1000, 650)).into_drawing_area();
    root.fill(&WHITE)?;
    let (upper, lower) = root.split_vertically(380);
    let end = runs
        .iter()
        .map(|(_, r)| r.rows.last().map_or(0.0, |x| x.t_ms as f64 * 1e-3))
        .fold(1.0, f64::max);
    let colours = [RGBColor(150, 150, 150), BLUE, RED, GREEN];
    let mut chart = ChartBuilder::on(&upper)
        .caption(
            format!("{title}: peak force per AC period"),
            ("sans-serif", 15),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(55)
        .build_cartesian_2d(0f64..end, 0f64..1.2)?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc("F / F_max")
        .draw()?;
    for (i, (name, r)) in runs.iter().enumerate() {
        let c = colours[i % colours.len()];
        chart
            .draw_series(LineSeries::new(
                r.rows
                    .iter()
                    .map(|x| (x.t_ms as f64 * 1e-3, x.f_true_n / tool_f_max_n)),
                c.stroke_width(1),
            ))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c));
    }
    for (level, name) in [(fraction, "F0"), (1.0, "F_max (the limit)")] {
        chart
            .draw_series(LineSeries::new(
                [(0.0, level), (end, level)],
                BLACK.stroke_width(1),
            ))?
            .label(name)
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    }
    crate::evaluation::plot::legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    let mut chart = ChartBuilder::on(&lower)
        .caption("plan ratio k the AC sets ($263=2)", ("sans-serif", 15))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(0f64..end, 0.7f64..1.05)?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc("k")
        .draw()?;
    for (i, (name, r)) in runs.iter().enumerate() {
        if r.rows.first().is_none_or(|x| x.feed_cap == u32::MAX) {
            continue;
        }
        let c = colours[i % colours.len()];
        chart
            .draw_series(LineSeries::new(
                r.rows.iter().map(|x| {
                    (
                        x.t_ms as f64 * 1e-3,
                        f64::from(x.feed_cap) / f64::from(f_max),
                    )
                }),
                c.stroke_width(1),
            ))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c));
    }
    crate::evaluation::plot::legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(x: i64, v: f64) -> WalkPoint {
        WalkPoint {
            block: 0,
            pos_blu: [x, 0, 0],
            feed_ipm: v,
            limit_ipm: v,
            cut_limit_ipm: v,
            f_peak_n: 0.0,
            t_peak_nm: 0.0,
        }
    }

    /// Pieces cover the block end to end, share their boundary points, split where the schedule
    /// leaves its band, and a short tail joins the piece before it.
    #[test]
    fn split_covers_the_block_and_follows_the_schedule() {
        // 1 mm = 394 BLU at 0.0001 in. 10 mm at 20 ipm, then 10 mm at 10 ipm, then 0.2 mm at 30.
        let mut pts: Vec<WalkPoint> = (0..=3937).map(|x| pt(x, 20.0)).collect();
        pts.extend((3938..=7874).map(|x| pt(x, 10.0)));
        pts.extend((7875..=7953).map(|x| pt(x, 30.0)));
        let r = split(&pts, 0.1, 1.0);
        assert_eq!(r.first().unwrap().0, 0);
        assert_eq!(r.last().unwrap().1, pts.len() - 1);
        for w in r.windows(2) {
            assert_eq!(w[0].1, w[1].0);
        }
        assert_eq!(r.len(), 2, "{r:?}");
        assert_eq!(
            r[0].1, 3937,
            "the first piece ends at the last point at 20 ipm"
        );
        // One feed throughout: one piece.
        let flat: Vec<WalkPoint> = (0..1000).map(|x| pt(x, 12.0)).collect();
        assert_eq!(split(&flat, 0.1, 1.0), [(0, 999)]);
    }
}
