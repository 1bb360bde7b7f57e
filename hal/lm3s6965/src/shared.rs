//! What the app's contexts share outside RTIC's resources (all contexts: the ISRs, the tasks, the
//! loader): the serial-mode flag and the block queue's sizes (the status words are the core's
//! `millac::rt::status::STATUS`).
use core::sync::atomic::AtomicBool;

/// The loader runs in serial mode: an operator can resume an AC hold, so a long hold does not end
/// the session. Written once by the loader.
pub static SERIAL: AtomicBool = AtomicBool::new(false);

/// Queue slots (a heapless spsc queue holds one less: 15 blocks).
pub const QUEUE: usize = 16;
/// The loader's record of queued blocks: the queue and room for nested chatter detours.
pub const RECORD: usize = millac::rt::replan::record_len(QUEUE);
