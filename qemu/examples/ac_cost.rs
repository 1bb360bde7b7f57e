//! The AC period's cost per strategy on the firmware (host, runs QEMU): the Fig. 1 cavity (or
//! PROGRAM) through the firmware under QEMU against the simulated cut, once per feed law
//! (`$251`: paper, integral, mrac), and the instructions of the AC period's dispatcher (SSI0:
//! the AC task at priority 1, entry to return, as `tests/cosim.rs` measures it) per period:
//! min, median, max, and the median's share of the 10 ms period at the board's 50 MHz
//! (500 000 cycles; the Cortex-M3 has no FPU, the laws' f32 work is soft-float).
//!
//! ```text
//! cargo run -p millac-qemu --release --example ac_cost [-- PROGRAM.nc] [--strategy NAME]
//! ```
//!
//! Each run writes its files to `target/ac-cost/NAME` (under CARGO_TARGET_DIR when set).
use anyhow::{Context, Result};
use millac::ac::law::Strategy;
use millac::ac::AcSettings;
use millac::Settings;
use millac_plant::Stock;
use millac_qemu::acsim::Cut;
use millac_qemu::runner;
use std::path::PathBuf;

/// Cycles of one 10 ms AC period at the LM3S6965's 50 MHz.
const PERIOD_CYCLES: f64 = 500_000.0;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut strategies = Strategy::ALL.to_vec();
    let mut program = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--strategy" {
            let name = it.next().context("--strategy needs a name")?;
            strategies = vec![Strategy::from_name(name)
                .with_context(|| format!("--strategy {name}: not paper, integral or mrac"))?];
        } else {
            program = Some(PathBuf::from(a));
        }
    }
    let (name, text) = match &program {
        Some(p) => (
            p.display().to_string(),
            std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?,
        ),
        None => (
            "Fig. 1 cavity".to_string(),
            include_str!("../programs/fig1-cavity.nc").to_string(),
        ),
    };
    let base = std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| PathBuf::from("target"), PathBuf::from)
        .join("ac-cost");
    let mut rows = Vec::new();
    for strategy in strategies {
        let out = base.join(strategy.name());
        let _ = std::fs::remove_dir_all(&out);
        let ac = runner::AcRun {
            cut: Cut::steel(Stock::default(), 1).at_program_rpm(&text, &Settings::default()),
            ac: true,
            faults: Vec::new(),
            settings: AcSettings {
                strategy,
                ..AcSettings::default()
            },
        };
        let o = runner::run_with(&text, &out, 4, Some(&ac))?;
        let cap = o.capture.context("the program was rejected")?;
        let mut v = cap.handlers[3].1.clone();
        anyhow::ensure!(!v.is_empty(), "no AC period ran");
        v.sort_unstable();
        let median = v[v.len() / 2];
        rows.push(format!(
            "| {} | {} | {} | {median} | {} | {:.2} % | {} | {} |",
            strategy.name(),
            v.len(),
            v[0],
            v[v.len() - 1],
            median as f64 / PERIOD_CYCLES * 100.0,
            o.summary["machining_time_s"],
            o.summary["ac"]["holds"],
        ));
    }
    println!();
    println!("AC period instructions under QEMU (SSI0, the AC task), {name}, shift 4");
    println!(
        "| strategy | periods | min | median | max | median / 10 ms at 50 MHz | time s | holds |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    for r in rows {
        println!("{r}");
    }
    Ok(())
}
