//! The AC program of the paper (adaptive control by constraint): DRR (ADC codes -> N, N*m),
//! ECR (errors), FRC (feed strategy), plus what the paper left out: overload hold and sensor-fault
//! hold with alarms. [`AcController`] runs in the AC task: `sample` at the sample rate (1 kHz),
//! `period` every AC period (10 ms), `resume` on the operator's command.
//!
//! Sensor faults (issue 6): per sample the DRR checks range, rails, and judges jumps by their
//! physical plausibility (a load step that persists and agrees with the torque is load; a lone
//! spike, or a jump force and torque disagree on, is a fault); per period the controller checks
//! for frozen channels while the axes feed and for a gain fault (F*R/T of the window peaks outside
//! the tool's band, [`plaus`]). Each has its own [`Alarm`]. Cost per sample: a few integer compares (and one F, T conversion
//! for a jump); per period: three f32 multiplications more than before.
//!
//! The controller only writes a feed cap (a feed number) for the frame, which takes
//! min(programmed, cap); 0 holds the feed. A hold never loses position: the frame keeps its
//! counters and simply stops feeding.
//!
//! Arithmetic is f32 (IEEE basic operations and the correctly rounded `libm::sqrtf` only), the
//! same code and types on the host and the target, so results are the same bits on both.

pub mod drr;
pub mod ecr;
pub mod frc;
pub mod law;
pub mod plaus;
pub mod settings;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_faults;

pub use drr::{Drr, Measured, Sensor, SensorFault, CODE_MAX};
pub use ecr::Errors;
pub use settings::{AcSettings, AcSettingsError, Calibration, FeedCeiling, Pick};

/// Why the controller holds the feed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Alarm {
    /// The critical error fell below the overload limit: the measured force and torque, the
    /// optimal values F0, T0, the permissible limits and the critical error.
    Overload {
        f_n: f32,
        t_nm: f32,
        f0_n: f32,
        t0_nm: f32,
        force_limit_n: f32,
        torque_limit_nm: f32,
        e: f32,
    },
    /// A sensor sample failed a plausibility check.
    Sensor(SensorFault),
    /// No sample arrived (or none passed the checks) during an AC period.
    NoSamples,
    /// Force and torque disagree: F*R/T of the window peaks (`ratio`) stayed outside the band
    /// `lo..hi` the tool geometry allows for `periods` AC periods while cutting. A gain fault (a
    /// loose transducer reads a fraction of the force) that the force codes alone cannot show;
    /// it cannot say which channel is wrong, so it names no sensor.
    ForceTorqueMismatch {
        f_n: f32,
        t_nm: f32,
        ratio: f32,
        lo: f32,
        hi: f32,
        periods: u32,
    },
    /// The process monitor heard chatter (`crate::monitor::chatter`): the largest amplitude of
    /// the sound spectrum away from the tooth harmonics, its frequency and the threshold.
    Chatter {
        freq_hz: f32,
        amplitude: f32,
        threshold: f32,
    },
    /// The process monitor declared a tool breakage (`crate::monitor::breakage`): the tooth
    /// period of the declaration and the residuals and thresholds that made it. The reaction
    /// stops the spindle as well as the feed (`Status::spindle_stop`).
    ToolBreakage(crate::monitor::Breakage),
}

impl Alarm {
    /// A short fixed text per kind of alarm.
    pub const fn message(&self) -> &'static str {
        match self {
            Alarm::Overload { .. } => "overload: cutting force or torque above the overload limit",
            Alarm::Sensor(SensorFault::Stuck { .. }) => "sensor stuck at an ADC rail",
            Alarm::Sensor(SensorFault::Jump { .. }) => "sensor jump larger than plausible",
            Alarm::Sensor(SensorFault::Range { .. }) => "sensor code outside 0..=4095",
            Alarm::Sensor(SensorFault::Frozen { .. }) => "sensor frozen while the axes feed",
            Alarm::NoSamples => "no fresh sensor samples in an AC period",
            Alarm::ForceTorqueMismatch { .. } => "force and torque disagree (transducer gain)",
            Alarm::Chatter { .. } => "chatter: the sound spectrum above its threshold",
            Alarm::ToolBreakage(b) => b.message(),
        }
    }
}

impl core::fmt::Display for Alarm {
    fn fmt(&self, w: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Alarm::Overload {
                f_n,
                t_nm,
                f0_n,
                t0_nm,
                force_limit_n,
                torque_limit_nm,
                e,
            } => write!(
                w,
                "overload hold: F = {f_n:.1} N (F0 {f0_n:.1} N, limit {force_limit_n:.1} N), \
                 T = {t_nm:.2} N*m (T0 {t0_nm:.2} N*m, limit {torque_limit_nm:.2} N*m), E = {e:.4}"
            ),
            Alarm::Sensor(SensorFault::Stuck { sensor, code }) => {
                write!(w, "sensor hold: {} stuck at code {code}", sensor.name())
            }
            Alarm::Sensor(SensorFault::Jump { sensor, from, to }) => {
                write!(
                    w,
                    "sensor hold: {} jumped from code {from} to {to}",
                    sensor.name()
                )
            }
            Alarm::Sensor(SensorFault::Range { sensor, code }) => {
                write!(
                    w,
                    "sensor hold: {} code {code} outside 0..=4095",
                    sensor.name()
                )
            }
            Alarm::Sensor(SensorFault::Frozen {
                sensor,
                code,
                samples,
            }) => write!(
                w,
                "sensor hold: {} frozen at code {code} for {samples} samples",
                sensor.name()
            ),
            Alarm::NoSamples => w.write_str("sensor hold: no fresh samples in an AC period"),
            Alarm::ForceTorqueMismatch {
                f_n,
                t_nm,
                ratio,
                lo,
                hi,
                periods,
            } => write!(
                w,
                "sensor hold: force and torque disagree: F*R/T = {ratio:.2} outside \
                 {lo:.2}..{hi:.2} for {periods} periods (F = {f_n:.1} N, T = {t_nm:.2} N*m)"
            ),
            Alarm::Chatter {
                freq_hz,
                amplitude,
                threshold,
            } => write!(
                w,
                "chatter hold: {amplitude:.1} at {freq_hz:.0} Hz above the threshold {threshold:.1}"
            ),
            Alarm::ToolBreakage(b) => write!(w, "breakage hold: {b}"),
        }
    }
}

/// The controller's state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AcState {
    /// Adapting the feed (the paper's loop).
    Run,
    /// Feed held (cap 0) because of the alarm; leaves only through [`AcController::resume`].
    Hold(Alarm),
}

/// What one AC period produces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AcOutput {
    /// Feed number for the frame: the FRC's f in Run, 0 in Hold.
    pub feed_cap: u32,
    pub state: AcState,
    /// The critical error of this period (the last one computed if no sample arrived).
    pub e: f32,
    /// Measured resultant force in N (picked from the window).
    pub f_n: f32,
    /// Measured torque magnitude in N*m (picked from the window).
    pub t_nm: f32,
    /// The alarm raised in this period (Some only in the period that enters Hold).
    pub alarm: Option<Alarm>,
}

/// The AC program: DRR, ECR, FRC and the holds.
#[derive(Clone, Debug)]
pub struct AcController {
    s: AcSettings,
    f0_n: f32,
    t0_nm: f32,
    step: f32,
    drr: Drr,
    /// The FRC's feed number, always in [f_min, f_max].
    f: u32,
    state: AcState,
    /// First sensor fault seen since the last period.
    pending: Option<SensorFault>,
    e: f32,
    f_n: f32,
    t_nm: f32,
    /// Feed number achieved over the last period (anti-windup), taken by the next `period`.
    achieved: Option<u32>,
    band: plaus::Band,
    /// Periods with F*R/T of the window peaks outside the band since the last one inside it.
    mismatch: u32,
    /// The feed law (strategy): the settings' (`AcSettings::strategy`), or another one from
    /// [`AcController::with_law`].
    law: law::FeedLaw,
}

/// Applies the feed ceiling of an enabled AC to a validated block before it is queued (loader task):
/// with [`FeedCeiling::Frm`] a feed block is queued at FRM (f = q0), so the controller's cap alone
/// sets its feed. The frame is unchanged (it always takes min(block feed, cap)).
pub fn apply_ceiling(block: &mut crate::nc::Block, ceiling: FeedCeiling, q0: u32) {
    use crate::nc::Motion;
    if ceiling == FeedCeiling::Frm {
        match &mut block.motion {
            Motion::Linear(l) => l.f = q0,
            Motion::Arc(c) => c.f = q0,
            Motion::Rapid(_) | Motion::Dwell(_) => {}
        }
    }
}

/// The feed number the machine achieved over one AC period from the position change `delta_blu`
/// (encoder counts): path length isqrt(dx^2 + dy^2 + dz^2) per period, in the frame's feed units
/// (f = q0 x BLU-per-second / W0). Integer arithmetic: the same result on host and target.
pub fn achieved_feed(delta_blu: [i64; 3], nc: &crate::Settings, period_ms: u32) -> u32 {
    let sq: u64 = delta_blu
        .iter()
        .map(|d| d.unsigned_abs().saturating_mul(d.unsigned_abs()))
        .fold(0, u64::saturating_add);
    let len = crate::nc::isqrt(sq);
    let den = (nc.frame_hz as u64).saturating_mul(period_ms as u64).max(1);
    let f = len.saturating_mul(nc.q0 as u64).saturating_mul(1000) / den;
    u32::try_from(f).unwrap_or(u32::MAX)
}

impl AcController {
    /// A controller in Run at f = f_min, or the reason the settings are refused.
    pub fn new(s: AcSettings) -> Result<Self, AcSettingsError> {
        s.validate()?;
        Ok(AcController {
            f0_n: s.f0_n(),
            t0_nm: s.t0_nm(),
            step: s.step_per_period(),
            drr: Drr::new(&s),
            f: s.f_min,
            state: AcState::Run,
            pending: None,
            e: 1.0,
            f_n: 0.0,
            t_nm: 0.0,
            achieved: None,
            band: plaus::Band::new(&s),
            mismatch: 0,
            law: law::FeedLaw::new(s.strategy, s.nominal_feed, s.f_max, s.gpc_lambda),
            s,
        })
    }

    /// The controller with another feed law (see [`law`]); the holds, the clamps, the
    /// anti-windup lead and the ceilings stay as they are.
    pub fn with_law(mut self, law: law::FeedLaw) -> Self {
        self.law = law;
        self
    }

    /// The feed law's on-line estimates (see [`law::FeedLaw::estimates`]), for the host's runs
    /// and plots; the firmware does not call it.
    pub fn law_estimates(&self) -> Option<[f32; 5]> {
        self.law.estimates()
    }

    /// Anti-windup (beyond the paper). The frame takes min(programmed feed, cap), so while the
    /// programmed feed binds, the paper's FRC would keep raising f towards f_max with nothing to
    /// show for it, and the next block with a higher programmed feed would start at f_max: a step
    /// into the cut that no 10 ms loop can catch. With the feed achieved over the last period (see
    /// [`achieved_feed`]) the next `period` keeps f at most one FRC step (fdot_m x dt) above it.
    /// Without a call the paper's FRC runs unchanged.
    pub fn set_achieved(&mut self, f: u32) {
        self.achieved = Some(f);
    }

    pub fn settings(&self) -> &AcSettings {
        &self.s
    }

    pub fn state(&self) -> AcState {
        self.state
    }

    /// The feed cap the frame should read now: f in Run, 0 in Hold.
    pub fn feed_cap(&self) -> u32 {
        match self.state {
            AcState::Run => self.f,
            AcState::Hold(_) => 0,
        }
    }

    /// Holds the feed for a process monitor's alarm (chatter; cap 0 from now on, until an
    /// explicit resume, as every hold). True when it entered the hold, false when already held.
    pub fn hold(&mut self, alarm: Alarm) -> bool {
        if self.state != AcState::Run {
            return false;
        }
        self.state = AcState::Hold(alarm);
        true
    }

    /// Holds the feed for a tool breakage whatever hold came before it (an overload from the
    /// broken tooth's doubled chip, a sensor hold, chatter): the breakage is what the operator
    /// must be told, and what a reset alone may end. True when the state changed.
    pub fn hold_over(&mut self, alarm: Alarm) -> bool {
        if self.state == AcState::Hold(alarm) {
            return false;
        }
        self.state = AcState::Hold(alarm);
        true
    }

    /// One conversion [T, Fu, Fv] (12-bit codes), at the sample rate. A faulty sample is kept
    /// out of the window and holds the feed at the next `period` (within one AC period).
    pub fn sample(&mut self, codes: [u16; 3]) {
        if let Err(fault) = self.drr.sample(codes) {
            self.pending = self.pending.or(Some(fault));
        }
    }

    /// One AC period: ends the DRR window, runs ECR and FRC (or holds), returns the feed cap.
    pub fn period(&mut self) -> AcOutput {
        let measured = self.drr.take(self.s.pick);
        let mut mismatch = None;
        let mut out_of_band = false;
        if let Some(m) = measured {
            let err = ecr::errors(m.f_n, m.t_nm, self.f0_n, self.t0_nm);
            self.e = err.e;
            self.f_n = m.f_n;
            self.t_nm = m.t_nm;
            // Gain fault: force against torque on this window's own peaks. A window in the band
            // restarts the count; one below the floor (a tooth gap, air) leaves it.
            let w = self.drr.window_peak();
            match self.band.judge(w.f_n, w.t_nm) {
                Some(true) => self.mismatch = 0,
                Some(false) => {
                    self.mismatch = self.mismatch.saturating_add(1);
                    out_of_band = true;
                }
                None => {}
            }
            // Raised only on a window that is itself out of the band (after a resume in air the
            // count stays, and the next window out of the band holds again at once).
            if self.s.ft_periods > 0 && out_of_band && self.mismatch >= self.s.ft_periods {
                mismatch = Some(Alarm::ForceTorqueMismatch {
                    f_n: w.f_n,
                    t_nm: w.t_nm,
                    ratio: self.band.ratio(w.f_n, w.t_nm),
                    lo: self.s.ft_ratio_min,
                    hi: self.s.ft_ratio_max,
                    periods: self.mismatch,
                });
            }
        }
        let pending = self.pending.take();
        let achieved = self.achieved.take();
        // Frozen channels count only while the axes feed (an idle machine may be quiet); without
        // an achieved feed the controller cannot tell, and the check is off.
        let frozen = if achieved.is_some_and(|a| a > 0) {
            self.drr.frozen(self.s.frozen_samples)
        } else {
            self.drr.restart_frozen();
            None
        };
        let mut alarm = None;
        if self.state == AcState::Run {
            // A sample-level sensor fault comes first: the samples after it (a channel stuck at
            // the level it jumped to) may read as an overload. A real load step raises no fault
            // (the DRR judges jumps), so an overload is still reported as an overload. Then the
            // overload, the period-level checks, and the absence of samples.
            alarm = match (pending, measured) {
                (Some(fault), _) => Some(Alarm::Sensor(fault)),
                (None, Some(m)) if self.e < self.s.overload_e => Some(Alarm::Overload {
                    f_n: m.f_n,
                    t_nm: m.t_nm,
                    f0_n: self.f0_n,
                    t0_nm: self.t0_nm,
                    force_limit_n: self.s.force_limit_n,
                    torque_limit_nm: self.s.torque_limit_nm,
                    e: self.e,
                }),
                (None, _) if frozen.is_some() => frozen.map(Alarm::Sensor),
                (None, _) if mismatch.is_some() => mismatch,
                (None, None) => Some(Alarm::NoSamples),
                (None, Some(_)) => {
                    // The paper's FRC lowers the feed on the latest window alone: the held peak
                    // (see `peak_windows`) keeps an overload for windows after the feed has cut
                    // it, and the FRC's tenfold deceleration would take the feed to f_min for
                    // it (a limit cycle behind a lagging feed drive). Above F0 in the held peak
                    // but not in the latest window: no change. Raises still wait for the held
                    // peak.
                    let e = if matches!(self.law, law::FeedLaw::Paper) && self.e < 0.0 {
                        let w = self.drr.window_peak();
                        ecr::errors(w.f_n, w.t_nm, self.f0_n, self.t0_nm).e.min(0.0)
                    } else {
                        self.e
                    };
                    let f = self.law.next(
                        self.f,
                        e,
                        achieved.unwrap_or(self.f),
                        self.step,
                        self.s.f_min,
                        self.s.f_max,
                    );
                    // Every law raises the feed by at most fdot_m x dt per period (the paper's
                    // FRC does so by construction: E <= 1). A law may lower it faster (the safe
                    // direction); the frame ramps both at the axes' acceleration.
                    let f = f.min(self.f.saturating_add(self.step as u32));
                    // While force and torque disagree the measured load may be too low: no raise.
                    self.f = if self.s.ft_periods > 0 && out_of_band {
                        f.min(self.f)
                    } else {
                        f
                    };
                    if let Some(a) = achieved {
                        let lead = a.saturating_add(self.step as u32).max(self.s.f_min);
                        if self.f > lead {
                            self.f = lead;
                        }
                    }
                    None
                }
            };
            if let Some(a) = alarm {
                self.state = AcState::Hold(a);
            }
        }
        AcOutput {
            feed_cap: self.feed_cap(),
            state: self.state,
            e: self.e,
            f_n: self.f_n,
            t_nm: self.t_nm,
            alarm,
        }
    }

    /// The operator's resume: leaves Hold and restarts the FRC from f_min. A fault or overload
    /// that persists holds again at the next period. No effect in Run.
    pub fn resume(&mut self) {
        if let AcState::Hold(_) = self.state {
            self.state = AcState::Run;
            self.f = self.s.f_min;
            self.law.resume();
        }
    }
}
