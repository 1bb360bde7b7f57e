//! The homing cycle's sequence (loader task; host tests): which move comes next, from the
//! set-up's settings and what ended the last one. The loader queues each move as a jog without
//! soft limits, stops it at once when the axis's switch closes, and tells [`Cycle::next`] how it
//! ended; this module holds no position and touches no hardware.
//!
//! Per axis, in the order Z, X, Y (Z first, clear of the work; one axis at a time), as grbl's:
//! 1. **Seek** toward the switch at `$25`, at most 1.5 times the axis's travel between its soft
//!    limits; the switch must close (else `ALARM:9`). Then `$26` ms of pause.
//! 2. **Pull off** by `$27` at `$25`; the switch must open (else `ALARM:8`).
//! 3. **Locate** toward the switch at `$24`, at most 5 times `$27`; it must close (`ALARM:9`).
//!    Then `$26` ms of pause.
//! 4. **Pull off** by `$27` at `$25`; the switch must open (`ALARM:8`). The axis is home: the
//!    loader makes its position there the soft limit on the switch's side, less the pull-off
//!    ([`home_position`]), so the switch sits on the soft limit.
//!
//! The direction: toward the positive end unless `$23` has the axis's bit (grbl's "direction
//! invert mask"). A reset or an e-stop during the cycle is the loader's (`ALARM:6`, or the trip).

use crate::protocol::codes::alarm;
use crate::settings::{Settings, Setup};

/// The homing order: Z, then X, then Y.
pub const ORDER: [usize; 3] = [2, 0, 1];

/// What the loader does next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Move `axis` by `um` micrometres at `rate_um_min`; with `until_switch` the move stops at
    /// once when the axis's switch closes.
    Move {
        axis: usize,
        um: i64,
        rate_um_min: u32,
        until_switch: bool,
    },
    /// Wait `ms` milliseconds (the switch's debounce, `$26`).
    Pause { ms: u32 },
    /// `axis` is home: its position becomes [`home_position`].
    Home { axis: usize },
    /// Every axis asked for is home.
    Done,
    /// The cycle failed with this alarm (8: the pull-off did not open the switch, 9: no switch
    /// within the search distance).
    Fail(u8),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Start,
    Seek,
    SeekPause,
    PullOff,
    Locate,
    LocatePause,
    FinalPullOff,
}

/// The homing cycle for the axes of a mask.
#[derive(Clone, Copy, Debug)]
pub struct Cycle {
    setup: Setup,
    /// Each axis's travel between its soft limits, um.
    travel_um: [i64; 3],
    /// The axes still to home, in [`ORDER`].
    axes: [Option<usize>; 3],
    at: usize,
    phase: Phase,
}

impl Cycle {
    /// The cycle for the axes of `mask` (bit k: axis k) with the set-up and the NC settings'
    /// soft limits.
    pub fn new(mask: u8, setup: &Setup, nc: &Settings) -> Cycle {
        let nm = i64::from(nc.blu.nm());
        let travel_um =
            [0, 1, 2].map(|k| (i64::from(nc.soft_max[k]) - i64::from(nc.soft_min[k])) * nm / 1000);
        Cycle {
            setup: *setup,
            travel_um,
            axes: ORDER.map(|k| (mask & (1 << k) != 0).then_some(k)),
            at: 0,
            phase: Phase::Start,
        }
    }

    /// The axis being homed, if any.
    pub fn axis(&self) -> Option<usize> {
        self.axes.iter().skip(self.at).flatten().next().copied()
    }

    /// +1 or -1: the direction toward `axis`'s switch.
    pub fn toward(&self, axis: usize) -> i64 {
        if self.setup.homing_dir_mask & (1 << axis) != 0 {
            -1
        } else {
            1
        }
    }

    /// The next step. `switch`: whether the axis's switch is closed now that the last step ended
    /// (ignored at the start and after a [`Step::Home`]).
    pub fn next(&mut self, switch: bool) -> Step {
        // Skip the axes not asked for.
        while self.at < self.axes.len() && self.axes.get(self.at).copied().flatten().is_none() {
            self.at += 1;
        }
        let Some(axis) = self.axis() else {
            return Step::Done;
        };
        let s = &self.setup;
        let toward = self.toward(axis);
        let pulloff = i64::from(s.homing_pulloff_um);
        let travel = self.travel_um.get(axis).copied().unwrap_or(0);
        let (phase, step) = match self.phase {
            Phase::Start => (
                Phase::Seek,
                Step::Move {
                    axis,
                    um: toward * (travel + travel / 2),
                    rate_um_min: s.homing_seek_um_min,
                    until_switch: true,
                },
            ),
            Phase::Seek | Phase::Locate if !switch => {
                return Step::Fail(alarm::HOMING_NO_SWITCH);
            }
            Phase::Seek => (
                Phase::SeekPause,
                Step::Pause {
                    ms: s.homing_debounce_ms,
                },
            ),
            Phase::SeekPause => (
                Phase::PullOff,
                Step::Move {
                    axis,
                    um: -toward * pulloff,
                    rate_um_min: s.homing_seek_um_min,
                    until_switch: false,
                },
            ),
            Phase::PullOff | Phase::FinalPullOff if switch => {
                return Step::Fail(alarm::HOMING_PULLOFF);
            }
            Phase::PullOff => (
                Phase::Locate,
                Step::Move {
                    axis,
                    um: toward * 5 * pulloff,
                    rate_um_min: s.homing_feed_um_min,
                    until_switch: true,
                },
            ),
            Phase::Locate => (
                Phase::LocatePause,
                Step::Pause {
                    ms: s.homing_debounce_ms,
                },
            ),
            Phase::LocatePause => (
                Phase::FinalPullOff,
                Step::Move {
                    axis,
                    um: -toward * pulloff,
                    rate_um_min: s.homing_seek_um_min,
                    until_switch: false,
                },
            ),
            Phase::FinalPullOff => {
                self.at += 1;
                (Phase::Start, Step::Home { axis })
            }
        };
        self.phase = phase;
        step
    }
}

/// Where a homed axis stands, BLU: its soft limit on the switch's side less the pull-off (rounded
/// to the nearest BLU), so the switch closes at the soft limit.
pub fn home_position(axis: usize, setup: &Setup, nc: &Settings) -> i32 {
    // Setup::validate keeps the pull-off within the travel: it fits.
    let pulloff = i64::from(
        crate::gcode::fine::blu_of_um(nc, i64::from(setup.homing_pulloff_um)).unwrap_or(i32::MAX),
    );
    let k = axis.min(2);
    let at = if setup.homing_dir_mask & (1 << k) != 0 {
        i64::from(nc.soft_min[k]) + pulloff
    } else {
        i64::from(nc.soft_max[k]) - pulloff
    };
    // Setup::validate keeps the pull-off within the travel: `at` lies between the soft limits.
    at as i32
}

#[cfg(test)]
mod tests;
