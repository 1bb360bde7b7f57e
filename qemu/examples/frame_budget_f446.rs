//! Frame ISR budget of the Nucleo-F446RE firmware, measured under QEMU (host): builds its `qemu`
//! feature (netduinoplus2, see `millac_qemu::f446`), streams each program of `frame_budget` over
//! USART2 and prints min / median / max instructions (entry to return, inclusive) of the frame ISR
//! (TIM2, with the DWT reads and the frame counter around the core's body) and of the pulse-end
//! ISR (TIM5). The `qemu` build's pin writes keep the levels in RAM for the read-back as well
//! (one byte store per pin write, see hal/nucleo-f446re/src/board.rs): the real build runs a
//! few instructions fewer.
//!
//! ```text
//! cargo run -p millac-qemu --release --example frame_budget_f446
//! ```
//!
//! Prints the worst cases and, from them, the highest W0 the F446 sustains with the default pulse
//! timing and with 2 us + 2 us (the rule of `Settings::validate_for`, at one cycle per instruction
//! plus 22 cycles of interrupt entry and return at 180 MHz). Fails when a program fails.
use anyhow::{Context, Result};
use millac_qemu::f446;
use millac_qemu::firmware::{build_board, NUCLEO_F446RE_QEMU};
use std::time::Duration;

#[path = "common/programs.rs"]
mod programs;

fn stats(v: &[u64]) -> (u64, u64, u64) {
    if v.is_empty() {
        return (0, 0, 0);
    }
    let mut s = v.to_vec();
    s.sort_unstable();
    (s[0], s[s.len() / 2], s[s.len() - 1])
}

fn main() -> Result<()> {
    let elf = build_board(&NUCLEO_F446RE_QEMU)?;
    let root = std::env::temp_dir().join(format!("millac-f446-budget-{}", std::process::id()));
    let (mut fworst, mut pworst) = (0, 0);
    println!(
        "{:<16} {:>7} {:>5} {:>5} {:>5}   {:>7} {:>5} {:>5} {:>5}",
        "program", "frames", "min", "med", "max", "pulses", "min", "med", "max"
    );
    for (k, (name, program)) in programs::all().into_iter().enumerate() {
        let s = f446::stream(
            &elf,
            &root.join(format!("p{k}")),
            &program,
            4,
            &["TIM2", "TIM5"],
            Duration::from_secs(300),
        )
        .with_context(|| format!("program `{name}`"))?;
        let (f, p) = (&s.capture.handlers[0].1, &s.capture.handlers[1].1);
        let (fmin, fmed, fmax) = stats(f);
        let (pmin, pmed, pmax) = stats(p);
        println!(
            "{name:<16} {:>7} {fmin:>5} {fmed:>5} {fmax:>5}   {:>7} {pmin:>5} {pmed:>5} {pmax:>5}",
            f.len(),
            p.len()
        );
        fworst = fworst.max(fmax);
        pworst = pworst.max(pmax);
    }
    let _ = std::fs::remove_dir_all(&root);
    println!("F446 frame ISR worst case: {fworst} instructions; pulse-end ISR: {pworst}");
    // Times at 180 MHz, one cycle per instruction plus exception entry and return (12 + 10
    // cycles); flash wait states the ART accelerator misses come on top (the board's DWT figure).
    let ns = |insns: u64| (insns + 22) as f64 * 1e3 / 180.0;
    let (f, p) = (ns(fworst), ns(pworst));
    println!("at 180 MHz, 1 cycle per instruction + 22 per interrupt: frame {f:.0} ns, pulse end {p:.0} ns");
    let defaults = millac::Settings::default();
    for (width, setup) in [
        (defaults.pulse_width_ns, defaults.sign_setup_ns),
        (2_000, 2_000),
    ] {
        // Settings::validate_for's rule for a board that states its ISR times: period >=
        // max(width, frame) + pulse end + setup, and both ISRs at most half the CPU.
        let period = (width as f64).max(f) + p + setup as f64;
        let hz = (1e9 / period).min(0.5e9 / (f + p));
        println!(
            "pulse {width} ns + sign setup {setup} ns: highest W0 (and rapid rate) {:.0} Hz",
            hz.floor()
        );
    }
    Ok(())
}
