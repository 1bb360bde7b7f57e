//! The bodies of the sampler and of the AC period, over the ports, for the firmware's tasks and the
//! host simulation alike, so the two cannot drift (sampler task, AC task; host).
//!
//! # Timing of the AC period
//!
//! The sampler takes one conversion per sample-clock period and says that an AC period is due
//! after every `sample_hz * period_ms / 1000`-th sample (10 at the defaults), with the sample count
//! as the period's deadline base. The period is thus clocked by the same clock as the samples:
//! every period sees exactly its own window of samples, and the host can replay the grouping
//! (period k = samples `k*N .. (k+1)*N`). A separate monotonic (SysTick) would be a second clock
//! beating against the sample clock, giving 9, 10 or 11 samples per window depending on phase.
//!
//! # The period
//!
//! One encoder reading per period: it gives the achieved feed (anti-windup, see
//! `AcController::set_achieved`) and it is the position logged, so a replay from `ac.log` and the
//! samples reproduces every decision. A hold is a feed cap of 0: the frame keeps its block and its
//! counters, it simply stops feeding; no block is dropped.
//!
//! # A missed conversion
//!
//! A sample clock tick whose ADC gives no fresh conversion ([`Conversion::Missed`], a dropout)
//! still counts as a sample and still makes a period due: the clock is the sample timer's, not the
//! ADC's answer. The sampler hands the period nothing for it, so a period whose whole window was
//! missed sees no fresh samples and holds with `Alarm::NoSamples` (feed cap 0, position kept), and
//! the run ends as after any hold. An ADC that is gone for good ([`Conversion::Lost`]) is the same
//! for the AC period (every later tick is missed, the period holds with `Alarm::NoSamples`), and
//! the sampler says so once ([`Sampled::Lost`]) so the app can report it: the machine stops
//! safely with its position exact and the run leaves its report, as after any hold.
//!
//! # The sampler's trip
//!
//! The AC period holds on an overload once per period (10 ms), but the sampler sees the crossing
//! at the sample rate (1 ms). With the AC applied, the sampler compares every fresh conversion
//! with the overload hold's own level ([`Trip`]: F above (1 - `overload_e`) F0, or |T| above
//! (1 - `overload_e`) T0, where the period's E falls below `overload_e`) and on the first sample
//! above it stores a feed cap of 0 at once: the frame starts its feed hold (and a rapid its
//! ladder) in its next frame, a period earlier than the AC period could. The AC period judges
//! the same sample ([`AcPeriod::sample`]) and makes the hold its alarm: a sensor fault when the
//! DRR refuses the sample, a tool breakage when the breakage monitor's tooth periods before it
//! show a chip moved from one tooth to the next ([`crate::monitor::BreakageDetector::chip_moved`]:
//! the broken tooth's missing chip, the next tooth's doubled one), else an overload, and keeps
//! it until the operator resumes, whatever the window's pick says.
//!
//! # End of a hold
//!
//! With an operator (serial mode), `~` or `$X` sets `Status::ac_resume` and the next period calls
//! `AcController::resume`: the FRC restarts from f_min (a fault or overload that persists holds
//! again). Without one (batch runs), after [`HOLD_EXIT_PERIODS`] periods in hold with the encoder
//! unchanged (only when the AC is enabled: a measure-only run logs the hold and goes on) the
//! period asks its caller to stop: the firmware reports its position and exits, the host
//! simulation ends the run. (The firmware ignores that request in serial mode.)
//!
//! # The operator's override
//!
//! The frame runs at min(programmed feed, AC cap) times the operator's factor, so the feed
//! achieved over a period is the factor times what the AC asked for. The anti-windup input is
//! divided by the factor: the AC works in programmed-feed units and its cap does not collapse
//! under an override below 100 % (with the achieved feed as it is, an override of 50 % would
//! pull the cap down to about twice one FRC step). In a cut where the force limit binds, the AC
//! thus holds the force at its limit whatever the override (the override acts where the
//! programmed feed binds, and in air); during a feed hold the achieved feed is 0 and the cap
//! falls towards f_min, so a resume restarts the cut gently.
use super::status::{AcWriter, FittedTool, SamplerWriter};
use crate::ac::{achieved_feed, AcController, AcOutput, AcState};
use crate::monitor::chatter::Spectrum;
use crate::monitor::{Breakage, BreakageDetector, BreakageSettings, FeedChange};
use crate::ports::{Codes, Conversion, ForceTorqueAdc};
use crate::settings::{Settings, Valid};
use crate::wire::SOUND_PER_SAMPLE;

/// The breakage monitor of an AC period ([`AcPeriod::with_breakage`]): the detector fed every
/// sample's resultant force, the spindle speed and flutes it judges for, and a declaration not
/// yet acted on.
pub struct BreakageMonitor {
    pub detector: BreakageDetector,
    rpm: u32,
    teeth: u8,
    pending: Option<Breakage>,
}

/// AC periods in hold with the encoder unchanged before a run stops (1 s at 10 ms).
pub const HOLD_EXIT_PERIODS: u32 = 100;

/// `Status::ac_state` while the AC runs (0: no period yet; a hold stores its `ALARM:N` number).
pub const AC_RUN: u8 = 1;

/// The achieved feed in programmed-feed units: divided by the operator's factor (Q8; 0, a feed
/// hold, leaves it as it is). See the module doc.
pub fn unscale_override(achieved: u32, factor_q8: u32) -> u32 {
    if factor_q8 == 0 {
        return achieved;
    }
    u32::try_from(u64::from(achieved) * 256 / u64::from(factor_q8)).unwrap_or(u32::MAX)
}

/// What one sample gave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sampled {
    /// The ADC has gone (for good) at this tick: no codes, the clock goes on as for a missed
    /// conversion (`due` likewise), so the AC periods hold with NoSamples.
    Lost { due: Option<u32> },
    /// The codes (None: no fresh conversion this tick, nothing for the AC period); `due`: an AC
    /// period is due with this deadline base (the sample count); `sound`: the sound channel's
    /// codes since the previous sample (None: no microphone).
    Codes {
        codes: Option<Codes>,
        due: Option<u32>,
        sound: Option<[u16; SOUND_PER_SAMPLE]>,
    },
}

/// The sampler's overload trip (see the module doc): the overload hold's level in engineering
/// units and the calibration that gets there from the codes. Built once from the AC settings
/// (init); used by the sampler (the hold) and by the AC period (its alarm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trip {
    cal: [crate::ac::Calibration; 3],
    /// The force level squared (N^2: no square root per sample) and the torque level (N*m).
    f_sq: f32,
    t_nm: f32,
}

/// How much wider a ball end mill's F R / T band is at its upper end: its edges cut at radii
/// below R (r = sqrt(a (2R - a)) at depth a: F R / T up to sqrt(1 + Kr^2) R / r), so the flat
/// end mill's bound holds for it only times R / r; 4 covers any cut deeper than R / 32 (r above
/// a quarter of R), below which its load is near the floor the band does not judge.
pub const BALL_BAND: f32 = 4.0;

/// The AC settings for a tool an M6 fitted: its permissible force, its permissible torque where
/// below the drive's (`$255`: the spindle's torque limits too), its flutes where known (else
/// `$267`), its radius where known (the force/torque plausibility's lever, else `$284`; a ball
/// end mill's band [`BALL_BAND`] wider at its upper end), the rest the machine's. None when the tool has no limits (nobody gave them and its
/// geometry does not tell, `crate::ac::strength::of_tool`): the AC does not limit it, and says
/// so. The AC period, the sampler's trip and the loader's status report each take it from
/// here. Any context but the ISRs.
pub fn tool_settings(
    base: &crate::ac::AcSettings,
    tool: &FittedTool,
) -> Option<Valid<crate::ac::AcSettings>> {
    let l = tool.limits?;
    crate::ac::AcSettings {
        force_limit_n: l.force_n,
        torque_limit_nm: l.torque_nm.min(base.torque_limit_nm),
        flutes: tool.flutes_or(base.flutes),
        tool_radius_mm: tool.radius_or(base.tool_radius_mm),
        ft_ratio_max: match tool.kind {
            crate::gcode::tools::ToolKind::Ball => base.ft_ratio_max * BALL_BAND,
            _ => base.ft_ratio_max,
        },
        ..*base
    }
    .validated()
    .ok()
}

/// The AC settings for the tool in the spindle: the machine's before any M6 (`$254`, `$255`,
/// `$267` describe the tool), else the fitted tool's ([`tool_settings`]; None: no limits).
/// Rebuilt only when the tool changes (`Status::tool_changes`). The sampler's trip and the AC
/// period keep one each.
#[derive(Clone, Copy, Debug)]
pub struct ToolFollower {
    base: Valid<crate::ac::AcSettings>,
    seen: u32,
    /// The tool's number (0: none fitted).
    number: u8,
}

impl ToolFollower {
    /// Following the tool from the machine's settings `base` (no M6 seen yet).
    pub fn new(base: Valid<crate::ac::AcSettings>) -> Self {
        ToolFollower {
            base,
            seen: 0,
            number: 0,
        }
    }

    /// The machine's settings.
    pub fn base(&self) -> &Valid<crate::ac::AcSettings> {
        &self.base
    }

    /// The number of the tool followed (0: none fitted).
    pub fn number(&self) -> u8 {
        self.number
    }

    /// A tool fitted since the last call, with its settings (None: it has no limits); None
    /// while the tool is the same (one word read, every sample).
    #[inline]
    pub fn changed(
        &mut self,
        status: &crate::rt::Status,
    ) -> Option<(FittedTool, Option<Valid<crate::ac::AcSettings>>)> {
        if status.tool_changes.get() == self.seen {
            return None;
        }
        let (n, tool) = status.fitted_tool()?;
        self.seen = n;
        self.number = tool.number;
        Some((tool, tool_settings(&self.base, &tool)))
    }
}

/// The sampler's trip for the tool in the spindle: [`Trip`] of its settings, rebuilt when an M6
/// fits another ([`ToolFollower`]); none for a tool without limits. Sampler task (with the AC
/// applied).
#[derive(Clone, Copy, Debug)]
pub struct ToolTrip {
    follower: ToolFollower,
    trip: Option<Trip>,
}

impl ToolTrip {
    pub fn new(base: Valid<crate::ac::AcSettings>) -> Self {
        ToolTrip {
            follower: ToolFollower::new(base),
            trip: Some(Trip::new(&base)),
        }
    }

    /// The trip of the tool in the spindle now.
    #[inline]
    pub fn follow(&mut self, status: &crate::rt::Status) -> Option<&Trip> {
        if let Some((_, s)) = self.follower.changed(status) {
            self.trip = s.map(|s| Trip::new(&s));
        }
        self.trip.as_ref()
    }
}

impl Trip {
    pub fn new(s: &crate::ac::AcSettings) -> Self {
        let k = 1.0 - s.overload_e;
        let f = k * s.f0_n();
        Trip {
            cal: s.cal,
            f_sq: f * f,
            t_nm: k * s.t0_nm(),
        }
    }

    /// The sample's F (N) and |T| (N*m) when either is above the overload hold's level. Codes out
    /// of the 12-bit range are the DRR's to judge (a fault), not a trip.
    #[inline]
    pub fn over(&self, c: Codes) -> Option<(f32, f32)> {
        if c.iter().any(|&k| k > crate::ac::CODE_MAX) {
            return None;
        }
        let t = self.cal[0].value(c[0]).abs();
        let (fu, fv) = (self.cal[1].value(c[1]), self.cal[2].value(c[2]));
        let f_sq = fu * fu + fv * fv;
        (f_sq > self.f_sq || t > self.t_nm).then(|| (crate::ac::ecr::force(fu, fv), t))
    }
}

/// One sample: the ADC converts with the encoder counts of this instant (a simulated ADC needs
/// them), the sample count advances (also when the conversion was missed). With `trip` (the AC
/// applied), a conversion above the overload hold's level holds the feed at once (a feed cap of
/// 0; see the module doc). Sampler task.
pub fn sample(
    adc: &mut impl ForceTorqueAdc,
    status: &SamplerWriter,
    per_period: u32,
    trip: Option<&Trip>,
) -> Sampled {
    let i = status.samples.get();
    let conversion = adc.sample(i, status.encoder());
    if let (Some(t), Conversion::Fresh(c)) = (trip, conversion) {
        if t.over(c).is_some() {
            status.trip();
        }
    }
    let n = i.wrapping_add(1);
    status.set_samples(n);
    let due = (n % per_period.max(1) == 0).then_some(n);
    let sound = adc.sound();
    match conversion {
        Conversion::Fresh(c) => Sampled::Codes {
            codes: Some(c),
            due,
            sound,
        },
        Conversion::Missed => Sampled::Codes {
            codes: None,
            due,
            sound,
        },
        Conversion::Lost => Sampled::Lost { due },
    }
}

/// A feed step for the breakage monitor: the motion of one AC period differs from the period
/// before by more than this percentage of the larger ([`BreakageDetector::feed_step`]). The
/// frame's deceleration at a corner takes the feed to a fifth within a few periods; the AC's own
/// changes are a few per cent per period.
pub const FEED_STEP_PCT: u64 = 30;
/// ... and by more than this many BLU: the motion of a constant feed over one AC period (or
/// over several) can differ from the same span before by a pulse at each end, so a difference
/// of up to two pulses says nothing; beyond it, the percentage decides. A floor on the motion
/// itself instead (10 BLU per period is 6 ipm at 0.0001 in) leaves a small tool's feeds, which
/// its AC moves between 2 and 6 ipm, without any notice, and its trips judged as breakages.
pub const FEED_STEP_MIN_BLU: u32 = 2;
/// A feed ramp for the breakage monitor: the motion of the last revolution's AC periods differs
/// from the revolution's before by more than this percentage of the larger. The AC's recovery
/// after a corner raises the feed by 10 to 20 % per period, below [`FEED_STEP_PCT`], for several
/// revolutions; the force follows it revolution by revolution, which the detector's
/// once-per-revolution differences would otherwise judge (the Fig. 1 cavity with the servo
/// drive: a breakage declared 0.3 s after a corner, with a sound tool). The AC's own regulation
/// in a steady cut moves a revolution's motion by a few per cent.
pub const FEED_RAMP_PCT: u64 = 15;
/// A feed change the breakage monitor records without holding (`FeedChange::hold` false): one
/// AC period's motion differs from the period before's by more than this percentage of the
/// larger. At the sampler's trip a loss after a lowering and a crossing after a raise are the
/// feed's ([`BreakageDetector::chip_moved`]); the AC's regulation of a small tool near its limit
/// moves its feed by 30 % a period (7 to 10 BLU), at the step's edge.
///
/// [`BreakageDetector::chip_moved`]: crate::monitor::BreakageDetector::chip_moved
pub const FEED_NOTE_PCT: u64 = 15;
/// AC periods of motion kept for the ramp test: two revolutions of up to half as many periods
/// (at 10 ms periods: 375 rpm and faster; slower spindles compare 16 periods).
pub const MOTION_RING: usize = 32;

/// The feed notices the breakage monitor gets ([`BreakageDetector::feed_step`]): from the encoder
/// at the end of every AC period, a step ([`FEED_STEP_PCT`]: the motion of the period against the
/// period before's) or a ramp ([`FEED_RAMP_PCT`]: the last revolution's periods against the
/// revolution's before). AC task ([`AcPeriod`]), and the host's replays of the detector.
///
/// [`BreakageDetector::feed_step`]: crate::monitor::BreakageDetector::feed_step
#[derive(Clone, Debug)]
pub struct FeedNotice {
    last: [i32; 3],
    /// The path's motion (BLU, the largest axis') of the last [`MOTION_RING`] periods, the
    /// newest at `at` - 1.
    motion: [u32; MOTION_RING],
    at: usize,
}

impl Default for FeedNotice {
    fn default() -> Self {
        Self::new()
    }
}

impl FeedNotice {
    /// No motion yet, from the origin.
    pub const fn new() -> Self {
        FeedNotice {
            last: [0; 3],
            motion: [0; MOTION_RING],
            at: 0,
        }
    }

    /// The period that ended at encoder `enc` (a spindle at `rpm`, 0: unknown, and periods of
    /// `period_ms`): the feed's change against the period before when it is more than
    /// [`FEED_NOTE_PCT`] (and the quantum), a step (`hold`) beyond [`FEED_STEP_PCT`]; else a
    /// ramp (`hold`), if there is one.
    pub fn period(&mut self, enc: [i32; 3], rpm: u32, period_ms: u32) -> Option<FeedChange> {
        let moved = (0..3)
            .map(|k| enc[k].wrapping_sub(self.last[k]).unsigned_abs())
            .max()
            .unwrap_or(0);
        self.last = enc;
        let before = self.back(0);
        if let Some(slot) = self.motion.get_mut(self.at) {
            *slot = moved;
        }
        self.at = (self.at + 1) % MOTION_RING;
        let (new, old) = (u64::from(moved), u64::from(before));
        let change = change_of(new, old, FEED_NOTE_PCT).map(|c| FeedChange {
            hold: change_of(new, old, FEED_STEP_PCT).is_some(),
            ..c
        });
        match change {
            Some(c) if c.hold => Some(c),
            _ => self.ramp(rpm, period_ms).or(change),
        }
    }

    /// The motion `k` periods before the newest.
    fn back(&self, k: usize) -> u32 {
        self.motion
            .get((self.at + 2 * MOTION_RING - 1 - k) % MOTION_RING)
            .copied()
            .unwrap_or(0)
    }

    /// Whether the motion of the last revolution's periods (at `rpm`, rounded to whole periods,
    /// 1 ..= [`MOTION_RING`] / 2) differs from the revolution's before by more than
    /// [`FEED_RAMP_PCT`] of the larger and by more than [`FEED_STEP_MIN_BLU`].
    fn ramp(&self, rpm: u32, period_ms: u32) -> Option<FeedChange> {
        let per_rev = rpm.saturating_mul(period_ms.max(1));
        if per_rev == 0 {
            return None;
        }
        let n = ((60_000 + per_rev / 2) / per_rev).clamp(1, MOTION_RING as u32 / 2) as usize;
        let new: u64 = (0..n).map(|k| u64::from(self.back(k))).sum();
        let old: u64 = (n..2 * n).map(|k| u64::from(self.back(k))).sum();
        change_of(new, old, FEED_RAMP_PCT)
    }
}

/// The change from motion `old` to `new` (BLU) when they differ by more than
/// [`FEED_STEP_MIN_BLU`] and `pct` % of the larger: the smaller as a percentage of the larger,
/// whether it rose, and `hold` (a step's or a ramp's; the caller says otherwise for a note).
fn change_of(new: u64, old: u64, pct: u64) -> Option<FeedChange> {
    let (lo, hi) = (new.min(old), new.max(old));
    (hi - lo > u64::from(FEED_STEP_MIN_BLU) && (hi - lo) * 100 > hi * pct).then(|| FeedChange {
        kept_pct: (lo * 100 / hi.max(1)) as u8,
        up: new > old,
        hold: true,
    })
}

/// The breakage monitor's teeth for `flutes` (`$267` or a tool's): 1 ..= `MAX_FLUTES`.
fn teeth(flutes: u32) -> u8 {
    u8::try_from(flutes.clamp(1, crate::monitor::MAX_FLUTES as u32)).unwrap_or(1)
}

/// A breakage monitor learning at `rpm` with `flutes` (clamped to the detector's range).
fn breakage_monitor(settings: Valid<BreakageSettings>, rpm: u32, flutes: u32) -> BreakageMonitor {
    let mut detector = BreakageDetector::new(settings);
    let teeth = teeth(flutes);
    detector.set_spindle(rpm as f32, teeth);
    BreakageMonitor {
        detector,
        rpm,
        teeth,
        pending: None,
    }
}

/// The AC period's state: the controller and what the period keeps between periods.
pub struct AcPeriod {
    pub ctl: AcController,
    nc: Settings,
    /// The controller's feed cap is applied (else measure and log only).
    enabled: bool,
    /// Feed the achieved feed to the controller (the firmware always does; the benchmark can run
    /// the paper's FRC exactly without it).
    anti_windup: bool,
    last: [i32; 3],
    still: u32,
    /// The breakage monitor's feed notices.
    feed: FeedNotice,
    /// A chatter verdict of the monitor task not yet acted on ([`AcPeriod::heard`]).
    chatter: Option<Spectrum>,
    /// Tool breakage detection on the force (None: off).
    breakage: Option<BreakageMonitor>,
    /// The overload hold's level per sample (the sampler's trip, see the module doc).
    trip: Trip,
    /// The tool in the spindle: its limits, flutes ([`ToolFollower`]).
    tool: ToolFollower,
    /// The tool has limits: the AC applies its cap when `enabled` (a tool without runs measure
    /// only, and the loader has said so).
    limited: bool,
    /// The first sample above it since the last period in Run: its F and T.
    tripped: Option<(f32, f32)>,
}

/// A process monitor's hold entered in this period: the output says it (state, alarm to report,
/// the held controller's cap).
fn held(out: &mut AcOutput, a: crate::ac::Alarm, ctl: &AcController) {
    out.state = AcState::Hold(a);
    out.alarm = Some(a);
    out.feed_cap = ctl.feed_cap();
}

/// The controller's feed number as the frame reads it: the cap and the plan ratio
/// ([`crate::ac::frame_words`]). The frame may run between the two stores. A hold stores only
/// its cap of 0 and leaves the ratio as it was (under a cap of 0 it does not matter), so no frame
/// meets the running cap with another ratio; otherwise the ratio goes first, so a resume's cap
/// never meets the ratio of before the hold.
fn publish(status: &AcWriter, feed_cap: u32, s: &crate::ac::AcSettings) {
    let (cap, ratio) = crate::ac::frame_words(feed_cap, s);
    if cap != 0 {
        status.set_plan_ratio(ratio);
    }
    status.set_feed_cap(cap);
}

/// What one period did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Period {
    pub out: AcOutput,
    /// The encoder counts the period read (logged as its position).
    pub encoder: [i32; 3],
    /// Held long enough with nothing moving: stop the run.
    pub halt: bool,
}

impl AcPeriod {
    /// Stores the controller's first cap into `status` when `enabled`. Init context.
    pub fn new(ctl: AcController, nc: Settings, enabled: bool, status: &AcWriter) -> Self {
        if enabled {
            publish(status, ctl.feed_cap(), ctl.settings());
        }
        let trip = Trip::new(ctl.settings());
        let tool = ToolFollower::new(ctl.valid_settings());
        AcPeriod {
            tool,
            limited: true,
            ctl,
            nc,
            enabled,
            anti_windup: true,
            last: [0; 3],
            still: 0,
            feed: FeedNotice::new(),
            chatter: None,
            breakage: None,
            trip,
            tripped: None,
        }
    }

    /// The breakage monitor when the AC settings turn it on (`$268`), for `$267` flutes at
    /// `$269` rpm until the machine is commanded a speed (`Status::spindle_rpm`); the firmware
    /// and the host simulation build it with this one function. (Chatter is judged by its own
    /// task, `crate::rt::monitor`, whose verdicts come in through [`AcPeriod::heard`].) Init
    /// context.
    pub fn with_monitors(self, s: &Valid<crate::ac::AcSettings>) -> Self {
        match s.breakage_settings() {
            Some(b) => self.with_breakage(b, s.monitor_rpm, s.flutes),
            None => self,
        }
    }

    /// Judges the resultant force of every sample for tool breakage (`crate::monitor::breakage`)
    /// at `rpm` and `flutes`: a declaration holds the feed at the next period with
    /// `Alarm::ToolBreakage` and asks the loader to stop the spindle (`Status::spindle_stop`), the
    /// thesis' reaction. Init context.
    pub fn with_breakage(
        mut self,
        settings: Valid<BreakageSettings>,
        rpm: u32,
        flutes: u32,
    ) -> Self {
        self.breakage = Some(breakage_monitor(settings, rpm, flutes));
        self
    }

    /// The cap is applied: the AC is enabled and the tool in the spindle has limits.
    fn applied(&self) -> bool {
        self.enabled && self.limited
    }

    /// An M6 fitted another tool (`s`: its settings, None: it has no limits): the controller
    /// starts afresh with its limits, as at a job start (plan ratio, the law's estimates, the
    /// held peak: `AcController::new`), the trip takes its levels, the breakage monitor its
    /// flutes (and starts learning anew). A tool without limits is measured against the
    /// machine's settings and its cap is not applied: the frame runs the programmed feeds.
    fn fit(
        &mut self,
        tool: &FittedTool,
        s: Option<Valid<crate::ac::AcSettings>>,
        status: &AcWriter,
    ) {
        self.limited = s.is_some();
        let s = s.unwrap_or(*self.tool.base());
        self.ctl = AcController::new(s);
        self.trip = Trip::new(&s);
        self.tripped = None;
        self.chatter = None;
        // The breakage monitor as `$268` says for this tool (auto: on where the table gives its
        // flutes), learning anew at the speed commanded (`$269` before any S).
        // (A new detector: the tool's kind may change its settings.)
        self.breakage = self
            .tool
            .base()
            .breakage_settings_for(tool.flutes, tool.kind)
            .map(|b| {
                let rpm = match self.breakage.as_ref().map(|m| m.rpm) {
                    Some(rpm) => rpm,
                    None => match status.spindle_rpm.get() {
                        0 => s.monitor_rpm,
                        rpm => rpm,
                    },
                };
                breakage_monitor(b, rpm, s.flutes)
            });
        // The new tool starts at the controller's first cap; a hold the sampler's trip has just
        // made on the new tool's level stays (this sample is judged by the new trip too, and the
        // period ends it as an overload). A tool without limits runs uncapped.
        if self.enabled && !self.limited {
            status.set_plan_ratio(crate::ports::PLAN_ONE);
            status.set_feed_cap(u32::MAX);
        } else if self.enabled && status.feed_cap.get() != 0 {
            publish(status, self.ctl.feed_cap(), self.ctl.settings());
        }
    }

    /// The tool the period judges for (the last M6's T; 0: none fitted, the settings' tool).
    pub fn tool(&self) -> u8 {
        self.tool.number()
    }

    /// The breakage monitor, if on.
    pub fn breakage(&self) -> Option<&BreakageMonitor> {
        self.breakage.as_ref()
    }

    /// The machine's commanded spindle speed reaches the breakage monitor (0: none yet, keep
    /// its own; a change restarts its learning, so only a change is passed on).
    fn follow_spindle(&mut self, rpm: u32) {
        if let Some(b) = self.breakage.as_mut() {
            if rpm != 0 && rpm != b.rpm {
                b.rpm = rpm;
                b.detector.set_spindle(rpm as f32, b.teeth);
            }
        }
    }

    /// A record's spectrum from the chatter monitor (`crate::rt::monitor::ChatterTask`): a
    /// record above its threshold holds the feed at the next period with `Alarm::Chatter` (the
    /// thesis' first reaction). AC task (from the monitor task's verdicts) or host.
    pub fn heard(&mut self, s: Spectrum) {
        if s.chatter && self.chatter.is_none() {
            self.chatter = Some(s);
        }
    }

    /// Runs the paper's FRC without the anti-windup input (benchmarks).
    pub fn without_anti_windup(mut self) -> Self {
        self.anti_windup = false;
        self
    }

    /// Samples per AC period.
    pub fn per_period(&self) -> u32 {
        self.ctl.settings().samples_per_period()
    }

    /// One conversion into the controller's window (and the breakage monitor's force); a tool
    /// an M6 fitted since the last sample takes over first ([`AcPeriod::fit`]: this sample is
    /// the new tool's, as the sampler's trip already judged it). AC task (from the sampler's
    /// queue) or host.
    pub fn sample(&mut self, codes: Codes, status: &AcWriter) {
        if let Some((tool, s)) = self.tool.changed(status) {
            self.fit(&tool, s, status);
        }
        self.ctl.sample(codes);
        // The sampler's trip on this sample (see the module doc), judged before the breakage
        // monitor takes the sample in: the tooth periods before it say what made the crossing.
        if self.tripped.is_none() && self.ctl.state() == AcState::Run {
            if let Some(ft) = self.trip.over(codes) {
                self.tripped = Some(ft);
                if let Some(m) = self.breakage.as_mut() {
                    if let Some(b) = m.detector.chip_moved() {
                        m.pending.get_or_insert(b);
                    }
                }
            }
        }
        if let Some(m) = self.breakage.as_mut() {
            let cal = &self.ctl.settings().cal;
            let (fu, fv) = (cal[1].value(codes[1]), cal[2].value(codes[2]));
            if let Some(b) = m.detector.sample_uv(fu, fv) {
                m.pending.get_or_insert(b);
            }
        }
    }

    /// One AC period: reads the encoder, gives the controller the achieved feed, runs it, writes
    /// the feed cap (when enabled) and counts the periods held with nothing moving. AC task.
    pub fn run(&mut self, status: &AcWriter) -> Period {
        let enc = status.encoder();
        if status.take_new_job() {
            self.ctl.new_job();
        }
        if status.take_resume() {
            self.ctl.resume();
            self.still = 0;
            // A resumed cut is judged afresh (after a breakage: with the new tool), and so is the
            // sound (`Status::resumes` restarts the chatter monitor's record).
            if let Some(m) = self.breakage.as_mut() {
                m.detector.reset();
                m.pending = None;
            }
            self.chatter = None;
            self.tripped = None;
            status.count_resume();
        }
        self.follow_spindle(status.spindle_rpm.get());
        // A feed step (a corner's deceleration and the acceleration after it, a hold, a
        // resume): the breakage monitor does not judge the force's transient as a tooth's.
        let rpm = self.breakage.as_ref().map_or(0, |m| m.rpm);
        let notice = self.feed.period(enc, rpm, self.ctl.settings().period_ms);
        if let (Some(m), Some(change)) = (self.breakage.as_mut(), notice) {
            m.detector.feed_step(change);
        }
        // The Z axis fed down in this period: the end face may cut (force/torque band).
        self.ctl.set_z_down(enc[2] < self.last[2]);
        if self.anti_windup {
            let d = [0, 1, 2].map(|k| i64::from(enc[k]) - i64::from(self.last[k]));
            let period_ms = self.ctl.settings().period_ms;
            let achieved = achieved_feed(d, &self.nc, period_ms);
            let factor = status.operator.get() & crate::nc::operator::FEED_MASK;
            self.ctl.set_achieved(unscale_override(achieved, factor));
        }
        let mut out = self.ctl.period();
        // The sampler held on a sample the period did not hold on (its pick is the latest
        // sample, or the crossing fell before a resume's first window): an overload all the same,
        // at the sample's F and T. The sampler's hold is never lifted by the period's cap.
        if let Some((f_n, t_nm)) = self.tripped.take() {
            if out.state == AcState::Run && self.applied() && self.ctl.judging() {
                // The DRR waits for the next sample to tell a spike from load (a channel at its
                // rail): the alarm is the next period's, and the sampler's hold stays meanwhile.
                self.tripped = Some((f_n, t_nm));
                out.feed_cap = 0;
            } else if out.state == AcState::Run && self.applied() {
                let s = self.ctl.settings();
                let a = crate::ac::Alarm::Overload {
                    f_n,
                    t_nm,
                    f0_n: s.f0_n(),
                    t0_nm: s.t0_nm(),
                    force_limit_n: s.force_limit_n,
                    torque_limit_nm: s.torque_limit_nm,
                    e: crate::ac::ecr::errors(f_n, t_nm, s.f0_n(), s.t0_nm()).e,
                };
                if self.ctl.hold(a) {
                    held(&mut out, a, &self.ctl);
                }
            }
        }
        if let Some(b) = self.breakage.as_mut().and_then(|m| m.pending.take()) {
            // Over any other hold (the broken tooth's doubled chip may have made an overload
            // first): the alarm the operator sees is the breakage, and the spindle stops.
            let a = crate::ac::Alarm::ToolBreakage(b);
            self.ctl.hold_over(a);
            held(&mut out, a, &self.ctl);
            if self.applied() {
                status.ask_spindle_stop();
            }
        }
        if let Some(s) = self.chatter.take() {
            let a = crate::ac::Alarm::Chatter {
                freq_hz: s.peak_hz,
                amplitude: s.peak_amplitude,
                threshold: s.threshold,
            };
            if self.ctl.hold(a) {
                status.set_chatter_hz(s.peak_hz);
                held(&mut out, a, &self.ctl);
            }
        }
        status.set_state(match out.state {
            AcState::Run => AC_RUN,
            AcState::Hold(a) => crate::protocol::codes::ac_alarm(&a),
        });
        status.set_measured(out.f_n, out.t_nm);
        if self.applied() {
            publish(status, out.feed_cap, self.ctl.settings());
        }
        let held = matches!(out.state, AcState::Hold(_));
        self.still = if held && enc == self.last {
            self.still.saturating_add(1)
        } else {
            0
        };
        self.last = enc;
        Period {
            out,
            encoder: enc,
            // Only a hold that is applied stops the machine (measure-only runs keep going).
            halt: self.applied() && held && self.still >= HOLD_EXIT_PERIODS,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ac::{AcSettings, Alarm};
    use crate::rt::Status;

    /// The feed notices at a small tool's feeds: a constant feed of 6.5 or 2.5 BLU per period
    /// (the periods' motions alternate by a pulse) raises none, a step from 7 to 3 BLU per
    /// period (4.2 to 1.8 ipm at 0.0001 in) and back raises one each way, and a ramp of a pulse
    /// per period at 1500 rpm (4 periods a revolution) is a ramp.
    #[test]
    fn feed_notices_see_a_small_tools_feed_steps_and_not_its_pulses() {
        let run = |motions: &[i32]| {
            let mut n = FeedNotice::new();
            let mut at = 0;
            motions
                .iter()
                .map(|&m| {
                    at += m;
                    n.period([at, 0, 0], 1500, 10).is_some()
                })
                .collect::<Vec<_>>()
        };
        let steady = |a: i32, b: i32| -> Vec<i32> {
            (0..40).map(|k| if k % 2 == 0 { a } else { b }).collect()
        };
        for motions in [steady(6, 7), steady(2, 3)] {
            let told = run(&motions);
            assert!(told[8..].iter().all(|&t| !t), "{motions:?}: {told:?}");
        }
        let step: Vec<i32> = [[7; 12], [3; 12], [7; 12]].concat();
        let told = run(&step);
        assert!(told[12] && told[24], "{told:?}");
        assert!(!told[8..12].iter().any(|&t| t), "{told:?}");
        let ramp: Vec<i32> = (0..20).map(|k| 2 + k / 2).collect();
        let told = run(&[vec![2; 12], ramp].concat());
        assert!(told[20..].iter().any(|&t| t), "{told:?}");
    }

    /// An ADC that converts mid-scale codes until `miss_from`, then misses every conversion, and
    /// is gone from `lost_from` on.
    struct Adc {
        miss_from: u32,
        lost_from: u32,
    }

    impl ForceTorqueAdc for Adc {
        fn sample(&mut self, index: u32, _encoder: [i32; 3]) -> Conversion {
            if index >= self.lost_from {
                Conversion::Lost
            } else if index >= self.miss_from {
                Conversion::Missed
            } else {
                let d = [0, 3, 0, 5][index as usize % 4];
                Conversion::Fresh([2048 + d, 2048 - d, 2048 + d])
            }
        }
    }

    /// A dropout: the sample clock goes on, periods stay due, the first period without a fresh
    /// sample holds with NoSamples (cap 0); a lost ADC is said once and then counts like missed
    /// conversions, and with nothing moving the hold ends the run after HOLD_EXIT_PERIODS.
    #[test]
    fn missed_conversions_keep_the_clock_and_hold_with_no_samples() {
        let status = Status::new();
        let w = status.split();
        let ctl = AcController::new(AcSettings::default().validated().unwrap());
        let mut period = AcPeriod::new(ctl, Settings::default(), true, &w.ac);
        let per = period.per_period();
        let mut adc = Adc {
            miss_from: 2 * per,
            lost_from: 5 * per,
        };
        let mut states = [None; 5];
        for p in 0..5 {
            for k in 0..per {
                let Sampled::Codes { codes, due, .. } = sample(&mut adc, &w.sampler, per, None)
                else {
                    panic!("lost before its time");
                };
                let i = p * per + k;
                assert_eq!(codes.is_some(), i < 2 * per, "sample {i}");
                assert_eq!(due, (k + 1 == per).then_some(i + 1), "sample {i}");
                if let Some(c) = codes {
                    period.sample(c, &w.ac);
                }
            }
            let out = period.run(&w.ac);
            states[p as usize] = Some((out.out.state, out.out.alarm, status.feed_cap.get()));
        }
        assert_eq!(status.samples.get(), 5 * per);
        for s in &states[..2] {
            assert!(
                matches!(s, Some((AcState::Run, None, cap)) if *cap > 0),
                "{s:?}"
            );
        }
        assert_eq!(
            states[2],
            Some((AcState::Hold(Alarm::NoSamples), Some(Alarm::NoSamples), 0))
        );
        assert!(matches!(
            states[4],
            Some((AcState::Hold(Alarm::NoSamples), None, 0))
        ));
        // Lost: said, counted, periods still due; the hold goes on and, the encoder still, ends
        // the run after HOLD_EXIT_PERIODS periods.
        let mut halted = None;
        for p in 5..(6 + HOLD_EXIT_PERIODS) {
            for k in 0..per {
                let due = match sample(&mut adc, &w.sampler, per, None) {
                    Sampled::Lost { due } => due,
                    s => panic!("sample {}: {s:?}", p * per + k),
                };
                assert_eq!(due, (k + 1 == per).then_some(p * per + k + 1));
            }
            let out = period.run(&w.ac);
            assert_eq!(out.out.state, AcState::Hold(Alarm::NoSamples));
            assert_eq!(status.feed_cap.get(), 0);
            if out.halt {
                halted = Some(p);
                break;
            }
        }
        assert_eq!(status.samples.get() % per, 0);
        // Held from period 2 on (the encoder never moved): the HOLD_EXIT_PERIODS-th held period.
        assert_eq!(halted, Some(2 + HOLD_EXIT_PERIODS - 1));
    }

    /// One period's window of mid-scale codes (as the `Adc` above converts).
    fn mid_scale_window(period: &mut AcPeriod, status: &AcWriter) {
        for k in 0..period.per_period() {
            let d = [0, 3, 0, 5][k as usize % 4];
            period.sample([2048 + d, 2048 - d, 2048 + d], status);
        }
    }

    /// Runs `periods` AC periods on mid-scale codes with the encoder advancing as the frame would
    /// at the AC's cap times the operator's factor; returns the last cap.
    fn cap_under_override(factor_q8: u32, periods: u32) -> u32 {
        let status = Status::new();
        let w = status.split();
        w.loader.set_operator(factor_q8);
        let nc = Settings::default();
        let ctl = AcController::new(AcSettings::default().validated().unwrap());
        let mut period = AcPeriod::new(ctl, nc, true, &w.ac);
        let period_ms = period.ctl.settings().period_ms as u64;
        let mut x = 0u64;
        for _ in 0..periods {
            mid_scale_window(&mut period, &w.ac);
            let cap = status.feed_cap.get() as u64;
            // BLU per period at feed number cap * factor: W0 f / q0 per second.
            x += cap * factor_q8 as u64 / 256 * nc.frame_hz as u64 * period_ms
                / (nc.q0 as u64 * 1000);
            w.pulse.set_encoder([x as i32, 0, 0]);
            period.run(&w.ac);
        }
        status.feed_cap.get()
    }

    /// The anti-windup input is taken in programmed-feed units: under a 50 % override the cap
    /// climbs as it does at 100 % (with the achieved feed as it is it would stay near f_min).
    #[test]
    fn an_override_does_not_pull_the_ac_cap_down() {
        let full = cap_under_override(256, 300);
        let half = cap_under_override(128, 300);
        let tenth = cap_under_override(26, 300);
        let f_min = AcSettings::default().f_min;
        assert!(full > 4 * f_min, "cap at 100 %: {full}");
        for cap in [half, tenth] {
            assert!(
                cap.abs_diff(full) * 20 <= full,
                "{cap} against {full} at 100 %"
            );
        }
        assert_eq!(unscale_override(1000, 128), 2000);
        assert_eq!(unscale_override(1000, 0), 1000);
    }

    /// The operator's resume (`Status::ac_resume`) takes the AC out of its hold at the next period,
    /// from f_min; the status words say hold, then run.
    #[test]
    fn the_operator_resumes_an_ac_hold() {
        let status = Status::new();
        let w = status.split();
        let ctl = AcController::new(AcSettings::default().validated().unwrap());
        let mut period = AcPeriod::new(ctl, Settings::default(), true, &w.ac);
        // A period without samples holds.
        let out = period.run(&w.ac);
        assert_eq!(out.out.state, AcState::Hold(Alarm::NoSamples));
        assert_eq!(
            status.ac_state.get(),
            crate::protocol::codes::alarm::AC_NO_SAMPLES
        );
        assert_eq!(status.feed_cap.get(), 0);
        // Still held with samples again, until the operator resumes.
        mid_scale_window(&mut period, &w.ac);
        assert!(matches!(period.run(&w.ac).out.state, AcState::Hold(_)));
        w.loader.ask_resume();
        mid_scale_window(&mut period, &w.ac);
        let out = period.run(&w.ac);
        assert_eq!(out.out.state, AcState::Run);
        assert!(!status.ac_resume.pending(), "the request is taken");
        assert_eq!(status.ac_state.get(), AC_RUN);
        let cap = status.feed_cap.get();
        let s = AcSettings::default();
        // From f_min, at most one FRC step up in this period.
        let most = s.f_min as f32 + s.step_per_period() + 1.0;
        assert!(
            cap > 0 && cap as f32 <= most,
            "resumed at {cap}, most {most}"
        );
    }

    /// Codes of a force `f_n` on Fu alone with the torque that agrees with it (F*R/T = 1 at the
    /// default 6.35 mm radius), at the default calibration.
    fn cut_codes(f_n: f32) -> Codes {
        let s = AcSettings::default();
        let code = |c: crate::ac::Calibration, v: f32| (c.offset + v / c.gain).round() as u16;
        [
            code(s.cal[0], f_n * s.tool_radius_mm / 1000.0),
            code(s.cal[1], f_n),
            code(s.cal[2], 0.0),
        ]
    }

    /// An ADC that reads a cut at `f_n` from sample `at` on (no load before).
    struct Step {
        at: u32,
        f_n: f32,
    }

    impl ForceTorqueAdc for Step {
        fn sample(&mut self, index: u32, _encoder: [i32; 3]) -> Conversion {
            Conversion::Fresh(cut_codes(if index >= self.at { self.f_n } else { 0.0 }))
        }
    }

    /// The sampler's trip: the first sample above the overload hold's level (1.1 F0 at the
    /// defaults) stores a feed cap of 0 at once, within the AC period, not at its end; a cut
    /// just below the level does not. The AC period then holds with the overload at that
    /// sample's force, and keeps the hold. Without the trip the cap stayed until the period.
    #[test]
    fn the_sampler_holds_on_the_first_sample_over_the_level() {
        let s = AcSettings::default();
        let trip = Trip::new(&s);
        let level = 1.1 * s.f0_n();
        for (f_n, trips) in [(0.98 * level, false), (1.02 * level, true)] {
            let status = Status::new();
            let w = status.split();
            let ctl = AcController::new(s.validated().unwrap());
            let mut period = AcPeriod::new(ctl, Settings::default(), true, &w.ac);
            let cap = status.feed_cap.get();
            assert!(cap > 0);
            let mut adc = Step { at: 3, f_n };
            let per = period.per_period();
            for i in 0..per {
                if let Sampled::Codes { codes: Some(c), .. } =
                    sample(&mut adc, &w.sampler, per, Some(&trip))
                {
                    period.sample(c, &w.ac);
                }
                let now = status.feed_cap.get();
                if i >= 3 && trips {
                    assert_eq!(now, 0, "{f_n} N: not held at sample {i}");
                } else {
                    assert_eq!(now, cap, "{f_n} N: held at sample {i}");
                }
            }
            let out = period.run(&w.ac).out;
            if trips {
                assert!(
                    matches!(out.alarm, Some(Alarm::Overload { f_n: f, .. }) if f > level),
                    "{out:?}"
                );
                assert_eq!(status.feed_cap.get(), 0);
            } else {
                assert_eq!(out.alarm, None);
            }
        }
    }

    /// An M6 brings the fitted tool's limits to the sampler's trip and to the AC period: a 400 N
    /// cut runs under the machine's tool (4000 N), and holds at once with the 3 mm end mill
    /// fitted (226 N: the trip at the first sample, the period's overload naming its limit);
    /// a tool without limits releases the cap and is measured only (its holds stop nothing).
    #[test]
    fn an_m6_brings_the_tools_limits_to_the_trip_and_the_period() {
        use crate::ac::strength::{derived, Strength};
        use crate::gcode::tools::ToolKind;
        use crate::rt::status::FittedTool;
        let s = AcSettings {
            breakage: crate::ac::Breakage::Auto,
            ..AcSettings::default()
        }
        .validated()
        .unwrap();
        let status = Status::new();
        let w = status.split();
        let mut period = AcPeriod::new(AcController::new(s), Settings::default(), true, &w.ac);
        let mut trip = ToolTrip::new(s);
        let per = period.per_period();
        let mut adc = Step { at: 0, f_n: 400.0 };
        let mut run = |period: &mut AcPeriod, trip: &mut ToolTrip| {
            let mut held_at = None;
            for i in 0..per {
                let t = trip.follow(&status);
                if let Sampled::Codes { codes: Some(c), .. } = sample(&mut adc, &w.sampler, per, t)
                {
                    period.sample(c, &w.ac);
                }
                if status.feed_cap.get() == 0 {
                    held_at.get_or_insert(i);
                }
            }
            (held_at, period.run(&w.ac))
        };
        let (held, p) = run(&mut period, &mut trip);
        assert_eq!((held, p.out.alarm), (None, None), "the machine's tool");
        // `$268` auto: no breakage monitor for the machine's own tool...
        assert!(period.breakage().is_none());
        let small = derived(ToolKind::Flat, 3.0, &Strength::HSS).unwrap();
        w.loader.set_tool(&FittedTool {
            number: 2,
            flutes: 2,
            radius_mm: 1.5,
            kind: ToolKind::Flat,
            limits: Some(small),
        });
        let (held, p) = run(&mut period, &mut trip);
        assert_eq!(held, Some(0), "the trip at the first sample");
        match p.out.alarm {
            Some(Alarm::Overload { force_limit_n, .. }) => {
                assert_eq!(force_limit_n, small.force_n)
            }
            a => panic!("{a:?}"),
        }
        assert_eq!(period.ctl.settings().flutes, 2);
        // ...one for a tool whose flutes the table gives...
        assert!(period.breakage().is_some(), "auto: on for T2's two flutes");
        // The force/torque plausibility's lever is the small tool's radius: its F R / T is 1
        // where the machine's 6.35 mm would make it 4.2, a sensor fault.
        assert_eq!(period.ctl.settings().tool_radius_mm, 1.5);
        w.loader.set_tool(&FittedTool {
            number: 3,
            flutes: 0,
            radius_mm: 0.0,
            kind: ToolKind::Flat,
            limits: None,
        });
        for _ in 0..2 * HOLD_EXIT_PERIODS {
            let (held, p) = run(&mut period, &mut trip);
            // ...and none for one whose flutes nobody gave.
            assert!(
                period.breakage().is_none(),
                "auto: off for T3, flutes unknown"
            );
            assert_eq!(held, None, "no trip without limits");
            assert!(!p.halt);
            assert_eq!(status.feed_cap.get(), u32::MAX, "the cap is released");
        }
    }

    /// A cut with Fu 3000 N, Fv -2000 N (F 3606 N, below the trip) and T 30.5 N*m, whose Fu
    /// spikes to its upper rail at sample `at` only.
    struct RailSpike {
        at: u32,
    }

    impl RailSpike {
        fn base() -> Codes {
            let s = AcSettings::default();
            let code = |c: crate::ac::Calibration, v: f32| (c.offset + v / c.gain).round() as u16;
            [
                code(s.cal[0], 30.5),
                code(s.cal[1], 3000.0),
                code(s.cal[2], -2000.0),
            ]
        }
    }

    impl ForceTorqueAdc for RailSpike {
        fn sample(&mut self, index: u32, _encoder: [i32; 3]) -> Conversion {
            let mut c = Self::base();
            if index == self.at {
                c[1] = crate::ac::CODE_MAX;
            }
            Conversion::Fresh(c)
        }
    }

    /// A Fu spike to its rail as the last sample of a period: 850 codes from the rail (no jump
    /// by size), F*R/T 1.14 and a force step the torque's noise and the holder's turn could
    /// explain, but a saturated code is a bound, not a value. The sampler trips at once (F reads
    /// 5490 N); the period does not call it an overload while the DRR waits for the next sample,
    /// and keeps the cap at 0; the next period holds with the spike's sensor fault. Before, the
    /// period made the trip an overload (alarm 100, which `~` resumes) at once.
    #[test]
    fn a_spike_to_the_rail_at_a_periods_end_is_told_by_the_next_sample() {
        let s = AcSettings::default();
        let trip = Trip::new(&s);
        let status = Status::new();
        let w = status.split();
        let ctl = AcController::new(s.validated().unwrap());
        let mut period = AcPeriod::new(ctl, Settings::default(), true, &w.ac);
        let per = period.per_period();
        let mut adc = RailSpike { at: 2 * per - 1 };
        let mut outs = Vec::new();
        for _ in 0..3 {
            for _ in 0..per {
                if let Sampled::Codes { codes: Some(c), .. } =
                    sample(&mut adc, &w.sampler, per, Some(&trip))
                {
                    period.sample(c, &w.ac);
                }
            }
            let out = period.run(&w.ac).out;
            outs.push((out.state, out.alarm, status.feed_cap.get()));
        }
        assert!(
            matches!(outs[0], (AcState::Run, None, cap) if cap > 0),
            "{outs:?}"
        );
        assert_eq!(outs[1], (AcState::Run, None, 0), "{outs:?}");
        let want = Alarm::Sensor(crate::ac::SensorFault::Jump {
            sensor: crate::ac::Sensor::ForceU,
            from: RailSpike::base()[1],
            to: crate::ac::CODE_MAX,
        });
        assert_eq!(outs[2], (AcState::Hold(want), Some(want), 0), "{outs:?}");
    }

    /// An enabled AC period under the plan (`FeedCeiling::Plan`, the other settings the
    /// defaults) on a started `status`, with its settings.
    fn under_the_plan(status: &AcWriter) -> (AcSettings, AcPeriod) {
        let s = AcSettings {
            ceiling: crate::ac::FeedCeiling::Plan,
            ..AcSettings::default()
        };
        let ctl = AcController::new(s.validated().unwrap());
        (s, AcPeriod::new(ctl, Settings::default(), true, status))
    }

    /// Under the plan a hold stores its cap of 0 and leaves the plan ratio as it was: the frame,
    /// which may run between the AC period's two stores, never feeds the running cap at another
    /// ratio (it would if the hold stored the ratio 1 first).
    #[test]
    fn a_hold_under_the_plan_keeps_the_plan_ratio() {
        let status = Status::new();
        let w = status.split();
        let (s, mut period) = under_the_plan(&w.ac);
        let k = status.plan_ratio.get();
        assert!(k > 0 && k < crate::ports::PLAN_ONE, "{k}");
        assert_eq!(status.feed_cap.get(), s.f_max);
        // A period without samples holds: the cap goes to 0, the ratio stays.
        let out = period.run(&w.ac);
        assert_eq!(out.out.state, AcState::Hold(Alarm::NoSamples));
        assert_eq!(status.feed_cap.get(), 0);
        assert_eq!(status.plan_ratio.get(), k);
        // The resume publishes the ratio with the cap again.
        w.loader.ask_resume();
        mid_scale_window(&mut period, &w.ac);
        assert_eq!(period.run(&w.ac).out.state, AcState::Run);
        assert_eq!(status.feed_cap.get(), s.f_max);
        assert_eq!(status.plan_ratio.get(), k);
    }

    /// The loader's job end (`Status::ac_new_job`: M2/M30 once run, or a soft reset) restarts
    /// the plan: the next period publishes k = PLAN_START again, whatever the job learnt.
    #[test]
    fn a_job_end_restarts_the_plan_ratio() {
        let status = Status::new();
        let w = status.split();
        let (s, mut period) = under_the_plan(&w.ac);
        let start = status.plan_ratio.get();
        // A cut at 0.94 F0 under k = PLAN_START: the first contact raises k.
        let load = 0.94 * s.f0_n();
        let mut n = 0;
        assert_eq!(
            cut_revolutions(&mut period, &w.ac, 3, [load; 4], &mut n),
            None
        );
        let learnt = status.plan_ratio.get();
        assert!(learnt > start, "{learnt} {start}");
        // The job ends; the next period (still the same cut) starts from PLAN_START again.
        w.loader.ask_new_job();
        for _ in 0..10 {
            period.sample([2048; 3], &w.ac);
        }
        period.run(&w.ac);
        assert_eq!(status.plan_ratio.get(), start);
        assert!(!status.ac_new_job.pending());
    }

    /// `revs` spindle revolutions (600 rpm, 4 flutes: 25 samples a tooth at 1 kHz) of a cut whose
    /// tooth k makes `loads[k]` N (on Fu, the torque to match on the default 0.5 in cutter, a
    /// +-2 code dither), through the AC period; returns the first alarm and its period.
    fn cut_revolutions(
        period: &mut AcPeriod,
        status: &AcWriter,
        revs: u32,
        loads: [f32; 4],
        from_period: &mut u32,
    ) -> Option<(u32, Alarm)> {
        let s = AcSettings::default();
        let code = |v: f32, gain: f32, d: f32| (2048.0 + v / gain + d).round() as u16;
        let mut first = None;
        for i in 0..revs * 100 {
            let f = loads[(i / 25 % 4) as usize];
            let d = [0.0, 2.0, 0.0, -2.0][(i % 4) as usize];
            let t = f * s.tool_radius_mm * 1e-3;
            period.sample(
                [
                    code(t, s.cal[0].gain, d),
                    code(f, s.cal[1].gain, d),
                    code(0.0, s.cal[2].gain, -d),
                ],
                status,
            );
            if i % 10 == 9 {
                let out = period.run(status);
                *from_period += 1;
                if first.is_none() {
                    first = out.out.alarm.map(|a| (*from_period, a));
                }
            }
        }
        first
    }

    /// `$268=1`: the AC period feeds every sample's force to the breakage detector; a sound tool
    /// with run-out cuts on; a broken tooth (its chip taken by the next) holds the feed with
    /// `Alarm::ToolBreakage` (`ALARM:108`) within two revolutions and asks the loader to stop the
    /// spindle; the operator's resume restarts the detector. With `$268=0` the same break cuts on.
    #[test]
    fn a_broken_tooth_holds_the_feed_and_stops_the_spindle() {
        let sound = [1050.0, 980.0, 1030.0, 950.0];
        let broken = [1050.0, 0.0, 2010.0, 950.0];
        for on in [true, false] {
            let status = Status::new();
            let w = status.split();
            let s = AcSettings {
                breakage: if on {
                    crate::ac::Breakage::On
                } else {
                    crate::ac::Breakage::Off
                },
                ..AcSettings::default()
            }
            .validated()
            .unwrap();
            let ctl = AcController::new(s);
            let mut period = AcPeriod::new(ctl, Settings::default(), true, &w.ac).with_monitors(&s);
            assert_eq!(period.breakage().is_some(), on);
            let mut n = 0;
            let early = cut_revolutions(&mut period, &w.ac, 40, sound, &mut n);
            assert_eq!(early, None, "sound tool");
            let broke_at = n;
            let hold = cut_revolutions(&mut period, &w.ac, 5, broken, &mut n);
            if !on {
                assert_eq!(hold, None);
                assert!(!status.spindle_stop.pending());
                continue;
            }
            let Some((at, Alarm::ToolBreakage(b))) = hold else {
                panic!("{hold:?}");
            };
            // Two revolutions are 20 periods; the hold acts in the period after the declaration.
            assert!(
                at - broke_at <= 21,
                "held {} periods after the break",
                at - broke_at
            );
            assert!(b.e1.abs() > b.th1 && b.e2.abs() > b.th2, "{b}");
            assert!(status.spindle_stop.pending());
            assert_eq!(
                status.ac_state.get(),
                crate::protocol::codes::alarm::AC_BREAKAGE
            );
            assert_eq!(status.feed_cap.get(), 0);
            // The operator resumes (a new tool): the detector starts afresh and learns again.
            w.loader.ask_resume();
            w.loader.take_spindle_stop();
            let again = cut_revolutions(&mut period, &w.ac, 40, sound, &mut n);
            assert_eq!(again, None);
            assert_eq!(status.ac_state.get(), AC_RUN);
            // The new tool breaks while another hold stands (a period without samples): the
            // breakage replaces it, is said, and stops the spindle.
            let held = period.run(&w.ac);
            assert_eq!(held.out.alarm, Some(Alarm::NoSamples));
            let second = cut_revolutions(&mut period, &w.ac, 5, broken, &mut n);
            assert!(
                matches!(second, Some((_, Alarm::ToolBreakage(_)))),
                "{second:?}"
            );
            assert!(status.spindle_stop.pending());
        }
    }
}
