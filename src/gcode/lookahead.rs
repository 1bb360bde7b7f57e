//! One-block look-ahead that decides the `decel` flag of feed blocks (loader task, between the
//! parser and the block queue; host tests).
//!
//! The paper only says that a block can carry a deceleration command. Our rule: a feed block
//! (Linear or Arc) decelerates at its end when
//! - the next block is not a feed block (Rapid or Dwell), or there is no next block (end of
//!   program, [`Lookahead::flush`]), or
//! - the direction changes by more than 30 degrees at the junction: the end tangent of the block
//!   against the start tangent of the next one (a line's tangent is its 3-D direction; an arc's
//!   is perpendicular to the radius vector, in the direction of travel).
//!
//! Otherwise the feed carries on into the next block without slowing down.

use crate::nc::{Block, Motion};

/// Tangents (start, end) of a feed block in machine axes; `None` for Rapid and Dwell.
fn tangents(b: &Block) -> Option<([i64; 3], [i64; 3])> {
    match &b.motion {
        Motion::Linear(l) => {
            let mut v = [0i64; 3];
            for (k, (out, &s)) in v.iter_mut().zip(l.steps.iter()).enumerate() {
                *out = if l.signs & (1 << k) != 0 {
                    s as i64
                } else {
                    -(s as i64)
                };
            }
            Some((v, v))
        }
        Motion::Arc(a) => {
            let (ia, ib) = a.plane.axes();
            let tangent = |p: [i32; 2]| {
                let (i, j) = (p[0] as i64, p[1] as i64);
                let (ta, tb) = if a.ccw { (-j, i) } else { (j, -i) };
                let mut v = [0i64; 3];
                if let Some(x) = v.get_mut(ia) {
                    *x = ta;
                }
                if let Some(x) = v.get_mut(ib) {
                    *x = tb;
                }
                v
            };
            let last = a
                .targets
                .get((a.n_targets as usize).wrapping_sub(1))
                .copied()
                .unwrap_or(a.start);
            // A helix's third axis: its travel per radian, helix / sweep = helix q / length, beside
            // the plane tangent's R per radian.
            let rise = a.helix as i64 * a.q as i64 / a.length.max(1) as i64;
            let (mut t0, mut t1) = (tangent(a.start), tangent(last));
            if let (Some(x), Some(y)) = (t0.get_mut(3 - ia - ib), t1.get_mut(3 - ia - ib)) {
                (*x, *y) = (rise, rise);
            }
            Some((t0, t1))
        }
        Motion::Rapid(_) | Motion::Dwell(_) => None,
    }
}

/// Scales a vector down so that every component is below 2^30 (keeps the direction).
fn reduce(v: [i64; 3]) -> [i64; 3] {
    let big = v.iter().map(|x| x.unsigned_abs()).max().unwrap_or(0);
    let shift = (64 - big.leading_zeros()).saturating_sub(30);
    v.map(|x| x >> shift)
}

/// True when the angle between u and v exceeds 30 degrees (or a vector is zero):
/// cos < sqrt(3)/2  <=>  dot <= 0 or 4 dot^2 < 3 |u|^2 |v|^2.
pub fn sharp(u: [i64; 3], v: [i64; 3]) -> bool {
    let (u, v) = (reduce(u), reduce(v));
    let dot: i128 = u
        .iter()
        .zip(v.iter())
        .map(|(a, b)| *a as i128 * *b as i128)
        .sum();
    let uu: u128 = u.iter().map(|a| (*a as i128 * *a as i128) as u128).sum();
    let vv: u128 = v.iter().map(|a| (*a as i128 * *a as i128) as u128).sum();
    if dot <= 0 || uu == 0 || vv == 0 {
        return true;
    }
    // Components < 2^30: uu, vv, dot < 3 * 2^60, so both sides stay below 2^127.
    let d = dot as u128;
    4 * d * d < 3 * uu * vv
}

/// Whether block `b` must decelerate at its end when followed by `next`.
pub fn needs_decel(b: &Block, next: Option<&Block>) -> bool {
    let Some((_, end)) = tangents(b) else {
        return false;
    };
    match next.and_then(tangents) {
        Some((start, _)) => sharp(end, start),
        None => true,
    }
}

fn with_decel(mut b: Block, decel: bool) -> Block {
    match &mut b.motion {
        Motion::Linear(l) => l.decel = decel,
        Motion::Arc(a) => a.decel = decel,
        Motion::Rapid(_) | Motion::Dwell(_) => {}
    }
    b
}

/// One-block look-ahead that decides the `decel` flag of feed blocks (rule in the module doc).
pub struct Lookahead {
    pending: Option<Block>,
}

impl Default for Lookahead {
    fn default() -> Self {
        Self::new()
    }
}

impl Lookahead {
    pub const fn new() -> Self {
        Lookahead { pending: None }
    }

    /// Takes the newest block; returns the previous one with its `decel` flag decided.
    pub fn push(&mut self, b: Block) -> Option<Block> {
        let prev = self.pending.replace(b)?;
        let decel = needs_decel(&prev, Some(&b));
        Some(with_decel(prev, decel))
    }

    /// True when a block is held.
    pub fn holds(&self) -> bool {
        self.pending.is_some()
    }

    /// End of program: the held block (a feed block always decelerates at the end).
    pub fn flush(&mut self) -> Option<Block> {
        let b = self.pending.take()?;
        let decel = needs_decel(&b, None);
        Some(with_decel(b, decel))
    }
}
