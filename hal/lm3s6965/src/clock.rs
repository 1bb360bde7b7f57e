//! The clock of the LM3S6965 timers as QEMU's lm3s6965evb runs them (init, where the reloads are
//! computed; the host simulation includes this file too, `millac_qemu::lm3s_clock`, so the board
//! and its host model share one definition).
use millac::ports::TimerClock;

/// 12.5 MHz after reset; a period of TAILR clocks, where silicon counts TAILR + 1.
pub struct QemuClock;

impl TimerClock for QemuClock {
    const TIMER_HZ: u32 = 12_500_000;

    fn reload(clocks: u32) -> u32 {
        clocks.max(1)
    }
}
