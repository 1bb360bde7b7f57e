//! The AC side of the QEMU board's init: when the host serves the simulated ADC
//! (`crate::simadc`), the AC task and its sampler (with the breakage monitor the settings turn
//! on, `$268`), the chatter monitor (`$266`), `ac.log`, and the sample timer started. Init; the
//! settings come validated from the start (`millac::rt::start`), so nothing here refuses them.
use heapless::spsc::{Producer, Queue};
use millac::ac::{Alarm, FeedCeiling};
use millac::monitor::chatter::Spectrum;
use millac::ports::{Board, Codes};
use millac::protocol::settings::MachineSettings;
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
use crate::semihost::LogFile;
use crate::simadc::SimAdc;
use crate::voice::fail;
use millac::rt::status::STATUS;

/// The AC's tasks, when the host serves the ADC.
pub struct Adaptive {
    pub sampler: Sampler<SimAdc>,
    pub ac: AcTask<LogFile>,
    /// The chatter monitor (`$266` above 0).
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
