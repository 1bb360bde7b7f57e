//! The AC side of the Nucleo-F446RE: at init the AC task and its sampler when the settings enable
//! the AC (`$250`; with the breakage monitor `$268` turns on, on the force channels; chatter,
//! `$266`, needs a sound channel this board does not have: a threshold set here is said once and
//! ignored) and the sample clock (it runs always: it feeds the watchdog and samples the operator
//! inputs); then the sampler task's tick. Init, sampler task.
use heapless::spsc::{Producer, Queue};
use millac::ac::Alarm;
use millac::inputs::Debouncer;
use millac::ports::{Codes, Inputs, OperatorInputs, SampleClock};
use millac::protocol::table::MachineSettings;
use millac::rt::actask::{self, AcTask, Sampler, ALARM_QUEUE, SAMPLE_QUEUE};
use millac::rt::status::{AcWriter, SamplerWriter};
use millac::settings::Valid;
use rtic::Mutex;

use crate::board::{self, InputPins, TripleAdc, F446};
use crate::loader::DefmtLog;

/// The AC's tasks (None: the AC is off, `$250=0`).
pub struct Adaptive {
    pub sampler: Option<Sampler<TripleAdc>>,
    pub ac: Option<AcTask<DefmtLog>>,
}

/// Starts the AC tasks the settings ask for and the sample clock. The settings come validated
/// from the start (`millac::rt::start`), so the AC tasks take them as they are. Init.
pub fn start(
    settings: &Valid<MachineSettings>,
    samples: &'static mut Queue<Codes, SAMPLE_QUEUE>,
    alarms: Producer<'static, Alarm, ALARM_QUEUE>,
    status: AcWriter<'static>,
    sampler_status: SamplerWriter<'static>,
) -> Adaptive {
    let ac = settings.ac();
    if ac.chatter_threshold > 0.0 {
        defmt::warn!("$266: this board has no sound channel; chatter detection is off");
    }
    let tasks = settings.ac_enabled.then(|| {
        actask::start(
            status,
            sampler_status,
            settings.nc,
            &ac,
            true,
            TripleAdc::new(),
            DefmtLog,
            samples.split(),
            alarms,
        )
    });
    board::sample_start(board::sample_reload(ac.sample_hz));
    let (sampler, ac) = tasks.unzip();
    Adaptive { sampler, ac }
}

/// The sampler task's own state besides the AC's sampler: the watchdog's view of the frame and
/// the operator inputs' sampling.
pub struct Tick {
    /// Frames counted at the last tick (the watchdog is fed only while the count grows).
    frames_seen: u32,
    pins: InputPins,
    /// Sample ticks per input sample (~1 kHz), and the ticks since the last.
    input_every: u32,
    input_tick: u32,
}

impl Tick {
    /// The inputs sampled at ~1 kHz (every `input_every`-th tick at `sample_hz`).
    pub fn new(pins: InputPins, sample_hz: u32) -> Self {
        Tick {
            frames_seen: 0,
            pins,
            input_every: (sample_hz / 1000).max(1),
            input_tick: 0,
        }
    }

    /// One tick of the sample clock: the watchdog fed while the frame runs, the operator inputs
    /// into the debouncer (10 samples: ~10 ms of debounce), one sample of the triple ADC; the AC
    /// period it makes due, if it does. Sampler task.
    pub fn run(
        &mut self,
        inputs: &mut impl Mutex<T = Debouncer>,
        sampler: &mut Option<Sampler<TripleAdc>>,
    ) -> Option<u32> {
        SampleClock::ack(&mut F446);
        let frames = board::frames();
        if frames != self.frames_seen {
            self.frames_seen = frames;
            F446::watchdog_feed();
        }
        // Under QEMU the GPIO inputs read 0 (no GPIO model), which would be every switch active:
        // they read as released instead.
        let raw = if cfg!(feature = "qemu") {
            Inputs::default()
        } else {
            self.pins.read()
        };
        self.input_tick += 1;
        if self.input_tick >= self.input_every {
            self.input_tick = 0;
            inputs.lock(|d| {
                d.sample(raw);
            });
        }
        sampler.as_mut()?.sample().due
    }
}
