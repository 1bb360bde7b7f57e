//! Single-word channels between the firmware's contexts: the frame ISR publishes its status
//! (position, blocks done, idle, stopped, velocity) and reads the feed cap and the operator's word;
//! the loader reads the status and writes the operator's word; the AC task writes the feed cap;
//! the pulse-end ISR counts the encoder; the sampler counts samples; the board's frame wrapper
//! publishes the frame's cycle counts. Relaxed atomics are enough: one core, and every word is
//! meaningful on its own. Any context.
use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, AtomicU8, Ordering::Relaxed};

/// The status words. The firmware has one `static` (all zero-initialised, so it sits in .bss and
/// the frame addresses every word from one base); the host simulation has its own.
pub struct Status {
    /// Feed number cap from the adaptive controller; `u32::MAX` = no cap, 0 = hold. Read by the
    /// frame ISR (only in the frames that feed). Zero at reset: init stores `u32::MAX` (or the AC's
    /// first cap) before any interrupt is enabled.
    pub feed_cap: AtomicU32,
    /// The AC's plan ratio k in Q12 (`crate::ports::FeedCap::planned`; `ports::PLAN_ONE` but
    /// under `FeedCeiling::Plan`). Written by the AC task, read by the frame ISR with the cap.
    /// Zero at reset: init stores `PLAN_ONE`.
    pub plan_ratio: AtomicU32,
    /// The operator's word (`millac::nc::operator`): feed and rapid override, feed hold, abort.
    /// Written by the loader only (from the protocol's realtime requests); read by the frame ISR
    /// once per frame. Zero at reset means held: init stores `operator::RUN` before any interrupt
    /// is enabled.
    pub operator: AtomicU32,
    /// The frame's feed velocity (`Frame::velocity_q8`, a feed number in Q8) and the rapid's hold
    /// ladder (`Frame::ladder`): both 0 = stopped (see [`Status::stopped`]). Written by the frame
    /// ISR in the frames without pulses, like `position`.
    pub velocity_q8: AtomicU32,
    pub ladder: AtomicU32,
    /// The AC's state for the status report: 0 = no AC period has run, 1 = run
    /// (`rt::ac::AC_RUN`), else held with this `ALARM:N` number (100 and up). Written by the AC
    /// task each period.
    pub ac_state: AtomicU8,
    /// The force (N) and torque (N*m) the last AC period measured, as `f32` bits. Written by the
    /// AC task each period; the loader turns them into F/F0 and T/T0 only for a status report.
    pub ac_force: AtomicU32,
    pub ac_torque: AtomicU32,
    /// The operator asks the AC to leave its hold (`~` or `$X`): set by the loader, taken (swapped
    /// back to false) by the AC task at its next period.
    pub ac_resume: AtomicBool,
    /// A job has ended (serial mode: a program end, M2/M30, once the motion before it has run,
    /// or a soft reset): set by the loader, taken by the AC task at its next period, which starts
    /// the next job afresh (`AcController::new_job`).
    pub ac_new_job: AtomicBool,
    /// Absolute position per axis (X, Y, Z) in BLU, as counted by the frame. Written by the frame
    /// ISR in the frames without pulses (idle, dwell, hold, between feed commands), so the frames
    /// with pulses, the frame's worst case, do not pay for it; read at the end of a program and on
    /// a hold. The live position is `encoder`.
    pub position: [AtomicI32; 3],
    /// Blocks completed since power-up. Written by the frame ISR in the frames without pulses,
    /// like `position`.
    pub blocks_done: AtomicU32,
    /// True when the frame has no block loaded, no pulse computed for a later frame and no pulse
    /// on the pins. Written by the frame ISR.
    pub idle: AtomicBool,
    /// Signs of the pulses computed by the last frame, for the pulse-end ISR to write once the
    /// current pulse has ended (both ISRs share one priority: a plain atomic, no lock).
    pub next_signs: AtomicU8,
    /// Encoder counts per axis in BLU: the pulses the board emitted, counted by the pulse-end ISR
    /// from the pins themselves (+1 / -1 per high PULSE line by its SIGN line) before it lowers
    /// them. One writer (plain load and store); read by the sampler and the AC task.
    pub encoder: [AtomicI32; 3],
    /// Samples taken since start (the sampler's next sample index). Written by the sampler.
    pub samples: AtomicU32,
    /// AC periods the sampler could not start because the previous one had not finished.
    pub ac_missed: AtomicU32,
    /// Samples the sampler could not queue for the AC task (queue full).
    pub samples_dropped: AtomicU32,
    /// The frame ISR's fewest and most CPU cycles (its body, as the board's frame wrapper measures
    /// it, e.g. with the cycle counter), for the status report's `FC:` field and `$I`. 0 = not
    /// measured (the QEMU board). One writer, the board's frame wrapper (plain load and store);
    /// read by the loader through [`Status::frame_cycles`].
    pub frame_cycles_min: AtomicU32,
    pub frame_cycles_max: AtomicU32,
    /// Frames that found the previous frame's pulse still on the pins (the pulse-end interrupt
    /// had not run: the frame and pulse-end interrupts took longer than the period): each one
    /// held its pulses back a period, so none is lost and the position stays exact, and the loader
    /// holds the machine with `ALARM:111`. Boards that can read their PULSE lines
    /// (`StepPort::pulse_still_high`). Written by the frame ISR only (plain load and store).
    pub frame_overruns: AtomicU32,
    /// The spindle speed the machine was last commanded (rpm; 0: none yet), for the process
    /// monitors' tooth period (`rt::ac`; until one is known they assume `$269`). Written by the
    /// loader when it applies a spindle change; read by the AC task.
    pub spindle_rpm: AtomicU32,
    /// The AC task asks the loader to stop the spindle (a tool breakage): set by the AC task,
    /// taken (swapped back to false) by the loader, which turns the spindle off at once.
    pub spindle_stop: AtomicBool,
    /// The frequency of the last chatter hold (Hz, an f32's bits): written by the AC task with
    /// the hold, read by the loader's reaction (`rt::replan`, the spindle speed of `$277`).
    pub chatter_hz: AtomicU32,
    /// AC resumes so far: written by the AC task when it leaves a hold; the chatter monitor
    /// restarts its record when it changes (the sound before the hold is not judged after it).
    pub resumes: AtomicU32,
    /// Sound samples the sampler could not queue for the chatter monitor (its queue full): the
    /// monitor restarts its record when it changes (a record with a gap is not judged).
    pub sound_dropped: AtomicU32,
}

impl Default for Status {
    fn default() -> Self {
        Self::new()
    }
}

impl Status {
    pub const fn new() -> Self {
        Status {
            feed_cap: AtomicU32::new(0),
            plan_ratio: AtomicU32::new(0),
            operator: AtomicU32::new(0),
            velocity_q8: AtomicU32::new(0),
            ladder: AtomicU32::new(0),
            ac_state: AtomicU8::new(0),
            ac_force: AtomicU32::new(0),
            ac_torque: AtomicU32::new(0),
            ac_resume: AtomicBool::new(false),
            ac_new_job: AtomicBool::new(false),
            position: [AtomicI32::new(0), AtomicI32::new(0), AtomicI32::new(0)],
            blocks_done: AtomicU32::new(0),
            idle: AtomicBool::new(true),
            next_signs: AtomicU8::new(0),
            encoder: [AtomicI32::new(0), AtomicI32::new(0), AtomicI32::new(0)],
            samples: AtomicU32::new(0),
            ac_missed: AtomicU32::new(0),
            samples_dropped: AtomicU32::new(0),
            frame_cycles_min: AtomicU32::new(0),
            frame_cycles_max: AtomicU32::new(0),
            frame_overruns: AtomicU32::new(0),
            spindle_rpm: AtomicU32::new(0),
            spindle_stop: AtomicBool::new(false),
            chatter_hz: AtomicU32::new(0),
            resumes: AtomicU32::new(0),
            sound_dropped: AtomicU32::new(0),
        }
    }

    /// Init, before any interrupt is enabled: no AC cap, the plan ratio 1, the operator's word at
    /// 100 % (the words are zero at reset, which would hold the feed).
    pub fn start(&self) {
        self.feed_cap.store(u32::MAX, Relaxed);
        self.plan_ratio.store(crate::ports::PLAN_ONE, Relaxed);
        self.operator.store(crate::nc::operator::RUN, Relaxed);
    }

    /// Nothing moves (a feed hold is complete), as last published by the frame.
    pub fn stopped(&self) -> bool {
        crate::nc::frame::stopped(
            self.idle.load(Relaxed),
            self.velocity_q8.load(Relaxed),
            self.ladder.load(Relaxed),
        )
    }

    /// The force (N) and torque (N*m) of the last AC period.
    pub fn ac_measured(&self) -> (f32, f32) {
        (
            f32::from_bits(self.ac_force.load(Relaxed)),
            f32::from_bits(self.ac_torque.load(Relaxed)),
        )
    }

    /// The frame ISR's (fewest, most) cycles, or None while not measured (either word 0: the
    /// wrapper has not written both yet, or the board does not measure).
    pub fn frame_cycles(&self) -> Option<(u32, u32)> {
        let min = self.frame_cycles_min.load(Relaxed);
        let max = self.frame_cycles_max.load(Relaxed);
        (min != 0 && max != 0).then_some((min, max))
    }

    /// The encoder counts X, Y, Z.
    pub fn encoder(&self) -> [i32; 3] {
        [0, 1, 2].map(|k| self.encoder[k].load(Relaxed))
    }

    /// The frame's position X, Y, Z as last published.
    pub fn position(&self) -> [i32; 3] {
        [0, 1, 2].map(|k| self.position[k].load(Relaxed))
    }

    /// What the frame ISR publishes (`crate::rt::isr::FrameTask::run`), from a frame the host
    /// runs itself: position, blocks done, velocity, ladder and idle, after every frame (the ISR
    /// publishes them in the frames without pulses, which is where the host's readers look).
    /// Host simulations and tests.
    pub fn publish_frame(&self, frame: &crate::nc::Frame) {
        for (p, v) in self.position.iter().zip(frame.position()) {
            p.store(v, Relaxed);
        }
        self.blocks_done.store(frame.blocks_done(), Relaxed);
        self.velocity_q8.store(frame.velocity_q8(), Relaxed);
        self.ladder.store(frame.ladder(), Relaxed);
        self.idle.store(frame.idle(), Relaxed);
    }
}
