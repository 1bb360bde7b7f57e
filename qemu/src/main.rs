//! millac host tool entry point (host): `cargo run --release` runs the demo (the roughing path of the
//! paper's Fig. 1 cavity) through the firmware under QEMU; `run PROGRAM --out DIR` runs any program;
//! `analyse CAPTURE.vcd PROGRAM` checks a capture (ours or a real logic analyser's) against a program.
mod cli;

use clap::Parser;
use cli::{demo::DemoArgs, host::HostArgs, run::RunArgs, serve::ServeArgs};
use cli::{Cli, Cmd, Unreported};
use std::path::PathBuf;

fn main() {
    let cli = Cli::parse();
    millac_qemu::progress::set_quiet(cli.quiet);
    // The commands that leave a report in their folder: SIGINT and SIGTERM end them with it.
    let report: Option<(PathBuf, bool)> = match &cli.cmd {
        None => Some((PathBuf::from("out/demo"), false)),
        Some(Cmd::Demo(DemoArgs { out, .. }))
        | Some(Cmd::Run(RunArgs { out, .. }))
        | Some(Cmd::Host(HostArgs { out, .. })) => Some((out.clone(), false)),
        Some(Cmd::Serve(ServeArgs { out, .. })) => Some((out.clone(), true)),
        _ => None,
    };
    if report.is_some() {
        millac_qemu::interrupt::install();
    }
    let result = match cli.cmd {
        None => cli::demo::bare(),
        Some(Cmd::Run(a)) => cli::run::command(a),
        Some(Cmd::Demo(a)) => cli::demo::command(a),
        Some(Cmd::Host(a)) => cli::host::command(a),
        Some(Cmd::Analyse(a)) => cli::analyse::command(a),
        Some(Cmd::Check(a)) => cli::check::command(a),
        Some(Cmd::Optimise(a)) => cli::optimise::command(a),
        Some(Cmd::Calibrate(a)) => cli::calibrate::command(a),
        Some(Cmd::Serve(a)) => cli::serve::command(a),
        Some(Cmd::Job(a)) => cli::job::command(a),
    };
    // A signal ends `run`, `demo` and `host` with the report of what was done and the shell's
    // status for it (128 + the signal); it is how `serve` ends normally.
    let interrupted =
        millac_qemu::interrupt::received().filter(|_| report.as_ref().is_some_and(|r| !r.1));
    match result {
        Ok(ok) => {
            if let (Some(sig), Some((out, _))) = (interrupted, &report) {
                eprintln!(
                    "millac: interrupted by {}: the report of what ran is in {}",
                    millac_qemu::interrupt::name(sig),
                    out.join("summary.json").display()
                );
                std::process::exit(128 + sig);
            }
            if !ok {
                std::process::exit(1);
            }
        }
        Err(e) => {
            eprintln!("millac: {e:#}");
            if let Some(u) = e.downcast_ref::<Unreported>() {
                eprintln!("{}", u.line);
            }
            std::process::exit(interrupted.map_or(2, |sig| 128 + sig));
        }
    }
}
