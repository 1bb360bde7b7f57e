//! Chatter detection on the sound channel (Munasinghe 1994, section 3.3 and chapter 5): the
//! chatter monitor's task (`crate::rt::monitor`) pushes every sound sample; each full record of [`RECORD`] samples is windowed
//! (Hann), transformed with a real FFT (`microfft`) and its largest amplitude away from the
//! tooth-passing harmonics is compared with a threshold set from chatter-free cutting (the
//! thesis' rule) or, without one, with the forced vibration's own largest amplitude
//! ([`AUTO_RATIO`]: no calibration, the default). One record is one detection cycle (256 samples: 51.2 ms at 5 kHz). no_std,
//! f32, no allocation; the record is 1 KB of RAM, the window a 1 KB table computed at compile time.
//!
//! Choices where the thesis is silent or its hardware differs:
//! - The sound's sample rate is a setting (`sound_hz`, default 5 kHz): at least 2.5 times the
//!   highest expected chatter frequency, as the thesis chose (its tool mode near 2 kHz).
//! - "Away from the tooth-passing harmonics": the bins within [`ChatterSettings::harmonic_bins`]
//!   of the first [`ChatterSettings::harmonics`] multiples of the tooth frequency rpm x z / 60
//!   are left out, and everything below `min_hz` (the spindle's and the forced vibration's low
//!   harmonics). Higher harmonics of a low tooth frequency fall every few bins and are not left
//!   out: the forced vibration's energy is in the first few.
//! - The amplitude is the windowed FFT's magnitude scaled by 2 / sum(window): a sine of
//!   amplitude A in the middle of a bin reads A.
use microfft::real::rfft_256;

use crate::settings::Valid;

/// Samples per detection record (the FFT's size).
pub const RECORD: usize = 256;

/// Without a threshold ([`ChatterSettings::threshold`] 0, the default): chatter when the largest
/// amplitude away from the tooth harmonics exceeds this many times their largest (the forced
/// vibration's) and [`AUTO_FLOOR`] in two records in a row. Regenerative chatter grows at the
/// tool's mode, away from the harmonics, to many times the forced vibration and stays; a stable
/// cut's spectrum away from them is the cut's noise, and an entry's knock rings the mode for a
/// record and decays. Chosen on the simulated plant (the thesis' table 3.2 preset, its
/// microphone with noise, `qemu/tests/chatter.rs`): the stable 2.54 mm cut's ratio is at most
/// 2.3 over 160 records (four noise seeds), and 6.0 in the one record of the slot's entry
/// (with the AC, the record after it 1.9); the 8.89 mm cut's is 3.3 to 5.1 in the record before
/// the plant's chatter marks, 15 to 25 in the next and beyond 40 after (in the slot: 10.9 and
/// 21.2 in its first two records). Independent of the microphone's gain: the same rule on any
/// machine.
pub const AUTO_RATIO: f32 = 4.0;
/// Without a threshold: the smallest amplitude judged as chatter (sound units; a 12-bit ADC's
/// code), so that a silent channel's rounding is never a spectrum.
pub const AUTO_FLOOR: f32 = 1.0;

/// Largest sound sample magnitude the detector takes (far beyond any sensor's range): the
/// spectrum of a full record at it stays finite in f32.
pub const SAMPLE_LIMIT: f32 = 1.0e9;

/// The chatter detector's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChatterSettings {
    /// Sound sample rate, Hz (1000..=100 000).
    pub sound_hz: u32,
    /// Chatter when the largest amplitude (sound units) away from the tooth harmonics exceeds
    /// this. Set it from a chatter-free cut's largest amplitude with a margin (the thesis); 0:
    /// against the forced vibration ([`AUTO_RATIO`]).
    pub threshold: f32,
    /// Frequencies below this (Hz) are not judged.
    pub min_hz: f32,
    /// How many multiples of the tooth frequency are left out (0..=64).
    pub harmonics: u32,
    /// Bins left out on each side of a tooth harmonic (0..=8).
    pub harmonic_bins: u32,
}

impl Default for ChatterSettings {
    /// 5 kHz, threshold 1.0 (set it for the sensor, or 0 for the automatic rule), below 300 Hz
    /// left out, the first 8 tooth harmonics +-1 bin.
    fn default() -> Self {
        ChatterSettings {
            sound_hz: 5000,
            threshold: 1.0,
            min_hz: 300.0,
            harmonics: 8,
            harmonic_bins: 1,
        }
    }
}

/// A chatter setting out of its range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChatterSettingsError {
    SoundRate,
    Threshold,
    MinFrequency,
    Harmonics,
}

impl ChatterSettingsError {
    pub fn message(&self) -> &'static str {
        match self {
            Self::SoundRate => "chatter: sound sample rate must be 1000..=100000 Hz",
            Self::Threshold => "chatter: threshold must be finite and >= 0",
            Self::MinFrequency => {
                "chatter: lowest frequency must be finite, >= 0 and below Nyquist"
            }
            Self::Harmonics => "chatter: harmonics 0..=64, harmonic bins 0..=8",
        }
    }
}

impl ChatterSettings {
    /// The spectrum's bin width (Hz): the resolution of a record's peak frequency.
    pub fn bin_hz(&self) -> f32 {
        self.sound_hz as f32 / RECORD as f32
    }

    /// [`ChatterSettings::validate`], and the settings as a [`Valid`] when they pass: what
    /// [`ChatterDetector::new`] takes.
    pub fn validated(self) -> Result<Valid<ChatterSettings>, ChatterSettingsError> {
        self.validate()?;
        Ok(Valid::checked(self))
    }

    /// Checks every setting; after it every computation of the detector is finite.
    pub fn validate(&self) -> Result<(), ChatterSettingsError> {
        if !(1000..=100_000).contains(&self.sound_hz) {
            return Err(ChatterSettingsError::SoundRate);
        }
        if !(self.threshold.is_finite() && self.threshold >= 0.0) {
            return Err(ChatterSettingsError::Threshold);
        }
        let nyquist = self.sound_hz as f32 / 2.0;
        if !(self.min_hz.is_finite() && self.min_hz >= 0.0 && self.min_hz < nyquist) {
            return Err(ChatterSettingsError::MinFrequency);
        }
        if self.harmonics > 64 || self.harmonic_bins > 8 {
            return Err(ChatterSettingsError::Harmonics);
        }
        Ok(())
    }
}

/// One detection cycle's result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spectrum {
    /// The detection cycle (record) number, from 0.
    pub cycle: u32,
    /// Frequency (Hz) and amplitude of the largest judged bin.
    pub peak_hz: f32,
    pub peak_amplitude: f32,
    /// The largest amplitude of the tooth harmonics' bins (the forced vibration; 0 without a
    /// tooth frequency).
    pub forced_amplitude: f32,
    /// The level the amplitude was judged against: the threshold, or [`AUTO_RATIO`] times the
    /// forced vibration's amplitude (at least [`AUTO_FLOOR`]).
    pub threshold: f32,
    /// The amplitude exceeds it (without a threshold: in this record and the one before).
    pub chatter: bool,
}

/// cos(x) for x in [0, 2 pi], in f64 at compile time: reduced to [-pi, pi] and summed as its
/// Taylor series to 30 terms (the last term below 1e-40 there).
const fn cos_const(x: f64) -> f64 {
    let pi = core::f64::consts::PI;
    let x = if x > pi { x - 2.0 * pi } else { x };
    let (mut term, mut sum, mut k) = (1.0f64, 1.0f64, 1u32);
    while k < 30 {
        term = -term * x * x / ((2 * k - 1) as f64 * (2 * k) as f64);
        sum += term;
        k += 1;
    }
    sum
}

/// The Hann window, periodic: 0.5 (1 - cos(2 pi i / N)), computed at compile time (computing
/// it with the soft-float cosine took milliseconds of the Cortex-M3's init, which delayed the
/// sample timer's start once the chatter monitor was on by default).
const fn hann() -> [f32; RECORD] {
    let mut w = [0.0f32; RECORD];
    let mut i = 0;
    while i < RECORD {
        let x = 2.0 * core::f64::consts::PI * i as f64 / RECORD as f64;
        w[i] = (0.5 * (1.0 - cos_const(x))) as f32;
        i += 1;
    }
    w
}

/// The window, computed once at compile time for [`WINDOW`] and [`SCALE`].
const HANN: [f32; RECORD] = hann();

/// The window every record is multiplied by.
static WINDOW: [f32; RECORD] = HANN;

/// 2 / sum(window): a sine of amplitude A in the middle of a bin reads A.
const SCALE: f32 = {
    let (mut sum, mut i) = (0.0f32, 0);
    while i < RECORD {
        sum += HANN[i];
        i += 1;
    }
    2.0 / sum
};

/// The detector: the record being filled.
#[derive(Clone, Debug)]
pub struct ChatterDetector {
    s: ChatterSettings,
    record: [f32; RECORD],
    filled: usize,
    cycle: u32,
    /// Without a threshold: the last record exceeded the automatic level.
    over: bool,
}

impl ChatterDetector {
    /// A detector at its first record (its settings checked: see [`Valid`]).
    pub fn new(s: Valid<ChatterSettings>) -> Self {
        ChatterDetector {
            s: s.get(),
            record: [0.0; RECORD],
            filled: 0,
            cycle: 0,
            over: false,
        }
    }

    pub fn settings(&self) -> &ChatterSettings {
        &self.s
    }

    /// Starts a new record (after a hold, a change of the cut).
    pub fn restart(&mut self) {
        self.filled = 0;
        self.over = false;
    }

    /// One sound sample (a value that is not finite counts as 0, one beyond +-[`SAMPLE_LIMIT`]
    /// as the limit, so the spectrum stays finite); at the end of a record, the record's
    /// spectrum judged for a spindle at `rpm` with `flutes` teeth.
    pub fn push(&mut self, sample: f32, rpm: u32, flutes: u32) -> Option<Spectrum> {
        let v = if sample.is_finite() {
            sample.clamp(-SAMPLE_LIMIT, SAMPLE_LIMIT)
        } else {
            0.0
        };
        if let Some(slot) = self.record.get_mut(self.filled) {
            *slot = v;
        }
        self.filled += 1;
        if self.filled < RECORD {
            return None;
        }
        self.filled = 0;
        let out = self.judge(rpm, flutes);
        self.cycle = self.cycle.wrapping_add(1);
        Some(out)
    }

    /// The spectrum of the full record.
    fn judge(&mut self, rpm: u32, flutes: u32) -> Spectrum {
        let mut x = [0.0f32; RECORD];
        for ((o, r), w) in x.iter_mut().zip(self.record.iter()).zip(WINDOW.iter()) {
            *o = r * w;
        }
        let spectrum = rfft_256(&mut x);
        let bin_hz = self.s.bin_hz();
        let tooth_hz = rpm as f32 * flutes as f32 / 60.0;
        // The bins left out, marked once per record in bin numbers (a soft-float compare per bin
        // and harmonic cost about a fifth of a 10 ms period on the Cortex-M3).
        let (left_out, harmonic) = self.left_out(tooth_hz, bin_hz);
        // The largest power |X|^2 of the judged bins, and of the harmonics' bins; one square
        // root each at the end (the amplitude is monotonic in it), not one per bin.
        let (mut peak_k, mut peak_p, mut forced_p) = (0usize, 0.0f32, 0.0f32);
        // Bin 0 holds DC and, packed in its imaginary part, Nyquist: never judged.
        for (k, ((c, out), h)) in spectrum
            .iter()
            .zip(left_out.iter())
            .zip(harmonic.iter())
            .enumerate()
            .skip(1)
        {
            let p = c.re * c.re + c.im * c.im;
            if *h {
                forced_p = forced_p.max(p);
            }
            if *out {
                continue;
            }
            if p > peak_p {
                (peak_k, peak_p) = (k, p);
            }
        }
        let peak = libm::sqrtf(peak_p) * SCALE;
        let forced = libm::sqrtf(forced_p) * SCALE;
        let (threshold, chatter) = if self.s.threshold > 0.0 {
            (self.s.threshold, peak > self.s.threshold)
        } else {
            let level = (AUTO_RATIO * forced).max(AUTO_FLOOR);
            let over = peak > level;
            let chatter = over && self.over;
            self.over = over;
            (level, chatter)
        };
        Spectrum {
            cycle: self.cycle,
            peak_hz: peak_k as f32 * bin_hz,
            peak_amplitude: peak,
            forced_amplitude: forced,
            threshold,
            chatter,
        }
    }

    /// The bins not judged: below `min_hz`, and within `harmonic_bins` (+ half a bin) of one of
    /// the first `harmonics` multiples of `tooth_hz` (none when it is not a positive frequency);
    /// and those of the harmonics alone.
    fn left_out(&self, tooth_hz: f32, bin_hz: f32) -> ([bool; RECORD / 2], [bool; RECORD / 2]) {
        let mut out = [false; RECORD / 2];
        let mut harmonic = [false; RECORD / 2];
        // min_hz is validated finite, >= 0 and below Nyquist: 0 ..= RECORD / 2 bins.
        let k_min = libm::ceilf(self.s.min_hz / bin_hz) as usize;
        for o in out.iter_mut().take(k_min) {
            *o = true;
        }
        if !(tooth_hz > 0.0 && tooth_hz.is_finite()) {
            return (out, harmonic);
        }
        let band = self.s.harmonic_bins as f32 + 0.5;
        for h in 1..=self.s.harmonics {
            let centre = h as f32 * tooth_hz / bin_hz;
            let lo = libm::ceilf(centre - band).max(0.0);
            let hi = libm::floorf(centre + band);
            if lo >= (RECORD / 2) as f32 {
                break;
            }
            // Both finite and within 0..RECORD/2 here: the casts are exact.
            let (lo, hi) = (lo as usize, hi.min((RECORD / 2 - 1) as f32) as usize);
            for (o, h) in out
                .iter_mut()
                .zip(harmonic.iter_mut())
                .take(hi + 1)
                .skip(lo)
            {
                *o = true;
                *h = true;
            }
        }
        (out, harmonic)
    }
}

/// A spindle speed of a stable lobe ([`lobe_rpm`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LobeSpeed {
    /// The new speed, rpm.
    pub rpm: u32,
    /// The number m of tooth periods in one period of the chatter at it: the chatter frequency
    /// is m times the new tooth frequency.
    pub m: u32,
}

/// The spindle speed of the nearest stable lobe, for a cut that chatters at `chatter_hz` with a
/// `flutes`-tooth cutter at `rpm` (the chatter task's reaction when `$277` allows one, in the
/// loader; host). Smith and Tlusty's rule, which the thesis' survey cites for chatter control by
/// spindle speed selection (Smith and Delio 1989, Delio, Tlusty and Smith 1992, its refs. 46-47):
/// the regeneration vanishes when the tooth frequency divides the chatter frequency, so the new
/// speed is `60 chatter_hz / (flutes m)` with m a whole number. Of the two m either side of the
/// present ratio, the speed nearer `rpm` is taken; the speed never exceeds `max_rpm` (a larger m,
/// a slower speed, takes its place). A change within the chatter frequency's resolution (half
/// of `resolution_hz`, a spectrum bin, relative to `chatter_hz`) is no change: the tooth
/// frequency already divides the chatter frequency as far as it is known, and the nearest other
/// lobe is taken. None when no such speed exists or an input is not a positive finite number.
///
/// Where the lobes are narrow (high lobe numbers: the thesis' 2-flute cutter at 1500 rpm chatters
/// with m about 31, lobes 48 rpm apart) no speed is much more stable than another, and the rule
/// helps little; the loader then falls back to the depth steps (`crate::rt::replan`).
pub fn lobe_rpm(
    chatter_hz: f32,
    flutes: u32,
    rpm: u32,
    max_rpm: u32,
    resolution_hz: f32,
) -> Option<LobeSpeed> {
    let ok = |v: f32| v.is_finite() && v > 0.0;
    if !(ok(chatter_hz) && ok(resolution_hz)) || flutes == 0 || rpm == 0 || max_rpm == 0 {
        return None;
    }
    // In f64: a speed of 100 000 rpm and m in the thousands stay exact enough.
    let (fc, z, n) = (f64::from(chatter_hz), f64::from(flutes), f64::from(rpm));
    let speed = |m: f64| 60.0 * fc / (z * m);
    let ratio = speed(1.0) / n;
    // The smallest m whose speed is within max_rpm.
    let m_min = libm::ceil(speed(1.0) / f64::from(max_rpm)).max(1.0);
    let min_change = n * 0.5 * f64::from(resolution_hz) / fc;
    let mut best: Option<(f64, f64)> = None;
    // The two m either side of the ratio, and the next ones out for a ratio that is whole.
    let (lo, hi) = (libm::floor(ratio), libm::ceil(ratio));
    for m in [lo - 1.0, lo, hi, hi + 1.0] {
        let m = m.max(m_min);
        let s = speed(m);
        let change = libm::fabs(s - n);
        if change <= min_change.max(1.0) || libm::round(s) > f64::from(max_rpm) {
            continue;
        }
        if best.is_none_or(|(_, c)| change < c) {
            best = Some((m, change));
        }
    }
    // The speed is at most max_rpm (a u32) and positive here.
    best.map(|(m, _)| LobeSpeed {
        rpm: libm::round(speed(m)) as u32,
        m: m as u32,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f32::consts::PI;

    /// A sound record: tooth harmonics (amplitude `forced` each, the first 5 of `tooth_hz`),
    /// plus a sine at `chatter_hz` of amplitude `chatter`, sampled at `fs`, from sample `start`.
    fn sound(i: usize, fs: f32, tooth_hz: f32, forced: f32, chatter_hz: f32, chatter: f32) -> f32 {
        let t = i as f32 / fs;
        let mut v = 0.0;
        for h in 1..=5 {
            v += forced * libm::sinf(2.0 * PI * h as f32 * tooth_hz * t);
        }
        v + chatter * libm::sinf(2.0 * PI * chatter_hz * t + 0.3)
    }

    fn detector(threshold: f32) -> ChatterDetector {
        ChatterDetector::new(
            ChatterSettings {
                threshold,
                ..ChatterSettings::default()
            }
            .validated()
            .unwrap(),
        )
    }

    /// A chatter tone far from the tooth harmonics is found at its frequency with its amplitude,
    /// and the (much larger) tooth harmonics are not judged: the thesis' table 3.2 cut (1500 rpm,
    /// 2 flutes: tooth frequency 50 Hz) with chatter near the tool's mode.
    #[test]
    fn a_chatter_tone_is_found_and_the_tooth_harmonics_left_out() {
        let mut d = detector(0.5);
        let mut got = None;
        for i in 0..RECORD {
            got = d.push(sound(i, 5000.0, 50.0, 5.0, 1953.1, 1.0), 1500, 2);
        }
        let s = got.expect("one record");
        assert!((s.peak_hz - 1953.1).abs() <= 20.0, "{s:?}");
        assert!((s.peak_amplitude - 1.0).abs() < 0.1, "{s:?}");
        assert!(s.chatter);
        // The same record without the chatter tone: only the harmonics (left out or below 300 Hz).
        let mut d = detector(0.5);
        let s = (0..RECORD)
            .filter_map(|i| d.push(sound(i, 5000.0, 50.0, 5.0, 1953.1, 0.0), 1500, 2))
            .last()
            .unwrap();
        assert!(!s.chatter, "{s:?}");
        assert!(s.peak_amplitude < 0.05, "{s:?}");
    }

    /// Harmonics above `min_hz` are left out only near them: a tooth frequency of 400 Hz (12 000
    /// rpm, 2 flutes) puts its harmonics at 400, 800, ... Hz, within the judged band; a strong
    /// forced vibration there is not chatter, a tone between two of them is.
    #[test]
    fn judged_bins_avoid_the_harmonics_of_a_fast_tooth() {
        let mut d = detector(0.5);
        let s = (0..RECORD)
            .filter_map(|i| d.push(sound(i, 5000.0, 400.0, 3.0, 0.0, 0.0), 12_000, 2))
            .last()
            .unwrap();
        assert!(!s.chatter, "harmonics only: {s:?}");
        let mut d = detector(0.5);
        let s = (0..RECORD)
            .filter_map(|i| d.push(sound(i, 5000.0, 400.0, 3.0, 1015.6, 0.8), 12_000, 2))
            .last()
            .unwrap();
        assert!(s.chatter && (s.peak_hz - 1015.6).abs() <= 20.0, "{s:?}");
        // With the harmonics not left out, the forced vibration alone would read as chatter.
        let mut d = ChatterDetector::new(
            ChatterSettings {
                threshold: 0.5,
                harmonics: 0,
                ..ChatterSettings::default()
            }
            .validated()
            .unwrap(),
        );
        let s = (0..RECORD)
            .filter_map(|i| d.push(sound(i, 5000.0, 400.0, 3.0, 0.0, 0.0), 12_000, 2))
            .last()
            .unwrap();
        assert!(s.chatter, "{s:?}");
    }

    /// The compile-time window is the Hann window the soft-float cosine gives, to f32's
    /// resolution.
    #[test]
    fn the_compile_time_window_is_hann() {
        for (i, w) in WINDOW.iter().enumerate() {
            let x = 2.0 * PI * i as f32 / RECORD as f32;
            let want = 0.5 * (1.0 - libm::cosf(x));
            assert!((w - want).abs() <= 1e-6, "{i}: {w} against {want}");
        }
        assert_eq!(WINDOW[0], 0.0);
        assert!((SCALE * RECORD as f32 / 4.0 - 1.0).abs() < 1e-6, "{SCALE}");
    }

    /// Without a threshold (0, the default) a tone away from the harmonics is chatter when it
    /// exceeds [`AUTO_RATIO`] times the forced vibration and [`AUTO_FLOOR`] in two records in a
    /// row, whatever the microphone's gain: the same records scaled by 0.01 .. 100 give the same
    /// verdicts (above the floor); silence is never chatter, nor one record's ring (a knock).
    #[test]
    fn without_a_threshold_chatter_is_judged_against_the_forced_vibration() {
        // The second of two records, with the tone in the first at `first` times its amplitude.
        let two = |forced: f32, chatter: f32, first: f32| {
            let mut d = detector(0.0);
            (0..2 * RECORD)
                .filter_map(|i| {
                    let c = if i < RECORD { first * chatter } else { chatter };
                    d.push(sound(i, 5000.0, 50.0, forced, 1953.1, c), 1500, 2)
                })
                .last()
                .unwrap()
        };
        let verdict = |forced: f32, chatter: f32| two(forced, chatter, 1.0);
        // A knock: the tone in one record only, either one.
        for (first, second) in [(1.0, 0.0), (0.0, 1.0)] {
            let mut d = detector(0.0);
            let s: Vec<Spectrum> = (0..2 * RECORD)
                .filter_map(|i| {
                    let c = if i < RECORD { first } else { second };
                    d.push(sound(i, 5000.0, 50.0, 5.0, 1953.1, 40.0 * c), 1500, 2)
                })
                .collect();
            assert!(s.iter().all(|s| !s.chatter), "{s:?}");
        }
        for gain in [0.01, 1.0, 100.0] {
            let (f, c) = (5.0 * gain, gain);
            let below = verdict(f, 0.9 * AUTO_RATIO * f);
            let above = verdict(f, 1.1 * AUTO_RATIO * f);
            assert!(!below.chatter, "gain {gain}: {below:?}");
            assert_eq!(
                above.chatter,
                above.peak_amplitude > AUTO_FLOOR,
                "gain {gain}: {above:?}"
            );
            assert!((below.forced_amplitude / f - 1.0).abs() < 0.1, "{below:?}");
            // A tone as large as the forced vibration is no chatter.
            assert!(!verdict(f, c * 5.0).chatter, "gain {gain}");
        }
        assert!(verdict(5.0, 1.1 * AUTO_RATIO * 5.0).chatter);
        let silent = verdict(0.0, 0.0);
        assert!(
            !silent.chatter && silent.threshold == AUTO_FLOOR,
            "{silent:?}"
        );
    }

    /// Chatter that starts in the middle of a record is detected at the end of that record or the
    /// next: within two detection cycles.
    #[test]
    fn chatter_is_detected_within_two_cycles() {
        for start in [10, 100, 200, 255, 300, 600] {
            let mut d = detector(0.5);
            let mut first = None;
            for i in 0..6 * RECORD {
                let c = if i >= start { 1.0 } else { 0.0 };
                if let Some(s) = d.push(sound(i, 5000.0, 50.0, 5.0, 1953.1, c), 1500, 2) {
                    if s.chatter && first.is_none() {
                        first = Some(i);
                    }
                }
            }
            let at = first.unwrap_or_else(|| panic!("start {start}: never detected"));
            assert!(
                at < start + 2 * RECORD,
                "start {start}: detected at sample {at}"
            );
        }
    }

    /// Garbage in (NaN, infinities, huge values, no spindle) never panics and never reads as a
    /// huge tone from a non-finite sample; settings out of range are refused.
    #[test]
    fn garbage_never_panics_and_bad_settings_are_refused() {
        let mut d = detector(0.5);
        for i in 0..3 * RECORD {
            let v = match i % 4 {
                0 => f32::NAN,
                1 => f32::INFINITY,
                2 => 1e30,
                _ => -1e30,
            };
            if let Some(s) = d.push(v, 0, 0) {
                assert!(s.peak_amplitude.is_finite(), "{s:?}");
            }
        }
        let mut d = detector(0.5);
        let s = (0..RECORD)
            .filter_map(|_| d.push(f32::NAN, 1500, 2))
            .last()
            .unwrap();
        assert!(!s.chatter && s.peak_amplitude == 0.0, "{s:?}");
        for bad in [
            ChatterSettings {
                sound_hz: 10,
                ..Default::default()
            },
            ChatterSettings {
                threshold: f32::NAN,
                ..Default::default()
            },
            ChatterSettings {
                min_hz: 3000.0,
                ..Default::default()
            },
            ChatterSettings {
                harmonic_bins: 9,
                ..Default::default()
            },
        ] {
            assert!(bad.validated().is_err(), "{bad:?}");
        }
    }

    /// The rule's speeds: the tooth frequency divides the chatter frequency, the lobe nearer the
    /// present speed, never above the limit, never a change within the frequency's resolution.
    #[test]
    fn the_lobe_speed_puts_a_tooth_harmonic_on_the_chatter_frequency() {
        // 1650 Hz with 2 flutes at 14 000 rpm: ratio 60 * 1650 / (2 * 14000) = 3.54; m = 4 gives
        // 12 375 rpm (1625 away), m = 3 gives 16 500 (2500 away).
        let bin = 5000.0 / 256.0;
        let s = lobe_rpm(1650.0, 2, 14_000, 30_000, bin).unwrap();
        assert_eq!(s, LobeSpeed { rpm: 12_375, m: 4 });
        let tooth_hz = s.rpm as f32 * 2.0 / 60.0;
        assert!((tooth_hz * s.m as f32 - 1650.0).abs() < 0.1, "{tooth_hz}");
        // Nearer the faster lobe: 60 * 1650 / (2 * 15500) = 3.19; m = 3 gives 16 500.
        assert_eq!(lobe_rpm(1650.0, 2, 15_500, 30_000, bin).unwrap().m, 3);
        // The faster lobe beyond the limit: the slower one.
        assert_eq!(
            lobe_rpm(1650.0, 2, 15_500, 16_000, bin).unwrap().rpm,
            12_375
        );
        // Far above the limit (a spindle commanded faster than $277 allows): the first lobe below.
        let s = lobe_rpm(1650.0, 2, 14_000, 5_000, bin).unwrap();
        assert!(s.rpm <= 5_000 && s.rpm > 5_000 * (s.m - 1) / s.m, "{s:?}");
        // A tooth harmonic already on the chatter frequency (ratio 4.000): the next lobe.
        let s = lobe_rpm(1650.0, 2, 12_375, 30_000, bin).unwrap();
        assert!(s.m == 3 || s.m == 5, "{s:?}");
        // The thesis' cut: 1560 Hz at 1500 rpm, m about 31: a change of 0.65 %, just beyond the
        // frequency's resolution (half a bin, 0.63 %).
        let s = lobe_rpm(1560.0, 2, 1500, 2000, bin).unwrap();
        assert_eq!((s.rpm, s.m), (1510, 31));
        // Below the tooth frequency (ratio < 1): m = 1, slower.
        assert_eq!(
            lobe_rpm(300.0, 2, 12_000, 30_000, bin).unwrap(),
            LobeSpeed { rpm: 9000, m: 1 }
        );
        // Garbage.
        for (hz, z, n, max, res) in [
            (f32::NAN, 2, 1500, 2000, bin),
            (-5.0, 2, 1500, 2000, bin),
            (1560.0, 0, 1500, 2000, bin),
            (1560.0, 2, 0, 2000, bin),
            (1560.0, 2, 1500, 0, bin),
            (1560.0, 2, 1500, 2000, f32::INFINITY),
            (f32::MAX, 8, u32::MAX, u32::MAX, bin),
        ] {
            let s = lobe_rpm(hz, z, n, max, res);
            if let Some(s) = s {
                assert!(s.rpm <= max && s.m >= 1, "{s:?}");
            }
        }
        assert_eq!(lobe_rpm(f32::NAN, 2, 1500, 2000, bin), None);
        assert_eq!(lobe_rpm(1560.0, 2, 1500, 0, bin), None);
    }
}
