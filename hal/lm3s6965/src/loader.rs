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
use cortex_m_semihosting::nr;
use millac::inputs::{Debouncer, Events, LimitSwitches, Trip};
use millac::ports::{Board, Inputs};
use millac::rt::status::STATUS;

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
            switches: if serial { machine() } else { None },
            inputs: millac::inputs::Debouncer::default(),
            fitted: 0,
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

/// The machine model's limit switches from `machine.txt` ([`crate::files::MACHINE_FILE`]), if
/// QEMU's working directory holds a valid one. Idle loader, once.
fn machine() -> Option<LimitSwitches> {
    let fd = crate::semihost::open(crate::files::MACHINE_FILE.as_bytes(), nr::open::R)?;
    let mut buf = [0u8; 512];
    let n = crate::semihost::read(fd, &mut buf);
    crate::semihost::close(fd);
    let text = core::str::from_utf8(buf.get(..n?)?).ok()?;
    LimitSwitches::parse(text)
}

/// The QEMU board as the loader sees it: in serial mode UART0 (`start` with the board's UART
/// clock; `kick` pends UART0) and the session log `serve.nc`; in both modes a simulated spindle:
/// the S of a spindle change reaches the simulated cut through the ADC's requests
/// ([`spindle_rpm`]), after the motion before it, as on the real board. In serial mode the
/// machine model's limit switches, when `machine.txt` gives them: closed from the pulses the
/// board emitted (the encoder), sampled through the core's debouncer at every loader turn, as
/// a real board samples its pins. No other operator inputs.
pub struct QemuLoader {
    pub clock_hz: u32,
    /// Serial mode: UART0 is started (program mode leaves it off).
    pub serial: bool,
    pub log: crate::session::SessionLog,
    pub switches: Option<LimitSwitches>,
    pub inputs: Debouncer,
    /// The tool in the simulated spindle (0 at power-up: none).
    pub fitted: u8,
}

impl QemuLoader {
    /// One sample of the simulated switches.
    fn sample(&mut self) -> Inputs {
        let limits = self.switches.map_or(0, |sw| sw.closed(STATUS.encoder()));
        self.inputs.sample(Inputs {
            limits,
            ..Inputs::default()
        })
    }
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

    fn log_move(&mut self, line: &str) {
        self.log.planned(line);
    }

    fn log_stop(&mut self, at: [i32; 3], signs: u8, cut: bool) {
        self.log.stop(at, signs, cut);
    }

    fn inputs(&mut self) -> Events {
        // No machine model (program mode, or no machine.txt): no inputs, no work per turn.
        if self.switches.is_none() {
            return Events::default();
        }
        self.sample();
        self.inputs.take()
    }

    fn latched(&mut self) -> Option<Trip> {
        self.inputs.latched()
    }

    fn acknowledge(&mut self) -> bool {
        self.sample();
        self.inputs.acknowledge()
    }

    fn latch_active(&mut self) -> bool {
        self.sample();
        self.inputs.latch_active()
    }

    fn limits(&mut self) -> u8 {
        self.sample().limits
    }

    fn limit_trips(&mut self, on: bool) {
        self.inputs.set_limit_trips(on);
    }

    /// The machine model's probe surface, from the pulses sent (not debounced: a probe stops
    /// its move at once).
    fn probe(&mut self) -> bool {
        let tool = self.fitted;
        self.switches
            .is_some_and(|sw| sw.touches(STATUS.encoder(), tool))
    }

    /// The simulated operator fitted the tool the change asked for (its length in the machine
    /// model).
    fn tool_fitted(&mut self, tool: u8) {
        self.fitted = tool;
    }
}
