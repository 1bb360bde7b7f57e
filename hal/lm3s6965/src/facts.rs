//! What the QEMU board is (`millac::ports::Board`; init, where the reloads are computed and the
//! settings validated, and the loader): the LM3S6965 timers as QEMU's lm3s6965evb runs them, the
//! generic limits, a simulated spindle. The host simulation includes this file too
//! (`millac_qemu::lm3s_facts`), so the board and its host model share one definition.
use millac::ports::Board;
use millac::settings::{BoardLimits, IsrBounds};

/// The board. Zero-sized: all state is in the peripherals (its ports are in `board.rs`).
pub struct Lm3s6965;

impl Board for Lm3s6965 {
    /// 12.5 MHz after reset.
    const TIMER_HZ: u32 = 12_500_000;

    /// A period of TAILR clocks (silicon counts TAILR + 1).
    fn reload(clocks: u32) -> u32 {
        clocks.max(1)
    }

    /// QEMU states no measured ISR times: the generic limits and their 75 % rule.
    const LIMITS: BoardLimits = BoardLimits::GENERIC;
    const ISR_BOUNDS: Option<IsrBounds> = None;
    /// A simulated one: the S of a spindle change reaches the simulated cut through the ADC's
    /// requests (`crate::loader::spindle_rpm`).
    const SPINDLE: bool = true;
}
