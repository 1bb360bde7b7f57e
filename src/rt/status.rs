//! Single-word channels between the firmware's contexts, each with one writer: the frame ISR
//! publishes its status (position, blocks done, idle, velocity) and reads the feed cap and the
//! operator's word; the pulse-end ISR counts the encoder; the sampler counts samples; the AC task
//! writes the feed cap; the loader writes the operator's word; the board's frame wrapper its
//! cycle counts. Everyone reads every word ([`Status`]); a word is written only through the
//! handle of its context ([`Writers`], handed out once at init), so the type says who writes.
//! The few words one context asks and another takes (a resume, a new job, a spindle stop) are
//! [`Request`]s: the asker's handle sets them, the taker's handle takes them. Relaxed atomics are
//! enough: one core, and every word is meaningful on its own. Any context.
//!
//! Reading needs nothing; writing needs the handle:
//! ```
//! let status = millac::rt::Status::new();
//! let w = status.split();
//! w.ac.set_feed_cap(0); // the AC task's handle writes the feed cap
//! assert_eq!(status.feed_cap.get(), 0);
//! ```
//! ```compile_fail
//! let status = millac::rt::Status::new();
//! let w = status.split();
//! status.feed_cap.set(0); // no handle: does not compile
//! assert_eq!(status.feed_cap.get(), 0);
//! ```
use core::ops::Deref;
use core::sync::atomic::{
    compiler_fence, AtomicBool, AtomicI32, AtomicU32, AtomicU8,
    Ordering::{Relaxed, SeqCst},
};

macro_rules! word {
    ($(#[$m:meta])* $name:ident, $t:ty, $atomic:ty) => {
        $(#[$m])*
        pub struct $name($atomic);

        impl $name {
            const fn new(v: $t) -> Self {
                $name(<$atomic>::new(v))
            }
            /// The word as last written.
            #[inline(always)]
            pub fn get(&self) -> $t {
                self.0.load(Relaxed)
            }
            /// Only the writer's handle (this module) stores.
            #[inline(always)]
            fn set(&self, v: $t) {
                self.0.store(v, Relaxed)
            }
        }
    };
}

word!(
    /// A `u32` status word: everyone reads, one handle writes.
    U32,
    u32,
    AtomicU32
);
word!(
    /// An `i32` status word: everyone reads, one handle writes.
    I32,
    i32,
    AtomicI32
);
word!(
    /// A `u8` status word: everyone reads, one handle writes.
    U8,
    u8,
    AtomicU8
);
word!(
    /// A flag: everyone reads, one handle writes.
    Flag,
    bool,
    AtomicBool
);

impl U32 {
    /// One more (wrapping), by the one writer: a plain load and store.
    #[inline(always)]
    fn bump(&self) {
        self.set(self.get().wrapping_add(1))
    }
}

/// A request one context asks and another takes: the asker's handle sets it, the taker's handle
/// takes it (swaps it back to false) when it acts on it; everyone may see whether it is pending.
pub struct Request(AtomicBool);

impl Request {
    const fn new() -> Self {
        Request(AtomicBool::new(false))
    }
    /// Asked and not taken yet.
    pub fn pending(&self) -> bool {
        self.0.load(Relaxed)
    }
    fn ask(&self) {
        self.0.store(true, Relaxed)
    }
    fn take(&self) -> bool {
        self.0.swap(false, Relaxed)
    }
}

/// The status words. The firmware has one `static` (all zero-initialised but `idle`, so it sits
/// in .data/.bss and the frame addresses every word from one base); the host simulation has its
/// own. Each word's writer is named in its doc and is the only handle that stores it.
pub struct Status {
    /// Feed number cap from the adaptive controller; `u32::MAX` = no cap, 0 = hold. Read by the
    /// frame ISR (only in the frames that feed). Written by the AC task ([`AcWriter`]), and held
    /// (0 only) by the sampler's overload trip ([`SamplerWriter::trip`]). Zero at reset:
    /// [`Status::split`] stores `u32::MAX` before any interrupt is enabled.
    pub feed_cap: U32,
    /// The AC's plan ratio k in Q12 (`crate::ports::FeedCap::planned`; `ports::PLAN_ONE` but
    /// under `FeedCeiling::Plan`). Written by the AC task, read by the frame ISR with the cap.
    pub plan_ratio: U32,
    /// The operator's word (`millac::nc::operator`): feed and rapid override, feed hold, abort.
    /// Written by the loader ([`LoaderWriter`], from the protocol's realtime requests and the
    /// re-planner's aborts); read by the frame ISR once per frame. Zero at reset means held:
    /// [`Status::split`] stores `operator::RUN`.
    pub operator: U32,
    /// The frame's feed velocity (`Frame::velocity_q8`, a feed number in Q8) and the rapid's hold
    /// ladder (`Frame::ladder`): both 0 = stopped (see [`Status::stopped`]). Written by the frame
    /// ISR ([`FrameWriter`]) in the frames without pulses, like `position`.
    pub velocity_q8: U32,
    pub ladder: U32,
    /// The AC's state for the status report: 0 = no AC period has run, 1 = run
    /// (`rt::ac::AC_RUN`), else held with this `ALARM:N` number (100 and up). Written by the AC
    /// task each period.
    pub ac_state: U8,
    /// The force (N) and torque (N*m) the last AC period measured, as `f32` bits
    /// ([`Status::ac_measured`]). Written by the AC task each period; the loader turns them into
    /// F/F0 and T/T0 only for a status report.
    ac_force: U32,
    ac_torque: U32,
    /// The operator asks the AC to leave its hold (`~` or `$X`, or a re-plan done): asked by the
    /// loader, taken by the AC task at its next period.
    pub ac_resume: Request,
    /// A job has ended (serial mode: a program end, M2/M30, once the motion before it has run,
    /// or a soft reset): asked by the loader, taken by the AC task at its next period, which
    /// starts the next job afresh (`AcController::new_job`).
    pub ac_new_job: Request,
    /// Absolute position per axis (X, Y, Z) in BLU, as counted by the frame. Written by the frame
    /// ISR in the frames without pulses (idle, dwell, hold, between feed commands), so the frames
    /// with pulses, the frame's worst case, do not pay for it; read at the end of a program and on
    /// a hold ([`Status::position`]). The live position is `encoder`.
    position: [I32; 3],
    /// Blocks completed since power-up. Written by the frame ISR in the frames without pulses,
    /// like `position`.
    pub blocks_done: U32,
    /// True when the frame has no block loaded, no pulse computed for a later frame and no pulse
    /// on the pins. Written by the frame ISR.
    pub idle: Flag,
    /// Signs of the pulses computed by the last frame, for the pulse-end ISR to write once the
    /// current pulse has ended (both ISRs share one priority: a plain atomic, no lock). Written
    /// by the frame ISR.
    pub next_signs: U8,
    /// Encoder counts per axis in BLU: the pulses the board emitted, counted by the pulse-end ISR
    /// ([`PulseWriter`]) from the pins themselves (+1 / -1 per high PULSE line by its SIGN line)
    /// before it lowers them ([`Status::encoder`]); read by the sampler and the AC task.
    encoder: [I32; 3],
    /// The machine coordinates of the counters' zero, BLU: 0 at power-up; homing sets it so that
    /// counter + origin is the axis's machine position ([`Status::machine_position`]). Written by
    /// the loader ([`LoaderWriter::set_origin`]); the ISRs never read it, so they count as before.
    origin: [I32; 3],
    /// Samples taken since start (the sampler's next sample index). Written by the sampler
    /// ([`SamplerWriter`]).
    pub samples: U32,
    /// AC periods the sampler could not start because the previous one had not finished.
    /// Written by the sampler.
    pub ac_missed: U32,
    /// Samples the sampler could not queue for the AC task (queue full). Written by the sampler.
    pub samples_dropped: U32,
    /// The frame ISR's fewest and most CPU cycles (its body, as the board's frame wrapper measures
    /// it, e.g. with the cycle counter), for the status report's `FC:` field and `$I`
    /// ([`Status::frame_cycles`]). 0 = not measured (the QEMU board). Written by the board's
    /// frame wrapper ([`CycleWriter`]).
    frame_cycles_min: U32,
    frame_cycles_max: U32,
    /// Frames that found the previous frame's pulse still on the pins (the pulse-end interrupt
    /// had not run: the frame and pulse-end interrupts took longer than the period): each one
    /// held its pulses back a period, so none is lost and the position stays exact, and the loader
    /// holds the machine with `ALARM:111`. Boards that can read their PULSE lines
    /// (`StepPort::pulse_still_high`). Written by the frame ISR.
    pub frame_overruns: U32,
    /// The spindle speed the machine was last commanded (rpm; 0: none yet), for the process
    /// monitors' tooth period (`rt::ac`; until one is known they assume `$269`). Written by the
    /// loader when it applies a spindle change; read by the AC task and the chatter monitor.
    pub spindle_rpm: U32,
    /// The AC task asks the loader to stop the spindle (a tool breakage): asked by the AC task,
    /// taken by the loader, which turns the spindle off at once.
    pub spindle_stop: Request,
    /// The frequency of the last chatter hold (Hz, an f32's bits, [`Status::chatter_hz`]):
    /// written by the AC task with the hold, read by the loader's reaction (`rt::replan`, the
    /// spindle speed of `$277`).
    chatter_hz: U32,
    /// AC resumes so far: written by the AC task when it leaves a hold; the chatter monitor
    /// restarts its record when it changes (the sound before the hold is not judged after it).
    pub resumes: U32,
    /// Sound samples the sampler could not queue for the chatter monitor (its queue full): the
    /// monitor restarts its record when it changes (a record with a gap is not judged). Written
    /// by the sampler.
    pub sound_dropped: U32,
    /// The tool in the spindle (`T` of the last M6; 0: none fitted since power-up, the AC
    /// settings' tool), its flutes (0: not known) and its permissible force and torque (N, N*m,
    /// `f32` bits; 0: no limits), for the AC period, the sampler's trip and the status report
    /// ([`Status::fitted_tool`]). Written by the loader at each M6, between two counts of
    /// `tool_changes`.
    tool: U8,
    tool_flutes: U8,
    tool_radius: U32,
    tool_kind: U8,
    tool_force: U32,
    tool_torque: U32,
    /// Twice the M6s since power-up, odd while the loader writes the tool's words (a sequence
    /// lock: the words are one record, not each meaningful on its own): a reader follows the
    /// tool when the count changes and takes the words read between two equal even counts
    /// ([`Status::fitted_tool`]).
    pub tool_changes: U32,
    /// The writers have been handed out ([`Status::split`]).
    split: AtomicBool,
}

/// The tool an M6 fitted, as the status words carry it ([`Status::fitted_tool`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FittedTool {
    /// Its number (`T`).
    pub number: u8,
    /// Its cutting edges (0: not known).
    pub flutes: u8,
    /// Its radius, mm (0: not known): the lever of the force/torque plausibility, F R / T.
    pub radius_mm: f32,
    /// Its kind (a ball end mill cuts at radii below R: the plausibility's band widens).
    pub kind: crate::gcode::tools::ToolKind,
    /// Its permissible cutting force and torque (`crate::ac::strength`); None: nobody said and
    /// its geometry does not tell (the AC does not limit it).
    pub limits: Option<crate::ac::strength::Limits>,
}

impl FittedTool {
    /// Tool `number` as its table entry describes it (None: no entry, T0): its flutes, and its
    /// limits, the table's own or from its geometry (`crate::ac::strength::of_tool`, high-speed
    /// steel). The loader at an M6, and the host's runs at a program's M6.
    pub fn of(number: u8, entry: Option<&crate::gcode::tools::Tool>) -> FittedTool {
        use crate::ac::strength::{of_tool, Strength};
        FittedTool {
            number,
            flutes: entry.map_or(0, |t| t.flutes),
            // Picometres -> mm (a diameter).
            radius_mm: entry.map_or(0.0, |t| t.diameter_pm as f32 * 0.5e-9),
            kind: entry.map_or(Default::default(), |t| t.kind),
            limits: entry.and_then(|t| of_tool(t, &Strength::HSS)).map(|l| l.0),
        }
    }

    /// Its radius (mm), or the machine's (`$284`, the AC's `tool_radius_mm`) where the table
    /// does not know it.
    pub fn radius_or(&self, machine: f32) -> f32 {
        if self.radius_mm > 0.0 {
            self.radius_mm
        } else {
            machine
        }
    }

    /// Its flutes, or the machine's (`$267`) where the table does not know them.
    pub fn flutes_or(&self, machine: u32) -> u32 {
        match self.flutes {
            0 => machine,
            n => u32::from(n),
        }
    }
}

impl Default for Status {
    fn default() -> Self {
        Self::new()
    }
}

impl Status {
    pub const fn new() -> Self {
        Status {
            feed_cap: U32::new(0),
            plan_ratio: U32::new(0),
            operator: U32::new(0),
            velocity_q8: U32::new(0),
            ladder: U32::new(0),
            ac_state: U8::new(0),
            ac_force: U32::new(0),
            ac_torque: U32::new(0),
            ac_resume: Request::new(),
            ac_new_job: Request::new(),
            position: [I32::new(0), I32::new(0), I32::new(0)],
            blocks_done: U32::new(0),
            idle: Flag::new(true),
            next_signs: U8::new(0),
            encoder: [I32::new(0), I32::new(0), I32::new(0)],
            origin: [I32::new(0), I32::new(0), I32::new(0)],
            samples: U32::new(0),
            ac_missed: U32::new(0),
            samples_dropped: U32::new(0),
            frame_cycles_min: U32::new(0),
            frame_cycles_max: U32::new(0),
            frame_overruns: U32::new(0),
            spindle_rpm: U32::new(0),
            spindle_stop: Request::new(),
            chatter_hz: U32::new(0),
            resumes: U32::new(0),
            sound_dropped: U32::new(0),
            tool: U8::new(0),
            tool_flutes: U8::new(0),
            tool_radius: U32::new(0),
            tool_kind: U8::new(0),
            tool_force: U32::new(0),
            tool_torque: U32::new(0),
            tool_changes: U32::new(0),
            split: AtomicBool::new(false),
        }
    }

    /// Init, before any interrupt is enabled: no AC cap, the plan ratio 1, the operator's word at
    /// 100 % (the words are zero at reset, which would hold the feed), and each context's handle,
    /// once: a second call is a programming error and panics (init only, never an ISR). The
    /// ISRs' handles reach the words through a reference (host simulations and tests; the
    /// firmware splits its one static with [`split_static`]).
    pub fn split(&self) -> Writers<'_, &Status> {
        self.split_at(self)
    }

    fn split_at<H: Home>(&self, home: H) -> Writers<'_, H> {
        assert!(!self.split.swap(true, Relaxed), "status split twice");
        self.feed_cap.set(u32::MAX);
        self.plan_ratio.set(crate::ports::PLAN_ONE);
        self.operator.set(crate::nc::operator::RUN);
        Writers {
            frame: FrameWriter(home),
            pulse: PulseWriter(home),
            cycles: CycleWriter(home),
            sampler: SamplerWriter(self),
            ac: AcWriter(self),
            loader: LoaderWriter(self),
        }
    }

    /// Nothing moves (a feed hold is complete), as last published by the frame.
    pub fn stopped(&self) -> bool {
        crate::nc::frame::stopped(self.idle.get(), self.velocity_q8.get(), self.ladder.get())
    }

    /// The force (N) and torque (N*m) of the last AC period.
    pub fn ac_measured(&self) -> (f32, f32) {
        (
            f32::from_bits(self.ac_force.get()),
            f32::from_bits(self.ac_torque.get()),
        )
    }

    /// The frequency (Hz) of the last chatter hold (0 before any).
    pub fn chatter_hz(&self) -> f32 {
        f32::from_bits(self.chatter_hz.get())
    }

    /// The frame ISR's (fewest, most) cycles, or None while not measured (either word 0: the
    /// wrapper has not written both yet, or the board does not measure).
    pub fn frame_cycles(&self) -> Option<(u32, u32)> {
        let min = self.frame_cycles_min.get();
        let max = self.frame_cycles_max.get();
        (min != 0 && max != 0).then_some((min, max))
    }

    /// The tool the last M6 fitted and the count it was read at (`tool_changes`); None before
    /// any M6 (the AC settings describe the tool) and while the loader writes it (its context
    /// is the lowest: a reader preempted it; read again at the next period).
    pub fn fitted_tool(&self) -> Option<(u32, FittedTool)> {
        let n = self.tool_changes.get();
        // One core: the compiler must not move the words' loads across the counts'.
        compiler_fence(SeqCst);
        let (f, t) = (
            f32::from_bits(self.tool_force.get()),
            f32::from_bits(self.tool_torque.get()),
        );
        let tool = FittedTool {
            number: self.tool.get(),
            flutes: self.tool_flutes.get(),
            radius_mm: f32::from_bits(self.tool_radius.get()),
            kind: crate::gcode::tools::ToolKind::from_code(self.tool_kind.get())
                .unwrap_or_default(),
            limits: (f > 0.0 && t > 0.0).then_some(crate::ac::strength::Limits {
                force_n: f,
                torque_nm: t,
            }),
        };
        compiler_fence(SeqCst);
        (n != 0 && n % 2 == 0 && self.tool_changes.get() == n).then_some((n, tool))
    }

    /// The encoder counts X, Y, Z.
    pub fn encoder(&self) -> [i32; 3] {
        [0, 1, 2].map(|k| self.encoder[k].get())
    }

    /// The frame's position X, Y, Z as last published.
    pub fn position(&self) -> [i32; 3] {
        [0, 1, 2].map(|k| self.position[k].get())
    }

    /// The counters' origin ([`Status::machine_position`]).
    pub fn origin(&self) -> [i32; 3] {
        [0, 1, 2].map(|k| self.origin[k].get())
    }

    /// The frame's position in machine coordinates: [`Status::position`] plus the origin homing
    /// set (the parser's, the soft limits' and the reports' coordinates).
    pub fn machine_position(&self) -> [i32; 3] {
        [0, 1, 2].map(|k| self.position[k].get().wrapping_add(self.origin[k].get()))
    }

    /// The encoder counts in machine coordinates (the status report's MPos).
    pub fn machine_encoder(&self) -> [i32; 3] {
        [0, 1, 2].map(|k| self.encoder[k].get().wrapping_add(self.origin[k].get()))
    }
}

/// The firmware's status words: one static for every board (all zero but `idle` at reset).
pub static STATUS: Status = Status::new();

/// Where an ISR's handle finds the status words: a reference (the host's own [`Status`]), or
/// [`Static`], the firmware's [`STATUS`] named by a zero-sized type: its address is a constant,
/// so the handle costs the ISRs nothing (no pointer to load, no register held).
pub trait Home: Copy {
    fn status(&self) -> &Status;
}

impl Home for &Status {
    #[inline(always)]
    fn status(&self) -> &Status {
        self
    }
}

/// The firmware's [`STATUS`] as an ISR's handle reaches it.
#[derive(Clone, Copy)]
pub struct Static;

impl Home for Static {
    #[inline(always)]
    fn status(&self) -> &Status {
        &STATUS
    }
}

/// The firmware's init: [`Status::split`] on [`STATUS`], the ISRs' handles zero-sized.
pub fn split_static() -> Writers<'static, Static> {
    STATUS.split_at(Static)
}

/// Each context's handle on the status, from [`Status::split`]: init hands each to its context
/// (an RTIC local resource or the struct that runs there) and keeps none. The ISRs' handles
/// (frame, pulse end, the frame wrapper's cycles) reach the words through `H` ([`Home`]); the
/// tasks' through a reference.
pub struct Writers<'a, H> {
    pub frame: FrameWriter<H>,
    pub pulse: PulseWriter<H>,
    pub cycles: CycleWriter<H>,
    pub sampler: SamplerWriter<'a>,
    pub ac: AcWriter<'a>,
    pub loader: LoaderWriter<'a>,
}

macro_rules! handle {
    ($(#[$m:meta])* $name:ident) => {
        $(#[$m])*
        pub struct $name<'a>(&'a Status);

        impl Deref for $name<'_> {
            type Target = Status;
            #[inline(always)]
            fn deref(&self) -> &Status {
                self.0
            }
        }
    };
}

/// An ISR's handle: `Copy` (the ISR bodies take it by value: zero-sized in the firmware), made
/// only by the split.
macro_rules! isr_handle {
    ($(#[$m:meta])* $name:ident) => {
        $(#[$m])*
        #[derive(Clone, Copy)]
        pub struct $name<H>(H);

        impl<H: Home> Deref for $name<H> {
            type Target = Status;
            #[inline(always)]
            fn deref(&self) -> &Status {
                self.0.status()
            }
        }
    };
}

isr_handle!(
    /// The frame ISR's handle: its position, blocks done, velocity, ladder, idle flag, next
    /// signs and overrun count (`crate::rt::FrameTask::run`).
    FrameWriter
);
isr_handle!(
    /// The pulse-end ISR's handle: the encoder counts (`crate::rt::pulse_end`).
    PulseWriter
);
handle!(
    /// The sampler's handle: the sample count, its dropped and missed counts, and the overload
    /// trip's hold (`crate::rt::actask::Sampler`).
    SamplerWriter
);
handle!(
    /// The AC task's handle: the feed cap and plan ratio, its state and measurements, the
    /// chatter frequency, the resume count; it takes the loader's requests and asks for a
    /// spindle stop (`crate::rt::ac::AcPeriod`).
    AcWriter
);
handle!(
    /// The loader's handle: the operator's word and the spindle speed; it asks the AC to resume
    /// or start a new job and takes the AC's spindle stop (`crate::rt::loader`,
    /// `crate::rt::replan`).
    LoaderWriter
);
isr_handle!(
    /// The board's frame wrapper's handle: the frame ISR's measured cycles.
    CycleWriter
);

impl<H: Home> FrameWriter<H> {
    /// What a frame without pulses publishes: position, blocks done, velocity and ladder.
    #[inline(always)]
    pub fn publish(&self, frame: &crate::nc::Frame) {
        let s: &Status = self;
        let [x, y, z] = frame.position();
        s.position[0].set(x);
        s.position[1].set(y);
        s.position[2].set(z);
        s.blocks_done.set(frame.blocks_done());
        s.velocity_q8.set(frame.velocity_q8());
        s.ladder.set(frame.ladder());
    }
    #[inline(always)]
    pub fn set_idle(&self, idle: bool) {
        self.idle.set(idle)
    }
    #[inline(always)]
    pub fn set_next_signs(&self, signs: u8) {
        self.next_signs.set(signs)
    }
    #[inline(always)]
    pub fn count_overrun(&self) {
        self.frame_overruns.bump()
    }
    /// Tests that run the frame themselves: everything the frame publishes, after every frame
    /// (the ISR publishes it in the frames without pulses, which is where the tests look).
    #[cfg(test)]
    pub(crate) fn publish_all(&self, frame: &crate::nc::Frame) {
        self.publish(frame);
        self.set_idle(frame.idle());
    }
}

impl<H: Home> PulseWriter<H> {
    /// One axis's encoder count: bit 0 of `pins` its PULSE line, bit 3 its SIGN line (+1 / -1
    /// per high PULSE line).
    #[inline(always)]
    pub fn count(&self, axis: usize, pins: u8) {
        if pins & 1 != 0 {
            let e = &self.encoder[axis];
            let d = if pins & 8 != 0 { 1 } else { -1 };
            e.set(e.get().wrapping_add(d));
        }
    }
    /// Tests that move the axes without pins: the encoder counts.
    #[cfg(test)]
    pub(crate) fn set_encoder(&self, counts: [i32; 3]) {
        for (e, c) in self.encoder.iter().zip(counts) {
            e.set(c);
        }
    }
}
impl SamplerWriter<'_> {
    pub fn set_samples(&self, n: u32) {
        self.0.samples.set(n)
    }
    pub fn count_missed_period(&self) {
        self.0.ac_missed.bump()
    }
    pub fn count_dropped_sample(&self) {
        self.0.samples_dropped.bump()
    }
    pub fn count_dropped_sound(&self) {
        self.0.sound_dropped.bump()
    }
    /// The overload trip: holds the feed at once (a cap of 0; the AC's next period holds too).
    pub fn trip(&self) {
        self.0.feed_cap.set(0)
    }
}

impl AcWriter<'_> {
    pub fn set_feed_cap(&self, cap: u32) {
        self.0.feed_cap.set(cap)
    }
    pub fn set_plan_ratio(&self, ratio: u32) {
        self.0.plan_ratio.set(ratio)
    }
    pub fn set_state(&self, state: u8) {
        self.0.ac_state.set(state)
    }
    /// The force (N) and torque (N*m) the period measured.
    pub fn set_measured(&self, f_n: f32, t_nm: f32) {
        self.0.ac_force.set(f_n.to_bits());
        self.0.ac_torque.set(t_nm.to_bits());
    }
    pub fn set_chatter_hz(&self, hz: f32) {
        self.0.chatter_hz.set(hz.to_bits())
    }
    pub fn count_resume(&self) {
        self.0.resumes.bump()
    }
    /// The operator's resume, if asked since the last call.
    pub fn take_resume(&self) -> bool {
        self.0.ac_resume.take()
    }
    /// A new job, if asked since the last call.
    pub fn take_new_job(&self) -> bool {
        self.0.ac_new_job.take()
    }
    /// Asks the loader to stop the spindle (a tool breakage).
    pub fn ask_spindle_stop(&self) {
        self.0.spindle_stop.ask()
    }
}

impl LoaderWriter<'_> {
    /// Homing: axis `k`'s counters' zero is at `origin` in machine coordinates.
    pub fn set_origin(&self, k: usize, origin: i32) {
        if let Some(o) = self.0.origin.get(k) {
            o.set(origin);
        }
    }
    pub fn set_operator(&self, word: u32) {
        self.0.operator.set(word)
    }
    /// The operator's word with `bits` set (`set`) or cleared.
    pub fn operator_bits(&self, bits: u32, set: bool) {
        let w = self.0.operator.get();
        self.0.operator.set(if set { w | bits } else { w & !bits });
    }
    pub fn set_spindle_rpm(&self, rpm: u32) {
        self.0.spindle_rpm.set(rpm)
    }
    /// An M6 has fitted `tool`: its words, then the count (readers follow the count).
    pub fn set_tool(&self, tool: &FittedTool) {
        let s = self.0;
        s.tool_changes.bump();
        compiler_fence(SeqCst);
        s.tool.set(tool.number);
        s.tool_flutes.set(tool.flutes);
        s.tool_radius.set(f32::to_bits(tool.radius_mm));
        s.tool_kind.set(tool.kind.code());
        let (f, t) = tool.limits.map_or((0.0, 0.0), |l| (l.force_n, l.torque_nm));
        s.tool_force.set(f32::to_bits(f));
        s.tool_torque.set(f32::to_bits(t));
        compiler_fence(SeqCst);
        s.tool_changes.bump();
    }
    /// Asks the AC to leave its hold at its next period.
    pub fn ask_resume(&self) {
        self.0.ac_resume.ask()
    }
    /// Asks the AC to start a new job at its next period.
    pub fn ask_new_job(&self) {
        self.0.ac_new_job.ask()
    }
    /// The AC's spindle stop, if asked since the last call.
    pub fn take_spindle_stop(&self) -> bool {
        self.0.spindle_stop.take()
    }
}

impl<H: Home> CycleWriter<H> {
    /// A new fewest cycles of the frame.
    #[inline(always)]
    pub fn set_min(&self, cycles: u32) {
        self.frame_cycles_min.set(cycles)
    }
    /// A new most cycles of the frame.
    #[inline(always)]
    pub fn set_max(&self, cycles: u32) {
        self.frame_cycles_max.set(cycles)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The handles are handed out once: a second split would make a second writer.
    #[test]
    #[should_panic(expected = "status split twice")]
    fn a_status_splits_once() {
        let s = Status::new();
        let _w = s.split();
        let _again = s.split();
    }

    /// The split starts the words the frame reads (no cap, plan ratio 1, the operator at 100 %),
    /// and a request is pending from its ask to its take, taken once.
    #[test]
    fn the_split_starts_the_words_and_a_request_is_taken_once() {
        let s = Status::new();
        assert_eq!((s.feed_cap.get(), s.operator.get()), (0, 0));
        let w = s.split();
        assert_eq!(s.feed_cap.get(), u32::MAX);
        assert_eq!(s.plan_ratio.get(), crate::ports::PLAN_ONE);
        assert_eq!(s.operator.get(), crate::nc::operator::RUN);
        assert!(!s.ac_resume.pending());
        w.loader.ask_resume();
        assert!(s.ac_resume.pending());
        assert!(w.ac.take_resume());
        assert!(!w.ac.take_resume() && !s.ac_resume.pending());
        w.ac.ask_spindle_stop();
        assert!(w.loader.take_spindle_stop() && !w.loader.take_spindle_stop());
    }

    /// The firmware's ISR handles are zero-sized: the ISRs address the static's words as
    /// constants, as they did before there were handles (the host's carry a reference).
    #[test]
    fn the_firmware_isr_handles_cost_nothing() {
        use core::mem::size_of;
        assert_eq!(size_of::<FrameWriter<Static>>(), 0);
        assert_eq!(size_of::<PulseWriter<Static>>(), 0);
        assert_eq!(size_of::<CycleWriter<Static>>(), 0);
        assert_eq!(size_of::<FrameWriter<&Status>>(), size_of::<usize>());
    }
}
