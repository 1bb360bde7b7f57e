//! The chatter monitor's task body (Munasinghe 1994, section 3.3), apart from the AC period: the
//! sound channel's codes into the detector, and at the end of each record (one detection cycle,
//! 256 sound samples) its spectrum. Firmware: a software task *below* the AC task (the record's
//! FFT is soft-float on the Cortex-M3, about 420 000 instructions, most of a 10 ms period; the AC
//! period preempts it, as the HP's interrupt preempted the AC program), spawned by the sampler
//! every AC period; it hands each record's verdict to the AC task, which holds the feed at its
//! next period ([`crate::rt::ac::AcPeriod::heard`]). Host: the simulation calls it per sample.

use super::ac::ToolFollower;
use super::status::Status;
use crate::ac::AcSettings;
use crate::monitor::chatter::{ChatterDetector, Spectrum};
use crate::settings::Valid;

/// The sound channel's code of silence (a 12-bit ADC's mid-scale): the chatter detector takes
/// code - this.
pub const SOUND_MIDSCALE: f32 = 2048.0;

/// The chatter monitor: the detector, the spindle it judges for, the last record's spectrum.
pub struct ChatterTask {
    pub detector: ChatterDetector,
    rpm: u32,
    flutes: u32,
    /// The last record's spectrum (cycle, peak Hz, amplitude).
    pub last: Option<Spectrum>,
    /// `Status::resumes` and `Status::sound_dropped` as last seen: a change restarts the record.
    seen: (u32, u32),
    /// The tool in the spindle: an M6 brings its flutes (the tooth harmonics to leave out).
    tool: ToolFollower,
}

impl ChatterTask {
    /// The monitor the AC settings ask for (`$278`; off: `None`): `$266` the threshold (0: the
    /// automatic rule), `$267` the flutes (the tooth harmonics left out), `$269` the speed until
    /// the machine is commanded one (`Status::spindle_rpm`). Init context.
    pub fn from_settings(s: &Valid<AcSettings>) -> Option<Self> {
        let settings = s.chatter_settings()?;
        Some(ChatterTask {
            detector: ChatterDetector::new(settings),
            rpm: s.monitor_rpm,
            flutes: s.flutes,
            last: None,
            seen: (0, 0),
            tool: ToolFollower::new(*s),
        })
    }

    /// The sound channel's codes of one sample (oldest first): the spectrum of the record they
    /// complete, if they do (every record's, above the threshold or not: `Spectrum::chatter`
    /// says). The spindle speed follows `status` (0: none commanded, keep the last); an AC resume
    /// or lost sound since the last call restarts the record. Monitor task or host.
    pub fn sound(&mut self, codes: &[u16], status: &Status) -> Option<Spectrum> {
        let rpm = status.spindle_rpm.get();
        if rpm != 0 {
            self.rpm = rpm;
        }
        if let Some((tool, _)) = self.tool.changed(status) {
            self.flutes = tool.flutes_or(self.tool.base().flutes);
            self.detector.restart();
        }
        let seen = (status.resumes.get(), status.sound_dropped.get());
        if seen != self.seen {
            self.seen = seen;
            self.detector.restart();
        }
        let mut out = None;
        for &c in codes {
            if let Some(s) =
                self.detector
                    .push(f32::from(c) - SOUND_MIDSCALE, self.rpm, self.flutes)
            {
                self.last = Some(s);
                // (A second record in the same call cannot come: a sample's codes are far fewer
                // than a record.)
                out = Some(s);
            }
        }
        out
    }

    /// The spindle speed the monitor judges for, rpm.
    pub fn rpm(&self) -> u32 {
        self.rpm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Off at `$278=0`, on by default; on, it follows the commanded speed and gives a spectrum
    /// once per record (256 sound samples) with a tone near the tool's mode found and judged as
    /// chatter.
    #[test]
    fn one_spectrum_per_record_at_the_commanded_speed() {
        let off = AcSettings {
            chatter: false,
            ..AcSettings::default()
        };
        assert!(ChatterTask::from_settings(&off.validated().unwrap()).is_none());
        assert!(ChatterTask::from_settings(&AcSettings::default().validated().unwrap()).is_some());
        let s = AcSettings {
            chatter_threshold: 5.0,
            flutes: 2,
            ..AcSettings::default()
        };
        let mut task = ChatterTask::from_settings(&s.validated().unwrap()).unwrap();
        let status = Status::new();
        let w = status.split();
        assert_eq!(task.rpm(), 600);
        w.loader.set_spindle_rpm(1500);
        let mut spectra = Vec::new();
        for i in 0..600u32 {
            let codes: [u16; 5] = core::array::from_fn(|j| {
                let t = (i * 5 + j as u32) as f32 / 5000.0;
                (2048.0 + 20.0 * libm::sinf(2.0 * core::f32::consts::PI * 1600.0 * t)) as u16
            });
            if let Some(sp) = task.sound(&codes, &status) {
                spectra.push((i, sp));
            }
        }
        assert_eq!(task.rpm(), 1500);
        // 3000 sound samples: 11 records, each closed by the sample that holds its 256th.
        assert_eq!(spectra.len(), 11);
        // A resume restarts the record: the next spectrum comes a whole record after it.
        let record = crate::monitor::chatter::RECORD as u32;
        let bumps: [(&dyn Fn(), u32); 2] = [
            (&|| w.ac.count_resume(), 1000),
            (&|| w.sampler.count_dropped_sound(), 2000),
        ];
        for (bump, at) in bumps {
            bump();
            let mut n = 0;
            let first = loop {
                n += 1;
                if task.sound(&[2048; 5], &status).is_some() {
                    break n;
                }
            };
            assert_eq!(first, record / 5 + 1, "after the change at {at}");
        }
        assert!(spectra.iter().all(|(_, sp)| sp.chatter), "{spectra:?}");
        assert!((spectra[0].1.peak_hz - 1600.0).abs() < 20.0, "{spectra:?}");
    }
}
