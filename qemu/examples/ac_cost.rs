//! The AC period's cost per strategy on the firmware (host, runs QEMU): the Fig. 1 cavity (or
//! PROGRAM) through the firmware under QEMU against the simulated cut, once per feed law
//! (`$251`: paper, integral, mrac), and the instructions of the AC period's dispatcher (SSI0:
//! the AC task at priority 1, entry to return, as `tests/cosim.rs` measures it) per period:
//! min, median, max, and the median's share of the 10 ms period at the board's 50 MHz
//! (500 000 cycles; the Cortex-M3 has no FPU, the laws' f32 work is soft-float).
//!
//! With `--monitors`, instead, the process monitors' cost beside the AC's (issue 10): the AC
//! period (SSI0, now with the breakage detector's per-sample work) and the chatter monitor's task
//! (I2C0, below the AC: a record's FFT, counted with everything that preempts it) on the breakage
//! slot (`$268=1`, sound and broken tooth) and the thesis' table 3.2 cut (`$266`, 2.54 and 8.89 mm).
//!
//! ```text
//! cargo run -p millac-qemu --release --example ac_cost [-- PROGRAM.nc] [--strategy NAME]
//! cargo run -p millac-qemu --release --example ac_cost -- --monitors
//! ```
//!
//! Each run writes its files to `target/ac-cost/NAME` (under CARGO_TARGET_DIR when set).
use anyhow::{Context, Result};
use millac::ac::law::Strategy;
use millac::ac::AcSettings;
use millac::Settings;
use millac_plant::Stock;
use millac_qemu::emulator::runner;
use millac_qemu::host::acsim::Cut;
use std::path::PathBuf;

/// Cycles of one 10 ms AC period at the LM3S6965's 50 MHz.
const PERIOD_CYCLES: f64 = 500_000.0;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut strategies = Strategy::ALL.to_vec();
    let mut program = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--monitors" {
            return monitors();
        }
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

/// min / median / max of `v` (instructions per run of a handler).
fn spread(v: &[u64]) -> (u64, u64, u64) {
    let mut v = v.to_vec();
    v.sort_unstable();
    match (v.first(), v.last()) {
        (Some(&lo), Some(&hi)) => (lo, v[v.len() / 2], hi),
        _ => (0, 0, 0),
    }
}

/// The process monitors' cost under QEMU (see the module docs).
fn monitors() -> Result<()> {
    use millac_plant::chatter::thesis_table_3_2 as t;
    use millac_qemu::{analysis, evaluation::breaklab, evaluation::chatterlab};
    let base = std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| PathBuf::from("target"), PathBuf::from)
        .join("ac-cost");
    let breakage = AcSettings {
        breakage: millac::ac::Breakage::On,
        ..AcSettings::default()
    };
    // The chatter threshold by the thesis' rule: twice the largest amplitude of the 2.54 mm cut.
    let s = Settings::default();
    let listen = AcSettings {
        flutes: t::FLUTES,
        monitor_rpm: t::RPM as u32,
        ..AcSettings::default()
    };
    let (text, cut) = chatterlab::preset_slot(0.1, 2.0);
    let prog = analysis::load_program(&text, &s).map_err(|e| anyhow::anyhow!("{e}"))?;
    let chatter = AcSettings {
        chatter_threshold: chatterlab::thesis_threshold(&prog, &s, &cut, listen)?,
        ..listen
    };
    let runs = [
        (
            "AC alone (monitors off), sound tool",
            breaklab::SLOT.to_string(),
            breaklab::slot_cut(None),
            AcSettings::default(),
        ),
        (
            "breakage on, sound tool",
            breaklab::SLOT.to_string(),
            breaklab::slot_cut(None),
            breakage,
        ),
        (
            "breakage on, tooth 1 broken at 6 s",
            breaklab::SLOT.to_string(),
            breaklab::slot_cut(Some(6.0)),
            breakage,
        ),
        (
            "chatter on, table 3.2 at 2.54 mm",
            chatterlab::preset_slot(0.1, 0.8).0,
            chatterlab::preset_slot(0.1, 0.8).1,
            chatter,
        ),
        (
            "chatter on, table 3.2 at 8.89 mm",
            chatterlab::preset_slot(0.35, 2.0).0,
            chatterlab::preset_slot(0.35, 2.0).1,
            chatter,
        ),
    ];
    let mut rows = Vec::new();
    for (k, (name, text, cut, acs)) in runs.into_iter().enumerate() {
        let out = base.join(format!("monitors-{k}"));
        let _ = std::fs::remove_dir_all(&out);
        let ac = runner::AcRun {
            cut,
            ac: true,
            faults: Vec::new(),
            settings: acs,
        };
        let o = runner::run_with(&text, &out, 4, Some(&ac))?;
        let cap = o.capture.context("the program was rejected")?;
        let (a0, a1, a2) = spread(&cap.handlers[3].1);
        let (m0, m1, m2) = spread(&cap.handlers[4].1);
        let overruns = o.ac_log.last().map_or(0, |r| r.overruns);
        let hold = o
            .ac_log
            .iter()
            .find_map(|r| r.hold.clone().map(|h| format!("{} ms: {h}", r.t_ms)))
            .unwrap_or_else(|| "none".into());
        rows.push(format!(
            "| {name} | {} | {a0} | {a1} | {a2} | {:.1} % | {m0} | {m1} | {m2} | {overruns} | {hold} |",
            o.ac_log.len(),
            a2 as f64 / PERIOD_CYCLES * 100.0,
        ));
    }
    println!();
    println!("Process monitors under QEMU (shift 4): AC period (SSI0) and chatter monitor task (I2C0) instructions");
    println!("| run | periods | AC min | AC median | AC max | AC max / 10 ms at 50 MHz | chatter task min | median | max | overruns | first hold |");
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |");
    for r in rows {
        println!("{r}");
    }
    Ok(())
}
