//! The adaptive-control side of the QEMU app: the sampler (TIMER_2A hardware task, priority 2,
//! below the frame) and the AC period (software task, priority 1, above the idle loader). The RTIC
//! app in `bin/millac-lm3s6965.rs` binds them; the bodies are the core's (`millac::rt::ac`, the
//! same code the host simulation runs); this module adds what is the QEMU board's own: the sample
//! queue between the two tasks, the overrun count and `ac.log` (its line format is
//! `millac::wire::AcLogLine`).
//!
//! Overruns: a period whose work ends after the next deadline (the sample counter has passed
//! `due + N`) counts one; a spawn the sampler could not make because the previous period was still
//! pending or running (`Status::ac_missed`) counts one more.
use core::sync::atomic::Ordering::Relaxed;

use heapless::spsc::{Consumer, Producer};
use millac::ac::{AcState, Alarm};
use millac::ports::{Codes, ForceTorqueAdc};
use millac::rt::ac::{self as body, AcPeriod};
use millac::rt::Status;
use millac::wire::{AcLogLine, LogState, AC_LOG_HEADER, SOUND_PER_SAMPLE};

/// Sample queue slots (holds one less): three periods of samples at the defaults.
pub const SAMPLE_QUEUE: usize = 32;

/// One sample tick for the AC task: the conversion (None: missed) and the sound channel's codes
/// since the previous tick (None: no microphone). A tick with neither is not queued.
#[derive(Clone, Copy)]
pub struct Tick {
    pub codes: Option<Codes>,
    pub sound: Option<[u16; SOUND_PER_SAMPLE]>,
}
/// Alarm queue slots from the AC task to the serial loader (holds one less; an alarm that does not
/// fit is still in ac.log and in the AC state word).
pub const ALARM_QUEUE: usize = 4;

/// Where the AC period writes its log lines (`millac::wire::AcLogLine`, one per period): the QEMU
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
    status: &'static Status,
    adc: D,
    queue: Producer<'static, Tick, SAMPLE_QUEUE>,
    per_period: u32,
}

/// What the app does after a sample: `due` = spawn the AC period with this deadline base (the
/// sample count).
pub enum Sampled {
    /// The host has just gone: report it once. The clock goes on and the AC periods see no samples
    /// from now on, so the machine holds (NoSamples) and the run ends as after any hold.
    Lost(Option<u32>),
    Ok(Option<u32>),
}

impl<D: ForceTorqueAdc> Sampler<D> {
    pub fn new(
        status: &'static Status,
        adc: D,
        queue: Producer<'static, Tick, SAMPLE_QUEUE>,
        per_period: u32,
    ) -> Self {
        Sampler {
            status,
            adc,
            queue,
            per_period,
        }
    }

    /// One sample (the core's body), codes and sound into the queue (a full queue counts
    /// `samples_dropped`; a missed conversion queues no codes, so the period sees no fresh
    /// sample for it). Sampler task.
    pub fn sample(&mut self) -> Sampled {
        match body::sample(&mut self.adc, self.status, self.per_period) {
            body::Sampled::Lost { due } => Sampled::Lost(due),
            body::Sampled::Codes { codes, due, sound } => {
                if (codes.is_some() || sound.is_some())
                    && self.queue.enqueue(Tick { codes, sound }).is_err()
                {
                    self.status.samples_dropped.fetch_add(1, Relaxed);
                }
                Sampled::Ok(due)
            }
        }
    }
}

/// The AC period's state.
pub struct AcTask<W: LogSink> {
    status: &'static Status,
    period: AcPeriod,
    samples: Consumer<'static, Tick, SAMPLE_QUEUE>,
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
        status: &'static Status,
        period: AcPeriod,
        samples: Consumer<'static, Tick, SAMPLE_QUEUE>,
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
            alarms,
            log,
            sample_hz,
            late: 0,
        }
    }

    /// Samples per AC period.
    pub fn per_period(&self) -> u32 {
        self.per_period
    }

    /// One AC period with deadline base `due` (the sample count when it was spawned). AC task.
    pub fn run(&mut self, due: u32) -> Period {
        while let Some(tick) = self.samples.dequeue() {
            if let Some(c) = tick.codes {
                self.period.sample(c);
            }
            if let Some(sound) = tick.sound {
                self.period.sound(&sound);
            }
        }
        let p = self.period.run(self.status);
        // Late: the next deadline passed while this period worked.
        if self.status.samples.load(Relaxed).wrapping_sub(due) >= self.per_period {
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
            overruns: self.late + self.status.ac_missed.load(Relaxed),
        };
        let mut text: heapless::String<192> = heapless::String::new();
        let _ = line.emit(&mut text);
        self.log.write(text.as_bytes());
        if let Some(a) = p.out.alarm {
            // For the serial loader's `[MSG:...]`; nobody reads it in batch mode.
            let _ = self.alarms.enqueue(a);
        }
        Period {
            alarm: p.out.alarm,
            halt: p.halt,
        }
    }
}
