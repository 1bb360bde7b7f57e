//! The AC side of the QEMU board: at init, when the host serves the simulated ADC
//! (`crate::simadc`), the AC task and its sampler (with the breakage monitor the settings turn
//! on, `$268`), the chatter monitor (`$278`, `$266`), `ac.log`, and the sample timer started (the settings
//! come validated from the start, `millac::rt::start`, so nothing here refuses them); then the
//! sampler task's tick and what follows an AC period (its alarm said, a long hold's end of the
//! run). Init, sampler task, AC task.
use heapless::spsc::{Producer, Queue};
use millac::ac::{Alarm, FeedCeiling};
use millac::monitor::chatter::Spectrum;
use millac::ports::{Board, Codes};
use millac::protocol::table::MachineSettings;
use millac::rt::actask::{
    self, AcTask, MonitorTask, Sampler, Sound, ALARM_QUEUE, SAMPLE_QUEUE, SOUND_QUEUE,
    VERDICT_QUEUE,
};
use millac::rt::clocks_for_hz;
use millac::rt::monitor::ChatterTask;
use millac::rt::status::{AcWriter, SamplerWriter};
use millac::settings::Valid;
use millac::wire::FLAG_AC_ENABLED;

use crate::board::Lm3s6965 as B;
use crate::program::held_exit;
use crate::results;
use crate::semihost::LogFile;
use crate::shared::SERIAL;
use crate::simadc::SimAdc;
use crate::voice::{error, fail, text};
use core::sync::atomic::Ordering::Relaxed;
use millac::ports::SampleClock;
use millac::rt::actask::Period;
use millac::rt::status::STATUS;

/// The AC's tasks, when the host serves the ADC.
pub struct Adaptive {
    pub sampler: Sampler<SimAdc>,
    pub ac: AcTask<LogFile>,
    /// The chatter monitor (`$278`, on by default).
    pub monitor: Option<MonitorTask>,
    /// The feed ceiling of an enabled AC, applied by the loader (None: measure only).
    pub ceiling: Option<FeedCeiling>,
}

/// The queues between the sampler, the AC period, the chatter monitor and the loader (the app's
/// `#[init]` locals).
pub struct Queues {
    pub samples: &'static mut Queue<Codes, SAMPLE_QUEUE>,
    pub sound: &'static mut Queue<Sound, SOUND_QUEUE>,
    pub verdicts: &'static mut Queue<Spectrum, VERDICT_QUEUE>,
}

/// Opens the simulated ADC (blocking until the host is ready) and starts the AC on it; None when
/// the host serves no ADC (no `adc.req`): no sample timer, no AC task, the feed cap stays off.
pub fn start(
    settings: &Valid<MachineSettings>,
    queues: Queues,
    alarms: Producer<'static, Alarm, ALARM_QUEUE>,
    status: AcWriter<'static>,
    sampler_status: SamplerWriter<'static>,
) -> Option<Adaptive> {
    let (adc, flags) = SimAdc::open()?;
    let ac_settings = settings.ac();
    let Some(log) = LogFile::create(crate::files::AC_LOG_FILE.as_bytes()) else {
        fail(format_args!("cannot create ac.log"));
    };
    // `$250=0` turns the AC's feed cap off even when the host enables it.
    let enabled = flags & FLAG_AC_ENABLED != 0 && settings.ac_enabled;
    let (mut sampler, mut ac) = actask::start(
        status,
        sampler_status,
        settings.nc,
        &ac_settings,
        enabled,
        adc,
        log,
        queues.samples.split(),
        alarms,
    );
    let monitor = match ChatterTask::from_settings(&ac_settings) {
        Some(c) => {
            let (sound_tx, sound_rx) = queues.sound.split();
            let (verdict_tx, verdict_rx) = queues.verdicts.split();
            sampler = sampler.with_sound(sound_tx);
            ac = ac.with_verdicts(verdict_rx);
            Some(MonitorTask::new(&STATUS, c, sound_rx, verdict_tx))
        }
        None => None,
    };
    crate::board::sample_timer_start(B::reload(clocks_for_hz(B::TIMER_HZ, ac_settings.sample_hz)));
    Some(Adaptive {
        sampler,
        ac,
        monitor,
        ceiling: enabled.then_some(ac_settings.ceiling),
    })
}

/// One tick of the sample clock: one sample (the sampler's; without one the clock stops), and
/// the AC period it makes due, if it does. Sampler task.
pub fn sample(sampler: &mut Option<Sampler<SimAdc>>) -> Option<u32> {
    SampleClock::ack(&mut B);
    let Some(s) = sampler.as_mut() else {
        SampleClock::stop(&mut B);
        return None;
    };
    let tick = s.sample();
    // The host has gone: without samples the AC cannot guard the cut. Said once; the periods go
    // on, see no samples and hold, and the run ends as after any hold.
    if tick.lost {
        error(format_args!("simulated ADC lost"));
    }
    tick.due
}

/// The AC period the last sample made due could not start (the previous one still runs).
/// Sampler task.
pub fn missed_period(sampler: &mut Option<Sampler<SimAdc>>) {
    if let Some(s) = sampler.as_mut() {
        s.missed_period();
    }
}

/// After an AC period: its hold's alarm into the result file and the log; program mode ends
/// the run after a long hold with nothing moving (serial mode waits for the operator). AC task.
pub fn period_done(p: Period) {
    if let Some(a) = p.alarm {
        let t = text(format_args!("{}", a));
        results::line(format_args!("alarm: {}", t));
        defmt::warn!("alarm: {=str}", t.as_str());
    }
    if p.halt && !SERIAL.load(Relaxed) {
        held_exit();
    }
}
