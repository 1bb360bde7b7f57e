//! `millac-qemu job [--out DIR]`: writes the whole die-sinking job of Fig. 1, generated from the
//! cavity's geometry (`millac_qemu::evaluation::job`), as DIR/fig1-job.nc (the program, four
//! tools with an M6 between them), DIR/fig1-job.tools (their `$T` lines, for `--tools`) and
//! DIR/fig1-job.stock (the blank, for `--stock`) (host: the CLI calls it from `main`).
use anyhow::Result;
use millac_qemu::evaluation::job;
use std::path::PathBuf;

/// `job`'s options.
#[derive(clap::Args)]
pub(crate) struct JobArgs {
    /// The folder the three files go to (made if missing).
    #[arg(long, default_value = "out/job")]
    pub(crate) out: PathBuf,
}

/// `job`: writes the files and says which.
pub(crate) fn command(args: JobArgs) -> Result<bool> {
    for path in job::fig1().write(&args.out)? {
        println!("wrote {}", path.display());
    }
    Ok(true)
}
