//! Host tests of the loader ([`super::loader::run`]), serial and program mode, on one thread: a
//! test board whose `running` and `wait` run the real frame (one frame per call, the pulse end
//! right after it), feed the sender's bytes at given frames (or a program file in memory),
//! collect the replies and play the operator inputs and the spindle output. What is checked: a
//! spindle change waits for the motion before it and applies before the line's own; an e-stop
//! stops at once with the position exact and latches ALARM:10 until released and `$X`; the feed
//! hold and cycle start buttons hold and resume; M2 waits for the motion and ends the job, on a
//! board with a spindle and on one without; a program file runs whatever its read size, stops at
//! its first refused line with the file's line number, and ends held on a frame overrun.
extern crate std;

use std::boxed::Box;
use std::collections::VecDeque;
use std::string::String;
use std::vec::Vec;

use heapless::spsc::{Consumer, Producer, Queue};

use super::console::{Console, Serial};
use super::loader::{run, Finished, LoaderBoard, Parts};
use super::program::{Program, ProgramFile, Said};
use super::status::{AcWriter, CycleWriter, PulseWriter, Writers};
use super::{FrameTask, Reloads, Status};
use crate::ac::Alarm;
use crate::gcode::Spindle;
use crate::inputs::{Events, Trip};
use crate::nc::{Frame, FrameConfig, Motion, Sealed};
use crate::ports::{FrameTimer, PulseTimer, SettingsStorage, StepPort};
use crate::protocol::rx::RxIsr;
use crate::protocol::rx::RxShared;
use crate::protocol::table::Persistent;
use crate::protocol::Protocol;

std::thread_local! {
    /// A program-mode session (`rt::program`): the program file's bytes and the read size. None
    /// (the default): serial mode.
    static PROGRAM: core::cell::RefCell<Option<(Vec<u8>, usize)>> =
        const { core::cell::RefCell::new(None) };
    /// The session's AC task: None (the default) no AC; `Some(ceiling)` an AC task whose periods
    /// run (`Status::ac_state` is `AC_RUN` from the first frame on), the loader getting
    /// `ceiling`: `Some` when the AC is enabled (the boards pass it so), None measure-only.
    static AC_TASK: core::cell::Cell<Option<Option<crate::ac::FeedCeiling>>> =
        const { core::cell::Cell::new(None) };
    /// The settings record the sessions of this thread share when set (`Some`): a session loads
    /// it and stores into it, so a second session starts from what the first stored. None (the
    /// default): no record, the defaults, and stores go nowhere.
    static RECORD: core::cell::RefCell<Option<Vec<u8>>> = const { core::cell::RefCell::new(None) };
    /// The machine's limit switches and the set-up of the sessions of this thread (`Some`): the
    /// bench closes each axis's switch from its true position, and the table takes the set-up.
    static MACHINE: core::cell::Cell<Option<(Switches, crate::settings::Setup)>> =
        const { core::cell::Cell::new(None) };
}

use crate::inputs::LimitSwitches as Switches;

const Q: usize = 16;
const T: usize = 1024;
const A: usize = 4;

/// The bench's settings storage: the thread's [`RECORD`] when a test keeps one, else none (the
/// defaults: 5 kHz, 0.0001 in, F30 = FRM).
struct NoStorage;

impl SettingsStorage for NoStorage {
    fn load(&mut self, buf: &mut [u8]) -> Option<usize> {
        RECORD.with(|r| {
            let r = r.borrow();
            let img = r.as_ref().filter(|i| !i.is_empty())?;
            let n = img.len().min(buf.len());
            buf.get_mut(..n)?.copy_from_slice(img.get(..n)?);
            Some(n)
        })
    }
    fn store(&mut self, image: &[u8]) -> bool {
        RECORD.with(|r| {
            if let Some(v) = r.borrow_mut().as_mut() {
                v.clear();
                v.extend_from_slice(image);
            }
        });
        true
    }
}

/// The pins, the frame timer and the pulse timer in software.
#[derive(Default)]
struct Pins {
    levels: u8,
    /// PULSE rises per axis.
    rises: [u32; 3],
}

impl StepPort for Pins {
    fn write_steps(&mut self, steps: u8) {
        for (k, r) in self.rises.iter_mut().enumerate() {
            *r += (steps >> k) as u32 & 1;
        }
        self.levels = (self.levels & !0b111) | (steps & 0b111);
    }
    fn write_signs(&mut self, signs: u8) {
        self.levels = (self.levels & 0b111) | ((signs & 0b111) << 3);
    }
    fn read_pins(&mut self) -> u8 {
        self.levels
    }
    fn pulse_still_high(&mut self) -> bool {
        self.levels & 0b111 != 0
    }
}

/// The frame and pulse timers: the bench runs the frames itself.
struct NoTimer;

impl FrameTimer for NoTimer {
    fn ack(&mut self) {}
    fn set_reload(&mut self, _: u32) {}
}

impl PulseTimer for NoTimer {
    fn start(&mut self) {}
    fn ack(&mut self) {}
}

/// What the board saw the loader do with the spindle: when (frame), what, and where the machine
/// stood and whether it was idle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct SpindleCall {
    frame: u64,
    state: Spindle,
    rpm: u32,
    position: [i32; 3],
    idle: bool,
}

/// The test board.
/// What the AC task (or the board) does in a session (see `Bench::ac_event`).
#[derive(Clone, Copy, Debug, PartialEq)]
enum AcEvent {
    Breakage,
    /// A measure-only AC's breakage verdict: the alarm for the loader and the state, as
    /// `rt::ac::AcPeriod::run` makes them when the AC is not enabled (no feed cap, no spindle
    /// stop).
    MeasuredBreakage,
    /// The board's interrupts overrun the period for this many frames: the pulse-end interrupt
    /// runs only after every other frame (it waits behind the next frame), as on a CPU too slow
    /// for the settings.
    LatePulseEnd(u64),
    /// With `$276` at this step (mm) and `$277` at this speed (rpm).
    Chatter {
        step_mm: f32,
        max_rpm: u32,
    },
}

/// The bench's board: `S`, it drives a spindle.
struct TestBoard<const S: bool>;

impl<const S: bool> crate::ports::Board for TestBoard<S> {
    const TIMER_HZ: u32 = 1_000_000;
    fn reload(clocks: u32) -> u32 {
        clocks
    }
    const LIMITS: crate::settings::BoardLimits = crate::settings::BoardLimits::GENERIC;
    const ISR_BOUNDS: Option<crate::settings::IsrBounds> = None;
    const SPINDLE: bool = S;
}

/// `S`: the board drives a spindle (`Board::SPINDLE`).
struct Bench<const S: bool = true> {
    status: &'static Status,
    /// The handles of the contexts the bench plays: the pulse end, the AC task, the
    /// board's frame wrapper (the loader's goes to the loader).
    pulse_w: PulseWriter<&'static Status>,
    ac_w: AcWriter<'static>,
    cycles_w: CycleWriter<&'static Status>,
    frame: FrameTask<&'static Status>,
    blocks: Consumer<'static, Sealed, Q>,
    pins: Pins,
    rx: RxIsr<'static>,
    tx: Consumer<'static, u8, T>,
    /// Bytes from the sender, each at a frame number.
    sends: VecDeque<(u64, Vec<u8>)>,
    /// Input events, each at a frame number.
    inputs: VecDeque<(u64, Events)>,
    /// The e-stop line (active) and the latch.
    estop_active: bool,
    latch: Option<Trip>,
    frames: u64,
    end: u64,
    out: String,
    spindle: Vec<SpindleCall>,
    /// Frames at which the e-stop line is released.
    release_at: Option<u64>,
    /// What a tripped event latches.
    trip: Trip,
    /// The board's frame limit and the frame cycles it "measures" from a frame number on.
    frame_limit: Option<u32>,
    slow_frames_at: Option<(u64, u32)>,
    /// The AC task's side of a tool breakage or chatter at a frame number: the hold, the spindle
    /// stop request (breakage) and the alarm for the loader, as `rt::ac::AcPeriod::run` makes
    /// them; after chatter also the AC's resume when the loader asks for it.
    ac_event: Option<(u64, AcEvent)>,
    alarms: Producer<'static, Alarm, A>,
    /// The frame at which the loader first said a job had ended (`Status::ac_new_job`), with the
    /// position then.
    job_end_at: Option<(u64, [i32; 3])>,
    /// The frames at which each `ok` came.
    oks_at: Vec<u64>,
    /// Program mode: how the run ended, whether it succeeded, its result lines.
    program: Option<(Option<Finished>, bool, Vec<String>)>,
    /// The machine's limit switches (None: no switches), and whether a closing one trips.
    switches: Option<Switches>,
    limit_trips: bool,
    /// Switches still closed at `$X` (they trip again once they have opened).
    let_be: u8,
    /// The tool in the simulated spindle (the machine model's lengths), and each fit (frame,
    /// tool) the loader reported.
    fitted: u8,
    fits: Vec<(u64, u8)>,
}

/// A program file in memory, read `chunk` bytes at a time; its result lines.
struct MemFile {
    bytes: Vec<u8>,
    at: usize,
    chunk: usize,
    results: Vec<String>,
}

impl ProgramFile for MemFile {
    const NAME: &'static str = "program.nc";

    fn read(&mut self, buf: &mut [u8]) -> Option<usize> {
        let rest = self.bytes.get(self.at..).unwrap_or(&[]);
        let n = self.chunk.min(buf.len()).min(rest.len());
        buf[..n].copy_from_slice(&rest[..n]);
        self.at += n;
        Some(n)
    }

    fn result(&mut self, kind: Said, text: core::fmt::Arguments) {
        self.results.push(std::format!("{}: {}", kind.word(), text));
    }
}

impl<const S: bool> Bench<S> {
    fn tick(&mut self) {
        self.frames += 1;
        while let Some((at, bytes)) = self.sends.front() {
            if *at > self.frames {
                break;
            }
            for &b in bytes {
                let _ = self.rx.push_byte(b);
            }
            self.sends.pop_front();
        }
        if self.release_at.is_some_and(|f| f <= self.frames) {
            self.estop_active = false;
        }
        // The frame's own measurement, as a board's wrapper writes it.
        let cycles = match self.slow_frames_at {
            Some((at, c)) if self.frames >= at => c,
            _ => 400,
        };
        let (s, ac) = (self.status, &self.ac_w);
        if AC_TASK.with(|c| c.get()).is_some() && s.ac_state.get() == 0 {
            ac.set_state(crate::rt::ac::AC_RUN);
        }
        if let Some((at, AcEvent::Chatter { .. })) = self.ac_event {
            if at == self.frames {
                ac.set_feed_cap(0);
                ac.set_chatter_hz(1680.0);
                ac.set_state(crate::protocol::codes::alarm::AC_CHATTER);
                let _ = self.alarms.enqueue(Alarm::Chatter {
                    freq_hz: 1680.0,
                    amplitude: 9.5,
                    threshold: 4.0,
                });
            }
            if ac.take_resume() {
                ac.set_feed_cap(u32::MAX);
                ac.set_state(crate::rt::ac::AC_RUN);
                ac.count_resume();
            }
        }
        if self.ac_event == Some((self.frames, AcEvent::Breakage)) {
            let b = crate::monitor::Breakage {
                tooth_period: 1234,
                e1: -900.0,
                e2: -950.0,
                th1: 300.0,
                th2: 200.0,
            };
            ac.set_feed_cap(0);
            ac.set_state(crate::protocol::codes::alarm::AC_BREAKAGE);
            ac.ask_spindle_stop();
            let _ = self.alarms.enqueue(Alarm::ToolBreakage(b));
        }
        if self.ac_event == Some((self.frames, AcEvent::MeasuredBreakage)) {
            ac.set_state(crate::protocol::codes::alarm::AC_BREAKAGE);
            let _ = self
                .alarms
                .enqueue(Alarm::ToolBreakage(crate::monitor::Breakage {
                    tooth_period: 1234,
                    e1: -900.0,
                    e2: -950.0,
                    th1: 300.0,
                    th2: 200.0,
                }));
        }
        let (min, max) = s.frame_cycles().unwrap_or((u32::MAX, 0));
        if cycles < min {
            self.cycles_w.set_min(cycles);
        }
        if cycles > max {
            self.cycles_w.set_max(cycles);
        }
        self.frame
            .run(&mut self.pins, &mut NoTimer, &mut NoTimer, &mut self.blocks);
        // The pulse timer's interrupt: only after a frame that raised PULSE lines (late: after
        // every other frame only, while the board overruns).
        let late = match self.ac_event {
            Some((at, AcEvent::LatePulseEnd(n))) => {
                self.frames >= at && self.frames < at + n && self.frames % 2 == 0
            }
            _ => false,
        };
        if self.pins.levels & 0b111 != 0 && !late {
            super::pulse_end(&mut self.pins, &mut NoTimer, self.pulse_w);
        }
        while let Some(b) = self.tx.dequeue() {
            self.out.push(b as char);
            if self.out.ends_with("ok\r\n") {
                self.oks_at.push(self.frames);
            }
        }
        if self.job_end_at.is_none() && s.ac_new_job.pending() {
            self.job_end_at = Some((self.frames, s.encoder()));
        }
    }

    fn idle(&self) -> bool {
        self.status.idle.get()
    }
}

impl<const S: bool> LoaderBoard for Bench<S> {
    fn start(&mut self) {}

    type Board = TestBoard<S>;

    fn spindle(&mut self, state: Spindle, rpm: u32, _max_rpm: u32) {
        self.spindle.push(SpindleCall {
            frame: self.frames,
            state,
            rpm,
            position: self.status.encoder(),
            idle: self.idle(),
        });
    }

    fn inputs(&mut self) -> Events {
        // A switch that closes while limits trip: the latch, as the board's debouncer sets it.
        if let Some(sw) = self.switches {
            let closed = sw.closed(self.status.encoder());
            // As the debouncer: a switch let be at `$X` trips again once it has opened.
            self.let_be &= closed;
            if self.limit_trips && closed & !self.let_be != 0 && self.latch.is_none() {
                self.latch = Some(Trip {
                    estop: false,
                    limits: closed,
                });
                return Events {
                    tripped: true,
                    ..Events::default()
                };
            }
        }
        match self.inputs.front() {
            Some((at, e)) if *at <= self.frames => {
                let e = *e;
                self.inputs.pop_front();
                if e.tripped {
                    self.estop_active = true;
                    self.latch = Some(self.trip);
                }
                e
            }
            _ => Events::default(),
        }
    }

    fn latched(&mut self) -> Option<Trip> {
        self.latch
    }

    fn acknowledge(&mut self) -> bool {
        if self.estop_active {
            return false;
        }
        self.let_be = self.limits();
        self.latch = None;
        true
    }

    fn limits(&mut self) -> u8 {
        self.switches
            .map_or(0, |sw| sw.closed(self.status.encoder()))
    }

    fn limit_trips(&mut self, on: bool) {
        self.limit_trips = on;
    }

    fn probe(&mut self) -> bool {
        let tool = self.fitted;
        self.switches
            .is_some_and(|sw| sw.touches(self.status.encoder(), tool))
    }

    fn tool_fitted(&mut self, tool: u8) {
        self.fitted = tool;
        self.fits.push((self.frames, tool));
    }

    fn latch_active(&mut self) -> bool {
        self.latch.is_some() && self.estop_active
    }

    fn frame_limit_cycles(&self) -> Option<u32> {
        self.frame_limit
    }

    fn running(&mut self) -> bool {
        self.tick();
        self.frames < self.end
    }

    fn wait(&mut self) {
        self.tick();
    }
}

/// Runs the loader for `frames` frames with the sender's `sends` and the `inputs`; returns the
/// bench (its output, spindle calls, final status).
fn session(
    sends: &[(u64, &str)],
    inputs: &[(u64, Events)],
    release_at: Option<u64>,
    frames: u64,
) -> Bench {
    session_with(sends, inputs, release_at, frames, ESTOP)
}

const ESTOP: Trip = Trip {
    estop: true,
    limits: 0,
};

fn session_with(
    sends: &[(u64, &str)],
    inputs: &[(u64, Events)],
    release_at: Option<u64>,
    frames: u64,
    trip: Trip,
) -> Bench {
    session_full(sends, inputs, release_at, frames, trip, None, None)
}

fn session_full(
    sends: &[(u64, &str)],
    inputs: &[(u64, Events)],
    release_at: Option<u64>,
    frames: u64,
    trip: Trip,
    frame_limit: Option<(u32, u64, u32)>,
    ac_event: Option<(u64, AcEvent)>,
) -> Bench {
    session_on(
        sends,
        inputs,
        release_at,
        frames,
        trip,
        frame_limit,
        ac_event,
    )
}

/// As [`session_full`], on a board with (`S`) or without a spindle.
fn session_on<const S: bool>(
    sends: &[(u64, &str)],
    inputs: &[(u64, Events)],
    release_at: Option<u64>,
    frames: u64,
    trip: Trip,
    frame_limit: Option<(u32, u64, u32)>,
    ac_event: Option<(u64, AcEvent)>,
) -> Bench<S> {
    let status: &'static Status = Box::leak(Box::new(Status::new()));
    let Writers {
        frame: frame_w,
        pulse: pulse_w,
        ac: ac_w,
        loader,
        cycles: cycles_w,
        sampler: _,
    } = status.split();
    let (blocks_tx, blocks) = Box::leak(Box::new(Queue::<Sealed, Q>::new())).split();
    let (tx_p, tx) = Box::leak(Box::new(Queue::<u8, T>::new())).split();
    let (alarm_tx, mut alarms) = Box::leak(Box::new(Queue::<Alarm, A>::new())).split();
    let (rx, task) = Box::leak(Box::new(RxShared::new())).split();
    let (mut table, _) =
        Persistent::load(NoStorage, crate::settings::BoardLimits::GENERIC).unwrap();
    if let Some((_, setup)) = MACHINE.with(|m| m.get()) {
        let mut m = table.settings.get();
        m.setup = setup;
        table.settings = m.validated(&table.board).unwrap();
    }
    if let Some((_, AcEvent::Chatter { step_mm, max_rpm })) = ac_event {
        let mut m = table.settings.get();
        m.ac.chatter_step_mm = step_mm;
        m.ac.chatter_max_rpm = max_rpm;
        table.settings = m.validated(&table.board).unwrap();
    }
    let settings = table.settings.nc;
    let mut proto = Protocol::new(task, (Q - 1) as u16);
    let mut blocks_tx = blocks_tx;
    let mut tx_p = tx_p;
    let mut bench = Bench {
        status,
        pulse_w,
        ac_w,
        cycles_w,
        frame: FrameTask::new(
            Frame::new(FrameConfig::from_settings(&settings)),
            Reloads { feed: 1, rapid: 1 },
            frame_w,
        ),
        blocks,
        pins: Pins::default(),
        rx,
        tx,
        sends: sends
            .iter()
            .map(|(f, s)| (*f, s.as_bytes().to_vec()))
            .collect(),
        inputs: inputs.iter().copied().collect(),
        estop_active: false,
        latch: None,
        frames: 0,
        end: frames,
        out: String::new(),
        spindle: Vec::new(),
        release_at,
        trip,
        frame_limit: frame_limit.map(|(l, _, _)| l),
        slow_frames_at: frame_limit.map(|(_, at, c)| (at, c)),
        ac_event,
        alarms: alarm_tx,
        job_end_at: None,
        oks_at: Vec::new(),
        program: None,
        switches: MACHINE.with(|m| m.get()).map(|(sw, _)| sw),
        fitted: 0,
        fits: Vec::new(),
        let_be: 0,
        limit_trips: true,
    };
    // The breakage and chatter events are an enabled AC's (its holds apply): the loader gets its
    // ceiling, as the boards give it with `$250=1`.
    let ceiling = match (AC_TASK.with(|c| c.get()), ac_event) {
        (Some(c), _) => c,
        (None, Some((_, AcEvent::Breakage | AcEvent::Chatter { .. }))) => {
            Some(crate::ac::AcSettings::default().ceiling)
        }
        _ => None,
    };
    let mut replan = Box::new(crate::rt::replan::Replan::<
        { crate::rt::replan::record_len(Q) },
    >::new(settings, &table.settings.ac, [0; 3]));
    // Program mode when a program file is set, else the serial line.
    let mut program = PROGRAM
        .with(|p| p.borrow_mut().take())
        .map(|(bytes, chunk)| {
            Program::new(MemFile {
                bytes,
                at: 0,
                chunk,
                results: Vec::new(),
            })
        });
    let mut serial = Serial::new(&mut proto, &mut tx_p, || {}, &settings);
    let console: &mut dyn Console = match program.as_mut() {
        Some(p) => p,
        None => &mut serial,
    };
    let finished = run(
        Parts {
            blocks: &mut blocks_tx,
            replan: &mut replan,
            table: &mut table,
            ceiling,
            console,
            ac_alarms: &mut alarms,
            status: &loader,
        },
        &mut bench,
    );
    if let Some(p) = program {
        let ok = p.ok();
        bench.program = Some((finished, ok, p.into_file().results));
    }
    bench
}

/// Program mode: `program` read `chunk` bytes at a time through the one loader, on the QEMU
/// board's shape (a simulated spindle), for at most `frames` frames, with an AC event. Returns
/// how the run ended, whether it succeeded, its result lines, and the bench.
fn program_run(
    program: impl AsRef<[u8]>,
    chunk: usize,
    frames: u64,
    ac_event: Option<(u64, AcEvent)>,
) -> (Option<Finished>, bool, Vec<String>, Bench) {
    PROGRAM.with(|p| *p.borrow_mut() = Some((program.as_ref().to_vec(), chunk)));
    let mut b = session_full(&[], &[], None, frames, ESTOP, None, ac_event);
    let (finished, ok, results) = b.program.take().expect("a program run");
    (finished, ok, results, b)
}

/// Program mode is the same loader with a program file for its line source: every line runs in
/// order whatever the read size (a line split across reads, CRLF, a last line without its
/// newline), the run ends once the machine stands after the file's last block, and nothing after
/// M2 is read.
#[test]
fn a_program_file_runs_through_the_loader_whatever_its_read_size() {
    let program = "G91 G1 F30 X0.01\r\nY0.01\n\n(a comment)\nX-0.005 Y0.005\nG1 Z-0.002";
    let mut ends = Vec::new();
    for chunk in [1, 7, 256] {
        let (finished, ok, results, b) = program_run(program, chunk, 40_000, None);
        assert_eq!(finished, Some(Finished::Done), "chunk {chunk}");
        assert!(ok && results.is_empty(), "chunk {chunk}: {results:?}");
        assert!(b.frames < 40_000 && b.status.idle.get());
        assert_eq!(b.status.encoder(), [50, 150, -20], "chunk {chunk}");
        ends.push(b.frames);
    }
    // The same motion, frame for frame, however the file was read.
    assert!(ends.windows(2).all(|w| w[0] == w[1]), "{ends:?}");
    // M2 ends the reading: the line after it never runs.
    let (finished, ok, results, b) =
        program_run("G91 G1 F30 X0.01\nM2\nG1 X0.05\n", 16, 40_000, None);
    assert_eq!((finished, ok), (Some(Finished::Done), true), "{results:?}");
    assert_eq!(b.status.encoder(), [100, 0, 0]);
}

/// The first refused line ends the reading: `error: line N: ...` with the file's own line number
/// (blank and comment lines count), the blocks before it run, the run fails. The same for a line
/// that is not UTF-8 or too long, refused before the parser.
#[test]
fn the_first_refused_line_of_a_program_stops_it_and_the_blocks_before_it_run() {
    let (finished, ok, results, b) = program_run(
        "G91 G1 F30 X0.01\n\n(comment)\nG1 X0.01 Q5\nG1 Y0.01\n",
        256,
        40_000,
        None,
    );
    assert_eq!((finished, ok), (Some(Finished::Done), false));
    assert_eq!(results.len(), 1, "{results:?}");
    assert!(results[0].starts_with("error: line 4: "), "{results:?}");
    assert_eq!(b.status.encoder(), [100, 0, 0]);

    // Raw bytes, read five at a time: the bad byte is in the second line.
    let bytes = b"G91 G1 F30 X0.01\nG1 Y0.01 (\xff)\nG1 Y0.01\n";
    let (finished, ok, results, b) = program_run(bytes, 5, 40_000, None);
    assert_eq!((finished, ok), (Some(Finished::Done), false));
    assert_eq!(results, ["error: line 2: not UTF-8"]);
    assert_eq!(b.status.encoder(), [100, 0, 0]);

    let long = std::format!(
        "G91 G1 F30 X0.01\nG1 Y0.01 ({})\nG1 Y0.01\n",
        "x".repeat(300)
    );
    let (_, ok, results, b) = program_run(&long, 64, 40_000, None);
    assert!(!ok);
    assert_eq!(results, ["error: line 2: line too long"]);
    assert_eq!(b.status.encoder(), [100, 0, 0]);
}

/// Unattended, a frame overrun holds the machine and ends the run once it stands (with the
/// position exact): `alarm: frame overrun ...`, [`Finished::Held`]; the rest is not read.
#[test]
fn a_frame_overrun_holds_a_program_and_ends_it_standing() {
    let program = "G91 G1 F30 X0.05\nG1 Y0.05\n";
    let (finished, _, results, b) =
        program_run(program, 256, 40_000, Some((300, AcEvent::LatePulseEnd(50))));
    assert_eq!(finished, Some(Finished::Held), "{results:?}");
    assert_eq!(results.len(), 1, "{results:?}");
    assert!(
        results[0].starts_with("alarm: frame overrun: ") && results[0].contains("no pulse lost"),
        "{results:?}"
    );
    assert!(b.status.stopped());
    let [x, y, _] = b.status.encoder();
    assert!(
        x > 0 && x < 500 && y == 0,
        "held on the first move: {x}, {y}"
    );
    // Without the overrun the same program runs to its end.
    let (finished, ok, _, b) = program_run(program, 256, 40_000, None);
    assert_eq!((finished, ok), (Some(Finished::Done), true));
    assert_eq!(b.status.encoder(), [500, 500, 0]);
}

fn oks(out: &str) -> usize {
    out.matches("ok\r\n").count()
}

/// 0.01 in = 100 BLU at F30 (FRM): about 100 frames of motion plus the ramps.
#[test]
fn a_spindle_change_waits_for_the_motion_before_it_and_runs_before_its_own() {
    let b = session(
        &[(1, "G91 G1 F30 X0.01\nM3 S500\nG1 X0.01\nM5 G1 X0.01\nM2\n")],
        &[],
        None,
        5000,
    );
    assert_eq!(oks(&b.out), 5, "{}", b.out);
    assert_eq!(b.status.encoder(), [300, 0, 0]);
    let calls: Vec<(Spindle, u32, [i32; 3], bool)> = b
        .spindle
        .iter()
        .map(|c| (c.state, c.rpm, c.position, c.idle))
        .collect();
    // M3 after the first move has run; M5 (with a move on its line) before that move; M2 with the
    // spindle already off changes nothing.
    assert_eq!(
        calls,
        [
            (Spindle::Cw, 500, [100, 0, 0], true),
            (Spindle::Off, 0, [200, 0, 0], true)
        ]
    );
    // The `ok` of `M3 S500` came after the first move: the sender saw 1 ok while it moved.
    assert!(b.spindle[0].frame > 100, "{:?}", b.spindle);
}

/// M2 (and M30) waits for the motion before it, as grbl syncs its buffer there, on every board;
/// only once it has run does the loader tell the AC that the job has ended (its `ok` then), so
/// the AC's next job (`AcController::new_job`) does not start under the last blocks of this one.
/// A soft reset ends the job too.
#[test]
fn a_program_end_waits_for_the_motion_then_ends_the_job() {
    let b = session(&[(1, "G91 G1 F30 X0.02\nM2\n")], &[], None, 3000);
    assert_eq!(oks(&b.out), 2, "{}", b.out);
    let (at, position) = b.job_end_at.expect("the job's end");
    assert_eq!(position, [200, 0, 0]);
    assert!(at > 200, "{at}");
    // The first `ok` came at once (the move queued), M2's after the move.
    assert!(b.oks_at[0] < 10 && b.oks_at[1] >= at, "{:?}", b.oks_at);
    // The same on a board without a spindle: M2 waits all the same, and no spindle is driven.
    let b = session_on::<false>(
        &[(1, "G91 G1 F30 X0.02\nM3 S500\nM2\n")],
        &[],
        None,
        3000,
        ESTOP,
        None,
        None,
    );
    assert_eq!(oks(&b.out), 3, "{}", b.out);
    let (at, position) = b.job_end_at.expect("the job's end without a spindle");
    assert_eq!(position, [200, 0, 0]);
    assert!(b.oks_at[1] < 10 && b.oks_at[2] >= at, "{:?}", b.oks_at);
    assert!(b.spindle.is_empty(), "{:?}", b.spindle);
    // No end, no job end; a soft reset ends it while moving.
    let b = session(&[(1, "G91 G1 F30 X0.02\n")], &[], None, 3000);
    assert_eq!(b.job_end_at, None);
    let b = session(&[(1, "G91 G1 F30 X1\n"), (100, "\u{18}")], &[], None, 3000);
    let (at, position) = b.job_end_at.expect("the reset's job end");
    assert!(at >= 100 && position[0] < 200, "{at} {position:?}");
}

#[test]
fn an_s_word_alone_changes_a_running_spindle_but_not_a_stopped_one() {
    let b = session(
        &[(1, "S800\nM4\nS900\nG91 G1 F30 Y0.01\nM5\n")],
        &[],
        None,
        3000,
    );
    assert_eq!(oks(&b.out), 5, "{}", b.out);
    let calls: Vec<(Spindle, u32)> = b.spindle.iter().map(|c| (c.state, c.rpm)).collect();
    assert_eq!(
        calls,
        [(Spindle::Ccw, 800), (Spindle::Ccw, 900), (Spindle::Off, 0)]
    );
    assert_eq!(b.spindle[2].position, [0, 100, 0]);
}

#[test]
fn an_estop_stops_at_once_latches_alarm_10_and_needs_release_and_unlock() {
    let trip = Events {
        tripped: true,
        ..Events::default()
    };
    // A long move (1 in = 10 000 BLU, ~2 s); the e-stop at frame 400; `$X` at 600 while still
    // pressed, released at 700, `$X` at 800, then a short move.
    let b = session(
        &[
            (1, "M3 S300\nG91 G1 F30 X1\n"),
            (600, "$X\n"),
            (800, "$X\n"),
            (900, "G91 G1 F30 Y0.01\n"),
        ],
        &[(400, trip)],
        Some(700),
        3000,
    );
    // The alarm once; the `$X` while pressed is refused before anything else is said.
    assert_eq!(b.out.matches("ALARM:10\r\n").count(), 1, "{}", b.out);
    assert!(b.out.contains("[MSG:E-stop]"), "{}", b.out);
    assert!(
        b.out.contains("[MSG:E-stop still active]\r\nerror:9\r\n"),
        "{}",
        b.out
    );
    assert_eq!(
        b.out.matches("[MSG:Caution: Unlocked]").count(),
        1,
        "{}",
        b.out
    );
    // Stopped at once: far short of 1 in, and the spindle went off at the trip.
    let x = b.status.encoder()[0];
    assert!(x > 0 && x < 1_000, "x = {x}");
    assert_eq!(
        b.status.encoder(),
        [x, 100, 0],
        "the move after the unlock runs"
    );
    assert_eq!(b.spindle.last().map(|c| c.state), Some(Spindle::Off));
    let off = b.spindle.iter().find(|c| c.state == Spindle::Off).unwrap();
    assert!(off.frame >= 400 && off.frame < 410, "{off:?}");
    // The stop position is the frame's own: exact (no pulse lost or added after the abort).
    assert_eq!(b.status.position(), b.status.encoder());
}

/// M0 and M6 wait for the motion before them, then the machine holds (`Hold:0`) with a message
/// naming the stop (the tool to fit) until cycle start; the lines sent meanwhile queue and run
/// after `~`. Unattended (a program file) the stop is told and the run goes on.
#[test]
fn m0_and_m6_stop_after_the_motion_before_them_and_wait_for_cycle_start() {
    let b = session(
        &[
            (
                1,
                "G91 G1 F30 X0.01
T2 M6
G1 X0.01
",
            ),
            (600, "?"),
            (700, "~"),
            (
                1000,
                "M0
G1 X0.01
",
            ),
            (1600, "?"),
            (1700, "~"),
        ],
        &[],
        None,
        4000,
    );
    assert!(
        b.out
            .contains("[MSG:Tool change (M6): fit T2, then cycle start]"),
        "{}",
        b.out
    );
    assert!(
        b.out.contains("[MSG:Pause (M0): cycle start resumes]"),
        "{}",
        b.out
    );
    // Held at frames 600 and 1600: stopped after the first and the second move.
    assert_eq!(b.out.matches("<Hold:0|").count(), 2, "{}", b.out);
    assert_eq!(oks(&b.out), 5, "{}", b.out);
    assert_eq!(
        b.status.encoder(),
        [300, 0, 0],
        "every move ran after cycle start"
    );
    // Without cycle start the machine stays after the first move.
    let b = session(
        &[(
            1,
            "G91 G1 F30 X0.01
T2 M6
G1 X0.01
",
        )],
        &[],
        None,
        3000,
    );
    assert_eq!(b.status.encoder(), [100, 0, 0]);
    // Unattended: told, and the run goes on to its end.
    let (finished, ok, results, b) = program_run(
        "G91 G1 F30 X0.01
T3 M6
G1 X0.01
M0
G1 X0.01
",
        256,
        40_000,
        None,
    );
    assert_eq!((finished, ok), (Some(Finished::Done), true), "{results:?}");
    assert_eq!(
        results,
        [
            "stop: tool change (M6) at line 2: T3",
            "stop: T3 has no limits (give it a diameter or $T3 F.. M..): the AC measures only",
            "stop: pause (M0) at line 4"
        ]
    );
    assert_eq!(b.status.encoder(), [300, 0, 0]);
}

/// An M6 tells the AC task, the sampler and the status report the fitted tool through the status
/// words (`Status::fitted_tool`): its number, flutes and limits (the table's own, else from its
/// geometry: `ac::strength::of_tool`), and says them; a tool with neither is said to have none
/// (the AC measures only) and the status report's `AC:` field goes (nothing caps the feed).
#[test]
fn an_m6_publishes_the_tools_limits_and_says_them() {
    use crate::ac::strength::{derived, Limits, Strength};
    use crate::gcode::tools::ToolKind;
    AC_TASK.with(|c| c.set(Some(Some(crate::ac::FeedCeiling::Programmed))));
    let b = session(
        &[
            (1, "$T2=D3 N2 K0\n$T4=D12.7 N4 K0 F900 M12\nT2 M6\n"),
            (300, "~"),
            (400, "?"),
            (500, "T4 M6\n"),
            (700, "~"),
            (800, "T5 M6\n"),
            (1000, "~"),
            (1100, "?"),
        ],
        &[],
        None,
        1200,
    );
    AC_TASK.with(|c| c.set(None));
    let out = &b.out;
    assert!(!out.contains("error"), "{out}");
    let small = derived(ToolKind::Flat, 3.0, &Strength::HSS).unwrap();
    assert!(
        out.contains(&std::format!(
            "[MSG:T2: F max {:.0} N, T max {:.2} N*m (its geometry)]",
            small.force_n,
            small.torque_nm
        )),
        "{out}"
    );
    assert!(
        out.contains("[MSG:T4: F max 900 N, T max 12.00 N*m (its table entry)]"),
        "{out}"
    );
    assert!(
        out.contains(
            "[MSG:T5 has no limits (give it a diameter or $T5 F.. M..): the AC measures only]"
        ),
        "{out}"
    );
    let reports: Vec<&str> = out.split('<').skip(1).collect();
    assert!(reports[0].contains("|T:2|AC:"), "{out}");
    assert!(
        reports[1].contains("|T:5|") && !reports[1].contains("|AC:"),
        "T5 is not capped: {out}"
    );
    let (n, t) = b.status.fitted_tool().unwrap();
    assert_eq!(n, 6, "three M6s, each counted twice");
    assert_eq!((t.number, t.flutes, t.limits), (5, 0, None));
    // The words as the AC task reads them, for T2 and T4.
    let status = Status::new();
    let w = status.split();
    for (tool, flutes, limits) in [
        (2, 2, small),
        (
            4,
            4,
            Limits {
                force_n: 900.0,
                torque_nm: 12.0,
            },
        ),
    ] {
        let fitted = super::status::FittedTool {
            number: tool,
            flutes,
            radius_mm: f32::from(flutes) * 0.75,
            kind: crate::gcode::tools::ToolKind::KINDS[usize::from(tool) % 3],
            limits: Some(limits),
        };
        w.loader.set_tool(&fitted);
        assert_eq!(status.fitted_tool().map(|f| f.1), Some(fitted));
    }
}

/// A peck cycle of many more blocks than the queue holds streams through it: the line's `ok`
/// comes at once, the loader pumps the rest as the queue empties (answering `?` and `!`
/// meanwhile), and the machine ends over the hole at R with every peck run.
#[test]
fn a_long_canned_cycle_streams_through_a_short_queue() {
    // 0.07 in from R 0.01 in to Z -0.06 in pecks of 0.004 in: 18 pecks, 54 blocks, queue of 16.
    let program = "G20 G0 X0 Y0 Z0.01 F30\nG99 G83 X0.01 Z-0.06 R0.01 Q0.004\nG80\nG0 X0\n";
    let hold = Events {
        feed_hold: true,
        ..Events::default()
    };
    let start = Events {
        cycle_start: true,
        ..Events::default()
    };
    let b = session(
        &[(1, program), (600, "?")],
        &[(500, hold), (900, start)],
        None,
        80_000,
    );
    assert_eq!(oks(&b.out), 4, "{}", b.out);
    assert!(b.out.contains("<Hold:"), "held mid-cycle: {}", b.out);
    assert_eq!(b.status.encoder(), [0, 0, 100]);
    // Every block of the cycle ran: the Z pulses are those of the program's blocks.
    let mut tape = crate::gcode::tape::Tape::new(crate::Settings::default());
    let mut blocks = Vec::new();
    for (n, l) in program.lines().enumerate() {
        tape.line(n as u32 + 1, l, |b| blocks.push(b)).unwrap();
    }
    tape.flush(|b| blocks.push(b));
    let z: u32 = blocks
        .iter()
        .map(|b| match b.motion {
            Motion::Rapid(r) => r.steps[2],
            Motion::Linear(l) => l.steps[2],
            _ => 0,
        })
        .sum();
    assert!(blocks.len() > 3 * Q, "{} blocks", blocks.len());
    assert_eq!(b.pins.rises[2], z);
}

/// Work offsets and the tool table survive a restart: G10 L2 / L1 are stored with the settings
/// at once, and the next start's parser has them (G55 X0 goes to the stored origin); `$RST=#`
/// clears them, for the running parser too.
#[test]
fn work_offsets_and_tools_are_stored_and_come_back_at_the_next_start() {
    RECORD.with(|r| *r.borrow_mut() = Some(Vec::new()));
    let b = session(
        &[(1, "G21 G10 L2 P2 X2.54 Y-1.27\nG10 L1 P3 Z5 R1.5\n")],
        &[],
        None,
        200,
    );
    assert_eq!(oks(&b.out), 2, "{}", b.out);
    let stored = RECORD.with(|r| r.borrow().clone()).unwrap();
    let work =
        crate::protocol::table::record::decode(&stored, &crate::settings::BoardLimits::GENERIC)
            .unwrap()
            .work;
    assert_eq!(work.systems[1], [2_540_000_000, -1_270_000_000, 0]);
    assert_eq!(work.tools.get(3).unwrap().length_pm, 5_000_000_000);
    // The next start: G55's origin and tool 3's length are there.
    let b = session(
        &[
            (1, "G21 G55 G0 X0 Y0\nT3 M6\nG43 H3 Z0\n"),
            (15_000, "$#\n"),
        ],
        &[(
            8_000,
            Events {
                cycle_start: true,
                ..Events::default()
            },
        )],
        None,
        20_000,
    );
    assert_eq!(b.status.encoder(), [1_000, -500, 1_969], "{}", b.out);
    assert!(b.out.contains("[G55:2.540,-1.270,0.000]"), "{}", b.out);
    // `$RST=#` clears them, in the record and in the running parser.
    let b = session(&[(1, "$RST=#\nG21 G55 G0 X1\n")], &[], None, 5000);
    assert_eq!(oks(&b.out), 2, "{}", b.out);
    assert_eq!(b.status.encoder(), [394, 0, 0]);
    // A G10 waits for the motion before it (the store must not come while the machine moves: a
    // flash store stalls the F446's interrupts), as grbl syncs its buffer there.
    let b = session(
        &[(1, "G20 G91 G1 F30 X0.01\nG1 0 L2 P2 X1\n")],
        &[],
        None,
        2000,
    );
    assert_eq!(oks(&b.out), 2, "{}", b.out);
    assert!(b.oks_at[0] < 10 && b.oks_at[1] > 100, "{:?}", b.oks_at);
    RECORD.with(|r| *r.borrow_mut() = None);
}

/// `$T` over the serial line: a tool described there is stored at once and the running parser
/// has it (G43 H applies its length without a restart); `$T3` lists it; `$T` while the machine
/// runs is refused (a store must not come during motion) and changes nothing.
#[test]
fn a_tool_set_with_dollar_t_is_stored_and_the_parser_has_it_at_once() {
    RECORD.with(|r| *r.borrow_mut() = Some(Vec::new()));
    let b = session(
        &[
            (1, "$T3=L5 D6 N4 K1 F900 M12\n"),
            (10, "$T3\n"),
            (20, "G21 G43 H3 G0 Z0\n"),
            (30, "G91 G1 F100 X1\n"),
            (40, "$T3=L7\n"),
        ],
        &[],
        None,
        20_000,
    );
    assert_eq!(oks(&b.out), 4, "{}", b.out);
    assert!(
        b.out
            .contains("$T3=L5 D6 N4 K1 F900 M12 (ball end mill)\r\nok\r\n"),
        "{}",
        b.out
    );
    assert!(b.out.contains("error:8"), "$T during motion: {}", b.out);
    // Z0 is the machine's 5 mm with tool 3's length applied (2.54 um BLU); X: 1 mm.
    assert_eq!(b.status.encoder(), [394, 0, 1_969], "{}", b.out);
    let stored = RECORD.with(|r| r.borrow().clone()).unwrap();
    let work =
        crate::protocol::table::record::decode(&stored, &crate::settings::BoardLimits::GENERIC)
            .unwrap()
            .work;
    let t = work.tools.get(3).unwrap();
    assert_eq!(
        t.length_pm, 5_000_000_000,
        "the refused $T3=L7 stored nothing"
    );
    assert_eq!(
        (t.diameter_pm, t.flutes, t.kind),
        (6_000_000_000, 4, crate::gcode::ToolKind::Ball)
    );
    assert_eq!((t.force_limit_n, t.torque_limit_nm), (900.0, 12.0));
    RECORD.with(|r| *r.borrow_mut() = None);
}

/// A homing set-up for the bench: quick (pull-off 0.2 mm, locate at 100 mm/min, pauses of
/// 20 ms) so a cycle fits a test.
fn homing_setup() -> crate::settings::Setup {
    crate::settings::Setup {
        homing: true,
        homing_pulloff_um: 200,
        homing_feed_um_min: 100_000,
        homing_debounce_ms: 20,
        ..crate::settings::Setup::default()
    }
}

/// The bench's machine: it stands 30, 20 and 5 mm short of its switches at power-up (true
/// BLU: the switches at 0; it starts at -11 811, -7 874, -1 969).
const SWITCHES: Switches = Switches {
    start: [-11_811, -7_874, -1_969],
    at: [0, 0, 0],
    negative: 0,
    probe: None,
    setter: None,
    tools: [0; crate::inputs::TOOLS],
};

/// The status report's MPos in BLU (tenths of a mil: the report's mm times 10 000 / 25.4).
fn mpos(out: &str) -> [i64; 3] {
    let r = out.rsplit("MPos:").next().unwrap();
    let v: Vec<f64> = r
        .split(['|', '>'])
        .next()
        .unwrap()
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    [0, 1, 2].map(|k| (v[k] / 0.00254).round() as i64)
}

/// With homing on (`$22=1`) the machine starts locked with `ALARM:11`: G-code is refused and
/// `$X` too (the position is not known); `$H` homes Z, then X, then Y, each stopping on its
/// switch, and leaves every axis its pull-off inside its soft maximum, which is where its switch
/// is. The lock is gone; G0 X0 Y0 Z0 goes to the machine's zero, 254 mm below the switches.
#[test]
fn homing_finds_the_switches_and_makes_the_soft_limits_the_machines() {
    MACHINE.with(|m| m.set(Some((SWITCHES, homing_setup()))));
    let b = session(
        &[
            (1, "G0 X1\n"),
            (10, "$X\n"),
            (20, "$H\n"),
            (60_000, "?"),
            (60_010, "G90 G0 X0 Y0 Z0\n"),
            (200_000, "?"),
        ],
        &[],
        None,
        200_100,
    );
    MACHINE.with(|m| m.set(None));
    let out = &b.out;
    assert!(out.contains("ALARM:11\r\n"), "{out}");
    let after_banner = out.split("ALARM:11").nth(1).unwrap();
    assert!(
        after_banner.starts_with("\r\n[MSG:Homing required: '$H']\r\nerror:9\r\n"),
        "{out}"
    );
    assert!(
        out.contains("[MSG:Homing required: '$H']\r\nerror:9\r\nok\r\n"),
        "$X refused, then $H: {out}"
    );
    // Home: the soft maximum (100 000 BLU, 40 000 for Z) less the pull-off (79 BLU).
    let home = out.split("<Idle|").nth(1).unwrap();
    assert_eq!(mpos(home), [99_921, 99_921, 39_921], "{out}");
    // The true position: 79 BLU inside each switch.
    let truth = [0, 1, 2].map(|k| b.status.encoder()[k] + SWITCHES.start[k]);
    assert_eq!(b.status.machine_encoder(), [0, 0, 0], "{out}");
    assert_eq!(
        truth,
        [-100_000, -100_000, -40_000],
        "machine zero is 254 mm below X's switch"
    );
    assert_eq!(oks(out), 2, "{out}");
}

/// Homing off (`$22=0`, the default): `$H` is `error:5`, as grbl's.
#[test]
fn homing_off_refuses_dollar_h() {
    let b = session(&[(1, "$H\n")], &[], None, 100);
    assert!(b.out.ends_with("error:5\r\n"), "{}", b.out);
}

/// A switch that never closes (the machine's switch far beyond the search): `ALARM:9`, the
/// machine stopped where the search ended, still locked.
#[test]
fn homing_without_a_switch_fails_with_alarm_9() {
    let far = Switches {
        at: [0, 0, 500_000],
        ..SWITCHES
    };
    let fast = crate::settings::Setup {
        homing_seek_um_min: 760_000,
        ..homing_setup()
    };
    MACHINE.with(|m| m.set(Some((far, fast))));
    // 120 000 BLU at 760 mm/min (4987 BLU/s, just under the feed DDA's top rate): 24 s.
    let b = session(&[(1, "$HZ\n"), (135_000, "G0 X1\n")], &[], None, 135_100);
    MACHINE.with(|m| m.set(None));
    assert!(
        b.out.contains("ALARM:9\r\nerror:9\r\nerror:9\r\n"),
        "{}",
        b.out
    );
    // 1.5 x Z's travel (80 000 BLU) searched.
    assert_eq!(b.status.encoder(), [0, 0, 120_000]);
}

/// An e-stop during a homed machine's move stops it and loses the position: once the e-stop is
/// released, `$X` is refused (homing required) until `$H` homes again; then it moves.
#[test]
fn an_estop_in_motion_loses_the_position_and_only_homing_unlocks() {
    MACHINE.with(|m| m.set(Some((SWITCHES, homing_setup()))));
    let estop = Events {
        tripped: true,
        ..Events::default()
    };
    let b = session(
        &[
            (1, "$H\n"),
            (60_000, "G91 G1 F500 X-5\n"),
            (72_000, "$X\n"),
            (72_010, "$H\n"),
            (140_000, "G21 G91 G1 F500 X-1\n"),
        ],
        &[(61_000, estop)],
        Some(70_000),
        150_000,
    );
    MACHINE.with(|m| m.set(None));
    let out = &b.out;
    assert!(out.contains("ALARM:10\r\n"), "{out}");
    let tail = out.split("ALARM:10\r\n").nth(1).unwrap();
    assert!(
        tail.contains("[MSG:Homing required: '$H']\r\nerror:9\r\nok\r\nok\r\n"),
        "$X refused, $H, then the move: {out}"
    );
    assert_eq!(
        b.status.machine_encoder(),
        [99_921 - 394, 99_921, 39_921],
        "{out}"
    );
}

/// Hard limits (`$21=1`, the default): a switch that closes in a move stops everything with
/// `ALARM:1` at the switch. `$X` unlocks with the switch still closed (as grbl's), so the axis
/// can be jogged off it; it does not trip while it stays closed, and trips again once it has
/// opened and closes anew. With `$21=0` the same move runs through (a machine whose switches
/// are only for homing).
#[test]
fn hard_limits_trip_with_21_on_and_not_with_21_off() {
    let sw = Switches {
        start: [0; 3],
        at: [1_969, 500_000, 500_000],
        negative: 0,
        probe: None,
        setter: None,
        tools: [0; crate::inputs::TOOLS],
    };
    for hard in [true, false] {
        let setup = crate::settings::Setup {
            hard_limits: hard,
            ..crate::settings::Setup::default()
        };
        MACHINE.with(|m| m.set(Some((sw, setup))));
        let b = session(
            &[
                (1, "G21 G91 G1 F2000 X10\n"),
                (40_000, "$X\n"),
                (40_100, "$J=G91 G21 X-2 F500\n"),
                (60_000, "?"),
                (60_100, "G21 G91 G1 F500 X5\n"),
            ],
            &[],
            None,
            100_000,
        );
        MACHINE.with(|m| m.set(None));
        if hard {
            let alarms: Vec<&str> = b.out.split("ALARM:1\r\n").collect();
            assert_eq!(alarms.len(), 3, "two trips: {}", b.out);
            assert!(
                alarms[1].starts_with(
                    "[MSG:Limit switch 001 (ZYX)]\r\n[MSG:Caution: Unlocked]\r\nok\r\nok\r\n<Idle|"
                ),
                "$X unlocks, the jog off runs: {}",
                b.out
            );
            // Jogged 2 mm (787 BLU) back from the switch.
            let off = mpos(alarms[1]);
            assert!(
                (1_969 - 787..1_969 - 787 + 20).contains(&off[0]),
                "{off:?}: {}",
                b.out
            );
            let x = b.status.encoder()[0];
            assert!(
                (1_969..1_969 + 20).contains(&x),
                "stopped at the switch again: {x}"
            );
        } else {
            assert!(!b.out.contains("ALARM"), "{}", b.out);
            assert_eq!(b.status.encoder(), [3_937 - 787 + 1_969, 0, 0]);
        }
    }
}

/// The bench's machine for probing: no switches near, a plate the probe touches at true Z
/// `z` and below (the machine starts at 0), the default set-up.
fn on_plate(z: i32) {
    let plate = Switches {
        start: [0; 3],
        at: [500_000; 3],
        negative: 0,
        probe: Some(z),
        setter: None,
        tools: [0; crate::inputs::TOOLS],
    };
    MACHINE.with(|m| m.set(Some((plate, crate::settings::Setup::default()))));
}

/// Probing against the machine model's plate at true Z -1000 BLU (the machine starts at 0):
/// G38.2 stops at once where the probe touches and says `[PRB:...:1]` before its `ok` (machine
/// coordinates), the parser standing there; G38.4 backs off until it clears; a G38.3 that finds
/// nothing says `:0` and `ok`; `$#` keeps the last probe; a G38.2 that finds nothing is
/// `ALARM:5`; a G38.2 started touching is `ALARM:4`, and nothing moves.
#[test]
fn probing_stops_where_the_probe_touches_and_reports_it() {
    on_plate(-1_000);
    let b = session(
        &[
            (1, "G21 G91 G38.2 Z-10 F200\n"),
            (19_000, "?"),
            (20_000, "G38.4 Z1 F20\n"),
            (40_000, "G0 Z1\n"),
            (42_000, "G38.3 Z2 F200\n"),
            (60_000, "$#\n"),
            (60_100, "G38.2 Z1 F200\n"),
        ],
        &[],
        None,
        80_000,
    );
    let out = &b.out;
    assert!(
        out.contains("[PRB:0.000,0.000,-2.540:1]\r\nok\r\n"),
        "{out}"
    );
    // Standing on the plate, the status report's Pn: says the probe touches.
    assert!(
        out.contains("<Idle|MPos:0.000,0.000,-2.540|FS:0,0|Pn:P|"),
        "{out}"
    );
    assert!(
        out.contains("[PRB:0.000,0.000,-2.537:1]\r\nok\r\n"),
        "backed off 1 BLU: {out}"
    );
    // Up 1 mm (394 BLU) from -999 BLU, then a G38.3 of 2 mm (787 BLU) up that touches nothing.
    assert!(out.contains("[PRB:0.000,0.000,0.462:0]\r\nok\r\n"), "{out}");
    assert!(
        out.contains("[TLO:0.000]\r\n[PRB:0.000,0.000,0.462:0]\r\nok\r\n"),
        "{out}"
    );
    assert!(
        out.ends_with("[PRB:0.000,0.000,1.463:0]\r\nALARM:5\r\nok\r\n"),
        "{out}"
    );
    assert_eq!(b.status.encoder(), [0, 0, 576]);
    // Touching at the start (standing on the plate after a G38.2): ALARM:4, nothing moves.
    let b = session(
        &[
            (1, "G21 G91 G38.2 Z-10 F200\n"),
            (19_000, "G38.2 Z-5 F100\n"),
        ],
        &[],
        None,
        21_000,
    );
    MACHINE.with(|m| m.set(None));
    assert!(
        b.out.ends_with(":1]\r\nok\r\nALARM:4\r\nok\r\n"),
        "{}",
        b.out
    );
    assert_eq!(b.status.encoder(), [0, 0, -1_000]);
}

/// A program file's probing move: the next line waits for it (the console of a program file
/// gives the next line without waiting for an answer; the probe's stop must not drop it, nor
/// the parser stand where it does not). The G0 X1 after the G38.2 runs from the plate.
#[test]
fn a_program_files_line_after_a_probe_runs_from_where_the_probe_stopped() {
    on_plate(-1_000);
    let (finished, ok, results, b) =
        program_run("G21 G91 G38.2 Z-10 F200\nG0 X1 Z1\n", 256, 40_000, None);
    assert_eq!((finished, ok), (Some(Finished::Done), true), "{results:?}");
    assert_eq!(b.status.encoder(), [394, 0, -1_000 + 394]);
    // A probe that finds nothing ends the run there, said as an alarm; the G0 after it never
    // runs.
    let (_, ok, results, b) = program_run("G21 G91 G38.2 Z-1 F200\nG0 X1\n", 256, 40_000, None);
    MACHINE.with(|m| m.set(None));
    assert!(!ok, "{results:?}");
    assert!(
        results[0].starts_with("alarm: probe failed (ALARM:5)"),
        "{results:?}"
    );
    assert_eq!(b.status.encoder(), [0, 0, -394]);
}

/// Probe protection: a move that is not a probing move and runs the probe into the plate (a
/// G0 meant for above it) holds the feed at the contact with `ALARM:13`; `~` does not resume
/// it until `$X`. A feed move that ends 1 BLU above the plate runs untouched.
#[test]
fn a_probe_contact_outside_probing_holds_with_alarm_13() {
    on_plate(-1_000);
    let b = session(
        &[
            (1, "G20 G90 G1 F20 Z-0.0999\n"),
            (40_000, "?"),
            (40_010, "G0 Z-0.2\n"),
            (60_000, "?"),
            (60_010, "~"),
            (61_000, "?"),
            (61_010, "$X\n"),
            (61_020, "~"),
            (80_000, "?"),
            (90_000, "?"),
        ],
        &[],
        None,
        90_100,
    );
    MACHINE.with(|m| m.set(None));
    let out = &b.out;
    let held = out.split("ALARM:13\r\n").collect::<Vec<_>>();
    assert_eq!(held.len(), 2, "one alarm: {out}");
    assert!(
        held[0].contains("<Idle|MPos:0.000,0.000,-2.537|"),
        "the first move, 1 BLU above the plate, ran through: {out}"
    );
    assert!(
        held[1].starts_with("[MSG:Probe contact outside probing: held]\r\n"),
        "{out}"
    );
    // Held near the plate (the rapid decelerates from where the probe touched), still held
    // after `~`, and after `$X` and `~` the move ends.
    let reports: Vec<&str> = held[1].split("<").skip(1).collect();
    assert!(reports[0].starts_with("Alarm|"), "{out}");
    assert!(reports[1].starts_with("Alarm|"), "~ refused: {out}");
    assert!(
        reports[2].starts_with("Idle|MPos:0.000,0.000,-5.080|"),
        "{out}"
    );
    let stopped = mpos(reports[0]);
    assert!(
        (-1_300..=-1_000).contains(&stopped[2]),
        "held near the contact: {stopped:?}"
    );
}

/// The bench's machine for tool changes: a tool setter whose pad's top is at true Z -7 874
/// (-20 mm) at X, Y 3 937 (10 mm), tool 1 3 937 BLU long (10 mm), tool 2 5 906 (15 mm); the
/// machine starts with no tool (0 long).
const SETTER: Switches = Switches {
    start: [0; 3],
    at: [500_000; 3],
    negative: 0,
    probe: None,
    setter: Some([3_937, 3_937, -7_874, 400]),
    tools: {
        let mut t = [0; crate::inputs::TOOLS];
        t[0] = 3_937;
        t[1] = 5_906;
        t
    },
};

/// `$341` = `mode`, the setter at 10, 10 mm, quick probing (pull-off 0.5 mm, seek 600 mm/min,
/// slow 100 mm/min, at most 60 mm).
fn change_setup(mode: u8) -> crate::settings::Setup {
    crate::settings::Setup {
        tool_change: mode,
        setter_um: [10_000, 10_000],
        probe_distance_um: 60_000,
        probe_seek_um_min: 600_000,
        probe_slow_um_min: 100_000,
        homing_pulloff_um: 500,
        ..crate::settings::Setup::default()
    }
}

/// The tool setter (`$341=2`): at each M6 the spindle stops, Z rises to the G30 position's Z
/// and X, Y go there; at the first change the tool in the spindle is measured on the setter
/// first. The machine holds naming the tool; after cycle start the new tool is measured, the
/// tool length offset becomes the old one plus how much higher the new tip touched, the
/// spindle runs again, and the machine returns so that the new tip is where the old one was;
/// only then comes the M6's `ok`. Two changes: the offsets are the tools' true lengths (the
/// first tool, none, is 0 long), and work Z0 puts tool 2's tip where no tool's would be.
#[test]
fn the_tool_change_measures_each_tool_on_the_setter_and_returns() {
    MACHINE.with(|m| m.set(Some((SETTER, change_setup(2)))));
    let b = session(
        &[
            (
                1,
                "G21 G90 G0 X0 Y0 Z25\nG30.1\nM3 S1000\nG0 X5 Y5 Z-2\nT1 M6\n",
            ),
            (150_000, "?"),
            (150_010, "~"),
            (300_000, "?"),
            (300_010, "T2 M6\n"),
            (450_000, "?"),
            (450_010, "~"),
            (600_000, "?"),
            (600_010, "$#\n"),
            (600_020, "G0 Z0\n"),
            (650_000, "?"),
        ],
        &[],
        None,
        650_100,
    );
    MACHINE.with(|m| m.set(None));
    let out = &b.out;
    assert!(!out.contains("error") && !out.contains("ALARM"), "{out}");
    assert_eq!(
        b.fits.iter().map(|f| f.1).collect::<Vec<_>>(),
        [1, 2],
        "{out}"
    );
    let reports: Vec<&str> = out.split('<').skip(1).collect();
    // Waiting for T1 at the G30 position, held; the M6 not yet answered.
    let g30 = [0, 0, 9_843];
    assert!(reports[0].starts_with("Hold:0|"), "{out}");
    assert_eq!(mpos(reports[0]), g30, "{out}");
    assert!(
        out.contains("[MSG:Tool change (M6): fit T1, then cycle start]"),
        "{out}"
    );
    assert_eq!(oks(out.split('<').next().unwrap()), 4, "{out}");
    // Back over X5 Y5, Z 10 mm higher (T1 is 10 mm longer than no tool), the tip where it was.
    let blu = |mm: f64| (mm / 0.00254).round() as i64;
    assert_eq!(
        mpos(reports[1]),
        [blu(5.0), blu(5.0), blu(-2.0) + 3_937],
        "{out}"
    );
    assert!(reports[2].starts_with("Hold:0|"), "{out}");
    assert_eq!(mpos(reports[2]), g30, "{out}");
    assert_eq!(
        mpos(reports[3]),
        [blu(5.0), blu(5.0), blu(-2.0) + 5_906],
        "{out}"
    );
    let tlo = std::format!("[TLO:{:.3}]", 5_906.0 * 0.00254);
    assert!(out.contains(&tlo), "{tlo}: {out}");
    // Work Z0 with T2: the spindle 15 mm up, T2's tip at true Z 0.
    assert_eq!(mpos(reports[4])[2], 5_906, "{out}");
    assert_eq!(oks(out), 8, "{out}");
    // The spindle: off for each change, on again before the way back.
    let states: Vec<Spindle> = b.spindle.iter().map(|c| c.state).collect();
    assert_eq!(
        states,
        [
            Spindle::Cw,
            Spindle::Off,
            Spindle::Cw,
            Spindle::Off,
            Spindle::Cw
        ],
        "{out}"
    );
    for c in &b.spindle[1..] {
        assert!(c.idle, "the machine stands for the spindle: {c:?}");
    }
}

/// `$341=1`: the table's length. The change goes to the G30 position, holds, and takes the
/// tool table's length as the offset (`[TLO:]` and `$G`'s G43), returning with the tip where
/// it was. A program run unattended goes through the same change without a hold.
#[test]
fn the_tool_change_takes_the_tables_length_and_runs_unattended() {
    MACHINE.with(|m| m.set(Some((SETTER, change_setup(1)))));
    let b = session(
        &[
            (
                1,
                "G21 G90 G0 X0 Y0 Z25\nG30.1\nG10 L1 P3 Z12.7\nG0 X5 Y5 Z-2\nT3 M6\n",
            ),
            (60_000, "?"),
            (60_010, "~"),
            (120_000, "?"),
            (120_010, "$#\n$G\n"),
        ],
        &[],
        None,
        120_100,
    );
    let out = &b.out;
    assert!(!out.contains("error") && !out.contains("ALARM"), "{out}");
    let reports: Vec<&str> = out.split('<').skip(1).collect();
    assert!(reports[0].starts_with("Hold:0|"), "{out}");
    assert_eq!(mpos(reports[0]), [0, 0, 9_843], "{out}");
    // 12.7 mm = 5 000 BLU higher.
    assert_eq!(mpos(reports[1]), [1_969, 1_969, -787 + 5_000], "{out}");
    assert!(out.contains("[TLO:12.700]"), "{out}");
    assert!(out.contains(" G43 "), "{out}");
    assert_eq!(b.fits.iter().map(|f| f.1).collect::<Vec<_>>(), [3]);
    let (finished, ok, results, b) = program_run(
        "G21 G90 G0 X0 Y0 Z25\nG30.1\nG10 L1 P3 Z12.7\nG0 X5 Y5 Z-2\nT3 M6\nG91 G0 X1\n",
        256,
        100_000,
        None,
    );
    MACHINE.with(|m| m.set(None));
    assert_eq!((finished, ok), (Some(Finished::Done), true), "{results:?}");
    assert_eq!(b.status.encoder(), [1_969 + 394, 1_969, -787 + 5_000]);
    assert_eq!(b.fits.iter().map(|f| f.1).collect::<Vec<_>>(), [3]);
}

/// G4 waits for the motion before it and is answered once its dwell has run, as grbl's (senders
/// use it to wait for the machine: CNCjs's `%wait` is `G4 P0.5`, bCNC's tool change a `g4p1`
/// before it reads the position): a `$#` right after its `ok` is answered (not `error:8`), and
/// the `ok` comes after the move's end plus the dwell.
#[test]
fn g4_is_answered_after_the_motion_before_it_and_its_dwell() {
    let b = session(&[(1, "G91 G1 F30 X0.01\nG4 P0.2\n$#\n")], &[], None, 6_000);
    let out = &b.out;
    assert!(!out.contains("error"), "{out}");
    assert_eq!(oks(out), 3, "{out}");
    // 100 BLU at 30 ipm (1 BLU a frame, with its ramps), then 0.2 s = 1000 frames.
    let g4 = b.oks_at[1];
    assert!((1_100..1_450).contains(&g4), "G4's ok at frame {g4}");
    assert!(out.contains("[G54:"), "{out}");
    // Which lines may be a G4 (the parser decides the rest).
    for (line, dwell) in [
        ("G4 P1", true),
        ("g04p1", true),
        ("G 4 P1", true),
        ("G4.0 P1", false),
        ("G40", false),
        ("G43.1 Z4", false),
        ("X4 G1", false),
        ("G1 X1 G4", true),
    ] {
        assert_eq!(super::loader::may_dwell(line), dwell, "{line}");
    }
}

/// The tool length offset a guided tool change set survives a soft reset (the tool in the
/// spindle has not changed; grbl would reset it to G49 with the other modes, and a sender that
/// resets at a job's end, as bCNC does, would cut the next job with the tool 15 mm too deep).
#[test]
fn a_soft_reset_keeps_the_length_offset_of_the_tool_in_the_spindle() {
    MACHINE.with(|m| m.set(Some((SETTER, change_setup(1)))));
    let b = session(
        &[
            (1, "G21 G90 G0 X0 Y0 Z25\nG30.1\nG10 L1 P3 Z12.7\nT3 M6\n"),
            (60_000, "~"),
            (100_000, "\u{18}"),
            (100_100, "$#\n$G\n"),
        ],
        &[],
        None,
        100_300,
    );
    MACHINE.with(|m| m.set(None));
    let after = b.out.rsplit("Grbl 1.1h").next().unwrap();
    assert!(after.contains("[TLO:12.700]"), "{}", b.out);
    assert!(after.contains(" G43 "), "{}", b.out);
}

/// A tool setter that is not where `$345`/`$346` say (none in the machine): the probe finds no
/// contact within `$342`, the change fails with `ALARM:5` and the M6 is refused.
#[test]
fn a_tool_change_that_finds_no_setter_fails_with_alarm_5() {
    let none = Switches {
        setter: None,
        ..SETTER
    };
    MACHINE.with(|m| m.set(Some((none, change_setup(2)))));
    let b = session(
        &[(1, "G21 G90 G0 X0 Y0 Z25\nG30.1\nT1 M6\n")],
        &[],
        None,
        60_000,
    );
    MACHINE.with(|m| m.set(None));
    assert!(b.out.ends_with("ALARM:5\r\nerror:9\r\n"), "{}", b.out);
    // Stopped at the end of the search: 60 mm below the G30 Z.
    assert_eq!(b.status.encoder(), [3_937, 3_937, 9_843 - 23_622]);
    assert!(b.fits.is_empty());
}

/// The senders' own probe and zero lines (from their sources: bCNC without spaces and in lower
/// case, UGS with G49 and P0, CNCjs with P1), each against the plate 1 mm below: every line is
/// answered `ok`, every probe stops on the plate and reports it, and each zeroing puts work zero
/// where the sender meant it.
#[test]
fn the_senders_probe_and_zero_lines_run_as_they_mean() {
    on_plate(-394);
    for (sender, lines, zero) in [
        // bCNC: single probe, then its zero (no spaces), then $#.
        (
            "bCNC",
            &["G21", "G91", "G38.2Z-10F10.0", "G90", "G10L20P1Z0", "$#"][..],
            "[G54:0.000,0.000,-1.001]",
        ),
        // bCNC's probe routine's form: lower case, words run together.
        (
            "bCNC routine",
            &["G21", "g91G38.2f10.0z-31.5", "g90", "G10L20P1X0Y0Z0", "$#"][..],
            "[G54:0.000,0.000,-1.001]",
        ),
        // UGS's probe module: G49 first, P0 (the system in force).
        (
            "UGS",
            &[
                "G21 G91 G49",
                "G38.2 Z-10 F100",
                "G90 G21",
                "G10 P0 L20 Z0",
                "$#",
            ][..],
            "[G54:0.000,0.000,-1.001]",
        ),
        // CNCjs's probe widget on a 10 mm plate.
        (
            "CNCjs",
            &[
                "G21",
                "G91",
                "G38.2 Z-10 F20",
                "G90",
                "G10 L20 P1 Z10",
                "$#",
            ][..],
            "[G54:0.000,0.000,-11.001]",
        ),
    ] {
        let sends: Vec<(u64, String)> = lines
            .iter()
            .enumerate()
            .map(|(i, l)| (1 + 20_000 * i as u64, std::format!("{l}\n")))
            .collect();
        let sends: Vec<(u64, &str)> = sends.iter().map(|(f, l)| (*f, l.as_str())).collect();
        let b = session(&sends, &[], None, 20_000 * lines.len() as u64 + 100);
        let out = &b.out;
        assert_eq!(oks(out), lines.len(), "{sender}: {out}");
        assert!(
            !out.contains("error") && !out.contains("ALARM"),
            "{sender}: {out}"
        );
        assert!(
            out.contains("[PRB:0.000,0.000,-1.001:1]\r\n"),
            "{sender}: {out}"
        );
        assert!(out.contains(zero), "{sender}: {out}");
    }
    MACHINE.with(|m| m.set(None));
}

#[test]
fn feed_hold_and_cycle_start_buttons_hold_and_resume() {
    let hold = Events {
        feed_hold: true,
        ..Events::default()
    };
    let start = Events {
        cycle_start: true,
        ..Events::default()
    };
    let b = session(
        &[(1, "G91 G1 F30 X0.1\n"), (700, "?")],
        &[(300, hold), (1200, start)],
        None,
        4000,
    );
    // Held in between: the status at frame 700 says Hold (stopped: Hold:0).
    assert!(b.out.contains("<Hold:0|"), "{}", b.out);
    assert_eq!(b.status.encoder(), [1000, 0, 0], "resumed to the end");
}

#[test]
fn a_limit_switch_stops_and_raises_alarm_1() {
    let trip = Events {
        tripped: true,
        ..Events::default()
    };
    let y_limit = Trip {
        estop: false,
        limits: 0b010,
    };
    let b = session_with(
        &[(1, "G91 G1 F30 Y1\n"), (800, "$X\n")],
        &[(300, trip)],
        Some(500),
        1500,
        y_limit,
    );
    assert!(b.out.contains("ALARM:1\r\n"), "{}", b.out);
    assert!(!b.out.contains("ALARM:10"), "{}", b.out);
    assert!(b.out.contains("[MSG:Limit switch 010 (ZYX)]"), "{}", b.out);
    assert!(b.out.contains("[MSG:Caution: Unlocked]"), "{}", b.out);
    let y = b.status.encoder()[1];
    assert!(y > 0 && y < 1_000, "stopped at once: y = {y}");
}

/// A board that states its frame limit: frames within it change nothing; a frame above it holds
/// the feed (the machine stops on its ramp, the block is kept) and raises ALARM:111 once.
#[test]
fn a_frame_over_the_boards_limit_holds_the_feed_and_raises_alarm_111() {
    let b = session_full(
        &[(1, "G91 G1 F30 X1\n"), (1500, "?")],
        &[],
        None,
        2000,
        ESTOP,
        Some((500, 300, 600)),
        None,
    );
    assert_eq!(b.out.matches("ALARM:111\r\n").count(), 1, "{}", b.out);
    assert!(
        b.out.contains("took 600 cycles, the board allows 500"),
        "{}",
        b.out
    );
    // The alarm state, standing (feed 0) short of the end: the held block is kept.
    assert!(
        b.out.contains("<Alarm|") && b.out.contains("|FS:0,"),
        "{}",
        b.out
    );
    let x = b.status.encoder()[0];
    assert!(x > 0 && x < 10_000, "held short of the end: x = {x}");
    // Within the limit: nothing happens.
    let b = session_full(
        &[(1, "G91 G1 F30 X0.01\n")],
        &[],
        None,
        1000,
        ESTOP,
        Some((500, 300, 450)),
        None,
    );
    assert!(!b.out.contains("ALARM"), "{}", b.out);
    assert_eq!(b.status.encoder(), [100, 0, 0]);
}

/// An e-stop while a line waits for the spindle: the waiting line is answered (refused: the
/// alarm locks G-code), so the sender's count stays right and the lines after `$X` are answered.
#[test]
fn a_trip_while_a_spindle_line_waits_answers_it_and_the_lines_after() {
    let trip = Events {
        tripped: true,
        ..Events::default()
    };
    let b = session(
        &[
            (1, "G91 G1 F30 X1\nM3 S500\n"),
            (800, "$X\n"),
            (900, "G91 G1 F30 Y0.01\n"),
        ],
        &[(400, trip)],
        Some(500),
        3000,
    );
    assert!(
        b.out.contains("ALARM:10\r\n[MSG:E-stop]\r\nerror:9\r\n"),
        "{}",
        b.out
    );
    assert!(b.out.contains("[MSG:Caution: Unlocked]"), "{}", b.out);
    // Every line answered once: the move, M3 (error:9), $X, the move after it.
    let answers = b.out.matches("ok\r\n").count() + b.out.matches("error:").count();
    assert_eq!(answers, 4, "{}", b.out);
    assert_eq!(b.status.encoder()[1], 100, "the move after $X ran");
    assert!(
        b.spindle.iter().all(|c| c.state == Spindle::Off),
        "{:?}",
        b.spindle
    );
}

/// The turn that sees a trip does not first apply a waiting spindle change: however the trip
/// and the machine's stop coincide, the spindle never turns on.
#[test]
fn no_spindle_on_in_the_turn_of_a_trip() {
    let sends = [(1u64, "G91 G1 F30 X0.01\nM3 S500\n")];
    let b = session(&sends, &[], None, 2000);
    let on_at = b.spindle[0].frame;
    let trip = Events {
        tripped: true,
        ..Events::default()
    };
    for at in [on_at - 1, on_at, on_at + 1] {
        let b = session(&sends, &[(at, trip)], None, 2000);
        let on = b.spindle.iter().any(|c| c.state != Spindle::Off);
        assert!(
            on == (at > on_at),
            "trip at {at} (on at {on_at}): {:?}",
            b.spindle
        );
    }
}

/// `~` does not resume a feed the frame-overrun alarm holds (nor does the cycle start button).
#[test]
fn resume_waits_for_unlock_after_alarm_111() {
    let run = |sends: &[(u64, &str)], inputs: &[(u64, Events)]| {
        session_full(
            sends,
            inputs,
            None,
            4000,
            ESTOP,
            Some((500, 300, 600)),
            None,
        )
    };
    let held = run(&[(1, "G91 G1 F30 X1\n")], &[]);
    let start = Events {
        cycle_start: true,
        ..Events::default()
    };
    let tried = run(&[(1, "G91 G1 F30 X1\n"), (1500, "~")], &[(1600, start)]);
    assert_eq!(
        tried.status.encoder(),
        held.status.encoder(),
        "{}",
        tried.out
    );
    // After `$X`, `~` resumes.
    let resumed = run(&[(1, "G91 G1 F30 X1\n"), (1500, "$X\n"), (1600, "~")], &[]);
    assert!(
        resumed.status.encoder()[0] > held.status.encoder()[0],
        "{}",
        resumed.out
    );
}

/// A tool breakage (the AC task's hold, spindle stop request and alarm): the loader stops the
/// spindle at once, says `ALARM:108` with the residuals in a `[MSG:...]`; `~` and `$X` are
/// refused (the broken tool is still in the cut) and a spindle line waiting for the motion is not
/// applied; a reset drops the queue with the spindle off, and then `$X` unlocks. The commanded
/// speed reaches `Status::spindle_rpm` (the monitors' tooth period).
/// A session of 3000 frames in which the tool breaks at frame 2000.
fn broken_at_2000(sends: &[(u64, &str)]) -> Bench {
    session_full(
        sends,
        &[],
        None,
        3000,
        ESTOP,
        None,
        Some((2000, AcEvent::Breakage)),
    )
}

#[test]
fn a_tool_breakage_stops_the_spindle_and_only_a_reset_leads_on() {
    let calls =
        |b: &Bench| -> Vec<(Spindle, u32)> { b.spindle.iter().map(|c| (c.state, c.rpm)).collect() };
    // A spindle line waiting for the motion is never applied (it would turn the spindle on).
    // (A breakage declared in the loader turn where the block before the line has run out:
    // that turn would apply the line.)
    let sends = [(1, "M3 S1000\n"), (2, "G91 G1 F30 X0.01\n"), (3, "S2000\n")];
    let free = session_full(&sends, &[], None, 3000, ESTOP, None, None);
    assert_eq!(calls(&free), [(Spindle::Cw, 1000), (Spindle::Cw, 2000)]);
    let b = session_full(
        &sends,
        &[],
        None,
        3000,
        ESTOP,
        None,
        Some((free.spindle[1].frame, AcEvent::Breakage)),
    );
    assert_eq!(
        calls(&b),
        [(Spindle::Cw, 1000), (Spindle::Off, 0)],
        "{:?}",
        b.spindle
    );
    let sends = [
        (1, "M3 S1000\n"),
        (2, "G91 G1 F30 X1\n"),
        (2500, "~"),
        (2600, "$X\n"),
    ];
    let b = broken_at_2000(&sends);
    assert_eq!(
        calls(&b),
        [(Spindle::Cw, 1000), (Spindle::Off, 0)],
        "{:?}",
        b.spindle
    );
    // Off within a loader turn or two of the request, with the feed held mid-block.
    assert!(b.spindle[1].frame >= 2000 && b.spindle[1].frame <= 2010);
    assert_eq!(b.status.spindle_rpm.get(), 1000);
    assert!(b.out.contains("ALARM:108\r\n"), "{}", b.out);
    assert!(b.out.contains("[MSG:Spindle stopped]"), "{}", b.out);
    assert!(
        b.out
            .contains("[MSG:AC hold: breakage hold: tool breakage at tooth period 1234"),
        "{}",
        b.out
    );
    assert!(
        b.out
            .contains("[MSG:Tool breakage: reset (Ctrl-X) first, then change the tool]")
            && b.out.ends_with("error:9\r\n"),
        "{}",
        b.out
    );
    assert!(!b.status.ac_resume.pending(), "~ and $X refused");
    // A reset, then `$X`: unlocked, the queue dropped, the spindle left off.
    let sends = [
        (1, "M3 S1000\n"),
        (2, "G91 G1 F30 X1\n"),
        (2500, "\u{18}"),
        (2700, "$X\n"),
    ];
    let b = broken_at_2000(&sends);
    assert_eq!(
        calls(&b),
        [(Spindle::Cw, 1000), (Spindle::Off, 0), (Spindle::Off, 0)],
        "{:?}",
        b.spindle
    );
    assert!(b.out.contains("[MSG:Caution: Unlocked]"), "{}", b.out);
    assert!(b.status.ac_resume.pending(), "the AC is asked to resume");
    assert!(b.status.encoder()[0] < 10_000, "the block was dropped");
    // Without a breakage the spindle just runs.
    let b = session_full(&sends[..2], &[], None, 3000, ESTOP, None, None);
    assert_eq!(b.spindle.len(), 1);
}

/// A chatter hold in serial mode with the default depth step: the loader re-plans the held line
/// (a message, no alarm), the AC resumes, the job runs to its end where the program ends, the
/// sender sees every `ok`, and the state is Idle. With `$276=0` the hold stays (`ALARM:107`).
#[test]
fn a_chatter_hold_is_replanned_and_the_job_completes() {
    // 0.1 in at F30 takes about 1000 frames; chatter at frame 400, in the first line.
    let sends = [(1, "G91 G1 F30 X0.1\n"), (2, "G1 Y0.01\n"), (11_000, "?")];
    let chatter = |step_mm| {
        Some((
            400,
            AcEvent::Chatter {
                step_mm,
                max_rpm: 0,
            },
        ))
    };
    let b = session_full(&sends, &[], None, 12_000, ESTOP, None, chatter(1.0));
    assert!(b.out.contains("[MSG:AC hold: chatter"), "{}", b.out);
    assert!(
        // 1 mm is 394 BLU of 0.0001 in.
        b.out
            .contains("[MSG:Chatter: depth reduced by 1.001 mm from X"),
        "{}",
        b.out
    );
    assert!(b.out.contains("(re-plan 1)]"), "{}", b.out);
    assert!(!b.out.contains("ALARM:"), "{}", b.out);
    assert_eq!(oks(&b.out), 2);
    assert!(b.out.contains("<Idle|"), "{}", b.out);
    // The machine ends where the program does: X 0.1 in, Y 0.01 in, Z back at 0.
    assert_eq!(b.status.position(), [1000, 100, 0]);
    // Without a step: the hold stays, the alarm is raised, the job does not end.
    let mut no_step = session_full(&sends, &[], None, 12_000, ESTOP, None, chatter(0.0));
    assert!(no_step.out.contains("ALARM:107"), "{}", no_step.out);
    assert!(!no_step.out.contains("Chatter: depth"), "{}", no_step.out);
    assert_ne!(no_step.status.position(), [1000, 100, 0]);
    no_step.out.clear();
}

/// `$277`: a chatter hold in serial mode changes the spindle speed to the nearest stable lobe
/// (1680 Hz with 4 flutes at 6000 rpm: m = 4, 6300 rpm), a message and no alarm, the spindle
/// output takes it, nothing is re-planned, the AC resumes and the job ends where the program
/// does.
#[test]
fn a_chatter_hold_changes_the_spindle_speed_first() {
    let sends = [
        (1, "S6000 M3\n"),
        (2, "G91 G1 F30 X0.1\n"),
        (3, "G1 Y0.01\n"),
        (11_000, "?"),
    ];
    let ev = Some((
        400,
        AcEvent::Chatter {
            step_mm: 1.0,
            max_rpm: 10_000,
        },
    ));
    let b = session_full(&sends, &[], None, 12_000, ESTOP, None, ev);
    assert!(
        b.out.contains(
            "[MSG:Chatter: spindle speed S6000 to S6300 (chatter 1680 Hz, 4 tooth periods"
        ),
        "{}",
        b.out
    );
    assert!(b.out.contains("(change 1)]"), "{}", b.out);
    assert!(
        !b.out.contains("ALARM:") && !b.out.contains("depth reduced"),
        "{}",
        b.out
    );
    let calls: Vec<(Spindle, u32)> = b.spindle.iter().map(|c| (c.state, c.rpm)).collect();
    assert_eq!(calls, [(Spindle::Cw, 6000), (Spindle::Cw, 6300)]);
    // The change is made where the hold stopped the machine, inside the first line.
    assert!(b.spindle[1].position[0] > 0 && b.spindle[1].position[0] < 1000);
    assert_eq!(b.status.spindle_rpm.get(), 6300);
    assert_eq!(oks(&b.out), 3);
    assert_eq!(b.status.position(), [1000, 100, 0]);
}

/// `$G` after M2 through the real loader: the units the program ran in (G21 or G20) stay, motion,
/// distance and spindle are back at G1 G90 M5 (grbl 1.1). Before, M2 returned every mode to
/// power-up and `$G` said G20 after a program in mm; CNCjs then showed inches.
#[test]
fn dollar_g_after_program_end_keeps_the_units() {
    for (units, feed) in [("G21", "F300"), ("G20", "F12")] {
        let program = std::format!("{units} G91 G1 {feed} X0.02\nM3 S400\nM2\n$G\n");
        let b = session(&[(1, program.as_str())], &[], None, 6000);
        let gc = b
            .out
            .lines()
            .find(|l| l.starts_with("[GC:"))
            .unwrap_or_else(|| panic!("no $G report: {}", b.out));
        assert!(gc.contains(&std::format!(" {units} ")), "{gc}");
        assert!(
            gc.starts_with("[GC:G1 G54 G17 ") && gc.contains(" G90 "),
            "{gc}"
        );
        assert!(gc.contains(" M5 ") && gc.contains(" S400"), "{gc}");
    }
}

/// A board whose interrupts overrun the frame period (the pulse end waits behind the next frame):
/// the frame that finds the last pulse still high holds its pulses back a period instead of
/// raising the line again (which loses the edge: the encoder then counts fewer pulses than the
/// position), and the loader holds the machine with `ALARM:111`. No pulse is lost: the encoder
/// equals the position, and after `$X` and `~` the rapid ends exactly where it was sent.
#[test]
fn a_frame_overrun_holds_and_loses_no_pulse() {
    let b = session_full(
        &[(1, "G91 G0 X1\n"), (20_000, "$X\n"), (21_000, "~")],
        &[],
        None,
        60_000,
        ESTOP,
        None,
        Some((3000, AcEvent::LatePulseEnd(300))),
    );
    assert!(b.out.contains("ALARM:111"), "{}", b.out);
    assert!(b.out.contains("Frame overran its period"), "{}", b.out);
    assert!(b.status.frame_overruns.get() > 0);
    assert_eq!(b.status.encoder(), [10_000, 0, 0], "{}", b.out);
    assert_eq!(b.status.position(), [10_000, 0, 0]);
}

/// A status report asked for between a line's `ok` and the loader's next turn, while the
/// look-ahead still holds the line's block (queued once no next line has come): the machine has
/// a move to make, so the state is `Run`, not `Idle`. Before, it said `Idle` at the old
/// position, and a sender that polls `?` after its last `ok` took the job for done (seen in
/// `serve` once its port answered within the loader's turn).
#[test]
fn a_report_right_after_an_ok_is_not_idle_while_the_look_ahead_holds_a_block() {
    let b = session(&[(5, "G20 G91 G1 X0.01 F30\n"), (6, "?")], &[], None, 400);
    let first = b
        .out
        .lines()
        .find(|l| l.starts_with('<'))
        .expect("a report");
    assert!(b.oks_at.first() == Some(&6), "{:?}: {}", b.oks_at, b.out);
    assert!(first.starts_with("<Run|"), "{first}\n{}", b.out);
    assert_eq!(b.status.encoder(), [100, 0, 0]);
}

/// The status report's `AC:` field is there only when the adaptive control is enabled (the
/// loader's feed ceiling given, as the boards give it with `$250=1` and the host's flag): a
/// measure-only AC (`--no-ac`) runs its periods but caps nothing, and the field's feed share and
/// `hold:N` would say it does. Before, the field came whenever an AC period had run.
#[test]
fn the_ac_field_is_reported_only_when_the_ac_is_enabled() {
    for enabled in [false, true] {
        let ceiling = enabled.then(|| crate::ac::AcSettings::default().ceiling);
        AC_TASK.with(|c| c.set(Some(ceiling)));
        let b = session(&[(5, "?")], &[], None, 40);
        AC_TASK.with(|c| c.set(None));
        let report = b
            .out
            .lines()
            .find(|l| l.starts_with('<'))
            .expect("a report");
        assert_eq!(
            report.contains("|AC:"),
            enabled,
            "enabled {enabled}: {report}"
        );
    }
}

/// A measure-only AC (`$250=0`, `--no-ac`) holds nothing: a verdict it would have held for is told
/// in a message, never as an alarm, and the sender's lines after it run. Before, the loader raised
/// `ALARM:108` for it while the machine went on, and the next line got `error:9`.
#[test]
fn a_measure_only_ac_tells_its_verdicts_without_an_alarm() {
    AC_TASK.with(|c| c.set(Some(None)));
    let sends = [(1, "G91 G1 F30 X0.01\n"), (300, "G1 Y0.01\n"), (900, "?")];
    let b = session_full(
        &sends,
        &[],
        None,
        1000,
        ESTOP,
        None,
        Some((50, AcEvent::MeasuredBreakage)),
    );
    AC_TASK.with(|c| c.set(None));
    assert!(!b.out.contains("ALARM:"), "{}", b.out);
    assert!(!b.out.contains("error:"), "{}", b.out);
    assert!(
        b.out
            .contains("[MSG:AC (measure only) would hold: breakage hold: tool breakage"),
        "{}",
        b.out
    );
    assert_eq!(oks(&b.out), 2, "{}", b.out);
    assert!(b.out.contains("<Idle|"), "{}", b.out);
    assert_eq!(b.status.encoder(), [100, 100, 0]);
    // The AC, held by its verdict, is asked to resume, so its next verdict is told too.
    assert!(b.status.ac_resume.pending(), "the AC stays deaf");
}

/// A probing move's `ok` comes once the machine stands, as grbl's (its G38 returns after the
/// motion has stopped): a `$#` sent while the probe moves, answered after that `ok`, lists the
/// parameters, not `error:8` (not idle). Before, the `ok` came at the contact, a few frames
/// before the stop, and a sender's `$#` right after it (bCNC's tool change under `serve`) was
/// refused.
#[test]
fn a_probes_ok_comes_once_the_machine_stands() {
    on_plate(-1_000);
    // From well before the contact (at about 3 830) to just after it.
    for t in (3_000..3_900).step_by(50) {
        let b = session(
            &[(1, "G21 G91 G38.2 Z-10 F200\n"), (t, "$#\n")],
            &[],
            None,
            8_000,
        );
        assert!(
            b.out.contains("[PRB:0.000,0.000,-2.540:1]\r\nok\r\n[G54:"),
            "$# at {t}: {}",
            b.out
        );
        assert!(!b.out.contains("error:"), "$# at {t}: {}", b.out);
    }
    MACHINE.with(|m| m.set(None));
}
