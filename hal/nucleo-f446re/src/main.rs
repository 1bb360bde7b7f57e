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
//! This app binds the runtime written once in `millac::rt` to the board's interrupts; the
//! board's parts: `board` (clocks, pins, ports, the frame's measurement), `adaptive` (the AC
//! tasks, the sampler's tick), `loader` (the loader's ends and run), `flash` (the settings
//! record), `facts` (the board's limits).
#![no_std]
#![no_main]

use defmt_rtt as _;
use panic_probe as _;

mod adaptive;
mod board;
mod facts;
mod flash;
mod loader;

#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true, dispatchers = [SPI1])]
mod app {
    use heapless::spsc::{Consumer, Queue};
    use millac::ac::Alarm;
    use millac::inputs::Debouncer;
    use millac::nc::Sealed;
    use millac::ports::Codes;
    use millac::protocol::rx::{RxIsr, RxShared};
    use millac::protocol::Protocol;
    use millac::rt::actask::{AcTask, Sampler, ALARM_QUEUE, SAMPLE_QUEUE};
    use millac::rt::replan::Replan;
    use millac::rt::status::{PulseWriter, Static};
    use millac::rt::{self, FrameTask};

    use crate::adaptive::{self, Tick};
    use crate::board::{self, FrameCycles, TripleAdc, F446};
    use crate::flash;
    use crate::loader::{DefmtLog, Ends, QUEUE, RECORD, TX_QUEUE};
    use millac::flashstore::FlashStore;
    use millac::ports::Board;

    /// The operator inputs' debouncer: sampled by the sampler task, read by the loader.
    #[shared]
    struct Shared {
        inputs: Debouncer,
    }

    #[local]
    struct Local {
        // With the plan ratio only where the board's limits say so (`BoardLimits::plan_ratio`,
        // which also decides whether `$263=2` is accepted): the F446's frame is past its
        // instruction bound with it (`facts::LIMITS`).
        frame: FrameTask<Static, { F446::LIMITS.plan_ratio }>,
        consumer: Consumer<'static, Sealed, QUEUE>,
        cycles: FrameCycles,
        pulse_status: PulseWriter<Static>,
        sampler: Option<Sampler<TripleAdc>>,
        ac: Option<AcTask<DefmtLog>>,
        tick: Tick,
        uart_rx: RxIsr<'static>,
        uart_tx: Consumer<'static, u8, TX_QUEUE>,
        loader: Ends,
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
        let mut rcc = board::clocks(cx.device.RCC);
        let (pins, spindle) = board::pins(cx.device.GPIOA, cx.device.GPIOB, &mut rcc);
        let watchdog_reset = F446::watchdog_reset();
        let start = match rt::start::start::<F446, _>(FlashStore::new(flash::sector())) {
            Ok(s) => s,
            Err(e) => defmt::panic!("settings: {}", e.message()),
        };
        // No cap unless the AC says otherwise, 100 % feed (before any interrupt is enabled); each
        // context's handle.
        let status = rt::status::split_static();
        let frame = start.frame(status.frame);
        let cycles = FrameCycles::new(&mut core.DCB, &mut core.DWT, status.cycles);
        let (mut table, refused) = (start.table, start.refused);
        // Under QEMU: no DMA model, so no ADC samples: the AC is off ($250=0).
        if cfg!(feature = "qemu") {
            table.settings = table.settings.with_ac_enabled(false);
        }
        if let Some(e) = refused {
            defmt::warn!("settings record refused: {}; defaults loaded", e.message());
        }
        let (blocks, consumer) = cx.local.queue.split();
        F446::init(start.reloads.feed, start.pulse);
        let (alarm_tx, ac_alarms) = cx.local.alarms.split();
        let adaptive::Adaptive { sampler, ac } = adaptive::start(
            &table.settings,
            cx.local.samples,
            alarm_tx,
            status.ac,
            status.sampler,
        );

        let (uart_rx, rx) = cx.local.serial_rx.split();
        let mut proto = Protocol::new(rx, (QUEUE - 1) as u16);
        proto.set_core_hz(board::CORE_HZ);
        // ALARM:120 after the banner, G-code locked until `$X` (as on the QEMU board).
        if let Some(e) = refused {
            proto.settings_refused(e);
        }
        let (tx, uart_tx) = cx.local.serial_tx.split();

        F446::watchdog_start();
        let nc = table.settings.nc;
        defmt::info!(
            "millac on Nucleo-F446RE: W0 {} Hz, rapid {} Hz, pulse {} ns, AC {}{}",
            nc.frame_hz,
            nc.rapid_hz,
            nc.pulse_width_ns,
            if ac.is_some() { "on" } else { "off" },
            if watchdog_reset {
                "; reset by the watchdog"
            } else {
                ""
            }
        );
        let tick = Tick::new(pins, table.settings.ac.sample_hz);
        let loader = Ends {
            blocks,
            table,
            proto,
            tx,
            ac_alarms,
            spindle,
            status: status.loader,
        };
        let inputs = Debouncer::new(millac::inputs::DEBOUNCE_SAMPLES);
        let pulse_status = status.pulse;
        #[rustfmt::skip]
        let local = Local { frame, consumer, cycles, pulse_status, sampler, ac, tick, uart_rx, uart_tx, loader };
        (Shared { inputs }, local)
    }

    /// The frame ISR: highest priority (3). No locks, logging, allocation or panics. Measures its
    /// own cycles with the DWT counter.
    #[task(binds = TIM2, priority = 3, local = [frame, consumer, cycles])]
    fn frame(cx: frame::Context) {
        let (frame, consumer) = (cx.local.frame, cx.local.consumer);
        cx.local
            .cycles
            .measure(|| frame.run(&mut F446, &mut F446, &mut F446, consumer));
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

    /// The sampler (TIM3 update, `sample_hz`): the watchdog, the operator inputs, one
    /// conversion of the triple ADC, the AC period spawned every N samples. Priority 2.
    #[task(binds = TIM3, priority = 2, local = [sampler, tick], shared = [inputs])]
    fn sample(mut cx: sample::Context) {
        let sampler = cx.local.sampler;
        if let Some(due) = cx.local.tick.run(&mut cx.shared.inputs, sampler) {
            if ac_period::spawn(due).is_err() {
                sampler.as_ref().map(Sampler::missed_period);
            }
        }
    }

    /// The AC period: priority 1.
    #[task(priority = 1, local = [ac])]
    async fn ac_period(cx: ac_period::Context, due: u32) {
        // The hold is reported by the loader (`[MSG:AC hold: ...]`): no log here, where the axes
        // may still move (defmt's RTT logger masks interrupts while it formats).
        if let Some(task) = cx.local.ac.as_mut() {
            let _ = task.run(due);
        }
    }

    /// The loader: the grbl protocol on USART2, for ever.
    #[idle(local = [loader, replan: Option<Replan<RECORD>> = None], shared = [inputs])]
    fn idle(cx: idle::Context) -> ! {
        crate::loader::run(cx.local.loader, cx.local.replan, cx.shared.inputs)
    }
}
