//! Process monitoring beside the adaptive control (issue 10), no_std, f32, no allocation: tool
//! breakage detection after Munasinghe's thesis section 3.2 ([`breakage`]:
//! [`BreakageDetector::sample`] every ADC sample, the tooth-period work inside it) and chatter
//! detection on the sound channel, section 3.3 ([`chatter`]: every sound sample, the spectrum
//! once per record). Called from the sampler and the AC/monitoring task.

pub mod breakage;
pub mod chatter;
#[cfg(test)]
mod tests;

pub use breakage::{
    Breakage, BreakageDetector, BreakageSettings, BreakageSettingsError, FeedChange, ThresholdMode,
    MAX_FLUTES,
};
