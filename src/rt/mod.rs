//! Run-time bodies of the firmware, written once over the [`crate::ports`] and called by a thin
//! RTIC app per board (hal/) and by the host simulation: the frame ISR and the pulse-end ISR
//! ([`isr`]), the sampler and the AC period ([`ac`]), the loader ([`loader`]) with its consoles ([`console`]: a serial line, [`program`]: a program file), the status
//! words between the contexts ([`status`]), and the timer arithmetic of init ([`clocks_for_hz`],
//! [`clocks_for_ns`]) for a board's clock (`ports::Board`).
//!
//! Contexts: [`isr::FrameTask::run`] frame ISR; [`isr::pulse_end`] pulse-end ISR; [`ac::sample`]
//! sampler; [`ac::AcPeriod::run`] AC task; the clock
//! functions init (they divide); [`status::Status`] any.

pub mod ac;
pub mod actask;
pub mod console;
pub mod homing;
pub mod isr;
pub mod loader;
pub mod monitor;
pub mod program;
pub mod replan;
pub mod start;
pub mod status;
#[cfg(test)]
mod tests;
pub mod toolchange;

pub use isr::{pulse_end, FrameTask, Reloads};
pub use status::Status;

/// Timer clocks in `ns` nanoseconds, rounded UP (a pulse is never shorter than asked), at least 1.
/// Init context (divides).
pub const fn clocks_for_ns(timer_hz: u32, ns: u32) -> u32 {
    let c = (timer_hz as u64 * ns as u64).div_ceil(1_000_000_000);
    clamp_clocks(c)
}

/// Timer clocks of one period of `rate_hz`, rounded to the nearest clock, at least 1.
/// `rate_hz` must be non-zero (validated settings). Init context (divides).
pub const fn clocks_for_hz(timer_hz: u32, rate_hz: u32) -> u32 {
    let r = if rate_hz == 0 { 1 } else { rate_hz as u64 };
    clamp_clocks((timer_hz as u64 + r / 2) / r)
}

const fn clamp_clocks(c: u64) -> u32 {
    if c == 0 {
        1
    } else if c > u32::MAX as u64 {
        u32::MAX
    } else {
        c as u32
    }
}
