//! Debouncing of the operator's inputs (e-stop, feed hold, cycle start, limit switches) and the
//! events the loader acts on. [`Debouncer::sample`] is called by the board's periodic input task
//! (e.g. every 1 ms, with [`crate::ports::OperatorInputs::read`]); the loader task takes the
//! events ([`Debouncer::take`]) and acknowledges the alarm latch ([`Debouncer::acknowledge`], on
//! `$X` or a soft reset). Both contexts share one `Debouncer` (an RTIC shared resource: each call
//! is a few dozen instructions, so the loader's lock is short). Pure logic, host-tested.
//!
//! # Rules
//!
//! - **Debounce.** A line changes its debounced state only after `samples` consecutive raw
//!   samples that agree on the new state (any sample equal to the current debounced state starts
//!   the count again). With `samples` = [`DEBOUNCE_SAMPLES`] = 10 and a 1 ms task, a line settles
//!   10 ms after its last bounce.
//! - **Safety first.** E-stop and the limit switches go active on the FIRST active raw sample:
//!   no debounce delay between a switch closing (or an e-stop wire breaking) and the alarm. Only
//!   their release is debounced. A bounce on a safety line can therefore trip the alarm, never
//!   delay it; a spurious trip costs the operator an `$X`, a delayed one could cost the machine.
//! - **Edges.** Feed hold and cycle start act on their debounced rising edge (pressed) only, so
//!   a held button acts once; releasing does nothing. Edges are kept until the loader takes them,
//!   so a loader slower than the input task misses none (several presses between two takes count
//!   as one).
//! - **Alarm latch.** An active e-stop or limit switch latches an alarm ([`Trip`]: which lines
//!   tripped it, accumulated while latched). It stays latched after the line is released, until
//!   the loader acknowledges it; the acknowledgement is refused while the e-stop is still active
//!   (debounced, so also during the release's bounce). A limit switch still closed at the
//!   acknowledgement is let be (the machine can be jogged off it, as grbl's): it trips again
//!   only once it has opened (debounced) and closes anew.
//! - At start every line is inactive: an e-stop or limit active at power-up trips at the first
//!   sample; a button held at power-up acts once `samples` samples later.
use crate::ports::Inputs;

/// Default debounce length in samples (10 ms with a 1 ms input task).
pub const DEBOUNCE_SAMPLES: u8 = 10;

/// Bit positions of the lines in the internal masks.
const ESTOP: u16 = 1 << 0;
const FEED_HOLD: u16 = 1 << 1;
const CYCLE_START: u16 = 1 << 2;
const LIMITS_SHIFT: u32 = 3;
/// Lines that trip at once and latch the alarm: e-stop and all eight limit bits.
const SAFETY: u16 = ESTOP | (0xff << LIMITS_SHIFT);
const LINES: usize = 3 + 8;

fn bits(i: Inputs) -> u16 {
    (i.estop as u16)
        | (i.feed_hold as u16) << 1
        | (i.cycle_start as u16) << 2
        | (i.limits as u16) << LIMITS_SHIFT
}

fn inputs(b: u16) -> Inputs {
    Inputs {
        estop: b & ESTOP != 0,
        feed_hold: b & FEED_HOLD != 0,
        cycle_start: b & CYCLE_START != 0,
        limits: (b >> LIMITS_SHIFT) as u8,
        probe: false,
    }
}

/// A simulated machine's limit switches (the QEMU board's machine model and the host benches;
/// a real board reads its pins): where the machine stands at power-up and where each axis's
/// switch is, in true BLU (the counters start at 0 wherever the machine stands, so true =
/// counter + start); a switch is closed at and beyond its position on its side.
///
/// File form (`machine.txt` in the QEMU board's working directory, one line; [`Self::parse`],
/// written by [`core::fmt::Display`]): `start X Y Z switches X Y Z negative MASK [probe Z]
/// [setter X Y Z R] [tool N L]...`, integers in BLU, MASK's bit k set when axis k's switch is
/// at its negative end; `probe Z`: a flat surface (a touch plate, the stock's top) the probe
/// touches at and below true Z; `setter X Y Z R`: a tool setter whose square pad (R either side
/// of X, Y) the probe touches at and below true Z; `tool N L`: tool N (1..16) is L long (its tip
/// L below the spindle's: the probe touches with the tip; tool 0, none, and any tool not given
/// are 0 long).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LimitSwitches {
    pub start: [i32; 3],
    pub at: [i32; 3],
    /// Bit k: axis k's switch closes at and below its position (else at and above).
    pub negative: u8,
    /// The probe touches at and below this true Z (None: nothing to touch).
    pub probe: Option<i32>,
    /// A tool setter: X, Y, the pad's top Z and its half width R (None: no setter).
    pub setter: Option<[i32; 4]>,
    /// The lengths of tools 1..16 (index 0 is tool 1).
    pub tools: [i32; TOOLS],
}

/// The tools a machine model knows the lengths of (1..=TOOLS).
pub const TOOLS: usize = 16;

impl LimitSwitches {
    /// The switches closed with the counters at `counts` (bit k: axis k).
    pub fn closed(&self, counts: [i32; 3]) -> u8 {
        (0..3).fold(0, |m, k| {
            let d = i64::from(counts[k]) + i64::from(self.start[k]) - i64::from(self.at[k]);
            let on = if self.negative & (1 << k) != 0 {
                d <= 0
            } else {
                d >= 0
            };
            m | (u8::from(on) << k)
        })
    }

    /// The probe touches with the counters at `counts` and tool `tool` in the spindle: the
    /// plate under the tool's tip, or the setter's pad.
    pub fn touches(&self, counts: [i32; 3], tool: u8) -> bool {
        let length = match usize::from(tool).checked_sub(1) {
            Some(k) => self.tools.get(k).copied().unwrap_or(0),
            None => 0,
        };
        let t = |k: usize| i64::from(counts[k]) + i64::from(self.start[k]);
        let tip = t(2) - i64::from(length);
        let plate = self.probe.is_some_and(|z| tip <= i64::from(z));
        let setter = self.setter.is_some_and(|[x, y, z, r]| {
            (t(0) - i64::from(x)).abs() <= i64::from(r)
                && (t(1) - i64::from(y)).abs() <= i64::from(r)
                && tip <= i64::from(z)
        });
        plate || setter
    }

    /// Reads the file form; None when it is not exactly that.
    pub fn parse(text: &str) -> Option<LimitSwitches> {
        let mut w = text.split_whitespace();
        let mut three = |name: &str| -> Option<[i32; 3]> {
            (w.next()? == name).then_some(())?;
            let mut v = [0; 3];
            for x in v.iter_mut() {
                *x = w.next()?.parse().ok()?;
            }
            Some(v)
        };
        let start = three("start")?;
        let at = three("switches")?;
        (w.next()? == "negative").then_some(())?;
        let negative: u8 = w.next()?.parse().ok().filter(|m| *m <= 7)?;
        let mut sw = LimitSwitches {
            start,
            at,
            negative,
            ..LimitSwitches::default()
        };
        let int = |w: &mut core::str::SplitWhitespace| -> Option<i32> { w.next()?.parse().ok() };
        while let Some(word) = w.next() {
            match word {
                "probe" if sw.probe.is_none() => sw.probe = Some(int(&mut w)?),
                "setter" if sw.setter.is_none() => {
                    let mut v = [0; 4];
                    for x in v.iter_mut() {
                        *x = int(&mut w)?;
                    }
                    sw.setter = Some(v).filter(|v| v[3] >= 0);
                    sw.setter?;
                }
                "tool" => {
                    let n = usize::try_from(int(&mut w)?)
                        .ok()
                        .filter(|n| (1..=TOOLS).contains(n))?;
                    let slot = sw.tools.get_mut(n - 1)?;
                    *slot = int(&mut w)?;
                }
                _ => return None,
            }
        }
        Some(sw)
    }
}

impl core::fmt::Display for LimitSwitches {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let ([a, b, c], [x, y, z]) = (self.start, self.at);
        write!(
            f,
            "start {a} {b} {c} switches {x} {y} {z} negative {}",
            self.negative
        )?;
        if let Some(p) = self.probe {
            write!(f, " probe {p}")?;
        }
        if let Some([x, y, z, r]) = self.setter {
            write!(f, " setter {x} {y} {z} {r}")?;
        }
        for (k, l) in self.tools.iter().enumerate().filter(|(_, l)| **l != 0) {
            write!(f, " tool {} {l}", k + 1)?;
        }
        Ok(())
    }
}

/// What latched the alarm: the e-stop and the limit switches (bit k = axis k) seen active since
/// the latch was set.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Trip {
    pub estop: bool,
    pub limits: u8,
}

/// The events since the loader's last [`Debouncer::take`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Events {
    /// Feed hold was pressed (debounced rising edge).
    pub feed_hold: bool,
    /// Cycle start was pressed (debounced rising edge).
    pub cycle_start: bool,
    /// The alarm latch was set (it was clear): stop, flush, raise the alarm. Which lines:
    /// [`Debouncer::latched`].
    pub tripped: bool,
}

/// The debouncer of the operator's inputs, with the feed hold / cycle start edges and the alarm
/// latch (see the module doc for the rules).
#[derive(Clone, Debug)]
pub struct Debouncer {
    samples: u8,
    /// Debounced state, bit per line.
    stable: u16,
    /// Consecutive raw samples that differ from `stable`, per line.
    count: [u8; LINES],
    /// Pending events for the loader.
    events: Events,
    /// The alarm latch: the safety lines seen active since it was set (0: clear).
    latch: u16,
    /// The lines that trip the latch: the e-stop, and the limit switches unless
    /// [`Debouncer::set_limit_trips`] turned them off.
    trips: u16,
    /// The probe as last sampled: not debounced (a probing move stops at its first touch).
    probe: bool,
    /// Limit switches still closed when the alarm was acknowledged: they trip again only once
    /// they have opened.
    let_be: u16,
}

impl Default for Debouncer {
    fn default() -> Self {
        Self::new(DEBOUNCE_SAMPLES)
    }
}

impl Debouncer {
    /// A debouncer that needs `samples` consecutive equal samples to change a line (0 counts as
    /// 1: no debouncing). Every line starts inactive, the latch clear.
    pub const fn new(samples: u8) -> Self {
        Debouncer {
            samples: if samples == 0 { 1 } else { samples },
            stable: 0,
            count: [0; LINES],
            events: Events {
                feed_hold: false,
                cycle_start: false,
                tripped: false,
            },
            latch: 0,
            trips: SAFETY,
            probe: false,
            let_be: 0,
        }
    }

    /// Whether a closing limit switch trips the latch (on at start): off while the homing cycle
    /// seeks the switches and with hard limits off (`$21=0`). The switches still go active at
    /// once and show in [`Debouncer::inputs`]. Loader task.
    pub fn set_limit_trips(&mut self, on: bool) {
        self.trips = if on { SAFETY } else { ESTOP };
    }

    /// One raw sample of the inputs. Board's periodic input task. Returns the debounced inputs.
    pub fn sample(&mut self, raw: Inputs) -> Inputs {
        let raw_probe = raw.probe;
        let raw = bits(raw);
        let before = self.stable;
        let mut stable = before;
        for (k, count) in self.count.iter_mut().enumerate() {
            let bit = 1u16 << k;
            if (raw ^ before) & bit == 0 {
                *count = 0;
            } else if raw & bit & SAFETY != 0 {
                // A safety line going active: at once.
                stable |= bit;
                *count = 0;
            } else {
                *count = count.saturating_add(1);
                if *count >= self.samples {
                    stable ^= bit;
                    *count = 0;
                }
            }
        }
        self.stable = stable;
        let rising = stable & !before;
        self.events.feed_hold |= rising & FEED_HOLD != 0;
        self.events.cycle_start |= rising & CYCLE_START != 0;
        self.let_be &= stable;
        let active = stable & self.trips & !self.let_be;
        if active != 0 {
            self.events.tripped |= self.latch == 0;
            self.latch |= active;
        }
        self.probe = raw_probe;
        self.inputs()
    }

    /// The debounced inputs as of the last sample, the probe as sampled. Any context that holds
    /// the debouncer.
    pub fn inputs(&self) -> Inputs {
        Inputs {
            probe: self.probe,
            ..inputs(self.stable)
        }
    }

    /// Takes (and clears) the events since the last call. Loader task.
    pub fn take(&mut self) -> Events {
        core::mem::take(&mut self.events)
    }

    /// The latched alarm, if any: which safety lines were active since it was set.
    pub fn latched(&self) -> Option<Trip> {
        if self.latch == 0 {
            return None;
        }
        let t = inputs(self.latch);
        Some(Trip {
            estop: t.estop,
            limits: t.limits,
        })
    }

    /// The operator acknowledges the alarm (`$X`, soft reset). Loader task. Clears the latch
    /// only when the e-stop is not active (debounced); a limit switch still closed is let be
    /// until it opens. Returns true when the latch is clear afterwards (also when nothing was
    /// latched), false when it stays latched.
    pub fn acknowledge(&mut self) -> bool {
        if self.stable & self.trips & ESTOP == 0 {
            self.let_be = self.stable & SAFETY & !ESTOP;
            self.latch = 0;
            self.events.tripped = false;
        }
        self.latch == 0
    }

    /// The alarm is latched and the e-stop is still active: `$X` would be refused. Loader task
    /// (the boards' `LoaderBoard::latch_active`).
    pub fn latch_active(&self) -> bool {
        self.latch != 0 && self.stable & ESTOP != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The machine model's switches close at their positions on their sides, from the start
    /// position; the file form reads back what it writes, and nothing else.
    #[test]
    fn limit_switches_close_at_their_positions_and_read_back() {
        let sw = LimitSwitches {
            start: [-100, 0, 50],
            at: [0, -30, 60],
            negative: 0b010,
            ..LimitSwitches::default()
        };
        assert_eq!(sw.closed([0, 0, 0]), 0);
        assert_eq!(sw.closed([100, -30, 10]), 0b111);
        assert_eq!(sw.closed([99, -29, 9]), 0);
        let text = std::format!("{sw}");
        assert_eq!(text, "start -100 0 50 switches 0 -30 60 negative 2");
        assert_eq!(LimitSwitches::parse(&text), Some(sw));
        assert_eq!(LimitSwitches::parse(&std::format!("{text}\n")), Some(sw));
        for bad in [
            "",
            "start 1 2 3",
            "start 1 2 3 switches 1 2 3 negative 8",
            &std::format!("{text} 1"),
        ] {
            assert_eq!(LimitSwitches::parse(bad), None, "{bad}");
        }
        // A probe surface at true Z 40: the counters' Z -10 is true Z 40.
        let with = LimitSwitches {
            probe: Some(40),
            ..sw
        };
        assert_eq!(LimitSwitches::parse(&std::format!("{with}")), Some(with));
        assert!(
            !sw.touches([0, 0, -10], 0)
                && !with.touches([0, 0, -9], 0)
                && with.touches([0, 0, -10], 0)
        );
        // A setter at true X 0, Y 0, its pad 5 either side with its top at true Z 20, and
        // tool 3 is 30 long: tool 3's tip touches the pad 30 higher than no tool.
        let mut tools = [0; TOOLS];
        tools[2] = 30;
        let setter = LimitSwitches {
            setter: Some([0, 0, 20, 5]),
            tools,
            ..sw
        };
        let text = std::format!("{setter}");
        assert_eq!(
            text,
            "start -100 0 50 switches 0 -30 60 negative 2 setter 0 0 20 5 tool 3 30"
        );
        assert_eq!(LimitSwitches::parse(&text), Some(setter));
        // Over the pad (true X 105 - 100 = 5), true Z 50 - 30 = 20 with no tool: touching.
        assert!(setter.touches([105, 0, -30], 0));
        assert!(!setter.touches([105, 0, -29], 0));
        assert!(!setter.touches([106, 0, -30], 0), "beside the pad");
        assert!(setter.touches([100, 0, 0], 3) && !setter.touches([100, 0, 1], 3));
        for bad in [
            "start 1 2 3 switches 1 2 3 negative 0 tool 17 5",
            "start 1 2 3 switches 1 2 3 negative 0 tool 0 5",
            "start 1 2 3 switches 1 2 3 negative 0 setter 1 2 3",
            "start 1 2 3 switches 1 2 3 negative 0 setter 1 2 3 -1",
            "start 1 2 3 switches 1 2 3 negative 0 probe 1 probe 2",
        ] {
            assert_eq!(LimitSwitches::parse(bad), None, "{bad}");
        }
    }

    /// With limit trips off (homing, `$21=0`) a closing limit switch shows at once in the inputs
    /// and latches nothing; the e-stop still trips. Turned back on, a switch still closed trips.
    #[test]
    fn limit_trips_off_leave_the_switches_to_the_homing_cycle() {
        let mut d = Debouncer::new(3);
        d.set_limit_trips(false);
        let x = Inputs {
            limits: 0b001,
            ..IDLE
        };
        assert_eq!(d.sample(x).limits, 0b001);
        assert_eq!(d.take(), Events::default());
        assert_eq!(d.latched(), None);
        assert!(d.acknowledge());
        d.sample(Inputs { estop: true, ..x });
        assert!(d.take().tripped);
        assert_eq!(d.latched().map(|t| (t.estop, t.limits)), Some((true, 0)));
        let mut d = Debouncer::new(3);
        d.set_limit_trips(false);
        d.sample(x);
        d.set_limit_trips(true);
        d.sample(x);
        assert!(d.take().tripped);
        assert_eq!(d.latched().map(|t| t.limits), Some(0b001));
    }

    const IDLE: Inputs = Inputs {
        estop: false,
        feed_hold: false,
        cycle_start: false,
        limits: 0,
        probe: false,
    };

    fn hold(on: bool) -> Inputs {
        Inputs {
            feed_hold: on,
            ..IDLE
        }
    }

    fn start(on: bool) -> Inputs {
        Inputs {
            cycle_start: on,
            ..IDLE
        }
    }

    fn estop(on: bool) -> Inputs {
        Inputs { estop: on, ..IDLE }
    }

    /// Feeds a sequence; returns the debounced value of `line` after each sample.
    fn run(d: &mut Debouncer, seq: &[Inputs], line: fn(Inputs) -> bool) -> Vec<bool> {
        seq.iter().map(|&i| line(d.sample(i))).collect()
    }

    #[test]
    fn a_bouncing_button_changes_after_n_equal_samples() {
        let mut d = Debouncer::new(3);
        let b = |s: &str| s.bytes().map(|c| hold(c == b'1')).collect::<Vec<_>>();
        // Press with bounce: 1 0 1 1 0 1 1 1 -> active only after the third 1 in a row.
        let got = run(&mut d, &b("10110111"), |i| i.feed_hold);
        assert_eq!(got, [false, false, false, false, false, false, false, true]);
        assert!(d.take().feed_hold);
        // Release with bounce: 0 1 0 0 1 0 0 0 -> inactive only after the third 0 in a row.
        let got = run(&mut d, &b("01001000"), |i| i.feed_hold);
        assert_eq!(got, [true, true, true, true, true, true, true, false]);
        // Releasing is no event; short glitches never reach the output.
        assert_eq!(d.take(), Events::default());
        let got = run(&mut d, &b("1101101"), |i| i.feed_hold);
        assert!(got.iter().all(|&a| !a));
        assert_eq!(d.take(), Events::default());
        assert_eq!(d.inputs(), IDLE);
    }

    #[test]
    fn a_held_button_acts_once() {
        let mut d = Debouncer::new(3);
        let mut presses = 0;
        for _ in 0..100 {
            d.sample(start(true));
            presses += d.take().cycle_start as u32;
        }
        assert_eq!(presses, 1);
        // Release and press again: a second action.
        for _ in 0..3 {
            d.sample(IDLE);
        }
        for _ in 0..3 {
            d.sample(start(true));
        }
        let e = d.take();
        assert!(e.cycle_start && !e.feed_hold && !e.tripped);
        // Presses between two takes are kept (not lost by a slow loader).
        for i in [IDLE, IDLE, IDLE, hold(true), hold(true), hold(true), IDLE] {
            d.sample(i);
        }
        assert!(d.take().feed_hold);
        assert!(!d.take().feed_hold);
    }

    #[test]
    fn estop_and_limits_trip_on_the_first_active_sample() {
        let mut d = Debouncer::new(10);
        assert!(d.sample(estop(true)).estop);
        assert!(d.take().tripped);
        assert_eq!(
            d.latched(),
            Some(Trip {
                estop: true,
                limits: 0
            })
        );
        let mut d = Debouncer::new(10);
        let limit_y = Inputs {
            limits: 0b010,
            ..IDLE
        };
        assert_eq!(d.sample(limit_y).limits, 0b010);
        assert!(d.take().tripped);
        assert_eq!(
            d.latched(),
            Some(Trip {
                estop: false,
                limits: 0b010
            })
        );
        // A second limit while latched adds to the trip, no new trip event.
        d.sample(Inputs {
            limits: 0b100,
            ..IDLE
        });
        assert!(!d.take().tripped);
        assert_eq!(d.latched().map(|t| t.limits), Some(0b110));
    }

    #[test]
    fn the_latch_survives_release_until_acknowledged() {
        let mut d = Debouncer::new(3);
        d.sample(estop(true));
        assert!(d.take().tripped);
        // Bouncing release: the debounced e-stop stays active, the ack is refused.
        for on in [false, true, false, false] {
            d.sample(estop(on));
            assert!(d.inputs().estop);
            assert!(!d.acknowledge());
        }
        // Released for good (3 samples): the latch is still set...
        d.sample(estop(false));
        assert!(!d.inputs().estop);
        assert!(d.latched().is_some());
        for _ in 0..50 {
            d.sample(IDLE);
        }
        assert!(d.latched().is_some());
        // ...until acknowledged.
        assert!(d.acknowledge());
        assert_eq!(d.latched(), None);
        assert!(d.acknowledge());
        // And it trips again.
        d.sample(estop(true));
        assert!(d.take().tripped);
    }

    /// A limit switch still closed does not refuse the acknowledgement (the e-stop does): it is
    /// let be, so the machine can be jogged off it; it does not trip again while it stays
    /// closed, and trips again once it has opened (debounced) and closes anew. Another switch
    /// trips meanwhile.
    #[test]
    fn a_limit_still_closed_is_let_be_until_it_opens() {
        let mut d = Debouncer::new(2);
        let limit_x = Inputs {
            limits: 0b001,
            ..IDLE
        };
        d.sample(limit_x);
        assert!(d.take().tripped);
        assert!(!d.latch_active(), "a limit alone does not refuse $X");
        assert!(d.acknowledge());
        assert_eq!(d.latched(), None);
        for _ in 0..20 {
            d.sample(limit_x);
        }
        assert_eq!(d.take(), Events::default(), "no trip while it stays closed");
        assert_eq!(d.latched(), None);
        // Y closes meanwhile: that trips.
        d.sample(Inputs {
            limits: 0b011,
            ..IDLE
        });
        assert!(d.take().tripped);
        assert_eq!(d.latched().map(|t| t.limits), Some(0b010));
        assert!(d.acknowledge());
        // Both open (one sample: not yet debounced), close again: still let be.
        d.sample(IDLE);
        d.sample(limit_x);
        assert_eq!(d.take(), Events::default());
        // Open for good, then closing trips again.
        d.sample(IDLE);
        d.sample(IDLE);
        d.sample(limit_x);
        assert!(d.take().tripped);
        // The e-stop still refuses the acknowledgement.
        d.sample(estop(true));
        assert!(d.latch_active());
        assert!(!d.acknowledge());
    }

    #[test]
    fn zero_samples_means_no_debouncing() {
        let mut d = Debouncer::new(0);
        assert!(d.sample(hold(true)).feed_hold);
        assert!(!d.sample(IDLE).feed_hold);
        assert!(d.take().feed_hold);
    }
}
