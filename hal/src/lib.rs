//! millac boards: the board-independent interface of the firmware (the `Board` trait the RTIC app
//! calls from init and from the frame and pulse-end ISRs), the status words the frame ISR publishes
//! for the idle loop, and the loader's line splitter (idle). Board bindings live in their own modules;
//! `simadc` is the QEMU board's lockstep simulated ADC (semihosting FIFOs to the host).
#![no_std]

pub mod actask;
pub mod lm3s6965;
pub mod simadc;
pub mod status;

/// What the RTIC app needs from a board: six pins and two timers. Static dispatch, no state: every
/// function is a handful of register stores.
///
/// Contexts: `init` from `#[init]` only; `frame_*` from the frame ISR; `pulse_*` from the frame ISR
/// (start) and the pulse-end ISR (ack); `write_*` from both ISRs (they share one priority).
pub trait Board {
    /// Clock of the frame and pulse timers in Hz.
    const TIMER_HZ: u32;
    /// Reload value for a period of `clocks` timer clocks (boards differ: some count
    /// `reload + 1` clocks per period). Called in init only.
    fn reload(clocks: u32) -> u32;

    /// Sets up the pins (all low), the periodic frame timer with `frame_reload` and its interrupt
    /// (started), and the one-shot pulse timer with `pulse_reload` (stopped). Init context.
    fn init(frame_reload: u32, pulse_reload: u32);
    /// Acknowledges the frame timer's interrupt. Frame ISR.
    fn frame_ack();
    /// Sets the frame timer's reload value (a value from [`Board::reload`]). Frame ISR.
    fn frame_set_reload(reload: u32);
    /// Starts the one-shot pulse timer (its reload was set in `init`). Frame ISR.
    fn pulse_start();
    /// Acknowledges the pulse timer's interrupt. Pulse-end ISR.
    fn pulse_ack();
    /// One store: PULSE line of axis k = bit k of `steps` (X, Y, Z = bits 0..2). Both ISRs.
    fn write_steps(steps: u8);
    /// One store: SIGN line of axis k = bit k of `signs` (high = positive). Both ISRs.
    fn write_signs(signs: u8);
    /// One load of the pin levels: bit k = PULSE line of axis k, bit k + 3 = its SIGN line.
    /// Pulse-end ISR (the encoder count).
    fn read_pins() -> u8;
}

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
