//! The adaptive-control side of the QEMU app: the sampler's work (TIMER_2A hardware task, priority
//! 2, below the frame) and the AC period's work (software task, priority 1, above the idle loader).
//! The RTIC app in `bin/millac-lm3s6965.rs` binds them; this module holds the logic.
//!
//! # Timing of the AC period
//!
//! The sampler spawns the AC task after every `sample_hz * period_ms / 1000`-th sample (10 at the
//! defaults), with the sample count as the period's deadline base. The period is thus clocked by
//! the same timer as the samples: every period sees exactly its own window of samples, and the host
//! can replay the grouping (period k = samples `k*N .. (k+1)*N`). A separate monotonic (SysTick)
//! would be a second clock beating against Timer 2, giving 9, 10 or 11 samples per window
//! depending on phase, and one more interrupt source that must be kept below the frame.
//!
//! Overruns: a period whose work ends after the next deadline (the sample counter has passed
//! `due + N`) counts one; a spawn the sampler could not make because the previous period was
//! still pending or running (`AC_MISSED`) counts one more. A hold is `FEED_CAP = 0`: the frame
//! keeps its block and its counters, it simply stops feeding; no block is dropped. Resume is not
//! wired to any command yet (`AcController::resume` exists; the protocol module will call it).
//!
//! # `ac.log`
//!
//! Text, one header row `t_ms,x_blu,y_blu,z_blu,feed_cap,e,f_n,t_nm,state,overruns`, then one line
//! per period: `t_ms` = the period's deadline (sample count * 1000 / sample_hz), the encoder
//! counts X, Y, Z in BLU at the end of the period's work, `feed_cap` the controller's feed number
//! (the frame takes min(programmed, cap); written to `FEED_CAP` only when the AC is enabled),
//! `e`, `f_n` (N), `t_nm` (N*m) as Rust's shortest round-trip f32 text, `state` = `run` or
//! `hold:<alarm message>`, `overruns` the running count.
//!
//! # End of a hold
//!
//! Nothing moves during a hold and the operator cannot resume yet, so after
//! [`HOLD_EXIT_PERIODS`] periods in hold with the encoder unchanged (AC enabled; a measure-only run
//! just logs the hold and goes on), [`AcTask::run`] asks the app to stop: it prints `millac: hold blocks=.. position=x,y,z` and exits QEMU with failure status.
use core::fmt::Write as _;
use core::sync::atomic::Ordering::Relaxed;

use heapless::spsc::{Consumer, Producer};
use millac::ac::{achieved_feed, AcController, AcState, Alarm};

use crate::simadc::{LogFile, SimAdc};
use millac::rt::Status;

/// Sample queue slots (holds one less): three periods of samples at the defaults.
pub const SAMPLE_QUEUE: usize = 32;
/// AC periods in hold with the encoder unchanged before the firmware stops (1 s at 10 ms).
pub const HOLD_EXIT_PERIODS: u32 = 100;
/// Header row of `ac.log`.
pub const LOG_HEADER: &str = "t_ms,x_blu,y_blu,z_blu,feed_cap,e,f_n,t_nm,state,overruns\n";

/// One conversion [T, Fu, Fv].
pub use millac::ports::Codes;

/// The sampler's state: the ADC, the queue to the AC task, the sample index.
pub struct Sampler {
    status: &'static Status,
    adc: SimAdc,
    queue: Producer<'static, Codes, SAMPLE_QUEUE>,
    index: u32,
    per_period: u32,
}

/// What the app does after a sample.
pub enum Sampled {
    /// The host has gone: stop the sample timer.
    Stop,
    /// Sampled; `Some(due)`: spawn the AC period with this deadline base (the sample count).
    Ok(Option<u32>),
}

impl Sampler {
    /// `per_period` samples per AC period (validated settings: at least 1).
    pub fn new(
        status: &'static Status,
        adc: SimAdc,
        queue: Producer<'static, Codes, SAMPLE_QUEUE>,
        per_period: u32,
    ) -> Self {
        Sampler {
            status,
            adc,
            queue,
            index: 0,
            per_period: per_period.max(1),
        }
    }

    /// One sample: lockstep exchange with the host, codes into the queue (a full queue counts
    /// `SAMPLES_DROPPED`). Sampler task.
    pub fn sample(&mut self) -> Sampled {
        let i = self.index;
        let Some(codes) = self.adc.exchange(i, self.status.encoder()) else {
            return Sampled::Stop;
        };
        if self.queue.enqueue(codes).is_err() {
            self.status.samples_dropped.fetch_add(1, Relaxed);
        }
        let n = i.wrapping_add(1);
        self.index = n;
        self.status.samples.store(n, Relaxed);
        Sampled::Ok((n % self.per_period == 0).then_some(n))
    }
}

/// The AC period's state.
pub struct AcTask {
    status: &'static Status,
    ctl: AcController,
    samples: Consumer<'static, Codes, SAMPLE_QUEUE>,
    log: LogFile,
    enabled: bool,
    per_period: u32,
    sample_hz: u32,
    late: u32,
    still: u32,
    last: [i32; 3],
    /// The NC settings, for the achieved feed (anti-windup) in frame feed numbers.
    nc: millac::Settings,
}

/// What one period asks of the app.
pub struct Period {
    /// The alarm that entered hold in this period: print it.
    pub alarm: Option<Alarm>,
    /// Held long enough with nothing moving: report and exit.
    pub halt: bool,
}

impl AcTask {
    /// Writes the log header; sets `FEED_CAP` to the controller's first cap when `enabled`.
    /// Init context.
    pub fn new(
        status: &'static Status,
        ctl: AcController,
        samples: Consumer<'static, Codes, SAMPLE_QUEUE>,
        mut log: LogFile,
        enabled: bool,
        nc: millac::Settings,
    ) -> Self {
        log.write(LOG_HEADER.as_bytes());
        if enabled {
            status.feed_cap.store(ctl.feed_cap(), Relaxed);
        }
        let s = ctl.settings();
        let (sample_hz, per_period) = (s.sample_hz, s.sample_hz * s.period_ms / 1000);
        AcTask {
            status,
            ctl,
            samples,
            log,
            enabled,
            per_period: per_period.max(1),
            sample_hz,
            late: 0,
            still: 0,
            last: [0; 3],
            nc,
        }
    }

    /// Samples per AC period.
    pub fn per_period(&self) -> u32 {
        self.per_period
    }

    /// One AC period with deadline base `due` (the sample count when it was spawned). AC task.
    pub fn run(&mut self, due: u32) -> Period {
        while let Some(codes) = self.samples.dequeue() {
            self.ctl.sample(codes);
        }
        // One encoder reading per period: it gives the achieved feed (anti-windup, see
        // AcController::set_achieved) and it is the position logged, so a replay from ac.log and
        // the samples reproduces every decision.
        let enc = self.status.encoder();
        let d = [0, 1, 2].map(|k| i64::from(enc[k]) - i64::from(self.last[k]));
        let period_ms = self.ctl.settings().period_ms;
        self.ctl.set_achieved(achieved_feed(d, &self.nc, period_ms));
        let out = self.ctl.period();
        if self.enabled {
            self.status.feed_cap.store(out.feed_cap, Relaxed);
        }
        let held = matches!(out.state, AcState::Hold(_));
        self.still = if held && enc == self.last {
            self.still + 1
        } else {
            0
        };
        self.last = enc;

        let mut line: heapless::String<192> = heapless::String::new();
        let t_ms = u64::from(due) * 1000 / u64::from(self.sample_hz);
        let _ = write!(
            line,
            "{t_ms},{},{},{},{},{},{},{},",
            enc[0], enc[1], enc[2], out.feed_cap, out.e, out.f_n, out.t_nm
        );
        let _ = match out.state {
            AcState::Run => line.write_str("run"),
            AcState::Hold(a) => write!(line, "hold:{}", a.message()),
        };
        // Late: the next deadline passed while this period worked.
        if self.status.samples.load(Relaxed).wrapping_sub(due) >= self.per_period {
            self.late += 1;
        }
        let overruns = self.late + self.status.ac_missed.load(Relaxed);
        let _ = writeln!(line, ",{overruns}");
        self.log.write(line.as_bytes());
        Period {
            alarm: out.alarm,
            // Only a hold that is applied stops the machine (measure-only runs keep going).
            halt: self.enabled && held && self.still >= HOLD_EXIT_PERIODS,
        }
    }
}
