//! Shared helpers of the host integration tests (host): random valid G-code programs with their
//! expected geometry computed independently of the parser (exact positions in nanometres, rounded
//! to BLU once), the tape + frame run that turns a program into pulses, and the per-block trace.
#![allow(dead_code)] // each test crate uses a part of it

use millac::gcode::tape::{Tape, TapeError};
use millac::nc::sim::{Sim, SimFrame};
use millac::nc::{Block, Frame, FrameConfig, Motion, Sealed};
use millac::Settings;
use proptest::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Nanometres per BLU (0.0001 in) of the default settings.
pub const NM_PER_BLU: i64 = 2540;
/// Nanometres per program unit: the last decimal of an inch word (4 decimals) or a mm word (3).
pub const NM_PER_INCH_UNIT: i64 = 2540;
pub const NM_PER_MM_UNIT: i64 = 1000;
/// Where random targets stay (BLU): inside the default soft limits with room for arcs.
pub const REACH: [i64; 3] = [60_000, 60_000, 12_000];
/// Soft limits of the default settings (BLU), the arcs' extent must stay inside.
pub const SOFT: [i64; 3] = [100_000, 100_000, 40_000];

/// `n / d` rounded half away from zero (d > 0): the parser's rounding of an exact length.
pub fn round_div(n: i128, d: i128) -> i64 {
    let q = (2 * n.abs() + d) / (2 * d);
    (if n < 0 { -q } else { q }) as i64
}

/// A word value of `n` program units with `dec` decimals, e.g. (-12345, 4) -> "-1.2345".
pub fn word(n: i64, dec: u32) -> String {
    let p = 10u64.pow(dec);
    let a = n.unsigned_abs();
    let sign = if n < 0 { "-" } else { "" };
    format!("{sign}{}.{:0w$}", a / p, a % p, w = dec as usize)
}

/// Machine BLU of an exact position in nm.
pub fn blu(nm: [i64; 3]) -> [i64; 3] {
    nm.map(|v| round_div(v as i128, NM_PER_BLU as i128))
}

/// Machine axes (a, b) of a plane: 0 = G17 (X, Y), 1 = G18 (Z, X), 2 = G19 (Y, Z).
pub const PLANES: [(usize, usize); 3] = [(0, 1), (2, 0), (1, 2)];

/// The shape of an expected block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    Rapid,
    Line,
    /// Centre in BLU (the third axis at the block's height), the plane's axes, direction.
    Arc {
        centre: [i64; 3],
        axes: (usize, usize),
        ccw: bool,
    },
}

/// What a motion line must produce.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Expect {
    pub line: u32,
    pub start: [i64; 3],
    pub end: [i64; 3],
    pub shape: Shape,
    /// The feed number of a feed move, f = q0 FR / FRM, from the F word in force.
    pub f: u32,
}

/// One random move before it is fitted to the position it starts from.
#[derive(Clone, Copy, Debug)]
pub enum Kind {
    Rapid,
    Line,
    /// Radius in BLU, start angle of the start point seen from the centre, sweep (radians).
    Arc {
        plane: usize,
        ccw: bool,
        radius: i64,
        a0: f64,
        sweep: f64,
    },
}

#[derive(Clone, Copy, Debug)]
pub struct RawMove {
    pub kind: Kind,
    pub mm: bool,
    pub incremental: bool,
    /// Target of a line or rapid, BLU (absolute; incremental words are derived from it).
    pub target: [i64; 3],
    /// Axis words left out of a line or rapid (bit k = axis k).
    pub omit: u8,
    /// A new feed in tenths of an ipm, or keep the modal one.
    pub feed_tenths: Option<u32>,
}

pub fn kind() -> impl Strategy<Value = Kind> {
    prop_oneof![
        1 => Just(Kind::Rapid),
        2 => Just(Kind::Line),
        2 => (0usize..3, any::<bool>(), 500i64..12_000, 0.0..TAU, 0.25..(TAU - 0.25)).prop_map(
            |(plane, ccw, radius, a0, sweep)| Kind::Arc { plane, ccw, radius, a0, sweep }
        ),
    ]
}

pub fn raw_move() -> impl Strategy<Value = RawMove> {
    (
        kind(),
        any::<bool>(),
        any::<bool>(),
        [
            -REACH[0]..=REACH[0],
            -REACH[1]..=REACH[1],
            -REACH[2]..=REACH[2],
        ],
        0u8..8,
        proptest::option::of(50u32..=300),
    )
        .prop_map(
            |(kind, mm, incremental, target, omit, feed_tenths)| RawMove {
                kind,
                mm,
                incremental,
                target,
                omit,
                feed_tenths,
            },
        )
}

/// A program: its lines (without line ends) and what each motion line must produce.
#[derive(Clone, Debug, Default)]
pub struct Program {
    pub lines: Vec<String>,
    pub expect: Vec<Expect>,
    /// Exact programmed position at the end (nm).
    pub end_nm: [i64; 3],
}

impl Program {
    /// The program text, every line ended by `eol` (empty for no lines).
    pub fn text(&self, eol: &str) -> String {
        self.lines.iter().map(|l| format!("{l}{eol}")).collect()
    }
    /// Machine position at the end (BLU).
    pub fn end(&self) -> [i64; 3] {
        blu(self.end_nm)
    }
}

/// Builds a program from random moves, starting at the origin in G20 G90 with no feed. Moves that
/// would leave the soft limits (arcs) are left out; a move that does not move the machine (its
/// target rounds to the current BLU) is kept as a line without a block.
#[derive(Default)]
pub struct Builder {
    pub prog: Program,
    pos: [i64; 3],
    mm: bool,
    incremental: bool,
    plane: usize,
    /// Feed number in force (0: none yet).
    f: u32,
}

impl Builder {
    fn unit(&self) -> (i64, u32) {
        if self.mm {
            (NM_PER_MM_UNIT, 3)
        } else {
            (NM_PER_INCH_UNIT, 4)
        }
    }

    /// Modal words to switch units and distance mode, and the feed word (with `fresh` or when no
    /// feed is in force yet; `feed_move` false: rapids need none).
    fn preamble(&mut self, m: &RawMove, feed_move: bool) -> String {
        let mut s = String::new();
        if m.mm != self.mm {
            s.push_str(if m.mm { "G21 " } else { "G20 " });
            self.mm = m.mm;
        }
        if m.incremental != self.incremental {
            s.push_str(if m.incremental { "G91 " } else { "G90 " });
            self.incremental = m.incremental;
        }
        let tenths = match (m.feed_tenths, feed_move && self.f == 0) {
            (Some(t), _) => Some(t),
            (None, true) => Some(100),
            (None, false) => None,
        };
        if let Some(t) = tenths {
            // F in ipm with one decimal, or the same speed in whole mm/min.
            let (text, f) = if self.mm {
                let mm_min = round_div(t as i128 * 254, 100);
                // f = q0 * FR / FRM: FR = mm_min * 100000/254 BLU/min, FRM = W0 * 60 BLU/min.
                (
                    format!("F{mm_min} "),
                    feed_number(mm_min as i128 * 100_000, 254),
                )
            } else {
                (
                    format!("F{} ", word(t as i64, 1)),
                    feed_number(t as i128 * 1000, 1),
                )
            };
            s.push_str(&text);
            self.f = f.max(1);
        }
        s
    }

    /// Adds one line (or none, for an arc that would leave the soft limits).
    pub fn push(&mut self, m: &RawMove) {
        match m.kind {
            Kind::Rapid | Kind::Line => self.push_line(m),
            Kind::Arc { .. } => self.push_arc(m),
        }
    }

    fn push_line(&mut self, m: &RawMove) {
        let feed = matches!(m.kind, Kind::Line);
        let mut s = self.preamble(m, feed);
        s.push_str(if feed { "G1" } else { "G0" });
        let (unit, dec) = self.unit();
        let start = blu(self.pos);
        let mut pos = self.pos;
        for k in 0..3 {
            if m.omit & (1 << k) != 0 {
                continue;
            }
            let t = m.target[k] * NM_PER_BLU;
            let n = if self.incremental {
                round_div((t - self.pos[k]) as i128, unit as i128)
            } else {
                round_div(t as i128, unit as i128)
            };
            pos[k] = if self.incremental {
                self.pos[k] + n * unit
            } else {
                n * unit
            };
            s.push_str(&format!(" {}{}", ["X", "Y", "Z"][k], word(n, dec)));
        }
        self.finish_line(s, start, pos, if feed { Shape::Line } else { Shape::Rapid });
    }

    fn push_arc(&mut self, m: &RawMove) {
        let Kind::Arc {
            plane,
            ccw,
            radius,
            a0,
            sweep,
        } = m.kind
        else {
            return;
        };
        let (ia, ib) = PLANES[plane];
        let r_nm = (radius * NM_PER_BLU) as f64;
        let (unit, dec) = if m.mm {
            (NM_PER_MM_UNIT, 3)
        } else {
            (NM_PER_INCH_UNIT, 4)
        };
        // Centre offsets from the start, in program units, and the exact centre.
        let off = [
            (-r_nm * a0.cos() / unit as f64).round() as i64,
            (-r_nm * a0.sin() / unit as f64).round() as i64,
        ];
        let c = [self.pos[ia] + off[0] * unit, self.pos[ib] + off[1] * unit];
        for (ck, k) in c.iter().zip([ia, ib]) {
            if (ck.abs() + 2 * NM_PER_BLU) / NM_PER_BLU + radius + 2 > SOFT[k] {
                return;
            }
        }
        let a1 = if ccw { a0 + sweep } else { a0 - sweep };
        let e = [c[0] as f64 + r_nm * a1.cos(), c[1] as f64 + r_nm * a1.sin()];
        // Ends anywhere, also just past an axis crossing and a BLU outside the start's circle (the
        // rounding of the centre and the end): the parser accepts them, as grbl does.
        let mut s = self.preamble(m, true);
        if plane != self.plane {
            s.push_str(["G17 ", "G18 ", "G19 "][plane]);
            self.plane = plane;
        }
        s.push_str(if ccw { "G3" } else { "G2" });
        let start = blu(self.pos);
        let mut pos = self.pos;
        for (ek, k) in e.iter().zip([ia, ib]) {
            let n = if self.incremental {
                ((ek - self.pos[k] as f64) / unit as f64).round() as i64
            } else {
                (ek / unit as f64).round() as i64
            };
            pos[k] = if self.incremental {
                self.pos[k] + n * unit
            } else {
                n * unit
            };
            s.push_str(&format!(" {}{}", ["X", "Y", "Z"][k], word(n, dec)));
        }
        for (o, k) in off.iter().zip([ia, ib]) {
            s.push_str(&format!(" {}{}", ["I", "J", "K"][k], word(*o, dec)));
        }
        let mut centre = start;
        centre[ia] = round_div(c[0] as i128, NM_PER_BLU as i128);
        centre[ib] = round_div(c[1] as i128, NM_PER_BLU as i128);
        let shape = Shape::Arc {
            centre,
            axes: (ia, ib),
            ccw,
        };
        self.finish_line(s, start, pos, shape);
    }

    fn finish_line(&mut self, text: String, start: [i64; 3], pos: [i64; 3], shape: Shape) {
        self.prog.lines.push(text);
        let line = self.prog.lines.len() as u32;
        self.pos = pos;
        self.prog.end_nm = pos;
        let end = blu(pos);
        if end != start || matches!(shape, Shape::Arc { .. }) {
            self.prog.expect.push(Expect {
                line,
                start,
                end,
                shape,
                f: if shape == Shape::Rapid { 0 } else { self.f },
            });
        }
    }
}

/// The feed number of a feed of `blu_per_min_num / den` BLU per minute at the default settings:
/// f = q0 FR / FRM, rounded, FRM = W0 * 60 BLU/min, at least 1, at most q0.
pub fn feed_number(blu_per_min_num: i128, den: i128) -> u32 {
    let s = Settings::default();
    let f = round_div(
        blu_per_min_num * s.q0 as i128,
        den * s.frame_hz as i128 * 60,
    );
    f.clamp(1, s.q0 as i64) as u32
}

pub fn program(moves: &[RawMove]) -> Program {
    let mut b = Builder::default();
    for m in moves {
        b.push(m);
    }
    b.prog
}

/// Random programs of 1..`n` moves.
pub fn programs(n: usize) -> impl Strategy<Value = Program> {
    proptest::collection::vec(raw_move(), 1..n).prop_map(|m| program(&m))
}

/// Reads `text` through the tape in chunks of `chunk` bytes (the loader's way): the blocks
/// emitted, and the error if the tape refused a line.
pub fn tape(text: &str, chunk: usize) -> (Vec<Sealed>, Option<TapeError>) {
    let mut t = Tape::new(Settings::default());
    let mut blocks = Vec::new();
    for c in text.as_bytes().chunks(chunk.max(1)) {
        if let Err(e) = t.feed(c, |b| blocks.push(b)) {
            return (blocks, Some(e));
        }
    }
    let err = t.finish(|b| blocks.push(b)).err();
    (blocks, err)
}

/// Runs blocks through the frame from the origin until the last is done.
pub fn run(blocks: &[Sealed]) -> Vec<SimFrame> {
    let s = Settings::default();
    let mut frame = Frame::new(FrameConfig::from_settings(&s));
    let frames: Vec<SimFrame> =
        Sim::new(&mut frame, blocks.iter().copied(), u32::MAX, 50_000_000).collect();
    assert_eq!(
        frame.blocks_done() as usize,
        blocks.len(),
        "the frame ran every block"
    );
    frames
}

/// One block as the pulses show it.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    /// Position (from the pulses) before the block and after each of its frames.
    pub path: Vec<[i64; 3]>,
    /// Pulses per axis.
    pub pulses: [u64; 3],
    /// Frames the block took.
    pub frames: u64,
}

impl Trace {
    pub fn end(&self) -> [i64; 3] {
        *self.path.last().unwrap_or(&[0; 3])
    }
}

/// Splits a frame run into per-block traces, integrating the pulses with their signs (the pulses
/// are the output; the frame's own position counter is checked against them).
pub fn traces(frames: &[SimFrame], n_blocks: usize) -> Vec<Trace> {
    let mut out: Vec<Trace> = (0..n_blocks).map(|_| Trace::default()).collect();
    let mut pos = [0i64; 3];
    for f in frames {
        let Some(t) = out.get_mut(f.block as usize) else {
            continue;
        };
        if t.path.is_empty() {
            t.path.push(pos);
        }
        for (k, (p, n)) in pos.iter_mut().zip(t.pulses.iter_mut()).enumerate() {
            if f.pulses.steps & (1 << k) != 0 {
                *p += if f.pulses.signs & (1 << k) != 0 {
                    1
                } else {
                    -1
                };
                *n += 1;
            }
        }
        assert_eq!(pos, f.position.map(i64::from), "pulses vs position counter");
        t.path.push(pos);
        t.frames += 1;
    }
    out
}

/// Distance of `p` from the line through `a` and `b` (a != b).
pub fn line_distance(p: [i64; 3], a: [i64; 3], b: [i64; 3]) -> f64 {
    let d: Vec<f64> = (0..3).map(|k| (b[k] - a[k]) as f64).collect();
    let v: Vec<f64> = (0..3).map(|k| (p[k] - a[k]) as f64).collect();
    let c = [
        v[1] * d[2] - v[2] * d[1],
        v[2] * d[0] - v[0] * d[2],
        v[0] * d[1] - v[1] * d[0],
    ];
    let n = |x: &[f64]| x.iter().map(|y| y * y).sum::<f64>().sqrt();
    n(&c) / n(&d)
}

/// The travel per plane axis of the arc from `p0` to `p1` (relative to the centre, BLU) on the
/// circle of radius `r` (the frame's rounded radius): the sum of the monotone pieces between the
/// axis crossings. None when an end lies within 1 BLU of an axis (the crossing is ambiguous).
pub fn arc_travel(p0: [i64; 2], p1: [i64; 2], ccw: bool, r: i64) -> Option<[u64; 2]> {
    if p0.iter().chain(p1.iter()).any(|v| v.abs() <= 1) {
        return None;
    }
    let ang = |p: [i64; 2]| (p[1] as f64).atan2(p[0] as f64).rem_euclid(TAU);
    let (t0, t1) = (ang(p0), ang(p1));
    let sweep = if ccw {
        (t1 - t0).rem_euclid(TAU)
    } else {
        (t0 - t1).rem_euclid(TAU)
    };
    let on_axis = |m: i64| match m.rem_euclid(4) {
        0 => [r, 0],
        1 => [0, r],
        2 => [-r, 0],
        _ => [0, -r],
    };
    let mut pts = vec![p0];
    if ccw {
        let mut m = (t0 / FRAC_PI_2).floor() as i64 + 1;
        while (m as f64) * FRAC_PI_2 < t0 + sweep {
            pts.push(on_axis(m));
            m += 1;
        }
    } else {
        let mut m = (t0 / FRAC_PI_2).ceil() as i64 - 1;
        while (m as f64) * FRAC_PI_2 > t0 - sweep {
            pts.push(on_axis(m));
            m -= 1;
        }
    }
    pts.push(p1);
    let mut t = [0u64; 2];
    for w in pts.windows(2) {
        t[0] += (w[1][0] - w[0][0]).unsigned_abs();
        t[1] += (w[1][1] - w[0][1]).unsigned_abs();
    }
    Some(t)
}

/// Sweep of an arc in radians, from its end points relative to the centre.
pub fn arc_sweep(p0: [i64; 2], p1: [i64; 2], ccw: bool) -> f64 {
    let ang = |p: [i64; 2]| (p[1] as f64).atan2(p[0] as f64);
    let d = if ccw {
        ang(p1) - ang(p0)
    } else {
        ang(p0) - ang(p1)
    };
    let s = d.rem_euclid(TAU);
    if s == 0.0 {
        TAU
    } else {
        s.min(2.0 * PI)
    }
}

/// The motion blocks' line numbers, in order.
pub fn lines_of(blocks: &[Sealed]) -> Vec<u32> {
    blocks.iter().map(|b| b.line).collect()
}

/// True for a feed block that runs at its feed to the end (no deceleration).
pub fn steady(b: &Block) -> bool {
    match b.motion {
        Motion::Linear(l) => !l.decel,
        Motion::Arc(a) => !a.decel,
        Motion::Rapid(_) | Motion::Dwell(_) => false,
    }
}
