//! Machine settings (units, frame rate, feed DDA, rapid, pulse timing, soft limits, acceleration)
//! and their validation. Read by the host tool, the G-code parser (task) and, once validated, by the
//! frame (ISR) through [`crate::nc::FrameConfig`]; listed and set through
//! [`crate::protocol::settings`].

/// The basic length unit: one pulse moves one BLU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Blu {
    /// 0.0001 inch, the paper's BLU.
    TenthMil,
    /// 0.001 mm (metric option).
    Micron,
}

impl Blu {
    /// BLU per inch as a rational number (numerator, denominator).
    pub const fn per_inch(self) -> (i64, i64) {
        match self {
            Blu::TenthMil => (10_000, 1),
            Blu::Micron => (25_400, 1),
        }
    }
    /// BLU per millimetre as a rational number (numerator, denominator).
    pub const fn per_mm(self) -> (i64, i64) {
        match self {
            Blu::TenthMil => (100_000, 254),
            Blu::Micron => (1_000, 1),
        }
    }
    /// Length of one BLU in nanometres (for reports).
    pub const fn nm(self) -> u32 {
        match self {
            Blu::TenthMil => 2540,
            Blu::Micron => 1000,
        }
    }
}

/// All settings. `Settings::default()` gives the paper's machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Settings {
    /// Basic length unit.
    pub blu: Blu,
    /// W0: frame interrupt rate in Hz during contouring (feed DDA ticks). Paper: 5000.
    pub frame_hz: u32,
    /// q0: capacity of the feed DDA. Feed number f = q0 * FR / FRM, FRM = W0 * BLU * 60.
    /// Paper: 3000, so f = 100 * FR in ipm at W0 = 5 kHz and BLU = 0.0001 in.
    pub q0: u32,
    /// Rapid (PTP) pulse rate per axis in pulses per second. Paper: 158 ipm = 26_333 BLU/s.
    pub rapid_hz: u32,
    /// PTP deceleration (and acceleration) thresholds in BLU, largest first: with fewer than
    /// `ptp_steps[k]` pulses left (or done) an axis pulses every 2^(k+1)-th rapid frame.
    pub ptp_steps: [u32; 3],
    /// Time constant of the exponential deceleration of flagged feed blocks, in microseconds.
    pub decel_tau_us: u32,
    /// Step pulse width in ns (minimum high time of a PULSE line).
    pub pulse_width_ns: u32,
    /// Sign setup time in ns (minimum time from a SIGN change to the next rising PULSE edge).
    pub sign_setup_ns: u32,
    /// Soft limits, machine coordinates in BLU, per axis X, Y, Z (inclusive).
    pub soft_min: [i32; 3],
    pub soft_max: [i32; 3],
    /// Acceleration limit per axis X, Y, Z in BLU/s^2, for the acceleration ramps (grbl's
    /// `$120`..`$122`, listed in mm/s^2). Default 250 000 BLU/s^2 = 25 in/s^2 = 635 mm/s^2
    /// (0.065 g, a servo-driven knee mill's feed drive): at 10 in/s^2 the ramps' lag made the
    /// paper's FRC (with the firmware's 3-window held peak) cycle at the Fig. 1 cavity's first
    /// full-slot entry (README, "Acceleration and the AC").
    pub accel_blu_s2: [u32; 3],
}

/// Range of [`Settings::accel_blu_s2`] in BLU/s^2 (0.0254 to 25 400 mm/s^2 at 0.0001 in).
pub const ACCEL_RANGE: core::ops::RangeInclusive<u32> = 100..=100_000_000;

impl Default for Settings {
    fn default() -> Self {
        Settings {
            blu: Blu::TenthMil,
            frame_hz: 5000,
            q0: 3000,
            rapid_hz: 26_333,
            ptp_steps: [400, 100, 25],
            decel_tau_us: 20_000,
            pulse_width_ns: 5_000,
            sign_setup_ns: 5_000,
            soft_min: [-100_000, -100_000, -40_000],
            soft_max: [100_000, 100_000, 40_000],
            accel_blu_s2: [250_000; 3],
        }
    }
}

/// Why a set of settings was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SettingsError {
    FrameRate,
    Q0,
    RapidRate,
    PtpSteps,
    DecelTau,
    PulseTiming,
    SoftLimits,
    Acceleration,
}

impl SettingsError {
    pub const fn message(self) -> &'static str {
        match self {
            SettingsError::FrameRate => "frame rate must be 100..=100000 Hz",
            SettingsError::Q0 => "q0 must be 1..=1000000",
            SettingsError::RapidRate => "rapid rate must be at least the frame rate and at most 200000 Hz",
            SettingsError::PtpSteps => "PTP deceleration thresholds must be decreasing and non-zero",
            SettingsError::DecelTau => "deceleration time constant must be 1 ms..=10 s",
            SettingsError::PulseTiming => {
                "pulse width + sign setup must leave at least 25% of the rapid frame period for the frame"
            }
            SettingsError::SoftLimits => "soft limits must satisfy min <= 0 <= max on every axis",
            SettingsError::Acceleration => "acceleration must be 100..=100000000 BLU/s^2 on every axis",
        }
    }
}

impl Settings {
    /// Checks every setting; the frame relies on these bounds and does no checks of its own.
    pub fn validate(&self) -> Result<(), SettingsError> {
        if !(100..=100_000).contains(&self.frame_hz) {
            return Err(SettingsError::FrameRate);
        }
        if !(1..=1_000_000).contains(&self.q0) {
            return Err(SettingsError::Q0);
        }
        if self.rapid_hz < self.frame_hz || self.rapid_hz > 200_000 {
            return Err(SettingsError::RapidRate);
        }
        let [a, b, c] = self.ptp_steps;
        if !(a > b && b > c && c > 0) {
            return Err(SettingsError::PtpSteps);
        }
        if !(1_000..=10_000_000).contains(&self.decel_tau_us) {
            return Err(SettingsError::DecelTau);
        }
        // The pulse must end and the sign must settle inside the shortest frame, with a quarter of
        // the frame left for the frame's own work.
        let period_ns = 1_000_000_000u64 / self.rapid_hz as u64;
        let need = self.pulse_width_ns as u64 + self.sign_setup_ns as u64;
        if self.pulse_width_ns == 0 || need * 4 > period_ns * 3 {
            return Err(SettingsError::PulseTiming);
        }
        for k in 0..3 {
            if self.soft_min[k] > 0 || self.soft_max[k] < 0 {
                return Err(SettingsError::SoftLimits);
            }
        }
        if !self.accel_blu_s2.iter().all(|a| ACCEL_RANGE.contains(a)) {
            return Err(SettingsError::Acceleration);
        }
        Ok(())
    }

    /// FRM, the highest contouring feed, in BLU per minute (= W0 * 60).
    pub const fn max_feed_blu_per_min(&self) -> u64 {
        self.frame_hz as u64 * 60
    }

    /// Deceleration gain K of the frame: a flagged block runs at f_eff = K * remaining / 256,
    /// which decays exponentially with time constant `decel_tau_us`:
    /// ds/dt = -W0 f/q0 = -W0 K s/(256 q0)  =>  tau = 256 q0 / (W0 K).
    pub const fn decel_gain_q8(&self) -> u32 {
        let k = (256u64 * self.q0 as u64 * 1_000_000)
            / (self.frame_hz as u64 * self.decel_tau_us as u64);
        if k == 0 {
            1
        } else if k > u16::MAX as u64 {
            u16::MAX as u32
        } else {
            k as u32
        }
    }
}
