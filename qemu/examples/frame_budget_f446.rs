//! Frame ISR budget of the Nucleo-F446RE firmware, measured under QEMU (host): builds its `qemu`
//! feature (netduinoplus2, see `millac_qemu::emulator::f446`), streams each program of `frame_budget` over
//! USART2 (queued under a hold before it runs, `StreamOptions::queue_first`: the blocks meet as
//! in the QEMU board's file, whatever the host's load) and prints min / median / max instructions (entry to return, inclusive) of the frame ISR
//! (TIM2, with the DWT reads and the frame counter around the core's body) and of the pulse-end
//! ISR (TIM5). The `qemu` build's pin writes keep the levels in RAM for the read-back as well
//! (one byte store per pin write, see hal/nucleo-f446re/src/board.rs): the real build runs a
//! few instructions fewer.
//!
//! ```text
//! cargo run -p millac-qemu --release --example frame_budget_f446
//! ```
//!
//! (or `... -- ELF` to measure an ELF built elsewhere, e.g. of another commit: its `qemu` build).
//! `FRAME_BUDGET_ONLY=NAME` runs the programs whose name contains NAME; `FRAME_BUDGET_TRACE=N`
//! prints the PCs of every frame longer than N instructions (as `frame_budget` does).
//!
//! Prints the worst cases against the instruction bounds the board's stated ISR times come from
//! (`millac_qemu::f446_facts::ISR_BOUNDS`), and the highest W0 the F446 sustains with the default
//! pulse timing and with 2 us + 2 us: with the stated times (`f446_facts::LIMITS`, the
//! firmware's validation) and with the measured counts at the same cycles per instruction. Fails
//! when a program fails or a count exceeds its bound.
use anyhow::{Context, Result};
use millac_qemu::emulator::f446;
use millac_qemu::emulator::firmware::{build_board, NUCLEO_F446RE_QEMU};
use std::time::Duration;

#[path = "common/programs.rs"]
mod programs;

fn main() -> Result<()> {
    let elf = match std::env::args_os().nth(1) {
        Some(elf) => std::path::PathBuf::from(elf),
        None => build_board(&NUCLEO_F446RE_QEMU)?,
    };
    let root = std::env::temp_dir().join(format!("millac-f446-budget-{}", std::process::id()));
    let (mut fworst, mut pworst) = (0, 0);
    programs::print_header();
    for (k, (name, program)) in programs::all().into_iter().enumerate() {
        let opts = f446::StreamOptions {
            trace: programs::trace_option(),
            queue_first: true,
            ..f446::StreamOptions::new(&["TIM2", "TIM5"], Duration::from_secs(300))
        };
        let s = f446::stream_with(&elf, &root.join(format!("p{k}")), &program, &opts)
            .with_context(|| format!("program `{name}`"))?;
        let (f, p) = (&s.capture.handlers[0].1, &s.capture.handlers[1].1);
        let (fmax, pmax) = programs::print_row(name, f, p);
        programs::print_worst(
            &program,
            f,
            &s.capture.handler_starts[0],
            &s.capture.pins,
            &s.capture.traces,
        );
        fworst = fworst.max(fmax);
        pworst = pworst.max(pmax);
    }
    let _ = std::fs::remove_dir_all(&root);
    println!("F446 frame ISR worst case: {fworst} instructions; pulse-end ISR: {pworst}");
    let bounds = millac_qemu::f446_facts::ISR_BOUNDS;
    println!(
        "bounds: frame {} instructions, pulse end {}, at {}.{} cycles per instruction + {} per \
         interrupt at {} MHz",
        bounds.frame_instructions,
        bounds.pulse_end_instructions,
        bounds.cpi_x10 / 10,
        bounds.cpi_x10 % 10,
        bounds.entry_exit_cycles,
        bounds.core_hz / 1_000_000
    );
    let stated = millac_qemu::f446_facts::LIMITS;
    let measured = millac::settings::BoardLimits {
        frame_work_ns: bounds.ns(fworst as u32),
        pulse_end_ns: bounds.ns(pworst as u32),
        ..stated
    };
    let defaults = millac::Settings::default();
    for (width, setup) in [
        (defaults.pulse_width_ns, defaults.sign_setup_ns),
        (2_000, 2_000),
    ] {
        println!(
            "pulse {width} ns + sign setup {setup} ns: highest W0 (= rapid rate) {} Hz stated \
             (frame {} ns, pulse end {} ns), {} Hz with the measured counts ({} ns, {} ns)",
            stated.highest_rate_hz(width, setup),
            stated.frame_work_ns,
            stated.pulse_end_ns,
            measured.highest_rate_hz(width, setup),
            measured.frame_work_ns,
            measured.pulse_end_ns
        );
    }
    anyhow::ensure!(
        fworst <= u64::from(bounds.frame_instructions)
            && pworst <= u64::from(bounds.pulse_end_instructions),
        "an ISR count exceeds its bound: raise ISR_BOUNDS in hal/nucleo-f446re/src/facts.rs (and the figures of docs/dev/results-nc.md)"
    );
    Ok(())
}
