//! Single-word channels between the contexts: the frame ISR publishes its status here after every
//! frame (position, blocks done, idle) and reads the feed cap; the idle loop (loader) reads the
//! status; the adaptive-control task writes the feed cap; the pulse-end ISR counts the encoder.
//! Relaxed atomics are enough: one core, and every word is meaningful on its own.
use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, AtomicU8};

/// Feed number cap from the adaptive controller; `u32::MAX` = no cap, 0 = hold. Read by the frame
/// ISR (only in the frames that feed). Zero-initialised (so it sits in .bss, merged with the other
/// status words the frame addresses): `init` stores `u32::MAX` (or the AC's first cap) before any
/// interrupt is enabled.
pub static FEED_CAP: AtomicU32 = AtomicU32::new(0);

/// Absolute position per axis (X, Y, Z) in BLU, as counted by the frame. Written by the frame ISR.
pub static POSITION: [AtomicI32; 3] = [AtomicI32::new(0), AtomicI32::new(0), AtomicI32::new(0)];

/// Blocks completed since power-up. Written by the frame ISR.
pub static BLOCKS_DONE: AtomicU32 = AtomicU32::new(0);

/// True when the frame has no block loaded, no pulse computed for a later frame and no pulse on the
/// pins (the frame that published it emitted none, and an earlier pulse ended before it ran).
/// Written by the frame ISR.
pub static IDLE: AtomicBool = AtomicBool::new(true);

/// Signs of the pulses computed by the last frame, for the pulse-end ISR to write once the current
/// pulse has ended. Written by the frame ISR, read by the pulse-end ISR; both run at the same
/// priority, so a plain atomic (no RTIC shared resource, no BASEPRI lock) is enough.
pub static NEXT_SIGNS: AtomicU8 = AtomicU8::new(0);

/// Encoder counts per axis (X, Y, Z) in BLU: the pulses the board emitted, counted by the
/// pulse-end ISR from the pins themselves (+1 / -1 per high PULSE line by its SIGN line) before it
/// lowers them. Written by the pulse-end ISR only (plain load + store, one writer), read by the
/// simulated-ADC sampler and the AC task.
pub static ENCODER: [AtomicI32; 3] = [AtomicI32::new(0), AtomicI32::new(0), AtomicI32::new(0)];

/// Samples taken by the simulated-ADC sampler since start (its next sample index). Written by the
/// sampler, read by the AC task (its overrun check).
pub static SAMPLES: AtomicU32 = AtomicU32::new(0);

/// AC periods the sampler could not start because the previous one had not finished (a missed
/// deadline). Written by the sampler, read by the AC task (logged in the overrun count).
pub static AC_MISSED: AtomicU32 = AtomicU32::new(0);

/// Samples the sampler could not queue for the AC task (queue full). Written by the sampler.
pub static SAMPLES_DROPPED: AtomicU32 = AtomicU32::new(0);
