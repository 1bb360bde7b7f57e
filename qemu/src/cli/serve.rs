//! `millac-qemu serve`: the firmware in serial mode with its UART on a TCP port for a G-code
//! sender (host: the CLI calls it from `main`; the session ends on SIGINT or SIGTERM).
use super::args::{cut_setup, parse_shift, CutArgs};
use super::reported;
use anyhow::Result;
use millac_qemu::emulator::runner;
use std::path::{Path, PathBuf};

/// `serve`'s options.
#[derive(clap::Args)]
pub(crate) struct ServeArgs {
    /// Address of the serial port (a grbl sender connects here; `socat` gives serial-only
    /// senders a pty in front of it).
    #[arg(long, default_value = millac_qemu::emulator::serve::DEFAULT_TCP)]
    pub(crate) tcp: String,
    #[arg(long, default_value = "out/serve")]
    pub(crate) out: PathBuf,
    /// The machine's settings record: loaded at start, rewritten after every accepted
    /// `$N=value`, kept across sessions [default: OUT/settings.bin].
    #[arg(long)]
    pub(crate) settings: Option<PathBuf>,
    /// QEMU -icount shift (virtual time = instructions * 2^N ns); 0..=7 (from 8 on the
    /// frame overruns its period in rapids).
    #[arg(long, default_value_t = runner::DEFAULT_SHIFT, value_parser = parse_shift)]
    pub(crate) shift: u32,
    /// No simulated ADC and no adaptive control.
    #[arg(long, conflicts_with = "strategy")]
    pub(crate) nc_only: bool,
    /// The machine model's limit switches, one line `start X Y Z switches X Y Z negative MASK`
    /// (BLU: where the machine stands at power-up and where each switch is; MASK bit k: axis
    /// k's switch at its negative end). Without it the machine has no switches.
    #[arg(long)]
    pub(crate) machine: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) cut: CutArgs,
}

/// `serve`: `--strategy` stored in the session's record, then [`serve`].
pub(crate) fn command(args: ServeArgs) -> Result<bool> {
    let ServeArgs {
        tcp,
        out,
        settings,
        shift,
        nc_only,
        machine,
        cut,
    } = args;
    let machine = match machine {
        Some(path) => {
            let text = std::fs::read_to_string(&path)
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            Some(millac::inputs::LimitSwitches::parse(&text).ok_or_else(|| {
                anyhow::anyhow!(
                    "{}: not a machine model (one line: start X Y Z switches X Y Z negative MASK)",
                    path.display()
                )
            })?)
        }
        None => None,
    };
    if let Some(s) = cut.strategy {
        anyhow::ensure!(
            settings.is_none(),
            "--strategy stores $251 only in the session's own record (OUT/settings.bin): \
             with --settings FILE set $251 in the session instead"
        );
        millac_qemu::emulator::serve::store_strategy(&out, s.into())?;
    }
    let settings = settings.unwrap_or_else(|| millac_qemu::emulator::serve::default_settings(&out));
    serve(
        &tcp,
        &out,
        &settings,
        shift,
        (!nc_only).then_some(&cut),
        machine.as_ref(),
    )
}

fn serve(
    tcp: &str,
    out: &Path,
    settings: &Path,
    shift: u32,
    cut: Option<&CutArgs>,
    machine: Option<&millac::inputs::LimitSwitches>,
) -> Result<bool> {
    let ac = match cut {
        Some(c) => Some(runner::AcRun {
            // The program arrives over the serial line during the session: the simulated
            // spindle starts at the default 600 rpm and takes the S of every spindle change
            // the firmware makes (through the ADC's requests).
            cut: cut_setup("", c)?,
            ac: !c.no_ac,
            faults: c.faults.clone(),
            settings: {
                anyhow::ensure!(
                    !c.monitor_breakage && c.chatter_threshold.is_none(),
                    "serve: set the process monitors in the session ($268=1 breakage, $266=CODES \
                     chatter threshold, $267 flutes)"
                );
                c.ac_settings(&millac_qemu::host::acsim::Cut::steel(
                    Default::default(),
                    c.seed,
                ))
            },
        }),
        None => None,
    };
    // SIGINT and SIGTERM end the session (the handler is installed in `main`).
    let stop = millac_qemu::interrupt::flag();
    println!(
        "millac serve: the machine's serial port (grbl 1.1) is on tcp://{tcp}, one client at a time; \
         point a sender there (serial-only senders: socat pty,raw,echo=0,link=/tmp/millac-tty \
         tcp:{tcp}). Ctrl-C ends the \
         session and writes {}/capture.vcd and summary.json. Settings ($N=value) persist in {}.",
        out.display(),
        settings.display()
    );
    let served = reported(
        out,
        true,
        millac_qemu::emulator::serve::serve(out, settings, tcp, shift, ac.as_ref(), machine, stop),
    )?;
    println!(
        "{}",
        serde_json::to_string_pretty(&served.summary).unwrap_or_default()
    );
    Ok(true)
}
