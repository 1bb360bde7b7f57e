//! The frame: Initiator, PTP, feed DDA, linear and circular DDA interpolators, output and position
//! counters (Fig. 4 and Fig. 5 of the paper). `Frame::tick` runs once per frame interrupt (ISR):
//! integers only, no panics, no allocation, no loops over data-dependent lengths.
//!
//! Per tick (the paper's "major part"):
//! - Initiator: with no block loaded, take the next validated block and load the registers.
//! - PTP: each axis pulses independently at the rapid rate (the frame timer is retimed to
//!   `rapid_hz` while a PTP block runs, see [`Rate`]); within `ptp_steps[k]` pulses of either end
//!   of its move an axis pulses only every 2nd, 4th, 8th rapid frame: the paper's three-step
//!   deceleration, mirrored as a three-step acceleration at the start (beyond the paper, so that
//!   stepper drives do not stall).
//! - Operator (beyond the paper): the operator's word (see [`super::operator`]) is read once per
//!   frame: its abort bit stops at once and drops the queue one block per frame; a hold (factor 0)
//!   keeps the Initiator from starting a block, stops a dwell's clock, ramps a feed block to 0 and
//!   walks a rapid down its ladder; the rapid override masks rapid frames.
//! - Feed: r0 += v; an overflow of q0 is one interpolation command, so commands come at W0 v / q0
//!   (r0, v and q0 in Q8). The velocity v follows min(f, AC cap) x the operator's factor by at most
//!   the block's acceleration ramp per frame (from 0 when the block starts from a stop; a chained
//!   line keeps it). A block flagged for deceleration caps v at once at f_eff = max(f / 5,
//!   min(f, K * remaining / 256)): velocity proportional to the remaining path, i.e. an
//!   exponential approach to 20 % of f (the paper's rule, not ramped).
//! - Interpolator: per command one DDA cycle. Linear: r_k += |d_k|, overflow past q = L -> pulse.
//!   Circular (the paper's DDA with a radius-error correction beyond it): the faster axis of the
//!   plane runs the DDA, r += max(|i|, |j|), overflow past q -> pulse; with it the slower axis
//!   pulses when that brings the point nearer the circle (the radius error e = i^2 + j^2 - R0^2
//!   follows every pulse exactly), so the path stays within half a BLU of the circle; every pulse
//!   moves i or j. A helix's third axis runs a linear DDA of |helix| over the arc's length. The
//!   arc runs segment by segment (axis crossings, see [`super::block::Arc`]); an axis whose
//!   segment counter is zero gets no more pulses, when one axis of a segment is done the other
//!   pulses at the DDA's rate, and a helix's third axis finishes once per command after the
//!   plane.
//! - Output and Position: the pulses with the current signs; counters decremented per pulse,
//!   absolute position updated. A line is done in the frame of its q-th command, a dwell in its
//!   last frame, a PTP block or an arc in the frame after its last pulse (which does nothing
//!   else); the Initiator runs the tick after that. An arc loads its first segment in the frame
//!   after the block (each frame loads one set of registers at most).
//! - Chained lines (beyond the paper): when a line is followed by a line, the frame of its last
//!   command also starts the next one, so a chain of short CAM segments costs no load frame and
//!   runs at its programmed feed (a load frame per block made 10-BLU blocks 10 % slow and 1-BLU
//!   blocks 50 %). For that a line's DDA registers |d_k|, q and the position steps `dir` are read in
//!   place from the front block of the queue in every command frame (never copied: a copy made
//!   the chaining frame 191 instructions, reading in place 176; docs/dev/results-nc.md's budget table has the
//!   figures);
//!   starting it only sets the remainders, the command count and the feed registers. Arcs, rapids
//!   and dwells still load in a frame of their own.
use super::block::{dirs, Block, Linear, Motion, Sealed};
use super::operator;
use crate::ports::{BlockSource, FeedCap};
use crate::settings::Settings;

/// The frame's share of the settings, precomputed in task context.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameConfig {
    /// q0 in Q8: the feed DDA runs on velocities in Q8 (see [`Frame`]'s `v`).
    pub q0_q8: u32,
    pub decel_gain_q8: u32,
    pub ptp_steps: [u32; 3],
    /// Acceleration limit per axis as a velocity change per frame, in Q8 feed numbers:
    /// a_k q0 256 / W0^2 (a feed number f is W0 f / q0 BLU/s), at least 1.
    pub accel_q8: [u32; 3],
}

impl FrameConfig {
    pub const fn from_settings(s: &Settings) -> Self {
        FrameConfig {
            q0_q8: s.q0 << 8,
            decel_gain_q8: s.decel_gain_q8(),
            ptp_steps: s.ptp_steps,
            accel_q8: [
                accel_q8(s, s.accel_blu_s2[0]),
                accel_q8(s, s.accel_blu_s2[1]),
                accel_q8(s, s.accel_blu_s2[2]),
            ],
        }
    }
}

/// An acceleration of `a` BLU/s^2 as a velocity change per frame in Q8 feed numbers, rounded, at
/// least 1 (the ramp's resolution is 1/256 of a feed number per frame), at most
/// [`super::block::RAMP_MAX`] (no limit).
const fn accel_q8(s: &Settings, a: u32) -> u32 {
    let w2 = s.frame_hz as u64 * s.frame_hz as u64;
    let v = (a as u64 * s.q0 as u64 * 256 + w2 / 2) / w2;
    if v == 0 {
        1
    } else if v > super::block::RAMP_MAX as u64 {
        super::block::RAMP_MAX
    } else {
        v as u32
    }
}

/// Which timer period the next frame wants: W0 (contouring, dwell, idle) or the rapid rate (PTP).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rate {
    Feed,
    Rapid,
}

/// What one frame outputs: bit k of `steps` = one pulse on axis k; `signs` bit k set = axis k
/// positive. `signs` holds the last direction of every axis, also of axes that do not step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Pulses {
    pub steps: u8,
    pub signs: u8,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Idle,
    Rapid,
    Linear,
    Arc,
    Dwell,
}

/// The NC state: DDA registers, counters, position. One instance lives in the frame ISR's locals.
pub struct Frame {
    /// The registers of arcs and PTP, in a line's layout (lines read theirs in place from the
    /// queue, see the module doc). Arcs use q, f, f_floor, decel_below, ramp and dir; PTP uses `steps`
    /// as n_k + 1 (n_k + 1 - count[k] is the pulses done + 1, for the acceleration steps) and dir.
    /// `dir` is the negated position step per pulse and axis, -1 or +1 (see [`dirs`]), meaningful
    /// for the axes that move. f_floor = max(f / 5, 1) is the deceleration floor; K * remaining /
    /// 256 < f only below decel_below commands left (0: no deceleration), so the frames before it
    /// skip the multiply. (The layout was measured: these fields as one struct give the shortest
    /// worst-case frame.)
    regs: Linear,
    /// DDA r registers (accumulators). Arc: [r_a, r_b, _].
    acc: [u32; 3],
    /// Feed DDA accumulator (Q8) and commands left (for deceleration).
    r0: u32,
    /// The feed velocity: the feed number (Q8) added to r0 in this frame. It follows the target
    /// (the programmed feed capped by the AC, times the operator's factor) at most `ramp` per frame
    /// up or down, and falls at once to the paper's deceleration curve. 0 at the start of a block
    /// that starts from a stop; carried over into a chained line.
    v: u32,
    /// PTP hold ladder: a cap on the pulses-done-or-left figure that picks the ladder's level. It
    /// counts down by one per pulse of the ladder's own level while the operator holds (0: stopped),
    /// and back up to ptp_steps[0] + 1 (no effect) once the hold is released, so a rapid stops and
    /// restarts on the same three steps as at its ends.
    ptp_m: u32,
    remaining: u32,
    cfg: FrameConfig,
    mode: Mode,
    position: [i32; 3],
    signs: u8,
    blocks_done: u32,
    /// PTP position counters: pulses left per axis (a line ends after q commands, an arc's
    /// segment counters are `ca`, `cb`, a dwell counts `ticks`).
    count: [u32; 3],
    /// PTP frame counter; dwell frames left.
    ticks: u32,
    /// Arc state: axis bits of a, b and the third axis, the registers i, j (position relative to
    /// the centre) times their unit steps, ti = da i and tj = db j (a pulse adds 1 to them, and
    /// |ti| = |i|), the radius error e = i^2 + j^2 - (i0^2 + j0^2) (|e| < 2^31: the parser keeps R
    /// within [`super::block::R_MAX`]), segment counters of a and b, unit steps da, db of i and j
    /// (+1 or -1), segments; a helix's third axis: |helix| (0 for a plane arc), the arc's length
    /// (its DDA modulus), pulses left.
    bit_a: u8,
    bit_b: u8,
    bit_z: u8,
    ti: i32,
    tj: i32,
    e: i32,
    ca: u32,
    cb: u32,
    da: i32,
    db: i32,
    seg: u8,
    n_seg: u8,
    hz: u32,
    hq: u32,
    cz: u32,
}

impl Frame {
    pub const fn new(cfg: FrameConfig) -> Self {
        Frame {
            cfg,
            mode: Mode::Idle,
            position: [0; 3],
            signs: 0,
            blocks_done: 0,
            count: [0; 3],
            regs: Linear {
                steps: [0; 3],
                q: 1,
                f: 0,
                f_floor: 1,
                decel_below: 0,
                ramp: 0,
                dir: [1; 3],
                signs: 0,
                decel: false,
            },
            acc: [0; 3],
            r0: 0,
            v: 0,
            ptp_m: 0,
            remaining: 0,
            ticks: 0,
            bit_a: 1,
            bit_b: 2,
            bit_z: 4,
            ti: 0,
            tj: 0,
            e: 0,
            ca: 0,
            cb: 0,
            da: 1,
            db: 1,
            seg: 0,
            n_seg: 0,
            hz: 0,
            hq: 1,
            cz: 0,
        }
    }

    /// One frame. `src` is the Initiator's block source: the running block stays at its front until
    /// it is done (the arc reads its segment targets there), then it is popped.
    /// `feed_cap` is the adaptive controller's feed number (u32::MAX = no cap, 0 = feed hold),
    /// read only by the frames that run the feed DDA (see [`FeedCap`]).
    ///
    /// Bounded work per frame: a frame that loads registers (a new block, or the next arc
    /// segment) runs no DDA cycle and emits no pulse; only the loaded block's sign lines change.
    #[inline]
    pub fn tick(&mut self, src: &mut impl BlockSource, feed_cap: impl FeedCap) -> Pulses {
        let op = feed_cap.operator();
        if op & operator::ABORT != 0 {
            // Soft reset: stop at once (the pulses computed before stay counted and go out), drop
            // one queued block per frame (bounded work) until the loader lifts the abort.
            self.mode = Mode::Idle;
            self.v = 0;
            if src.front().map(Sealed::block).is_some() {
                src.pop();
            }
            return Pulses {
                steps: 0,
                signs: self.signs,
            };
        }
        if self.mode == Mode::Idle {
            // A hold keeps the next block from starting.
            if !operator::held(op) {
                if let Some(b) = src.front().map(Sealed::block) {
                    self.initiate(b);
                }
            }
            return Pulses {
                steps: 0,
                signs: self.signs,
            };
        }
        match self.mode {
            Mode::Idle => {}
            // A rapid (or arc) ends in the frame after its last pulses: that frame only pops it,
            // so the frame with the last ladder (or DDA) cycle does no end-of-block work.
            Mode::Rapid => {
                if self.count[0] | self.count[1] | self.count[2] == 0 {
                    self.done(src);
                } else {
                    // The ladder moves the position counters itself.
                    let steps = self.ptp(op);
                    return Pulses {
                        steps,
                        signs: self.signs,
                    };
                }
            }
            // A line ends in the frame of its last command (its duration is q commands), and when
            // the next block is a line too, that frame also loads it: a chain of lines costs no
            // load frame, so short blocks run at their programmed feed.
            Mode::Linear => {
                // The line's registers are read in place, from the front block (never copied).
                let (steps, signs) = match src.front().map(Sealed::block) {
                    Some(Block {
                        motion: Motion::Linear(l),
                        ..
                    }) => {
                        let cap = feed_cap.feed_cap();
                        let planned = feed_cap.planned(l.f);
                        if !self.feed(cap, planned, op, l.f_floor, l.decel_below, l.ramp) {
                            return Pulses {
                                steps: 0,
                                signs: self.signs,
                            };
                        }
                        let steps = self.linear(&l.steps, l.q);
                        self.position_update(steps, &l.dir);
                        (steps, self.signs)
                    }
                    // Not reached: the running line stays the front block until it is done.
                    // Were it not, nothing would move (no pulse, no command): ending it here
                    // too was measured to cost every frame 3 to 8 instructions.
                    _ => (0, self.signs),
                };
                // q commands give exactly |d_k| overflows per axis (see `linear`). The frame of the
                // last command also starts the next block when that is a line (no copy: its
                // registers are read in place), so a chain of lines costs no load frame. The
                // pulses go out with this block's signs; the next block's apply from its own first
                // pulses (the next frame's).
                if self.remaining == 0 {
                    self.done(src);
                    if let Some(Block {
                        motion: Motion::Linear(l),
                        ..
                    }) = src.front().map(Sealed::block)
                    {
                        self.load_linear(l);
                    }
                }
                return Pulses { steps, signs };
            }
            Mode::Arc => {
                let plane_done = self.ca | self.cb == 0;
                if plane_done && self.seg.wrapping_add(1) < self.n_seg {
                    // The previous frame finished a segment (or the block started with an empty
                    // one): load the next one.
                    self.seg = self.seg.wrapping_add(1);
                    self.load_segment(src);
                } else if plane_done && self.cz == 0 {
                    self.done(src);
                } else if self.feed(
                    feed_cap.feed_cap(),
                    feed_cap.planned(self.regs.f),
                    op,
                    self.regs.f_floor,
                    self.regs.decel_below,
                    self.regs.ramp,
                ) {
                    let steps = self.circular();
                    let dir = self.regs.dir;
                    self.position_update(steps, &dir);
                    return Pulses {
                        steps,
                        signs: self.signs,
                    };
                }
            }
            Mode::Dwell => {
                // A hold stops the dwell's clock too.
                if !operator::held(op) {
                    self.ticks = self.ticks.saturating_sub(1);
                }
                if self.ticks == 0 {
                    self.done(src);
                }
            }
        }
        Pulses {
            steps: 0,
            signs: self.signs,
        }
    }

    /// Timer rate the next frame needs.
    #[inline]
    pub fn rate(&self) -> Rate {
        if self.mode == Mode::Rapid {
            Rate::Rapid
        } else {
            Rate::Feed
        }
    }

    /// Absolute position in BLU, updated per pulse.
    #[inline]
    pub fn position(&self) -> [i32; 3] {
        self.position
    }

    /// True when no block is loaded.
    #[inline]
    pub fn idle(&self) -> bool {
        self.mode == Mode::Idle
    }

    /// The feed velocity as a feed number in Q8: 0 in rapids and dwells, and when a feed hold has
    /// stopped a feed block; after a feed block, its last velocity until the next block starts.
    #[inline]
    pub fn velocity_q8(&self) -> u32 {
        self.v
    }

    /// The rapid's hold ladder: 0 when no rapid runs or a hold has stopped it.
    #[inline]
    pub fn ladder(&self) -> u32 {
        self.ptp_m
    }

    /// True when nothing moves: idle, dwelling, a feed block at velocity 0 or a rapid stopped by
    /// the hold ladder (a feed hold is complete: grbl's `Hold:0`). See [`stopped`].
    #[inline]
    pub fn stopped(&self) -> bool {
        stopped(self.idle(), self.v, self.ptp_m)
    }

    /// Blocks completed since power-up.
    #[inline]
    pub fn blocks_done(&self) -> u32 {
        self.blocks_done
    }

    /// The Initiator: load a validated block into the registers (read in place, not copied).
    #[inline]
    fn initiate(&mut self, block: &Block) {
        match &block.motion {
            Motion::Rapid(r) => {
                self.mode = Mode::Rapid;
                self.count = r.steps;
                self.regs.steps = [
                    r.steps[0].wrapping_add(1),
                    r.steps[1].wrapping_add(1),
                    r.steps[2].wrapping_add(1),
                ];
                self.regs.dir = dirs(r.signs);
                self.ticks = 0;
                self.ptp_m = self.cfg.ptp_steps[0].saturating_add(1);
                self.v = 0;
                // The parser completed the byte (non-moving axes keep their line): write it as it is.
                self.signs = r.signs;
            }
            Motion::Linear(l) => {
                // From a stop: the ramp starts at 0. No rapid runs (see `stopped`).
                self.v = 0;
                self.ptp_m = 0;
                self.load_linear(l);
            }
            Motion::Arc(c) => {
                self.mode = Mode::Arc;
                let (a, b) = c.plane.axes();
                self.bit_a = 1 << a;
                self.bit_b = 1 << b;
                // Unit steps +1 until the first segment sets them: ti = i, tj = j.
                self.da = 1;
                self.db = 1;
                self.ti = c.start[0];
                self.tj = c.start[1];
                self.bit_z = 7 & !(self.bit_a | self.bit_b);
                // q >= 1 (parser); f_floor and decel_below come sealed (see `Block::seal`).
                self.regs.q = c.q;
                self.e = 0;
                // The third axis: its sign line now (segments change only a and b), its DDA over
                // the whole arc.
                self.hz = c.helix.unsigned_abs();
                self.cz = self.hz;
                self.hq = c.length;
                self.acc[0] = c.q / 2;
                self.acc[2] = c.length / 2;
                if c.helix > 0 {
                    self.signs |= self.bit_z;
                } else if c.helix < 0 {
                    self.signs &= !self.bit_z;
                }
                self.regs.f = c.f;
                self.regs.f_floor = c.f_floor;
                self.remaining = c.length;
                self.regs.decel_below = c.decel_below;
                self.regs.ramp = c.ramp;
                self.v = 0;
                self.ptp_m = 0;
                self.n_seg = c.n_targets;
                // No segment yet: the next frame loads segment 0 (seg wraps to 0), so loading the
                // block and its first segment are two frames of bounded work.
                self.seg = u8::MAX;
                self.ca = 0;
                self.cb = 0;
            }
            Motion::Dwell(d) => {
                self.mode = Mode::Dwell;
                self.v = 0;
                self.ptp_m = 0;
                self.ticks = d.frames;
            }
        }
    }

    /// Loads a line's registers (the Initiator; also chained at the end of the line before it).
    /// The feed DDA's accumulator r0 carries over, so the feed keeps its phase across blocks.
    #[inline(always)]
    fn load_linear(&mut self, l: &Linear) {
        self.mode = Mode::Linear;
        // q >= 1 (parser); the other registers stay in the block (read in place).
        let q = l.q;
        let half = q / 2;
        self.acc = [half, half, half];
        self.remaining = q;
        self.signs = l.signs;
    }

    /// The block is done and leaves the source; the Initiator runs next frame.
    #[inline]
    fn done(&mut self, src: &mut impl BlockSource) {
        self.mode = Mode::Idle;
        self.blocks_done = self.blocks_done.wrapping_add(1);
        src.pop();
    }

    /// Loads segment `self.seg` of the running arc (the source's front block).
    #[inline(always)]
    fn load_segment(&mut self, src: &mut impl BlockSource) {
        match src.front().map(Sealed::block) {
            Some(Block {
                motion: Motion::Arc(c),
                ..
            }) => self.load_arc_segment(c),
            // Not reached: the running arc is the front block. Finish it (no segment left).
            _ => {
                self.ca = 0;
                self.cb = 0;
                self.seg = self.n_seg;
            }
        }
    }

    /// Counters, unit steps and signs of segment `self.seg` of `c`: |target - (i, j)| per axis.
    #[inline(always)]
    fn load_arc_segment(&mut self, c: &super::block::Arc) {
        let i = self.da.wrapping_mul(self.ti);
        let j = self.db.wrapping_mul(self.tj);
        let t = match c.targets.get(self.seg as usize) {
            Some(t) => *t,
            None => [i, j],
        };
        let da = t[0].wrapping_sub(i);
        let db = t[1].wrapping_sub(j);
        self.ca = da.unsigned_abs();
        self.cb = db.unsigned_abs();
        self.da = if da > 0 { 1 } else { -1 };
        self.db = if db > 0 { 1 } else { -1 };
        self.ti = self.da.wrapping_mul(i);
        self.tj = self.db.wrapping_mul(j);
        // The DDA's remainders run on over the crossings (set once, at the block's start): the
        // plane's commands add up to q x sweep, so that the third axis keeps in step.
        // Only the axes that move in this segment change their sign line.
        let (bit_a, bit_b) = (self.bit_a, self.bit_b);
        let mut mask = 0u8;
        let mut signs = 0u8;
        if da != 0 {
            mask |= bit_a;
        }
        if db != 0 {
            mask |= bit_b;
        }
        if da > 0 {
            signs |= bit_a;
        }
        if db > 0 {
            signs |= bit_b;
        }
        self.signs = (self.signs & !mask) | signs;
        self.regs.dir = dirs(self.signs);
    }

    /// Feed-rate DDA: true when this frame produces an interpolation command.
    ///
    /// The velocity v (Q8) moves towards the target min(f x k, cap) * operator factor by at most
    /// the block's ramp per frame, up or down (feed hold: target 0; resume: back to the target);
    /// a block flagged for deceleration then caps it at once at max(f / 5, K * remaining / 256),
    /// the paper's exponential approach (it is not ramped: it is the rule for those blocks).
    /// `planned` is the block's feed f times the AC's plan ratio k ([`FeedCap::planned`]: f
    /// but under the plan).
    #[inline(always)]
    fn feed(
        &mut self,
        feed_cap: u32,
        planned: u32,
        op: u32,
        f_floor: u32,
        decel_below: u32,
        ramp: u32,
    ) -> bool {
        let lim = if feed_cap < planned {
            feed_cap
        } else {
            planned
        };
        // f <= q0 <= 10^6 and the factor <= 512: the product fits 32 bits.
        let target = lim.wrapping_mul(op & operator::FEED_MASK);
        let mut v = self.v;
        // Cruising (v at the target) is the common case: one compare.
        if v != target {
            if v < target {
                v = v.wrapping_add(ramp);
                if v > target {
                    v = target;
                }
            } else if v.wrapping_sub(target) > ramp {
                v = v.wrapping_sub(ramp);
            } else {
                v = target;
            }
        }
        if self.remaining < decel_below {
            // No overflow: see `Block::seal`.
            let d = self.cfg.decel_gain_q8.wrapping_mul(self.remaining) >> 8;
            let d = if d < f_floor { f_floor } else { d };
            let d = d << 8;
            if v > d {
                v = d;
            }
        }
        self.v = v;
        self.r0 = self.r0.wrapping_add(v);
        if self.r0 >= self.cfg.q0_q8 {
            self.r0 -= self.cfg.q0_q8;
            self.remaining = self.remaining.saturating_sub(1);
            true
        } else {
            false
        }
    }

    /// Linear DDA cycle: r_k += |d_k|; an overflow past q gives a pulse. With r_k starting at
    /// floor(q / 2) and |d_k| <= q = L, after n commands axis k has had floor((q / 2 + n |d_k|) / q)
    /// pulses: never more than |d_k| before the q-th command and exactly |d_k| after it, so the
    /// block ends after q commands and needs no per-axis counters.
    #[inline(always)]
    fn linear(&mut self, d: &[u32; 3], q: u32) -> u8 {
        // Written out per axis, not as a loop: the firmware's code outside the frame is built for
        // size, and a loop is not unrolled there.
        let mut steps = 0u8;
        dda_axis(&mut self.acc[0], d[0], q, 1, &mut steps);
        dda_axis(&mut self.acc[1], d[1], q, 2, &mut steps);
        dda_axis(&mut self.acc[2], d[2], q, 4, &mut steps);
        steps
    }

    /// Circular DDA cycle in the plane (a, b) with the radius-error correction, and a helix's third
    /// axis; ti, tj and e follow every pulse. While both axes of the segment have pulses left, the
    /// faster axis (a when |j| >= |i|: it moves at |j| / q per command, b at |i| / q) runs the DDA
    /// and the slower one pulses with it when that makes |e| smaller: |e + 2 t + 1| < |e| with t
    /// its register times its unit step, which is the midpoint rule (the slower axis is the
    /// lattice point nearest the circle). When one axis of the segment is done the other pulses at
    /// the DDA's rate. When the plane is done and the third axis is not, it pulses once per
    /// command.
    #[inline(always)]
    fn circular(&mut self) -> u8 {
        let (ca, cb) = (self.ca, self.cb);
        let mut steps = 0u8;
        if ca | cb == 0 {
            // The plane is done (the frame runs commands only while the third axis is not): it
            // pulses once per command.
            self.acc[2] = self.hq;
        } else {
            let ai = self.ti.unsigned_abs();
            let aj = self.tj.unsigned_abs();
            let a_major = aj >= ai;
            let q = self.regs.q;
            let r = self.acc[0].wrapping_add(if a_major { aj } else { ai });
            if r >= q {
                self.acc[0] = r - q;
                // a pulses when it is the faster axis, or when b's segment is done (then a
                // finishes at its own rate); b likewise. A pulse adds 1 to ti (or tj), and to e
                // (ti + 1)^2 - ti^2 = 2 ti + 1: the slower axis pulses when that makes |e| smaller.
                if (a_major && ca != 0) || cb == 0 {
                    let ti = self.ti.wrapping_add(1);
                    self.ti = ti;
                    let e = self.e.wrapping_add(ti.wrapping_mul(2).wrapping_sub(1));
                    self.ca = ca.wrapping_sub(1);
                    steps |= self.bit_a;
                    self.e = e;
                    let e2 = e.wrapping_add(self.tj.wrapping_mul(2).wrapping_add(1));
                    if cb != 0 && e2.unsigned_abs() < e.unsigned_abs() {
                        self.e = e2;
                        self.tj = self.tj.wrapping_add(1);
                        self.cb = cb.wrapping_sub(1);
                        steps |= self.bit_b;
                    }
                } else {
                    let tj = self.tj.wrapping_add(1);
                    self.tj = tj;
                    let e = self.e.wrapping_add(tj.wrapping_mul(2).wrapping_sub(1));
                    self.cb = cb.wrapping_sub(1);
                    steps |= self.bit_b;
                    self.e = e;
                    let e2 = e.wrapping_add(self.ti.wrapping_mul(2).wrapping_add(1));
                    if ca != 0 && e2.unsigned_abs() < e.unsigned_abs() {
                        self.e = e2;
                        self.ti = self.ti.wrapping_add(1);
                        self.ca = ca.wrapping_sub(1);
                        steps |= self.bit_a;
                    }
                }
            } else {
                self.acc[0] = r;
            }
        }
        // The third axis: a linear DDA over the arc's length (hz = 0 for a plane arc).
        let rz = self.acc[2].wrapping_add(self.hz);
        if rz >= self.hq && self.cz != 0 {
            self.acc[2] = rz - self.hq;
            self.cz -= 1;
            steps |= self.bit_z;
        } else {
            self.acc[2] = rz;
        }
        steps
    }

    /// PTP: independent axes at the rapid rate, three steps of deceleration (and acceleration).
    /// The operator's hold walks the same ladder down in time (`ptp_m`), the rapid override
    /// skips frames (its mask bits).
    #[inline(always)]
    fn ptp(&mut self, op: u32) -> u8 {
        let ticks = self.ticks.wrapping_add(1);
        self.ticks = ticks;
        let [s1, s2, s3] = self.cfg.ptp_steps;
        let level = |m: u32| {
            if m > s1 {
                0
            } else if m > s2 {
                1
            } else if m > s3 {
                3
            } else {
                7
            }
        };
        // The hold ladder: one step per frame of its own level.
        let pm = self.ptp_m;
        let hold_mask = level(pm);
        if ticks & hold_mask == 0 {
            if operator::held(op) {
                self.ptp_m = pm.saturating_sub(1);
            } else if pm <= s1 {
                self.ptp_m = pm + 1;
            }
        }
        if pm == 0 {
            return 0;
        }
        let common = hold_mask | (op & operator::RAPID_MASK) >> operator::RAPID_SHIFT;
        let mut steps = 0u8;
        for k in 0..3 {
            let left = self.count[k];
            if left != 0 {
                // Pulses done + 1 (exact in wrapping arithmetic: it is at most n_k).
                let done = self.regs.steps[k].wrapping_sub(left);
                let m = if done < left { done } else { left };
                if ticks & (level(m) | common) == 0 {
                    self.count[k] = left - 1;
                    self.position[k] = self.position[k].wrapping_sub(self.regs.dir[k]);
                    steps |= 1 << k;
                }
            }
        }
        steps
    }

    /// Position: absolute counters follow every pulse with its sign (per axis, not a loop: see
    /// `linear`).
    #[inline(always)]
    fn position_update(&mut self, steps: u8, dir: &[i32; 3]) {
        let [p0, p1, p2] = &mut self.position;
        position_axis(p0, steps & 1, dir[0]);
        position_axis(p1, steps & 2, dir[1]);
        position_axis(p2, steps & 4, dir[2]);
    }
}

/// One axis of the linear DDA cycle: r += |d|; an overflow past q is a pulse (`bit` in `steps`).
#[inline(always)]
fn dda_axis(acc: &mut u32, d: u32, q: u32, bit: u8, steps: &mut u8) {
    let r = acc.wrapping_add(d);
    if r >= q {
        *acc = r - q;
        *steps |= bit;
    } else {
        *acc = r;
    }
}

/// One axis's position counter: follows a pulse (`bit` set) with its sign.
#[inline(always)]
fn position_axis(position: &mut i32, bit: u8, dir: i32) {
    if bit != 0 {
        *position = position.wrapping_sub(dir);
    }
}

/// Whether the machine stands still, from what the frame publishes: idle, or neither a feed velocity
/// nor a rapid's hold ladder (each is 0 while the other kind of block runs, and in dwells).
#[inline(always)]
pub const fn stopped(idle: bool, velocity_q8: u32, ladder: u32) -> bool {
    idle || velocity_q8 | ladder == 0
}
