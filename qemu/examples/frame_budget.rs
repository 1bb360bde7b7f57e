//! Frame ISR budget benchmark: runs the firmware under QEMU on one small program per block type and
//! prints min / median / max instructions (entry to return, inclusive) of the frame ISR (TIMER_0A)
//! and of the pulse-end ISR (TIMER_1A). Budget: the frame ISR takes fewer than 200 instructions
//! (150 before chained lines, 179 before the acceleration ramps and the operator's word: the frame
//! that ends a line and starts the next one is the worst case, see docs/dev/results-nc.md).
//!
//! It builds nothing: build the firmware first, then pass the ELF:
//!
//! ```text
//! cargo fw
//! cargo run -p millac-qemu --release --example frame_budget -- \
//!     target/thumbv7m-none-eabi/firmware/millac-lm3s6965
//! ```
//!
//! (with `CARGO_TARGET_DIR` set, the ELF is under that directory). Each program's row is followed
//! by where its worst frame was: its index, virtual time and the program line whose end it is in
//! or near. `FRAME_BUDGET_DETAIL=1` also lists the frames over budget and the counts around the
//! worst one; `FRAME_BUDGET_TRACE=N` prints the PCs of every frame longer than N instructions
//! (`addr2line -e ELF` names them); `FRAME_BUDGET_ONLY=NAME` runs the programs whose name
//! contains NAME. Exits with status 1 when a program fails or the frame ISR exceeds the budget.
use anyhow::{bail, ensure, Context, Result};
use millac_qemu::emulator::capture::{run_capture, Capture, CaptureSpec, HandlerSpec};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Frame ISR budget in instructions (the worst case must stay below it).
const BUDGET: u64 = 199;

#[path = "common/programs.rs"]
mod programs;

fn run(elf: &Path, dir: &Path, program: &str, handlers: &[HandlerSpec]) -> Result<Capture> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(dir.join("program.nc"), program)?;
    let mut spec = CaptureSpec::new(elf, dir);
    spec.handlers = handlers.to_vec();
    spec.trace = programs::trace_option();
    spec.timeout = Duration::from_secs(300);
    let cap = run_capture(&spec)?;
    ensure!(
        cap.status == Some(0),
        "firmware exit status {:?}: {}\nlog:\n{}",
        cap.status,
        cap.result,
        cap.stdout
    );
    Ok(cap)
}

fn main() -> Result<()> {
    let Some(elf) = std::env::args_os().nth(1).map(PathBuf::from) else {
        bail!("usage: frame_budget FIRMWARE_ELF (build it with `cargo fw`)");
    };
    let handlers = vec![
        HandlerSpec::from_elf(&elf, "TIMER_0A")?,
        HandlerSpec::from_elf(&elf, "TIMER_1A")?,
    ];
    let root = std::env::temp_dir().join(format!("millac-frame-budget-{}", std::process::id()));
    let mut worst = 0;
    programs::print_header();
    for (k, (name, program)) in programs::all().into_iter().enumerate() {
        let dir = root.join(format!("p{k}"));
        let cap =
            run(&elf, &dir, &program, &handlers).with_context(|| format!("program `{name}`"))?;
        let (f, p) = (&cap.handlers[0].1, &cap.handlers[1].1);
        let (fmax, _) = programs::print_row(name, f, p);
        programs::print_worst(&program, f, &cap.handler_starts[0], &cap.pins, &cap.traces);
        worst = worst.max(fmax);
        if std::env::var_os("FRAME_BUDGET_DETAIL").is_some() {
            // The frames over budget: instruction count, how often, and the counts around the first.
            let mut over: Vec<(u64, usize)> = Vec::new();
            for &n in f.iter().filter(|&&n| n > BUDGET) {
                match over.iter_mut().find(|(m, _)| *m == n) {
                    Some(o) => o.1 += 1,
                    None => over.push((n, 1)),
                }
            }
            over.sort_unstable();
            println!("  over budget (count x times): {over:?}");
            if let Some(i) = f.iter().position(|&n| n == fmax) {
                println!(
                    "  around the max: {:?}",
                    &f[i.saturating_sub(4)..(i + 4).min(f.len())]
                );
            }
        }
    }
    let _ = std::fs::remove_dir_all(&root);
    println!("frame ISR worst case: {worst} instructions (budget {BUDGET})");
    if worst > BUDGET {
        std::process::exit(1);
    }
    Ok(())
}
