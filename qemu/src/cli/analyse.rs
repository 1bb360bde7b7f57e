//! `millac-qemu analyse CAPTURE PROGRAM`: a VCD capture (ours or a real logic analyser's) checked
//! against its program, no QEMU (host: the CLI calls it from `main`).
use anyhow::{Context, Result};
use millac::Settings;
use millac_qemu::{analysis, analysis::vcd, emulator::runner};
use std::path::{Path, PathBuf};

/// `analyse`'s arguments.
#[derive(clap::Args)]
pub(crate) struct AnalyseArgs {
    pub(crate) capture: PathBuf,
    pub(crate) program: PathBuf,
}

/// `analyse`: the two files through [`analyse_file`].
pub(crate) fn command(args: AnalyseArgs) -> Result<bool> {
    let AnalyseArgs { capture, program } = args;
    analyse_file(&capture, &program)
}

fn analyse_file(capture: &Path, program: &Path) -> Result<bool> {
    let settings = Settings::default();
    let text = std::fs::read_to_string(program)
        .with_context(|| format!("reading {}", program.display()))?;
    let prog = analysis::load_program(&text, &settings)
        .map_err(|e| anyhow::anyhow!("program rejected: {e}"))?;
    let trace = vcd::read_vcd(&std::fs::read_to_string(capture)?)?;
    let mut report = analysis::analyse(&prog, &settings, trace.initial, &trace.events);
    let e = analysis::edges(trace.initial, &trace.events);
    report.pulses_match_host =
        Some(analysis::compare_with_host(&prog, &settings, &e.groups).is_none());
    let summary = runner::summary_json(&prog, &report);
    println!("{}", serde_json::to_string_pretty(&summary)?);
    Ok(runner::checks_pass(&report))
}
