//! The LM3S6965 board (the lm3s6965evb that QEMU emulates): pins on GPIO port B, the frame on
//! general-purpose Timer 0 (TIMER_0A, periodic) and the step pulse end on Timer 1 (TIMER_1A,
//! one-shot); the simulated ADC's sample clock on Timer 2 (TIMER_2A, periodic, only when the host
//! serves the ADC). Raw volatile register access: the `lm3s6965` device crate has interrupt names
//! only. [`Lm3s6965`] implements the core's ports (`millac::ports`: StepPort, FrameTimer,
//! PulseTimer, SampleClock) with one register access each (what the board is, `millac::ports::Board`,
//! is in `crate::facts`). `init` runs in `#[init]`;
//! everything else in the frame and pulse-end ISRs (and the sampler).
//!
//! Pins (port B): PB0 X_STEP, PB1 Y_STEP, PB2 Z_STEP, PB3 X_SIGN, PB4 Y_SIGN, PB5 Z_SIGN.
//! Registers (LM3S6965 datasheet): SYSCTL RCGC1/RCGC2 clock gates; GPIO DIR, DEN and the masked
//! data window (address bits [9:2] select the pins a store changes); GPTM CFG, TAMR, CTL, IMR, ICR,
//! TAILR.
use millac::ports::{FrameTimer, PulseTimer, SampleClock, StepPort};

pub use crate::facts::Lm3s6965;

// System control: run-mode clock gating.
const SYSCTL_RCGC1: usize = 0x400F_E104;
const RCGC1_TIMER0: u32 = 1 << 16;
const RCGC1_TIMER1: u32 = 1 << 17;
const RCGC1_TIMER2: u32 = 1 << 18;
const SYSCTL_RCGC2: usize = 0x400F_E108;
const RCGC2_GPIOB: u32 = 1 << 1;

// GPIO port B (APB aperture).
const GPIOB: usize = 0x4000_5000;
const GPIO_DIR: usize = 0x400;
const GPIO_DEN: usize = 0x51C;
/// The six pins we drive: PB0..PB5.
const PINS: u32 = 0b11_1111;
/// PULSE lines PB0..PB2: `steps` bit k is pin k.
const STEP_MASK: usize = 0b00_0111;
/// SIGN lines PB3..PB5: `signs` bit k is pin k + 3.
const SIGN_MASK: usize = 0b11_1000;
const SIGN_SHIFT: u32 = 3;

/// Masked data address: a store there changes only the pins whose bit is set in `mask`.
const fn gpio_data(base: usize, mask: usize) -> usize {
    base + (mask << 2)
}
const STEP_DATA: usize = gpio_data(GPIOB, STEP_MASK);
const SIGN_DATA: usize = gpio_data(GPIOB, SIGN_MASK);
const ALL_DATA: usize = gpio_data(GPIOB, PINS as usize);

// General-purpose timers.
const TIMER0: usize = 0x4003_0000;
const TIMER1: usize = 0x4003_1000;
const TIMER2: usize = 0x4003_2000;
const GPTM_CFG: usize = 0x000; // 0 = one 32-bit timer
const GPTM_TAMR: usize = 0x004; // Timer A mode: 1 = one-shot, 2 = periodic
const GPTM_CTL: usize = 0x00C; // bit 0 TAEN: Timer A enable
const GPTM_IMR: usize = 0x018; // bit 0 TATOIM: Timer A time-out interrupt mask
const GPTM_ICR: usize = 0x024; // bit 0 TATOCINT: write 1 to clear the time-out interrupt
const GPTM_TAILR: usize = 0x028; // Timer A interval load
const CFG_32BIT: u32 = 0;
const TAMR_ONE_SHOT: u32 = 1;
const TAMR_PERIODIC: u32 = 2;
const CTL_TAEN: u32 = 1;
const TATO: u32 = 1;

/// One 32-bit volatile store to a peripheral register (this module's and `uart`'s).
#[inline(always)]
pub(crate) fn write(addr: usize, value: u32) {
    // SAFETY: only called with LM3S6965 register addresses (the constants of this module and of
    // `uart`), all valid, aligned 32-bit device registers; stores to them have no effect on
    // Rust-visible memory.
    unsafe { core::ptr::write_volatile(addr as *mut u32, value) }
}

/// One 32-bit volatile load from a peripheral register (this module's and `uart`'s).
#[inline(always)]
pub(crate) fn read(addr: usize) -> u32 {
    // SAFETY: as for `write`.
    unsafe { core::ptr::read_volatile(addr as *const u32) }
}

/// Sets `bits` in a register (read-modify-write). Init only: not atomic against ISRs.
fn set_bits(addr: usize, bits: u32) {
    write(addr, read(addr) | bits);
}

impl Lm3s6965 {
    /// Sets up the pins (all low), the periodic frame timer with `frame_reload` and its interrupt
    /// (started), and the one-shot pulse timer with `pulse_reload` (stopped). Init context.
    pub fn init(frame_reload: u32, pulse_reload: u32) {
        set_bits(SYSCTL_RCGC1, RCGC1_TIMER0 | RCGC1_TIMER1);
        set_bits(SYSCTL_RCGC2, RCGC2_GPIOB);
        // Silicon needs a few clocks after ungating before the peripheral answers: the read-backs
        // take them.
        let _ = read(SYSCTL_RCGC1);
        let _ = read(SYSCTL_RCGC2);

        // All six lines low, then outputs, digital enable.
        write(ALL_DATA, 0);
        set_bits(GPIOB + GPIO_DIR, PINS);
        set_bits(GPIOB + GPIO_DEN, PINS);

        // Pulse timer: one-shot, not started (the frame starts it with each pulse).
        timer32(TIMER1, TAMR_ONE_SHOT, pulse_reload);

        // Frame timer: periodic, started (the interrupt is taken once init returns and RTIC
        // unmasks it).
        timer32(TIMER0, TAMR_PERIODIC, frame_reload);
        write(TIMER0 + GPTM_CTL, CTL_TAEN);
    }
}

impl FrameTimer for Lm3s6965 {
    #[inline(always)]
    fn ack(&mut self) {
        write(TIMER0 + GPTM_ICR, TATO);
    }

    /// LM3S silicon loads a new TAILR into the running counter at once; QEMU 7.2 keeps the
    /// time-out already scheduled and uses the new value from the following period on.
    #[inline(always)]
    fn set_reload(&mut self, reload: u32) {
        write(TIMER0 + GPTM_TAILR, reload);
    }
}

impl PulseTimer for Lm3s6965 {
    /// A one-shot timer clears TAEN at its time-out, so setting TAEN restarts it from TAILR.
    #[inline(always)]
    fn start(&mut self) {
        write(TIMER1 + GPTM_CTL, CTL_TAEN);
    }

    #[inline(always)]
    fn ack(&mut self) {
        write(TIMER1 + GPTM_ICR, TATO);
    }
}

impl StepPort for Lm3s6965 {
    /// The masked address ignores value bits outside PB0..PB2: no masking needed here.
    #[inline(always)]
    fn write_steps(&mut self, steps: u8) {
        write(STEP_DATA, u32::from(steps));
    }

    /// The masked address ignores value bits outside PB3..PB5.
    #[inline(always)]
    fn write_signs(&mut self, signs: u8) {
        write(SIGN_DATA, u32::from(signs) << SIGN_SHIFT);
    }

    /// A masked read returns the levels of PB0..PB5 only (output pins read their data bits).
    #[inline(always)]
    fn read_pins(&mut self) -> u8 {
        read(ALL_DATA) as u8
    }

    /// PB0..PB2 read back (one load): a PULSE line still high means the pulse end has not run.
    #[inline(always)]
    fn pulse_still_high(&mut self) -> bool {
        read(STEP_DATA) != 0
    }
}

/// Sample timer of the simulated ADC: Timer 2 (TIMER_2A), 32-bit periodic with `reload`, interrupt
/// on time-out, started. Init context (only when the host serves the simulated ADC).
pub fn sample_timer_start(reload: u32) {
    set_bits(SYSCTL_RCGC1, RCGC1_TIMER2);
    let _ = read(SYSCTL_RCGC1);
    timer32(TIMER2, TAMR_PERIODIC, reload);
    write(TIMER2 + GPTM_CTL, CTL_TAEN);
}

/// Sets up the timer at `base`, stopped, as a 32-bit timer in `mode` (`TAMR_ONE_SHOT` or
/// `TAMR_PERIODIC`) of `reload` clocks, with its time-out interrupt on (the frame and pulse
/// timers, the sample clock). Setting `CTL_TAEN` starts it. Init context.
fn timer32(base: usize, mode: u32, reload: u32) {
    write(base + GPTM_CTL, 0);
    write(base + GPTM_CFG, CFG_32BIT);
    write(base + GPTM_TAMR, mode);
    write(base + GPTM_TAILR, reload);
    write(base + GPTM_ICR, TATO);
    write(base + GPTM_IMR, TATO);
}

/// Timer 2, the sample clock of the simulated ADC. Sampler task.
impl SampleClock for Lm3s6965 {
    #[inline(always)]
    fn ack(&mut self) {
        write(TIMER2 + GPTM_ICR, TATO);
    }

    /// Stops the sample timer (the host has gone).
    fn stop(&mut self) {
        write(TIMER2 + GPTM_CTL, 0);
        write(TIMER2 + GPTM_IMR, 0);
        write(TIMER2 + GPTM_ICR, TATO);
    }
}
