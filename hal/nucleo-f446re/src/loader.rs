//! The Nucleo-F446RE as the loader sees it (idle loader; the AC task's log): the loader's ends
//! from init and its run (the grbl protocol on USART2, for ever), USART2 (started, kicked), the
//! operator inputs through the shared debouncer (a short lock against the sampler), the spindle
//! outputs, the frame's cycle limit, and the AC log at defmt's debug level.
use heapless::spsc::{Consumer, Producer};
use millac::ac::Alarm;
use millac::flashstore::FlashStore;
use millac::gcode::Spindle;
use millac::inputs::{Debouncer, Events, Trip};
use millac::nc::Sealed;
use millac::ports::Board;
use millac::protocol::table::Persistent;
use millac::protocol::Protocol;
use millac::rt::actask::{LogSink, ALARM_QUEUE};
use millac::rt::console::Serial;
use millac::rt::loader::{self, LoaderBoard, Parts};
use millac::rt::replan::Replan;
use millac::rt::status::LoaderWriter;
use rtic::Mutex;
use stm32f4xx_hal::gpio::{AnyPin, Output};

use crate::board;
use crate::facts::F446;
use crate::flash::Sector;

/// Queue slots (a heapless spsc queue holds one less: 31 blocks).
pub const QUEUE: usize = 32;
/// The loader's record of queued blocks: the queue and room for nested chatter detours.
pub const RECORD: usize = millac::rt::replan::record_len(QUEUE);
/// Transmit queue slots.
pub const TX_QUEUE: usize = 512;

/// What init hands the loader (the idle task's local resource).
pub struct Ends {
    pub blocks: Producer<'static, Sealed, QUEUE>,
    /// The settings table (the stored record, or the defaults) in its flash sector.
    pub table: Persistent<FlashStore<Sector>>,
    pub proto: Protocol<'static>,
    pub tx: Producer<'static, u8, TX_QUEUE>,
    /// The AC task's holds.
    pub ac_alarms: Consumer<'static, Alarm, ALARM_QUEUE>,
    /// The spindle enable and direction pins.
    pub spindle: board::SpindlePins,
    pub status: LoaderWriter<'static>,
}

/// The serial loader, for ever: the grbl protocol on USART2. `replan`: the loader's record of
/// the queued blocks (chatter suppression, `$276`; this board has no sound channel, so it never
/// re-plans, but the loader is the same), in the idle task's static storage; `inputs`: the
/// operator inputs' debouncer shared with the sampler. Idle loader.
pub fn run<M: Mutex<T = Debouncer>>(
    ends: &mut Ends,
    replan: &mut Option<Replan<RECORD>>,
    inputs: M,
) -> ! {
    let settings = ends.table.settings;
    let (enable, direction) = (&mut ends.spindle.0, &mut ends.spindle.1);
    let mut board = Nucleo {
        inputs,
        enable,
        direction,
        frame_limit: F446::frame_limit_cycles(&settings.nc).unwrap_or(u32::MAX),
    };
    let replan = replan.insert(Replan::new(settings.nc, &settings.ac, [0; 3]));
    let mut console = Serial::new(&mut ends.proto, &mut ends.tx, kick, &settings.nc);
    loader::run(
        Parts {
            blocks: &mut ends.blocks,
            replan,
            table: &mut ends.table,
            ceiling: settings.ac_enabled.then_some(settings.ac.ceiling),
            console: &mut console,
            ac_alarms: &mut ends.ac_alarms,
            status: &ends.status,
        },
        &mut board,
    );
    // Never reached: the board's loader runs for ever.
    loop {
        cortex_m::asm::nop();
    }
}

/// Pends USART2 so that it moves queued bytes out (the serial console's writer).
pub fn kick() {
    rtic::pend(stm32f4xx_hal::pac::Interrupt::USART2);
}

/// The board as the serial loader sees it: USART2, the operator inputs (through the shared
/// debouncer: a short lock against the sampler), the spindle outputs.
pub struct Nucleo<'a, M: Mutex<T = Debouncer>> {
    pub inputs: M,
    pub enable: &'a mut AnyPin<Output>,
    pub direction: &'a mut AnyPin<Output>,
    /// The frame work the running settings tolerate, in DWT cycles.
    pub frame_limit: u32,
}

impl<M: Mutex<T = Debouncer>> LoaderBoard for Nucleo<'_, M> {
    fn start(&mut self) {
        board::usart2_start();
    }

    type Board = F446;

    /// Enable high for M3/M4, direction high for M4, PWM duty S / `$30`.
    fn spindle(&mut self, state: Spindle, rpm: u32, max_rpm: u32) {
        match state {
            Spindle::Off => {
                board::spindle_pwm_set(0);
                self.enable.set_low();
            }
            Spindle::Cw | Spindle::Ccw => {
                self.direction.set_state((state == Spindle::Ccw).into());
                board::spindle_pwm_set(board::spindle_duty(rpm, max_rpm));
                self.enable.set_high();
            }
        }
        defmt::info!("spindle {} at {} rpm", defmt::Debug2Format(&state), rpm);
    }

    fn frame_limit_cycles(&self) -> Option<u32> {
        Some(self.frame_limit)
    }

    fn inputs(&mut self) -> Events {
        self.inputs.lock(|d| d.take())
    }

    fn latched(&mut self) -> Option<Trip> {
        self.inputs.lock(|d| d.latched())
    }

    fn acknowledge(&mut self) -> bool {
        self.inputs.lock(|d| d.acknowledge())
    }

    fn latch_active(&mut self) -> bool {
        self.inputs.lock(|d| d.latch_active())
    }

    fn limits(&mut self) -> u8 {
        self.inputs.lock(|d| d.inputs().limits)
    }

    fn limit_trips(&mut self, on: bool) {
        self.inputs.lock(|d| d.set_limit_trips(on))
    }

    /// The probe pin as the input task last sampled it (every 1 ms, not debounced).
    fn probe(&mut self) -> bool {
        self.inputs.lock(|d| d.inputs().probe)
    }
}

/// The AC log lines at defmt's debug level (`DEFMT_LOG=debug` to see them).
pub struct DefmtLog;

impl LogSink for DefmtLog {
    fn write(&mut self, bytes: &[u8]) {
        if let Ok(s) = core::str::from_utf8(bytes) {
            defmt::debug!("{=str}", s.trim_end());
        }
    }
}
