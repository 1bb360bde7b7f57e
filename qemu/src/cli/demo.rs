//! `millac-qemu demo` (and `millac-qemu` with no arguments): the paper's Fig. 1 cavity through the
//! firmware under QEMU (host: the CLI calls it from `main`).
use super::args::{CutArgs, DriveArg};
use super::run::run;
use super::DEMO;
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

fn demo(out: &Path, cut: &CutArgs) -> Result<bool> {
    println!(
        "millac demo: roughing the cavity of Fig. 1 (Tlusty, Koren, McNeil) through the firmware under QEMU, {}",
        match (cut.no_ac, cut.strategy) {
            (true, _) => "adaptive control off (--no-ac)".to_string(),
            (false, None) => "with adaptive control".to_string(),
            (false, Some(_)) => format!(
                "with adaptive control (strategy {})",
                cut.strategy.map_or(millac::ac::AcSettings::default().strategy, Into::into).name()
            ),
        }
    );
    run(DEMO, out, runner::DEFAULT_SHIFT, Some(cut))
}
