//! What the Nucleo-F446RE is (`millac::ports::Board`; init, where the reloads are computed and
//! the settings validated, and the loader; the host tools include this file too,
//! `millac_qemu::f446_facts`, for the CI's checks and the budget benchmark): its clocks, its ISR
//! bounds and the limits derived from them, its spindle. Board facts live with the board; the
//! core knows only the shapes (`millac::ports::Board`, `millac::settings::{BoardLimits,
//! IsrBounds}`).
use millac::ports::Board;
use millac::settings::{BoardLimits, IsrBounds};

/// The board. Zero-sized: all state is in the peripherals (its ports are in `board.rs`).
pub struct F446;

/// Core clock (SYSCLK = HCLK) in Hz.
pub const CORE_HZ: u32 = ISR_BOUNDS.core_hz;
/// PCLK1 (USART2) in Hz.
pub const PCLK1_HZ: u32 = 45_000_000;
/// APB1 timer clock (TIM2, TIM3, TIM5) in Hz.
pub const TIMER_HZ: u32 = 2 * PCLK1_HZ;

impl Board for F446 {
    const TIMER_HZ: u32 = TIMER_HZ;

    /// TIM2, TIM3, TIM5 count ARR + 1 clocks per period.
    fn reload(clocks: u32) -> u32 {
        clocks.saturating_sub(1).max(1)
    }

    /// See [`LIMITS`] (docs/dev/results-nc.md, "Speed on the Nucleo-F446RE").
    const LIMITS: BoardLimits = LIMITS;
    const ISR_BOUNDS: Option<IsrBounds> = Some(ISR_BOUNDS);
    /// Enable, direction and PWM outputs (`board.rs`).
    const SPINDLE: bool = true;
}

/// The Nucleo-F446RE's ISR bounds (see `IsrBounds`): instruction counts measured under QEMU
/// (`frame_budget_f446`), a cycles-per-instruction bound, the exception entry and return.
pub const ISR_BOUNDS: IsrBounds = IsrBounds {
    core_hz: 180_000_000,
    frame_instructions: 220,
    pulse_end_instructions: 60,
    cpi_x10: 15,
    entry_exit_cycles: 24,
};

/// The Nucleo-F446RE (STM32F446RE at 180 MHz): ISR times from [`ISR_BOUNDS`]. With them it
/// sustains W0 = rapid rate up to 192 kHz with 2 us pulses and 2 us sign setup (the two ISRs'
/// share of the CPU binds; `BoardLimits::highest_rate_hz`), 94 kHz with the default 5 us + 5 us
/// (the sign setup gap binds). Not 200 kHz: the frame's worst case (a line that decelerates into
/// the next one) is 215 instructions, and 200 kHz allows at most 207.
pub const LIMITS: BoardLimits = BoardLimits {
    max_frame_hz: 250_000,
    max_rapid_hz: 250_000,
    frame_work_ns: ISR_BOUNDS.ns(ISR_BOUNDS.frame_instructions),
    pulse_end_ns: ISR_BOUNDS.ns(ISR_BOUNDS.pulse_end_instructions),
    // The plan ratio's load and multiply (and the layout they move) make its frame 220
    // instructions (215 without): the whole bound above, no margin left.
    plan_ratio: false,
};

#[cfg(test)]
mod tests {
    use super::*;

    /// The F446's stated times follow from its bounds ((instructions x 1.5 + 24) cycles at
    /// 180 MHz, rounded up to the ns), and its highest rate with 2 us pulses and 2 us sign setup
    /// is where the two ISRs take half the CPU.
    #[test]
    fn the_f446_rates_follow_from_its_bounds() {
        let b = LIMITS;
        let ns = |instructions: u32| {
            ((instructions as u64 * 15 + 240) * 100_000_000).div_ceil(180_000_000) as u32
        };
        assert_eq!(b.frame_work_ns, ns(ISR_BOUNDS.frame_instructions));
        assert_eq!(b.pulse_end_ns, ns(ISR_BOUNDS.pulse_end_instructions));
        let r = b.highest_rate_hz(2_000, 2_000);
        // The ISR share binds: (frame + pulse end) x r <= half a second, one Hz more is over.
        let both = (b.frame_work_ns + b.pulse_end_ns) as u64;
        assert!(both * r as u64 <= 500_000_000, "{r} Hz");
        assert!(both * (r as u64 + 1) > 500_000_000, "{r} Hz");
        // The default pulse times (5 + 5 us) bind by the gap instead.
        let r5 = b.highest_rate_hz(5_000, 5_000);
        assert_eq!(
            r5 as u64,
            1_000_000_000 / (5_000 + b.pulse_end_ns as u64 + 5_000)
        );
    }

    /// A board that leaves the plan ratio out of its frame refuses `$263=2` and keeps what it
    /// had (the Nucleo's frame budget has no room for it).
    #[test]
    fn the_nucleo_refuses_the_plan_ratio() {
        use millac::protocol::table::{parse_assignment, Invalid, MachineSettings, SetError};
        let mut f = MachineSettings::default();
        let before = f.ac.ceiling;
        let (n, v) = parse_assignment("$263=2").unwrap();
        let e = f.set(n, v, &LIMITS).unwrap_err();
        assert_eq!(e, SetError::Invalid(Invalid::PlanNotOnThisBoard));
        assert_eq!(e.code(), 52);
        assert_eq!(f.ac.ceiling, before);
    }
}
