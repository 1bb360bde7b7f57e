//! millac firmware for the lm3s6965evb (QEMU): the RTIC 2 app. `init` loads the settings record
//! (`settings.bin`, see "Settings" below), validates the settings and starts the board; the frame
//! ISR (TIMER_0A) and the pulse-end ISR (TIMER_1A) drive the pins; the idle loop is the loader: it
//! reads `program.nc` through semihosting, parses it and queues the blocks, then reports the final
//! position and exits QEMU (without `program.nc`: the serial loader, `millac::rt::loader`).
//!
//! # Adaptive control (only when the host serves the simulated ADC, see `crate::simadc`)
//!
//! Priorities: frame and pulse-end 4; the sampler (TIMER_2A, `sample_hz`) and UART0 3; the AC
//! period (software task, dispatcher SSI0, spawned by the sampler every `period_ms`) 2; the
//! chatter monitor (software task, dispatcher I2C0, spawned with every AC period; it returns at
//! once unless `$266` turned it on: a record's FFT is most of a 10 ms period in soft-float, so it runs below the AC period,
//! which preempts it) 1; the idle loader 0. The pulse-end ISR counts the pulses on the pins into the encoder counts (`STATUS.encoder`,
//! a `millac::rt::Status`); the sampler exchanges them for ADC codes with the host in lockstep and
//! queues them; the AC task runs the `AcController` on them, writes the feed cap
//! (`STATUS.feed_cap`, when enabled) and `ac.log`, reports `alarm: ..` on a hold and stops the run
//! after a long hold with nothing moving (see `millac::rt::actask`). Without `adc.req` in the
//! working directory none of this starts: no sample timer, no AC task, the feed cap stays
//! `u32::MAX` and the firmware behaves as before.
//!
//! The frame and pulse-end bodies, and the timing rule that makes pulses and signs correct by
//! construction, are in `millac::rt::isr`; this app binds them to TIMER_0A and TIMER_1A.
//!
//! The frame timer runs at W0 (`frame_hz`) while contouring, dwelling or idle, and is retimed to
//! `rapid_hz` while the frame asks for `Rate::Rapid` (PTP), so the 5 kHz contouring frame and the
//! 26.3 kHz rapid pulse rate come from one timer.
//!
//! No monotonic/SysTick: any that is added must have a priority below the frame's.
//!
//! The board's log and result file: `crate::voice`; its settings record and what a refused one
//! does: `crate::storage`.
#![no_std]
#![no_main]

use core::panic::PanicInfo;
use core::sync::atomic::{AtomicBool, Ordering};

// The defmt global logger: frames to semihosting stdout (linked for it, nothing is called).
use defmt_semihosting as _;
mod adaptive;
mod board;
mod facts;
mod files;
mod program;
mod results;
mod semihost;
mod session;
mod shared;
mod simadc;
mod storage;
mod uart;
mod voice;

use voice::{exit, text};

/// Set by the first panic: a panic inside the panic handler (the logger taken where the first
/// panic struck) only exits.
static PANICKED: AtomicBool = AtomicBool::new(false);

/// Any context: `panic: <message>` in the result file and in the log, exit with failure.
#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    if !PANICKED.swap(true, Ordering::Relaxed) {
        let t = text(format_args!("{}", info));
        results::line(format_args!("panic: {}", t));
        defmt::error!("panic: {=str}", t.as_str());
    }
    exit(false)
}

// RTIC gives the dispatchers to the software tasks' priorities from the lowest up: I2C0 the
// chatter monitor (1), SSI0 the AC period (2; the host's instruction counts name SSI0).
#[rtic::app(device = lm3s6965, peripherals = false, dispatchers = [I2C0, SSI0])]
mod app {
    use core::sync::atomic::Ordering::Relaxed;

    use crate::adaptive;
    use crate::semihost::LogFile;
    use crate::simadc::SimAdc;
    use crate::storage::FileStorage;
    use crate::uart::TX_QUEUE;
    use heapless::spsc::{Consumer, Producer, Queue};
    use millac::ac::Alarm;
    use millac::ac::FeedCeiling;
    use millac::monitor::chatter::Spectrum;
    use millac::nc::Sealed;
    use millac::ports::{Board, Codes, SampleClock};
    use millac::protocol::rx::{RxIsr, RxShared};
    use millac::protocol::settings::record::RecordError;
    use millac::protocol::settings::Persistent;
    use millac::protocol::Protocol;
    use millac::rt::actask::{
        AcTask, MonitorTask, Sampler, Sound, ALARM_QUEUE, SAMPLE_QUEUE, SOUND_QUEUE, VERDICT_QUEUE,
    };
    use millac::rt::replan::Replan;
    use millac::rt::{self, FrameTask};
    use millac::Settings;

    use crate::program::held_exit;
    use crate::results;
    use crate::shared::{QUEUE, RECORD, SERIAL};
    use crate::voice::{error, fail, text};
    use millac::rt::console::{Console, Serial};
    use millac::rt::loader;
    use millac::rt::status::{LoaderWriter, PulseWriter, Static};

    /// The board this binary drives (a unit struct: its ports are `&mut B`).
    use crate::board::Lm3s6965 as B;

    /// Nothing shared through RTIC: the frame and pulse-end ISRs share the next signs through
    /// the atomic `NEXT_SIGNS` (same priority, so no lock and no resource proxy is needed).
    #[shared]
    struct Shared {}

    #[local]
    struct Local {
        frame: FrameTask<Static>,
        /// Each context's handle on the status words (`millac::rt::status`): the pulse end's, the
        /// loader's (the frame task, the sampler and the AC task hold theirs).
        pulse_status: PulseWriter<Static>,
        loader_status: LoaderWriter<'static>,
        consumer: Consumer<'static, Sealed, QUEUE>,
        producer: Producer<'static, Sealed, QUEUE>,
        settings: Settings,
        /// The settings table of serial mode (the loaded record) and its storage.
        table: Persistent<FileStorage>,
        /// Why the stored record was refused (program mode refuses to run).
        refused: Option<RecordError>,
        /// The feed ceiling of an enabled AC, applied by the loader (None: programmed feeds).
        ceiling: Option<FeedCeiling>,
        sampler: Option<Sampler<SimAdc>>,
        ac: Option<AcTask<LogFile>>,
        /// The chatter monitor (`$266` above 0 and the simulated ADC served).
        monitor: Option<MonitorTask>,
        /// UART0 task's ends: received bytes into the protocol's ring (realtime bytes taken out
        /// there), bytes to send out.
        uart_rx: RxIsr<'static>,
        uart_tx: Consumer<'static, u8, TX_QUEUE>,
        /// The loader's ends (serial mode): the protocol, the transmit queue.
        proto: Protocol<'static>,
        tx: Producer<'static, u8, TX_QUEUE>,
        /// AC holds for the serial loader's messages.
        ac_alarms: Consumer<'static, Alarm, ALARM_QUEUE>,
    }

    #[init(local = [
        queue: Queue<Sealed, QUEUE> = Queue::new(),
        samples: Queue<Codes, SAMPLE_QUEUE> = Queue::new(),
        sound: Queue<Sound, SOUND_QUEUE> = Queue::new(),
        verdicts: Queue<Spectrum, VERDICT_QUEUE> = Queue::new(),
        serial_rx: RxShared = RxShared::new(),
        serial_tx: Queue<u8, TX_QUEUE> = Queue::new(),
        alarms: Queue<Alarm, ALARM_QUEUE> = Queue::new(),
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        // The result file first: everything after may report into it.
        results::create();
        // The stored record (validated as a whole), or the defaults; the reloads they give.
        let start = match rt::start::start::<B, _>(FileStorage) {
            Ok(s) => s,
            Err(e) => fail(format_args!("settings: {}", e.message())),
        };
        // No cap unless the AC says otherwise, 100 % feed (before any interrupt is enabled); each
        // context's handle.
        let status = rt::status::split_static();
        let frame = start.frame(status.frame);
        let (table, refused) = (start.table, start.refused);
        let settings = table.settings.nc;
        let (producer, consumer) = cx.local.queue.split();
        B::init(start.reloads.feed, start.pulse);

        // The simulated ADC and the AC, if the host serves them (blocks until it is ready).
        let (alarm_tx, ac_alarms) = cx.local.alarms.split();
        let queues = adaptive::Queues {
            samples: cx.local.samples,
            sound: cx.local.sound,
            verdicts: cx.local.verdicts,
        };
        let (sampler, ac, monitor, ceiling) =
            match adaptive::start(&table.settings, queues, alarm_tx, status.ac, status.sampler) {
                Some(a) => (Some(a.sampler), Some(a.ac), a.monitor, a.ceiling),
                None => (None, None, None, None),
            };

        let (uart_rx, rx) = cx.local.serial_rx.split();
        let mut proto = Protocol::new(rx, (QUEUE - 1) as u16);
        if let Some(e) = refused {
            proto.settings_refused(e);
        }
        let (tx, uart_tx) = cx.local.serial_tx.split();

        (
            Shared {},
            Local {
                uart_rx,
                uart_tx,
                proto,
                tx,
                ac_alarms,
                frame,
                pulse_status: status.pulse,
                loader_status: status.loader,
                consumer,
                producer,
                settings,
                table,
                refused,
                ceiling,
                sampler,
                ac,
                monitor,
            },
        )
    }

    /// The frame ISR: highest priority (4). No locks, logging, allocation or panics.
    #[task(binds = TIMER_0A, priority = 4, local = [frame, consumer])]
    fn frame(cx: frame::Context) {
        let local = cx.local;
        local.frame.run(&mut B, &mut B, &mut B, local.consumer);
    }

    /// UART0 (serial mode only: its interrupts are enabled by the loader): received bytes to the
    /// loader, queued bytes out. Priority 3, below the frame.
    #[task(binds = UART0, priority = 3, local = [uart_rx, uart_tx])]
    fn uart0(cx: uart0::Context) {
        let rx = cx.local.uart_rx;
        // A byte the ring cannot take is counted there; the loader raises the overflow alarm.
        crate::uart::on_interrupt(cx.local.uart_tx, |b| {
            let _ = rx.push_byte(b);
        });
    }

    /// The pulse-end ISR: same priority as the frame, so it runs after the frame has finished.
    #[task(binds = TIMER_1A, priority = 4, local = [pulse_status])]
    fn pulse_end(cx: pulse_end::Context) {
        rt::pulse_end(&mut B, &mut B, *cx.local.pulse_status);
    }

    /// The sampler: one lockstep exchange with the host's simulated ADC per Timer 2 period,
    /// priority 3 (below the frame). Spawns the AC period (and the chatter monitor) every N
    /// samples.
    #[task(binds = TIMER_2A, priority = 3, local = [sampler])]
    fn sample(cx: sample::Context) {
        SampleClock::ack(&mut B);
        let Some(s) = cx.local.sampler.as_mut() else {
            SampleClock::stop(&mut B);
            return;
        };
        let tick = s.sample();
        // The host has gone: without samples the AC cannot guard the cut. Said once; the
        // periods go on, see no samples and hold, and the run ends as after any hold.
        if tick.lost {
            error(format_args!("simulated ADC lost"));
        }
        let due = tick.due;
        if let Some(due) = due {
            if ac_period::spawn(due).is_err() {
                s.missed_period();
            }
            // Still busy with a record's FFT: it drains the queue when it is done (the queue
            // holds 63 ms of sound).
            let _ = monitor::spawn();
        }
    }

    /// The chatter monitor: priority 1 (above the idle loader, below the AC period). Without
    /// a chatter monitor it returns at once.
    #[task(priority = 1, local = [monitor])]
    async fn monitor(cx: monitor::Context) {
        if let Some(m) = cx.local.monitor.as_mut() {
            m.run();
        }
    }

    /// The AC period: priority 2 (above the chatter monitor, below the sampler).
    #[task(priority = 2, local = [ac])]
    async fn ac_period(cx: ac_period::Context, due: u32) {
        let Some(task) = cx.local.ac.as_mut() else {
            return;
        };
        let p = task.run(due);
        if let Some(a) = p.alarm {
            let t = text(format_args!("{}", a));
            results::line(format_args!("alarm: {}", t));
            defmt::warn!("alarm: {=str}", t.as_str());
        }
        if p.halt && !SERIAL.load(Relaxed) {
            held_exit();
        }
    }

    /// The loader (busy loop: QEMU 7.2 with icount loses timer interrupts on WFI): program
    /// mode when QEMU's working directory holds `program.nc` (it runs the file and exits), else
    /// serial mode (the operator streams G-code over UART0).
    #[idle(local = [
        producer, settings, table, refused, ceiling, proto, tx, ac_alarms, loader_status,
        replan: Option<Replan<RECORD>> = None
    ])]
    fn idle(cx: idle::Context) -> ! {
        let local = cx.local;
        // The loader's record of the queued blocks: chatter suppression (`$276`) re-plans from
        // it, in both modes (and changes the spindle speed first where `$277` allows).
        let replan = local.replan.insert(Replan::new(
            *local.settings,
            &local.table.settings.ac,
            [0; 3],
        ));
        let mut program =
            crate::program::open().map(|p| crate::program::console(p, *local.refused));
        let serial = program.is_none();
        SERIAL.store(serial, Relaxed);
        let mut line = Serial::new(local.proto, local.tx, crate::uart::kick, local.settings);
        let console: &mut dyn Console = match program.as_mut() {
            Some(p) => p,
            None => &mut line,
        };
        let finished = loader::run(
            loader::Parts {
                blocks: local.producer,
                replan,
                table: local.table,
                ceiling: *local.ceiling,
                console,
                ac_alarms: local.ac_alarms,
                status: local.loader_status,
            },
            &mut crate::uart::QemuLoader {
                clock_hz: B::TIMER_HZ,
                serial,
                log: match serial {
                    true => crate::session::SessionLog::create(),
                    false => crate::session::SessionLog::none(),
                },
            },
        );
        if let Some(p) = program {
            crate::program::finish(p, finished);
        }
        // The board's loader never ends (it runs while the board says so: always).
        crate::voice::exit(true)
    }
}
