//! `millac-qemu run PROGRAM`: a G-code program through the firmware under QEMU (host: the CLI
//! calls it from `main`; `demo` runs its program through [`run`] too).
use super::args::{cut_setup, parse_shift, CutArgs};
use super::{reported, with_program};
use anyhow::Result;
use millac_qemu::emulator::runner;
use std::path::{Path, PathBuf};

/// `run`'s options.
#[derive(clap::Args)]
pub(crate) struct RunArgs {
    pub(crate) program: PathBuf,
    #[arg(long, default_value = "out")]
    pub(crate) out: PathBuf,
    /// QEMU -icount shift: one instruction = 2^N ns (4: 62.5 MIPS, close to a 50-72 MHz M3);
    /// 0..=7 (from 8 on the frame overruns its period in rapids).
    #[arg(long, default_value_t = runner::DEFAULT_SHIFT, value_parser = parse_shift)]
    pub(crate) shift: u32,
    /// NC only: no simulated ADC and no adaptive control (the pulses then equal the host core's).
    #[arg(long, conflicts_with_all = ["faults", "strategy"])]
    pub(crate) nc_only: bool,
    #[command(flatten)]
    pub(crate) cut: CutArgs,
}

/// `run`: the program file through [`run`].
pub(crate) fn command(args: RunArgs) -> Result<bool> {
    let RunArgs {
        program,
        out,
        shift,
        nc_only,
        cut,
    } = args;
    with_program(&program, &out, |text| {
        run(text, &out, shift, (!nc_only).then_some(&cut))
    })
}

pub(crate) fn run(text: &str, out: &Path, shift: u32, cut: Option<&CutArgs>) -> Result<bool> {
    let ac = match cut {
        Some(c) => {
            let cut = cut_setup(text, c)?;
            Some(runner::AcRun {
                settings: c.ac_settings(&cut),
                cut,
                ac: !c.no_ac,
                faults: c.faults.clone(),
            })
        }
        None => None,
    };
    let stop = millac_qemu::interrupt::flag();
    // The bar: virtual time against check's estimate (0 for a program the run will refuse).
    let settings = millac::Settings::default();
    let estimate = millac_qemu::analysis::load_program(text, &settings).map_or(0.0, |p| {
        millac_qemu::host::acsim::estimated_time_s(&p, &settings)
    });
    let o = reported(
        out,
        false,
        millac_qemu::progress::with_clock("QEMU run", estimate, || {
            runner::run_until(text, out, shift, ac.as_ref(), Some(stop))
        }),
    )?;
    if o.report.is_some() {
        runner::print_summary(&o.summary, out);
    }
    if !o.ok {
        eprintln!("millac: a check failed, see {}/summary.json", out.display());
    }
    Ok(o.ok)
}
