//! The QEMU board as the loader sees it (idle loader): the loader's ends from init, the mode
//! (program mode when QEMU's working directory holds `program.nc`, else serial mode on UART0),
//! the simulated spindle and the session log. One `loader::Parts` for both modes: the console is
//! the program file or the serial line.
use core::sync::atomic::Ordering::Relaxed;

use heapless::spsc::{Consumer, Producer};
use millac::ac::{Alarm, FeedCeiling};
use millac::nc::Sealed;
use millac::protocol::table::record::RecordError;
use millac::protocol::table::Persistent;
use millac::protocol::Protocol;
use millac::rt::actask::ALARM_QUEUE;
use millac::rt::console::{Console, Serial};
use millac::rt::loader::{self, Parts};
use millac::rt::replan::Replan;
use millac::rt::status::LoaderWriter;

use crate::facts::Lm3s6965 as B;
use crate::shared::{QUEUE, RECORD, SERIAL};
use crate::storage::FileStorage;
use crate::uart::TX_QUEUE;
use millac::ports::Board;

/// What init hands the loader (the idle task's local resource).
pub struct Ends {
    pub blocks: Producer<'static, Sealed, QUEUE>,
    /// The settings table (the loaded record, or the defaults) and its storage.
    pub table: Persistent<FileStorage>,
    /// Why the stored record was refused (program mode then runs nothing).
    pub refused: Option<RecordError>,
    /// The feed ceiling of an enabled AC, applied by the loader (None: programmed feeds).
    pub ceiling: Option<FeedCeiling>,
    /// Serial mode's protocol and transmit queue.
    pub proto: Protocol<'static>,
    pub tx: Producer<'static, u8, TX_QUEUE>,
    /// The AC task's holds.
    pub ac_alarms: Consumer<'static, Alarm, ALARM_QUEUE>,
    pub status: LoaderWriter<'static>,
}

/// The loader, for ever: program mode runs `program.nc` and exits QEMU; serial mode serves the
/// operator on UART0. `replan`: the loader's record of the queued blocks (chatter suppression,
/// `$276`, re-plans from it in both modes), in the idle task's static storage. Idle loader.
pub fn run(ends: &mut Ends, replan: &mut Option<Replan<RECORD>>) -> ! {
    let nc = ends.table.settings.nc;
    let replan = replan.insert(Replan::new(nc, &ends.table.settings.ac, [0; 3]));
    let mut program = crate::program::open().map(|p| crate::program::console(p, ends.refused));
    let serial = program.is_none();
    SERIAL.store(serial, Relaxed);
    let mut line = Serial::new(&mut ends.proto, &mut ends.tx, crate::uart::kick, &nc);
    let console: &mut dyn Console = match program.as_mut() {
        Some(p) => p,
        None => &mut line,
    };
    let finished = loader::run(
        Parts {
            blocks: &mut ends.blocks,
            replan,
            table: &mut ends.table,
            ceiling: ends.ceiling,
            console,
            ac_alarms: &mut ends.ac_alarms,
            status: &ends.status,
        },
        &mut QemuLoader {
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
    // Serial mode never ends (the loader runs while the board says so: always).
    crate::voice::exit(true)
}

/// The spindle speed the serial session has commanded (rpm, the S of its last spindle change; 0
/// before any), for the simulated ADC's requests: the simulated spindle turns at it. Written by
/// the loader task ([`QemuLoader`]'s `spindle`), read by the sampler.
static SPINDLE_RPM: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

/// The spindle speed commanded in the serial session (rpm; 0: none yet). Sampler task.
pub fn spindle_rpm() -> u32 {
    SPINDLE_RPM.load(core::sync::atomic::Ordering::Relaxed)
}

/// The simulated spindle turns at `rpm` from the next ADC request on (0: no change). Loader task
/// (the serial loader's spindle changes; in tape mode the chatter reaction's speed, `$277`).
pub fn set_spindle_rpm(rpm: u32) {
    if rpm > 0 {
        SPINDLE_RPM.store(rpm, core::sync::atomic::Ordering::Relaxed);
    }
}

/// The QEMU board as the loader sees it: in serial mode UART0 (`start` with the board's UART
/// clock; `kick` pends UART0) and the session log `serve.nc`; in both modes a simulated spindle:
/// the S of a spindle change reaches the simulated cut through the ADC's requests
/// ([`spindle_rpm`]), after the motion before it, as on the real board. No operator inputs.
pub struct QemuLoader {
    pub clock_hz: u32,
    /// Serial mode: UART0 is started (program mode leaves it off).
    pub serial: bool,
    pub log: crate::session::SessionLog,
}

impl millac::rt::loader::LoaderBoard for QemuLoader {
    type Board = crate::facts::Lm3s6965;

    /// The simulated spindle takes the commanded speed; stopping it (M5, a reset) leaves the
    /// speed: the simulated cut has no stopped spindle (the plant turns whenever the tool moves).
    fn spindle(&mut self, _state: millac::gcode::Spindle, rpm: u32, _max_rpm: u32) {
        set_spindle_rpm(rpm);
    }

    fn start(&mut self) {
        if self.serial {
            crate::uart::init(self.clock_hz);
        }
    }

    fn log_gcode(&mut self, line: &str) {
        self.log.gcode(line);
    }

    fn log_jog(&mut self, jog: &millac::protocol::jog::JogRequest) {
        self.log.jog(jog);
    }

    fn log_flush(&mut self) {
        self.log.flush();
    }

    fn log_reset(&mut self) {
        self.log.reset();
    }
}
