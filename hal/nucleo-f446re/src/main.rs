//! millac firmware for the Nucleo-F446RE: the RTIC 2 app. `init` brings the clock tree to 180 MHz
//! (HSE bypass from the ST-LINK's 8 MHz), loads the settings record, validates it against the
//! board's limits and starts the board; the frame ISR (TIM2) and the pulse-end ISR (TIM5) drive
//! the pins with the core's bodies (`millac::rt`, the same code as on the QEMU board); the idle
//! loop is the serial loader (`millac::rt::loader`: grbl 1.1 over USART2, the ST-LINK virtual COM
//! port).
//!
//! Priorities: frame and pulse-end 3; the sampler (TIM3, `sample_hz`) and USART2 2; the AC period
//! (software task, dispatcher SPI1) 1; the idle loader 0. Logs go through defmt over RTT (read by
//! `probe-rs run`), never from the frame or pulse-end ISR (defmt's RTT logger takes a critical
//! section).
//!
//! With the `qemu` feature the same app runs under QEMU's netduinoplus2 machine (STM32F405):
//! only what that machine does not model changes (no clock tree set-up, the settings in RAM, the
//! pins' levels kept in RAM for the pulse-end ISR's read-back, the operator inputs released, the
//! AC off); see `board` and `flash`.
//!
//! The frame measures itself with the DWT cycle counter: cycles from the first instruction of the
//! handler to its last (the exception entry and return, 12 + ~10 cycles on a Cortex-M4 with zero
//! wait states, come on top), min and max since reset.
#![no_std]
#![no_main]

use defmt_rtt as _;
use panic_probe as _;

mod board;
mod facts;
mod flash;
mod loader;

#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true, dispatchers = [SPI1])]
mod app {
    use core::sync::atomic::AtomicU32;
    use core::sync::atomic::Ordering::Relaxed;

    use cortex_m::peripheral::DWT;
    use heapless::spsc::{Consumer, Producer, Queue};
    use millac::ac::Alarm;
    use millac::nc::Sealed;
    use millac::ports::{Board, Codes, SampleClock};
    use millac::protocol::rx::{RxIsr, RxShared};
    use millac::protocol::settings::Persistent;
    use millac::protocol::Protocol;
    use millac::rt::actask::{self, AcTask, Sampler, ALARM_QUEUE, SAMPLE_QUEUE};
    use millac::rt::replan::Replan;
    use millac::rt::{self, FrameTask};
    use stm32f4xx_hal::prelude::*;
    #[cfg(not(feature = "qemu"))]
    use stm32f4xx_hal::rcc::Config;

    use millac::flashstore::FlashStore;

    use crate::board::{self, TripleAdc, F446};
    use crate::flash::{self, Sector};
    use crate::loader::{kick, DefmtLog, Nucleo};
    use millac::inputs::Debouncer;
    use millac::ports::{OperatorInputs, PinInputs};
    use millac::rt::console::Serial;
    use millac::rt::status::{CycleWriter, LoaderWriter, PulseWriter, Static};
    use stm32f4xx_hal::gpio::{AnyPin, Input, Output};

    /// Frames since reset (the sampler feeds the watchdog only while it grows).
    static FRAMES: AtomicU32 = AtomicU32::new(0);

    /// Queue slots (a heapless spsc queue holds one less: 31 blocks).
    const QUEUE: usize = 32;
    /// The loader's record of queued blocks: the queue and room for nested chatter detours.
    const RECORD: usize = millac::rt::replan::record_len(QUEUE);
    /// Transmit queue slots.
    const TX_QUEUE: usize = 512;

    /// The operator inputs' debouncer: sampled by the sampler task, read by the loader.
    #[shared]
    struct Shared {
        inputs: Debouncer,
    }

    /// The frame's own measurement: min and max cycles since reset.
    pub struct FrameCycles {
        min: u32,
        max: u32,
        /// The frame wrapper's handle on the status words: the cycles for the status report.
        status: CycleWriter<Static>,
    }

    #[local]
    struct Local {
        // With the plan ratio only where the board's limits say so (`BoardLimits::plan_ratio`,
        // which also decides whether `$263=2` is accepted): the F446's frame is past its
        // instruction bound with it (`limits::LIMITS`).
        frame: FrameTask<Static, { F446::LIMITS.plan_ratio }>,
        consumer: Consumer<'static, Sealed, QUEUE>,
        producer: Producer<'static, Sealed, QUEUE>,
        table: Persistent<FlashStore<Sector>>,
        cycles: FrameCycles,
        /// Each context's handle on the status words (`millac::rt::status`): the pulse end's, the
        /// loader's (the frame task, the sampler, the AC task and the frame wrapper hold theirs).
        pulse_status: PulseWriter<Static>,
        loader_status: LoaderWriter<'static>,
        sampler: Option<Sampler<TripleAdc>>,
        ac: Option<AcTask<DefmtLog>>,
        frames_seen: u32,
        /// The operator input pins (embedded-hal input pins with pull-ups).
        pins: PinInputs<AnyPin<Input>>,
        /// Sample ticks per input sample (~1 kHz).
        input_every: u32,
        /// The spindle enable and direction pins.
        spindle: (AnyPin<Output>, AnyPin<Output>),
        uart_rx: RxIsr<'static>,
        uart_tx: Consumer<'static, u8, TX_QUEUE>,
        proto: Protocol<'static>,
        tx: Producer<'static, u8, TX_QUEUE>,
        ac_alarms: Consumer<'static, Alarm, ALARM_QUEUE>,
    }

    #[init(local = [
        queue: Queue<Sealed, QUEUE> = Queue::new(),
        samples: Queue<Codes, SAMPLE_QUEUE> = Queue::new(),
        serial_rx: RxShared = RxShared::new(),
        serial_tx: Queue<u8, TX_QUEUE> = Queue::new(),
        alarms: Queue<Alarm, ALARM_QUEUE> = Queue::new(),
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        let mut core = cx.core;
        #[cfg(not(feature = "qemu"))]
        let mut rcc = cx.device.RCC.freeze(
            Config::hse(8.MHz())
                .bypass_hse_oscillator()
                .sysclk(board::CORE_HZ.Hz())
                .pclk1(board::PCLK1_HZ.Hz())
                .pclk2(90.MHz()),
        );
        #[cfg(not(feature = "qemu"))]
        {
            let c = rcc.clocks;
            if c.sysclk().raw() != board::CORE_HZ || c.timclk1().raw() != board::TIMER_HZ {
                defmt::panic!(
                    "clock tree: sysclk {} Hz, APB1 timers {} Hz",
                    c.sysclk().raw(),
                    c.timclk1().raw()
                );
            }
        }
        // QEMU's netduinoplus2 has no RCC model (reads 0: `freeze` would wait for HSE ready
        // forever); its timers count at their own fixed clock (`board::TIMER_HZ`).
        #[cfg(feature = "qemu")]
        let mut rcc = cx.device.RCC.constrain();
        // Operator inputs (pull-ups, switches to ground): PB12 e-stop (normally closed), PB13 feed
        // hold, PB14 cycle start, PB15 / PB1 / PB2 X / Y / Z limit. Spindle: PA8 enable, PA9
        // direction (high = M4), PB6 PWM (TIM4 CH1).
        let gpioa = cx.device.GPIOA.split(&mut rcc);
        let gpiob = cx.device.GPIOB.split(&mut rcc);
        let pins = PinInputs {
            estop: gpiob.pb12.into_pull_up_input().erase(),
            feed_hold: gpiob.pb13.into_pull_up_input().erase(),
            cycle_start: gpiob.pb14.into_pull_up_input().erase(),
            limits: [
                gpiob.pb15.into_pull_up_input().erase(),
                gpiob.pb1.into_pull_up_input().erase(),
                gpiob.pb2.into_pull_up_input().erase(),
            ],
        };
        let spindle = (
            gpioa.pa8.into_push_pull_output().erase(),
            gpioa.pa9.into_push_pull_output().erase(),
        );
        board::spindle_pwm_start();
        core.DCB.enable_trace();
        core.DWT.enable_cycle_counter();
        let watchdog_reset = F446::watchdog_reset();

        let start = match rt::start::start::<F446, _>(FlashStore::new(flash::sector())) {
            Ok(s) => s,
            Err(e) => defmt::panic!("settings: {}", e.message()),
        };
        // No cap unless the AC says otherwise, 100 % feed (before any interrupt is enabled); each
        // context's handle.
        let status = rt::status::split_static();
        let frame = start.frame(status.frame);
        let (table, refused) = (start.table, start.refused);
        // Under QEMU: no DMA model, so no ADC samples: the AC is off ($250=0).
        #[cfg(feature = "qemu")]
        let table = {
            let mut table = table;
            table.settings = table.settings.with_ac_enabled(false);
            table
        };
        if let Some(e) = refused {
            defmt::warn!("settings record refused: {}; defaults loaded", e.message());
        }
        let settings = table.settings.nc;
        let (producer, consumer) = cx.local.queue.split();
        F446::init(start.reloads.feed, start.pulse);

        // The AC, when enabled by the settings ($250); the sampler runs always (it feeds the
        // watchdog).
        let ac_settings = table.settings.ac();
        let (alarm_tx, ac_alarms) = cx.local.alarms.split();
        if ac_settings.chatter_threshold > 0.0 {
            defmt::warn!("$266: this board has no sound channel; chatter detection is off");
        }
        // The breakage monitor when the settings turn it on ($268), on the force channels;
        // chatter ($266) needs a sound channel this board does not have: a threshold set here is
        // ignored (said once at start). The settings come validated from the start, so the AC
        // tasks take them as they are.
        let (sampler, ac) = if table.settings.ac_enabled {
            let (s, t) = actask::start(
                status.ac,
                status.sampler,
                settings,
                &ac_settings,
                true,
                TripleAdc::new(),
                DefmtLog,
                cx.local.samples.split(),
                alarm_tx,
            );
            (Some(s), Some(t))
        } else {
            (None, None)
        };
        board::sample_start(board::sample_reload(ac_settings.sample_hz));

        let (uart_rx, rx) = cx.local.serial_rx.split();
        let mut proto = Protocol::new(rx, (QUEUE - 1) as u16);
        proto.set_core_hz(board::CORE_HZ);
        // ALARM:120 after the banner, G-code locked until `$X` (as on the QEMU board).
        if let Some(e) = refused {
            proto.settings_refused(e);
        }
        let (tx, uart_tx) = cx.local.serial_tx.split();

        F446::watchdog_start();
        defmt::info!(
            "millac on Nucleo-F446RE: W0 {} Hz, rapid {} Hz, pulse {} ns, AC {}{}",
            settings.frame_hz,
            settings.rapid_hz,
            settings.pulse_width_ns,
            if ac.is_some() { "on" } else { "off" },
            if watchdog_reset {
                "; reset by the watchdog"
            } else {
                ""
            }
        );

        // The inputs are sampled at ~1 kHz (every `input_every`-th sample tick) and debounced over
        // 10 of those samples.
        let input_every = (ac_settings.sample_hz / 1000).max(1);
        (
            Shared {
                inputs: Debouncer::new(millac::inputs::DEBOUNCE_SAMPLES),
            },
            Local {
                frame,
                consumer,
                producer,
                table,
                cycles: FrameCycles {
                    min: u32::MAX,
                    max: 0,
                    status: status.cycles,
                },
                pulse_status: status.pulse,
                loader_status: status.loader,
                sampler,
                ac,
                frames_seen: 0,
                pins,
                input_every,
                spindle,
                uart_rx,
                uart_tx,
                proto,
                tx,
                ac_alarms,
            },
        )
    }

    /// The frame ISR: highest priority (3). No locks, logging, allocation or panics. Measures its
    /// own cycles with the DWT counter.
    #[task(binds = TIM2, priority = 3, local = [frame, consumer, cycles])]
    fn frame(cx: frame::Context) {
        let t0 = DWT::cycle_count();
        let local = cx.local;
        local
            .frame
            .run(&mut F446, &mut F446, &mut F446, local.consumer);
        FRAMES.store(FRAMES.load(Relaxed).wrapping_add(1), Relaxed);
        let dt = DWT::cycle_count().wrapping_sub(t0);
        let c = local.cycles;
        if dt < c.min {
            c.min = dt;
            c.status.set_min(dt);
        }
        if dt > c.max {
            c.max = dt;
            c.status.set_max(dt);
        }
    }

    /// The pulse-end ISR: same priority as the frame.
    #[task(binds = TIM5, priority = 3, local = [pulse_status])]
    fn pulse_end(cx: pulse_end::Context) {
        rt::pulse_end(&mut F446, &mut F446, *cx.local.pulse_status);
    }

    /// USART2: received bytes into the protocol's ring, queued bytes out. Priority 2.
    #[task(binds = USART2, priority = 2, local = [uart_rx, uart_tx])]
    fn usart2(cx: usart2::Context) {
        board::usart2_interrupt(cx.local.uart_tx, cx.local.uart_rx);
        // QEMU's USART raises no transmit-empty interrupt: pend it again while TXEIE is on.
        #[cfg(feature = "qemu")]
        if board::usart2_txe_wanted() {
            rtic::pend(stm32f4xx_hal::pac::Interrupt::USART2);
        }
    }

    /// The sampler (TIM3 update, `sample_hz`): one conversion of the triple ADC, the AC period
    /// spawned every N samples; feeds the watchdog while the frame runs. Priority 2.
    #[task(
        binds = TIM3,
        priority = 2,
        local = [sampler, frames_seen, pins, input_every, input_tick: u32 = 0],
        shared = [inputs]
    )]
    fn sample(mut cx: sample::Context) {
        SampleClock::ack(&mut F446);
        let frames = FRAMES.load(Relaxed);
        if frames != *cx.local.frames_seen {
            *cx.local.frames_seen = frames;
            F446::watchdog_feed();
        }
        // Under QEMU the GPIO inputs read 0 (no GPIO model), which would be every switch active:
        // they read as released instead.
        let raw = if cfg!(feature = "qemu") {
            millac::ports::Inputs::default()
        } else {
            cx.local.pins.read()
        };
        // The inputs at ~1 kHz whatever the sample rate (10 samples: ~10 ms of debounce).
        *cx.local.input_tick += 1;
        if *cx.local.input_tick >= *cx.local.input_every {
            *cx.local.input_tick = 0;
            cx.shared.inputs.lock(|d| {
                d.sample(raw);
            });
        }
        let Some(s) = cx.local.sampler.as_mut() else {
            return;
        };
        let due = s.sample().due;
        if let Some(due) = due {
            if ac_period::spawn(due).is_err() {
                s.missed_period();
            }
        }
    }

    /// The AC period: priority 1.
    #[task(priority = 1, local = [ac])]
    async fn ac_period(cx: ac_period::Context, due: u32) {
        let Some(task) = cx.local.ac.as_mut() else {
            return;
        };
        // The hold is reported by the loader (`[MSG:AC hold: ...]`): no log here, where the axes
        // may still move (defmt's RTT logger masks interrupts while it formats).
        let _ = task.run(due);
    }

    /// The loader: the grbl protocol on USART2, forever.
    #[idle(
        local = [
            producer, table, proto, tx, ac_alarms, spindle, loader_status,
            replan: Option<Replan<RECORD>> = None
        ],
        shared = [inputs]
    )]
    fn idle(cx: idle::Context) -> ! {
        let (enable, direction) = cx.local.spindle;
        let mut board = Nucleo {
            inputs: cx.shared.inputs,
            enable,
            direction,
            frame_limit: F446::frame_limit_cycles(&cx.local.table.settings.nc).unwrap_or(u32::MAX),
        };
        let ceiling = cx
            .local
            .table
            .settings
            .ac_enabled
            .then_some(cx.local.table.settings.ac.ceiling);
        // The loader's record of the queued blocks (chatter suppression, `$276`; this board has no
        // sound channel, so it never re-plans, but the loader is the same).
        let settings = &cx.local.table.settings;
        let replan = cx
            .local
            .replan
            .insert(Replan::new(settings.nc, &settings.ac, [0; 3]));
        let nc = settings.nc;
        let mut console = Serial::new(cx.local.proto, cx.local.tx, kick, &nc);
        millac::rt::loader::run(
            millac::rt::loader::Parts {
                blocks: cx.local.producer,
                replan,
                table: cx.local.table,
                ceiling,
                console: &mut console,
                ac_alarms: cx.local.ac_alarms,
                status: cx.local.loader_status,
            },
            &mut board,
        );
        // Never reached: the board's loader runs for ever.
        loop {
            cortex_m::asm::nop();
        }
    }
}
