//! The frame: Initiator, PTP, feed DDA, interpolators, output and position. `Frame::tick` is called
//! once per frame interrupt (ISR): integers only, no panics, no allocation. STUB: API fixed, body WIP.
use super::block::Block;
use crate::settings::Settings;

/// The frame's share of the settings, precomputed in task context.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameConfig {
    pub q0: u32,
    pub decel_gain_q8: u32,
    pub ptp_steps: [u32; 3],
}

impl FrameConfig {
    pub const fn from_settings(s: &Settings) -> Self {
        FrameConfig { q0: s.q0, decel_gain_q8: s.decel_gain_q8(), ptp_steps: s.ptp_steps }
    }
}

/// Which timer period the next frame wants: W0 (contouring, dwell, idle) or the rapid rate (PTP).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rate {
    Feed,
    Rapid,
}

/// What one frame outputs: bit k of `steps` = one pulse on axis k; `signs` bit k set = axis k
/// positive. `signs` holds the last direction of every axis, also of axes that do not step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Pulses {
    pub steps: u8,
    pub signs: u8,
}

pub struct Frame {
    cfg: FrameConfig,
    position: [i32; 3],
}

impl Frame {
    pub const fn new(cfg: FrameConfig) -> Self {
        Frame { cfg, position: [0; 3] }
    }
    /// One frame. `next` is the Initiator's block source; it is called only when no block is loaded.
    /// `feed_cap` is the adaptive controller's feed number (u32::MAX = no cap).
    #[inline]
    pub fn tick(&mut self, next: impl FnMut() -> Option<Block>, feed_cap: u32) -> Pulses {
        let _ = (next, feed_cap, self.cfg);
        Pulses::default()
    }
    /// Timer rate the next frame needs.
    pub fn rate(&self) -> Rate {
        Rate::Feed
    }
    /// Absolute position in BLU, updated per pulse.
    pub fn position(&self) -> [i32; 3] {
        self.position
    }
    /// True when no block is loaded.
    pub fn idle(&self) -> bool {
        true
    }
    /// Blocks completed since power-up.
    pub fn blocks_done(&self) -> u32 {
        0
    }
}
