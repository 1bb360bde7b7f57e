//! Canned drilling cycles G73 G81 G82 G83 G85 G89 in the XY plane (loader task; host tests): the
//! parser validates a cycle line once into a [`Cycle`] (every hole and level within the soft
//! limits, every feed move within the DDA), and the tape expands it into blocks one at a time
//! ([`Cycle::next_block`]), so that a long peck cycle never needs more room in the block queue than
//! one block.
//!
//! The motions are LinuxCNC's (its interpreter is the reference, see the differential test):
//! before the first hole, a Z below R rises to R; then per repeat (L): a rapid in XY to the hole at
//! the current Z, a rapid in Z to R (unless there), the cycle's own moves, and the retract to the
//! clear level (G98: the Z where the series of cycles began, if above R; G99: R).
//! - G81: feed to the bottom, rapid out. G82: and a dwell of P seconds at the bottom.
//! - G83: pecks of Q: feed down Q, rapid up to R, rapid down to 0.254 mm (0.010 in) above the
//!   last depth, until the bottom; G73 the same without the rapid up to R (chip breaking).
//! - G85: feed to the bottom, feed back to R, rapid to the clear level. G89: feed down, dwell P,
//!   feed out to the clear level.
//!
//! In G90, X Y R Z are program coordinates; in G91 X and Y are increments per repeat from the
//! current position, R an increment from the Z where the series began, Z an increment from R.
//! R, Z, Q and P are sticky while the same cycle stays in force; L is per line.

use super::fine::{fine_to_blu, FINE_PER_MM};
use crate::nc::{steps_and_signs, Block, Dwell, Linear, Motion, Rapid};
use crate::settings::Settings;

/// The cycles millac expands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CycleKind {
    /// G73: peck with chip breaking.
    ChipBreak,
    /// G81: drill.
    Drill,
    /// G82: drill with a dwell at the bottom.
    DrillDwell,
    /// G83: peck drilling.
    Peck,
    /// G85: bore, feed out.
    Bore,
    /// G89: bore with a dwell, feed out.
    BoreDwell,
}

impl CycleKind {
    /// The cycle of a motion code (in tenths).
    pub const fn of_code(code: u16) -> Option<CycleKind> {
        Some(match code {
            730 => CycleKind::ChipBreak,
            810 => CycleKind::Drill,
            820 => CycleKind::DrillDwell,
            830 => CycleKind::Peck,
            850 => CycleKind::Bore,
            890 => CycleKind::BoreDwell,
            _ => return None,
        })
    }

    /// The G number.
    pub const fn code(self) -> u16 {
        match self {
            CycleKind::ChipBreak => 73,
            CycleKind::Drill => 81,
            CycleKind::DrillDwell => 82,
            CycleKind::Peck => 83,
            CycleKind::Bore => 85,
            CycleKind::BoreDwell => 89,
        }
    }

    /// Whether the cycle pecks (takes Q).
    pub const fn pecks(self) -> bool {
        matches!(self, CycleKind::ChipBreak | CycleKind::Peck)
    }

    /// Whether the cycle dwells at the bottom (takes P).
    pub const fn dwells(self) -> bool {
        matches!(self, CycleKind::DrillDwell | CycleKind::BoreDwell)
    }
}

/// The sticky words of the cycle in force (fine units as the words gave them; `il` the Z where
/// the series began, machine fine units, None outside a series).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CycleWords {
    pub r: i128,
    pub z: i128,
    pub q: i128,
    pub dwell_frames: u32,
    pub il: Option<i128>,
}

/// The rapid back-off of G73/G83 above the last peck: 0.254 mm (LinuxCNC's 0.010 in, the same
/// length in a metric program), fine units.
pub const PECK_CLEARANCE: i128 = FINE_PER_MM / 1000 * 254;

/// One move of a cycle, machine fine units.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Move {
    Rapid([i128; 3]),
    Feed([i128; 3]),
    Dwell,
}

/// Where the expansion stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    /// Before the first hole: rise to R if below it.
    Rise,
    /// A hole: the XY rapid.
    Position,
    /// The Z rapid to R.
    ToR,
    /// The cycle's own moves: `n` counts them within the hole.
    Body(u32),
    Done,
}

/// A validated canned cycle line: its levels in machine fine units and its holes. Made by
/// [`plan`], expanded by [`Cycle::next_block`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cycle {
    pub kind: CycleKind,
    pub line: u32,
    /// The first hole (machine fine X, Y), the step between holes, how many.
    pub first: [i128; 2],
    pub step: [i128; 2],
    pub repeats: u32,
    pub r: i128,
    pub bottom: i128,
    pub clear: i128,
    pub q: i128,
    pub dwell_frames: u32,
    /// Feed number of the feed moves.
    pub f: u32,
    // The expansion's state: where it stands and the machine position (fine and BLU).
    step_at: Step,
    hole: u32,
    depth: i128,
    /// The hole's last feed (to the bottom) has been made.
    bottomed: bool,
    at: [i128; 3],
    blu: [i32; 3],
}

impl Cycle {
    /// A cycle from the machine position `at` (fine) / `blu`. The caller has validated it.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        kind: CycleKind,
        line: u32,
        first: [i128; 2],
        step: [i128; 2],
        repeats: u32,
        levels: [i128; 3],
        q: i128,
        dwell_frames: u32,
        f: u32,
        at: [i128; 3],
        blu: [i32; 3],
    ) -> Cycle {
        let [r, bottom, clear] = levels;
        Cycle {
            kind,
            line,
            first,
            step,
            repeats,
            r,
            bottom,
            clear,
            q,
            dwell_frames,
            f,
            step_at: Step::Rise,
            hole: 0,
            depth: r,
            bottomed: false,
            at,
            blu,
        }
    }

    /// The XY of hole `n` (0-based).
    pub fn hole_xy(&self, n: u32) -> [i128; 2] {
        [0, 1].map(|k| self.first[k] + self.step[k] * n as i128)
    }

    /// The next move, or None at the end.
    fn next_move(&mut self) -> Option<Move> {
        loop {
            match self.step_at {
                Step::Done => return None,
                Step::Rise => {
                    self.step_at = Step::Position;
                    if self.at[2] < self.r {
                        return Some(Move::Rapid([self.at[0], self.at[1], self.r]));
                    }
                }
                Step::Position => {
                    if self.hole == self.repeats {
                        self.step_at = Step::Done;
                        continue;
                    }
                    self.step_at = Step::ToR;
                    let [x, y] = self.hole_xy(self.hole);
                    return Some(Move::Rapid([x, y, self.at[2]]));
                }
                Step::ToR => {
                    self.step_at = Step::Body(0);
                    self.depth = self.r;
                    self.bottomed = false;
                    if self.at[2] != self.r {
                        return Some(Move::Rapid([self.at[0], self.at[1], self.r]));
                    }
                }
                Step::Body(n) => {
                    self.step_at = Step::Body(n + 1);
                    let [x, y, _] = self.at;
                    let z = |z| [x, y, z];
                    let m = match self.body(n) {
                        Some(m) => m,
                        None => {
                            self.hole += 1;
                            self.step_at = Step::Position;
                            continue;
                        }
                    };
                    return Some(match m {
                        Level::Feed(l) => Move::Feed(z(l)),
                        Level::Rapid(l) => Move::Rapid(z(l)),
                        Level::Dwell => Move::Dwell,
                    });
                }
            }
        }
    }

    /// Move `n` of the cycle's own moves at a hole (None after the last).
    fn body(&mut self, n: u32) -> Option<Level> {
        use CycleKind as K;
        use Level::*;
        match self.kind {
            K::Drill => [Feed(self.bottom), Rapid(self.clear)]
                .get(n as usize)
                .copied(),
            K::DrillDwell => [Feed(self.bottom), Dwell, Rapid(self.clear)]
                .get(n as usize)
                .copied(),
            K::Bore => [Feed(self.bottom), Feed(self.r), Rapid(self.clear)]
                .get(n as usize)
                .copied(),
            K::BoreDwell => [Feed(self.bottom), Dwell, Feed(self.clear)]
                .get(n as usize)
                .copied(),
            K::Peck | K::ChipBreak => {
                // Pecks of three moves (G83: feed, up to R, down near the depth) or two (G73:
                // feed, back off), while the next depth is above the bottom; then the last feed
                // and the retract.
                let per = if self.kind == K::Peck { 3 } else { 2 };
                let phase = n % per;
                if self.bottomed {
                    // After the last feed: the retract, once.
                    return if phase == 1 {
                        Some(Rapid(self.clear))
                    } else {
                        None
                    };
                }
                if phase == 0 {
                    let next = self.depth - self.q;
                    if next > self.bottom {
                        self.depth = next;
                        return Some(Feed(next));
                    }
                    // The last feed, then the retract.
                    self.bottomed = true;
                    self.depth = self.bottom;
                    return Some(Feed(self.bottom));
                }
                if self.kind == K::Peck && phase == 1 {
                    Some(Rapid(self.r))
                } else {
                    Some(Rapid(self.depth + PECK_CLEARANCE))
                }
            }
        }
    }

    /// The next block, in machine BLU from where the last one ended; moves that do not move the
    /// machine by a BLU are skipped. None at the end.
    pub fn next_block(&mut self, st: &Settings) -> Option<Block> {
        loop {
            let m = self.next_move()?;
            let (target, feed) = match m {
                Move::Dwell => {
                    if self.dwell_frames == 0 {
                        continue;
                    }
                    return Some(Block {
                        line: self.line,
                        motion: Motion::Dwell(Dwell {
                            frames: self.dwell_frames,
                        }),
                    });
                }
                Move::Rapid(t) => (t, false),
                Move::Feed(t) => (t, true),
            };
            self.at = target;
            let blu = target.map(|f| fine_to_blu(st, f).unwrap_or(0));
            let d = [0, 1, 2].map(|k| blu[k] as i64 - self.blu[k] as i64);
            self.blu = blu;
            let (steps, signs) = steps_and_signs(d);
            if steps == [0; 3] {
                continue;
            }
            let motion = if feed {
                // A feed is along Z only: q = |dz| (validated to fit the DDA).
                let q = steps.iter().copied().max().unwrap_or(1).max(1);
                Motion::Linear(Linear {
                    steps,
                    signs,
                    q,
                    f: self.f,
                    decel: false,
                    f_floor: 0,
                    decel_below: 0,
                    ramp: 0,
                    dir: [1; 3],
                })
            } else {
                Motion::Rapid(Rapid { steps, signs })
            };
            return Some(Block {
                line: self.line,
                motion,
            });
        }
    }

    /// True when every block has been given.
    pub fn done(&self) -> bool {
        self.step_at == Step::Done
    }
}

/// A level of the cycle's own moves at a hole.
#[derive(Clone, Copy)]
enum Level {
    Feed(i128),
    Rapid(i128),
    Dwell,
}
