//! millac firmware for the lm3s6965evb (QEMU): the RTIC 2 app. `init` validates the settings and
//! starts the board; the frame ISR (TIMER_0A) and the pulse-end ISR (TIMER_1A) drive the pins; the
//! idle loop is the loader: it reads `program.nc` through semihosting, parses it and queues the
//! blocks, then reports the final position and exits QEMU.
//!
//! # Adaptive control (only when the host serves the simulated ADC, see `millac_hal::simadc`)
//!
//! Priorities: frame and pulse-end 3; the sampler (TIMER_2A, `sample_hz`) 2; the AC period
//! (software task, dispatcher SSI0, spawned by the sampler every `period_ms`) 1; the idle loader
//! 0. The pulse-end ISR counts the pulses on the pins into `ENCODER`; the sampler exchanges the
//! encoder counts for ADC codes with the host in lockstep and queues them; the AC task runs the
//! `AcController` on them, writes `FEED_CAP` (when enabled) and `ac.log`, prints `alarm: ..` on a
//! hold and stops the run after a long hold with nothing moving (see `millac_hal::actask`).
//! Without `adc.req` in the working directory none of this starts: no sample timer, no AC task,
//! `FEED_CAP` stays `u32::MAX` and the firmware behaves as before.
//!
//! # Timing rule (why pulses and signs are correct by construction)
//!
//! Frame ISR and pulse-end ISR run at the same, highest priority, so neither preempts the other:
//! the pulse end waits (tail-chains) until the frame is done. Each frame first outputs the pulses
//! computed in the PREVIOUS frame (`pending`): one store sets the PULSE lines high, then the
//! one-shot pulse timer starts for `pulse_width_ns`. Only then does the frame compute the next
//! pulses `p` (whose time varies with the block); their SIGN lines are written
//! - at once, if this frame emitted no pulse (the PULSE lines are low), or
//! - by the pulse-end ISR, right after it sets the PULSE lines low again.
//!
//! So a PULSE line is high for at least `pulse_width_ns` (the timer runs that long, and the falling
//! edge waits for the frame's work if that is longer), a SIGN line changes only while every PULSE
//! line is low, and the next rising edge comes one frame period after this frame's rising edge.
//! The SIGN-to-rising-edge gap is therefore at least the period minus max(pulse width, frame work);
//! `Settings::validate` guarantees pulse width + sign setup <= 75 % of the shortest (rapid) period,
//! which leaves the sign setup time as long as the frame's work stays within the remaining 25 %.
//! Rising edges keep the timer's period exactly: the pulse store is the frame's first work after
//! the acknowledge, at a fixed number of instructions from the interrupt.
//!
//! The frame timer runs at W0 (`frame_hz`) while contouring, dwelling or idle, and is retimed to
//! `rapid_hz` while the frame asks for `Rate::Rapid` (PTP), so the 5 kHz contouring frame and the
//! 26.3 kHz rapid pulse rate come from one timer.
//!
//! No monotonic/SysTick: any that is added must have a priority below the frame's.
#![no_std]
#![no_main]

use core::fmt::{self, Write as _};
use core::panic::PanicInfo;

use cortex_m_semihosting::{debug, hio};

/// Semihosting stdout without the critical section `hprintln!` takes (it would delay the frame ISR
/// while the loader prints an error); output errors are ignored, nothing here panics.
struct Out(Option<hio::HostStream>);

impl Out {
    fn open() -> Self {
        Out(hio::hstdout().ok())
    }
    fn line(&mut self, args: fmt::Arguments) {
        if let Some(s) = self.0.as_mut() {
            let _ = s.write_fmt(args);
            let _ = s.write_str("\n");
        }
    }
}

/// Prints `error: <what>` and leaves QEMU with a failure status. Init and idle.
fn fail(what: fmt::Arguments) -> ! {
    Out::open().line(format_args!("error: {}", what));
    exit(false)
}

/// Leaves QEMU through semihosting (success or failure status). Never returns on QEMU; on a
/// debugger that continues, parks the core.
fn exit(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::nop();
    }
}

/// Any context: prints the panic through semihosting and exits with failure.
#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    Out::open().line(format_args!("panic: {}", info));
    exit(false)
}

#[rtic::app(device = lm3s6965, peripherals = false, dispatchers = [SSI0])]
mod app {
    use core::sync::atomic::Ordering::Relaxed;

    use cortex_m_semihosting::{nr, syscall};
    use heapless::spsc::{Consumer, Producer, Queue};
    use millac::ac::{AcController, AcSettings, FeedCeiling};
    use millac::gcode::tape::Tape;
    use millac::nc::{Block, BlockSource, FeedCap, Frame, FrameConfig, Pulses, Rate};
    use millac::Settings;
    use millac_hal::actask::{AcTask, Codes, Sampled, Sampler, SAMPLE_QUEUE};
    use millac_hal::lm3s6965::{self as board, Lm3s6965};
    use millac_hal::simadc::{LogFile, SimAdc, FLAG_AC_ENABLED};
    use millac_hal::status::{BLOCKS_DONE, ENCODER, FEED_CAP, IDLE, NEXT_SIGNS, POSITION};
    use millac_hal::{clocks_for_hz, clocks_for_ns, Board};

    use super::{exit, fail, Out};

    /// The board this binary drives.
    type B = Lm3s6965;

    /// Queue slots (a heapless spsc queue holds one less: 15 blocks).
    const QUEUE: usize = 16;
    /// Semihosting read size.
    const CHUNK: usize = 256;

    /// Nothing shared through RTIC: the frame and pulse-end ISRs share the next signs through
    /// the atomic `NEXT_SIGNS` (same priority, so no lock and no resource proxy is needed).
    #[shared]
    struct Shared {}

    /// Frame timer reload values for the two rates.
    pub struct Reloads {
        feed: u32,
        rapid: u32,
    }

    #[local]
    struct Local {
        frame: Frame,
        consumer: Consumer<'static, Block, QUEUE>,
        pending: Pulses,
        rate: Rate,
        reloads: Reloads,
        producer: Producer<'static, Block, QUEUE>,
        settings: Settings,
        /// The feed ceiling of an enabled AC, applied by the loader (None: programmed feeds).
        ceiling: Option<FeedCeiling>,
        sampler: Option<Sampler>,
        ac: Option<AcTask>,
    }

    #[init(local = [
        queue: Queue<Block, QUEUE> = Queue::new(),
        samples: Queue<Codes, SAMPLE_QUEUE> = Queue::new(),
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        let settings = Settings::default();
        if let Err(e) = settings.validate() {
            fail(format_args!("settings: {}", e.message()));
        }
        let (producer, consumer) = cx.local.queue.split();

        let reloads = Reloads {
            feed: B::reload(clocks_for_hz(B::TIMER_HZ, settings.frame_hz)),
            rapid: B::reload(clocks_for_hz(B::TIMER_HZ, settings.rapid_hz)),
        };
        let pulse = B::reload(clocks_for_ns(B::TIMER_HZ, settings.pulse_width_ns));
        // No cap unless the AC says otherwise (before any interrupt is enabled).
        FEED_CAP.store(u32::MAX, Relaxed);
        B::init(reloads.feed, pulse);

        // The simulated ADC and the AC, if the host serves them (blocks until it is ready).
        let (mut sampler, mut ac, mut ceiling) = (None, None, None);
        if let Some((adc, flags)) = SimAdc::open() {
            let ac_settings = AcSettings::default();
            let ctl = match AcController::new(ac_settings) {
                Ok(c) => c,
                Err(e) => fail(format_args!("AC settings: {}", e.message())),
            };
            let Some(log) = LogFile::create(b"ac.log\0") else {
                fail(format_args!("cannot create ac.log"));
            };
            let (tx, rx) = cx.local.samples.split();
            let enabled = flags & FLAG_AC_ENABLED != 0;
            if enabled {
                ceiling = Some(ac_settings.ceiling);
            }
            let task = AcTask::new(ctl, rx, log, enabled, settings);
            sampler = Some(Sampler::new(adc, tx, task.per_period()));
            ac = Some(task);
            board::sample_timer_start(B::reload(clocks_for_hz(B::TIMER_HZ, ac_settings.sample_hz)));
        }

        (
            Shared {},
            Local {
                frame: Frame::new(FrameConfig::from_settings(&settings)),
                consumer,
                pending: Pulses::default(),
                rate: Rate::Feed,
                reloads,
                producer,
                settings,
                ceiling,
                sampler,
                ac,
            },
        )
    }

    /// The frame ISR: highest priority (3). No locks, logging, allocation or panics.
    #[task(binds = TIMER_0A, priority = 3,
           local = [frame, consumer, pending, rate, reloads])]
    fn frame(cx: frame::Context) {
        B::frame_ack();
        let pending = *cx.local.pending;
        if pending.steps != 0 {
            B::write_steps(pending.steps);
            B::pulse_start();
        }

        let frame = cx.local.frame;
        let was_idle = frame.idle();
        let p = frame.tick(&mut Source(cx.local.consumer), AcCap);

        if pending.steps == 0 {
            B::write_signs(p.signs);
        } else {
            NEXT_SIGNS.store(p.signs, Relaxed);
        }
        *cx.local.pending = p;

        // Published by the frames without pulses (idle, dwell, hold, between feed commands), so
        // the frames with pulses (the frame's worst case) do not pay for it. Read at the end of the
        // program and on a hold, when no pulse is computed; the live position is `ENCODER`.
        if p.steps == 0 {
            let [x, y, z] = frame.position();
            POSITION[0].store(x, Relaxed);
            POSITION[1].store(y, Relaxed);
            POSITION[2].store(z, Relaxed);
        }

        // The rate, the blocks done and the idle flag change only when a block is loaded or done.
        // They are published by the frames that start idle (the frame after a block's end runs
        // idle and loads the next block): one frame late after a block's end, never in a frame
        // that works on a block. IDLE is stored false by the frame that loads a block.
        if was_idle {
            let idle = frame.idle();
            let rate = frame.rate();
            if rate != *cx.local.rate {
                *cx.local.rate = rate;
                B::frame_set_reload(match rate {
                    Rate::Feed => cx.local.reloads.feed,
                    Rate::Rapid => cx.local.reloads.rapid,
                });
            }
            BLOCKS_DONE.store(frame.blocks_done(), Relaxed);
            IDLE.store(idle && p.steps == 0 && pending.steps == 0, Relaxed);
        }
    }

    /// The block queue as the frame's Initiator sees it: the running block stays at the front
    /// (read in place, never copied) and is dequeued when it is done.
    struct Source<'a>(&'a mut Consumer<'static, Block, QUEUE>);

    impl BlockSource for Source<'_> {
        #[inline(always)]
        fn front(&mut self) -> Option<&Block> {
            self.0.peek()
        }
        #[inline(always)]
        fn pop(&mut self) {
            // The value is dropped unread: only the head index moves.
            let _ = self.0.dequeue();
        }
    }

    /// The AC's feed cap as the frame reads it: loaded only by the frames that feed.
    struct AcCap;

    impl FeedCap for AcCap {
        #[inline(always)]
        fn feed_cap(&self) -> u32 {
            FEED_CAP.load(Relaxed)
        }
    }

    /// The pulse-end ISR: same priority as the frame, so it runs after the frame has finished.
    /// Before lowering the PULSE lines it counts them, by their SIGN lines, into the encoder
    /// (the only writer of `ENCODER`: plain load and store).
    #[task(binds = TIMER_1A, priority = 3)]
    fn pulse_end(_: pulse_end::Context) {
        B::pulse_ack();
        let pins = B::read_pins();
        for (k, e) in ENCODER.iter().enumerate() {
            if pins & (1 << k) != 0 {
                let d = if pins & (8 << k) != 0 { 1 } else { -1 };
                e.store(e.load(Relaxed).wrapping_add(d), Relaxed);
            }
        }
        B::write_steps(0);
        B::write_signs(NEXT_SIGNS.load(Relaxed));
    }

    /// The sampler: one lockstep exchange with the host's simulated ADC per Timer 2 period,
    /// priority 2 (below the frame). Spawns the AC period every N samples.
    #[task(binds = TIMER_2A, priority = 2, local = [sampler])]
    fn sample(cx: sample::Context) {
        board::sample_timer_ack();
        let Some(s) = cx.local.sampler.as_mut() else {
            board::sample_timer_stop();
            return;
        };
        match s.sample() {
            // The host has gone: without samples the AC cannot guard the cut.
            Sampled::Stop => {
                board::sample_timer_stop();
                fail(format_args!("simulated ADC lost"));
            }
            Sampled::Ok(Some(due)) => {
                if ac_period::spawn(due).is_err() {
                    millac_hal::status::AC_MISSED.fetch_add(1, Relaxed);
                }
            }
            Sampled::Ok(None) => {}
        }
    }

    /// The AC period: priority 1 (above the idle loader, below the sampler).
    #[task(priority = 1, local = [ac])]
    async fn ac_period(cx: ac_period::Context, due: u32) {
        let Some(task) = cx.local.ac.as_mut() else {
            return;
        };
        let p = task.run(due);
        if let Some(a) = p.alarm {
            Out::open().line(format_args!("alarm: {}", a));
        }
        if p.halt {
            let [x, y, z] = [
                POSITION[0].load(Relaxed),
                POSITION[1].load(Relaxed),
                POSITION[2].load(Relaxed),
            ];
            Out::open().line(format_args!(
                "millac: hold blocks={} position={},{},{}",
                BLOCKS_DONE.load(Relaxed),
                x,
                y,
                z
            ));
            exit(false);
        }
    }

    /// The loader (busy loop: QEMU 7.2 with icount loses timer interrupts on WFI).
    #[idle(local = [producer, settings, ceiling])]
    fn idle(cx: idle::Context) -> ! {
        let producer = cx.local.producer;
        let mut out = Out::open();
        let ok = match load(producer, cx.local.settings, *cx.local.ceiling, &mut out) {
            Loaded::All => true,
            Loaded::Error => false,
            Loaded::NoFile => exit(false),
        };

        // Every accepted block runs to completion, also after an error.
        while producer.len() != 0 || !IDLE.load(Relaxed) {
            cortex_m::asm::nop();
        }
        let [x, y, z] = [
            POSITION[0].load(Relaxed),
            POSITION[1].load(Relaxed),
            POSITION[2].load(Relaxed),
        ];
        out.line(format_args!(
            "millac: blocks={} position={},{},{}",
            BLOCKS_DONE.load(Relaxed),
            x,
            y,
            z
        ));
        exit(ok)
    }

    /// How loading ended.
    enum Loaded {
        /// Program end (M2/M30) or end of file.
        All,
        /// A line was refused or the file could not be read (printed); the blocks before it run.
        Error,
        /// No `program.nc` (printed): nothing to run, nothing to report.
        NoFile,
    }

    /// Reads, parses and queues the program. Errors are printed here.
    fn load(
        producer: &mut Producer<'static, Block, QUEUE>,
        settings: &Settings,
        ceiling: Option<FeedCeiling>,
        out: &mut Out,
    ) -> Loaded {
        let mut enqueue = |b: Block| enqueue(producer, b);
        let path = b"program.nc\0";
        // SAFETY: SYS_OPEN with a NUL-terminated name, its length without the NUL, mode "r".
        let fd = unsafe { syscall!(OPEN, path.as_ptr(), nr::open::R, path.len() - 1) } as isize;
        if fd == -1 {
            out.line(format_args!("error: cannot open program.nc"));
            return Loaded::NoFile;
        }

        // The tape finishes every block, with an enabled AC's feed ceiling.
        let mut tape = match ceiling {
            Some(c) => Tape::with_ac_ceiling(*settings, c),
            None => Tape::new(*settings),
        };
        let mut chunk = [0u8; CHUNK];
        let mut ok = true;
        loop {
            // SAFETY: SYS_READ into a buffer we own, at most its length; returns the bytes NOT read.
            let left = unsafe { syscall!(READ, fd, chunk.as_mut_ptr(), chunk.len()) };
            let Some(n) = chunk.len().checked_sub(left) else {
                out.line(format_args!("error: cannot read program.nc"));
                ok = false;
                // What was accepted still runs.
                let _ = tape.finish(&mut enqueue);
                break;
            };
            let bytes = chunk.get(..n).unwrap_or(&[]);
            let result = if bytes.is_empty() {
                tape.finish(&mut enqueue)
            } else {
                tape.feed(bytes, &mut enqueue)
            };
            if let Err(e) = result {
                out.line(format_args!("error: {}", e));
                ok = false;
            }
            if tape.done() {
                break;
            }
        }
        // SAFETY: SYS_CLOSE of the handle opened above.
        unsafe { syscall!(CLOSE, fd) };
        if ok {
            Loaded::All
        } else {
            Loaded::Error
        }
    }

    /// Queues a block, waiting while the queue is full (the frame drains it).
    fn enqueue(producer: &mut Producer<'static, Block, QUEUE>, b: Block) {
        while producer.enqueue(b).is_err() {
            cortex_m::asm::nop();
        }
    }
}
