//! DRR, the Data Reading Routine: raw 12-bit ADC codes [T, Fu, Fv] -> N*m and N, the window of one
//! AC period (latest and peak sample) and the plausibility checks of every sample (code range,
//! stuck at a rail, implausible jump). Called from the AC task: `sample` at the sample rate,
//! `take` once per AC period.
//!
//! The paper's DRR overwrote its memory cells with every conversion, so the ECR saw the latest
//! sample. The cutter breaks at the peak, so this DRR keeps both per window: the latest sample and
//! the peaks (largest F = sqrt(Fu^2 + Fv^2) over the samples, computed per sample so that the peak
//! is a force that really occurred; largest |T|). [`Pick`] chooses which one the ECR uses.
//! T is taken as a magnitude (|T|): the spindle may turn either way; the paper's T is a magnitude.
//!
//! # Frozen channels (issue 6, D6)
//!
//! Per channel the DRR counts the samples the code has stayed within `frozen_codes` of the code
//! that started the run (integer compare per channel and sample). Whether a run is a fault is the
//! controller's decision: only while the axes feed (see [`super::AcController::period`]), because
//! an idle machine may have perfectly quiet transducers.
//!
//! # Jumps: load step or sensor fault (issue 6, D4)
//!
//! A code that moves more than `jump_codes` since the previous sample is a *jump*. A real load
//! can do that: with straight flutes a full-depth entry steps Fu by 1900 codes in one sample. A
//! jump is therefore judged by its physical plausibility before the sample may enter the window,
//! first by the other channels, F*R/T of the jumped sample against the force/torque band
//! ([`super::plaus`]):
//! - outside the band (a Fu spike does not move T, a T stuck at a rail does not move F), or a
//!   force that moved by more than the torque's change allows ([`Band::step_plausible`]: a Fu
//!   spike on a loaded tool, whose total may still look like a cut): [`SensorFault::Jump`] at once,
//!   the sample kept out;
//! - inside the band: load, into the window at once, even a one-sample pulse (the model makes
//!   them when a tooth meets a wall: the chips made it, so it counts);
//! - both F*R and T below the band's floor (nothing to judge; with the default 1500 codes and
//!   5 N*m floor a jump is always large enough to judge), or a channel that arrived at its rail
//!   (a saturated code is a bound, not a value): by persistence. The sample is kept out
//!   until the next one; if a jumped channel is back (closer to its code before the jump than to
//!   the jumped code) it was a lone spike, [`SensorFault::Jump`]; otherwise it enters the window.
//!
//! A code that *arrives at a rail* (0 or 4095) is judged the same way whatever its size, with both
//! ends of the band also while the tool plunges ([`Band::judge_both_ends`]): a saturated channel
//! is the `rail` fault's signature, and T = 4095 alone (102 N*m) would read as an overload. A
//! load beyond the range that the other channels confirm is still an overload.
//!
//! So a real load step reaches the ECR with its own sample and an overload is reported as an
//! overload; a spike never reaches the window. The `spike` fault (one sample of Fu +3000 codes,
//! then back) gives `sensor hold: Fu jumped from code A to B` and holds the feed at the end of
//! the AC period. (A Fu that flips from -3750 N to +3750 N keeps F and its totals, but its force
//! vector moved by 7500 N with no torque: [`Band::step_plausible`] refuses it.)

use super::ecr;
use super::plaus::Band;
use super::settings::{AcSettings, Calibration, Pick, PEAK_WINDOWS_MAX};

/// Largest code of a 12-bit ADC (the upper rail).
pub const CODE_MAX: u16 = 4095;

/// One ADC channel, in the order of the codes handed to `sample`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sensor {
    Torque,
    ForceU,
    ForceV,
}

impl Sensor {
    pub const ALL: [Sensor; 3] = [Sensor::Torque, Sensor::ForceU, Sensor::ForceV];

    pub const fn name(self) -> &'static str {
        match self {
            Sensor::Torque => "T",
            Sensor::ForceU => "Fu",
            Sensor::ForceV => "Fv",
        }
    }
}

/// A sample that cannot be a measurement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorFault {
    /// The code was at a rail (0 or 4095) for the settable number of consecutive samples.
    Stuck { sensor: Sensor, code: u16 },
    /// The code moved more than `jump_codes` (or arrived at a rail) since the previous sample and
    /// the jump was not plausible: force and torque disagreed, or it returned at the next sample.
    Jump { sensor: Sensor, from: u16, to: u16 },
    /// A code above 4095: not a 12-bit conversion.
    Range { sensor: Sensor, code: u16 },
    /// The code stayed within `frozen_codes` of `code` for `samples` samples while the axes fed.
    Frozen {
        sensor: Sensor,
        code: u16,
        samples: u32,
    },
}

/// What the ECR gets from one window: the resultant force F (N) and the torque magnitude (N*m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measured {
    pub f_n: f32,
    pub t_nm: f32,
}

/// A jumped sample kept out of the window until the next sample judges it.
#[derive(Clone, Copy, Debug)]
struct Suspect {
    codes: [u16; 3],
    /// The codes before the jump.
    from: [u16; 3],
    /// Bit k: channel k jumped.
    jumped: u8,
}

impl Suspect {
    /// The first jumped channel that `now` has brought back (closer to its code before the jump
    /// than to the jumped code): the jump was a spike.
    fn returned(&self, now: [u16; 3]) -> Option<usize> {
        (0..3).find(|&k| {
            self.jumped & (1 << k) != 0
                && now[k].abs_diff(self.from[k]) < now[k].abs_diff(self.codes[k])
        })
    }

    fn fault(&self, k: usize) -> SensorFault {
        SensorFault::Jump {
            sensor: Sensor::ALL[k],
            from: self.from[k],
            to: self.codes[k],
        }
    }
}

/// The DRR state: calibration, the running fault detectors and the current window.
#[derive(Clone, Debug)]
pub struct Drr {
    cal: [Calibration; 3],
    stuck_samples: u32,
    jump_codes: u16,
    band: Band,
    /// A jumped sample waiting for the next sample (see the module docs).
    suspect: Option<Suspect>,
    frozen_codes: u16,
    /// Per channel: the code that started the current run of unchanged codes, and its length.
    frozen_at: [u16; 3],
    frozen_run: [u32; 3],
    /// Previous in-range codes (for the jump check). Before the first sample: the channels'
    /// zero-load codes (their calibration offsets), so a fault present from the first sample (a
    /// channel at a rail, a spike) is judged as a jump from no load like any other; it read as
    /// an overload before, which `~` resumes without `$X`.
    prev: Option<[u16; 3]>,
    /// Consecutive samples at a rail, per channel.
    at_rail: [u32; 3],
    /// Samples accepted into the current window.
    count: u32,
    latest: Measured,
    peak: Measured,
    /// The peaks of the window the last `take` ended (its own samples, whatever the pick).
    window_peak: Measured,
    /// Peaks of the previous windows (a ring of `hold - 1`), for the held peak.
    past: [Measured; PEAK_WINDOWS_MAX],
    past_at: usize,
    hold: usize,
}

impl Drr {
    pub fn new(s: &AcSettings) -> Self {
        Drr {
            cal: s.cal,
            stuck_samples: s.stuck_samples,
            jump_codes: s.jump_codes,
            band: Band::new(s),
            suspect: None,
            frozen_codes: s.frozen_codes,
            frozen_at: [0; 3],
            frozen_run: [0; 3],
            prev: Some(
                s.cal
                    .map(|c| libm::roundf(c.offset).clamp(0.0, CODE_MAX as f32) as u16),
            ),
            at_rail: [0; 3],
            count: 0,
            latest: Measured {
                f_n: 0.0,
                t_nm: 0.0,
            },
            peak: Measured {
                f_n: 0.0,
                t_nm: 0.0,
            },
            window_peak: Measured {
                f_n: 0.0,
                t_nm: 0.0,
            },
            past: [Measured {
                f_n: 0.0,
                t_nm: 0.0,
            }; PEAK_WINDOWS_MAX],
            past_at: 0,
            hold: (s.peak_windows as usize).clamp(1, PEAK_WINDOWS_MAX),
        }
    }

    /// Whether the end face may be cutting (see [`Band::plunging`]): a jump is then judged by the
    /// band's upper end only. AC task, once per period.
    pub fn plunging(&mut self, on: bool) {
        self.band.plunging(on);
    }

    /// Engineering values of one set of codes: [T, Fu, Fv] -> (T in N*m, Fu in N, Fv in N).
    pub fn convert(&self, codes: [u16; 3]) -> (f32, f32, f32) {
        let [ct, cu, cv] = self.cal;
        let [t, u, v] = codes;
        (ct.value(t), cu.value(u), cv.value(v))
    }

    /// Engineering values of one sample: F (N) and |T| (N*m).
    fn measure(&self, codes: [u16; 3]) -> Measured {
        let (t, fu, fv) = self.convert(codes);
        Measured {
            f_n: ecr::force(fu, fv),
            t_nm: t.abs(),
        }
    }

    /// One conversion of the three ADCs. A faulty sample is reported and kept out of the window.
    /// Checks, per channel in the order T, Fu, Fv: range, then stuck at a rail; then the judgement
    /// of a pending jump and the jump check (see the module docs). A jumped sample too small for
    /// the force/torque judgement is kept out (`Ok`) until the next sample judges it.
    pub fn sample(&mut self, codes: [u16; 3]) -> Result<(), SensorFault> {
        let mut fault = None;
        for (k, (&code, &sensor)) in codes.iter().zip(Sensor::ALL.iter()).enumerate() {
            if code > CODE_MAX {
                fault = fault.or(Some(SensorFault::Range { sensor, code }));
                continue;
            }
            if let (Some(at), Some(run)) = (self.frozen_at.get_mut(k), self.frozen_run.get_mut(k)) {
                if *run > 0 && code.abs_diff(*at) <= self.frozen_codes {
                    *run = run.saturating_add(1);
                } else {
                    (*at, *run) = (code, 1);
                }
            }
            if let Some(run) = self.at_rail.get_mut(k) {
                *run = if code == 0 || code == CODE_MAX {
                    run.saturating_add(1)
                } else {
                    0
                };
                if self.stuck_samples > 0 && *run >= self.stuck_samples {
                    fault = fault.or(Some(SensorFault::Stuck { sensor, code }));
                }
            }
        }
        if fault.is_some() && codes.iter().any(|&c| c > CODE_MAX) {
            // Not a conversion: neither the jump reference nor a judge of a pending jump.
            return fault.map_or(Ok(()), Err);
        }
        let prev = self.prev.replace(codes);
        if let Some(s) = self.suspect.take() {
            match s.returned(codes) {
                // A lone spike: this sample is back where the one before the spike was.
                Some(k) => return Err(fault.unwrap_or(s.fault(k))),
                // The step persists: it was load.
                None => self.admit(self.measure(s.codes)),
            }
        }
        let m = self.measure(codes);
        if let Some(p) = prev {
            let rail = |c: u16| c == 0 || c == CODE_MAX;
            let mut saturated = false;
            let jumped = (0..3).fold(0u8, |acc, k| {
                let arrives = self.jump_codes < CODE_MAX && rail(codes[k]) && !rail(p[k]);
                saturated |= arrives;
                acc | (u8::from(arrives || p[k].abs_diff(codes[k]) > self.jump_codes) << k)
            });
            if jumped != 0 {
                let s = Suspect {
                    codes,
                    from: p,
                    jumped,
                };
                let first = jumped.trailing_zeros() as usize;
                let verdict = if saturated {
                    self.band.judge_both_ends(m.f_n, m.t_nm)
                } else {
                    self.band.judge(m.f_n, m.t_nm)
                };
                match verdict {
                    // Force and torque disagree: the other channels do not confirm the jump.
                    Some(false) => return Err(fault.unwrap_or(s.fault(first))),
                    // The force moved by more than the torque's change allows: a force spike
                    // on a loaded tool, whose new total may still look like a cut.
                    _ if !self
                        .band
                        .step_plausible(self.convert(p), self.convert(codes)) =>
                    {
                        return Err(fault.unwrap_or(s.fault(first)))
                    }
                    // They agree: load (even a one-sample pulse: the chips made it), unless a
                    // channel arrived at its rail: a saturated code is a bound, not a value (a
                    // Fu spike clamped at 4095 from near the top of the scale moves F by a few
                    // hundred N, within what the torque's noise allows).
                    Some(true) if !saturated => {}
                    // Too small to judge, or saturated: kept out until the next sample shows
                    // whether it persists.
                    _ => {
                        self.suspect = Some(s);
                        return fault.map_or(Ok(()), Err);
                    }
                }
            }
        }
        if let Some(f) = fault {
            return Err(f);
        }
        self.admit(m);
        Ok(())
    }

    /// Whether a jumped sample waits for the next one to be judged (see the module docs): the
    /// sampler's trip on it is then the DRR's to classify, a period later at most.
    pub fn judging(&self) -> bool {
        self.suspect.is_some()
    }

    /// One accepted sample into the window.
    fn admit(&mut self, m: Measured) {
        if self.count == 0 {
            self.peak = m;
        } else {
            self.peak.f_n = self.peak.f_n.max(m.f_n);
            self.peak.t_nm = self.peak.t_nm.max(m.t_nm);
        }
        self.latest = m;
        self.count = self.count.saturating_add(1);
    }

    /// The first channel whose code has not moved (beyond `frozen_codes`) for at least `samples`
    /// samples since the last [`Drr::restart_frozen`]. `samples` = 0: never.
    pub fn frozen(&self, samples: u32) -> Option<SensorFault> {
        if samples == 0 {
            return None;
        }
        (0..3).find_map(|k| {
            let (run, code) = (*self.frozen_run.get(k)?, *self.frozen_at.get(k)?);
            (run >= samples).then_some(SensorFault::Frozen {
                sensor: Sensor::ALL[k],
                code,
                samples: run,
            })
        })
    }

    /// Restarts the frozen-channel runs (the axes stood still: quiet codes are no fault).
    pub fn restart_frozen(&mut self) {
        self.frozen_run = [0; 3];
    }

    /// The peaks (largest F, largest |T|) of the window the last `take` ended, over its own
    /// samples, whatever the pick: the force/torque check compares them. Each accepted sample of a
    /// cut has F*R/T in the band, so the two peaks do too, even when they come from different
    /// samples.
    pub fn window_peak(&self) -> Measured {
        self.window_peak
    }

    /// Samples accepted into the current window so far.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// Ends the window: the picked measurement, or None when no sample arrived in it. The peak is
    /// the largest over this window and the `peak_windows - 1` windows before it.
    pub fn take(&mut self, pick: Pick) -> Option<Measured> {
        if self.count == 0 {
            return None;
        }
        self.count = 0;
        let cur = self.peak;
        let mut held = cur;
        for p in self.past.iter().take(self.hold - 1) {
            held.f_n = held.f_n.max(p.f_n);
            held.t_nm = held.t_nm.max(p.t_nm);
        }
        self.window_peak = cur;
        if self.hold > 1 {
            if let Some(slot) = self.past.get_mut(self.past_at) {
                *slot = cur;
            }
            self.past_at = (self.past_at + 1) % (self.hold - 1);
        }
        Some(match pick {
            Pick::Peak => held,
            Pick::Latest => self.latest,
        })
    }
}
