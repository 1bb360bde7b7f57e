//! Tool breakage detection (Munasinghe 1994, section 3.2, Eqs. 3.43-3.49) for the AC/monitoring
//! task: [`BreakageDetector::sample`] every ADC sample (1 kHz), and inside it, once per tooth
//! period, [`BreakageDetector::tooth_period`] (also callable directly with an average force).
//!
//! # Algorithm
//! 1. **Average force per tooth period** Fa(j). The thesis averages the fixed-frame components
//!    Fx, Fy over a tooth period and takes the magnitude (Eqs. 3.43-3.45). millac's transducer
//!    measures Fu, Fv in the *rotating* holder frame, whose components turn with the spindle and
//!    would partly cancel in a component average; the magnitude F = sqrt(Fu^2 + Fv^2) is the same
//!    in every frame, so the detector averages F per sample instead (the DRR already forms it).
//!    This is the mean of |F|, not |mean F|: both are constant in a steady cut and both move with
//!    the load of each tooth, which is all the differences below use.
//! 2. **Tooth period** = 60 / (rpm x z) s, told by [`BreakageDetector::set_spindle`]. A phase
//!    accumulator in Q16 samples (u32: one sample = 65536) adds one sample per call and closes a
//!    tooth period when it passes the period, keeping the remainder: non-integer periods (24.6
//!    samples) alternate 24- and 25-sample averages whose mean period is exact, with no drift and
//!    no floating-point accumulation. There is no spindle index: the average over any window one
//!    tooth period long removes the tooth-pass pulse shape whatever its phase; the phase only
//!    mixes neighbouring teeth, which the run-out filter sees as part of the per-revolution
//!    pattern.
//! 3. **First differences** dFa(j) = Fa(j) - Fa(j-1) through a first-order adaptive filter
//!    e1(j) = dFa(j) - phi1 dFa(j-1) (Eq. 3.47): removes slow geometric transients.
//!    **Once-per-revolution differences** dmFa(j) = Fa(j) - Fa(j-m), m = flutes, through a second
//!    filter e2(j) = dmFa(j) - phi2 dmFa(j-1) (Eqs. 3.48-3.49): removes the run-out pattern.
//!    Both phi by exponentially weighted least squares (EWLS), phi = sum lambda^k x(j-k) x(j-k-1)
//!    / sum lambda^k x(j-k-1)^2, updated every tooth period *after* the residual is formed (a
//!    priori residuals: a break is judged against the model of the cut before it), clamped to
//!    [-1, 1] (a stable filter; a NaN estimate is dropped).
//! 4. **Thresholds and decision**: see [`ThresholdMode`]. [`ThresholdMode::Thesis`] is the
//!    thesis' rule as written; [`ThresholdMode::Adaptive`] (default) is the firmware's.
//! 5. **Air and idle**: no decisions while the spindle is unknown or in air: Fa below
//!    `air_floor_n` for a whole revolution (m tooth periods; a single low period inside a cut is
//!    what a fully broken tooth that cuts alone looks like, and is judged). A cut starts at the
//!    first Fa above the floor; every return to the cut from air (or a spindle change, or a
//!    reset) restarts the filters and the learning. A non-finite Fa (a tooth period without a
//!    valid sample) restarts at once.
//!
//! Cost: per sample one finite check, a clamp, an f32 add and a u32 add and compare (the caller
//! passes F, which the DRR already computes); per tooth period about 50 f32 operations, no
//! square root, one division and an m-term sum, the chip-transfer test's ten more (no
//! division), and while a curvature episode is open about 20 more, four divisions and two
//! m-term sums (host, steady cut: ~8 ns per sample, ~10 ns per tooth period,
//! `cost_on_the_host`), and one store of the force into a ring of [`REV_RING`] samples for
//! the sampler trip's signature (judged at a trip only). State: the ring's 1 KiB and 576 bytes on the host
//! (`state_size`), most of the rest the per-tooth
//! suspicion ring, the quiet pattern and the episode's curvatures (the chip-transfer test's two
//! once-per-revolution differences took the place of dFa(j-1), which is Fa(j-1) - Fa(j-2)
//! from the two forces kept anyway, and of a u32 for the flutes, now a u8).
//!
//! # Measured on the simulated plant (`qemu/tests/breakage.rs`, defaults, 600 rpm, 4 flutes)
//! - False alarms with a sound tool: none over the Fig. 1 cavity (58 s) and the pocket (18 s),
//!   run-out 5/0/-3/0 um at the programmed feeds and with the AC (told of feed steps as the AC
//!   period tells it), 10/0/-6/0 um at the programmed feeds; with the AC and the thesis' servo
//!   drives, whose corners the AC recovers from over several revolutions (told as a feed ramp,
//!   `crate::rt::ac::FEED_RAMP_PCT`; before, a false breakage 0.3 s after the cavity's corner at
//!   19.07 s).
//! - Broken tooth (tooth 0 and 1 at 15, 30, ... 90 % of the machining time where the cut is
//!   above 1000 N, programmed feeds), delay in revolutions, tooth 0 / tooth 1, with the plant's
//!   causal breakage (the next tooth's doubled chip a tooth period after the break,
//!   `millac_plant::teeth`): cavity 8.70 s 0.71 / 1.21, 17.41 s 1.43 / 1.93, 26.11 s 1.39 /
//!   1.39, 43.52 s 1.07 / 1.32; pocket 5.46 s 1.44 / 1.69, 8.18 s 1.92 / 1.42, 10.91 s 1.39 /
//!   1.64, 13.64 s 1.11 / 1.36 (the island's entry while learning, a miss with the static
//!   plant, whose doubled chip came in the sample of the break, before the loss), 16.37 s 1.58 /
//!   1.83 (the exit starts with the break). 18 of 18 within two revolutions, worst 1.93
//!   (history: 7 of 18 with the revolution confirmation alone, 12 with the curvature
//!   confirmation, 18 with the chip-transfer test, the curvature from the suspicion's own period
//!   on, its persistence rule and level guard 0.25; the rule of each is in the test's output).
//! - The same detector on further runs (not in the test, measured with the static plant, before
//!   its causal breakage):
//!   no false alarm over the cavity and the pocket with run-out 8/0/-5/0 and 0/6/0/-4 um at the
//!   programmed feeds and with the AC, and 3/2/-4/1 um with the AC; one over the cavity with
//!   3/2/-4/1 um at the programmed feeds (at 18.3 s, as before these rules: open). None on the
//!   breakage slot (with and without the AC), the pocket with the AC and a stiff mode, the
//!   depth-step slot and the TIIM step. Broken teeth 0..3 at 12.5, 17.5, ... 92.5 % of the
//!   machining time (skipping every third, where the tooth was chipped by 0.03 mm instead):
//!   68 of 76 within two revolutions (before the changes that made the 18 above: 61). Not: cavity 10.15 s (the cut
//!   leaves for air within the revolution after the break: nothing left to see; detected or
//!   not at the next entries), pocket 3.18 s teeth 0, 1, 3 (4.5 revolutions after the pocket's
//!   first entry, still learning; the extra chip spreads over the two periods after the
//!   dip, so the chip-transfer test's flanks differ by more than half the jump; open), and
//!   cavity 44.97 s tooth 3 (2.05).
//!
//! Arithmetic is f32 with IEEE basic operations only per sample and per tooth period
//! (`libm::exp2f` once per spindle change), the same bits on host and target. No input (NaN,
//! infinities, huge values, rpm 0) panics: samples are clamped to [0, `FORCE_MAX_N`], non-finite
//! samples are skipped, a tooth period without a valid sample counts as air.

use core::fmt;

use crate::settings::Valid;

/// Most flutes the detector handles (the size of its per-tooth rings: end mills for die sinking
/// have 2 to 8; each flute more costs 32 bytes of state).
pub const MAX_FLUTES: usize = 8;
/// A change of the feed the AC period saw ([`BreakageDetector::feed_step`]): a step (a corner,
/// a hold, the AC's own step) or a ramp (the AC's recovery after a corner, or its regulation
/// moving a small tool's feed by up to 30 % a period, revolution by revolution).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FeedChange {
    /// The smaller of the two motions compared (one AC period's and the last's, or a
    /// revolution's and the one's before), as a percentage of the larger (0..=100).
    pub kept_pct: u8,
    /// The newer motion is the larger: the feed rose.
    pub up: bool,
    /// A step or a ramp the detector does not judge through (see
    /// [`BreakageDetector::feed_step`]); else a smaller change it only records for the sampler
    /// trip's verdict ([`BreakageDetector::chip_moved`]).
    pub hold: bool,
}

/// Tooth periods whose feed notices the detector remembers for the sampler trip's verdict
/// ([`BreakageDetector::chip_moved`]): the revolution before a loss, the loss's period and the
/// one after it, at the most flutes.
const NOTICES: usize = MAX_FLUTES + 2;
/// How much more of a tooth period's force than the feed step's share a loss the step explains
/// may be ([`BreakageDetector::chip_moved`]): the tooth periods' scatter.
pub const FEED_LOSS_TOL: f32 = 0.1;
/// Largest force a sample may contribute, in N (larger finite values are clamped to it).
pub const FORCE_MAX_N: f32 = 1.0e7;
/// Tooth periods shorter than this many samples are refused (no average is meaningful).
pub const PERIOD_MIN_SAMPLES: f32 = 4.0;
/// Tooth periods longer than this many samples are refused (Q16 range of the accumulator).
pub const PERIOD_MAX_SAMPLES: f32 = 60_000.0;
const Q16: u32 = 1 << 16;
/// Chip-transfer test (Adaptive mode, see [`ThresholdMode::Adaptive`]): the smallest jump
/// dmFa(s+1) - dmFa(s), as a fraction of the level L. A broken tooth that loses a share c of
/// its tooth period's force to the next tooth makes a jump of about 2c L, so this is a loss of
/// a quarter or more: the large breaks, which the test decides within the revolution of the
/// break; smaller chips are left to the confirmations, which see down to 5 %. The jump must
/// also stand above the once-per-revolution threshold th2 the cut taught (its own noise): on a
/// light, noisy cut (a helical entry's clean-up circle, where the wedge's chip fades to nothing
/// at about 70 N, tooth periods scattering by 15 N) the flanks and the pair matched by chance
/// once in 1300 tooth periods, a jump of 0.52 L against a th2 of 0.70 L.
pub const TRANSFER_MIN: f32 = 0.5;
/// Chip-transfer test: the suspected period's own loss, dmFa(s-1) - dmFa(s), at least this
/// fraction of the jump. A broken tooth's period loses its chip against the revolution's change
/// just before it (half the jump when the tooth periods fit the tooth passes; measured on the
/// simulated plant's breaks, `qemu/tests/breakage.rs` and `breaks_under_ac`, 0.23 to 0.92). A
/// staircase of force steps about a revolution apart (a small end mill entering a corner, the
/// engagement growing cell row by cell row) can meet the three tolerances of [`TRANSFER_TOL`]
/// with the jump made by the next step alone: the Fig. 1 job's 6 mm corner end mill under QEMU,
/// with its tooth periods started 0 to 37 samples after its S (over two tooth periods of
/// phases), at 5 of the 38 starts, a loss of 0.06 and a false breakage. (On the host's run the
/// losses were 0.19 to 0.28: [`TRANSFER_RISE`] rejects those.) Without a rise, a jump with
/// a small loss also fails the pair's or the flanks' tolerance unless the period before fell:
/// `a_jump_after_a_period_that_lost_nothing_is_not_a_chip_transfer`.
pub const TRANSFER_LOSS: f32 = 0.15;
/// Chip-transfer test: how far the cut's own change per revolution (the flanks' mean) may rise,
/// as a fraction of the jump (it may fall by up to [`TRANSFER_TOL`]). A broken tooth's doubled
/// chip raises the peak and the AC lowers the feed in the revolutions after: a falling trend is
/// the break's own consequence (the simulated plant's breaks under the AC, `breaks_under_ac`:
/// falling by 0.13 to 0.37 of the jump), while a break in a steady cut or on an entry's ramp
/// rises by 0.09 at most. A cut rising faster is a corner entry's staircase (the Fig. 1 job's
/// corner end mill: 0.29 to 0.46 of the jump, with the other tolerances met); a break inside
/// it is left to the confirmations.
pub const TRANSFER_RISE: f32 = 0.2;
/// Chip-transfer test: how far the flanks dmFa(s-1), dmFa(s+2) may differ from each other, from
/// nil (their mean: the cut's own change per revolution), and the pair dmFa(s) + dmFa(s+1) from
/// the flanks' sum, each as a fraction of the jump. A chip moved from one tooth period to the
/// next gives 0 on all three (up to the window's split of a tooth pass), every geometric event
/// on one of them about 1 (a step: the flanks differ by the jump; a dip or a bump of up to a
/// revolution: the pair's sum differs by the jump; a ramp whose kinks make the jump: the flanks'
/// mean is about the jump or more), so the tolerance is the middle, 0.5.
pub const TRANSFER_TOL: f32 = 0.5;
/// Adaptive confirmation: how far the mean Fa of the revolution after the suspicion (j .. j+m-1)
/// may differ from the one before the *episode* (the revolution before the first of the
/// suspicions pending together: a break's transitional tooth pass, or a geometric transient
/// just before the suspicion, does not enter the reference), as a fraction of |dFa(j)|. A damaged tooth
/// leaves its chip to the next one, so the material per revolution, and the mean force, stay
/// (up to noise and the size effect); a corner, a hole, a ramp or a depth change move the mean
/// by about the step that made the suspicion.
pub const CONSERVE_FRACTION: f32 = 0.25;
/// The sampler trip's breakage signature ([`BreakageDetector::chip_moved`]): the smallest loss
/// of a tooth period's average force against the same tooth period a revolution before, as a
/// fraction of the level, in one of the two tooth periods before a crossing of the overload
/// level. A tooth that breaks loses most of its chip (with 4 flutes its pass is a quarter of the
/// revolution's force, so the tooth period holding it drops by up to the level; the periods are
/// not aligned with the teeth, so the loss may be split over two). Chosen on the simulated
/// plant (`qemu/tests/breakage.rs`): at 0.5, 4 of 24 breaks were classified; at 0.2, 14, and the
/// real overloads tried (the full-depth entry, the TIIM depth step) stay overloads.
pub const CHIP_MOVED_MIN: f32 = 0.2;
/// Samples of force kept for the sampler trip's per-sample comparison with the revolution before
/// ([`BreakageDetector::rev_loss`]): a revolution and two tooth periods of up to this many
/// samples (at 1 kHz with 4 flutes: 352 rpm and faster). Slower, the trip is judged by the tooth
/// periods alone.
pub const REV_RING: usize = 256;
/// The sampler trip's per-sample breakage signature ([`BreakageDetector::rev_loss`]): the
/// smallest loss of force against the same spindle angle a revolution before, averaged over
/// half a tooth period within the two tooth periods before the crossing, as a fraction of the
/// level. A broken tooth's missing pass loses about the level or more there wherever the tooth
/// periods' boundaries fall (0.75 .. 2.2 on the simulated plant's breaks the tooth-period test
/// missed); a real overload's rise loses nothing (the TIIM depth step: 0.01). Under the AC
/// (`breaks_under_ac --spread 10`): 229 of 240 broken teeth told, 10 held as overloads.
pub const REV_LOSS_MIN: f32 = 0.5;
/// Curvature confirmation: the smallest relative curvature judged (a chip of 7 % of a tooth's
/// load moved to the next tooth makes about 1.5 x 7 %).
pub const CURVATURE_MIN: f32 = 0.1;
/// Curvature confirmation: the local level must be at least this fraction of the quiet
/// pattern's (an exit's tail, where the pattern itself changes shape as the teeth leave the
/// cut, is not judged). On the simulated pocket a sound exit's tail, unguarded, bends the same
/// slot twice at 5 to 11 % of the pattern's level; a tooth broken as the exit starts is
/// confirmed at 45 %. A quarter sits between with a factor of about 2 each way. (It was 0.5
/// before [`CURVATURE_KEEP`]: then it also had to stop a transient's decaying bend, at 49 %
/// on a depth step of the cavity.)
pub const CURVATURE_LEVEL: f32 = 0.25;
/// Curvature confirmation: an episode closes this many revolutions after its first suspicion.
pub const CURVATURE_SPAN: u32 = 3;
/// Curvature confirmation: the second revolution's bend must be at least this fraction of the
/// first's (same slot, same sign). A broken tooth changes the per-tooth pattern for good, so its
/// bend stays or grows (as the level falls in an exit the relative bend grows); a geometric
/// transient that spans more than a revolution leaves a bend that decays (on the cavity's depth
/// step at 18.2 s with 10 um run-out: 0.28 then 0.12). It was 0.5 until a corner's
/// deceleration and the acceleration after it (the pocket under QEMU with the AC, 16.45 s: the
/// force dipped to a third for two tooth periods) bent the same slot at its two knees a
/// revolution apart, the second bend between 0.7 and 0.8 of the first, and were declared a
/// breakage (`tests::a_corners_dip_and_recovery_is_not_a_breakage`); the 18 breaks of the
/// cavity and the pocket are still confirmed within two revolutions at 0.8.
pub const CURVATURE_KEEP: f32 = 0.8;

/// How the thresholds on |e1| and |e2| are set and when a breakage is declared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ThresholdMode {
    /// The thesis: thresholds = `factor` x the largest |residual| of each filter over the first
    /// `learn_revs` revolutions of a cut, fixed thereafter; a breakage is declared in the first
    /// tooth period where both residuals exceed their thresholds. Fragile: a corner or a hole
    /// larger than the entry's transient is a false alarm, and a large entry transient blinds the
    /// detector for the rest of the cut.
    Thesis,
    /// The firmware's (default):
    /// - **learning over steady revolutions only**: a tooth period is steady when its
    ///   once-per-revolution change |dmFa(j)| is within the thresholds' floor (below it no
    ///   change can be judged anyway); any unsteady period during the learning (an entry, a
    ///   ramp, a corner) clears the maxima and restarts it, so the learning ends after
    ///   `learn_revs` consecutive steady revolutions. The thesis learns over the first
    ///   revolutions from the first contact, i.e. *across* the entry: on the simulated Fig. 1
    ///   cavity the full-slot entry (6 N -> 1700 N -> 4000 N in two tooth periods) left th1, th2 at
    ///   10500 N / 5050 N, which the decay (half-life 20 revolutions) had brought to only
    ///   3500 N / 1700 N 3.7 s later, when a broken tooth changed Fa by about +-1400 N. Learning
    ///   over the steady cut gives 340 N / 195 N there (the run-out residuals and the floor);
    /// - each threshold is `factor` x L x a running maximum M of |residual| / L, L the mean Fa of
    ///   the last revolution (run-out and noise residuals scale with the load: after a depth
    ///   change of 7x the absolute thresholds of the thesis sit inside the run-out). M decays with
    ///   a half-life of `decay_revs` revolutions and takes in only residuals within the threshold
    ///   (a violation does not raise its own threshold); a floor `floor_fraction` x L and
    ///   `min_threshold_n`. L is the revolution before the tooth period, so a break (which
    ///   conserves the mean, see (iii)) does not move it;
    /// - both residuals over their thresholds in the same tooth period, and the raw change
    ///   |dmFa(j)| over th2 as well (after a transient e2 rings with phi2 x dmFa(j-1) while nothing
    ///   changed), make a *suspicion* for that tooth (slot j mod m); M is frozen while any
    ///   suspicion is pending;
    /// - one revolution later, in the same slot, the suspicion is *confirmed* (breakage) when
    ///   (ii) |dmFa(j+m)| < th2 (the once-per-revolution pattern is stationary again: not a
    ///   ramp, not a transient; a broken tooth changes the per-tooth pattern for good: the
    ///   thesis' "persistently high residuals"), and (iii) the revolution's mean force is
    ///   conserved, |mean Fa(j..j+m-1) - R| <= [`CONSERVE_FRACTION`] x |dFa(j)|, R the mean of the
    ///   revolution before the *episode* (the first of the suspicions pending together): a damaged
    ///   tooth's chip goes to the next tooth, the material per revolution does not change, while
    ///   every geometric event changes it. Otherwise it is dropped. An entry or exit ramp whose
    ///   slope persists keeps dmFa at about m x the slope, so it fails (ii) whenever m >= 2; a
    ///   corner or a depth step fails (iii).
    ///
    ///   A former check (i), "the step repeats" |dFa(j+m) - dFa(j)| <= 0.5 |dFa(j)|, is gone: by
    ///   algebra dFa(j+m) - dFa(j) = dmFa(j+m) - dmFa(j+m-1), so given (ii) it only asked that the
    ///   *previous* slot's change be small against the suspected step. On the plant a break's
    ///   first tooth pass is transitional and the change spreads over neighbouring tooth windows
    ///   (Fig. 1 cavity, tooth 0: -1556, +434, +1633, 0 N by slot), so (i) dropped the first full
    ///   period's true suspicion (detection at 1.96 instead of 1.46 revolutions). The one plant
    ///   event (i) alone rejected (a one-period dip at 26.65 s in the cavity followed by a lower
    ///   level, whose dip pulled the revolution mean before the suspicion down to the new level)
    ///   is rejected by (iii) with the episode's reference (the dip is itself a suspicion, so the
    ///   reference is the revolution before it).
    ///
    ///   The price is one revolution of delay: detection at the end of period s + m, s the
    ///   suspicion. Worst case for a break at the start of period k: k is partly affected and may
    ///   not be suspected; a broken tooth changes at least two slots strongly (its own and the
    ///   next tooth's, which takes its chip), so the suspicion is at the latest at k + m - 1 and
    ///   the detection at k + 2m - 1: 2m - 1 + 1 tooth periods = 2 revolutions. A geometric
    ///   transient inside the confirmation revolution makes (ii) fail: then the detection waits
    ///   for a stationary revolution after it, or for the curvature confirmation below.
    /// - **curvature confirmation** (a second way to confirm, for breaks next to geometric
    ///   transients, ramps and a broken tooth whose load keeps changing): a corner or a ramp
    ///   scales every tooth alike (a gain g(t) common to the teeth, smooth but for the
    ///   transient's own periods), a break moves one tooth's load to the next. The first
    ///   suspicion opens an *episode* (for [`CURVATURE_SPAN`] revolutions; M stays frozen);
    ///   each tooth period's Fa is divided by the per-slot pattern of the last *quiet* revolution
    ///   (m periods with |dmFa| within the thresholds' floor, normalised by its mean; frozen
    ///   during the episode; with th2 instead of the floor, where th2 was large after a noisy
    ///   learning, the first period of a ramp entered the pattern and bent its slot in every
    ///   revolution after, a false alarm once the level guard below was lowered),
    ///   u(j) = Fa(j) / P(slot j), which removes the run-out, and the relative curvature
    ///   c(j-1) = (u(j-1) - (u(j-2) + u(j)) / 2) / mean(u(j-2..j)) is formed. A ramp gives
    ///   c = 0, a transient gives c only at its own periods, once; a broken tooth gives
    ///   -1.5 and +1.5 times its lost share at its slot and the next, every revolution. Breakage
    ///   when c of a slot and the same slot's c one revolution earlier (both in the episode,
    ///   from the suspicion's own period on: c(s) is formed in period s + 1) exceed
    ///   t = max(th2 / L, [`CURVATURE_MIN`]) with the same sign, the later at least
    ///   [`CURVATURE_KEEP`] of the earlier (a break's bend persists, a transient's decays), with
    ///   the local level mean u at least [`CURVATURE_LEVEL`] of the quiet pattern's (in an
    ///   exit's tail the pattern changes shape as the teeth leave the cut one by one). Being
    ///   local (three periods), it is blind to a transient elsewhere in the revolution. Its
    ///   price: the same slot's c one revolution later is known one period after it, so the
    ///   earliest confirmation is at s + m + 1 (s the suspicion). (It used to start at c(s + 1),
    ///   the suspicion's own bend left out: a break whose suspicion is its own first period then
    ///   waited a revolution more, 2.08 revolutions on the pocket's exit at 16.37 s.)
    /// - **chip-transfer test** (a third way, without suspicion or confirmation, and also while
    ///   learning): the once-per-revolution differences of four consecutive periods s-1 .. s+2
    ///   show a negative dmFa(s) followed by a positive dmFa(s+1), a jump A = dmFa(s+1) -
    ///   dmFa(s) >= [`TRANSFER_MIN`] x L, while the flanks dmFa(s-1) and dmFa(s+2) agree with
    ///   each other and are small against A (the cut's own change per revolution), and the
    ///   pair's sum equals the flanks' (the chip moved, the material per revolution did not:
    ///   each within [`TRANSFER_TOL`] x A), the suspected period itself having lost against the
    ///   flank before it ([`TRANSFER_LOSS`]) and the cut not rising fast ([`TRANSFER_RISE`]: a
    ///   corner entry's staircase). This is a large break seen in the revolution of the
    ///   break itself: the lost chip at one tooth period and the next tooth's extra chip, against
    ///   the same tooth periods one revolution earlier. Differences per revolution remove the
    ///   run-out and a linear ramp (a constant dmFa), so the test works on an entry's ramp where
    ///   the learning (steady revolutions only) has not ended: on the pocket a re-entry ramps
    ///   from 1000 to 1700 N for 1.5 s and learning over linear ramps would not help there (the
    ///   ramp's per-revolution change is jagged by +-100 N at 1300 N, and the break came 7.75
    ///   revolutions after the entry, less than the 7 a perfect ramp would need to learn).
    ///   Decided at the end of period s + 2, at most a revolution after the break. A step, a
    ///   hole or a bump, and a ramp's kink, each fail one of the three tolerances by about A
    ///   (see [`TRANSFER_TOL`]). It also confirms a break whose broken tooth's load keeps
    ///   falling for revolutions (the pattern is never stationary for (ii)), and one next to
    ///   an exit.
    Adaptive,
}

/// Settings of the breakage detector. [`BreakageSettings::default`] gives the thesis' numbers
/// where it has them (5 revolutions, factor 2) and plausible values for the rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BreakageSettings {
    /// Rate of [`BreakageDetector::sample`] calls, Hz. Default 1000 (the AC's sample rate).
    pub sample_hz: u32,
    /// EWLS forgetting factor lambda of both filters, per tooth period, in [0.5, 1). Default
    /// 0.95: a memory of 1 / (1 - lambda) = 20 tooth periods (5 revolutions of a 4-flute cutter),
    /// long enough that one break spike moves phi little (the thesis gives no value), short
    /// enough to follow an entry or a corner within a few revolutions.
    pub lambda: f32,
    /// Revolutions of learning after each entry from air (thesis: 5). 1..=100.
    pub learn_revs: u32,
    /// Threshold = factor x the largest |residual| (thesis: 2). Finite, 1..=100.
    pub factor: f32,
    /// The threshold rule. Default [`ThresholdMode::Adaptive`].
    pub mode: ThresholdMode,
    /// Adaptive: half-life of the running maximum of |residual|, revolutions. Default 20 (2 s at
    /// 600 rpm): an entry's transient is forgotten within a few seconds, while the run-out and
    /// noise of the last revolutions stay in. Finite, 1..=10000.
    pub decay_revs: f32,
    /// Adaptive: thresholds at least this fraction of the force level L (the mean Fa of the last
    /// revolution). Default 0.05: a
    /// tooth losing 5 % of its chip is the smallest change the detector is asked to see; below it
    /// run-out drift and noise dominate. 0..=1.
    pub floor_fraction: f32,
    /// Both modes: thresholds at least this, N (above the averaged sensor noise: the default
    /// transducer's 5 N per sample is about 1 N on a 25-sample average). Default 10. (0, 1e6].
    pub min_threshold_n: f32,
    /// Fa below this is air (no decisions, learning restarts on the next entry), N. Default 50
    /// (the noise's magnitude averages about 6 N). (0, 1e6].
    pub air_floor_n: f32,
    /// Adaptive: the curvature confirmation decides (default true). Its premise is that a
    /// geometric change scales every tooth's load alike; a ball end mill's tooth passes on a 3D
    /// surface meet different parts of it (the steps a roughing tool left, the slope), so its
    /// tooth periods' pattern bends revolution after revolution with a sound tool: the Fig. 1
    /// job's 10 mm two-flute ball end mill finishing the sloped bottom, replayed at each of the
    /// 38 phases of its tooth period, had a false breakage at 22 with it and at none without
    /// it (`AcSettings::breakage_settings_for` turns it off for a ball end mill). The
    /// revolution's confirmation and the chip-transfer test still decide: a two-flute ball's
    /// broken tooth moves half the revolution's load, a large break the transfer test sees
    /// within the revolution.
    pub curvature: bool,
}

impl Default for BreakageSettings {
    fn default() -> Self {
        BreakageSettings {
            sample_hz: 1000,
            lambda: 0.95,
            learn_revs: 5,
            factor: 2.0,
            mode: ThresholdMode::Adaptive,
            decay_revs: 20.0,
            floor_fraction: 0.05,
            min_threshold_n: 10.0,
            air_floor_n: 50.0,
            curvature: true,
        }
    }
}

/// Why a set of breakage settings was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BreakageSettingsError {
    SampleRate,
    Lambda,
    LearnRevs,
    Factor,
    DecayRevs,
    FloorFraction,
    MinThreshold,
    AirFloor,
}

impl BreakageSettingsError {
    pub const fn message(self) -> &'static str {
        match self {
            BreakageSettingsError::SampleRate => "breakage sample rate must be 100..=100000 Hz",
            BreakageSettingsError::Lambda => "breakage forgetting factor must be in [0.5, 1)",
            BreakageSettingsError::LearnRevs => "breakage learning must be 1..=100 revolutions",
            BreakageSettingsError::Factor => "breakage threshold factor must be 1..=100",
            BreakageSettingsError::DecayRevs => {
                "breakage threshold half-life must be 1..=10000 revolutions"
            }
            BreakageSettingsError::FloorFraction => {
                "breakage threshold floor must be 0..=1 of the force level"
            }
            BreakageSettingsError::MinThreshold => {
                "breakage minimum threshold must be finite and in (0, 1e6] N"
            }
            BreakageSettingsError::AirFloor => {
                "breakage air floor must be finite and in (0, 1e6] N"
            }
        }
    }
}

impl fmt::Display for BreakageSettingsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.message())
    }
}

impl BreakageSettings {
    /// [`BreakageSettings::validate`], and the settings as a [`Valid`] when they pass: what
    /// [`BreakageDetector::new`] takes.
    pub fn validated(self) -> Result<Valid<BreakageSettings>, BreakageSettingsError> {
        self.validate()?;
        Ok(Valid::checked(self))
    }

    /// Checks every setting; after it every computation of the detector is finite.
    pub fn validate(&self) -> Result<(), BreakageSettingsError> {
        use BreakageSettingsError as E;
        let within = |v: f32, lo: f32, hi: f32| v.is_finite() && v >= lo && v <= hi;
        if !(100..=100_000).contains(&self.sample_hz) {
            return Err(E::SampleRate);
        }
        if !(self.lambda.is_finite() && self.lambda >= 0.5 && self.lambda < 1.0) {
            return Err(E::Lambda);
        }
        if !(1..=100).contains(&self.learn_revs) {
            return Err(E::LearnRevs);
        }
        if !within(self.factor, 1.0, 100.0) {
            return Err(E::Factor);
        }
        if !within(self.decay_revs, 1.0, 1.0e4) {
            return Err(E::DecayRevs);
        }
        if !within(self.floor_fraction, 0.0, 1.0) {
            return Err(E::FloorFraction);
        }
        if !(within(self.min_threshold_n, 0.0, 1.0e6) && self.min_threshold_n > 0.0) {
            return Err(E::MinThreshold);
        }
        if !(within(self.air_floor_n, 0.0, 1.0e6) && self.air_floor_n > 0.0) {
            return Err(E::AirFloor);
        }
        Ok(())
    }
}

/// A declared breakage: the tooth period of the declaration (counted since the detector was
/// made or reset) and the residuals and thresholds of the tooth period where both residuals
/// first violated their thresholds (the same period in [`ThresholdMode::Thesis`], one revolution
/// before the declaration in [`ThresholdMode::Adaptive`]), in N; for the chip-transfer test
/// (Adaptive), the declaring period's residuals and current thresholds, which need not be
/// violated (the test judges the once-per-revolution differences themselves; while learning the
/// thresholds are the floor).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Breakage {
    pub tooth_period: u32,
    pub e1: f32,
    pub e2: f32,
    pub th1: f32,
    pub th2: f32,
}

impl Breakage {
    /// A short fixed text, as [`crate::ac::Alarm::message`].
    pub const fn message(&self) -> &'static str {
        "tool breakage: tooth force pattern changed"
    }
}

impl fmt::Display for Breakage {
    /// The text the protocol prints inside `[MSG:...]`.
    fn fmt(&self, w: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            w,
            "tool breakage at tooth period {}: e1 = {:.1} N (threshold {:.1} N), e2 = {:.1} N \
             (threshold {:.1} N)",
            self.tooth_period, self.e1, self.th1, self.e2, self.th2
        )
    }
}

/// First-order time-series filter x(j) = phi x(j-1) + e(j), phi by EWLS.
#[derive(Clone, Copy, Debug, Default)]
struct Ewls {
    sxy: f32,
    sxx: f32,
    phi: f32,
}

impl Ewls {
    /// The a priori residual of x, then the update of phi.
    fn step(&mut self, x: f32, x_prev: f32, lambda: f32) -> f32 {
        let e = x - self.phi * x_prev;
        self.sxy = lambda * self.sxy + x * x_prev;
        self.sxx = lambda * self.sxx + x_prev * x_prev;
        if self.sxx > 1.0e-12 {
            let phi = self.sxy / self.sxx;
            if phi.is_finite() {
                self.phi = phi.clamp(-1.0, 1.0);
            }
        }
        e
    }
}

/// A pending suspicion (Adaptive mode): the residuals and thresholds when both violated.
#[derive(Clone, Copy, Debug)]
struct Suspect {
    /// dFa(j) of the suspected tooth period.
    d: f32,
    /// Mean Fa of the revolution before the episode (see [`CONSERVE_FRACTION`]).
    rev_mean: f32,
    e1: f32,
    e2: f32,
    th1: f32,
    th2: f32,
}

/// An open curvature episode (Adaptive mode, see [`CURVATURE_MIN`]).
#[derive(Clone, Copy, Debug)]
struct Episode {
    /// Tooth periods since its first suspicion.
    age: u32,
    /// Relative curvature of the pattern-corrected force by slot, the last revolution's.
    curv: [f32; MAX_FLUTES],
    /// The relative threshold th2 / L of the first suspicion, at least [`CURVATURE_MIN`].
    t: f32,
    /// The first suspicion's residuals and thresholds (the report).
    e1: f32,
    e2: f32,
    th1: f32,
    th2: f32,
}

/// The breakage detector: fed every sample, decides every tooth period.
#[derive(Clone, Debug)]
pub struct BreakageDetector {
    s: BreakageSettings,
    /// Tooth period in Q16 samples; 0 = spindle unknown (no decisions).
    period_q16: u32,
    /// Flutes m (1..=MAX_FLUTES; meaningful only with a known spindle).
    flutes: u8,
    /// Running-maximum decay per tooth period, 0.5^(1 / (decay_revs x m)).
    decay: f32,
    acc_q16: u32,
    sum: f32,
    count: u32,
    /// Tooth periods since made or reset.
    j: u32,
    /// Consecutive tooth periods in the cut since the last entry from air (saturating).
    n_cut: u32,
    /// Consecutive tooth periods below the air floor (saturating).
    n_air: u8,
    /// Adaptive: consecutive steady tooth periods of the learning (saturating).
    n_steady: u32,
    /// Fa of the last m tooth periods, by slot j mod m.
    hist: [f32; MAX_FLUTES],
    prev_fa: f32,
    /// Fa(j-2).
    prev_fa2: f32,
    /// Fa of the last quiet revolution by slot (its per-slot pattern); all 0 before one.
    pat: [f32; MAX_FLUTES],
    /// Consecutive tooth periods with |dmFa| within th2 (saturating).
    n_quiet: u32,
    ep: Option<Episode>,
    dm_prev: f32,
    /// dmFa(j-2), dmFa(j-3) (the chip-transfer test, see [`TRANSFER_MIN`]).
    dm_prev2: f32,
    dm_prev3: f32,
    f1: Ewls,
    f2: Ewls,
    /// Running maxima of |e1|, |e2|.
    m1: f32,
    m2: f32,
    /// Mean Fa of the revolution before the current tooth period (at least the air floor): the
    /// scale of the adaptive thresholds.
    level: f32,
    pending: [Option<Suspect>; MAX_FLUTES],
    latched: Option<Breakage>,
    /// No suspicion is raised or confirmed before this tooth period ([`Self::feed_step`]).
    hold_until: u32,
    /// The last [`NOTICES`] tooth periods (j) in which feed notices came, newest at
    /// `notice_at` - 1; `noticed` of them are real (a count, at most [`NOTICES`]).
    notices: [u32; NOTICES],
    /// For each, the least feed kept ([`FeedChange::kept_pct`]) of its notices that lowered the
    /// feed (100: none lowered it), and whether one raised it.
    kept: [u8; NOTICES],
    raised: [bool; NOTICES],
    notice_at: u8,
    noticed: u8,
    /// The force of the last [`REV_RING`] samples (NaN: no valid sample), oldest overwritten.
    ring: [f32; REV_RING],
    /// The next sample's index in `ring`.
    ring_at: u16,
    /// Samples in the ring since the last restart (saturating at [`REV_RING`]).
    ring_len: u16,
    /// Samples per revolution, rounded (0: unknown or longer than the ring).
    rev: u16,
    /// The last residuals (e1, e2), for the host's tests and figures (not in the firmware).
    #[cfg(any(test, feature = "std"))]
    e_last: (f32, f32),
}

impl BreakageDetector {
    /// A detector with an unknown spindle (its settings checked: see [`Valid`]).
    pub fn new(s: Valid<BreakageSettings>) -> Self {
        BreakageDetector {
            s: s.get(),
            period_q16: 0,
            flutes: 1,
            decay: 1.0,
            acc_q16: 0,
            sum: 0.0,
            count: 0,
            j: 0,
            n_cut: 0,
            n_air: 0,
            n_steady: 0,
            hist: [0.0; MAX_FLUTES],
            prev_fa: 0.0,
            prev_fa2: 0.0,
            pat: [0.0; MAX_FLUTES],
            n_quiet: 0,
            ep: None,
            dm_prev: 0.0,
            dm_prev2: 0.0,
            dm_prev3: 0.0,
            f1: Ewls::default(),
            f2: Ewls::default(),
            m1: 0.0,
            m2: 0.0,
            level: 0.0,
            pending: [None; MAX_FLUTES],
            latched: None,
            hold_until: 0,
            notices: [0; NOTICES],
            kept: [100; NOTICES],
            raised: [false; NOTICES],
            notice_at: 0,
            noticed: 0,
            ring: [0.0; REV_RING],
            ring_at: 0,
            ring_len: 0,
            rev: 0,
            #[cfg(any(test, feature = "std"))]
            e_last: (0.0, 0.0),
        }
    }

    pub fn settings(&self) -> &BreakageSettings {
        &self.s
    }

    /// The spindle speed (rpm) and the cutter's flutes. An rpm that is not finite and positive,
    /// flutes outside 1..=[`MAX_FLUTES`], or a tooth period outside 4..=60000 samples make the
    /// spindle unknown (no decisions). A change of the tooth period or the flutes restarts the
    /// tooth-period phase and the learning; telling the same values again changes nothing.
    /// With one flute the two differences coincide (m = 1): the detector runs but the run-out
    /// filter adds nothing.
    pub fn set_spindle(&mut self, rpm: f32, flutes: u8) {
        let z = flutes as u32;
        let samples = 60.0 * self.s.sample_hz as f32 / (rpm * z as f32);
        let ok = rpm.is_finite()
            && rpm > 0.0
            && (1..=MAX_FLUTES as u32).contains(&z)
            && (PERIOD_MIN_SAMPLES..=PERIOD_MAX_SAMPLES).contains(&samples);
        let q = if ok { (samples * Q16 as f32) as u32 } else { 0 };
        if q == self.period_q16 && (q == 0 || z == self.m()) {
            return;
        }
        self.period_q16 = q;
        if ok {
            self.flutes = flutes;
            self.decay = libm::exp2f(-1.0 / (self.s.decay_revs * z as f32));
        }
        let rev = libm::roundf(samples * z as f32);
        self.rev = if ok && rev <= REV_RING as f32 {
            rev as u16
        } else {
            0
        };
        self.acc_q16 = 0;
        self.sum = 0.0;
        self.count = 0;
        self.restart();
    }

    /// Whether a spindle speed and flutes are known.
    pub fn spindle_known(&self) -> bool {
        self.period_q16 != 0
    }

    /// The tooth period in samples (0 when the spindle is unknown).
    pub fn period_samples(&self) -> f32 {
        self.period_q16 as f32 / Q16 as f32
    }

    /// Clears a latched breakage and restarts the learning (the operator's reset after a tool
    /// change); the spindle stays known.
    pub fn reset(&mut self) {
        self.latched = None;
        self.j = 0;
        self.hold_until = 0;
        self.noticed = 0;
        self.notice_at = 0;
        self.restart();
    }

    /// The feed changed by a step the controller knows of (the frame's deceleration at a corner
    /// and the acceleration after it, an AC hold or resume), or ramps revolution by revolution
    /// (the AC's recovery after a corner; `crate::rt::ac::FeedNotice`): the force follows the
    /// feed, whole revolutions alike. Open suspicions and a curvature episode are dropped, and for one
    /// revolution from now none is raised or confirmed (the filters and the history go on). A
    /// corner's dip and recovery otherwise look like a tooth's lost chip to the suspicion and
    /// its confirmations (the pocket under QEMU with the AC at 16.45 s: declared at the
    /// recovery). A change without `hold` (a smaller one) is only recorded: the sampler trip's
    /// verdict weighs the feed's changes of the last tooth periods ([`Self::chip_moved`]).
    /// Called by the AC period ([`crate::rt::ac::AcPeriod`]), which sees the feed.
    pub fn feed_step(&mut self, change: FeedChange) {
        if change.hold {
            self.pending = [None; MAX_FLUTES];
            self.ep = None;
            self.hold_until = self.j.wrapping_add(self.m());
        }
        let newest = (usize::from(self.notice_at) + NOTICES - 1) % NOTICES;
        let at = if self.noticed > 0 && self.notices.get(newest) == Some(&self.j) {
            newest
        } else {
            let at = usize::from(self.notice_at);
            if let (Some(n), Some(k), Some(r)) = (
                self.notices.get_mut(at),
                self.kept.get_mut(at),
                self.raised.get_mut(at),
            ) {
                *n = self.j;
                *k = 100;
                *r = false;
            }
            self.notice_at = (self.notice_at + 1) % NOTICES as u8;
            self.noticed = (self.noticed + 1).min(NOTICES as u8);
            at
        };
        if change.up {
            if let Some(r) = self.raised.get_mut(at) {
                *r = true;
            }
        } else if let Some(k) = self.kept.get_mut(at) {
            *k = (*k).min(change.kept_pct.min(100));
        }
    }

    /// Whether feed changes explain the loss of tooth period `lost` (`loss`: the share of its
    /// force a revolution before that it lost) and the crossing after it: a lowering came in the revolution before the
    /// period began, or while it ran (a notice while the detector's last complete period was
    /// `lost` - m .. `lost` - 1: the AC period notices a change at its end, within a tooth
    /// period for the spindles this detector serves), and moved the feed by at least the
    /// loss less [`FEED_LOSS_TOL`] (the force follows the feed, less than in proportion: the
    /// specific force grows as the chip thins), and a raise came while the lost period ran or
    /// after it (a feed that only fell cannot cross the overload level, and one that rose
    /// before the loss did not make the crossing after it). A breakage's own consequences come later: the
    /// next tooth's doubled chip is in period `lost` + 1, and the AC's reaction to it is
    /// noticed while the last complete period is `lost` or later; and a broken tooth's period
    /// loses more than a feed step that came with it (a corner's deceleration of the pocket
    /// beside a break: 95 % lost after steps that kept half the feed).
    fn fed_before(&self, lost: u32, loss: f32) -> bool {
        let m = self.m();
        let noticed = || {
            self.notices
                .iter()
                .zip(self.kept.iter().zip(&self.raised))
                .take(usize::from(self.noticed))
        };
        // A lowering that explains the loss.
        let lowered = noticed().any(|(&n, (&kept, _))| {
            (1..=m).contains(&lost.wrapping_sub(n))
                && loss <= 1.0 - f32::from(kept) / 100.0 + FEED_LOSS_TOL
        });
        // A raise while the lost period ran or after it (the last complete period `lost` - 1
        // or later; j is at most `lost` + 1): what made the crossing.
        let raised =
            noticed().any(|(&n, (_, &up))| up && n.wrapping_sub(lost.wrapping_sub(1)) <= 2);
        lowered && raised
    }

    /// The latched breakage, if any.
    pub fn breakage(&self) -> Option<Breakage> {
        self.latched
    }

    /// The current thresholds (th1, th2) in N (meaningful after the learning).
    pub fn thresholds(&self) -> (f32, f32) {
        self.thresholds_now()
    }

    /// Tooth periods judged so far (air and cut): a caller sees a period close when it changes.
    pub fn periods(&self) -> u32 {
        self.j
    }

    /// The residuals (e1, e2) of the last tooth period that formed them (N; host: tests and
    /// figures).
    #[cfg(any(test, feature = "std"))]
    pub fn residuals(&self) -> (f32, f32) {
        self.e_last
    }

    /// Whether the detector is learning (in air, or within the learning revolutions of a cut).
    pub fn learning(&self) -> bool {
        match self.s.mode {
            ThresholdMode::Thesis => self.n_cut <= self.learn_periods(),
            ThresholdMode::Adaptive => self.n_steady < self.m().saturating_mul(self.s.learn_revs),
        }
    }

    /// One ADC sample: the resultant force F in N (sqrt(Fu^2 + Fv^2), see the module docs).
    /// Returns the breakage in the sample that closes the tooth period declaring it.
    pub fn sample(&mut self, f_n: f32) -> Option<Breakage> {
        if self.period_q16 == 0 {
            return None;
        }
        let f = if f_n.is_finite() {
            let f = f_n.clamp(0.0, FORCE_MAX_N);
            self.sum += f;
            self.count += 1;
            f
        } else {
            f32::NAN
        };
        if let Some(slot) = self.ring.get_mut(usize::from(self.ring_at)) {
            *slot = f;
        }
        self.ring_at = (self.ring_at + 1) % REV_RING as u16;
        self.ring_len = self.ring_len.saturating_add(1).min(REV_RING as u16);
        self.acc_q16 = self.acc_q16.saturating_add(Q16);
        if self.acc_q16 < self.period_q16 {
            return None;
        }
        self.acc_q16 -= self.period_q16;
        let fa = if self.count > 0 {
            self.sum / self.count as f32
        } else {
            f32::NAN
        };
        self.sum = 0.0;
        self.count = 0;
        self.tooth_period(fa)
    }

    /// Whether the force before this instant shows a chip moved from one tooth to the next: one
    /// of the last two complete tooth periods' average force lost at least [`CHIP_MOVED_MIN`] of
    /// the level against the same tooth period a revolution before, or the samples of the last
    /// two tooth periods, against the same spindle angle a revolution before, lost at least
    /// [`REV_LOSS_MIN`] of the level over half a tooth period ([`Self::rev_loss`]: the broken
    /// tooth's missing pass where it falls inside the tooth period not yet complete, or splits
    /// over two). Asked when a sample crosses the overload level (the AC period's sampler trip,
    /// `crate::rt::ac`): the crossing right after such a loss is the next tooth's doubled chip,
    /// the breakage's own signature, and the hold is a breakage, not an overload. A real
    /// overload (a harder spot, a deeper cut, a boss) raises the force without the loss before
    /// it. Nor does a feed change the AC period told ([`Self::feed_step`]): a loss a lowering
    /// explains, with a raise during or after it, is the feed's and the crossing an overload
    /// (`fed_before`). Needs a known spindle and a revolution of cut (one tooth period below
    /// the air floor is the broken tooth cutting alone; two are air) and a detector not
    /// latched; the report carries the loss as e2 and its threshold as th2, the first
    /// difference as e1.
    pub fn chip_moved(&self) -> Option<Breakage> {
        // A revolution of cut (one tooth period below the air floor is a broken tooth that cuts
        // alone, not air), a known spindle, not latched.
        if self.period_q16 == 0
            || self.latched.is_some()
            || self.n_cut <= self.m().saturating_add(1)
            || self.n_air > 1
        {
            return None;
        }
        // The tooth periods are not aligned with the teeth: the broken tooth's missing pass may
        // fall in either of the last two.
        let dm = self.dm_prev.min(self.dm_prev2);
        let th = CHIP_MOVED_MIN * self.level;
        // The report: the tooth periods' loss and threshold where they tell it, else the samples'.
        // The loss's tooth period and its share of that period's force a revolution before
        // (the samples' loss is of the level: at most 1, an upper bound of the share).
        let (e2, th2, lost, loss) = if self.n_air == 0 && -dm >= th {
            let (lost, fa) = if self.dm_prev <= self.dm_prev2 {
                (self.j, self.prev_fa)
            } else {
                (self.j.wrapping_sub(1), self.prev_fa2)
            };
            (dm, th, lost, -dm / (fa - dm).max(1.0e-3))
        } else {
            match self.rev_loss_at() {
                Some((l, lost)) if l >= REV_LOSS_MIN => {
                    (-l * self.level, REV_LOSS_MIN * self.level, lost, l.min(1.0))
                }
                _ => return None,
            }
        };
        // A loss that follows a feed change is the feed's (all teeth alike), and the crossing
        // after it an overload.
        if self.fed_before(lost, loss) {
            return None;
        }
        Some(Breakage {
            tooth_period: self.j,
            e1: self.prev_fa - self.prev_fa2,
            e2,
            th1: th,
            th2,
        })
    }

    /// The largest loss of force against the same spindle angle a revolution before (the
    /// revolution rounded to whole samples), averaged over half a tooth period, within the last
    /// two tooth periods of samples, as a fraction of the level (None: a revolution and two
    /// tooth periods are more than [`REV_RING`] samples, or more than the samples since the cut
    /// began). Asked at a sampler trip only (about 500 subtractions at 600 rpm, 4 flutes, 1 kHz).
    pub fn rev_loss(&self) -> Option<f32> {
        self.rev_loss_at().map(|(l, _)| l)
    }

    /// [`Self::rev_loss`] and the tooth period its window falls in (the window's middle: the
    /// current, incomplete period is j + 1).
    fn rev_loss_at(&self) -> Option<(f32, u32)> {
        let rev = usize::from(self.rev);
        let tp = (self.period_q16 / Q16) as usize;
        let half = (tp / 2).max(1);
        let span = 2 * tp;
        if rev == 0
            || rev + span > REV_RING
            || usize::from(self.ring_len) < rev + span
            || self.level <= 0.0
        {
            return None;
        }
        let at = |back: usize| -> f32 {
            let i = (usize::from(self.ring_at) + REV_RING * 2 - back) % REV_RING;
            self.ring.get(i).copied().unwrap_or(f32::NAN)
        };
        // d(k) = F(now - k) - F(now - k - rev), k = 1 ..= span; windows of `half` samples.
        let mut worst = 0.0f32;
        let mut worst_end = 1;
        for end in 1..=(span + 1 - half) {
            let mut sum = 0.0f32;
            for k in end..end + half {
                sum += at(k) - at(k + rev);
            }
            if sum.is_finite() && sum / (half as f32) < worst {
                worst = sum / half as f32;
                worst_end = end;
            }
        }
        // Samples back to the window's middle, against the samples of the current period.
        let mid = worst_end + half / 2;
        let since = (self.acc_q16 / Q16) as usize;
        let lost = if mid <= since {
            self.j.wrapping_add(1)
        } else {
            self.j.wrapping_sub(((mid - since - 1) / tp.max(1)) as u32)
        };
        Some((-worst / self.level, lost))
    }

    /// One ADC sample as its rotating-frame components Fu, Fv in N.
    pub fn sample_uv(&mut self, fu_n: f32, fv_n: f32) -> Option<Breakage> {
        self.sample(crate::ac::ecr::force(fu_n, fv_n))
    }

    /// The tooth-period work on an average force Fa(j) in N (the lower-level entry point: called
    /// by [`Self::sample`], or directly by a caller that averages elsewhere). Needs a known
    /// spindle (for m). A non-finite Fa counts as air. Returns the breakage in the tooth period
    /// that declares it, once; afterwards the detector stays latched until [`Self::reset`].
    pub fn tooth_period(&mut self, fa: f32) -> Option<Breakage> {
        if self.latched.is_some() || self.period_q16 == 0 {
            return None;
        }
        self.j = self.j.wrapping_add(1);
        if !fa.is_finite() {
            self.restart();
            return None;
        }
        // Air is a whole revolution below the floor: a single low tooth period inside a cut is a
        // broken tooth (a tooth that cuts alone and lost its whole chip averages ~0), not air.
        if fa < self.s.air_floor_n {
            self.n_air = self.n_air.saturating_add(1);
            if self.n_cut == 0 || u32::from(self.n_air) >= self.m() {
                self.restart();
                return None;
            }
        } else {
            self.n_air = 0;
        }
        let fa = fa.clamp(0.0, FORCE_MAX_N);
        let lambda = self.s.lambda;
        self.n_cut = self.n_cut.saturating_add(1);
        let slot = (self.j % self.m()) as usize;
        if self.n_cut == 1 {
            self.prev_fa = fa;
            self.prev_fa2 = fa;
            // The revolution mean starts at the entry's force (dmFa waits for a revolution).
            self.hist = [fa; MAX_FLUTES];
            return None;
        }
        let d = fa - self.prev_fa;
        // dFa(j-1) = Fa(j-1) - Fa(j-2), the same f32 subtraction as when it was formed (0 on
        // the first period of a cut, where both hold the entry's Fa).
        let e1 = self.f1.step(d, self.prev_fa - self.prev_fa2, lambda);
        let (dm, e2) = if self.n_cut > self.m() {
            let dm = fa - self.hist.get(slot).copied().unwrap_or(fa);
            (dm, self.f2.step(dm, self.dm_prev, lambda))
        } else {
            (0.0, 0.0)
        };
        // Mean Fa of the last revolution (j-m .. j-1), before this period enters the history.
        let m_len = (self.m() as usize).min(MAX_FLUTES);
        let rev_mean =
            self.hist.get(..m_len).unwrap_or(&[]).iter().sum::<f32>() / self.m().max(1) as f32;
        if let Some(h) = self.hist.get_mut(slot) {
            *h = fa;
        }
        let fa_1 = self.prev_fa;
        let fa_2 = self.prev_fa2;
        self.prev_fa2 = fa_1;
        self.prev_fa = fa;
        self.level = rev_mean.max(self.s.air_floor_n);
        let transfer = self.s.mode == ThresholdMode::Adaptive
            && self.n_cut >= self.m().saturating_add(4)
            && self.transfer(dm);
        self.dm_prev3 = self.dm_prev2;
        self.dm_prev2 = self.dm_prev;
        self.dm_prev = dm;
        #[cfg(any(test, feature = "std"))]
        {
            self.e_last = (e1, e2);
        }
        if (self.hold_until.wrapping_sub(self.j) as i32) > 0 {
            // Within a revolution of a feed step: the filters and the history went on, nothing
            // is judged or learnt from the transient.
            return None;
        }
        let (a1, a2) = (e1.abs(), e2.abs());
        // Adaptive: M is relative to the level; the thesis' is in N.
        let inv = match self.s.mode {
            ThresholdMode::Thesis => 1.0,
            ThresholdMode::Adaptive => 1.0 / self.level,
        };
        if transfer {
            let (th1, th2) = self.thresholds_now();
            let b = Breakage {
                tooth_period: self.j,
                e1,
                e2,
                th1,
                th2,
            };
            self.latched = Some(b);
            return Some(b);
        }
        if self.learning() {
            if self.s.mode == ThresholdMode::Adaptive {
                // Learn only over steady revolutions: a period whose once-per-revolution change
                // is above the thresholds' floor (an entry, a ramp, a corner) restarts it.
                let steady = self.n_cut > self.m() && dm.abs() <= self.floor();
                if steady {
                    self.n_steady = self.n_steady.saturating_add(1);
                } else {
                    self.n_steady = 0;
                    self.m1 = 0.0;
                    self.m2 = 0.0;
                    return None;
                }
            }
            self.m1 = self.m1.max(a1 * inv);
            self.m2 = self.m2.max(a2 * inv);
            return None;
        }
        let (th1, th2) = self.thresholds_now();
        let both = a1 > th1 && a2 > th2;
        let found = match self.s.mode {
            ThresholdMode::Thesis => both.then_some(Suspect {
                d,
                rev_mean,
                e1,
                e2,
                th1,
                th2,
            }),
            ThresholdMode::Adaptive => {
                let mut found = None;
                if let Some(p) = self.pending.get_mut(slot).and_then(Option::take) {
                    let conserved = (rev_mean - p.rev_mean).abs() <= CONSERVE_FRACTION * p.d.abs();
                    if conserved && dm.abs() < th2 {
                        found = Some(p);
                    }
                }
                // The episode runs (and closes) either way; its verdict counts where the
                // settings trust it (not for a ball end mill: see `BreakageSettings::curvature`).
                let hit = self
                    .curvature_step(slot, fa, fa_1, fa_2)
                    .filter(|_| self.s.curvature);
                if found.is_none() {
                    found = hit;
                }
                // The last quiet revolution's pattern (frozen while an episode is open).
                self.n_quiet = if dm.abs() <= self.floor() {
                    self.n_quiet.saturating_add(1)
                } else {
                    0
                };
                if self.ep.is_none() && self.n_quiet >= self.m() {
                    self.pat = self.hist;
                }
                // The raw once-per-revolution change must be there too: after a geometric
                // transient e2 rings (phi2 x dmFa(j-1)) while dmFa(j) is nil; a break's first
                // period has both. And a loss: a damaged tooth cuts less than it did a
                // revolution ago (dmFa < 0 at its period, the next tooth's gain follows), while
                // the tail of a rising engagement gains at every tooth (the fast step after a
                // steady cut: dmFa +309 then +155 N, suspected, and the revolution after it at
                // the new level looked conserved).
                // (dm_prev2 is dmFa(j-1) here: the history moved on above.)
                let lost = dm.min(self.dm_prev2) < 0.0;
                if found.is_none() && both && dm.abs() > th2 && lost {
                    if self.ep.is_none() && self.pat_level() > 0.0 {
                        self.ep = Some(Episode {
                            age: 0,
                            curv: [0.0; MAX_FLUTES],
                            t: (th2 / self.level).max(CURVATURE_MIN),
                            e1,
                            e2,
                            th1,
                            th2,
                        });
                    }
                    // The revolution before the episode: the first pending suspicion's.
                    let base = self
                        .pending
                        .iter()
                        .flatten()
                        .next()
                        .map_or(rev_mean, |p| p.rev_mean);
                    if let Some(p) = self.pending.get_mut(slot) {
                        *p = Some(Suspect {
                            d,
                            rev_mean: base,
                            e1,
                            e2,
                            th1,
                            th2,
                        });
                    }
                }
                if self.pending.iter().all(Option::is_none) && self.ep.is_none() {
                    let k = self.decay;
                    let keep = |m: f32, a: f32, th: f32| {
                        if a <= th {
                            (k * m).max(a * inv)
                        } else {
                            k * m
                        }
                    };
                    self.m1 = keep(self.m1, a1, th1);
                    self.m2 = keep(self.m2, a2, th2);
                }
                found
            }
        };
        let b = found.map(|p| Breakage {
            tooth_period: self.j,
            e1: p.e1,
            e2: p.e2,
            th1: p.th1,
            th2: p.th2,
        });
        self.latched = b;
        b
    }

    /// The curvature confirmation (Adaptive mode), every tooth period while an episode is open:
    /// u = Fa / the quiet pattern of its slot for j-2, j-1, j, and the relative curvature of
    /// u at j-1, c = (u(j-1) - (u(j-2) + u(j)) / 2) / mean u. A breakage when c and the same
    /// slot's c one revolution earlier (both in the episode) exceed the episode's threshold with
    /// the same sign, and the local level mean u is at least [`CURVATURE_LEVEL`] of the quiet
    /// pattern's. The episode closes after [`CURVATURE_SPAN`] revolutions.
    fn curvature_step(&mut self, slot: usize, fa: f32, fa_1: f32, fa_2: f32) -> Option<Suspect> {
        let m = (self.m() as usize).clamp(1, MAX_FLUTES);
        let s1 = (slot + m - 1) % m;
        let s2 = (slot + 2 * m - 2) % m;
        let level = self.pat_level();
        // The pattern normalised by its mean (a quiet revolution is in the cut: level > 0).
        let p = |k: usize| (self.pat.get(k).copied().unwrap_or(level) / level.max(1.0)).max(1.0e-3);
        let (u0, u1, u2) = (fa / p(slot), fa_1 / p(s1), fa_2 / p(s2));
        let floor = self.s.air_floor_n;
        let min_n = self.s.min_threshold_n;
        let span = self.m().saturating_mul(CURVATURE_SPAN);
        let ep = self.ep.as_mut()?;
        ep.age = ep.age.saturating_add(1);
        let mut found = None;
        if ep.age >= 1 {
            let mean = (u0 + u1 + u2) / 3.0;
            let c = (u1 - 0.5 * (u0 + u2)) / mean.max(floor);
            let old = ep.curv.get(s1).copied().unwrap_or(0.0);
            // Never below what the thresholds' floor in N is at this force: as a light cut
            // fades (an exit) the sensor's noise alone bends u by more than the episode's
            // threshold, set at the level where the episode opened (a 166 N cut's exit
            // bent the same slot twice by 0.1 at 50 N, over its 0.06).
            let t = ep.t.max(min_n / mean.max(floor));
            if mean >= CURVATURE_LEVEL * level
                && c.abs() > t
                && old.abs() > t
                && c.abs() >= CURVATURE_KEEP * old.abs()
                && (c > 0.0) == (old > 0.0)
            {
                found = Some(Suspect {
                    d: 0.0,
                    rev_mean: 0.0,
                    e1: ep.e1,
                    e2: ep.e2,
                    th1: ep.th1,
                    th2: ep.th2,
                });
            }
            if let Some(x) = ep.curv.get_mut(s1) {
                *x = c;
            }
        }
        if found.is_none() && ep.age > span {
            self.ep = None;
        }
        found
    }

    /// The chip-transfer test on dmFa(j-3 .. j), s = j-2 (see [`TRANSFER_MIN`], [`TRANSFER_LOSS`],
    /// [`TRANSFER_TOL`], [`TRANSFER_RISE`]): dmFa(s+1) - dmFa(s) = A >= [`TRANSFER_MIN`] x L, the
    /// loss dmFa(s-1) - dmFa(s) >= [`TRANSFER_LOSS`] x A, the flanks' difference, the flanks' mean
    /// and the pair's excess over the flanks within [`TRANSFER_TOL`] x A, and the flanks' mean
    /// at most [`TRANSFER_RISE`] x A.
    fn transfer(&self, dm0: f32) -> bool {
        let (dm1, dm2, dm3) = (self.dm_prev, self.dm_prev2, self.dm_prev3);
        let a = dm1 - dm2;
        let (_, th2) = self.thresholds_now();
        a >= TRANSFER_MIN * self.level
            && a > th2
            && dm3 - dm2 >= TRANSFER_LOSS * a
            && (dm0 - dm3).abs() <= TRANSFER_TOL * a
            && 0.5 * (dm0 + dm3).abs() <= TRANSFER_TOL * a
            && 0.5 * (dm0 + dm3) <= TRANSFER_RISE * a
            && (dm1 + dm2 - dm0 - dm3).abs() <= TRANSFER_TOL * a
    }

    /// The flutes m as u32.
    fn m(&self) -> u32 {
        u32::from(self.flutes)
    }

    /// The mean Fa of the quiet pattern (0 before one).
    fn pat_level(&self) -> f32 {
        let m_len = (self.m() as usize).min(MAX_FLUTES);
        self.pat.get(..m_len).unwrap_or(&[]).iter().sum::<f32>() / self.m().max(1) as f32
    }

    /// Tooth periods of learning after an entry: one revolution to fill the once-per-revolution
    /// history, then `learn_revs` revolutions.
    #[cfg(test)]
    pub(super) fn f1_last_abs(&self) -> f32 {
        self.e_last.0.abs()
    }

    #[cfg(test)]
    pub(super) fn f2_last_abs(&self) -> f32 {
        self.e_last.1.abs()
    }

    fn learn_periods(&self) -> u32 {
        self.m().saturating_mul(self.s.learn_revs.saturating_add(1))
    }

    /// The adaptive thresholds' floor at the current level, N.
    fn floor(&self) -> f32 {
        self.s
            .min_threshold_n
            .max(self.s.floor_fraction * self.level)
    }

    fn thresholds_now(&self) -> (f32, f32) {
        let (scale, floor) = match self.s.mode {
            ThresholdMode::Thesis => (1.0, self.s.min_threshold_n),
            ThresholdMode::Adaptive => (self.level, self.floor()),
        };
        (
            (self.s.factor * scale * self.m1).max(floor),
            (self.s.factor * scale * self.m2).max(floor),
        )
    }

    /// Back to air: filters, history, learning and suspicions restart (the latch stays).
    fn restart(&mut self) {
        self.ring_len = 0;
        self.n_cut = 0;
        self.n_air = 0;
        self.n_steady = 0;
        self.prev_fa = 0.0;
        self.prev_fa2 = 0.0;
        self.pat = [0.0; MAX_FLUTES];
        self.n_quiet = 0;
        self.ep = None;
        self.dm_prev = 0.0;
        self.dm_prev2 = 0.0;
        self.dm_prev3 = 0.0;
        self.f1 = Ewls::default();
        self.f2 = Ewls::default();
        self.m1 = 0.0;
        self.m2 = 0.0;
        self.level = 0.0;
        self.hist = [0.0; MAX_FLUTES];
        self.pending = [None; MAX_FLUTES];
    }
}
