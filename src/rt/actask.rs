//! The adaptive-control tasks as every board's RTIC app binds them: the sampler (a timer's
//! hardware task, below the frame), the AC period (a software task) and the chatter monitor (a
//! software task below it, above the idle loader: the AC period preempts its record's FFT). The
//! bodies are `crate::rt::ac`'s (the same code the host simulation runs); this module adds the
//! glue between them: the sample, sound and verdict queues, the overrun count and the AC log
//! through the board's `LogSink` (its line format is `crate::wire::AcLogLine`). Sampler, AC and
//! monitor task contexts.
//!
//! Overruns: a period whose work ends after the next deadline (the sample counter has passed
//! `due + N`) counts one; a spawn the sampler could not make because the previous period was still
//! pending or running (`Status::ac_missed`) counts one more.
use crate::ac::{AcState, Alarm};
use crate::monitor::chatter::Spectrum;
use crate::ports::{Codes, ForceTorqueAdc};
use crate::rt::ac::{self as body, AcPeriod};
use crate::rt::monitor::ChatterTask;
use crate::rt::status::{AcWriter, SamplerWriter};
use crate::rt::Status;
use crate::settings::Valid;
use crate::wire::{AcLogLine, LogState, AC_LOG_HEADER, SOUND_PER_SAMPLE};
use heapless::spsc::{Consumer, Producer};

/// Sample queue slots (holds one less): three periods of samples at the defaults.
pub const SAMPLE_QUEUE: usize = 32;

/// Sound queue slots (holds one less): the sound codes of 63 samples (63 ms at 1 kHz), more than
/// the chatter monitor needs for a record's FFT (about 7 ms of CPU under QEMU's clock, preempted
/// by everything above it).
pub const SOUND_QUEUE: usize = 64;
/// Verdict queue slots from the chatter monitor to the AC task (holds one less).
pub const VERDICT_QUEUE: usize = 4;

/// One sample's sound codes (the microphone's, since the previous sample).
pub type Sound = [u16; SOUND_PER_SAMPLE];

/// Alarm queue slots from the AC task to the loader (holds one less; an alarm that does not
/// fit is still in ac.log and in the AC state word).
pub const ALARM_QUEUE: usize = 4;

/// Where the AC period writes its log lines (`crate::wire::AcLogLine`, one per period): the QEMU
/// board's `ac.log`, a real board's debug log, or nothing. AC task. Must not block for long.
pub trait LogSink {
    fn write(&mut self, bytes: &[u8]);
}

/// No AC log.
impl LogSink for () {
    fn write(&mut self, _: &[u8]) {}
}

/// The sampler's state: the ADC, the queue to the AC task.
pub struct Sampler<D: ForceTorqueAdc> {
    status: SamplerWriter<'static>,
    adc: D,
    queue: Producer<'static, Codes, SAMPLE_QUEUE>,
    /// The chatter monitor's sound queue (None: no chatter monitor).
    sound: Option<Producer<'static, Sound, SOUND_QUEUE>>,
    per_period: u32,
    /// The overload trip when the AC is applied, for the tool in the spindle
    /// (`crate::rt::ac::ToolTrip`; None: measure only).
    trip: Option<crate::rt::ac::ToolTrip>,
}

/// What the app does after a sample: spawn the AC period when `due` (its deadline base, the
/// sample count); report it once when `lost` (the ADC has just gone: the clock goes on and the AC
/// periods see no samples from now on, so the machine holds with NoSamples and the run ends as
/// after any hold). (The core's [`body::Sampled`] is the sample itself.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleTick {
    pub due: Option<u32>,
    pub lost: bool,
}

impl<D: ForceTorqueAdc> Sampler<D> {
    pub fn new(
        status: SamplerWriter<'static>,
        adc: D,
        queue: Producer<'static, Codes, SAMPLE_QUEUE>,
        per_period: u32,
    ) -> Self {
        Sampler {
            status,
            adc,
            queue,
            sound: None,
            per_period,
            trip: None,
        }
    }

    /// Holds the feed from the sampler on the first sample above the overload hold's level (the
    /// AC applied: its feed cap is the frame's). Init context.
    pub fn with_trip(mut self, trip: crate::rt::ac::ToolTrip) -> Self {
        self.trip = Some(trip);
        self
    }

    /// The AC period this sample made due could not start (the previous one still runs):
    /// counted into `Status::ac_missed`. Sampler task.
    pub fn missed_period(&self) {
        self.status.count_missed_period();
    }

    /// Queues the sound channel's codes for the chatter monitor. Init context.
    pub fn with_sound(mut self, sound: Producer<'static, Sound, SOUND_QUEUE>) -> Self {
        self.sound = Some(sound);
        self
    }

    /// One sample (the core's body), codes into the AC task's queue and sound into the chatter
    /// monitor's (a full queue counts `samples_dropped`, or `sound_dropped`; a missed conversion
    /// queues no codes, so the period sees no fresh sample for it). Sampler task.
    pub fn sample(&mut self) -> SampleTick {
        let status: &Status = &self.status;
        let trip = self.trip.as_mut().and_then(|t| t.follow(status));
        match body::sample(&mut self.adc, &self.status, self.per_period, trip) {
            body::Sampled::Lost { due } => SampleTick { due, lost: true },
            body::Sampled::Codes { codes, due, sound } => {
                if let Some(c) = codes {
                    if self.queue.enqueue(c).is_err() {
                        self.status.count_dropped_sample();
                    }
                }
                // A lost sample of sound makes the monitor restart its record (no gap judged).
                if let (Some(q), Some(s)) = (self.sound.as_mut(), sound) {
                    if q.enqueue(s).is_err() {
                        self.status.count_dropped_sound();
                    }
                }
                SampleTick { due, lost: false }
            }
        }
    }
}

/// The chatter monitor's task: the sound the sampler queued into the detector; each record's
/// verdict to the AC task (`crate::rt::monitor`).
pub struct MonitorTask {
    status: &'static Status,
    chatter: ChatterTask,
    sound: Consumer<'static, Sound, SOUND_QUEUE>,
    verdicts: Producer<'static, Spectrum, VERDICT_QUEUE>,
}

impl MonitorTask {
    pub fn new(
        status: &'static Status,
        chatter: ChatterTask,
        sound: Consumer<'static, Sound, SOUND_QUEUE>,
        verdicts: Producer<'static, Spectrum, VERDICT_QUEUE>,
    ) -> Self {
        MonitorTask {
            status,
            chatter,
            sound,
            verdicts,
        }
    }

    /// Everything queued since the last run; a record's spectrum goes to the AC task (a full
    /// verdict queue drops it: the AC task has four records' verdicts it has not read yet).
    /// Monitor task.
    pub fn run(&mut self) {
        while let Some(s) = self.sound.dequeue() {
            if let Some(v) = self.chatter.sound(&s, self.status) {
                let _ = self.verdicts.enqueue(v);
            }
        }
    }
}

/// The AC tasks every board starts from its settings: the controller, the AC period with the
/// process monitors the settings turn on, the AC task over the sample queue, and its sampler
/// (with the overload trip when the AC is `enabled`, i.e. applied to the feed). Nothing is checked
/// here: the AC settings come validated (a [`Valid`]), and so do the monitors' settings derived
/// from them. Init context.
#[allow(clippy::too_many_arguments)]
pub fn start<D: ForceTorqueAdc, W: LogSink>(
    status: AcWriter<'static>,
    sampler_status: SamplerWriter<'static>,
    settings: crate::Settings,
    ac: &Valid<crate::ac::AcSettings>,
    enabled: bool,
    adc: D,
    log: W,
    samples: (
        Producer<'static, Codes, SAMPLE_QUEUE>,
        Consumer<'static, Codes, SAMPLE_QUEUE>,
    ),
    alarms: Producer<'static, Alarm, ALARM_QUEUE>,
) -> (Sampler<D>, AcTask<W>) {
    let ctl = crate::ac::AcController::new(*ac);
    let period = AcPeriod::new(ctl, settings, enabled, &status).with_monitors(ac);
    let (tx, rx) = samples;
    let task = AcTask::new(status, period, rx, alarms, log);
    let mut sampler = Sampler::new(sampler_status, adc, tx, task.per_period());
    if enabled {
        sampler = sampler.with_trip(body::ToolTrip::new(*ac));
    }
    (sampler, task)
}

/// The AC period's state.
pub struct AcTask<W: LogSink> {
    status: AcWriter<'static>,
    period: AcPeriod,
    samples: Consumer<'static, Codes, SAMPLE_QUEUE>,
    /// The chatter monitor's verdicts (None: no chatter monitor).
    verdicts: Option<Consumer<'static, Spectrum, VERDICT_QUEUE>>,
    alarms: Producer<'static, Alarm, ALARM_QUEUE>,
    log: W,
    per_period: u32,
    sample_hz: u32,
    late: u32,
}

/// What one period asks of the app.
pub struct Period {
    /// The alarm that entered hold in this period: print it.
    pub alarm: Option<Alarm>,
    /// Held long enough with nothing moving: report and exit.
    pub halt: bool,
}

impl<W: LogSink> AcTask<W> {
    /// Writes the log header. Init context.
    pub fn new(
        status: AcWriter<'static>,
        period: AcPeriod,
        samples: Consumer<'static, Codes, SAMPLE_QUEUE>,
        alarms: Producer<'static, Alarm, ALARM_QUEUE>,
        mut log: W,
    ) -> Self {
        log.write(AC_LOG_HEADER.as_bytes());
        let sample_hz = period.ctl.settings().sample_hz;
        AcTask {
            status,
            per_period: period.per_period(),
            period,
            samples,
            verdicts: None,
            alarms,
            log,
            sample_hz,
            late: 0,
        }
    }

    /// Takes the chatter monitor's verdicts. Init context.
    pub fn with_verdicts(mut self, verdicts: Consumer<'static, Spectrum, VERDICT_QUEUE>) -> Self {
        self.verdicts = Some(verdicts);
        self
    }

    /// Samples per AC period.
    pub fn per_period(&self) -> u32 {
        self.per_period
    }

    /// One AC period with deadline base `due` (the sample count when it was spawned). AC task.
    pub fn run(&mut self, due: u32) -> Period {
        while let Some(codes) = self.samples.dequeue() {
            self.period.sample(codes, &self.status);
        }
        if let Some(v) = self.verdicts.as_mut() {
            while let Some(s) = v.dequeue() {
                self.period.heard(s);
            }
        }
        let p = self.period.run(&self.status);
        // Late: the next deadline passed while this period worked.
        if self.status.samples.get().wrapping_sub(due) >= self.per_period {
            self.late += 1;
        }
        let line = AcLogLine {
            t_ms: u64::from(due) * 1000 / u64::from(self.sample_hz),
            pos_blu: p.encoder,
            feed_cap: p.out.feed_cap,
            e: p.out.e,
            f_n: p.out.f_n,
            t_nm: p.out.t_nm,
            state: match p.out.state {
                AcState::Run => LogState::Run,
                AcState::Hold(a) => LogState::Hold(a.message()),
            },
            overruns: self.late + self.status.ac_missed.get(),
            tool: self.period.tool(),
        };
        let mut text: heapless::String<192> = heapless::String::new();
        let _ = line.emit(&mut text);
        self.log.write(text.as_bytes());
        if let Some(a) = p.out.alarm {
            // For the loader: a serial line's `[MSG:...]` (a program run's `alarm:` line is the app's AC task's).
            let _ = self.alarms.enqueue(a);
        }
        Period {
            alarm: p.out.alarm,
            halt: p.halt,
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::ac::AcSettings;
    use crate::ports::Conversion;
    use heapless::spsc::Queue;
    use std::boxed::Box;

    /// Mid-scale codes every sample.
    struct Quiet;

    impl ForceTorqueAdc for Quiet {
        fn sample(&mut self, _index: u32, _encoder: [i32; 3]) -> Conversion {
            Conversion::Fresh([2048; 3])
        }
    }

    type Started = (Sampler<Quiet>, AcTask<()>);

    fn started(ac: Valid<AcSettings>, enabled: bool) -> Started {
        let status: &'static Status = Box::leak(Box::new(Status::new()));
        let w = status.split();
        let samples: &'static mut Queue<Codes, SAMPLE_QUEUE> = Box::leak(Box::new(Queue::new()));
        let alarms: &'static mut Queue<Alarm, ALARM_QUEUE> = Box::leak(Box::new(Queue::new()));
        let (alarm_tx, _) = alarms.split();
        start(
            w.ac,
            w.sampler,
            crate::Settings::default(),
            &ac,
            enabled,
            Quiet,
            (),
            samples.split(),
            alarm_tx,
        )
    }

    /// The boards' start of the AC tasks: it takes validated AC settings (a `Valid`, so it has no
    /// refusal of its own) and starts the tasks, the sampler with the overload trip only when the
    /// AC is applied, the breakage monitor when the settings turn it on. Settings that fail their
    /// checks never reach it: their validation refuses them.
    #[test]
    fn the_ac_tasks_start_from_valid_settings() {
        let valid = AcSettings::default().validated().unwrap();
        let (s, t) = started(valid, true);
        assert!(s.trip.is_some());
        assert_eq!(t.per_period(), AcSettings::default().samples_per_period());
        assert!(t.period.breakage().is_none());
        let (s, _) = started(valid, false);
        assert!(s.trip.is_none());
        let bad_ac = AcSettings {
            period_ms: 0,
            ..AcSettings::default()
        };
        assert_eq!(bad_ac.validated(), Err(crate::ac::AcSettingsError::Period));
        // The AC settings' validation covers what the monitors take from them: with the
        // breakage monitor on, valid settings start it.
        let monitored = AcSettings {
            breakage: crate::ac::Breakage::On,
            ..AcSettings::default()
        };
        let (_, t) = started(monitored.validated().unwrap(), true);
        assert!(t.period.breakage().is_some());
    }
}
