//! Machine settings (units, frame rate, feed DDA, rapid, pulse timing, soft limits, acceleration)
//! and their validation for a board's limits and measured ISR times ([`Settings::validate`] with a
//! [`BoardLimits`]; [`BoardLimits::GENERIC`] for the QEMU board and the host tools). Read by the host tool, the G-code parser
//! (task) and, once validated, by the frame (ISR) through [`crate::nc::FrameConfig`]; listed and
//! set through [`crate::protocol::table`].
//!
//! Settings that passed their checks are a type of their own, [`Valid`]: they are checked once,
//! where they are made (a stored record's decode, `$N=value`, a host tool's input), and whatever is
//! built from them (the frame's configuration, the adaptive controller, the process monitors) takes
//! a `Valid` and does not check again.

use core::ops::Deref;

/// Settings that passed their checks: a consumer that takes a `Valid<T>` does not check again.
///
/// Only this crate's validating functions make one: [`Settings::validated`] (for a board),
/// `AcSettings::validated`, `BreakageSettings::validated`, `ChatterSettings::validated`,
/// `MachineSettings::validated` (for a board), and the projections of a valid whole that need no
/// second check (`Valid<MachineSettings>::nc` and `::ac`, the monitors' settings derived from valid
/// AC settings). Read through [`Deref`] (`valid.frame_hz`); [`Valid::get`] gives the settings back
/// (to change a copy, which must be validated again to become a `Valid`).
///
/// ```
/// use millac::settings::{BoardLimits, Settings};
/// let s = Settings::default().validated(&BoardLimits::GENERIC).unwrap();
/// assert_eq!(s.frame_hz, 5000);
/// let slow = Settings { frame_hz: 10, ..s.get() };
/// assert!(slow.validated(&BoardLimits::GENERIC).is_err());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Valid<T>(T);

impl<T> Valid<T> {
    /// Wraps settings that the caller has just checked (or that a checked whole bounds): for the
    /// validating functions of this crate only.
    pub(crate) const fn checked(settings: T) -> Self {
        Valid(settings)
    }

    /// The settings themselves.
    pub fn get(self) -> T {
        self.0
    }
}

impl<T> Deref for Valid<T> {
    type Target = T;

    fn deref(&self) -> &T {
        &self.0
    }
}

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
    /// full-slot entry (docs/user/adaptive-control.md, "Choosing F0, T0 and the feed law").
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

/// Setting the machine up: the hard limits, homing, the probe and the tool change (grbl's `$6`,
/// `$21`-`$27`; grblHAL's `$341`-`$344`; millac's `$345`, `$346`). Lengths in micrometres and rates
/// in micrometres per minute (listed in mm and mm/min), so they do not depend on the BLU. Loader
/// task (`$H`, G38, M6), init and the host tools.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Setup {
    /// `$6`: the probe input is active low (inverted). Default false.
    pub probe_invert: bool,
    /// `$21`: a limit switch outside homing stops everything with `ALARM:1` and marks the
    /// position lost. Default true (a machine without switches never closes one).
    pub hard_limits: bool,
    /// `$22`: homing enabled; the machine starts locked (`ALARM:11`) until `$H`. Default false.
    pub homing: bool,
    /// `$23`: bit k set, axis k homes toward its negative end (its switch at the soft minimum);
    /// clear, toward its positive end (at the soft maximum). Default 0.
    pub homing_dir_mask: u8,
    /// `$24`: the locating feed, um/min. Default 25 mm/min.
    pub homing_feed_um_min: u32,
    /// `$25`: the seek rate, um/min. Default 500 mm/min.
    pub homing_seek_um_min: u32,
    /// `$26`: the pause after a switch stops an axis, ms. Default 250.
    pub homing_debounce_ms: u32,
    /// `$27`: the pull-off distance from the switch, um. Default 1 mm.
    pub homing_pulloff_um: u32,
    /// `$341`: at M6, 0 stop and wait for cycle start; 1 go to the G30 position, wait, and take
    /// the new tool's length from the table; 2 go to the G30 position, wait, and probe the new
    /// tool on the tool setter. Default 0.
    pub tool_change: u8,
    /// `$342`: the longest probing move of a tool-setter measurement, um. Default 30 mm.
    pub probe_distance_um: u32,
    /// `$343`: the tool setter's slow (measuring) feed, um/min. Default 25 mm/min.
    pub probe_slow_um_min: u32,
    /// `$344`: the tool setter's seek feed, um/min. Default 200 mm/min.
    pub probe_seek_um_min: u32,
    /// `$345`, `$346`: the tool setter's X and Y, machine coordinates, um. Default 0, 0.
    pub setter_um: [i32; 2],
}

impl Default for Setup {
    fn default() -> Self {
        Setup {
            probe_invert: false,
            hard_limits: true,
            homing: false,
            homing_dir_mask: 0,
            homing_feed_um_min: 25_000,
            homing_seek_um_min: 500_000,
            homing_debounce_ms: 250,
            homing_pulloff_um: 1_000,
            tool_change: 0,
            probe_distance_um: 30_000,
            probe_slow_um_min: 25_000,
            probe_seek_um_min: 200_000,
            setter_um: [0, 0],
        }
    }
}

/// Why [`Setup::validate`] refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SetupError {
    /// A homing or probing rate is 0 or above the rapid rate.
    Rate,
    /// The pull-off is 0 or beyond an axis's travel between its soft limits, or the probing
    /// distance is 0 or above 10 m.
    Distance,
    /// `$23` above 7, `$26` above 10 s, `$341` above 2.
    Choice,
}

impl SetupError {
    pub const fn message(self) -> &'static str {
        match self {
            SetupError::Rate => "homing and probing rates must be above 0 and at most the rapid rate",
            SetupError::Distance => {
                "the pull-off must be above 0 and within every axis's travel, the probing distance 1 um..10 m"
            }
            SetupError::Choice => "$23 must be 0..7, $26 at most 10000 ms, $341 0..2",
        }
    }
}

impl Setup {
    /// Checks the set-up against the NC settings (rates within the rapid rate, the pull-off within
    /// every axis's travel). Init, loader (`$n=`), host.
    pub fn validate(&self, nc: &Settings) -> Result<(), SetupError> {
        if self.homing_dir_mask > 7 || self.homing_debounce_ms > 10_000 || self.tool_change > 2 {
            return Err(SetupError::Choice);
        }
        let rapid = nc.rapid_um_min();
        let rates = [
            self.homing_feed_um_min,
            self.homing_seek_um_min,
            self.probe_slow_um_min,
            self.probe_seek_um_min,
        ];
        if rates.iter().any(|&r| r == 0 || u64::from(r) > rapid) {
            return Err(SetupError::Rate);
        }
        let travel_um = (0..3)
            .map(|k| {
                let blu = i64::from(nc.soft_max[k]) - i64::from(nc.soft_min[k]);
                blu * i64::from(nc.blu.nm()) / 1000
            })
            .min()
            .unwrap_or(0);
        if self.homing_pulloff_um == 0
            || i64::from(self.homing_pulloff_um) >= travel_um
            || !(1..=10_000_000).contains(&self.probe_distance_um)
        {
            return Err(SetupError::Distance);
        }
        Ok(())
    }
}

/// What a board can do, for [`Settings::validate`]: its rate caps and the worst-case times of
/// its frame and pulse-end ISRs (measured on the board, e.g. with the cycle counter, and stated as
/// constants in its firmware). Init context (a `const` per board).
///
/// With measured ISR times the timing rule of [`crate::rt::isr`] is checked with real numbers at
/// the rapid rate (the shortest frame period T):
/// - the SIGN-to-rising-edge gap, at least T - max(pulse width, frame work) - pulse end, must be
///   at least the sign setup time ([`SettingsError::SignSetup`]);
/// - the two ISRs together take at most [`ISR_SHARE_PCT`] % of the CPU:
///   (frame work + pulse end) * rapid_hz <= 0.5 s per second ([`SettingsError::IsrLoad`]), so the
///   sampler, the AC task and the loader keep the other half.
///
/// Without them (`frame_work_ns == 0`, as [`BoardLimits::GENERIC`]) the generic rule applies
/// instead: pulse width + sign setup <= 75 % of T, a quarter of T left for the frame's work.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoardLimits {
    /// Highest frame rate W0 (`frame_hz`) the board runs, Hz.
    pub max_frame_hz: u32,
    /// Highest rapid rate (`rapid_hz`) the board runs, Hz.
    pub max_rapid_hz: u32,
    /// Worst frame ISR time including interrupt entry and exit, ns; 0 = not measured.
    pub frame_work_ns: u32,
    /// Worst pulse-end ISR time including interrupt entry and exit, ns.
    pub pulse_end_ns: u32,
    /// The board's frame applies the AC's plan ratio (`FeedCeiling::Plan`, `$263=2`; the frame
    /// task `rt::FrameTask<true>`). A board whose frame budget has no room for its load and
    /// multiply leaves it out (`FrameTask<false>`) and refuses `$263=2`.
    pub plan_ratio: bool,
}

impl BoardLimits {
    /// The limits of the QEMU board and the host tools (W0 up to
    /// 100 kHz, rapid up to 200 kHz, ISR times not measured: the 75 % rule).
    pub const GENERIC: BoardLimits = BoardLimits {
        max_frame_hz: 100_000,
        max_rapid_hz: 200_000,
        frame_work_ns: 0,
        pulse_end_ns: 0,
        plan_ratio: true,
    };

    /// The most frame work (ns, entry and exit included) that settings `s` tolerate on this board:
    /// the largest `frame_work_ns` for which the timing rule and the ISR share of
    /// [`Settings::validate`] still hold (the pulse width's own part of the gap aside). A
    /// board that measures its frame holds the feed when a frame takes longer (ALARM:111).
    pub fn frame_work_allowed_ns(&self, s: &Settings) -> u64 {
        let rapid = s.rapid_hz.max(1) as u64;
        let period = 1_000_000_000 / rapid;
        let pulse_end = self.pulse_end_ns as u64;
        let gap = period.saturating_sub(pulse_end + s.sign_setup_ns as u64);
        let share = (1_000_000_000 * ISR_SHARE_PCT / 100 / rapid).saturating_sub(pulse_end);
        gap.min(share)
    }

    /// The board states its ISR times (the timing rule is checked with them).
    pub const fn measured(&self) -> bool {
        self.frame_work_ns != 0
    }

    /// The highest frame rate this board sustains with a pulse width and a sign setup time: the
    /// largest rate r (Hz) for which the default settings with W0 = rapid rate = r and these pulse
    /// times pass [`Settings::validate`]; 0 if none does. Host and init (a search of ~20
    /// validations).
    pub fn highest_rate_hz(&self, pulse_width_ns: u32, sign_setup_ns: u32) -> u32 {
        let ok = |r: u32| {
            Settings {
                frame_hz: r,
                rapid_hz: r,
                pulse_width_ns,
                sign_setup_ns,
                ..Settings::default()
            }
            .validate(self)
            .is_ok()
        };
        // Every check is monotonic in the rate: a rate that fails fails above it too.
        let (mut lo, mut hi) = (0u32, FRAME_HZ_CEILING.min(RAPID_HZ_CEILING) + 1);
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            // Below 100 Hz nothing validates: search above it.
            if mid < 100 || ok(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        if lo >= 100 && ok(lo) {
            lo
        } else {
            0
        }
    }
}

/// How the Nucleo-F446RE's ISR times are stated: the most instructions each ISR runs (from entry
/// to return, counted under QEMU on the F446 build: `cargo run -p millac-qemu --release --example
/// frame_budget_f446`), times a bound on cycles per instruction, plus the exception entry and
/// return, at the core clock. The counts at the time of writing: the frame 215 (the frame that
/// ends a line decelerating into the next line and starts that one, the benchmark's `G1 corners`
/// and `G0 then G1`; a rapid frame 197), the pulse end 59. The bounds add a margin of 5 and 1
/// instructions (2 %) for code generation drift (a change of four instructions in the rapid
/// frames moved them by 9) and combinations no program runs (a feed hold or an AC cap in that
/// frame). A CI test (`board_f446`) runs that frame and checks the counts stay within these
/// bounds.
///
/// The cycles-per-instruction bound (1.5) is an assumption, not a measurement: on the Cortex-M4
/// most instructions take one cycle, loads two (one when pipelined), taken branches two to four;
/// the flash has 5 wait states at 180 MHz, hidden for sequential code by the ART accelerator's
/// prefetch and for the small hot ISRs by its 1 KiB instruction cache, but exposed when another
/// task has evicted them. Only the board's DWT figures (`FC:` in the status, `[FRAME:...]` in
/// `$I`) confirm it; the firmware checks them against what the running settings tolerate and holds
/// the feed with ALARM:111 when a frame takes longer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IsrBounds {
    pub core_hz: u32,
    pub frame_instructions: u32,
    pub pulse_end_instructions: u32,
    /// Cycles per instruction, in tenths.
    pub cpi_x10: u32,
    /// Exception entry and return, cycles.
    pub entry_exit_cycles: u32,
}

impl IsrBounds {
    /// Nanoseconds (rounded up) of an ISR of `instructions` instructions.
    pub const fn ns(&self, instructions: u32) -> u32 {
        let tenths = instructions as u64 * self.cpi_x10 as u64 + 10 * self.entry_exit_cycles as u64;
        (tenths * 100_000_000).div_ceil(self.core_hz as u64) as u32
    }
}

/// Highest frame rate any board may state (keeps the frame's arithmetic far from overflow).
pub const FRAME_HZ_CEILING: u32 = 1_000_000;
/// Highest rapid rate any board may state.
pub const RAPID_HZ_CEILING: u32 = 1_000_000;
/// Share of the CPU, in percent, the frame and pulse-end ISRs may take at the rapid rate on a
/// board with measured ISR times.
pub const ISR_SHARE_PCT: u64 = 50;

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
    /// The board's measured ISR times leave less than the sign setup time between a SIGN change
    /// and the next rising PULSE edge at the rapid rate.
    SignSetup,
    /// The frame and pulse-end ISRs would take more than [`ISR_SHARE_PCT`] % of the CPU at the
    /// rapid rate.
    IsrLoad,
}

impl SettingsError {
    pub const fn message(self) -> &'static str {
        match self {
            SettingsError::FrameRate => {
                "frame rate must be 100..=100000 Hz, or up to the board's own maximum"
            }
            SettingsError::Q0 => "q0 must be 1..=1000000",
            SettingsError::RapidRate => {
                "rapid rate must be at least the frame rate and at most 200000 Hz, or the board's own maximum"
            }
            SettingsError::PtpSteps => "PTP deceleration thresholds must be decreasing and non-zero",
            SettingsError::DecelTau => "deceleration time constant must be 1 ms..=10 s",
            SettingsError::PulseTiming => {
                "pulse width + sign setup must leave at least 25% of the rapid frame period for the frame"
            }
            SettingsError::SoftLimits => "soft limits must satisfy min <= 0 <= max on every axis",
            SettingsError::Acceleration => "acceleration must be 100..=100000000 BLU/s^2 on every axis",
            SettingsError::SignSetup => {
                "rapid period - max(pulse width, frame ISR) - pulse-end ISR must be at least the sign setup time on this board"
            }
            SettingsError::IsrLoad => {
                "frame + pulse-end ISRs must take at most 50% of the CPU at the rapid rate on this board"
            }
        }
    }
}

impl Settings {
    /// The rapid rate in um/min (the rapid pulse rate times the BLU).
    pub fn rapid_um_min(&self) -> u64 {
        u64::from(self.rapid_hz) * u64::from(self.blu.nm()) * 60 / 1000
    }

    /// [`Settings::validate`] for `board`, and the settings as a [`Valid`] when they pass: what a
    /// consumer of NC settings takes.
    pub fn validated(self, board: &BoardLimits) -> Result<Valid<Settings>, SettingsError> {
        self.validate(board)?;
        Ok(Valid::checked(self))
    }

    /// Checks every setting for `board`: the generic ranges, with the frame and rapid rate caps
    /// taken from the board (up to [`FRAME_HZ_CEILING`] / [`RAPID_HZ_CEILING`]), and the timing
    /// rule of [`crate::rt::isr`] with the board's measured ISR times (see [`BoardLimits`]).
    /// Init (before the frame timer starts), loader (`$n=`), host.
    pub fn validate(&self, board: &BoardLimits) -> Result<(), SettingsError> {
        let max_frame_hz = board.max_frame_hz.min(FRAME_HZ_CEILING);
        if !(100..=max_frame_hz).contains(&self.frame_hz) {
            return Err(SettingsError::FrameRate);
        }
        if !(1..=1_000_000).contains(&self.q0) {
            return Err(SettingsError::Q0);
        }
        let max_rapid_hz = board.max_rapid_hz.min(RAPID_HZ_CEILING);
        if self.rapid_hz < self.frame_hz || self.rapid_hz > max_rapid_hz {
            return Err(SettingsError::RapidRate);
        }
        let [a, b, c] = self.ptp_steps;
        if !(a > b && b > c && c > 0) {
            return Err(SettingsError::PtpSteps);
        }
        if !(1_000..=10_000_000).contains(&self.decel_tau_us) {
            return Err(SettingsError::DecelTau);
        }
        // The shortest frame period (rapid_hz >= frame_hz), rounded down: the check is on the
        // safe side.
        let period_ns = 1_000_000_000u64 / self.rapid_hz as u64;
        let width = self.pulse_width_ns as u64;
        let setup = self.sign_setup_ns as u64;
        if width == 0 {
            return Err(SettingsError::PulseTiming);
        }
        if board.measured() {
            // The timing rule with the board's numbers: the SIGN lines change after the pulse
            // end ISR, which runs after max(pulse width, frame work); the next rising edge comes
            // one period after this one.
            let frame = board.frame_work_ns as u64;
            let pulse_end = board.pulse_end_ns as u64;
            if period_ns < width.max(frame) + pulse_end + setup {
                return Err(SettingsError::SignSetup);
            }
            // Both ISRs run once per rapid frame: their share of the CPU, in ns per second.
            let busy = (frame + pulse_end) * self.rapid_hz as u64;
            if busy * 100 > 1_000_000_000 * ISR_SHARE_PCT {
                return Err(SettingsError::IsrLoad);
            }
        } else if (width + setup) * 4 > period_ns * 3 {
            // Unmeasured ISR times: the pulse must end and the sign must settle inside the
            // shortest frame, with a quarter of the frame left for the frame's own work.
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A Nucleo-F446RE-like board: W0 up to 250 kHz, measured ISR times.
    const F446: BoardLimits = BoardLimits {
        max_frame_hz: 250_000,
        max_rapid_hz: 250_000,
        frame_work_ns: 1500,
        pulse_end_ns: 400,
        plan_ratio: true,
    };

    /// 200 kHz contouring and rapid, 2 us pulse, 2 us sign setup.
    fn fast() -> Settings {
        Settings {
            frame_hz: 200_000,
            rapid_hz: 200_000,
            pulse_width_ns: 2000,
            sign_setup_ns: 2000,
            ..Settings::default()
        }
    }

    /// The frame work the running settings tolerate is the edge of validation too: a board whose
    /// frame took exactly that long would still validate them, one ns more would not.
    #[test]
    fn the_frame_work_allowed_is_the_edge_for_the_running_settings() {
        let b = F446;
        for s in [
            Settings::default(),
            Settings {
                frame_hz: 190_000,
                rapid_hz: 190_000,
                pulse_width_ns: 1_000,
                sign_setup_ns: 2_000,
                ..Settings::default()
            },
            Settings {
                frame_hz: 100_000,
                rapid_hz: 150_000,
                pulse_width_ns: 2_000,
                sign_setup_ns: 2_000,
                ..Settings::default()
            },
        ] {
            assert_eq!(s.validate(&b), Ok(()), "{s:?}");
            let allowed = b.frame_work_allowed_ns(&s);
            assert!(allowed >= b.frame_work_ns as u64, "{allowed}");
            let at = |ns: u64| BoardLimits {
                frame_work_ns: ns as u32,
                ..b
            };
            assert_eq!(s.validate(&at(allowed)), Ok(()), "{s:?} at {allowed}");
            assert!(
                s.validate(&at(allowed + 1)).is_err(),
                "{s:?} at {allowed} + 1"
            );
        }
    }

    /// The highest rate is the edge of validation: it validates and one Hz more does not. For the
    /// generic board with 5 us + 5 us it is the 75 % rule's 75 kHz (10 us <= 0.75 T); for a
    /// measured board it is the tighter of the sign-setup gap and the ISR share.
    #[test]
    fn the_highest_rate_is_the_edge_of_validation() {
        let at = |b: &BoardLimits, r: u32, w: u32, s: u32| {
            Settings {
                frame_hz: r,
                rapid_hz: r,
                pulse_width_ns: w,
                sign_setup_ns: s,
                ..Settings::default()
            }
            .validate(b)
            .is_ok()
        };
        for (b, w, s) in [
            (BoardLimits::GENERIC, 5_000, 5_000),
            (BoardLimits::GENERIC, 2_000, 2_000),
            (F446, 2_000, 2_000),
            (F446, 5_000, 5_000),
            (F446, 2_000, 10_000),
        ] {
            let r = b.highest_rate_hz(w, s);
            assert!(r >= 100 && at(&b, r, w, s), "{b:?} {w} {s}: {r}");
            assert!(!at(&b, r + 1, w, s), "{b:?} {w} {s}: {r} + 1");
        }
        // The period is whole ns, rounded down: 4 x 10 000 <= 3 x floor(1e9 / r) needs a period
        // of 13 334 ns.
        assert_eq!(
            BoardLimits::GENERIC.highest_rate_hz(5_000, 5_000),
            1_000_000_000 / 13_334
        );
        // The brief's board: gap 1/r >= 2000 + 400 + 2000 ns -> 227 272 Hz; ISR share
        // (1500 + 400) ns * r <= 0.5 s -> 263 157 Hz; its maximum 250 kHz: the gap binds.
        assert_eq!(F446.highest_rate_hz(2_000, 2_000), 1_000_000_000 / 4_400);
        // Nothing validates: a pulse longer than any allowed period.
        assert_eq!(BoardLimits::GENERIC.highest_rate_hz(20_000_000, 1), 0);
    }

    #[test]
    fn a_fast_board_runs_200_khz_with_its_measured_isr_times() {
        // Gap 5000 - max(2000, 1500) - 400 = 2600 >= 2000; load (1500 + 400) * 200k = 38 %.
        assert_eq!(fast().validate(&F446), Ok(()));
        // The generic limits refuse it (W0 above 100 kHz), and so would the 75 % rule.
        assert_eq!(
            fast().validate(&crate::settings::BoardLimits::GENERIC),
            Err(SettingsError::FrameRate)
        );
        let unmeasured = BoardLimits {
            frame_work_ns: 0,
            pulse_end_ns: 0,
            ..F446
        };
        assert_eq!(
            fast().validate(&unmeasured),
            Err(SettingsError::PulseTiming)
        );
    }

    #[test]
    fn the_sign_setup_gap_uses_the_frame_work_and_the_pulse_end() {
        let with = |frame_work_ns, pulse_end_ns| BoardLimits {
            frame_work_ns,
            pulse_end_ns,
            ..F446
        };
        // The brief's board with more frame work: 5000 - 2700 - 400 = 1900 < 2000.
        assert_eq!(
            fast().validate(&with(2700, 400)),
            Err(SettingsError::SignSetup)
        );
        // Frame work above the pulse width sets the falling edge (a 3 us sign setup keeps the
        // ISR load below half): 5000 - 1600 - 400 = 3000.
        let long_setup = Settings {
            pulse_width_ns: 1000,
            sign_setup_ns: 3000,
            ..fast()
        };
        assert_eq!(long_setup.validate(&with(1600, 400)), Ok(()));
        assert_eq!(
            long_setup.validate(&with(1601, 400)),
            Err(SettingsError::SignSetup)
        );
        // Below the pulse width it does not matter for the gap.
        assert_eq!(long_setup.validate(&with(900, 400)), Ok(()));
        // A longer pulse-end ISR eats the gap too: 5000 - 2000 - 1001 < 2000.
        assert_eq!(
            fast().validate(&with(1500, 1001)),
            Err(SettingsError::SignSetup)
        );
        // A pulse longer than the frame work sets the falling edge: 5000 - 2500 - 400 = 2100.
        let wide = Settings {
            pulse_width_ns: 2500,
            sign_setup_ns: 2100,
            ..fast()
        };
        assert_eq!(wide.validate(&with(100, 400)), Ok(()));
        assert_eq!(wide.validate(&with(2000, 400)), Ok(()));
        assert_eq!(
            wide.validate(&with(100, 401)),
            Err(SettingsError::SignSetup)
        );
    }

    #[test]
    fn the_isrs_may_take_half_the_cpu_at_the_rapid_rate() {
        let s = Settings {
            pulse_width_ns: 1000,
            sign_setup_ns: 1000,
            ..fast()
        };
        let with = |frame_work_ns, pulse_end_ns| BoardLimits {
            frame_work_ns,
            pulse_end_ns,
            ..F446
        };
        // (1900 + 600) ns * 200 kHz = 0.5 s per second: exactly half.
        assert_eq!(s.validate(&with(1900, 600)), Ok(()));
        // 2600 ns: 52 %, although the gap (5000 - 2000 - 600 = 2400) is fine.
        assert_eq!(s.validate(&with(2000, 600)), Err(SettingsError::IsrLoad));
        // The same board at a lower rapid rate is fine.
        let slower = Settings {
            frame_hz: 150_000,
            rapid_hz: 150_000,
            ..s
        };
        assert_eq!(slower.validate(&with(2000, 600)), Ok(()));
    }

    #[test]
    fn the_board_caps_the_frame_and_rapid_rates() {
        let at = |frame_hz, rapid_hz| Settings {
            frame_hz,
            rapid_hz,
            pulse_width_ns: 1000,
            sign_setup_ns: 1000,
            ..Settings::default()
        };
        let roomy = BoardLimits {
            frame_work_ns: 500,
            pulse_end_ns: 100,
            ..F446
        };
        assert_eq!(at(250_000, 250_000).validate(&roomy), Ok(()));
        assert_eq!(
            at(250_001, 250_001).validate(&roomy),
            Err(SettingsError::FrameRate)
        );
        assert_eq!(
            at(200_000, 250_001).validate(&roomy),
            Err(SettingsError::RapidRate)
        );
        assert_eq!(
            fast().validate(&BoardLimits {
                max_frame_hz: 199_999,
                ..F446
            }),
            Err(SettingsError::FrameRate)
        );
        // No board goes past the ceilings.
        let unlimited = BoardLimits {
            max_frame_hz: u32::MAX,
            max_rapid_hz: u32::MAX,
            frame_work_ns: 1,
            pulse_end_ns: 1,
            plan_ratio: true,
        };
        let ceiling = Settings {
            pulse_width_ns: 100,
            sign_setup_ns: 100,
            ..at(FRAME_HZ_CEILING, RAPID_HZ_CEILING)
        };
        assert_eq!(ceiling.validate(&unlimited), Ok(()));
        let above = Settings {
            frame_hz: FRAME_HZ_CEILING + 1,
            rapid_hz: FRAME_HZ_CEILING + 1,
            ..ceiling
        };
        assert_eq!(above.validate(&unlimited), Err(SettingsError::FrameRate));
    }

    /// `Settings::validate` as it was before boards had limits of their own.
    fn validate_before_boards(s: &Settings) -> Result<(), SettingsError> {
        if !(100..=100_000).contains(&s.frame_hz) {
            return Err(SettingsError::FrameRate);
        }
        if !(1..=1_000_000).contains(&s.q0) {
            return Err(SettingsError::Q0);
        }
        if s.rapid_hz < s.frame_hz || s.rapid_hz > 200_000 {
            return Err(SettingsError::RapidRate);
        }
        let [a, b, c] = s.ptp_steps;
        if !(a > b && b > c && c > 0) {
            return Err(SettingsError::PtpSteps);
        }
        if !(1_000..=10_000_000).contains(&s.decel_tau_us) {
            return Err(SettingsError::DecelTau);
        }
        let period_ns = 1_000_000_000u64 / s.rapid_hz as u64;
        let need = s.pulse_width_ns as u64 + s.sign_setup_ns as u64;
        if s.pulse_width_ns == 0 || need * 4 > period_ns * 3 {
            return Err(SettingsError::PulseTiming);
        }
        for k in 0..3 {
            if s.soft_min[k] > 0 || s.soft_max[k] < 0 {
                return Err(SettingsError::SoftLimits);
            }
        }
        if !s.accel_blu_s2.iter().all(|a| ACCEL_RANGE.contains(a)) {
            return Err(SettingsError::Acceleration);
        }
        Ok(())
    }

    fn around(edges: &'static [u32]) -> impl Strategy<Value = u32> {
        prop_oneof![
            proptest::sample::select(edges),
            proptest::sample::select(edges).prop_map(|e| e.saturating_add(1)),
            proptest::sample::select(edges).prop_map(|e| e.saturating_sub(1)),
            any::<u32>(),
        ]
    }

    proptest! {
        #[test]
        fn validate_is_unchanged_for_the_generic_board(
            frame_hz in around(&[100, 5000, 100_000, 200_000]),
            rapid_hz in around(&[100, 26_333, 100_000, 200_000, 250_000]),
            q0 in around(&[1, 3000, 1_000_000]),
            width in around(&[0, 1000, 2000, 5000, 10_000]),
            setup in around(&[0, 1000, 2000, 5000, 10_000]),
            tau in around(&[1000, 20_000, 10_000_000]),
            min_x in -2i32..=2,
            accel in around(&[100, 250_000, 100_000_000]),
        ) {
            let s = Settings {
                frame_hz,
                rapid_hz,
                q0,
                pulse_width_ns: width,
                sign_setup_ns: setup,
                decel_tau_us: tau,
                soft_min: [min_x, -1, -1],
                accel_blu_s2: [accel, 250_000, 250_000],
                ..Settings::default()
            };
            prop_assert_eq!(s.validate(&crate::settings::BoardLimits::GENERIC), validate_before_boards(&s));
            prop_assert_eq!(s.validate(&BoardLimits::GENERIC), validate_before_boards(&s));
        }
    }
}
