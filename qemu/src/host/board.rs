//! The host board (host): the step, frame-timer and pulse-timer ports in software on a virtual
//! clock, driven by the firmware's own frame and pulse-end ISR bodies (`millac::rt::isr`:
//! `FrameTask::run`, `pulse_end`), so the host simulation and the firmware cannot drift apart.
//!
//! Timing model (the QEMU board's, measured there): a frame interrupt at time t runs with the
//! reload the timer held when it fired (a reload written by the ISR takes effect at the next
//! period, as the LM3S's TAILR does), emits the pulses computed by the interrupt before, and the
//! pulse ends before anything of lower priority runs (the pulse width is shorter than the frame
//! ISR's work plus the sampler's start). A sample at the same instant as a frame interrupt runs
//! after it (the frame ISR has the highest priority).
use crate::lm3s_facts::Lm3s6965;
use millac::nc::Frame;
use millac::ports::{BlockSource, Board, FrameTimer, PulseTimer, StepPort};
use millac::rt::status::{FrameWriter, PulseWriter};
use millac::rt::{isr, FrameTask, Reloads, Status};
use millac::Settings;

/// The PULSE (bits 0-2) and SIGN (bits 3-5) lines.
#[derive(Default)]
struct Pins(u8);

impl StepPort for Pins {
    fn write_steps(&mut self, steps: u8) {
        self.0 = (self.0 & !0b111) | (steps & 0b111);
    }
    fn write_signs(&mut self, signs: u8) {
        self.0 = (self.0 & 0b111) | ((signs & 0b111) << 3);
    }
    fn read_pins(&mut self) -> u8 {
        self.0
    }
}

/// The frame timer's reload register.
struct Timer(u32);

impl FrameTimer for Timer {
    fn ack(&mut self) {}
    fn set_reload(&mut self, reload: u32) {
        self.0 = reload;
    }
}

/// The pulse one-shot: running from the frame's pulse store until its pulse end.
#[derive(Default)]
struct OneShot(bool);

impl PulseTimer for OneShot {
    fn start(&mut self) {
        self.0 = true;
    }
    fn ack(&mut self) {
        self.0 = false;
    }
}

/// The firmware's frame task on the host board, at the QEMU board's timer clock.
pub struct HostFrames<'a> {
    task: FrameTask<&'a Status, true>,
    /// The pulse-end ISR's handle (the frame's is in its task).
    end: PulseWriter<&'a Status>,
    pins: Pins,
    timer: Timer,
    pulse: OneShot,
}

/// What one frame interrupt did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Interrupt {
    /// Time to the next frame interrupt, ns (the reload the timer fired with).
    pub period_ns: u64,
    /// Whether it emitted pulses (counted into the encoder by the pulse end).
    pub pulsed: bool,
}

impl<'a> HostFrames<'a> {
    /// The frame task at the feed rate, as a board's init starts it, with the frame ISR's and the
    /// pulse end's handles on the status.
    pub fn new(
        settings: &Settings,
        frame: FrameWriter<&'a Status>,
        end: PulseWriter<&'a Status>,
    ) -> Self {
        let reloads = Reloads::for_settings::<Lm3s6965>(settings);
        HostFrames {
            task: FrameTask::new(
                Frame::new(millac::nc::FrameConfig::from_settings(settings)),
                reloads,
                frame,
            ),
            end,
            pins: Pins::default(),
            timer: Timer(reloads.feed),
            pulse: OneShot::default(),
        }
    }

    /// One frame interrupt and, when it pulsed, its pulse end: `FrameTask::run` and `pulse_end`,
    /// the firmware's bodies.
    pub fn interrupt(&mut self, src: &mut impl BlockSource) -> Interrupt {
        let period_ns = reload_ns(self.timer.0);
        self.task
            .run(&mut self.pins, &mut self.timer, &mut self.pulse, src);
        let pulsed = self.pulse.0;
        if pulsed {
            isr::pulse_end(&mut self.pins, &mut self.pulse, self.end);
        }
        Interrupt { period_ns, pulsed }
    }

    /// The frame (its state for the host's bookkeeping; only the ISR body changes it).
    pub fn frame(&self) -> &Frame {
        &self.task.frame
    }
}

/// A frame timer reload of the QEMU board in ns (QEMU counts a period of TAILR clocks).
pub fn reload_ns(reload: u32) -> u64 {
    u64::from(reload) * 1_000_000_000 / u64::from(Lm3s6965::TIMER_HZ)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::host::acsim;
    use millac::nc::Rate;

    /// The host simulation counts its position with the firmware's pulse end and times its frames
    /// with the firmware's reload rule: a program of rapids, lines and an arc ends where its last
    /// block ends (the encoder the pulse end counts, not the frame's own counters), every path
    /// point is one pulse per axis from the one before, and a rapid's end costs one frame at the
    /// rapid period (the frame after it starts idle and only then retimes the timer; a reload
    /// takes effect at the next period).
    #[test]
    fn the_host_runs_the_firmwares_frame_and_pulse_end() {
        let settings = Settings::default();
        let text = "G20 G90\nG0 X0.02 Y-0.01\nG1 X0.03 Y0.01 F30\nG2 X0.05 Y0.01 I0.01 J0\n\
                    G0 X0.01 Y0.004\nG1 X-0.001 F30\nM2\n";
        let prog = crate::analysis::load_program(text, &settings).unwrap();
        let cut = acsim::Cut::steel(millac_plant::Stock::default(), 1);
        let run = acsim::run(&prog, &settings, &cut, None).unwrap();
        assert_eq!(run.final_position, [-10, 40, 0]);
        assert_eq!(run.blocks_done, prog.len());
        let mut at = [0i64; 3];
        for (p, _, _) in &run.path {
            assert!((0..3).all(|k| (p[k] - at[k]).abs() <= 1), "{at:?} -> {p:?}");
            assert_ne!(*p, at);
            at = *p;
        }
        assert_eq!(at, run.final_position);

        // The frames' periods: the frame after a rapid's last frame starts idle, loads the next
        // block and runs at the rapid period still (its reload takes effect at the next period).
        let (feed, rapid) = (
            acsim::period_ns(&settings, Rate::Feed),
            acsim::period_ns(&settings, Rate::Rapid),
        );
        assert_ne!(feed, rapid);
        let status = millac::rt::Status::new();
        let w = status.split();
        let mut queue: std::collections::VecDeque<_> = prog.iter().map(|b| b.block).collect();
        let mut frames = HostFrames::new(&settings, w.frame, w.pulse);
        let mut ends = 0;
        // The rate the frame before started with.
        let mut last_rate = Rate::Feed;
        for _ in 0..100_000 {
            let was_idle = frames.frame().idle();
            let rate = frames.frame().rate();
            let irq = frames.interrupt(&mut queue);
            if was_idle && last_rate == Rate::Rapid {
                assert_eq!(irq.period_ns, rapid, "the frame after a rapid");
                ends += 1;
            } else if was_idle {
                assert_eq!(irq.period_ns, feed, "a frame that loads after a feed block");
            }
            last_rate = rate;
            if status.idle.get() && queue.is_empty() {
                break;
            }
        }
        assert_eq!(ends, 2, "two rapids");
        assert_eq!(status.encoder(), [-10, 40, 0]);
    }
}
