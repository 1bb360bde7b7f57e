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
//!
//! Under the plan (`$263=2`, [`FeedCeiling::Plan`], issue 11) the controller's feed number is a
//! ratio k x f_max that the frame multiplies every block's programmed feed by
//! ([`frame_words`]): the plan's feeds are the feed-forward, k the correction of its model's
//! error ([`PLAN_START`] documents the rules).

pub mod drr;
pub mod ecr;
pub mod frc;
pub mod law;
pub mod plaus;
pub mod settings;
pub mod strength;
#[cfg(test)]
mod tests;

pub use drr::{Drr, Measured, Sensor, SensorFault, CODE_MAX};
pub use ecr::Errors;
pub use settings::{AcSettings, AcSettingsError, Breakage, Calibration, FeedCeiling, Pick};

use crate::settings::Valid;

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
    /// Periods left in which the end face may cut (see [`AcController::set_z_down`]).
    z_down: u32,
    /// The feed law (strategy): the settings' (`AcSettings::strategy`), or another one from
    /// [`AcController::with_law`].
    law: law::FeedLaw,
    /// Under the plan: the controller's feed numbers of the last [`PLAN_HISTORY`] periods, the
    /// latest first (the chip a window measured was cut at one of them).
    plan_history: [u32; PLAN_HISTORY],
    /// Under the plan: whether a window has been loaded enough to judge the first contact (see
    /// [`PLAN_START`]).
    plan_learnt: bool,
    /// Under the plan, before the first contact is judged: periods loaded in a row.
    plan_loaded: u32,
    /// Under the plan: the plan's error (load per unit of k) of the last [`PLAN_HISTORY`]
    /// periods, the latest first (a raise needs an error that is not falling).
    plan_loads: [f32; PLAN_HISTORY],
}

/// Prediction and feedback together (`FeedCeiling::Plan`, issue 11): how the controller
/// corrects the plan (an optimised program: `millac optimise` sets every piece's feed for F0 at
/// the piece's peak) by the plan ratio k <= 1 the frame multiplies every block's feed by.
///
/// The firmware does not know what load the plan predicts for a window (a block says its feed,
/// not its load; a comment would not survive the senders that strip them), so it judges the
/// plan's error only where the measured load (the larger of F/F0 and T/T0) says it: near F0,
/// where the plan predicted about F0. With tol the plan's tolerance ([`plan_tolerance`]: half
/// the way from F0 to the overload hold, 0.05 at the defaults):
/// - **lower**: a window above 1 + tol lowers k at once to bring its load to 1 + tol / 2 (from the
///   largest k of the periods that can have cut its chip: the windows after a correction still
///   show the chip cut before it, and are not corrected twice);
/// - **raise**: a window from 1 / (1 + tol) to 1 whose load per unit of k is not falling
///   ([`PLAN_STEADY`]: a load that stays while k rises is a cut leaving the material, not the
///   plan's error) raises k at once to bring it to F0 (from the smallest k of those periods, at
///   most 1 and at most one FRC step a period): a correction comes back wherever the plan is
///   right again (a hidden boss met at the guard's 1.056 F0 is lowered to 1 + tol / 2, and the
///   plan's next cut at F0 loads 0.97, within the band), while a light window raises k by at
///   most 1 + tol, so an entry after it meets at most 1 + tol of F0 (a material the plan
///   underrates does not creep back to the plan's feed in a pass that leaves the material);
///   a spike above about 1 + 1.5 tol (1.076 F0 at the defaults) that the plan does not repeat
///   leaves k below the band until a window loads it again, perhaps not before the end of the
///   job (the price of the bound);
/// - **first contact**: k starts at [`PLAN_START`], so that the first entry, a step no 10 ms
///   loop can follow (the peak force of an entry is the full tooth's at once), meets a material
///   up to 1.22 times as hard as the plan assumed below the overload hold; until a window has
///   been loaded to PLAN_START / (1 + tol) for longer than the held peak (`peak_windows`: the
///   entry's rising edge, the tooth not yet full, is not judged), that load sets k both ways to
///   bring it to F0;
/// - lighter windows (air, a corner's dip) leave k as it is: a correction learnt in one cut
///   carries across the air cut to the next entry.
///
/// Bounds: within the tolerance nothing changes, so the noise of the measured peak and the
/// plan's own rounding (a percent or two above F0 at a piece's peak) do not slow the plan; after
/// a correction an entry meets at most 1 + tol / 2 of F0 (times the error's change).
pub const PLAN_START: f32 = 0.9;
/// A window raises k only while the plan's error it shows (its load per unit of k) is not
/// falling: at least this fraction of that of every one of the last [`PLAN_HISTORY`] periods
/// (see [`PLAN_START`]).
pub const PLAN_STEADY: f32 = 0.99;
/// Periods of k kept for a correction (the chip lags the feed by up to a tooth period, and the
/// held peak by `peak_windows`).
pub const PLAN_HISTORY: usize = 4;

/// The plan's tolerance tol of [`PLAN_START`]: half the way from F0 to the overload hold, as a
/// fraction of F0 (`-overload_e / 2`; 0.05 at the defaults, where the hold is at 1.1 F0).
pub fn plan_tolerance(s: &AcSettings) -> f32 {
    -0.5 * s.overload_e
}

/// k = PLAN_START as the controller's feed number (k x f_max).
fn plan_start(s: &AcSettings) -> u32 {
    (s.f_max as f32 * PLAN_START) as u32
}

/// The frame's words for the controller's output `feed_cap` (its feed number, 0 in a hold):
/// (feed cap, plan ratio in Q12). Outside the plan they are the feed number and
/// [`crate::ports::PLAN_ONE`]. Under the plan ([`FeedCeiling::Plan`]) the controller's feed
/// number is k x f_max: the frame's cap is f_max (FRM, 0 in a hold) and the ratio k, rounded to
/// the nearest 4096th and never above 1. AC task (and the host simulation).
pub fn frame_words(feed_cap: u32, s: &AcSettings) -> (u32, u32) {
    use crate::ports::PLAN_ONE;
    if s.ceiling != FeedCeiling::Plan || feed_cap == 0 {
        return (feed_cap, PLAN_ONE);
    }
    let f_max = u64::from(s.f_max.max(1));
    let k = (u64::from(feed_cap) * u64::from(PLAN_ONE) + f_max / 2) / f_max;
    (s.f_max, k.min(u64::from(PLAN_ONE)) as u32)
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
    /// A controller in Run at f = f_min (its settings checked: see [`Valid`]).
    pub fn new(s: Valid<AcSettings>) -> Self {
        let s = s.get();
        let mut c = AcController {
            f0_n: s.f0_n(),
            t0_nm: s.t0_nm(),
            step: s.step_per_period(),
            drr: Drr::new(&s),
            state: AcState::Run,
            pending: None,
            e: 1.0,
            f_n: 0.0,
            t_nm: 0.0,
            achieved: None,
            band: plaus::Band::new(&s),
            mismatch: 0,
            z_down: 0,
            law: law::FeedLaw::new(s.strategy, s.nominal_feed, s.f_max, s.gpc_lambda),
            // Under the plan the controller's feed number is k x f_max, and `new_job` starts it.
            f: s.f_min,
            plan_history: [s.f_min; PLAN_HISTORY],
            plan_learnt: false,
            plan_loaded: 0,
            plan_loads: [0.0; PLAN_HISTORY],
            s,
        };
        c.new_job();
        c
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

    /// The Z axis fed down over the last AC period (a plunge, a ramp, a helix: the end face may
    /// cut, see [`plaus`]): the force/torque band's lower end is not judged in this period and
    /// the held peak's windows after it, neither for the gain check nor for jumps. Without a
    /// call the whole band is judged, as before. AC task (`crate::rt::ac::AcPeriod::run`, from
    /// the encoder).
    pub fn set_z_down(&mut self, down: bool) {
        self.z_down = if down {
            self.s.peak_windows.max(1) + 1
        } else {
            self.z_down.saturating_sub(1)
        };
        let on = self.z_down > 0;
        self.band.plunging(on);
        self.drr.plunging(on);
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

    /// The settings as they came in, checked ([`AcController::new`] takes them validated and
    /// nothing changes them).
    pub fn valid_settings(&self) -> Valid<AcSettings> {
        Valid::checked(self.s)
    }

    /// Whether the DRR holds a jumped sample back until the next one tells a spike from load
    /// (see [`drr`]). AC task.
    pub fn judging(&self) -> bool {
        self.drr.judging()
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
                (None, Some(_)) if self.s.ceiling == FeedCeiling::Plan => {
                    self.plan_next(out_of_band);
                    None
                }
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
    /// that persists holds again at the next period. No effect in Run. Under the plan the ratio k
    /// restarts where it was, lowered by the load the hold measured when that was above F0
    /// (an overload is the plan's error there, as [`PLAN_START`]'s lowering corrects it).
    pub fn resume(&mut self) {
        if let AcState::Hold(_) = self.state {
            self.state = AcState::Run;
            self.f = if self.s.ceiling == FeedCeiling::Plan {
                let load = (1.0 - self.e).max(1.0);
                ((self.f as f32 / load) as u32).clamp(self.s.f_min, self.s.f_max)
            } else {
                self.s.f_min
            };
            self.plan_history = [self.f; PLAN_HISTORY];
            self.law.resume();
        }
    }

    /// A new job (the serial loader's program end, M2/M30, or soft reset:
    /// `crate::rt::Status::ac_new_job`; [`AcController::new`] starts the first). Under the plan the ratio k starts again at
    /// [`PLAN_START`] and the next first contact is judged afresh: the next job's plan and
    /// material are not this one's, and a k of 1 learnt on a plan that was right would meet the
    /// next job's first entry unprotected. In a hold, the resume then starts from there. The other
    /// laws keep what they have learnt (their feed follows the load within a period or two). AC
    /// task (and the host).
    pub fn new_job(&mut self) {
        if self.s.ceiling != FeedCeiling::Plan {
            return;
        }
        self.f = plan_start(&self.s);
        self.plan_history = [self.f; PLAN_HISTORY];
        self.plan_learnt = false;
        self.plan_loaded = 0;
        self.plan_loads = [0.0; PLAN_HISTORY];
    }

    /// Under the plan: the next feed number k x f_max (see [`PLAN_START`]), and the periods'
    /// history it is judged by.
    fn plan_next(&mut self, out_of_band: bool) {
        let tol = plan_tolerance(&self.s);
        let w = self.drr.window_peak();
        let latest = 1.0 - ecr::errors(w.f_n, w.t_nm, self.f0_n, self.t0_nm).e;
        let held = 1.0 - self.e;
        let hist = self.plan_history.iter().copied();
        let (hi, lo) = (
            hist.clone().max().unwrap_or(self.f),
            hist.min().unwrap_or(self.f),
        );
        // The plan's error as the held peak shows it: its load per unit of k (the smallest k of
        // the periods that can have cut its chip).
        let error = held * self.s.f_max as f32 / lo.max(1) as f32;
        // `as` saturates (and maps NaN to 0, clamped below).
        let toward = |k: u32, load: f32, to: f32| (k as f32 * to / load) as u32;
        let raise_floor = if self.plan_learnt {
            1.0 / (1.0 + tol)
        } else {
            PLAN_START / (1.0 + tol)
        };
        let f = if latest > 1.0 + tol {
            self.plan_learnt = true;
            self.f.min(toward(hi, latest, 1.0 + 0.5 * tol))
        } else if !self.plan_learnt && held >= raise_floor && {
            // The first contact: judged once the held peak has seen only loaded windows (the
            // entry's rising edge, where the tooth is not yet full, says nothing).
            self.plan_loaded = self.plan_loaded.saturating_add(1);
            self.plan_loaded > self.s.peak_windows
        } {
            // The plan's error measured, both ways.
            self.plan_learnt = true;
            if held >= 1.0 {
                self.f.min(toward(hi, held, 1.0))
            } else {
                self.f.max(toward(lo, held, 1.0))
            }
        } else if !self.plan_learnt {
            if held < raise_floor {
                self.plan_loaded = 0;
            }
            self.f
        } else if out_of_band
            || held >= 1.0
            || held < raise_floor
            || error < PLAN_STEADY * self.plan_loads.iter().copied().fold(0.0, f32::max)
        {
            self.f
        } else {
            self.f
                .max(toward(lo, held, 1.0))
                .min(self.f.saturating_add(self.step as u32))
        };
        self.f = f.clamp(self.s.f_min, self.s.f_max);
        self.plan_history.rotate_right(1);
        self.plan_history[0] = self.f;
        self.plan_loads.rotate_right(1);
        self.plan_loads[0] = error;
    }
}
