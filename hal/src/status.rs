//! Single-word channels between the contexts: the frame ISR publishes its status here after every
//! frame (position, blocks done, idle) and reads the feed cap; the idle loop (loader) reads the
//! status; the adaptive-control task (later) writes the feed cap. Relaxed atomics are enough: one
//! core, and every word is meaningful on its own.
use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, AtomicU8};

/// Feed number cap from the adaptive controller; `u32::MAX` = no cap. Read by the frame ISR.
pub static FEED_CAP: AtomicU32 = AtomicU32::new(u32::MAX);

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
