//! The tool change's sequence (loader task; host tests): which move comes next at an M6 with
//! `$341` = 1 or 2, from the set-up's settings and what ended the last step. The loader runs
//! each step (a rapid in machine coordinates, a probing move down that stops at the probe's
//! contact, the operator fitting the tool, the new tool length offset) and tells
//! [`Change::next`] how it ended; this module holds no hardware and queues nothing.
//!
//! `$341=1`, the table's length:
//! 1. Z rapids to the G30 position's Z (`G30.1` stores it), then X and Y to the G30 position.
//! 2. The operator fits the new tool and presses cycle start (a program run unattended goes on
//!    at once: the machine fits it, or there is nobody to).
//! 3. The tool length offset becomes the tool table's length of the new tool (as `G43 H<n>`).
//! 4. The spindle runs again as before the change; X and Y rapid back to where the M6 came, then
//!    Z to where the new tool's tip is where the old one's was (the old Z plus the change of the
//!    tool length offset).
//!
//! `$341=2`, the tool setter: as 1, but the new tool is measured on the tool setter at `$345`,
//! `$346` (machine coordinates) between 2 and 3: from the G30 Z it probes down at most `$342` at
//! `$344`, backs off by the pull-off `$27`, probes again at `$343` over twice the pull-off, and
//! the tool length offset becomes the old one plus how much higher (or lower) the new tool's tip
//! touched than the old one's. The old tool's contact is measured the same way before it comes
//! out, at the first change after power-up or after the position was lost (the loader keeps it,
//! [`Change::reference`], across changes); a probe that finds no contact fails the change with
//! `ALARM:5`.

use crate::gcode::fine::{blu_of_um, fine_of_pm, fine_to_blu};
use crate::protocol::codes::alarm;
use crate::protocol::report::pm_per_blu;
use crate::settings::{Settings, Setup};

/// What the loader does next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Rapid to these machine coordinates (BLU; the axes given only).
    Rapid([Option<i32>; 3]),
    /// Probe down: move -Z at most `blu` at `rate_um_min`, stopping at once at the probe's
    /// contact.
    Probe { blu: i32, rate_um_min: u32 },
    /// The operator fits `tool` and presses cycle start.
    Fit { tool: u8 },
    /// The new tool length offset, picometres; `table`: the table's length of the new tool (as
    /// `G43 H<n>`), else a measured one (as `G43.1`).
    Length { tlo_pm: i64, table: bool },
    /// The spindle runs again as it did before the change.
    Spindle,
    /// The change is done.
    Done,
    /// The change failed with this alarm.
    Fail(u8),
}

/// How the last step ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ended {
    /// The start, a rapid, the operator's cycle start or a step without motion.
    Done,
    /// A probing move: the machine Z (BLU) where the probe touched, None without contact.
    Probed(Option<i32>),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Start,
    /// Z at the change height.
    Up,
    /// Over the setter (the old tool: `old`).
    OverSetter {
        old: bool,
    },
    Seek {
        old: bool,
    },
    BackOff {
        old: bool,
    },
    Slow {
        old: bool,
    },
    /// The old tool measured: up to the change height.
    UpAgain,
    /// At the change position.
    AtChange,
    /// The new tool fitted.
    Fitted,
    /// The new tool's length set.
    Measured,
    /// With the setter: back up at the change height.
    Risen,
    /// The spindle runs again.
    Over,
    Back,
    End,
}

/// One tool change.
#[derive(Clone, Copy, Debug)]
pub struct Change {
    setup: Setup,
    tool: u8,
    /// Where the M6 came, machine BLU.
    start: [i32; 3],
    /// The G30 position (the change position), machine BLU.
    g30: [i32; 3],
    /// The tool setter's X and Y, machine BLU.
    setter: [i32; 2],
    /// The back-off between the setter's two probes, BLU.
    backoff: i32,
    /// The probing distance `$342`, BLU.
    distance: i32,
    /// Picometres per BLU.
    pm_per_blu: i64,
    /// The tool length offset before the change, picometres.
    tlo_old_pm: i64,
    /// The tool table's length of the new tool, picometres.
    table_pm: i64,
    /// How much higher (BLU) the spindle stands for the new tool's tip to be where the old one's
    /// was: the table's length less the old offset (`$341=1`; rounded as a word is), then the
    /// measured difference (`$341=2`).
    rise: i32,
    /// Where the tool in the spindle touched the setter (machine Z, BLU).
    reference: Option<i32>,
    phase: Phase,
}

impl Change {
    /// The change to `tool` that began at `start` (machine BLU) with the G30 position `g30_pm`
    /// (machine picometres), the tool length offset in force `tlo_pm`, the new tool's table
    /// length `table_pm`, and where the tool in the spindle last touched the setter.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        tool: u8,
        start: [i32; 3],
        g30_pm: [i64; 3],
        tlo_pm: i64,
        table_pm: i64,
        reference: Option<i32>,
        setup: &Setup,
        nc: &Settings,
    ) -> Change {
        // As the parser rounds a word, saturated at the counters' range (a move there is refused
        // by the soft limits).
        let saturate = |v: Option<i32>, negative: bool| {
            v.unwrap_or(if negative { i32::MIN } else { i32::MAX })
        };
        let of_pm = |pm: i64| saturate(fine_to_blu(nc, fine_of_pm(pm)), pm < 0);
        let of_um = |um: i64| saturate(blu_of_um(nc, um), um < 0);
        Change {
            setup: *setup,
            tool,
            start,
            g30: g30_pm.map(of_pm),
            setter: setup.setter_um.map(|um| of_um(i64::from(um))),
            backoff: of_um(i64::from(setup.homing_pulloff_um)).max(1),
            distance: of_um(i64::from(setup.probe_distance_um)).max(1),
            pm_per_blu: pm_per_blu(nc.blu),
            tlo_old_pm: tlo_pm,
            table_pm,
            rise: of_pm(table_pm.saturating_sub(tlo_pm)),
            reference,
            phase: Phase::Start,
        }
    }

    /// Where the tool in the spindle touches the setter (machine Z, BLU), once measured: the
    /// loader keeps it for the next change.
    pub fn reference(&self) -> Option<i32> {
        self.reference
    }

    fn setter_mode(&self) -> bool {
        self.setup.tool_change == 2
    }

    /// The next step, after the last one `ended`.
    pub fn next(&mut self, ended: Ended) -> Step {
        let [gx, gy, gz] = self.g30;
        let [sx, sy] = self.setter;
        let (phase, step) = match (self.phase, ended) {
            (Phase::Start, _) => (Phase::Up, Step::Rapid([None, None, Some(gz)])),
            (Phase::Up, _) if self.setter_mode() && self.reference.is_none() => (
                Phase::OverSetter { old: true },
                Step::Rapid([Some(sx), Some(sy), None]),
            ),
            (Phase::Up | Phase::UpAgain, _) => {
                (Phase::AtChange, Step::Rapid([Some(gx), Some(gy), None]))
            }
            (Phase::OverSetter { old }, _) => (
                Phase::Seek { old },
                Step::Probe {
                    blu: self.distance,
                    rate_um_min: self.setup.probe_seek_um_min,
                },
            ),
            (Phase::Seek { old }, Ended::Probed(Some(z))) => (
                Phase::BackOff { old },
                Step::Rapid([None, None, Some(z.saturating_add(self.backoff))]),
            ),
            (Phase::BackOff { old }, _) => (
                Phase::Slow { old },
                Step::Probe {
                    blu: self.backoff.saturating_mul(2),
                    rate_um_min: self.setup.probe_slow_um_min,
                },
            ),
            (Phase::Slow { old: true }, Ended::Probed(Some(z))) => {
                self.reference = Some(z);
                (Phase::UpAgain, Step::Rapid([None, None, Some(gz)]))
            }
            (Phase::Slow { old: false }, Ended::Probed(Some(z))) => {
                // The new tool touched `z - reference` BLU higher than the old one: its tip is
                // that much further from the spindle.
                let old = self.reference.unwrap_or(z);
                let d = i64::from(z) - i64::from(old);
                self.rise = d.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
                self.reference = Some(z);
                (
                    Phase::Measured,
                    Step::Length {
                        tlo_pm: self.tlo_old_pm.saturating_add(d * self.pm_per_blu),
                        table: false,
                    },
                )
            }
            // No contact (or, not a sequence the loader makes, a probing phase ended by anything
            // but a probe).
            (Phase::Seek { .. } | Phase::Slow { .. }, _) => {
                (Phase::End, Step::Fail(alarm::PROBE_NO_CONTACT))
            }
            (Phase::AtChange, _) => (Phase::Fitted, Step::Fit { tool: self.tool }),
            (Phase::Fitted, _) if self.setter_mode() => (
                Phase::OverSetter { old: false },
                Step::Rapid([Some(sx), Some(sy), None]),
            ),
            (Phase::Fitted, _) => {
                // Measured nowhere: the reference contact belongs to the old tool.
                self.reference = None;
                (
                    Phase::Measured,
                    Step::Length {
                        tlo_pm: self.table_pm,
                        table: true,
                    },
                )
            }
            (Phase::Measured, _) if self.setter_mode() => {
                (Phase::Risen, Step::Rapid([None, None, Some(gz)]))
            }
            (Phase::Measured | Phase::Risen, _) => (Phase::Over, Step::Spindle),
            (Phase::Over, _) => (
                Phase::Back,
                Step::Rapid([Some(self.start[0]), Some(self.start[1]), None]),
            ),
            (Phase::Back, _) => {
                let z = i64::from(self.start[2]) + i64::from(self.rise);
                let z = z.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
                (Phase::End, Step::Rapid([None, None, Some(z)]))
            }
            (Phase::End, _) => (Phase::End, Step::Done),
        };
        self.phase = phase;
        step
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The setter's sequence, walked with a machine whose tools touch the setter at known
    /// heights: the old tool measured first (no reference yet), the fit at the G30 position,
    /// the new tool measured, the offset the old one plus the difference, the way back with the
    /// tip where it was. At the next change the reference is known: no measurement before it.
    #[test]
    fn the_setter_sequence_measures_old_then_new_and_returns() {
        let nc = Settings::default();
        let setup = Setup {
            tool_change: 2,
            setter_um: [25_400, 50_800],
            homing_pulloff_um: 254,
            ..Setup::default()
        };
        let pm = 2_540_000; // pm per BLU at the default 0.0001 in
        let start = [100, 200, -300];
        let mut c = Change::new(4, start, [0, 0, 5_000 * pm], 7 * pm, 0, None, &setup, &nc);
        // The old tool touches at Z -1 000, the new one 60 BLU higher.
        let mut probes = [Some(-990), Some(-1_000), Some(-930), Some(-940)].into_iter();
        let mut steps = Vec::new();
        let mut ended = Ended::Done;
        loop {
            let s = c.next(ended);
            steps.push(s);
            ended = match s {
                Step::Probe { .. } => Ended::Probed(probes.next().flatten()),
                Step::Done | Step::Fail(_) => break,
                _ => Ended::Done,
            };
        }
        let (seek, slow) = (setup.probe_seek_um_min, setup.probe_slow_um_min);
        let distance = (30_000 * 1000 + 1270) / 2540;
        assert_eq!(
            steps,
            [
                Step::Rapid([None, None, Some(5_000)]),
                Step::Rapid([Some(10_000), Some(20_000), None]),
                Step::Probe {
                    blu: distance,
                    rate_um_min: seek
                },
                Step::Rapid([None, None, Some(-890)]),
                Step::Probe {
                    blu: 200,
                    rate_um_min: slow
                },
                Step::Rapid([None, None, Some(5_000)]),
                Step::Rapid([Some(0), Some(0), None]),
                Step::Fit { tool: 4 },
                Step::Rapid([Some(10_000), Some(20_000), None]),
                Step::Probe {
                    blu: distance,
                    rate_um_min: seek
                },
                Step::Rapid([None, None, Some(-830)]),
                Step::Probe {
                    blu: 200,
                    rate_um_min: slow
                },
                Step::Length {
                    tlo_pm: 67 * pm,
                    table: false
                },
                Step::Rapid([None, None, Some(5_000)]),
                Step::Spindle,
                Step::Rapid([Some(100), Some(200), None]),
                Step::Rapid([None, None, Some(-240)]),
                Step::Done,
            ]
        );
        assert_eq!(c.reference(), Some(-940));
        // The next change knows the reference: straight to the change position.
        let mut c = Change::new(5, start, [0; 3], 0, 0, Some(-940), &setup, &nc);
        assert_eq!(c.next(Ended::Done), Step::Rapid([None, None, Some(0)]));
        assert_eq!(c.next(Ended::Done), Step::Rapid([Some(0), Some(0), None]));
        assert_eq!(c.next(Ended::Done), Step::Fit { tool: 5 });
        // A probe without contact fails the change.
        assert_eq!(
            c.next(Ended::Done),
            Step::Rapid([Some(10_000), Some(20_000), None])
        );
        c.next(Ended::Done);
        assert_eq!(
            c.next(Ended::Probed(None)),
            Step::Fail(alarm::PROBE_NO_CONTACT)
        );
    }

    /// The table's length (`$341=1`): no setter, the offset the table's, the reference
    /// forgotten (the new tool was not measured).
    #[test]
    fn the_table_sequence_takes_the_tables_length() {
        let nc = Settings::default();
        let setup = Setup {
            tool_change: 1,
            ..Setup::default()
        };
        let pm = 2_540_000;
        let mut c = Change::new(
            2,
            [0, 0, 0],
            [pm, 2 * pm, 3 * pm],
            0,
            500 * pm,
            Some(7),
            &setup,
            &nc,
        );
        let steps: Vec<Step> = (0..8).map(|_| c.next(Ended::Done)).collect();
        assert_eq!(
            steps,
            [
                Step::Rapid([None, None, Some(3)]),
                Step::Rapid([Some(1), Some(2), None]),
                Step::Fit { tool: 2 },
                Step::Length {
                    tlo_pm: 500 * pm,
                    table: true
                },
                Step::Spindle,
                Step::Rapid([Some(0), Some(0), None]),
                Step::Rapid([None, None, Some(500)]),
                Step::Done,
            ]
        );
        assert_eq!(c.reference(), None);
    }
}
