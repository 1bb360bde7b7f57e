//! millac firmware for the lm3s6965evb (QEMU): the RTIC 2 app, binding the runtime written once in
//! `millac::rt` to this board's interrupts. `init` loads the settings record (`crate::storage`)
//! and starts the board; the frame ISR (TIMER_0A) and the pulse-end ISR (TIMER_1A, both priority
//! 4) run `millac::rt::isr`'s bodies; UART0 (3) moves the serial line's bytes; when the host serves
//! the simulated ADC (`crate::simadc`, `crate::adaptive`) the sampler (TIMER_2A, 3), the AC period
//! (2) and the chatter monitor (1) run `millac::rt::actask`'s; the idle loop is the loader
//! (`crate::loader`: program mode on `program.nc`, else serial mode). No monotonic/SysTick: any
//! that is added must have a priority below the frame's. The data paths and priorities:
//! docs/dev/architecture.md; the log, the result file and the panic: `crate::voice`.
#![no_std]
#![no_main]

// The defmt global logger: frames to semihosting stdout (linked for it, nothing is called).
use defmt_semihosting as _;
mod adaptive;
mod board;
mod facts;
mod files;
mod loader;
mod program;
mod results;
mod semihost;
mod session;
mod shared;
mod simadc;
mod storage;
mod uart;
mod voice;

// RTIC gives the dispatchers to the software tasks' priorities from the lowest up: I2C0 the
// chatter monitor (1), SSI0 the AC period (2; the host's instruction counts name SSI0).
#[rtic::app(device = lm3s6965, peripherals = false, dispatchers = [I2C0, SSI0])]
mod app {
    use crate::adaptive;
    use crate::loader::Ends;
    use crate::results;
    use crate::semihost::LogFile;
    use crate::shared::{QUEUE, RECORD};
    use crate::simadc::SimAdc;
    use crate::storage::FileStorage;
    use crate::uart::TX_QUEUE;
    use crate::voice::fail;
    use heapless::spsc::{Consumer, Queue};
    use millac::ac::Alarm;
    use millac::monitor::chatter::Spectrum;
    use millac::nc::Sealed;
    use millac::ports::Codes;
    use millac::protocol::rx::{RxIsr, RxShared};
    use millac::protocol::Protocol;
    use millac::rt::actask::{
        AcTask, MonitorTask, Sampler, Sound, ALARM_QUEUE, SAMPLE_QUEUE, SOUND_QUEUE, VERDICT_QUEUE,
    };
    use millac::rt::replan::Replan;
    use millac::rt::status::{PulseWriter, Static};
    use millac::rt::{self, FrameTask};

    /// The board this binary drives (a unit struct: its ports are `&mut B`).
    use crate::board::Lm3s6965 as B;

    /// Nothing shared through RTIC: the contexts share the status words (`millac::rt::status`),
    /// each writing through its own handle.
    #[shared]
    struct Shared {}

    #[local]
    struct Local {
        /// The frame ISR's state and its block queue's end.
        frame: FrameTask<Static>,
        consumer: Consumer<'static, Sealed, QUEUE>,
        pulse_status: PulseWriter<Static>,
        sampler: Option<Sampler<SimAdc>>,
        ac: Option<AcTask<LogFile>>,
        /// The chatter monitor (`$278`, on by default, and the simulated ADC served).
        monitor: Option<MonitorTask>,
        /// UART0 task's ends: received bytes into the protocol's ring (realtime bytes taken out
        /// there), bytes to send out.
        uart_rx: RxIsr<'static>,
        uart_tx: Consumer<'static, u8, TX_QUEUE>,
        loader: Ends,
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
        let (blocks, consumer) = cx.local.queue.split();
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
        let loader = Ends {
            blocks,
            table,
            refused,
            ceiling,
            proto,
            tx,
            ac_alarms,
            status: status.loader,
        };
        let pulse_status = status.pulse;
        (
            Shared {},
            Local {
                frame,
                consumer,
                pulse_status,
                sampler,
                ac,
                monitor,
                uart_rx,
                uart_tx,
                loader,
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
        let Some(due) = adaptive::sample(cx.local.sampler) else {
            return;
        };
        if ac_period::spawn(due).is_err() {
            adaptive::missed_period(cx.local.sampler);
        }
        // Still busy with a record's FFT: it drains the queue when it is done (the queue holds
        // 63 ms of sound).
        let _ = monitor::spawn();
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
        if let Some(task) = cx.local.ac.as_mut() {
            adaptive::period_done(task.run(due));
        }
    }

    /// The loader (busy loop: QEMU 7.2 with icount loses timer interrupts on WFI).
    #[idle(local = [loader, replan: Option<Replan<RECORD>> = None])]
    fn idle(cx: idle::Context) -> ! {
        crate::loader::run(cx.local.loader, cx.local.replan)
    }
}
