//! The host tool's command line (host: `main` parses it and runs the subcommand): [`Cli`] and
//! [`Cmd`], one module per subcommand with its options and its body, [`args`] the options several
//! share, and here what several subcommands' bodies share (the demo program, the program file,
//! the report of a failure).
pub(crate) mod analyse;
pub(crate) mod args;
pub(crate) mod calibrate;
pub(crate) mod check;
pub(crate) mod demo;
pub(crate) mod host;
pub(crate) mod job;
pub(crate) mod optimise;
pub(crate) mod run;
pub(crate) mod serve;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use millac_qemu::emulator::runner;
use std::path::Path;

/// The demo: the whole Fig. 1 job (`millac_qemu::evaluation::job`), its program and `cut` with
/// the job's blank and tool table (unless `--stock` or `--tools` gave others).
pub(crate) fn demo_job(cut: &args::CutArgs) -> (millac_qemu::evaluation::job::Job, args::CutArgs) {
    let j = millac_qemu::evaluation::job::fig1();
    let cut = args::CutArgs {
        stock_text: Some(j.stock.clone()),
        tools_text: Some(j.tools.clone()),
        ..cut.clone()
    };
    (j, cut)
}

#[derive(Parser)]
#[command(
    name = "millac",
    about = "millac NC firmware under QEMU with a virtual logic analyser"
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub(crate) cmd: Option<Cmd>,
    /// No progress bars (they show only on a terminal anyway).
    #[arg(long, global = true)]
    pub(crate) quiet: bool,
}

#[derive(Subcommand)]
pub(crate) enum Cmd {
    /// Run a G-code program through the firmware; writes DIR/capture.vcd and DIR/summary.json.
    Run(run::RunArgs),
    /// Run the demo (the default with no arguments).
    Demo(demo::DemoArgs),
    /// Run a program with adaptive control natively on the host (no QEMU) against the simulated cut:
    /// DIR/ac.csv, DIR/ac.svg and the side-by-side table. Fast experiments and benchmarks.
    Host(host::HostArgs),
    /// Check a VCD capture against a program (no QEMU); writes a summary to stdout.
    Analyse(analyse::AnalyseArgs),
    /// Validate a program without running it (no QEMU): blocks, bounding box, end point, feeds,
    /// the estimated time, and every refused line with its number; `--json` for one object.
    /// Exits 1 when a line is refused.
    Check(check::CheckArgs),
    /// Optimise a program's feeds offline by virtual machining (no QEMU, no sensor): split its
    /// feed blocks where the cut changes and give each piece the largest feed that keeps the
    /// simulated force within F0 and the torque within T0. Writes OUT (G-code with a header
    /// saying what was done), OUT.csv (the pieces) and OUT.svg (the feed before and after along
    /// the path), and prints the simulated times and peak forces of both programs.
    Optimise(optimise::OptimiseArgs),
    /// Fit Georgiev and Chetrokov's quadratic force model y(a, f) from test cuts on the
    /// simulated plant (full slots at each depth and feed); writes the model file (JSON: the
    /// coefficients, the validity range and the test cuts) for `optimise --model`.
    Calibrate(calibrate::CalibrateArgs),
    /// Run the firmware in serial mode with its UART on a TCP port for a G-code sender, until
    /// SIGINT or SIGTERM; then write DIR/capture.vcd and DIR/summary.json.
    Serve(serve::ServeArgs),
    /// Write the whole die-sinking job of Fig. 1, generated from the cavity's geometry: DIR/
    /// fig1-job.nc (drill, roughing end mill, corner end mill, ball end mill, an M6 between
    /// them), DIR/fig1-job.tools (their $T lines, for --tools) and DIR/fig1-job.stock (--stock).
    Job(job::JobArgs),
}

/// The report of a command that failed once it had begun to write into its folder (a failure
/// of its options writes nothing): `out/summary.json` with `completed` false and `error`
/// {`message`} (no `line`: not a program's rejection), so no earlier run's summary is left to
/// be taken for this one. When it cannot be written, the error carries [`Unreported`]: `main`
/// says in one line which file and why. A folder that holds `serve`'s settings is not a run's
/// folder: `run` refuses it and nothing is written there.
pub(crate) fn reported<T>(out: &Path, serve: bool, r: Result<T>) -> Result<T> {
    let Err(e) = r else { return r };
    let path = out.join("summary.json");
    if !serve && std::fs::symlink_metadata(out.join(millac_qemu::lm3s_files::SETTINGS_NAME)).is_ok()
    {
        return Err(e);
    }
    let summary = serde_json::json!({
        "completed": false,
        "error": {"message": format!("{e:#}")},
    });
    let written = std::fs::create_dir_all(out)
        .with_context(|| format!("creating {}", out.display()))
        .and_then(|()| runner::write_json(&path, &summary));
    match written {
        Ok(()) => Err(e),
        Err(w) => Err(anyhow::Error::new(Unreported {
            line: format!(
                "millac: no report written: {}: {}",
                path.display(),
                w.root_cause()
            ),
            error: e,
        })),
    }
}

/// A failure whose report could not be written ([`reported`]): it reads as the failure;
/// `line` says which file and why.
#[derive(Debug)]
pub(crate) struct Unreported {
    pub(crate) error: anyhow::Error,
    pub(crate) line: String,
}

impl std::fmt::Display for Unreported {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:#}", self.error)
    }
}

impl std::error::Error for Unreported {}

/// Reads the program file and runs `f` on its text; a file that is not UTF-8 is rejected like
/// any bad program (summary.json `error` naming the line, status 1).
pub(crate) fn with_program(
    path: &Path,
    out: &Path,
    f: impl FnOnce(&str) -> Result<bool>,
) -> Result<bool> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    match runner::program_text(&bytes) {
        Ok(text) => f(text),
        Err(r) => runner::write_rejection(out, &r).map(|_| false),
    }
}
