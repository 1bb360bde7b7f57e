//! Single-word channels between the firmware's contexts: the frame ISR publishes its status
//! (position, blocks done, idle) and reads the feed cap; the loader reads the status; the AC task
//! writes the feed cap; the pulse-end ISR counts the encoder; the sampler counts samples. Relaxed
//! atomics are enough: one core, and every word is meaningful on its own. Any context.
use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, AtomicU8, Ordering::Relaxed};

/// The status words. The firmware has one `static` (all zero-initialised, so it sits in .bss and
/// the frame addresses every word from one base); the host simulation has its own.
pub struct Status {
    /// Feed number cap from the adaptive controller; `u32::MAX` = no cap, 0 = hold. Read by the
    /// frame ISR (only in the frames that feed). Zero at reset: init stores `u32::MAX` (or the AC's
    /// first cap) before any interrupt is enabled.
    pub feed_cap: AtomicU32,
    /// Absolute position per axis (X, Y, Z) in BLU, as counted by the frame. Written by the frame
    /// ISR in the frames without pulses (idle, dwell, hold, between feed commands), so the frames
    /// with pulses, the frame's worst case, do not pay for it; read at the end of a program and on
    /// a hold. The live position is `encoder`.
    pub position: [AtomicI32; 3],
    /// Blocks completed since power-up. Written by the frame ISR in the frames without pulses,
    /// like `position`.
    pub blocks_done: AtomicU32,
    /// True when the frame has no block loaded, no pulse computed for a later frame and no pulse
    /// on the pins. Written by the frame ISR.
    pub idle: AtomicBool,
    /// Signs of the pulses computed by the last frame, for the pulse-end ISR to write once the
    /// current pulse has ended (both ISRs share one priority: a plain atomic, no lock).
    pub next_signs: AtomicU8,
    /// Encoder counts per axis in BLU: the pulses the board emitted, counted by the pulse-end ISR
    /// from the pins themselves (+1 / -1 per high PULSE line by its SIGN line) before it lowers
    /// them. One writer (plain load and store); read by the sampler and the AC task.
    pub encoder: [AtomicI32; 3],
    /// Samples taken since start (the sampler's next sample index). Written by the sampler.
    pub samples: AtomicU32,
    /// AC periods the sampler could not start because the previous one had not finished.
    pub ac_missed: AtomicU32,
    /// Samples the sampler could not queue for the AC task (queue full).
    pub samples_dropped: AtomicU32,
}

impl Default for Status {
    fn default() -> Self {
        Self::new()
    }
}

impl Status {
    pub const fn new() -> Self {
        Status {
            feed_cap: AtomicU32::new(0),
            position: [AtomicI32::new(0), AtomicI32::new(0), AtomicI32::new(0)],
            blocks_done: AtomicU32::new(0),
            idle: AtomicBool::new(true),
            next_signs: AtomicU8::new(0),
            encoder: [AtomicI32::new(0), AtomicI32::new(0), AtomicI32::new(0)],
            samples: AtomicU32::new(0),
            ac_missed: AtomicU32::new(0),
            samples_dropped: AtomicU32::new(0),
        }
    }

    /// The encoder counts X, Y, Z.
    pub fn encoder(&self) -> [i32; 3] {
        [0, 1, 2].map(|k| self.encoder[k].load(Relaxed))
    }

    /// The frame's position X, Y, Z as last published.
    pub fn position(&self) -> [i32; 3] {
        [0, 1, 2].map(|k| self.position[k].load(Relaxed))
    }
}
