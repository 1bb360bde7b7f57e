//! `millac-qemu demo` (and `millac-qemu` with no arguments): the paper's whole Fig. 1 job through
//! the firmware under QEMU, generated from the cavity's geometry (`millac_qemu::evaluation::job`):
//! drill, roughing end mill, corner end mill, ball end mill, each with its own limits (host: the
//! CLI calls it from `main`).
use super::args::{CutArgs, DriveArg};
use super::run::run;
use anyhow::Result;
use millac_qemu::emulator::runner;
use std::path::{Path, PathBuf};

/// `demo`'s options.
#[derive(clap::Args)]
pub(crate) struct DemoArgs {
    #[arg(long, default_value = "out/demo")]
    pub(crate) out: PathBuf,
    #[command(flatten)]
    pub(crate) cut: CutArgs,
}

/// `demo`: its options through [`demo`].
pub(crate) fn command(args: DemoArgs) -> Result<bool> {
    let DemoArgs { out, cut } = args;
    demo(&out, &cut)
}

/// No subcommand: the demo with every option at its default.
pub(crate) fn bare() -> Result<bool> {
    demo(
        Path::new("out/demo"),
        &CutArgs {
            no_ac: false,
            seed: 1,
            stock: None,
            tools: None,
            stock_text: None,
            tools_text: None,
            faults: Vec::new(),
            strategy: None,
            drive: DriveArg::Stepper,
            ks_exponent: 0.0,
            break_tooth: Vec::new(),
            chip_tooth: Vec::new(),
            runout: None,
            preset: None,
            monitor_breakage: false,
            chatter_threshold: None,
        },
    )
}

/// The demo: the job's program with its blank and tool table (unless `--stock` or `--tools` give
/// others), through [`run`]; the job's three files are written beside the run's report.
fn demo(out: &Path, cut: &CutArgs) -> Result<bool> {
    println!(
        "millac demo: the whole die-sinking job of Fig. 1 (Tlusty, Koren, McNeil) through the firmware under QEMU: slot drill, roughing end mill, corner end mill, ball end mill, {}",
        match (cut.no_ac, cut.strategy) {
            (true, _) => "adaptive control off (--no-ac)".to_string(),
            (false, None) => "with adaptive control".to_string(),
            (false, Some(_)) => format!(
                "with adaptive control (strategy {})",
                cut.strategy.map_or(millac::ac::AcSettings::default().strategy, Into::into).name()
            ),
        }
    );
    let (j, cut) = super::demo_job(cut);
    let ok = run(&j.program, out, runner::DEFAULT_SHIFT, Some(&cut))?;
    if out.is_dir() {
        j.write(out)?;
        println!(
            "  the job: {}/fig1-job.nc, fig1-job.tools, fig1-job.stock (millac-qemu job writes them too)",
            out.display()
        );
    }
    Ok(ok)
}
