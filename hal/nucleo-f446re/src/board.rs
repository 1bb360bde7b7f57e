//! The Nucleo-F446RE board (STM32F446RE, Cortex-M4F at 180 MHz): the core's ports with one register
//! access each, plus the set-up of the peripherals that need exact timing, the clock tree and the
//! pins, and the frame's own measurement. `init`, `clocks`, `pins` and the `*_start` functions run
//! in `#[init]`; the port methods in the frame ISR (TIM2), the pulse-end ISR (TIM5),
//! the sampler (TIM3) and the serial task (USART2), as each item says.
//!
//! # Pins and peripherals
//!
//! | role | pin / peripheral | Nucleo header |
//! | --- | --- | --- |
//! | X, Y, Z PULSE | PC4, PC5, PC6 (push-pull, one BSRR store for all three) | CN10 34, 6, 4 |
//! | X, Y, Z SIGN | PC7, PC8, PC9 (one BSRR store for all three) | CN10 19 (D9), 2, 1 |
//! | frame timer | TIM2, 32-bit, update interrupt at W0 (or the rapid rate) | |
//! | pulse timer | TIM5, 32-bit, one-pulse mode, update interrupt = pulse end | |
//! | sample clock | TIM3, update = sampler interrupt and TRGO = ADC trigger | |
//! | T, Fu, Fv | ADC1 IN0 PA0, ADC2 IN1 PA1, ADC3 IN10 PC0, triple simultaneous, DMA2 stream 0 | A0, A1, A5 |
//! | grbl serial | USART2 PA2 TX, PA3 RX (the ST-LINK virtual COM port), 115200 8N1 | USB |
//! | watchdog | IWDG, ~100 ms (~8 s around a flash sector erase) | |
//! | settings | flash sector 7 (see `flash`) | |
//!
//! Timers TIM2, TIM3 and TIM5 are on APB1: PCLK1 = 45 MHz, timer clock 2 x PCLK1 = 90 MHz
//! ([`TIMER_HZ`]). The PULSE and SIGN lines are written with the GPIO port's bit set/reset
//! register (BSRR): one store sets and clears any mix of pins atomically, so neither ISR needs a
//! read-modify-write of ODR.
//!
//! Registers: RM0390 (STM32F446 reference manual), as raw volatile accesses at the addresses
//! below: the frame path is one store per port call, with no proxy that the compiler might not
//! inline (the no-call check of CI scans the built ISRs).
use millac::ports::{
    Codes, Conversion, ForceTorqueAdc, FrameTimer, PulseTimer, SampleClock, StepPort,
};

pub use crate::facts::{CORE_HZ, F446, PCLK1_HZ, TIMER_HZ};

use core::sync::atomic::{AtomicU32, Ordering::Relaxed};
use cortex_m::peripheral::{DCB, DWT};
use millac::ports::PinInputs;
use millac::rt::status::{CycleWriter, Static};
use stm32f4xx_hal::gpio::{AnyPin, Input, Output};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::rcc::Rcc;

// GPIO port C (AHB1).
const GPIOC: usize = 0x4002_0800;
const GPIO_MODER: usize = 0x00;
const GPIO_OSPEEDR: usize = 0x08;
#[cfg_attr(feature = "qemu", allow(dead_code))]
const GPIO_ODR: usize = 0x14;
const GPIO_BSRR: usize = 0x18;
/// First PULSE pin (PC4); the SIGN pins follow (PC7..PC9).
const STEP_SHIFT: u32 = 4;
const SIGN_SHIFT: u32 = 7;
/// The six pins PC4..PC9.
const PINS: u32 = 0b11_1111 << STEP_SHIFT;

// RCC (AHB1).
const RCC: usize = 0x4002_3800;
const RCC_AHB1ENR: usize = RCC + 0x30;
const RCC_APB1ENR: usize = RCC + 0x40;
const RCC_APB2ENR: usize = RCC + 0x44;
const RCC_CSR: usize = RCC + 0x74;
const AHB1_GPIOA: u32 = 1 << 0;
const AHB1_GPIOC: u32 = 1 << 2;
const AHB1_DMA2: u32 = 1 << 22;
const APB1_TIM2: u32 = 1 << 0;
const APB1_TIM3: u32 = 1 << 1;
const APB1_TIM5: u32 = 1 << 3;
const APB1_USART2: u32 = 1 << 17;
const APB2_ADC123: u32 = 0b111 << 8;
const CSR_RMVF: u32 = 1 << 24;
const CSR_IWDGRSTF: u32 = 1 << 29;

// General-purpose timers (APB1).
const TIM2: usize = 0x4000_0000;
const TIM3: usize = 0x4000_0400;
const TIM5: usize = 0x4000_0C00;
const TIM_CR1: usize = 0x00;
const TIM_CR2: usize = 0x04;
const TIM_DIER: usize = 0x0C;
const TIM_SR: usize = 0x10;
const TIM_EGR: usize = 0x14;
const TIM_CNT: usize = 0x24;
const TIM_PSC: usize = 0x28;
const TIM_ARR: usize = 0x2C;
const CR1_CEN: u32 = 1 << 0;
const CR1_URS: u32 = 1 << 2;
const CR1_OPM: u32 = 1 << 3;
const CR1_ARPE: u32 = 1 << 7;
/// CR2 MMS = 010: the update event is the trigger output (TRGO).
const CR2_MMS_UPDATE: u32 = 0b010 << 4;
const DIER_UIE: u32 = 1;
const EGR_UG: u32 = 1;

// USART2 (APB1).
const USART2: usize = 0x4000_4400;
const US_SR: usize = 0x00;
const US_DR: usize = 0x04;
const US_BRR: usize = 0x08;
const US_CR1: usize = 0x0C;
const SR_ORE: u32 = 1 << 3;
const SR_RXNE: u32 = 1 << 5;
const SR_TXE: u32 = 1 << 7;
const CR1_UE: u32 = 1 << 13;
const CR1_TXEIE: u32 = 1 << 7;
const CR1_RXNEIE: u32 = 1 << 5;
const CR1_TE: u32 = 1 << 3;
const CR1_RE: u32 = 1 << 2;

// ADC1/2/3 and their common registers (APB2).
const ADC1: usize = 0x4001_2000;
const ADC2: usize = 0x4001_2100;
const ADC3: usize = 0x4001_2200;
const ADC_SR: usize = 0x00;
const ADC_CR2: usize = 0x08;
const ADC_SMPR1: usize = 0x0C;
const ADC_SMPR2: usize = 0x10;
const ADC_SQR1: usize = 0x2C;
const ADC_SQR3: usize = 0x34;
const ADC_CCR: usize = 0x4001_2304;
const ADC_CDR: usize = 0x4001_2308;
const ADC_SR_OVR: u32 = 1 << 5;
const CR2_ADON: u32 = 1 << 0;
/// EXTSEL = 1000: TIM3 TRGO; EXTEN = 01: rising edge.
const CR2_TRIGGER_TIM3: u32 = (0b1000 << 24) | (0b01 << 28);
/// CCR: MULTI = 10110 (triple, regular simultaneous only), DMA mode 1 (one half-word per request,
/// ADC1, ADC2, ADC3 in turn), DDS (requests go on after each transfer), ADCPRE = /4 (22.5 MHz).
const CCR_TRIPLE: u32 = 0b10110 | (0b01 << 14) | (1 << 13) | (0b01 << 16);
/// Sample time 144 ADC clocks (6.4 us at 22.5 MHz): room for an amplifier's output impedance.
const SMP_144: u32 = 0b110;

// DMA2 stream 0, channel 0 (ADC1).
const DMA2: usize = 0x4002_6400;
const DMA_LISR: usize = DMA2;
const DMA_LIFCR: usize = DMA2 + 0x08;
const S0CR: usize = DMA2 + 0x10;
const S0NDTR: usize = DMA2 + 0x14;
const S0PAR: usize = DMA2 + 0x18;
const S0M0AR: usize = DMA2 + 0x1C;
/// Stream 0 flags in LISR/LIFCR: FEIF0, DMEIF0, TEIF0, HTIF0, TCIF0.
const S0_FLAGS: u32 = 0b11_1101;
const S0_TCIF: u32 = 1 << 5;
const S0_HTIF: u32 = 1 << 4;
const S0_TEIF: u32 = 1 << 3;
/// Peripheral to memory, circular, memory increment, half-words both sides, high priority.
const S0CR_ADC: u32 = (1 << 8) | (1 << 10) | (0b01 << 11) | (0b01 << 13) | (0b10 << 16);
const DMA_EN: u32 = 1;

// Independent watchdog.
const IWDG_KR: usize = 0x4000_3000;
const IWDG_PR: usize = 0x4000_3004;
const IWDG_RLR: usize = 0x4000_3008;
const IWDG_SR: usize = 0x4000_300C;
const KR_START: u32 = 0xCCCC;
const KR_FEED: u32 = 0xAAAA;
const KR_UNLOCK: u32 = 0x5555;

/// One 32-bit volatile store to a peripheral register of this module.
#[inline(always)]
fn write(addr: usize, value: u32) {
    // SAFETY: only called with the STM32F446 register addresses of this module, all valid,
    // aligned 32-bit device registers; stores to them do not touch Rust-visible memory (the DMA
    // target is the `ADC_CODES` static, which Rust reads only through volatile loads).
    unsafe { core::ptr::write_volatile(addr as *mut u32, value) }
}

/// One 32-bit volatile load from a peripheral register of this module.
#[inline(always)]
fn read(addr: usize) -> u32 {
    // SAFETY: as for `write`.
    unsafe { core::ptr::read_volatile(addr as *const u32) }
}

/// Sets `bits` in a register (read-modify-write). Init only: not atomic against ISRs.
fn set_bits(addr: usize, bits: u32) {
    write(addr, read(addr) | bits);
}

impl F446 {
    /// Sets up the six lines (low, push-pull outputs, high speed), the frame timer TIM2 (periodic
    /// with `frame_reload`, update interrupt, started) and the pulse timer TIM5 (one-pulse with
    /// `pulse_reload`, update interrupt, stopped). The clock tree is already at 180 MHz (the
    /// HAL's `freeze`). Init context, before the interrupts are unmasked.
    pub fn init(frame_reload: u32, pulse_reload: u32) {
        set_bits(RCC_AHB1ENR, AHB1_GPIOA | AHB1_GPIOC | AHB1_DMA2);
        set_bits(RCC_APB1ENR, APB1_TIM2 | APB1_TIM3 | APB1_TIM5 | APB1_USART2);
        set_bits(RCC_APB2ENR, APB2_ADC123);
        // The clock gates take two bus clocks: the read-back waits for them.
        let _ = read(RCC_APB2ENR);

        // PC4..PC9: low, then output mode (01) and fast speed (10) for each.
        write(GPIOC + GPIO_BSRR, PINS << 16);
        let mut moder = read(GPIOC + GPIO_MODER);
        let mut speed = read(GPIOC + GPIO_OSPEEDR);
        for pin in STEP_SHIFT..SIGN_SHIFT + 3 {
            moder = (moder & !(0b11 << (2 * pin))) | (0b01 << (2 * pin));
            // 10 = fast speed (up to 50 MHz at 3.3 V): edges of a few ns, plenty for step lines.
            speed = (speed & !(0b11 << (2 * pin))) | (0b10 << (2 * pin));
        }
        write(GPIOC + GPIO_OSPEEDR, speed);
        write(GPIOC + GPIO_MODER, moder);

        // Pulse timer: one-pulse mode, only a counter overflow sets UIF (URS), stopped. The UG
        // event loads ARR and PSC; its UIF is cleared before the interrupt is enabled.
        write(TIM5 + TIM_CR1, CR1_OPM | CR1_URS);
        write(TIM5 + TIM_PSC, 0);
        write(TIM5 + TIM_ARR, pulse_reload);
        write(TIM5 + TIM_EGR, EGR_UG);
        write(TIM5 + TIM_SR, 0);
        write(TIM5 + TIM_CNT, 0);
        write(TIM5 + TIM_DIER, DIER_UIE);

        // Frame timer: periodic, ARR preloaded (a new period starts at the next update, as on
        // the QEMU board), update interrupt, started.
        write(TIM2 + TIM_CR1, CR1_ARPE | CR1_URS);
        write(TIM2 + TIM_PSC, 0);
        write(TIM2 + TIM_ARR, frame_reload);
        write(TIM2 + TIM_EGR, EGR_UG);
        write(TIM2 + TIM_SR, 0);
        write(TIM2 + TIM_DIER, DIER_UIE);
        write(TIM2 + TIM_CR1, CR1_ARPE | CR1_URS | CR1_CEN);
    }

    /// The reset was caused by the independent watchdog (read once at init; the flags are then
    /// cleared so the next reset reports its own cause). Init context.
    pub fn watchdog_reset() -> bool {
        let csr = read(RCC_CSR);
        write(RCC_CSR, csr | CSR_RMVF);
        csr & CSR_IWDGRSTF != 0
    }

    /// Starts the independent watchdog: LSI (~32 kHz) / 32, reload 100: ~100 ms (70..190 ms over
    /// the LSI's tolerance). Once started it cannot be stopped; a reset brings every pin back to
    /// its reset state (input, floating), so the drives see no pulses and the spindle enable
    /// line falls to its pull-down. Init context.
    pub fn watchdog_start() {
        write(IWDG_KR, KR_START);
        write(IWDG_KR, KR_UNLOCK);
        write(IWDG_PR, 0b011);
        write(IWDG_RLR, 100);
        write(IWDG_KR, KR_FEED);
    }

    /// Stretches the watchdog to ~8 s (LSI / 64, reload 4095) around a flash sector erase, which
    /// stalls every fetch from flash for 1-2 s, and brings it back to ~100 ms after. Loader task
    /// (the settings store), only while the machine stands.
    ///
    /// The sampler feeds the watchdog (KR = 0xAAAA) at any time, and any KR write other than the
    /// unlock key ends the unlock: the unlock and the two writes run with interrupts off (a few
    /// cycles), after any earlier update has reached the LSI domain. Returns whether the new
    /// values took (read back once the update is done): a caller about to erase must not
    /// erase with the short timeout.
    pub fn watchdog_stretch(long: bool) -> bool {
        let (pr, rlr) = if long { (0b100, 0xFFF) } else { (0b011, 100) };
        // Values reach the LSI domain within a few LSI clocks (SR PVU, RVU clear).
        while read(IWDG_SR) != 0 {}
        cortex_m::interrupt::free(|_| {
            write(IWDG_KR, KR_UNLOCK);
            write(IWDG_PR, pr);
            write(IWDG_RLR, rlr);
        });
        while read(IWDG_SR) != 0 {}
        write(IWDG_KR, KR_FEED);
        read(IWDG_PR) & 0b111 == pr && read(IWDG_RLR) & 0xFFF == rlr
    }

    /// Pauses (true) or resumes the frame interrupt by its update interrupt enable, around a
    /// flash operation while the machine stands: a pending update runs when it resumes. Loader
    /// task.
    pub fn frame_pause(pause: bool) {
        write(TIM2 + TIM_DIER, if pause { 0 } else { DIER_UIE });
    }

    /// Feeds the watchdog. Sampler task (only while the frame runs).
    #[inline(always)]
    pub fn watchdog_feed() {
        write(IWDG_KR, KR_FEED);
    }
}

impl FrameTimer for F446 {
    #[inline(always)]
    fn ack(&mut self) {
        write(TIM2 + TIM_SR, 0);
    }

    /// ARR is preloaded: the new period starts at the next update event.
    #[inline(always)]
    fn set_reload(&mut self, reload: u32) {
        write(TIM2 + TIM_ARR, reload);
    }
}

impl PulseTimer for F446 {
    /// One-pulse mode clears CEN at the overflow and leaves CNT at 0: setting CEN starts a new
    /// pulse width.
    ///
    /// Under QEMU (feature `qemu`): QEMU 7.2's stm32f2xx timer ignores OPM, its CNT counts on
    /// past ARR, and after the first pulse it raised no more update interrupts (measured), so the
    /// start pends TIM5 itself: the pulse-end ISR runs right after the frame (zero pulse width,
    /// the same code and pin writes).
    #[inline(always)]
    fn start(&mut self) {
        write(TIM5 + TIM_CR1, CR1_OPM | CR1_URS | CR1_CEN);
        #[cfg(feature = "qemu")]
        cortex_m::peripheral::NVIC::pend(stm32f4xx_hal::pac::Interrupt::TIM5);
    }

    /// Under QEMU (feature `qemu`) the ack also clears CEN, as one-pulse mode does at the
    /// overflow on the board (so QEMU's timer raises nothing of its own).
    #[inline(always)]
    fn ack(&mut self) {
        write(TIM5 + TIM_SR, 0);
        #[cfg(feature = "qemu")]
        write(TIM5 + TIM_CR1, CR1_OPM | CR1_URS);
    }
}

impl StepPort for F446 {
    /// One BSRR store: the set half raises the PULSE lines in `steps`, the reset half lowers the
    /// others (of the three).
    #[inline(always)]
    fn write_steps(&mut self, steps: u8) {
        let s = u32::from(steps) & 0b111;
        write(
            GPIOC + GPIO_BSRR,
            (s << STEP_SHIFT) | ((!s & 0b111) << (STEP_SHIFT + 16)),
        );
        #[cfg(feature = "qemu")]
        PINS_WRITTEN[0].store(s as u8, Relaxed);
    }

    /// One BSRR store for the three SIGN lines.
    #[inline(always)]
    fn write_signs(&mut self, signs: u8) {
        let s = u32::from(signs) & 0b111;
        write(
            GPIOC + GPIO_BSRR,
            (s << SIGN_SHIFT) | ((!s & 0b111) << (SIGN_SHIFT + 16)),
        );
        #[cfg(feature = "qemu")]
        PINS_WRITTEN[1].store(s as u8, Relaxed);
    }

    /// The output data register: PULSE lines in bits 0..2, SIGN lines in bits 3..5.
    #[inline(always)]
    fn read_pins(&mut self) -> u8 {
        #[cfg(feature = "qemu")]
        return PINS_WRITTEN[0].load(Relaxed) | (PINS_WRITTEN[1].load(Relaxed) << 3);
        #[cfg(not(feature = "qemu"))]
        return ((read(GPIOC + GPIO_ODR) >> STEP_SHIFT) & 0b11_1111) as u8;
    }
}

/// Under QEMU (feature `qemu`): the PULSE and SIGN levels last written (netduinoplus2 models no
/// GPIO: the BSRR stores are dropped and ODR reads 0), read back by `read_pins`. One byte store
/// per pin write and two loads per read-back more than the real build.
#[cfg(feature = "qemu")]
static PINS_WRITTEN: [core::sync::atomic::AtomicU8; 2] = [
    core::sync::atomic::AtomicU8::new(0),
    core::sync::atomic::AtomicU8::new(0),
];

/// The DMA target of the triple ADC, two halves used in turn (ping-pong): [T, Fu, Fv] of one
/// conversion each (ADC1, ADC2, ADC3). The sampler reads the half the DMA completed last while the
/// DMA fills the other, so a late sampler never reads a half being written.
struct Codes6(core::cell::UnsafeCell<[u16; 6]>);

// SAFETY: written only by the DMA, read only by the sampler task through volatile loads.
unsafe impl Sync for Codes6 {}

static ADC_CODES: Codes6 = Codes6(core::cell::UnsafeCell::new([0; 6]));

/// Starts the sample clock TIM3 at `sample_reload + 1` microseconds and the triple ADC it
/// triggers: ADC1 converts T on PA0 (IN0), ADC2 Fu on PA1 (IN1), ADC3 Fv on PC0 (IN10), all three
/// at the same instant (regular simultaneous mode), and DMA2 stream 0 moves the three results
/// into one half of [`ADC_CODES`] after every conversion (the halves in turn). The TIM3
/// update interrupt is the sampler: it reads the conversion its previous update started (one
/// sample period of delay). Init context.
pub fn sample_start(sample_reload: u32) {
    // Analog mode (11) on PA0, PA1 and PC0.
    set_bits(0x4002_0000 + GPIO_MODER, 0b1111);
    set_bits(GPIOC + GPIO_MODER, 0b11);

    // One conversion of one channel on each converter.
    for (adc, ch) in [(ADC1, 0u32), (ADC2, 1), (ADC3, 10)] {
        write(adc + ADC_SQR1, 0);
        write(adc + ADC_SQR3, ch);
        if ch < 10 {
            write(adc + ADC_SMPR2, SMP_144 << (3 * ch));
        } else {
            write(adc + ADC_SMPR1, SMP_144 << (3 * (ch - 10)));
        }
    }
    write(ADC_CCR, CCR_TRIPLE);

    // DMA: ADC_CDR (one half-word per request) into the two halves of six codes, circular.
    write(S0CR, 0);
    write(DMA_LIFCR, S0_FLAGS);
    write(S0PAR, ADC_CDR as u32);
    write(S0M0AR, ADC_CODES.0.get() as u32);
    write(S0NDTR, 6);
    write(S0CR, S0CR_ADC);
    write(S0CR, S0CR_ADC | DMA_EN);

    // ADC1 is the master: it takes the trigger; all three are on. The converters need t_STAB
    // (3 us) after ADON before a conversion is valid: the timer starts after ~5 us.
    write(ADC2 + ADC_CR2, CR2_ADON);
    write(ADC3 + ADC_CR2, CR2_ADON);
    write(ADC1 + ADC_CR2, CR2_ADON | CR2_TRIGGER_TIM3);
    cortex_m::asm::delay(CORE_HZ / 200_000);

    // TIM3: 1 MHz count, update every sample_reload + 1 counts, update as TRGO, interrupt.
    write(TIM3 + TIM_CR1, CR1_URS);
    write(TIM3 + TIM_CR2, CR2_MMS_UPDATE);
    write(TIM3 + TIM_PSC, TIMER_HZ / 1_000_000 - 1);
    write(TIM3 + TIM_ARR, sample_reload);
    write(TIM3 + TIM_EGR, EGR_UG);
    write(TIM3 + TIM_SR, 0);
    write(TIM3 + TIM_DIER, DIER_UIE);
    write(TIM3 + TIM_CR1, CR1_URS | CR1_CEN);
}

/// TIM3 reload for a sample rate (1 MHz count): 1e6 / hz - 1. Init context.
pub fn sample_reload(hz: u32) -> u32 {
    (1_000_000 / hz.max(1)).saturating_sub(1).clamp(1, 0xFFFF)
}

/// TIM3, the sample clock. Sampler task.
impl SampleClock for F446 {
    #[inline(always)]
    fn ack(&mut self) {
        write(TIM3 + TIM_SR, 0);
    }

    fn stop(&mut self) {
        write(TIM3 + TIM_CR1, 0);
        write(TIM3 + TIM_DIER, 0);
        write(TIM3 + TIM_SR, 0);
    }
}

/// The triple ADC as the sampler reads it: which half of the ping-pong buffer it read last.
/// Sampler task.
pub struct TripleAdc {
    last_half: Option<usize>,
}

impl TripleAdc {
    pub const fn new() -> Self {
        TripleAdc { last_half: None }
    }
}

impl ForceTorqueAdc for TripleAdc {
    /// The codes of the last completed conversion (the one the previous sample tick started):
    /// `Fresh` when the DMA has completed a half (HTIF or TCIF) since the last call and it is not
    /// the half read last time, `Missed` otherwise (no conversion, an overrun, a DMA error: the
    /// AC period that sees no fresh sample holds). NDTR is read before the flags: while the DMA
    /// writes one half (NDTR 6..4: the first, 3..1: the second) the other is the complete one; a
    /// conversion that completes between the two reads leaves its flag for the next call, which
    /// then finds the half it names already read and reports a miss rather than the same codes
    /// twice. An overrun or a transfer error re-arms the ADC and the stream, so a single fault
    /// costs one sample. The encoder is not needed by a real converter.
    fn sample(&mut self, _index: u32, _encoder: [i32; 3]) -> Conversion {
        let first = if read(S0NDTR) > 3 { 3 } else { 0 };
        let flags = read(DMA_LISR);
        write(DMA_LIFCR, flags & S0_FLAGS);
        let overrun = [ADC1, ADC2, ADC3]
            .iter()
            .any(|adc| read(adc + ADC_SR) & ADC_SR_OVR != 0);
        if overrun || flags & S0_TEIF != 0 {
            rearm();
            self.last_half = None;
            return Conversion::Missed;
        }
        if flags & (S0_TCIF | S0_HTIF) == 0 || self.last_half == Some(first) {
            return Conversion::Missed;
        }
        self.last_half = Some(first);
        let p = ADC_CODES.0.get() as *const u16;
        // SAFETY: `p + first .. p + first + 3` is one half of ADC_CODES (first is 0 or 3); the DMA
        // completed it and writes the other half now (a conversion every sample period).
        let codes: Codes = unsafe {
            [
                core::ptr::read_volatile(p.add(first)),
                core::ptr::read_volatile(p.add(first + 1)),
                core::ptr::read_volatile(p.add(first + 2)),
            ]
        };
        Conversion::Fresh(codes.map(|c| c & 0x0FFF))
    }
}

/// After an overrun or a DMA error: stream off, flags and OVR cleared, six transfers again.
fn rearm() {
    write(S0CR, S0CR_ADC);
    while read(S0CR) & DMA_EN != 0 {}
    write(DMA_LIFCR, S0_FLAGS);
    // Multi-ADC DMA mode off and on again restarts its request sequence at ADC1 (RM0390, overrun
    // in multi-ADC mode), so the codes land in the order T, Fu, Fv again.
    write(ADC_CCR, CCR_TRIPLE & !(0b11 << 14));
    for adc in [ADC1, ADC2, ADC3] {
        write(adc + ADC_SR, 0);
    }
    write(ADC_CCR, CCR_TRIPLE);
    write(S0NDTR, 6);
    write(S0CR, S0CR_ADC | DMA_EN);
}

/// USART2 at 115200 8N1 on PA2/PA3 (AF7), receive interrupt on (the transmit interrupt is on
/// while bytes wait). Loader context, before the banner.
pub fn usart2_start() {
    // PA2, PA3: alternate function 7.
    let gpioa = 0x4002_0000;
    let moder = read(gpioa + GPIO_MODER) & !(0b1111 << 4);
    write(gpioa + GPIO_MODER, moder | (0b1010 << 4));
    let afrl = read(gpioa + 0x20) & !(0xFF << 8);
    write(gpioa + 0x20, afrl | (0x77 << 8));
    write(USART2 + US_CR1, 0);
    // Oversampling by 16: BRR = PCLK1 / baud as 12.4 fixed point, rounded.
    write(USART2 + US_BRR, (PCLK1_HZ + 115_200 / 2) / 115_200);
    write(USART2 + US_CR1, CR1_UE | CR1_TE | CR1_RE | CR1_RXNEIE);
}

/// The USART2 interrupt: every received byte into the protocol's ring; an overrun (ORE: a byte
/// arrived while DR still held the previous one, e.g. while a flash operation stalled this
/// interrupt) is reported as a lost byte after the byte DR holds (reading SR then DR clears it),
/// so the loader raises the overflow alarm instead of parsing a broken line. Then one queued byte
/// out if the transmitter is empty; the transmit interrupt stays on only while bytes wait.
/// Serial task.
#[inline(always)]
pub fn usart2_interrupt<const N: usize>(
    tx: &mut heapless::spsc::Consumer<'static, u8, N>,
    rx: &mut millac::protocol::rx::RxIsr<'static>,
) {
    let mut sr = read(USART2 + US_SR);
    while sr & (SR_RXNE | SR_ORE) != 0 {
        let b = read(USART2 + US_DR) as u8;
        if sr & SR_RXNE != 0 {
            let _ = rx.push_byte(b);
        }
        if sr & SR_ORE != 0 {
            rx.lost_bytes(1);
        }
        sr = read(USART2 + US_SR);
    }
    if sr & SR_TXE != 0 {
        if let Some(b) = tx.dequeue() {
            write(USART2 + US_DR, u32::from(b));
        }
    }
    let cr1 = read(USART2 + US_CR1);
    if tx.ready() {
        write(USART2 + US_CR1, cr1 | CR1_TXEIE);
    } else {
        write(USART2 + US_CR1, cr1 & !CR1_TXEIE);
    }
}

/// Under QEMU (feature `qemu`): the transmit interrupt is enabled (bytes wait). QEMU 7.2's
/// stm32f2xx USART sends a DR store at once and keeps TXE set, but raises no interrupt for
/// TXEIE: the serial task pends itself while this holds. Serial task.
#[cfg(feature = "qemu")]
#[inline(always)]
pub fn usart2_txe_wanted() -> bool {
    read(USART2 + US_CR1) & CR1_TXEIE != 0
}

// Spindle PWM: TIM4 channel 1 on PB6 (AF2), 1 kHz.
const GPIOB: usize = 0x4002_0400;
const TIM4: usize = 0x4000_0800;
const APB1_TIM4: u32 = 1 << 2;
const AHB1_GPIOB: u32 = 1 << 1;
const TIM_CCMR1: usize = 0x18;
const TIM_CCER: usize = 0x20;
const TIM_CCR1: usize = 0x34;
/// PWM period in 1 MHz counts (1 kHz).
const PWM_PERIOD: u32 = 1000;

/// Starts the spindle PWM on PB6 (TIM4 CH1, PWM mode 1, preloaded, duty 0). Init context.
pub fn spindle_pwm_start() {
    set_bits(RCC_AHB1ENR, AHB1_GPIOB);
    set_bits(RCC_APB1ENR, APB1_TIM4);
    let _ = read(RCC_APB1ENR);
    let moder = read(GPIOB + GPIO_MODER) & !(0b11 << 12);
    write(GPIOB + GPIO_MODER, moder | (0b10 << 12));
    let afrl = read(GPIOB + 0x20) & !(0xF << 24);
    write(GPIOB + 0x20, afrl | (2 << 24));
    write(TIM4 + TIM_PSC, TIMER_HZ / 1_000_000 - 1);
    write(TIM4 + TIM_ARR, PWM_PERIOD - 1);
    write(TIM4 + TIM_CCR1, 0);
    // OC1M = 110 (PWM mode 1), OC1PE (preload).
    write(TIM4 + TIM_CCMR1, (0b110 << 4) | (1 << 3));
    write(TIM4 + TIM_CCER, 1);
    write(TIM4 + TIM_EGR, EGR_UG);
    write(TIM4 + TIM_CR1, CR1_ARPE | CR1_CEN);
}

/// The spindle PWM duty for `rpm` of `max_rpm` (full duty at and above it). Loader task.
pub fn spindle_duty(rpm: u32, max_rpm: u32) -> u32 {
    let d = u64::from(rpm) * u64::from(PWM_PERIOD) / u64::from(max_rpm.max(1));
    d.min(u64::from(PWM_PERIOD)) as u32
}

/// Sets the PWM compare value (from [`spindle_duty`]). Loader task.
pub fn spindle_pwm_set(duty: u32) {
    write(TIM4 + TIM_CCR1, duty.min(PWM_PERIOD));
}

/// Frames since reset (the sampler feeds the watchdog only while it grows). Written by the frame
/// wrapper ([`FrameCycles::measure`]).
static FRAMES: AtomicU32 = AtomicU32::new(0);

/// Frames since reset. Sampler task.
pub fn frames() -> u32 {
    FRAMES.load(Relaxed)
}

/// The frame's own measurement with the DWT cycle counter: cycles from the first instruction of
/// the handler to its last (the exception entry and return, 12 + ~10 cycles on a Cortex-M4 with
/// zero wait states, come on top), min and max since reset, published for the status report.
pub struct FrameCycles {
    min: u32,
    max: u32,
    /// The frame wrapper's handle on the status words.
    status: CycleWriter<Static>,
}

impl FrameCycles {
    /// Starts the cycle counter. Init.
    pub fn new(dcb: &mut DCB, dwt: &mut DWT, status: CycleWriter<Static>) -> Self {
        dcb.enable_trace();
        dwt.enable_cycle_counter();
        FrameCycles {
            min: u32::MAX,
            max: 0,
            status,
        }
    }

    /// Runs `frame` (the frame ISR's body), counts it and measures it. Frame ISR.
    #[inline(always)]
    pub fn measure(&mut self, frame: impl FnOnce()) {
        let t0 = DWT::cycle_count();
        frame();
        FRAMES.store(FRAMES.load(Relaxed).wrapping_add(1), Relaxed);
        let dt = DWT::cycle_count().wrapping_sub(t0);
        if dt < self.min {
            self.min = dt;
            self.status.set_min(dt);
        }
        if dt > self.max {
            self.max = dt;
            self.status.set_max(dt);
        }
    }
}

/// The clock tree: 180 MHz from the ST-LINK's 8 MHz (HSE bypass), APB1 at [`PCLK1_HZ`] (its timers
/// at [`TIMER_HZ`]), checked. Under QEMU (the netduinoplus2 has no RCC model: it reads 0, and
/// `freeze` would wait for HSE ready for ever) the reset clocks; its timers count at their own
/// fixed clock. Init.
pub fn clocks(rcc: pac::RCC) -> Rcc {
    #[cfg(not(feature = "qemu"))]
    {
        use stm32f4xx_hal::prelude::*;
        let rcc = rcc.freeze(
            stm32f4xx_hal::rcc::Config::hse(8.MHz())
                .bypass_hse_oscillator()
                .sysclk(CORE_HZ.Hz())
                .pclk1(PCLK1_HZ.Hz())
                .pclk2(90.MHz()),
        );
        let c = rcc.clocks;
        if c.sysclk().raw() != CORE_HZ || c.timclk1().raw() != TIMER_HZ {
            defmt::panic!(
                "clock tree: sysclk {} Hz, APB1 timers {} Hz",
                c.sysclk().raw(),
                c.timclk1().raw()
            );
        }
        rcc
    }
    #[cfg(feature = "qemu")]
    {
        use stm32f4xx_hal::rcc::RccExt;
        rcc.constrain()
    }
}

/// The operator input pins (embedded-hal input pins with pull-ups).
pub type InputPins = PinInputs<AnyPin<Input>>;
/// The spindle's enable and direction pins.
pub type SpindlePins = (AnyPin<Output>, AnyPin<Output>);

/// The operator inputs (pull-ups, switches to ground): PB12 e-stop (normally closed), PB13 feed
/// hold, PB14 cycle start, PB15 / PB1 / PB2 X / Y / Z limit, PB0 probe; the spindle's PA8 enable and PA9
/// direction (high = M4) outputs, and its PWM on PB6 (TIM4 CH1) started. Init.
pub fn pins(gpioa: pac::GPIOA, gpiob: pac::GPIOB, rcc: &mut Rcc) -> (InputPins, SpindlePins) {
    use stm32f4xx_hal::gpio::GpioExt;
    let (gpioa, gpiob) = (gpioa.split(rcc), gpiob.split(rcc));
    let inputs = PinInputs {
        estop: gpiob.pb12.into_pull_up_input().erase(),
        feed_hold: gpiob.pb13.into_pull_up_input().erase(),
        cycle_start: gpiob.pb14.into_pull_up_input().erase(),
        limits: [
            gpiob.pb15.into_pull_up_input().erase(),
            gpiob.pb1.into_pull_up_input().erase(),
            gpiob.pb2.into_pull_up_input().erase(),
        ],
        probe: gpiob.pb0.into_pull_up_input().erase(),
    };
    let spindle = (
        gpioa.pa8.into_push_pull_output().erase(),
        gpioa.pa9.into_push_pull_output().erase(),
    );
    spindle_pwm_start();
    (inputs, spindle)
}
