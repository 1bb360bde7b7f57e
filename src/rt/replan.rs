//! Chatter suppression by depth reduction (Munasinghe 1994, sections 3.3 and 4.4.4, after Weck):
//! the loader's record of the blocks it queued, and the re-plan it makes of them when the chatter
//! monitor has held the feed (loader task of both modes; the host simulation runs the same code).
//!
//! # What the thesis does, and what this does
//!
//! On chatter the HOAM-CNC stops the axes, reads the NC block being executed and its start
//! point, moves Z to reduce the depth of cut by a set amount, and rewrites the program so that the
//! total depth is removed in more passes; then it cuts on and listens again, and reduces again
//! while the chatter lasts. Here, once the chatter hold has brought the machine to a stop at Pc
//! inside the block that ends at P1 (a straight feed move in the XY plane at height z):
//!
//! 1. Z up by the step d (`$276`), as a rapid: out of the cut;
//! 2. Pc -> P1 at z + d, at the block's feed: the rest of the block at the reduced depth;
//! 3. back P1 -> Pc at z + d, a rapid through the slot just cut;
//! 4. Z down by d at Pc, a rapid: the tool's disc at Pc was cut to z before the hold;
//! 5. Pc -> P1 at z, at the block's feed: the layer of thickness d left by step 2;
//!
//! then the blocks that were queued behind the held one, unchanged: the detour ends at P1, where
//! the held block would have ended, and blocks are incremental. The frame's abort (the soft reset's
//! bit) drops the queue at the stop (the position is exact: the machine stands), the detour and
//! the copies of the dropped blocks are queued, and the AC resumes from f_min. If the upper pass
//! chatters again, its own detour lifts it by another d, so the depth is reduced step by step
//! until the chatter is gone, as in the thesis; every lower layer is d thick. The cutting direction
//! of every pass is the programmed one (no plunge into material, no change from climb to
//! conventional milling).
//!
//! # Choices (documented in docs/user/monitoring.md, "Chatter suppression")
//!
//! - Only a straight feed move without Z motion is re-planned (a slot or a pocket's pass). An arc
//!   or a ramp held for chatter stays held with `ALARM:107` as without suppression (the operator
//!   decides), and the report says why. A hold in a rapid or a dwell, or with nothing queued, is
//!   a verdict on the cut before (the monitor judges a record after it ends): the AC resumes.
//! - The lift is checked against the Z soft limit; a detour that would leave it is refused the
//!   same way, and so is a ninth detour inside the others ([`NESTED`]).
//! - A detour's layer has a known thickness. If it chatters, lifting it by the step would leave
//!   its pass in air and cut the same layer again, for ever; it is split in halves instead
//!   ([`step`]), down to [`MIN_LAYER_BLU`], then held.
//! - The program's modes are untouched; the parser still stands at the end of the last line it
//!   read, where the machine will be once the queue has run.
//!
//! # The spindle speed first (`$277`)
//!
//! With `$277` set (the top speed it may command, rpm), a chatter hold first changes the spindle
//! speed to the nearest stable lobe's ([`crate::monitor::chatter::lobe_rpm`]: the tooth frequency
//! a whole fraction of the chatter frequency the hold heard, `Status::chatter_hz`), and the feed
//! resumes in the same block: nothing is re-planned, the geometry is the program's (so also an
//! arc or a ramp). The thesis does not do this (its survey cites it, Smith and Delio); the issue
//! asks for it as a choice. [`SPEED_TRIES`] changes in one held block that do not quiet the cut,
//! or no such speed within `$277`, and the depth steps of `$276` take over (where the lobes are
//! narrow, as for the thesis' cutter at 1500 rpm, no speed helps: docs/dev/monitors.md); the passes of a
//! detour then go straight to further depth steps (the speeds failed in that cut). The new speed stays
//! until the program commands another. [`Event::Speed`] tells the loader, which applies it to
//! the spindle and then calls [`Replan::speed_applied`] (the AC resumes only then).

use crate::ac::AcSettings;
use crate::monitor::chatter::{lobe_rpm, ChatterSettings};
use crate::nc::{
    isqrt, operator, steps_and_signs, Block, FrameConfig, Linear, Motion, Rapid, Sealed, X, Y, Z,
};
use crate::protocol::codes::alarm;
use crate::rt::status::LoaderWriter;
use crate::settings::Settings;

/// Blocks of one detour.
pub const DETOUR: usize = 5;

/// Detours inside detours a record of [`record_len`] holds: every re-plan while the blocks of the
/// last one are still queued adds `DETOUR - 1` blocks (the thesis' pocket needed three steps;
/// the table 3.2 cut here takes up to eight of 1 mm, see docs/dev/monitors.md, "Chatter suppression by depth steps").
pub const NESTED: usize = 8;

/// The record a loader needs for a queue of `queue` slots: the queue, and [`NESTED`] detours.
pub const fn record_len(queue: usize) -> usize {
    queue + 1 + (DETOUR - 1) * NESTED
}

/// Where the loader queues blocks: the producer end of the frame's queue. Loader task; host.
pub trait Sink {
    /// Blocks queued and not yet done by the frame (the running block included).
    fn queued(&self) -> usize;
    /// Queues `b` if there is room.
    fn try_push(&mut self, b: Sealed) -> Result<(), Sealed>;
}

impl<const Q: usize> Sink for heapless::spsc::Producer<'static, Sealed, Q> {
    fn queued(&self) -> usize {
        heapless::spsc::Producer::len(self)
    }
    fn try_push(&mut self, b: Sealed) -> Result<(), Sealed> {
        self.enqueue(b)
    }
}

/// A bounded host queue of `cap` blocks as the loader's sink and the frame's block source (host
/// simulations and tests; feature `std`), like the firmware's SPSC queue.
#[cfg(any(test, feature = "std"))]
#[derive(Clone, Debug, Default)]
pub struct HostQueue {
    pub blocks: std::collections::VecDeque<Sealed>,
    pub cap: usize,
}

#[cfg(any(test, feature = "std"))]
impl Sink for HostQueue {
    fn queued(&self) -> usize {
        self.blocks.len()
    }
    fn try_push(&mut self, b: Sealed) -> Result<(), Sealed> {
        if self.blocks.len() >= self.cap {
            return Err(b);
        }
        self.blocks.push_back(b);
        Ok(())
    }
}

#[cfg(any(test, feature = "std"))]
impl crate::ports::BlockSource for HostQueue {
    fn front(&mut self) -> Option<&Sealed> {
        self.blocks.front()
    }
    fn pop(&mut self) {
        self.blocks.pop_front();
    }
}

/// Why a chatter hold could not be re-planned (it stays a hold, `ALARM:107`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The held block is an arc.
    NotLinear,
    /// The held block moves Z (a ramp or a plunge): no depth to reduce.
    MovesZ,
    /// Z + the step would pass the Z soft limit (BLU).
    SoftLimit { z: i32, max: i32 },
    /// The loader's record has no room for another detour ([`NESTED`] inside each other).
    Nested,
    /// The held block is a detour's layer (BLU) too thin to split again (below
    /// [`MIN_LAYER_BLU`] per half).
    Thin { layer: u32 },
    /// No depth step (`$276=0`), and no spindle speed within `$277` (or [`SPEED_TRIES`] of them)
    /// quieted the cut.
    NoSpeed,
}

impl Refusal {
    pub fn message(&self) -> &'static str {
        match self {
            Refusal::NotLinear => "the held block is an arc",
            Refusal::MovesZ => "the held block moves Z",
            Refusal::SoftLimit { .. } => "the lifted pass would pass the Z soft limit",
            Refusal::Nested => "too many depth steps inside each other",
            Refusal::Thin { .. } => "the layer is too thin to split again",
            Refusal::NoSpeed => "no depth step ($276), and no spindle speed within $277 quieted it",
        }
    }
}

/// The thinnest half a chattering layer is split into (BLU): 0.1 mm in 0.0001 in (0.04 mm in
/// microns would be 40; a step this small is below any useful depth of cut either way).
pub const MIN_LAYER_BLU: u32 = 40;

/// The step of a re-plan of a block that cuts a layer of `layer` BLU (0: a programmed block, the
/// layer unknown): the set step `lift` for a programmed block; half the layer for a detour's
/// layer (lifting it by the whole step would leave its pass in air and cut the same layer again,
/// for ever); None when that half is below [`MIN_LAYER_BLU`].
pub fn step(layer: u32, lift: u32) -> Option<u32> {
    match layer {
        0 => Some(lift),
        t => Some(t / 2).filter(|h| *h >= MIN_LAYER_BLU),
    }
}

/// The position change of a block (BLU).
pub fn displacement(b: &Block) -> [i32; 3] {
    // `dirs` is the frame's negated step per pulse.
    let signed = |steps: [u32; 3], signs: u8| {
        let dir = crate::nc::block::dirs(signs);
        [X, Y, Z].map(|k| -(steps[k] as i32) * dir[k])
    };
    match &b.motion {
        Motion::Rapid(r) => signed(r.steps, r.signs),
        Motion::Linear(l) => signed(l.steps, l.signs),
        Motion::Arc(c) => {
            let (a, bb) = c.plane.axes();
            let end = c
                .targets
                .get(usize::from(c.n_targets).saturating_sub(1))
                .copied()
                .unwrap_or(c.start);
            let mut d = [0; 3];
            d[a] = end[0] - c.start[0];
            d[bb] = end[1] - c.start[1];
            d[3 - a - bb] = c.helix;
            d
        }
        Motion::Dwell(_) => [0; 3],
    }
}

/// A rapid by `d` (BLU), sealed.
fn rapid(line: u32, d: [i32; 3], cfg: &FrameConfig) -> Sealed {
    let (steps, signs) = steps_and_signs(d.map(i64::from));
    Block {
        line,
        motion: Motion::Rapid(Rapid { steps, signs }),
    }
    .seal(cfg)
}

/// The straight feed move `l` re-made for the XY move `d` (BLU), sealed.
fn feed_move(line: u32, l: &Linear, d: [i32; 2], decel: bool, cfg: &FrameConfig) -> Sealed {
    let (steps, signs) = steps_and_signs([i64::from(d[0]), i64::from(d[1]), 0]);
    let q = isqrt(u64::from(steps[0]).pow(2) + u64::from(steps[1]).pow(2)) as u32;
    Block {
        line,
        motion: Motion::Linear(Linear {
            steps,
            q: q.max(1),
            signs,
            decel,
            ..*l
        }),
    }
    .seal(cfg)
}

/// The detour that removes the rest of `held` (a straight XY feed move ending at `p1`) in two
/// layers from the stop `pc`: see the module docs. Empty when nothing of it is left in XY.
pub fn detour(
    held: &Block,
    pc: [i32; 3],
    p1: [i32; 3],
    lift: u32,
    nc: &Settings,
    cfg: &FrameConfig,
) -> Result<heapless::Vec<Sealed, DETOUR>, Refusal> {
    let Motion::Linear(l) = &held.motion else {
        return Err(Refusal::NotLinear);
    };
    if l.steps[Z] != 0 {
        return Err(Refusal::MovesZ);
    }
    let mut out = heapless::Vec::new();
    let d = [p1[X] - pc[X], p1[Y] - pc[Y]];
    if d == [0, 0] {
        return Ok(out);
    }
    let up = i32::try_from(lift).unwrap_or(i32::MAX);
    let z = pc[Z].saturating_add(up);
    if z > nc.soft_max[Z] {
        return Err(Refusal::SoftLimit {
            z,
            max: nc.soft_max[Z],
        });
    }
    let line = held.line;
    for b in [
        rapid(line, [0, 0, up], cfg),
        feed_move(line, l, d, true, cfg),
        rapid(line, [-d[0], -d[1], 0], cfg),
        rapid(line, [0, 0, -up], cfg),
        feed_move(line, l, d, l.decel, cfg),
    ] {
        // DETOUR blocks fit.
        let _ = out.push(b);
    }
    Ok(out)
}

/// One re-plan, for the report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Replanned {
    /// Where the machine stopped (BLU).
    pub at: [i32; 3],
    /// The end of the held block (BLU).
    pub to: [i32; 3],
    /// The step (BLU).
    pub lift: u32,
    /// The held block's source line.
    pub line: u32,
    /// Re-plans so far in this run.
    pub count: u32,
}

/// The firmware's result-file form (tape mode, `chatter: re-planned ...`), parsed by the host's
/// tests: `COUNT at X,Y,Z to X,Y,Z lift=BLU line=N` (BLU).
impl core::fmt::Display for Replanned {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let (a, t) = (self.at, self.to);
        write!(
            f,
            "{} at {},{},{} to {},{},{} lift={} line={}",
            self.count, a[0], a[1], a[2], t[0], t[1], t[2], self.lift, self.line
        )
    }
}

/// Spindle speed changes in one held block before the depth steps take over: the rule's first
/// speed, and one more from the chatter heard at it (Smith and Delio iterate the same way).
pub const SPEED_TRIES: u32 = 2;

/// One change of the spindle speed for chatter, for the report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpeedChange {
    /// Where the machine stopped (BLU).
    pub at: [i32; 3],
    /// The speed before and after, rpm.
    pub from: u32,
    pub to: u32,
    /// The chatter frequency the hold heard, Hz (rounded).
    pub chatter_hz: u32,
    /// Tooth periods per chatter period at the new speed (the lobe's m).
    pub m: u32,
    /// The held block's source line.
    pub line: u32,
    /// Speed changes so far in this run.
    pub count: u32,
}

/// The firmware's result-file form (tape mode, `chatter: spindle ...`), parsed by the host's
/// tests: `COUNT S=FROM->TO at X,Y,Z chatter=HZ m=M line=N`.
impl core::fmt::Display for SpeedChange {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let a = self.at;
        write!(
            f,
            "{} S={}->{} at {},{},{} chatter={} m={} line={}",
            self.count, self.from, self.to, a[0], a[1], a[2], self.chatter_hz, self.m, self.line
        )
    }
}

/// What a call of [`Replan::poll`] did, for the loader to report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    None,
    /// A chatter hold was re-planned; the AC resumes.
    Replanned(Replanned),
    /// A chatter hold is to be answered by this spindle speed: the loader applies it to the
    /// spindle, then calls [`Replan::speed_applied`], which resumes the AC.
    Speed(SpeedChange),
    /// A chatter hold that stays a hold (`ALARM:107`), and why.
    Refused {
        at: [i32; 3],
        why: Refusal,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Watching for a chatter hold that has stopped the machine.
    Watch,
    /// The frame drops its queue (the abort bit is set).
    Abort,
    /// Done (re-planned or refused) for the hold that ended `Status::resumes` at this count:
    /// waiting for the AC to resume.
    Done { resumes: u32 },
}

/// A queued block and where it starts.
#[derive(Clone, Copy, Debug)]
struct Entry {
    block: Sealed,
    start: [i32; 3],
    /// The thickness (BLU) of the layer this block cuts when a detour made it (the lower pass:
    /// the step; the upper pass of a split layer: the rest); 0 for a programmed block (unknown).
    layer: u32,
    /// A chatter hold in it may change the spindle speed (`$277`): a programmed block; not a
    /// detour's, which comes only after the speeds failed in the same cut.
    speed: bool,
}

const EMPTY: Entry = Entry {
    block: Sealed::NOTHING,
    start: [0; 3],
    layer: 0,
    speed: false,
};

/// The loader's record of the blocks it has queued and the frame has not yet done (by the
/// blocks handed to the queue less those still in it), and blocks waiting for room in the queue (after a
/// re-plan the detour and the copies may be more than the queue holds). [`record_len`] of the
/// queue's length leaves room for [`NESTED`] detours. Loader task; host.
pub struct Replan<const N: usize> {
    ring: [Entry; N],
    /// Sequence number (the frame's block count) of the oldest entry kept.
    base: u32,
    /// Sequence number of the next block recorded, and of the next block handed to the queue.
    issued: u32,
    sent: u32,
    /// Where the last recorded block ends.
    end: [i32; 3],
    /// The depth step, BLU (0: chatter holds stay holds).
    lift: u32,
    /// The spindle speed reaction: `$277` (0: off), the flutes, the speed assumed until one is
    /// commanded (`$269`), the chatter frequency's resolution (Hz).
    max_rpm: u32,
    flutes: u32,
    monitor_rpm: u32,
    bin_hz: f32,
    /// The block (sequence number) of the last speed change, the changes in it, and in the run.
    speed_seq: u32,
    speed_tries: u32,
    speed_count: u32,
    nc: Settings,
    cfg: FrameConfig,
    state: State,
    count: u32,
    /// The re-plan under way: the detour, the held block's sequence number, the stop.
    path: heapless::Vec<Sealed, DETOUR>,
    held_seq: u32,
    at: [i32; 3],
    /// Its step and the layers of its upper and lower pass (0: unknown).
    step: u32,
    layers: [u32; 2],
    /// Events of the polls [`Replan::enqueue`] made, for the loader's next [`Replan::poll`].
    late: heapless::Deque<Event, 4>,
}

impl<const N: usize> Replan<N> {
    /// Starts at the machine's position `at`; from `ac`, `$276` the depth step (0 or less: off),
    /// `$277` the spindle speed reaction's top speed (0: off), `$267` the flutes and `$269` the
    /// speed until one is commanded. (The record's sequence numbers are its own: the queue's
    /// front is the blocks handed to it less those still in it.) Init or loader task.
    pub fn new(nc: Settings, ac: &AcSettings, at: [i32; 3]) -> Self {
        let (num, den) = nc.blu.per_mm();
        let lift_mm = ac.chatter_step_mm;
        let lift = if lift_mm > 0.0 {
            libm::round(f64::from(lift_mm) * num as f64 / den as f64) as u32
        } else {
            0
        };
        Replan {
            ring: [EMPTY; N],
            base: 0,
            issued: 0,
            sent: 0,
            end: at,
            lift,
            max_rpm: ac.chatter_max_rpm,
            flutes: ac.flutes,
            monitor_rpm: ac.monitor_rpm,
            bin_hz: ChatterSettings::default().bin_hz(),
            speed_seq: 0,
            speed_tries: 0,
            speed_count: 0,
            nc,
            cfg: FrameConfig::from_settings(&nc),
            state: State::Watch,
            count: 0,
            path: heapless::Vec::new(),
            held_seq: 0,
            at,
            step: 0,
            layers: [0; 2],
            late: heapless::Deque::new(),
        }
    }

    /// No reaction to chatter (a measure-only AC holds nothing, so nothing is re-planned: its
    /// verdicts are only told). Loader task, at start.
    pub fn without_reactions(&mut self) {
        self.lift = 0;
        self.max_rpm = 0;
    }

    /// A chatter hold gets a reaction (a depth step or a spindle speed), not only an alarm.
    pub fn reacts(&self) -> bool {
        self.lift > 0 || self.max_rpm > 0
    }

    /// The loader has applied [`Event::Speed`]'s speed `rpm` to the spindle: the monitors follow
    /// it and the AC resumes. Loader task.
    pub fn speed_applied(&self, status: &LoaderWriter, rpm: u32) {
        status.set_spindle_rpm(rpm);
        status.ask_resume();
    }

    /// The spindle speed for the chatter hold in block `seq`, if `$277` allows one and the
    /// block has not had [`SPEED_TRIES`] already.
    fn speed_change(
        &mut self,
        seq: u32,
        line: u32,
        at: [i32; 3],
        status: &LoaderWriter,
    ) -> Option<SpeedChange> {
        if self.max_rpm == 0 {
            return None;
        }
        let tries = if seq == self.speed_seq {
            self.speed_tries
        } else {
            0
        };
        if tries >= SPEED_TRIES {
            return None;
        }
        let hz = status.chatter_hz();
        let rpm = match status.spindle_rpm.get() {
            0 => self.monitor_rpm,
            r => r,
        };
        let lobe = lobe_rpm(hz, self.flutes, rpm, self.max_rpm, self.bin_hz)?;
        self.speed_seq = seq;
        self.speed_tries = tries + 1;
        self.speed_count = self.speed_count.wrapping_add(1);
        Some(SpeedChange {
            at,
            from: rpm,
            to: lobe.rpm,
            // A frequency below Nyquist: the cast is exact enough.
            chatter_hz: libm::roundf(hz) as u32,
            m: lobe.m,
            line,
            count: self.speed_count,
        })
    }

    /// After the frame dropped the queue for another reason (a soft reset, a jog cancel): the
    /// record starts again at `at`, empty. Loader task.
    pub fn restart(&mut self, at: [i32; 3]) {
        self.base = self.sent;
        self.issued = self.sent;
        self.end = at;
        self.state = State::Watch;
    }

    /// Blocks recorded and not yet handed to the queue.
    pub fn pending(&self) -> bool {
        self.sent != self.issued
    }

    /// The frame is dropping the queue for a re-plan: the loader must not change the operator's
    /// word (its abort bit) until [`Replan::poll`] has finished it.
    pub fn aborting(&self) -> bool {
        self.state == State::Abort
    }

    /// Records `b` and queues it; Err(b) while blocks recorded earlier still wait for room (a
    /// re-plan's) or the frame is dropping the queue: the loader waits for the frame, polling,
    /// and offers it again. So the record holds the queue and one block more, and the rest of
    /// it is room for detours. Loader task.
    pub fn offer(&mut self, sink: &mut impl Sink, b: Sealed) -> Result<(), Sealed> {
        self.trim(self.front(sink));
        self.drain(sink);
        let full = self.issued.wrapping_sub(self.base) as usize >= N;
        if self.pending() || full || self.state == State::Abort {
            return Err(b);
        }
        self.record(b);
        self.drain(sink);
        Ok(())
    }

    /// Offers `b` until it is taken, polling meanwhile (`wait` runs between tries); the polls'
    /// events come out of the loader's next [`Replan::poll`]. Loader task.
    pub fn enqueue(
        &mut self,
        sink: &mut impl Sink,
        b: Sealed,
        status: &LoaderWriter,
        mut wait: impl FnMut(),
    ) {
        let mut b = b;
        while let Err(back) = self.offer(sink, b) {
            b = back;
            wait();
            let e = self.poll(sink, status);
            if e != Event::None {
                // Four re-plans while one block waits cannot happen (each needs the AC to
                // resume and to hold again); the oldest would be dropped.
                if self.late.is_full() {
                    self.late.pop_front();
                }
                let _ = self.late.push_back(e);
            }
        }
    }

    fn record(&mut self, b: Sealed) {
        let i = self.issued as usize % N;
        if let Some(e) = self.ring.get_mut(i) {
            *e = Entry {
                block: b,
                start: self.end,
                layer: 0,
                speed: true,
            };
        }
        let d = displacement(&b);
        self.end = [X, Y, Z].map(|k| self.end[k].wrapping_add(d[k]));
        self.issued = self.issued.wrapping_add(1);
    }

    /// The sequence number of the queue's front block (the running one, or the next to start):
    /// the blocks handed to the queue less those still in it. Not `Status::blocks_done`: the
    /// frame publishes that only in frames without pulses, never during a chain of short blocks
    /// (the record then looked full and the chain ran dry: 8 % slow on the firmware test's 400
    /// blocks of 10 BLU).
    fn front(&self, sink: &impl Sink) -> u32 {
        self.sent.wrapping_sub(sink.queued() as u32)
    }

    /// Forgets the blocks the frame has done.
    fn trim(&mut self, done: u32) {
        // Only forward, and never past what was recorded.
        if done.wrapping_sub(self.base) <= self.issued.wrapping_sub(self.base) {
            self.base = done;
        }
    }

    fn entry(&self, seq: u32) -> Option<Entry> {
        (seq.wrapping_sub(self.base) < self.issued.wrapping_sub(self.base))
            .then(|| self.ring.get(seq as usize % N).copied())
            .flatten()
    }

    fn drain(&mut self, sink: &mut impl Sink) {
        // Nothing is queued while the frame drops the queue.
        while self.sent != self.issued && self.state != State::Abort {
            let Some(e) = self.entry(self.sent) else {
                break;
            };
            if sink.try_push(e.block).is_err() {
                break;
            }
            self.sent = self.sent.wrapping_add(1);
        }
    }

    /// One step of the reaction (call it every turn of the loader; the host after every frame):
    /// a chatter hold that has stopped the machine starts the frame's abort; the emptied queue
    /// gets the detour and the copies, and the AC is told to resume; waiting blocks are queued as
    /// room comes. Loader task.
    pub fn poll(&mut self, sink: &mut impl Sink, status: &LoaderWriter) -> Event {
        if let Some(e) = self.late.pop_front() {
            self.drain(sink);
            return e;
        }
        let mut event = Event::None;
        match self.state {
            State::Watch => {
                let chatter = status.ac_state.get() == alarm::AC_CHATTER;
                if self.reacts() && chatter && status.stopped() {
                    let done = self.front(sink);
                    self.trim(done);
                    let at = status.machine_position();
                    let held = self
                        .entry(done)
                        .filter(|e| matches!(e.block.motion, Motion::Linear(_) | Motion::Arc(_)));
                    let Some(e) = held else {
                        // Held in a rapid, a dwell or at the end: no cut to re-plan (the verdict
                        // was on the sound of the cut before); the AC resumes.
                        self.state = State::Done {
                            resumes: status.resumes.get(),
                        };
                        status.ask_resume();
                        self.drain(sink);
                        return Event::None;
                    };
                    // The spindle speed first, where `$277` allows: the block goes on.
                    let change = e
                        .speed
                        .then(|| self.speed_change(done, e.block.line, at, status))
                        .flatten();
                    if let Some(change) = change {
                        self.state = State::Done {
                            resumes: status.resumes.get(),
                        };
                        self.drain(sink);
                        return Event::Speed(change);
                    }
                    let plan = match step(e.layer, self.lift) {
                        _ if self.lift == 0 => Err(Refusal::NoSpeed),
                        Some(lift) => {
                            self.step = lift;
                            self.layers = if e.layer == 0 {
                                [0, lift]
                            } else {
                                [e.layer - lift, lift]
                            };
                            detour(&e.block, at, end_of(&e), lift, &self.nc, &self.cfg)
                        }
                        None => Err(Refusal::Thin { layer: e.layer }),
                    }
                    .and_then(|path| {
                        // The detour takes the held block's entry and len - 1 more.
                        let used = self.issued.wrapping_sub(self.base) as usize;
                        if used + path.len().saturating_sub(1) > N {
                            Err(Refusal::Nested)
                        } else {
                            Ok(path)
                        }
                    });
                    match plan {
                        Ok(path) => {
                            // The machine stands until the abort is done: the plan holds.
                            self.path = path;
                            self.held_seq = done;
                            self.at = at;
                            status.operator_bits(operator::ABORT, true);
                            self.state = State::Abort;
                        }
                        Err(why) => {
                            self.state = State::Done {
                                resumes: status.resumes.get(),
                            };
                            event = Event::Refused { at, why };
                        }
                    }
                }
            }
            State::Abort => {
                if sink.queued() == 0 && status.idle.get() {
                    status.operator_bits(operator::ABORT, false);
                    event = self.requeue();
                    self.state = State::Done {
                        resumes: status.resumes.get(),
                    };
                    status.ask_resume();
                }
                return event;
            }
            State::Done { resumes } => {
                if status.resumes.get() != resumes {
                    self.state = State::Watch;
                }
            }
        }
        self.drain(sink);
        event
    }

    /// The queue is empty and the machine stands: the record restarts at the stop with the
    /// detour in place of the held block, the blocks behind it unchanged (their starts too: the
    /// detour ends where the held block ended).
    fn requeue(&mut self) -> Event {
        let done = self.held_seq;
        let path = core::mem::take(&mut self.path);
        let Some(held) = self.entry(done) else {
            // Not reached: the abort starts only with a held block in the record.
            self.sent = done;
            self.restart(self.end);
            return Event::None;
        };
        let behind = self.issued.wrapping_sub(done).wrapping_sub(1);
        let len = path.len() as u32;
        // Move the blocks behind into their new places (towards the end when the detour is
        // longer than one block: from the last one down; else from the first one up).
        let from = done.wrapping_add(1);
        let to = done.wrapping_add(len);
        let slot = |seq: u32| seq as usize % N;
        for i in 0..behind {
            let i = if len > 1 { behind - 1 - i } else { i };
            let e = self.ring.get(slot(from.wrapping_add(i))).copied();
            if let (Some(e), Some(dst)) = (e, self.ring.get_mut(slot(to.wrapping_add(i)))) {
                *dst = e;
            }
        }
        let mut start = self.at;
        for (i, b) in path.iter().enumerate() {
            if let Some(dst) = self.ring.get_mut(slot(done.wrapping_add(i as u32))) {
                // The upper pass (1) and the lower pass (4) cut layers of known thickness.
                let layer = match i {
                    1 => self.layers[0],
                    4 => self.layers[1],
                    _ => 0,
                };
                *dst = Entry {
                    block: *b,
                    start,
                    layer,
                    speed: false,
                };
            }
            let d = displacement(b);
            start = [X, Y, Z].map(|k| start[k].wrapping_add(d[k]));
        }
        self.base = done;
        self.sent = done;
        self.issued = done.wrapping_add(len).wrapping_add(behind);
        self.count = self.count.wrapping_add(1);
        // The sequence numbers from `done` on are new blocks: no speed was tried in them.
        self.speed_tries = 0;
        Event::Replanned(Replanned {
            at: self.at,
            to: end_of(&held),
            lift: self.step,
            line: held.block.line,
            count: self.count,
        })
    }
}

fn end_of(e: &Entry) -> [i32; 3] {
    let d = displacement(&e.block);
    [X, Y, Z].map(|k| e.start[k].wrapping_add(d[k]))
}

#[cfg(test)]
mod tests;
