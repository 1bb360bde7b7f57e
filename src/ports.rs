//! Ports: one trait per hardware role the firmware needs, each saying which context calls it. The
//! bodies of the frame ISR, the pulse-end ISR, the sampler and the AC period ([`crate::rt`]) are
//! written once over these traits; a board implements them (hal/) and a thin RTIC app per board
//! binds the bodies to its interrupts; the host simulation implements them in software.
//!
//! Static dispatch only (generics, no trait objects, no function-pointer tables): a board's port
//! is usually a zero-sized type whose methods are one register access each, and the ISR budget is
//! measured with them inlined.
//!
//! # embedded-hal
//!
//! embedded-hal 1.0 has traits for digital pins ([`embedded_hal::digital::OutputPin`],
//! [`embedded_hal::digital::InputPin`]) and delays, but none for ADCs or timers (0.2's `adc` and
//! `timer` modules were dropped in 1.0). So:
//! - step/sign output: [`PinStepPort`] implements [`StepPort`] over six embedded-hal output pins
//!   (any board, tested with embedded-hal-mock). A board whose pins share a GPIO port should write
//!   them with one store instead (the LM3S6965 board does: a masked store sets all three PULSE
//!   lines at once, the timing rule (docs/dev/nc-frame.md, "Timing rules") needs that);
//! - operator inputs: [`PinInputs`] implements [`OperatorInputs`] over embedded-hal input pins;
//! - frame timer, pulse timer, sample clock, force/torque ADC, serial, settings storage: millac's
//!   own traits below.
use crate::nc::Sealed;
use crate::settings::{BoardLimits, IsrBounds, Settings};

/// The Initiator's block queue as the frame sees it: the running block stays at the front until
/// it is done. Frame ISR (the consumer end of the queue the loader fills); the host simulation.
pub trait BlockSource {
    /// The front block, by reference (no copy in the ISR), or None when the queue is empty.
    fn front(&mut self) -> Option<&Sealed>;
    /// Removes the front block (called once, when it is done).
    fn pop(&mut self);
}

/// The block queue's consumer end as the frame's block source (every board's frame ISR): the
/// running block is read in place at the front (never copied) and dequeued when it is done.
impl<const N: usize> BlockSource for heapless::spsc::Consumer<'_, Sealed, N> {
    #[inline(always)]
    fn front(&mut self) -> Option<&Sealed> {
        self.peek()
    }
    #[inline(always)]
    fn pop(&mut self) {
        // The value is dropped unread: only the head index moves.
        let _ = self.dequeue();
    }
}

/// A host queue as the frame's block source (host tests and simulations; feature `std`).
#[cfg(any(test, feature = "std"))]
impl BlockSource for std::collections::VecDeque<Sealed> {
    fn front(&mut self) -> Option<&Sealed> {
        std::collections::VecDeque::front(self)
    }
    fn pop(&mut self) {
        self.pop_front();
    }
}

/// The plan ratio of 1 (Q12): the block's programmed feed as it is.
pub const PLAN_ONE: u32 = 1 << 12;

/// f x k for a plan ratio k in Q12 (see [`FeedCap::planned`]): f <= q0 <= 10^6 and k <= 2^12,
/// so the product fits 32 bits. Frame ISR.
#[inline(always)]
pub fn times_ratio(f: u32, k: u32) -> u32 {
    f.wrapping_mul(k) >> 12
}

/// Where a frame gets the adaptive controller's feed cap. Frame ISR: only the frames that run the
/// feed DDA (linear or circular feeding) read it. A `u32` is a fixed cap; the firmware passes a
/// type that loads the AC task's atomic.
pub trait FeedCap {
    /// Feed number cap: u32::MAX = no cap, 0 = feed hold.
    fn feed_cap(&self) -> u32;
    /// The block's programmed feed `f` times the adaptive controller's plan ratio k (Q12,
    /// 0..=[`PLAN_ONE`]): the frame feeds at min(f x k, cap). k is 1 except under
    /// `FeedCeiling::Plan` (prediction and feedback together, `crate::ac`); read with the cap.
    /// Default: f as it is (no load, no multiply: a frame without the plan ratio).
    #[inline(always)]
    fn planned(&self, f: u32) -> u32 {
        f
    }
    /// The operator's word (see [`crate::nc::operator`]): feed override, rapid override, hold,
    /// abort. Read once per frame. Default: run at 100 %.
    #[inline(always)]
    fn operator(&self) -> u32 {
        crate::nc::operator::RUN
    }
}

impl FeedCap for u32 {
    #[inline(always)]
    fn feed_cap(&self) -> u32 {
        *self
    }
}

/// (AC feed cap, operator word, plan ratio in Q12: [`PLAN_ONE`] outside the plan): a host test's
/// or simulation's inputs.
impl FeedCap for (u32, u32, u32) {
    #[inline(always)]
    fn feed_cap(&self) -> u32 {
        self.0
    }
    #[inline(always)]
    fn operator(&self) -> u32 {
        self.1
    }
    #[inline(always)]
    fn planned(&self, f: u32) -> u32 {
        times_ratio(f, self.2)
    }
}

/// Step (PULSE) and direction (SIGN) lines, X, Y, Z. Frame ISR and pulse-end ISR (one priority:
/// neither preempts the other, so the writes need no lock).
pub trait StepPort {
    /// PULSE line of axis k = bit k of `steps` (X, Y, Z = bits 0..2), all three together.
    fn write_steps(&mut self, steps: u8);
    /// SIGN line of axis k = bit k of `signs` (high = positive).
    fn write_signs(&mut self, signs: u8);
    /// The pin levels: bit k = PULSE line of axis k, bit k + 3 = its SIGN line (the pulse-end ISR
    /// counts the encoder from them).
    fn read_pins(&mut self) -> u8;
    /// Whether a PULSE line is still high when the frame is about to raise the next pulses: the
    /// pulse-end interrupt has not run since the last ones, so the interrupts overran the frame
    /// period and a rising edge would be lost. The frame then holds its pulses back a period
    /// (`Status::frame_overruns`). Frame ISR. Default: never (a board whose frame budget has no
    /// room for the read, or that measures its frame another way: the constant folds away).
    #[inline(always)]
    fn pulse_still_high(&mut self) -> bool {
        false
    }
}

/// The periodic frame timer. Frame ISR (and init, which starts it).
pub trait FrameTimer {
    /// Acknowledges the frame timer's interrupt.
    fn ack(&mut self);
    /// Sets the reload value of the next periods (from [`Board::reload`]).
    fn set_reload(&mut self, reload: u32);
}

/// The one-shot pulse-width timer. Frame ISR (start) and pulse-end ISR (ack).
pub trait PulseTimer {
    /// Starts the one-shot for the pulse width set at init.
    fn start(&mut self);
    /// Acknowledges its interrupt.
    fn ack(&mut self);
}

/// What a board is, as the core needs to know it: its timers' clock, the limits its settings are
/// validated against (rates, ISR times, whether its frame applies the plan ratio), the ISR bounds
/// they derive from, and whether it drives a spindle. One implementation per board, in the
/// board's folder (`hal/<board>/src/facts.rs`, which the host tools include too: one
/// definition). Init (the reloads, the settings' validation; it divides) and the loader.
pub trait Board {
    /// Timer clock in Hz.
    const TIMER_HZ: u32;
    /// Reload value for a period of `clocks` timer clocks (boards differ: some count
    /// `reload + 1` clocks per period).
    fn reload(clocks: u32) -> u32;
    /// The limits the settings are validated against (`Settings::validate`).
    const LIMITS: BoardLimits;
    /// The ISR bounds [`Board::LIMITS`] derive from, on a board that states them (None: the
    /// limits' generic rule, see `BoardLimits`).
    const ISR_BOUNDS: Option<IsrBounds>;
    /// The board drives a spindle: a line that changes M3/M4/M5 or S waits until the motion
    /// queued before it has finished (grbl's buffer sync), then the loader applies it.
    const SPINDLE: bool;

    /// The most core cycles a frame may take with settings `s` (the board's
    /// `BoardLimits::frame_work_allowed_ns`), less the exception entry and return that a
    /// measurement inside the handler does not see; None without ISR bounds. Init (it divides).
    fn frame_limit_cycles(s: &Settings) -> Option<u32> {
        let b = Self::ISR_BOUNDS?;
        let ns = Self::LIMITS.frame_work_allowed_ns(s);
        let cycles = ns * u64::from(b.core_hz) / 1_000_000_000;
        Some(
            u32::try_from(cycles)
                .unwrap_or(u32::MAX)
                .saturating_sub(b.entry_exit_cycles),
        )
    }
}

/// The sample clock of the force/torque ADC. Sampler task (its interrupt).
pub trait SampleClock {
    /// Acknowledges the sample clock's interrupt.
    fn ack(&mut self);
    /// Stops the clock (the ADC has gone).
    fn stop(&mut self);
}

/// Codes of one simultaneous conversion: [T, Fu, Fv], 12 bits each.
pub type Codes = [u16; 3];

/// What the ADC gave at one tick of the sample clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Conversion {
    /// A fresh conversion.
    Fresh(Codes),
    /// No fresh conversion this tick (a dropout: the converter did not answer). The sample clock
    /// goes on; the AC period that sees no fresh sample holds (`Alarm::NoSamples`).
    Missed,
    /// The ADC has gone for good (the simulation's host closed the link): the sampler stops.
    Lost,
}

/// The force/torque ADC: three channels converted together, and optionally a sound channel at
/// [`crate::wire::SOUND_PER_SAMPLE`] times the sample rate (the chatter detector's microphone).
/// Sampler task.
pub trait ForceTorqueAdc {
    /// One conversion, given the encoder counts at the sample (a simulated ADC computes the cut
    /// from them; a real one ignores them).
    fn sample(&mut self, index: u32, encoder: [i32; 3]) -> Conversion;

    /// The sound channel's codes since the previous sample, oldest first (after `sample`); None
    /// when the board has no microphone (the default) or it delivered none.
    fn sound(&mut self) -> Option<[u16; crate::wire::SOUND_PER_SAMPLE]> {
        None
    }
}

/// The operator's serial line (grbl protocol, later). Loader task.
pub trait Serial {
    /// Reads what has arrived into `buf`, returns the count (0: nothing yet).
    fn read(&mut self, buf: &mut [u8]) -> usize;
    /// Writes as much of `bytes` as fits, returns the count.
    fn write(&mut self, bytes: &[u8]) -> usize;
}

/// Persistent settings. Init (load) and loader task (store).
pub trait SettingsStorage {
    /// Reads the stored image into `buf`, returns its length, or None when nothing is stored.
    fn load(&mut self, buf: &mut [u8]) -> Option<usize>;
    /// Stores an image; false when the storage refused it.
    fn store(&mut self, image: &[u8]) -> bool;
}

/// The operator's inputs, active = true: raw from [`OperatorInputs::read`], debounced by
/// [`crate::inputs::Debouncer`]. Board's periodic input task, loader task.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Inputs {
    pub estop: bool,
    pub feed_hold: bool,
    pub cycle_start: bool,
    /// Axis limit switches, bit k = axis k.
    pub limits: u8,
    /// The probe touches (as wired: a probe closing to ground; `$6` inverts it). Not debounced.
    pub probe: bool,
}

/// Operator inputs (e-stop, feed hold, cycle start, limits), raw. The board's periodic input task,
/// which passes each sample to [`crate::inputs::Debouncer::sample`].
pub trait OperatorInputs {
    fn read(&mut self) -> Inputs;
}

/// A [`StepPort`] over six embedded-hal output pins (any board). Pin errors are ignored: a GPIO
/// write on the boards we know cannot fail, and the frame has no way to report one. The three
/// PULSE lines are written one after the other (a few instructions apart); boards with a shared
/// GPIO port should implement [`StepPort`] with one store.
pub struct PinStepPort<S, D> {
    pub step: [S; 3],
    pub sign: [D; 3],
    /// The levels last written (read back by `read_pins`).
    levels: u8,
}

impl<S: embedded_hal::digital::OutputPin, D: embedded_hal::digital::OutputPin> PinStepPort<S, D> {
    pub fn new(step: [S; 3], sign: [D; 3]) -> Self {
        PinStepPort {
            step,
            sign,
            levels: 0,
        }
    }
}

impl<S: embedded_hal::digital::OutputPin, D: embedded_hal::digital::OutputPin> StepPort
    for PinStepPort<S, D>
{
    fn write_steps(&mut self, steps: u8) {
        for (k, pin) in self.step.iter_mut().enumerate() {
            let _ = pin.set_state((steps & (1 << k) != 0).into());
        }
        self.levels = (self.levels & !0b111) | (steps & 0b111);
    }

    fn write_signs(&mut self, signs: u8) {
        for (k, pin) in self.sign.iter_mut().enumerate() {
            let _ = pin.set_state((signs & (1 << k) != 0).into());
        }
        self.levels = (self.levels & 0b111) | ((signs & 0b111) << 3);
    }

    fn read_pins(&mut self) -> u8 {
        self.levels
    }
}

/// [`OperatorInputs`] over embedded-hal input pins with pull-ups, contacts to ground (the usual
/// wiring). The buttons and limit switches are normally open: active low. The e-stop is a normally
/// closed contact: closed (low) while released, so it is active HIGH: pressed, or its wire broken,
/// the pull-up takes the pin high and the machine stops. A pin that cannot be read counts as
/// active (safe side). No debouncing here: [`crate::inputs::Debouncer`] does it.
pub struct PinInputs<P> {
    pub estop: P,
    pub feed_hold: P,
    pub cycle_start: P,
    pub limits: [P; 3],
    /// The probe (normally open to ground: touching reads low).
    pub probe: P,
}

impl<P: embedded_hal::digital::InputPin> OperatorInputs for PinInputs<P> {
    fn read(&mut self) -> Inputs {
        let active = |p: &mut P| p.is_low().unwrap_or(true);
        let estop = self.estop.is_high().unwrap_or(true);
        let mut limits = 0u8;
        for (k, p) in self.limits.iter_mut().enumerate() {
            if active(p) {
                limits |= 1 << k;
            }
        }
        Inputs {
            estop,
            feed_hold: active(&mut self.feed_hold),
            cycle_start: active(&mut self.cycle_start),
            limits,
            probe: active(&mut self.probe),
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use embedded_hal_mock::eh1::digital::{Mock as PinMock, State, Transaction as T};

    #[test]
    fn pin_step_port_sets_each_line_and_reads_back() {
        let step = [
            PinMock::new(&[T::set(State::High), T::set(State::Low)]),
            PinMock::new(&[T::set(State::Low), T::set(State::Low)]),
            PinMock::new(&[T::set(State::High), T::set(State::Low)]),
        ];
        let sign = [
            PinMock::new(&[T::set(State::Low)]),
            PinMock::new(&[T::set(State::High)]),
            PinMock::new(&[T::set(State::High)]),
        ];
        let mut p = PinStepPort::new(step, sign);
        p.write_steps(0b101);
        p.write_signs(0b110);
        assert_eq!(p.read_pins(), 0b110_101);
        p.write_steps(0);
        assert_eq!(p.read_pins(), 0b110_000);
        for pin in p.step.iter_mut().chain(p.sign.iter_mut()) {
            pin.done();
        }
    }

    /// Buttons and limits active low; the e-stop (normally closed) active high: released (contact
    /// closed, low) it is not an e-stop, pressed or with its wire broken (high) it is.
    #[test]
    fn pin_inputs_are_active_low_the_estop_normally_closed() {
        let mut i = PinInputs {
            estop: PinMock::new(&[T::get(State::Low), T::get(State::High)]),
            feed_hold: PinMock::new(&[T::get(State::Low), T::get(State::High)]),
            cycle_start: PinMock::new(&[T::get(State::High), T::get(State::Low)]),
            limits: [
                PinMock::new(&[T::get(State::High), T::get(State::High)]),
                PinMock::new(&[T::get(State::Low), T::get(State::High)]),
                PinMock::new(&[T::get(State::High), T::get(State::Low)]),
            ],
            probe: PinMock::new(&[T::get(State::High), T::get(State::Low)]),
        };
        assert_eq!(
            i.read(),
            Inputs {
                estop: false,
                feed_hold: true,
                cycle_start: false,
                limits: 0b010,
                probe: false,
            }
        );
        assert_eq!(
            i.read(),
            Inputs {
                estop: true,
                feed_hold: false,
                cycle_start: true,
                limits: 0b100,
                probe: true,
            }
        );
        for pin in [
            &mut i.estop,
            &mut i.feed_hold,
            &mut i.cycle_start,
            &mut i.probe,
        ]
        .into_iter()
        .chain(i.limits.iter_mut())
        {
            pin.done();
        }
    }
}
