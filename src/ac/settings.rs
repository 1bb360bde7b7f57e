//! Settings of the adaptive controller (ADC calibration, window pick, permissible limits and the
//! optimal fraction, FRC limits, overload and sensor-fault thresholds) and their validation. Read by
//! the host tool and, once validated ([`AcSettings::validated`]), by the AC task; the process
//! monitors' settings derived from valid AC settings ([`Valid::breakage_settings`],
//! [`Valid::chatter_settings`]).
//!
//! Units: forces in N, torques in N*m, feeds in *feed numbers* (the frame's `f`; at the paper's
//! defaults W0 = 5 kHz, q0 = 3000, BLU = 0.0001 in, one feed number is 0.01 ipm, f = 100 x FR).

use crate::gcode::tools::ToolKind;
use crate::monitor::chatter::ChatterSettings;
use crate::monitor::BreakageSettings;
use crate::settings::Valid;

/// Calibration of one ADC channel: `value = gain * (code - offset)`.
///
/// `offset` is the code read at zero load (mid-scale 2048 for the bipolar amplifiers of the
/// defaults, so that both rails 0 and 4095 are far from any normal reading), `gain` the
/// engineering units per code (N/code or N*m/code; negative for an inverted sensor).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    pub gain: f32,
    pub offset: f32,
}

impl Calibration {
    /// Engineering value of a code. Finite for every code once the settings are validated.
    #[inline]
    pub fn value(&self, code: u16) -> f32 {
        self.gain * (code as f32 - self.offset)
    }
}

/// Which sample of a window the ECR sees.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pick {
    /// The largest F (F = sqrt(Fu^2 + Fv^2) per sample) and the largest |T| in the window: the
    /// cutter breaks at the peak, not at the last sample. Default.
    Peak,
    /// The latest sample of the window, as the paper's DRR (which overwrote its memory cells).
    Latest,
}

/// What `$268` does with the breakage monitor.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u8)]
pub enum Breakage {
    /// Off for every tool (`$268=0`).
    Off,
    /// On for every tool, the machine's own (`$267`, `$269`) before any M6 too (`$268=1`).
    On,
    /// On for each tool an M6 fits whose flutes the tool table gives (`N`), at the spindle
    /// speed commanded; off for the machine's tool before any M6 (`$268=2`, the default: a
    /// user who never heard of the setting has breakage detection on every tool the table
    /// describes). A ball end mill's detector runs without the curvature confirmation
    /// ([`BreakageSettings::curvature`]).
    #[default]
    Auto,
}

impl Breakage {
    /// Its `$268` value.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The mode of a `$268` value, None for a value that names none.
    pub fn from_code(code: u8) -> Option<Breakage> {
        [Breakage::Off, Breakage::On, Breakage::Auto]
            .get(usize::from(code))
            .copied()
    }
}

/// All settings of the AC program. `AcSettings::default()` gives the paper's numbers where the
/// paper has them (10 ms period, fdot_m = 750 ipm/s, F0/T0 = 90 % of the permissible limits,
/// feeds up to FRM = 30 ipm) and plausible values for the rest (calibration, limits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AcSettings {
    /// Rate at which `sample` is called, in Hz. Default 1000.
    pub sample_hz: u32,
    /// AC period (the paper's dt) in ms: `period` is called this often. Default 10.
    pub period_ms: u32,
    /// Calibration of the channels in the order of the codes: [T, Fu, Fv].
    pub cal: [Calibration; 3],
    /// Which sample of a window the ECR uses. Default [`Pick::Peak`].
    pub pick: Pick,
    /// Permissible cutting force in N (tool strength). F0 = `optimal_fraction` x this.
    pub force_limit_n: f32,
    /// Permissible spindle torque in N*m (drive). T0 = `optimal_fraction` x this.
    pub torque_limit_nm: f32,
    /// F0 / force limit and T0 / torque limit. Paper: "around 90 percent". Default 0.9.
    pub optimal_fraction: f32,
    /// fdot_m, the largest feed acceleration, in feed numbers per second.
    /// Paper: 750 ipm/s = 75_000 at the default feed number scale.
    pub fdot_m: u32,
    /// Lowest feed the FRC commands (and the feed after `resume`), feed number. Default 100 = 1 ipm.
    pub f_min: u32,
    /// Highest feed the FRC commands, feed number. Default 3000 = 30 ipm = FRM.
    /// May exceed the programmed feed: the frame takes min(programmed, cap).
    pub f_max: u32,
    /// Overload limit on the critical error: E below it holds the feed at once (feed cap 0).
    /// The paper assumes E > -0.1; default -0.1, i.e. F > 1.1 F0 = 99 % of the permissible force.
    pub overload_e: f32,
    /// A code at a rail (0 or 4095) this many consecutive samples is a stuck sensor. 0 = off.
    /// Default 20 (20 ms at 1 kHz).
    pub stuck_samples: u32,
    /// A change of a code by more than this between consecutive samples is a *jump*, judged before
    /// the sample may enter the window (see [`super::drr`]): a jump the other channels contradict
    /// (force against torque, see `ft_ratio_min`) or that returns at the next sample is a sensor
    /// fault; a jump that is consistent and persists is load. A code arriving at a rail is judged
    /// the same way. 4095 = off (both). Default 1500.
    pub jump_codes: u16,
    /// A channel whose code stays within this many codes of where it started, for `frozen_samples`
    /// samples while the axes feed, is frozen (a dead amplifier, a hung ADC channel): a live
    /// transducer always moves (noise, tooth pulsation, the rotating holder). 0..=100 and below
    /// `jump_codes`. Default 1 (the simulated transducer's noise is 2 codes sigma; set it above the
    /// real channel's quantisation and below its noise in a cut).
    pub frozen_codes: u16,
    /// Samples a channel must stay within `frozen_codes` while the axes feed (the achieved feed of
    /// [`super::AcController::set_achieved`] above zero) to be frozen. 0 = off. Default 50 (50 ms:
    /// half a spindle turn at 600 rpm).
    pub frozen_samples: u32,
    /// Cutter radius R in mm, for the force/torque plausibility F*R/T. Default 6.35 (the 0.5 in
    /// end mill of the demo).
    pub tool_radius_mm: f32,
    /// Band of F*R/T that a cut can produce. One tooth cutting gives sqrt(1 + Kr^2) (1.04 at
    /// Kr = 0.3); several teeth partly cancel in the resultant F but not in T: a full slot with a
    /// 4-flute cutter gives 0.74..1.04, many teeth tend to pi/4 sqrt(1 + Kr^2) = 0.82. Defaults
    /// 0.6 and 1.4: a margin of about 20 % on the model's honest range, while a gain fault that
    /// halves Fu, Fv (0.37..0.52) or T (1.5..2.1) falls outside. Widen it for other cutters.
    pub ft_ratio_min: f32,
    /// Upper end of the F*R/T band (see `ft_ratio_min`). Default 1.4.
    pub ft_ratio_max: f32,
    /// F*R/T is judged only when T or F*R is at least this (N*m), well above the noise (the
    /// default transducer's noise is 0.1 N*m on T, 0.03 N*m on F*R). Default 5 N*m (7 % of T0).
    pub ft_floor_nm: f32,
    /// AC windows whose peaks give F*R/T outside the band (above the floor) that hold the feed
    /// with [`super::Alarm::ForceTorqueMismatch`]: a gain fault (a loose or miscalibrated
    /// transducer). A window in the band restarts the count, one below the floor (air, a tooth
    /// gap) leaves it. In a window out of the band the FRC does not raise the feed. 0 = off (the
    /// band still judges jumps). Default 5 (50 ms).
    pub ft_periods: u32,
    /// With `Pick::Peak`, the peak is held over this many AC windows (the current one and the
    /// ones before it), 1..=8. Beyond the paper: a window must span a tooth period, or the peak
    /// misses the tooth and the FRC raises the feed on a false low reading. At 600 rpm a 4-flute
    /// cutter has a 25 ms tooth period, longer than the 10 ms window. Choose
    /// windows >= 60000 / (rpm x flutes x period_ms); default 3 (30 ms).
    pub peak_windows: u32,
    /// What the frame's feed ceiling is while the AC runs: the programmed feed (default, the
    /// frame takes min(programmed, cap)), FRM, so the AC alone sets the feed up to `f_max`, or
    /// the plan: the programmed feeds times the controller's correction k <= 1.
    pub ceiling: FeedCeiling,
    /// The feed law (`$251`, see `super::law`): GPC by default, the fastest law of the AC
    /// benchmark that finished every program without a hold with both feed drives (docs/dev/results-ac.md, "AC
    /// benchmark"); the paper's FRC is `$251=0`.
    pub strategy: super::law::Strategy,
    /// The nominal feed of the integral and MRAC laws (`$264`), feed number: the feed at which
    /// the nominal cut reaches F0 (their gain and initial estimate come from it). Default 1500 =
    /// 15 ipm, in [f_min, f_max].
    pub nominal_feed: u32,
    /// The GPC law's control weight lambda (`$265`, on the normalised feed): larger is gentler.
    /// Default 10 (the AC benchmark with the stepper and the servo drive: no hold on any program,
    /// where 5 held on the pocket's entry behind the servo and 15 was slower); 0..=1e6.
    pub gpc_lambda: f32,
    /// Process monitoring (issue 10, `crate::monitor`). The tool's flutes (`$267`, 1..=8): the
    /// tooth period the breakage detector averages over and the tooth harmonics the chatter
    /// detector leaves out. Default 4.
    pub flutes: u32,
    /// The spindle speed the monitors assume until the program commands one (`$269`, rpm,
    /// 1..=100000). Default 600 (the paper's).
    pub monitor_rpm: u32,
    /// The chatter threshold (`$266`): the sound spectrum's largest amplitude away from the
    /// tooth harmonics above which a record is chatter, in sound codes about mid-scale, set from
    /// a chatter-free cut (the thesis' rule: twice its largest amplitude); 0 (the default):
    /// against the forced vibration, no calibration (`crate::monitor::chatter::AUTO_RATIO`).
    pub chatter_threshold: f32,
    /// Chatter detection (`$278`): on (the default) wherever the board has a sound channel and
    /// sound arrives; off.
    pub chatter: bool,
    /// Tool breakage detection (`$268`, `crate::monitor::breakage` with its defaults): off, on
    /// for every tool, or on for each tool an M6 fits whose flutes the tool table gives (the
    /// default; [`Breakage`]).
    pub breakage: Breakage,
    /// Chatter suppression (`$276`, mm, 0..=50): the depth step a chatter hold lifts the rest of
    /// the held pass by, the material below cut in an extra pass (`crate::rt::replan`, the
    /// thesis' reaction); 0 leaves a chatter hold a hold (`ALARM:107`). Default 1.0 mm, the
    /// thesis' step (Munasinghe 1994, section 5.3.2).
    pub chatter_step_mm: f32,
    /// Chatter suppression by spindle speed (`$277`, rpm, 0..=100 000): the top speed a chatter
    /// hold may change the spindle to, the nearest stable lobe's (`crate::monitor::chatter::lobe_rpm`,
    /// `crate::rt::replan`), before the depth steps of `$276`; 0 (the default) leaves the speed
    /// alone.
    pub chatter_max_rpm: u32,
}

/// The feed ceiling under adaptive control (see [`AcSettings::ceiling`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FeedCeiling {
    /// The programmed F word stays the ceiling.
    Programmed,
    /// Feed blocks are queued at FRM (f = q0): the controller's cap is the feed. Only applied
    /// while the AC is enabled; without AC the programmed feeds run.
    Frm,
    /// Prediction and feedback together (issue 11): the programmed feeds are a plan (an
    /// optimised program, `millac optimise`) and run as feed-forward; the controller corrects
    /// them by one ratio k <= 1 that the frame multiplies every block's feed by
    /// ([`crate::ports::FeedCap::planned`]), learnt where the measured load shows the plan's
    /// error and carried across blocks (see `super::AcController` and [`super::PLAN_START`]).
    Plan,
}

/// Most AC windows a peak can be held over.
pub const PEAK_WINDOWS_MAX: usize = 8;

impl Default for AcSettings {
    fn default() -> Self {
        AcSettings {
            sample_hz: 1000,
            period_ms: 10,
            cal: [
                // T: +-102.4 N*m full scale.
                Calibration {
                    gain: 0.05,
                    offset: 2048.0,
                },
                // Fu, Fv: +-5120 N full scale.
                Calibration {
                    gain: 2.5,
                    offset: 2048.0,
                },
                Calibration {
                    gain: 2.5,
                    offset: 2048.0,
                },
            ],
            pick: Pick::Peak,
            force_limit_n: 4000.0,
            torque_limit_nm: 80.0,
            optimal_fraction: 0.9,
            fdot_m: 75_000,
            f_min: 100,
            f_max: 3000,
            overload_e: -0.1,
            stuck_samples: 20,
            jump_codes: 1500,
            frozen_codes: 1,
            frozen_samples: 50,
            tool_radius_mm: 6.35,
            ft_ratio_min: 0.6,
            ft_ratio_max: 1.4,
            ft_floor_nm: 5.0,
            ft_periods: 5,
            peak_windows: 3,
            ceiling: FeedCeiling::Programmed,
            strategy: super::law::Strategy::Gpc,
            nominal_feed: 1500,
            gpc_lambda: 10.0,
            flutes: 4,
            monitor_rpm: 600,
            chatter_threshold: 0.0,
            chatter: true,
            breakage: Breakage::default(),
            chatter_step_mm: 1.0,
            chatter_max_rpm: 0,
        }
    }
}

/// Why a set of AC settings was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AcSettingsError {
    SampleRate,
    Period,
    SamplesPerPeriod,
    Calibration,
    Limits,
    OptimalFraction,
    FdotM,
    FeedRange,
    OverloadLimit,
    StuckSamples,
    JumpCodes,
    PeakWindows,
    FrozenCodes,
    FrozenSamples,
    ToolRadius,
    ForceTorqueBand,
    ForceTorqueFloor,
    ForceTorquePeriods,
    NominalFeed,
    GpcLambda,
    /// The monitors' flutes (1..=8), spindle speed (1..=100000 rpm), chatter threshold
    /// (finite, >= 0) or chatter step (0..=50 mm).
    Monitor,
}

impl AcSettingsError {
    pub const fn message(self) -> &'static str {
        match self {
            AcSettingsError::SampleRate => "AC sample rate must be 100..=100000 Hz",
            AcSettingsError::Period => "AC period must be 1..=1000 ms",
            AcSettingsError::SamplesPerPeriod => "at least one sample must arrive per AC period",
            AcSettingsError::Calibration => {
                "calibration gains must be finite, non-zero and |gain| <= 1e4; offsets 0..=4095"
            }
            AcSettingsError::Limits => "force and torque limits must be finite, > 0 and <= 1e7",
            AcSettingsError::OptimalFraction => "optimal fraction (F0/Fmax, T0/Tmax) must be in (0, 1]",
            AcSettingsError::FdotM => {
                "fdot_m must be 1..=10000000 feed numbers/s and give at least one feed number per period"
            }
            AcSettingsError::FeedRange => "feed limits must satisfy 1 <= f_min <= f_max <= 1000000",
            AcSettingsError::OverloadLimit => "overload limit on E must be in [-1, 0)",
            AcSettingsError::StuckSamples => "stuck-sensor count must be 0 (off) ..=1000000 samples",
            AcSettingsError::JumpCodes => "plausible jump must be 1..=4095 codes",
            AcSettingsError::PeakWindows => "the peak must be held over 1..=8 AC windows",
            AcSettingsError::FrozenCodes => {
                "frozen-sensor band must be 0..=100 codes and below the plausible jump"
            }
            AcSettingsError::FrozenSamples => {
                "frozen-sensor count must be 0 (off) ..=1000000 samples"
            }
            AcSettingsError::ToolRadius => "tool radius must be finite and in (0, 1000] mm",
            AcSettingsError::ForceTorqueBand => {
                "F*R/T band must be finite with 0 < ft_ratio_min < ft_ratio_max <= 100"
            }
            AcSettingsError::NominalFeed => "the nominal feed must be within [f_min, f_max]",
            AcSettingsError::GpcLambda => "the GPC weight lambda must be 0..=1e6",
            AcSettingsError::Monitor => {
                "monitors: flutes 1..=8, spindle speed 1..=100000 rpm, chatter threshold >= 0, \
                 chatter step 0..=50 mm"
            }
            AcSettingsError::ForceTorquePeriods => {
                "force/torque mismatch count must be 0 (off) ..=100000 AC periods"
            }
            AcSettingsError::ForceTorqueFloor => {
                "F*R/T torque floor must be finite and in (0, 1e7] N*m"
            }
        }
    }
}

impl core::fmt::Display for AcSettingsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.message())
    }
}

impl AcSettings {
    /// [`AcSettings::validate`], and the settings as a [`Valid`] when they pass: what the
    /// controller ([`super::AcController::new`]) and the monitors' derivations take.
    pub fn validated(self) -> Result<Valid<AcSettings>, AcSettingsError> {
        self.validate()?;
        Ok(Valid::checked(self))
    }

    /// Checks every setting. After this, every computation of the controller is finite (no NaN,
    /// no infinity, no division by zero) for every input code, so the AC task does no checks of
    /// its own.
    pub fn validate(&self) -> Result<(), AcSettingsError> {
        if !(100..=100_000).contains(&self.sample_hz) {
            return Err(AcSettingsError::SampleRate);
        }
        if !(1..=1000).contains(&self.period_ms) {
            return Err(AcSettingsError::Period);
        }
        if (self.sample_hz as u64) * (self.period_ms as u64) < 1000 {
            return Err(AcSettingsError::SamplesPerPeriod);
        }
        for c in &self.cal {
            let g_ok = c.gain.is_finite() && c.gain != 0.0 && c.gain.abs() <= 1e4;
            let o_ok = c.offset.is_finite() && (0.0..=4095.0).contains(&c.offset);
            if !(g_ok && o_ok) {
                return Err(AcSettingsError::Calibration);
            }
        }
        for l in [self.force_limit_n, self.torque_limit_nm] {
            if !(l.is_finite() && l > 0.0 && l <= 1e7) {
                return Err(AcSettingsError::Limits);
            }
        }
        let r = self.optimal_fraction;
        if !(r.is_finite() && r > 0.0 && r <= 1.0) {
            return Err(AcSettingsError::OptimalFraction);
        }
        if !(1..=10_000_000).contains(&self.fdot_m)
            || (self.fdot_m as u64) * (self.period_ms as u64) < 1000
        {
            return Err(AcSettingsError::FdotM);
        }
        if !(1 <= self.f_min && self.f_min <= self.f_max && self.f_max <= 1_000_000) {
            return Err(AcSettingsError::FeedRange);
        }
        if !(self.f_min..=self.f_max).contains(&self.nominal_feed) {
            return Err(AcSettingsError::NominalFeed);
        }
        if !(0.0..=1.0e6).contains(&self.gpc_lambda) {
            return Err(AcSettingsError::GpcLambda);
        }
        let monitors_ok = (1..=crate::monitor::MAX_FLUTES as u32).contains(&self.flutes)
            && (1..=100_000).contains(&self.monitor_rpm)
            && self.chatter_threshold.is_finite()
            && self.chatter_threshold >= 0.0
            && (0.0..=50.0).contains(&self.chatter_step_mm)
            && self.chatter_max_rpm <= 100_000;
        if !monitors_ok {
            return Err(AcSettingsError::Monitor);
        }
        let o = self.overload_e;
        if !(o.is_finite() && (-1.0..0.0).contains(&o)) {
            return Err(AcSettingsError::OverloadLimit);
        }
        if self.stuck_samples > 1_000_000 {
            return Err(AcSettingsError::StuckSamples);
        }
        if !(1..=4095).contains(&self.jump_codes) {
            return Err(AcSettingsError::JumpCodes);
        }
        if !(1..=PEAK_WINDOWS_MAX as u32).contains(&self.peak_windows) {
            return Err(AcSettingsError::PeakWindows);
        }
        if self.frozen_codes > 100 || self.frozen_codes >= self.jump_codes {
            return Err(AcSettingsError::FrozenCodes);
        }
        if self.frozen_samples > 1_000_000 {
            return Err(AcSettingsError::FrozenSamples);
        }
        let r = self.tool_radius_mm;
        if !(r.is_finite() && r > 0.0 && r <= 1000.0) {
            return Err(AcSettingsError::ToolRadius);
        }
        let (lo, hi) = (self.ft_ratio_min, self.ft_ratio_max);
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo < hi && hi <= 100.0) {
            return Err(AcSettingsError::ForceTorqueBand);
        }
        let fl = self.ft_floor_nm;
        if !(fl.is_finite() && fl > 0.0 && fl <= 1e7) {
            return Err(AcSettingsError::ForceTorqueFloor);
        }
        if self.ft_periods > 100_000 {
            return Err(AcSettingsError::ForceTorquePeriods);
        }
        Ok(())
    }

    /// F0, the optimal force in N.
    pub fn f0_n(&self) -> f32 {
        self.optimal_fraction * self.force_limit_n
    }

    /// T0, the optimal torque in N*m.
    pub fn t0_nm(&self) -> f32 {
        self.optimal_fraction * self.torque_limit_nm
    }

    /// Samples per AC period, sample_hz x period_ms / 1000 (at least 1; validation asks for 1):
    /// period k holds samples k N .. (k + 1) N, in the firmware, the host simulation and the
    /// replay of a co-simulation.
    pub fn samples_per_period(&self) -> u32 {
        (self.sample_hz.saturating_mul(self.period_ms) / 1000).max(1)
    }

    /// fdot_m x dt: the largest feed change of one AC period, in feed numbers (750 at defaults).
    /// The product is formed in u64 and converted once, so host and target get the same f32.
    pub fn step_per_period(&self) -> f32 {
        ((self.fdot_m as u64 * self.period_ms as u64) as f32) / 1000.0
    }
}

impl Valid<AcSettings> {
    /// The breakage monitor's settings when `$268` turns it on: the detector's defaults at the
    /// AC's sample rate. No second check: [`AcSettings::validate`] bounds the sample rate to the
    /// breakage detector's own range (100..=100 000 Hz), and the rest are the detector's defaults.
    pub fn breakage_settings(&self) -> Option<Valid<BreakageSettings>> {
        (self.breakage == Breakage::On).then(|| self.breakage_detector())
    }

    /// The breakage monitor's settings for a tool an M6 fitted with `flutes` (0: the table does
    /// not say) of `kind`: on with `$268` = 1, and with 2 (auto) where the flutes are known;
    /// for a ball end mill without the curvature confirmation
    /// ([`BreakageSettings::curvature`]).
    pub fn breakage_settings_for(
        &self,
        flutes: u8,
        kind: ToolKind,
    ) -> Option<Valid<BreakageSettings>> {
        let on = match self.breakage {
            Breakage::Off => false,
            Breakage::On => true,
            Breakage::Auto => flutes > 0,
        };
        on.then(|| {
            Valid::checked(BreakageSettings {
                curvature: kind != ToolKind::Ball,
                ..self.breakage_detector().get()
            })
        })
    }

    /// The breakage detector's settings: its defaults at the AC's sample rate.
    fn breakage_detector(&self) -> Valid<BreakageSettings> {
        {
            Valid::checked(BreakageSettings {
                sample_hz: self.sample_hz,
                ..BreakageSettings::default()
            })
        }
    }

    /// The chatter monitor's settings when `$278` turns it on: the detector's defaults with the
    /// threshold `$266` (0: the automatic rule). No second check: [`AcSettings::validate`] keeps
    /// the threshold finite and at least 0, and the rest are the detector's defaults.
    pub fn chatter_settings(&self) -> Option<Valid<ChatterSettings>> {
        self.chatter.then(|| {
            Valid::checked(ChatterSettings {
                threshold: self.chatter_threshold,
                ..ChatterSettings::default()
            })
        })
    }
}

#[cfg(test)]
mod derived_tests {
    use super::*;

    fn valid(s: AcSettings) -> Valid<AcSettings> {
        s.validated()
            .unwrap_or_else(|e| panic!("{}: {s:?}", e.message()))
    }

    /// The breakage settings derived from valid AC settings pass the detector's own validation
    /// at both ends of the AC's sample rate range (what makes the derivation's missing check
    /// honest), and exist only with `$268` on.
    #[test]
    fn breakage_settings_from_valid_ac_settings_pass_their_own_checks() {
        assert_eq!(valid(AcSettings::default()).breakage_settings(), None);
        for sample_hz in [100_000, 100, 1000] {
            let ac = valid(AcSettings {
                sample_hz,
                period_ms: 1000,
                fdot_m: 1000,
                breakage: Breakage::On,
                ..AcSettings::default()
            });
            let b = ac.breakage_settings().expect("$268 on");
            assert_eq!(b.validate(), Ok(()), "{b:?}");
            assert_eq!(b.sample_hz, sample_hz);
            assert_eq!(b.get().validated(), Ok(b));
        }
        // Just outside the range the AC settings are refused, so no derivation sees them.
        for sample_hz in [99, 100_001] {
            let ac = AcSettings {
                sample_hz,
                period_ms: 1000,
                fdot_m: 1000,
                breakage: Breakage::On,
                ..AcSettings::default()
            };
            assert!(ac.validated().is_err(), "{sample_hz}");
        }
    }

    /// By default (`$268=2`) every tool an M6 fits whose flutes the table gives has a breakage
    /// monitor, a ball end mill's without the curvature confirmation; a tool whose flutes
    /// nobody gave has none, nor has the machine's own before any M6; `$268=0` turns it off for
    /// all and `$268=1` on for all.
    #[test]
    fn the_breakage_monitor_follows_the_tool_by_default() {
        let d = valid(AcSettings::default());
        assert_eq!(d.breakage, Breakage::Auto);
        assert_eq!(d.breakage_settings(), None);
        assert_eq!(d.breakage_settings_for(0, ToolKind::Flat), None);
        let flat = d
            .breakage_settings_for(3, ToolKind::Flat)
            .expect("flutes known");
        assert!(flat.curvature);
        let ball = d
            .breakage_settings_for(2, ToolKind::Ball)
            .expect("flutes known");
        assert!(!ball.curvature);
        assert_eq!(
            ball.get(),
            BreakageSettings {
                curvature: false,
                ..flat.get()
            }
        );
        let off = valid(AcSettings {
            breakage: Breakage::Off,
            ..AcSettings::default()
        });
        assert_eq!(off.breakage_settings_for(4, ToolKind::Flat), None);
        let on = valid(AcSettings {
            breakage: Breakage::On,
            ..AcSettings::default()
        });
        assert!(on.breakage_settings().is_some());
        assert!(on.breakage_settings_for(0, ToolKind::Drill).is_some());
    }

    /// The chatter settings derived from valid AC settings pass the detector's own validation at
    /// the edges of the thresholds the AC settings accept (the smallest positive f32, the largest
    /// finite one, and 0, the automatic rule), and exist only with `$278` on.
    #[test]
    fn chatter_settings_from_valid_ac_settings_pass_their_own_checks() {
        let off = AcSettings {
            chatter: false,
            ..AcSettings::default()
        };
        assert_eq!(valid(off).chatter_settings(), None);
        for threshold in [
            0.0,
            f32::MAX,
            f32::from_bits(1),
            f32::MIN_POSITIVE,
            1e-6,
            1.0,
            1e12,
        ] {
            let ac = valid(AcSettings {
                chatter_threshold: threshold,
                ..AcSettings::default()
            });
            let c = ac.chatter_settings().expect("on by default");
            assert_eq!(c.validate(), Ok(()), "{c:?}");
            assert_eq!(c.threshold, threshold);
            assert_eq!(c.get().validated(), Ok(c));
        }
        // Not finite or negative: the AC settings are refused, so no derivation sees them.
        for threshold in [f32::INFINITY, f32::NAN, -1.0] {
            let ac = AcSettings {
                chatter_threshold: threshold,
                ..AcSettings::default()
            };
            assert!(ac.validated().is_err(), "{threshold}");
        }
    }
}
