//! Host tests of the homing sequence against a one-axis-at-a-time machine model whose switches
//! close at set positions.
extern crate std;
use super::*;
use std::vec::Vec;

/// The machine: true positions (um) and, per axis, the switch's position and whether it works
/// (a broken switch never closes; a stuck one never opens).
struct Machine {
    at: [i64; 3],
    switch_at: [i64; 3],
    broken: [bool; 3],
    stuck: [bool; 3],
    /// Which side the switch closes on: +1 at and beyond it toward the positive end.
    side: [i64; 3],
}

impl Machine {
    fn closed(&self, k: usize) -> bool {
        self.stuck[k] || (!self.broken[k] && (self.at[k] - self.switch_at[k]) * self.side[k] >= 0)
    }

    /// Runs a move: to its end, or to the first um where the switch closes when `until`.
    fn run(&mut self, k: usize, um: i64, until: bool) {
        let dir = um.signum();
        for _ in 0..um.abs() {
            if until && self.closed(k) {
                return;
            }
            self.at[k] += dir;
        }
    }
}

/// Runs the cycle to its end; the steps taken and the final step.
fn home(mask: u8, setup: &Setup, nc: &Settings, m: &mut Machine) -> (Vec<Step>, Step) {
    let mut c = Cycle::new(mask, setup, nc);
    let mut steps = Vec::new();
    let mut switch = false;
    loop {
        let s = c.next(switch);
        steps.push(s);
        match s {
            Step::Move {
                axis,
                um,
                until_switch,
                ..
            } => {
                m.run(axis, um, until_switch);
                switch = m.closed(axis);
            }
            Step::Pause { .. } | Step::Home { .. } => {}
            Step::Done | Step::Fail(_) => return (steps, s),
        }
        assert!(steps.len() < 100);
    }
}

fn machine(at: [i64; 3]) -> Machine {
    Machine {
        at,
        // Switches 7 mm beyond where the machine starts, on the positive side.
        switch_at: [at[0] + 7_000, at[1] + 12_000, at[2] + 3_000],
        broken: [false; 3],
        stuck: [false; 3],
        side: [1; 3],
    }
}

#[test]
fn every_axis_homes_z_first_and_stands_its_pull_off_from_its_switch() {
    let setup = Setup {
        homing: true,
        ..Setup::default()
    };
    let nc = Settings::default();
    let mut m = machine([-40_000, 5_000, 0]);
    let (steps, end) = home(0b111, &setup, &nc, &mut m);
    assert_eq!(end, Step::Done);
    let homes: Vec<usize> = steps
        .iter()
        .filter_map(|s| match s {
            Step::Home { axis } => Some(*axis),
            _ => None,
        })
        .collect();
    assert_eq!(homes, [2, 0, 1]);
    for k in 0..3 {
        // The switch closes at switch_at; the final pull-off leaves the axis 1 mm short of it.
        assert_eq!(m.at[k], m.switch_at[k] - 1_000, "axis {k}");
    }
    // Seek at $25, locate at $24, over 1.5 x the travel and 5 x the pull-off.
    assert_eq!(
        steps[0],
        Step::Move {
            axis: 2,
            um: 304_800,
            rate_um_min: 500_000,
            until_switch: true
        }
    );
    assert!(steps.contains(&Step::Move {
        axis: 2,
        um: 5_000,
        rate_um_min: 25_000,
        until_switch: true
    }));
    assert!(steps.contains(&Step::Pause { ms: 250 }));
}

#[test]
fn the_direction_mask_homes_toward_the_negative_end_and_the_home_is_the_soft_minimum() {
    let setup = Setup {
        homing: true,
        homing_dir_mask: 0b001,
        ..Setup::default()
    };
    let nc = Settings::default();
    let mut m = machine([0; 3]);
    m.switch_at[0] = -30_000;
    m.side[0] = -1;
    let (_, end) = home(0b001, &setup, &nc, &mut m);
    assert_eq!(end, Step::Done);
    assert_eq!(
        m.at,
        [-29_000, 0, 0],
        "only X moved, to 1 mm inside its switch"
    );
    // The soft minimum plus the pull-off (394 BLU of 2.54 um), and the maximum less it.
    assert_eq!(home_position(0, &setup, &nc), -100_000 + 394);
    assert_eq!(home_position(1, &setup, &nc), 100_000 - 394);
}

#[test]
fn a_switch_that_never_closes_or_never_opens_fails_the_cycle() {
    let setup = Setup::default();
    let nc = Settings::default();
    let mut m = machine([0; 3]);
    m.broken[0] = true;
    let (steps, end) = home(0b001, &setup, &nc, &mut m);
    assert_eq!(end, Step::Fail(9), "{steps:?}");
    assert_eq!(steps.len(), 2, "the seek, then the failure");
    let mut m = machine([0; 3]);
    m.stuck[2] = true;
    let (_, end) = home(0b100, &setup, &nc, &mut m);
    assert_eq!(end, Step::Fail(8));
    // No axis asked for: done at once.
    assert_eq!(home(0, &setup, &nc, &mut machine([0; 3])).1, Step::Done);
}
