//! The bodies of the frame ISR and the pulse-end ISR over the ports (frame ISR, pulse-end ISR): a
//! board's RTIC app binds them to its timer interrupts, both at the same, highest priority.
//!
//! # Timing rule (why pulses and signs are correct by construction)
//!
//! Neither ISR preempts the other: the pulse end waits (tail-chains) until the frame is done. Each
//! frame first outputs the pulses computed in the PREVIOUS frame (`pending`): one store sets the
//! PULSE lines high, then the one-shot pulse timer starts for the pulse width. Only then does the
//! frame compute the next pulses `p` (whose time varies with the block); their SIGN lines are
//! written
//! - at once, if this frame emitted no pulse (the PULSE lines are low), or
//! - by the pulse-end ISR, right after it sets the PULSE lines low again.
//!
//! So a PULSE line is high for at least the pulse width (the timer runs that long, and the falling
//! edge waits for the frame's work if that is longer), a SIGN line changes only while every PULSE
//! line is low, and the next rising edge comes one frame period after this frame's rising edge.
//! The SIGN-to-rising-edge gap is therefore at least the period minus max(pulse width, frame work)
//! minus the pulse-end ISR's own time. A board that states its measured ISR times
//! (`settings::BoardLimits`) has exactly that checked by `Settings::validate` at the shortest
//! (rapid) period, together with a cap on the two ISRs' share of the CPU; without them
//! (`BoardLimits::GENERIC`, the QEMU board) the check is pulse width + sign setup <= 75 % of the
//! rapid period, which leaves the sign setup time as long as the frame's work stays within the
//! remaining 25 %.
//! Rising edges keep the timer's period exactly: the pulse store is the frame's first work after
//! the acknowledge, at a fixed number of instructions from the interrupt.
//!
//! The frame timer runs at W0 while contouring, dwelling or idle, and is retimed to the rapid rate
//! while the frame asks for `Rate::Rapid` (PTP), so both rates come from one timer.
//!
//! No locks, no logging, no allocation, no panic path (a QEMU test scans the built ISRs for calls
//! and traps).
use super::status::{FrameWriter, Home, PulseWriter};
use crate::nc::{Frame, Pulses, Rate};
use crate::ports::{BlockSource, Board, FeedCap, FrameTimer, PulseTimer, StepPort};
use crate::settings::Settings;

/// Frame timer reload values for the two rates (from `Board::reload`, computed in init).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reloads {
    pub feed: u32,
    pub rapid: u32,
}

impl Reloads {
    /// The reloads of a board's frame timer (its clock, `C`) for the settings' W0 (`frame_hz`)
    /// and rapid rate (`rapid_hz`). Init context (and the host board).
    pub fn for_settings<C: Board>(settings: &Settings) -> Reloads {
        Reloads {
            feed: C::reload(super::clocks_for_hz(C::TIMER_HZ, settings.frame_hz)),
            rapid: C::reload(super::clocks_for_hz(C::TIMER_HZ, settings.rapid_hz)),
        }
    }

    /// The reload of `rate`.
    pub fn of(&self, rate: Rate) -> u32 {
        match rate {
            Rate::Feed => self.feed,
            Rate::Rapid => self.rapid,
        }
    }
}

/// The frame ISR's state (an RTIC local resource of the frame task). `PLAN`: the frame applies
/// the AC's plan ratio (`FeedCeiling::Plan`, `$263=2`: one load and a multiply in the frames that
/// feed); a board without room for it in its frame budget builds `FrameTask<false>` (the ratio
/// is the constant 1, folded away) and refuses `$263=2` (`BoardLimits::plan_ratio`).
pub struct FrameTask<H, const PLAN: bool = true> {
    pub frame: Frame,
    pending: Pulses,
    rate: Rate,
    reloads: Reloads,
    /// The frame ISR's handle on the status words (zero-sized in the firmware: see
    /// `status::Home`).
    status: FrameWriter<H>,
}

/// The AC's feed cap and plan ratio (one load each, only by the frames that feed; the ratio only
/// with `PLAN`) and the operator's word (one load per frame) as the frame reads them.
struct StatusCap<'a, const PLAN: bool>(&'a super::Status);

impl<const PLAN: bool> FeedCap for StatusCap<'_, PLAN> {
    #[inline(always)]
    fn feed_cap(&self) -> u32 {
        self.0.feed_cap.get()
    }
    #[inline(always)]
    fn operator(&self) -> u32 {
        self.0.operator.get()
    }
    #[inline(always)]
    fn planned(&self, f: u32) -> u32 {
        if PLAN {
            crate::ports::times_ratio(f, self.0.plan_ratio.get())
        } else {
            f
        }
    }
}

impl<H: Home, const PLAN: bool> FrameTask<H, PLAN> {
    /// A frame task at the feed rate (the frame timer starts with `reloads.feed`), publishing
    /// through `status`. Init context.
    pub const fn new(frame: Frame, reloads: Reloads, status: FrameWriter<H>) -> Self {
        FrameTask {
            frame,
            pending: Pulses { steps: 0, signs: 0 },
            rate: Rate::Feed,
            reloads,
            status,
        }
    }

    /// One frame interrupt. Frame ISR.
    #[inline(always)]
    pub fn run(
        &mut self,
        port: &mut impl StepPort,
        timer: &mut impl FrameTimer,
        pulse: &mut impl PulseTimer,
        src: &mut impl BlockSource,
    ) {
        timer.ack();
        let pending = self.pending;
        if pending.steps != 0 {
            if port.pulse_still_high() {
                // Overrun: the last pulse has not ended (the pulse-end interrupt waits behind this
                // one). Raising the line again would lose an edge: this frame does nothing, its
                // pulses go out a period later, and the loader holds the machine.
                self.status.count_overrun();
                return;
            }
            port.write_steps(pending.steps);
            pulse.start();
        }

        let frame = &mut self.frame;
        let was_idle = frame.idle();
        let p = frame.tick(src, StatusCap::<PLAN>(&self.status));

        if pending.steps == 0 {
            port.write_signs(p.signs);
        } else {
            self.status.set_next_signs(p.signs);
        }
        self.pending = p;

        // Position and blocks done: published by the frames without pulses (see
        // `Status::position`), so a hold or the end of the program always reports them exactly.
        if p.steps == 0 {
            self.status.publish(frame);
        }

        // The rate and the idle flag change only when a block is loaded or done. They are
        // published by the frames that start idle (the frame after a block's end runs idle and
        // loads the next block): one frame late after a block's end, never in a frame that works
        // on a block. (A chained line starts without an idle frame: its rate is the feed rate
        // already, and the machine is not idle.)
        if was_idle {
            let idle = frame.idle();
            let rate = frame.rate();
            if rate != self.rate {
                self.rate = rate;
                timer.set_reload(match rate {
                    Rate::Feed => self.reloads.feed,
                    Rate::Rapid => self.reloads.rapid,
                });
            }
            self.status
                .set_idle(idle && p.steps == 0 && pending.steps == 0);
        }
    }
}

/// One pulse-end interrupt: counts the high PULSE lines into the encoder by their SIGN lines (the
/// only writer of `encoder`: plain load and store), lowers them and only then writes the SIGN
/// lines for the next pulses. Pulse-end ISR.
#[inline(always)]
pub fn pulse_end(
    port: &mut impl StepPort,
    pulse: &mut impl PulseTimer,
    status: PulseWriter<impl Home>,
) {
    pulse.ack();
    let pins = port.read_pins();
    // Per axis, not a loop (the firmware outside the ISRs is built for size: no unrolling).
    status.count(0, pins);
    status.count(1, pins >> 1);
    status.count(2, pins >> 2);
    port.write_steps(0);
    port.write_signs(status.next_signs.get());
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::gcode::tape::Tape;
    use crate::nc::FrameConfig;
    use crate::settings::Settings;
    use std::collections::VecDeque;
    use std::vec::Vec;

    /// Pins in software: records every write, checks that a SIGN line never changes while a PULSE
    /// line is high (the timing rule), and that PULSE lines rise only from low.
    #[derive(Default)]
    struct Pins {
        levels: u8,
        rises: [u32; 3],
        violations: Vec<&'static str>,
    }

    impl StepPort for Pins {
        fn write_steps(&mut self, steps: u8) {
            for k in 0..3 {
                if steps & (1 << k) != 0 && self.levels & (1 << k) != 0 {
                    self.violations.push("PULSE raised while high");
                }
                if steps & (1 << k) != 0 {
                    self.rises[k] += 1;
                }
            }
            self.levels = (self.levels & !0b111) | (steps & 0b111);
        }
        fn write_signs(&mut self, signs: u8) {
            let new = (self.levels & 0b111) | ((signs & 0b111) << 3);
            if new & 0b111_000 != self.levels & 0b111_000 && self.levels & 0b111 != 0 {
                self.violations
                    .push("SIGN changed while a PULSE line was high");
            }
            self.levels = new;
        }
        fn read_pins(&mut self) -> u8 {
            self.levels
        }
    }

    /// The frame timer in software: records the reloads.
    #[derive(Default)]
    struct Timer {
        reloads: Vec<u32>,
    }

    impl FrameTimer for Timer {
        fn ack(&mut self) {}
        fn set_reload(&mut self, reload: u32) {
            self.reloads.push(reload);
        }
    }

    /// The pulse one-shot in software: running until the test fires the pulse end.
    #[derive(Default)]
    struct OneShot {
        pulse_running: bool,
    }

    impl PulseTimer for OneShot {
        fn start(&mut self) {
            self.pulse_running = true;
        }
        fn ack(&mut self) {
            self.pulse_running = false;
        }
    }

    /// The frame and pulse-end bodies on software ports: a program with rapids, lines and arcs
    /// keeps the timing rule in every frame, the encoder counted from the pins ends where the
    /// frame's position counters do, the status says idle with the exact position, and the frame
    /// timer is retimed for the rapids and back.
    #[test]
    fn frame_and_pulse_end_keep_the_timing_rule_and_the_encoder() {
        let settings = Settings::default();
        let text = "G20 G90\nG0 X0.02 Y-0.01\nG1 X0.03 Y0.01 F30\nG2 X0.05 Y0.01 I0.01 J0\n\
                    G1 X0.04 Y0 Z-0.002 F12\nG0 X0 Y0 Z0\nG1 X-0.001 F30\nM2\n";
        let mut blocks = VecDeque::new();
        let mut tape = Tape::new(settings);
        tape.feed(text.as_bytes(), |b| blocks.push_back(b)).unwrap();
        tape.finish(|b| blocks.push_back(b)).unwrap();
        let n_blocks = blocks.len() as u32;
        let mut src = blocks;
        let status = crate::rt::Status::new();
        let w = status.split();
        let reloads = Reloads {
            feed: 2500,
            rapid: 475,
        };
        let mut task = FrameTask::<_, true>::new(
            Frame::new(FrameConfig::from_settings(&settings)),
            reloads,
            w.frame,
        );
        let (mut pins, mut timer, mut oneshot) =
            (Pins::default(), Timer::default(), OneShot::default());
        for _ in 0..200_000 {
            task.run(&mut pins, &mut timer, &mut oneshot, &mut src);
            if oneshot.pulse_running {
                pulse_end(&mut pins, &mut oneshot, w.pulse);
            }
            if status.idle.get() && src.is_empty() && task.frame.idle() {
                break;
            }
        }
        assert!(
            pins.violations.is_empty(),
            "{} violations, first: {:?}",
            pins.violations.len(),
            pins.violations.first()
        );
        assert!(status.idle.get(), "did not finish");
        let end = [-10, 0, 0];
        assert_eq!(task.frame.position(), end);
        assert_eq!(status.encoder(), end);
        assert_eq!(status.position(), end);
        assert_eq!(status.blocks_done.get(), n_blocks);
        assert!(pins.rises.iter().all(|&r| r > 0));
        // Retimed to the rapid rate for each G0 and back to W0 after it.
        assert_eq!(timer.reloads, [475, 2500, 475, 2500]);
    }
}
