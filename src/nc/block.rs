//! Validated NC blocks: what the G-code parser (task context) queues and the Initiator (frame ISR)
//! loads. Everything in a `Block` has been checked; the frame trusts it and does no checks.

/// Axis indices into `[_; 3]` arrays and bit positions in step/sign masks.
pub const X: usize = 0;
pub const Y: usize = 1;
pub const Z: usize = 2;

/// The plane of a circular block, as grbl names its axes: (a, b) = (X, Y) for G17, (Z, X) for G18,
/// (Y, Z) for G19. Counter-clockwise is from +a towards +b, seen from the positive third axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plane {
    XY,
    ZX,
    YZ,
}

impl Plane {
    /// Machine axis indices of (a, b).
    pub const fn axes(self) -> (usize, usize) {
        match self {
            Plane::XY => (X, Y),
            Plane::ZX => (Z, X),
            Plane::YZ => (Y, Z),
        }
    }
}

/// The position counters and SIGN bits of a move by `d` (BLU per axis): |d_k|, and bit k set when
/// axis k moves positive. The parser's lines and rapids and the chatter re-plan's detour (task
/// context) make their registers with it.
pub fn steps_and_signs(d: [i64; 3]) -> ([u32; 3], u8) {
    let mut signs = 0u8;
    let steps = [X, Y, Z].map(|k| {
        if d[k] > 0 {
            signs |= 1 << k;
        }
        // |d| < 2^32 for positions in i32: fits u32.
        d[k].unsigned_abs() as u32
    });
    (steps, signs)
}

/// PTP (G0): every axis moves independently at the rapid rate with three-step deceleration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rapid {
    /// Pulses per axis (position counters).
    pub steps: [u32; 3],
    /// Sign bits: bit k set = axis k moves in the positive direction.
    pub signs: u8,
}

/// Largest q of a linear block: the DDA adds |d_k| <= q to a remainder below q, so r_k + |d_k| <=
/// 2q - 1 must fit 32 bits. The parser refuses longer lines (an arc's q = R is below 2^31 and its
/// registers |i|, |j| fit i32, so its sums fit as well).
pub const Q_MAX: u32 = 1 << 31;

/// Linear interpolation (G1): q = L = isqrt(x^2 + y^2 + z^2).
///
/// `steps` to `dir` are the frame's register image in the frame's own field order (`repr(C)`), so
/// that the Initiator loads a line with a few multiple-register loads and stores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct Linear {
    /// Incremental distances |x|, |y|, |z| in BLU: the DDA registers y1..y3 and the counters.
    pub steps: [u32; 3],
    /// q = L, 1..=[`Q_MAX`].
    pub q: u32,
    /// Feed number f (1..=q0).
    pub f: u32,
    /// Derived from f and decel by [`Block::seal`]: the deceleration floor and threshold.
    pub f_floor: u32,
    pub decel_below: u32,
    /// Derived from the direction by [`Block::seal`]: the acceleration ramp, the most the frame's
    /// velocity (a feed number in Q8) changes per frame, so that no axis exceeds its limit.
    pub ramp: u32,
    /// Derived from signs by [`Block::seal`]: the negated position step per pulse, -1 or +1.
    pub dir: [i32; 3],
    pub signs: u8,
    /// Decelerate exponentially to 20 % of f near the end of the block.
    pub decel: bool,
}

/// Largest ramp: above any velocity the frame can reach (q0 <= 10^6 times a factor <= 512, in Q8,
/// is below 2^30), so a ramp this large changes the velocity at once, and velocity + ramp never
/// overflows.
pub const RAMP_MAX: u32 = 1 << 30;

/// The highest feed number of an arc of radius `r` BLU whose centripetal acceleration stays within
/// `accel_q8` (Q8 feed numbers per frame, see `FrameConfig::accel_q8`): v^2 / R <= a with
/// v = W0 f / q0 and a = accel_q8 W0^2 / (256 q0) gives f^2 <= accel_q8 R q0 / 256, and with
/// `q0_q8` = 256 q0 that is accel_q8 R q0_q8 / 65536. At least 1; u32::MAX when no feed could
/// reach it.
pub fn centripetal_feed(accel_q8: u32, r: u32, q0_q8: u32) -> u32 {
    let f2 = accel_q8 as u128 * r as u128 * q0_q8 as u128 / 65_536;
    match u64::try_from(f2) {
        Ok(f2) => u32::try_from(super::isqrt(f2)).unwrap_or(u32::MAX).max(1),
        Err(_) => u32::MAX,
    }
}

/// Most quadrant segments an arc can have (a full circle from a point off the axes).
pub const MAX_SEGMENTS: usize = 5;

/// Largest radius of an arc in BLU: the frame keeps the radius error i^2 + j^2 - R^2 in 32 bits
/// (see [`Arc`]), so the registers stay below 2^28 (268 m at 1 um per BLU).
pub const R_MAX: u32 = 1 << 28;

/// Most turns of one G2/G3 line (its P word, which the parser expands into as many blocks).
pub const MAX_TURNS: u32 = 10_000;

/// Circular interpolation (G2/G3) as a DDA with radius-error correction: registers i = a - a_c,
/// j = b - b_c, modulus q. The arc is cut at axis crossings into segments; inside a segment both
/// axes move monotonically, so the position counters of a segment are |delta a| and |delta b| and
/// its signs are constant. The last target is the programmed end point (relative to the centre).
///
/// Per interpolation command the faster axis of the two (a when |j| >= |i|) runs the DDA,
/// r += max(|i|, |j|), overflow past q = a pulse; when it pulses, the slower axis pulses too if
/// that brings the point nearer the start's circle (|e| smaller, e = i^2 + j^2 - i0^2 - j0^2, kept
/// exact per pulse): the slower axis is the lattice point nearest the circle, the radial error at
/// most half a BLU. A helix moves the third axis by `helix` BLU along the arc: a linear DDA of
/// |helix| over `length` commands, the plane's modulus q = R x length / (R x sweep) so that the
/// path (not its projection) runs at the feed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Arc {
    pub plane: Plane,
    /// G3 (counter-clockwise) when true, G2 when false.
    pub ccw: bool,
    /// Start point relative to the centre (i, j) in BLU.
    pub start: [i32; 2],
    /// R = round(sqrt(i^2 + j^2)) of the start point, 1..=[`R_MAX`].
    pub r: u32,
    /// The DDA's modulus: R for a plane arc, R x length / (R x sweep) for a helix (the plane
    /// moves less than one BLU per command), at most [`Q_MAX`].
    pub q: u32,
    /// Signed travel of the third axis (0 for a plane arc), |helix| <= length.
    pub helix: i32,
    /// Segment end points relative to the centre; the first `n_targets` are used.
    pub targets: [[i32; 2]; MAX_SEGMENTS],
    pub n_targets: u8,
    pub f: u32,
    pub decel: bool,
    /// Path length in BLU (number of interpolation commands the arc takes, along the helix for a
    /// helix), for deceleration and the third axis's DDA. At least 1.
    pub length: u32,
    /// Derived from f and decel by [`Block::seal`]: the deceleration floor and threshold.
    pub f_floor: u32,
    pub decel_below: u32,
    /// Derived by [`Block::seal`]: the acceleration ramp (see [`Linear::ramp`]), from the
    /// smaller limit of the plane's two axes.
    pub ramp: u32,
}

/// G4: wait a number of frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dwell {
    pub frames: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    Rapid(Rapid),
    Linear(Linear),
    Arc(Arc),
    Dwell(Dwell),
}

/// One block of the program, as the Initiator loads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Block {
    /// Source line number (1-based) of the G-code line that produced it.
    pub line: u32,
    pub motion: Motion,
}

impl Block {
    /// Completes the frame's register image of a feed block from its feed number and deceleration
    /// flag (task context: the tape reader seals every block it emits, and whoever changes `f` or
    /// `decel` later seals again), so that the Initiator only copies registers:
    /// - `f_floor` = max(f / 5, 1), the deceleration floor (20 % of f);
    /// - `decel_below`: the number of commands left below which K * remaining / 256 < f, i.e.
    ///   floor(256 f / K) + 1 (u32::MAX when K is 0 or 256 f overflows); 0 when the block does not
    ///   decelerate. Below it, K * remaining <= 256 f fits 32 bits, so the frame's product does.
    ///
    /// - `ramp`: the path acceleration in Q8 feed numbers per frame that keeps every axis within
    ///   its limit: a line moves axis k by |d_k| / q of the path, so the path may accelerate at
    ///   min over the moving axes of a_k q / |d_k|; an arc at the smaller limit a of its plane's
    ///   axes. At least 1.
    /// - An arc's feed is capped so that its centripetal acceleration v^2 / R stays within that
    ///   a (each axis of the plane sees a sinusoid of that amplitude; grbl limits arcs the same
    ///   way): f <= sqrt(a R) q0 / W0, see [`centripetal_feed`].
    ///
    /// Only a sealed block reaches the frame ([`Sealed`]: the queue's type): an unsealed one
    /// (all 0) would never start, its ramp being 0.
    pub fn seal(mut self, cfg: &super::FrameConfig) -> Sealed {
        let k = cfg.decel_gain_q8;
        let regs = |f: u32, decel: bool| {
            let floor = (f / 5).max(1);
            let below = if !decel {
                0
            } else {
                match f.checked_mul(256) {
                    Some(x) => x.checked_div(k).map_or(u32::MAX, |v| v.saturating_add(1)),
                    None => u32::MAX.checked_div(k).unwrap_or(u32::MAX),
                }
            };
            (floor, below)
        };
        let a = cfg.accel_q8;
        match &mut self.motion {
            Motion::Linear(l) => {
                (l.f_floor, l.decel_below) = regs(l.f, l.decel);
                l.dir = dirs(l.signs);
                let mut ramp = u64::MAX;
                for (ak, &dk) in a.iter().zip(l.steps.iter()) {
                    if dk != 0 {
                        ramp = ramp.min(*ak as u64 * l.q as u64 / dk as u64);
                    }
                }
                l.ramp = ramp.clamp(1, RAMP_MAX as u64) as u32;
            }
            Motion::Arc(c) => {
                let (x, y) = c.plane.axes();
                let mut a_arc = a[x].min(a[y]) as u64;
                if c.helix != 0 {
                    // The third axis moves |helix| / length of the path.
                    let z = a[3 - x - y] as u64 * c.length as u64 / c.helix.unsigned_abs() as u64;
                    a_arc = a_arc.min(z);
                }
                let a_arc = a_arc.clamp(1, RAMP_MAX as u64) as u32;
                // The plane's speed is R / q of the path's: the centripetal cap on q is safe.
                c.f = c.f.min(centripetal_feed(a_arc, c.q.max(c.r), cfg.q0_q8));
                (c.f_floor, c.decel_below) = regs(c.f, c.decel);
                c.ramp = a_arc;
            }
            Motion::Rapid(_) | Motion::Dwell(_) => {}
        }
        Sealed(self)
    }
}

/// A block the frame may run: sealed by [`Block::seal`] after its last change, the only way to
/// make one. It cannot be changed (it reads as a [`Block`] through `Deref`), so the frame never
/// sees registers that disagree with the feed; whoever changes a block (the re-planner) takes it
/// apart ([`Sealed::into_block`]) and seals it again. The block queue carries these. Any context.
///
/// ```
/// # use millac::nc::{Block, Dwell, FrameConfig, Motion};
/// let cfg = FrameConfig::from_settings(&millac::Settings::default());
/// let s = Block { line: 1, motion: Motion::Dwell(Dwell { frames: 1 }) }.seal(&cfg);
/// assert_eq!(s.line, 1);
/// ```
/// It reads as a block, and cannot be changed in place:
/// ```compile_fail
/// # use millac::nc::{Block, Dwell, FrameConfig, Motion};
/// let cfg = FrameConfig::from_settings(&millac::Settings::default());
/// let mut s = Block { line: 1, motion: Motion::Dwell(Dwell { frames: 1 }) }.seal(&cfg);
/// s.line = 2;
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sealed(Block);

impl Sealed {
    /// A dwell of no frames (sealing changes nothing in a dwell): a placeholder where a block
    /// must be, doing nothing.
    pub const NOTHING: Sealed = Sealed(Block {
        line: 0,
        motion: Motion::Dwell(Dwell { frames: 0 }),
    });

    /// The block, to read (the frame: `src.front().map(Sealed::block)`).
    #[inline(always)]
    pub const fn block(&self) -> &Block {
        &self.0
    }

    /// The block, to change (and seal again).
    pub const fn into_block(self) -> Block {
        self.0
    }
}

impl core::ops::Deref for Sealed {
    type Target = Block;
    #[inline(always)]
    fn deref(&self) -> &Block {
        &self.0
    }
}

/// Position step per pulse of each axis for the sign bits `signs`, negated: -1 (bit set, the
/// axis moves positive) or +1; the position counter subtracts it. (Sign-extending bit k gives 0 or
/// -1, and `| 1` makes that +1 or -1: two instructions per axis.)
#[inline(always)]
pub(crate) const fn dirs(signs: u8) -> [i32; 3] {
    let s = signs as i32;
    [
        (s << 31 >> 31) | 1,
        (s << 30 >> 31) | 1,
        (s << 29 >> 31) | 1,
    ]
}
