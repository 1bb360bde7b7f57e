//! millac host tool entry point (host): `cargo run --release` runs the demo (the roughing path of the
//! paper's Fig. 1 cavity) through the firmware under QEMU; `run PROGRAM --out DIR` runs any program;
//! `analyse CAPTURE.vcd PROGRAM` checks a capture (ours or a real logic analyser's) against a program.
use anyhow::{Context, Result};
use clap::{Parser, Subcommand, ValueEnum};
use millac::Settings;
use millac_qemu::{analysis, analysis::vcd, emulator::runner};
use std::path::{Path, PathBuf};

/// The shipped demo program.
const DEMO: &str = include_str!("../programs/fig1-cavity.nc");

#[derive(Parser)]
#[command(
    name = "millac",
    about = "millac NC firmware under QEMU with a virtual logic analyser"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Option<Cmd>,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a G-code program through the firmware; writes DIR/capture.vcd and DIR/summary.json.
    Run {
        program: PathBuf,
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// QEMU -icount shift: one instruction = 2^N ns (4: 62.5 MIPS, close to a 50-72 MHz M3);
        /// 0..=7 (from 8 on the frame overruns its period in rapids).
        #[arg(long, default_value_t = runner::DEFAULT_SHIFT, value_parser = parse_shift)]
        shift: u32,
        /// NC only: no simulated ADC and no adaptive control (the pulses then equal the host core's).
        #[arg(long, conflicts_with_all = ["faults", "strategy"])]
        nc_only: bool,
        #[command(flatten)]
        cut: CutArgs,
    },
    /// Run the demo (the default with no arguments).
    Demo {
        #[arg(long, default_value = "out/demo")]
        out: PathBuf,
        #[command(flatten)]
        cut: CutArgs,
    },
    /// Run a program with adaptive control natively on the host (no QEMU) against the simulated cut:
    /// DIR/ac.csv, DIR/ac.svg and the side-by-side table. Fast experiments and benchmarks.
    Host {
        program: Option<PathBuf>,
        #[arg(long, default_value = "out/host")]
        out: PathBuf,
        #[command(flatten)]
        cut: CutArgs,
    },
    /// Check a VCD capture against a program (no QEMU); writes a summary to stdout.
    Analyse { capture: PathBuf, program: PathBuf },
    /// Optimise a program's feeds offline by virtual machining (no QEMU, no sensor): split its
    /// feed blocks where the cut changes and give each piece the largest feed that keeps the
    /// simulated force within F0 and the torque within T0. Writes OUT (G-code with a header
    /// saying what was done), OUT.csv (the pieces) and OUT.svg (the feed before and after along
    /// the path), and prints the simulated times and peak forces of both programs.
    Optimise {
        program: PathBuf,
        #[arg(long)]
        out: PathBuf,
        /// Stock description file (default: the Fig. 1 die blank with its drilled start hole).
        #[arg(long)]
        stock: Option<PathBuf>,
        /// The cutter: DIAMETER_MM,FLUTES[,F_MAX_N[,T_MAX_NM]] (default: the 0.5 in 4-flute end
        /// mill, 4000 N, 80 N*m).
        #[arg(long, value_name = "D_MM,Z[,F_MAX_N[,T_MAX_NM]]", value_parser = parse_tool)]
        tool: Option<millac_plant::Tool>,
        /// The workpiece material.
        #[arg(long, value_enum, default_value = "steel")]
        material: MaterialArg,
        /// F0 and T0 as a fraction of the cutter's permissible force and torque (the AC's $256).
        #[arg(long, default_value_t = 0.9)]
        fraction: f64,
        /// Feed of the pieces that cut nothing, ipm [default: FRM, the machine's fastest feed].
        #[arg(long, value_name = "IPM")]
        air_feed: Option<f64>,
        /// A new piece where the feed the cut allows leaves the piece's band by this ratio.
        #[arg(long, default_value_t = 0.03)]
        split: f64,
        /// Shortest piece, mm.
        #[arg(long, default_value_t = 1.0)]
        min_piece_mm: f64,
        /// A fitted model (`calibrate`'s file): Georgiev and Chetrokov's quadratic model sets the
        /// feeds instead of the full force model, where it covers the depth.
        #[arg(long, value_name = "FILE")]
        model: Option<PathBuf>,
        /// The guard against a stock that is not as described: where the description says air
        /// but the stock's blanks could still hold material, at most the feed that would load
        /// such material to this fraction of the permissible force, so that the AC under the
        /// plan ($263=2) can catch it; 0 trusts the description.
        #[arg(long, default_value_t = 0.95)]
        guard: f64,
    },
    /// Fit Georgiev and Chetrokov's quadratic force model y(a, f) from test cuts on the
    /// simulated plant (full slots at each depth and feed); writes the model file (JSON: the
    /// coefficients, the validity range and the test cuts) for `optimise --model`.
    Calibrate {
        #[arg(long)]
        out: PathBuf,
        /// The cutter: DIAMETER_MM,FLUTES[,F_MAX_N[,T_MAX_NM]].
        #[arg(long, value_name = "D_MM,Z[,F_MAX_N[,T_MAX_NM]]", value_parser = parse_tool)]
        tool: Option<millac_plant::Tool>,
        #[arg(long, value_enum, default_value = "steel")]
        material: MaterialArg,
        /// Spindle speed, rpm.
        #[arg(long, default_value_t = 600.0)]
        rpm: f64,
        /// Depths of the test cuts, mm.
        #[arg(long, value_delimiter = ',', default_value = "1,3,5,7,9")]
        depths: Vec<f64>,
        /// Feeds of the test cuts, ipm.
        #[arg(long, value_delimiter = ',', default_value = "5,10,15,20,25,30")]
        feeds: Vec<f64>,
        /// A test cut cut on a machine: its depth (mm), its feed (ipm) and its run's ac.csv
        /// (repeat for every cut; at least six, over two depths and two feeds or more). With
        /// logs the model is fitted from them, not from the simulated plant.
        #[arg(long = "log", value_name = "A_MM,F_IPM,AC_CSV", value_parser = parse_log)]
        logs: Vec<(f64, f64, PathBuf)>,
        /// Write the test cuts of the grid (--depths x --feeds) as programs into this folder
        /// (cut-A-F.nc, on the blank `blank X0 Y0 W3 H2 Z0`, the top face at Z0) and stop: cut
        /// them on the machine with the AC measuring, then fit with --log.
        #[arg(long, value_name = "DIR")]
        write_cuts: Option<PathBuf>,
    },
    /// Run the firmware in serial mode with its UART on a TCP port for a G-code sender, until
    /// SIGINT or SIGTERM; then write DIR/capture.vcd and DIR/summary.json.
    Serve {
        /// Address of the serial port (a grbl sender connects here; `socat` gives serial-only
        /// senders a pty in front of it).
        #[arg(long, default_value = millac_qemu::emulator::serve::DEFAULT_TCP)]
        tcp: String,
        #[arg(long, default_value = "out/serve")]
        out: PathBuf,
        /// The machine's settings record: loaded at start, rewritten after every accepted
        /// `$N=value`, kept across sessions [default: OUT/settings.bin].
        #[arg(long)]
        settings: Option<PathBuf>,
        /// QEMU -icount shift (virtual time = instructions * 2^N ns); 0..=7 (from 8 on the
        /// frame overruns its period in rapids).
        #[arg(long, default_value_t = runner::DEFAULT_SHIFT, value_parser = parse_shift)]
        shift: u32,
        /// No simulated ADC and no adaptive control.
        #[arg(long, conflicts_with = "strategy")]
        nc_only: bool,
        #[command(flatten)]
        cut: CutArgs,
    },
}

/// The simulated cutting process.
#[derive(clap::Args, Clone, Debug)]
struct CutArgs {
    /// Run without adaptive control (programmed feeds).
    #[arg(long)]
    no_ac: bool,
    /// Seed of the transducer noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Stock description file (default: the Fig. 1 die blank with its drilled start hole).
    #[arg(long)]
    stock: Option<PathBuf>,
    /// Inject a sensor fault into the simulated ADC from KIND@SECONDS of virtual time on (rail,
    /// frozen, dropout, spike, gain; repeatable), e.g. --fault gain@2.5. The same transformation
    /// under QEMU (run, demo) and on the host (host); millac_qemu::host::fault lists each alarm.
    #[arg(long = "fault", value_name = "KIND@SECONDS")]
    faults: Vec<millac_qemu::host::fault::Fault>,
    /// The AC's feed law ($251) [default: gpc]: the same settings reach the firmware (a
    /// settings record in the run directory) and the host's simulation, replay and report. In
    /// `serve` it is stored in the session's record OUT/settings.bin (not with --settings).
    #[arg(long, value_enum)]
    strategy: Option<StrategyArg>,
    /// The feed drives of the simulated machine: a stepper (the tool where the pulses put it) or
    /// the thesis' servo position loop (wn^2 = 60318, 2 zeta wn = 400: the tool lags).
    #[arg(long, value_enum, default_value = "stepper")]
    drive: DriveArg,
    /// Kienzle exponent m of the steel's specific cutting pressure, Ks(h) = 2000 N/mm^2 x
    /// (h / 0.1 mm)^-m, 0 <= m < 1 (steel's usual m is about 0.25): the thesis' "non linear
    /// region" of the cutting forces, the force growing as the feed per tooth to the 1 - m.
    /// 0 (the default) keeps Ks constant.
    #[arg(long, default_value_t = 0.0, value_name = "M")]
    ks_exponent: f64,
    /// A whole cut set-up: `thesis-table-3.2` is Munasinghe's chatter test (a 15.875 mm 2-flute
    /// end mill, 76.2 mm overhang, flexible in X and Y with a 1600 Hz mode and heard by a
    /// microphone at 5 kHz; Al 7075; 1500 rpm unless the program's S says otherwise): chatter at
    /// 8.89 mm depth, stable at 2.54 mm (millac_plant::chatter::thesis_table_3_2).
    #[arg(long, value_enum)]
    preset: Option<PresetArg>,
    /// Tooth N (counted from 0 in cutting order: tooth 0 on +X at t = 0, tooth 1 the next to cut)
    /// breaks at SECONDS of virtual time: it cuts nothing from then on and the next tooth takes
    /// its chip (repeatable), e.g. --break-tooth 1@2.5. millac_plant::teeth has the model.
    #[arg(long = "break-tooth", value_name = "N@SECONDS", value_parser = millac_qemu::host::acsim::parse_break_tooth)]
    break_tooth: Vec<millac_plant::ToothEvent>,
    /// Tooth N's edge chips at SECONDS: it loses DEPTH_MM of radius (default 0.05 mm), the next
    /// tooth takes it (repeatable; a tooth's deepest chip so far counts), e.g.
    /// --chip-tooth 0@3:0.1.
    #[arg(long = "chip-tooth", value_name = "N@SECONDS[:DEPTH_MM]", value_parser = millac_qemu::host::acsim::parse_chip_tooth)]
    chip_tooth: Vec<millac_plant::ToothEvent>,
    /// Radial run-out of the teeth in micrometres, one value per tooth from tooth 0 (signed, +
    /// cuts deeper; |value| <= 1000), e.g. --runout 10,0,0,0.
    #[arg(long, value_name = "UM,UM,...")]
    runout: Option<millac_qemu::host::acsim::RunoutUm>,
    /// Tool breakage detection in the AC task ($268=1): a declared breakage holds the feed
    /// (ALARM:108) and stops the spindle; the tool's flutes and the program's S set its tooth
    /// period. `run`, `demo`, `host` (in `serve`, set $268 in the session).
    #[arg(long)]
    monitor_breakage: bool,
    /// Chatter detection in the AC task ($266): the threshold of the sound spectrum's largest
    /// amplitude away from the tooth harmonics, in sound codes (set it from a chatter-free cut:
    /// twice its largest amplitude); a record above it holds the feed (ALARM:107). Needs a
    /// microphone (`--preset thesis-table-3.2`). `run`, `demo`, `host` (in `serve`, set $266).
    #[arg(long, value_name = "CODES")]
    chatter_threshold: Option<f32>,
}

/// `--shift N`: a number the firmware can keep ([`runner::check_shift`]).
fn parse_shift(s: &str) -> Result<u32, String> {
    let n: u32 = s
        .trim()
        .parse()
        .map_err(|e| format!("'{s}' is not a shift (0..={}): {e}", runner::MAX_SHIFT))?;
    runner::check_shift(n)
}

/// `--material`: the plant's materials.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum MaterialArg {
    /// Steel, Ks 2000 N/mm^2.
    Steel,
    /// Steel with Kienzle's size effect (m = 0.25).
    SteelKienzle,
    /// Aluminium, Ks 800 N/mm^2.
    Aluminium,
}

impl From<MaterialArg> for millac_plant::Material {
    fn from(m: MaterialArg) -> Self {
        match m {
            MaterialArg::Steel => millac_plant::Material::STEEL,
            MaterialArg::SteelKienzle => millac_plant::Material::STEEL_KIENZLE,
            MaterialArg::Aluminium => millac_plant::Material::ALUMINIUM,
        }
    }
}

/// `--tool D_MM,Z[,F_MAX_N[,T_MAX_NM]]`.
fn parse_tool(s: &str) -> Result<millac_plant::Tool, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}")))
        .collect::<Result<_, _>>()?;
    let d = millac_plant::Tool::default();
    let (dia, z) = match v[..] {
        [dia, z, ..] if v.len() <= 4 => (dia, z),
        _ => return Err("expected D_MM,FLUTES[,F_MAX_N[,T_MAX_NM]]".into()),
    };
    let ok = |x: f64| x.is_finite() && x > 0.0;
    if !(ok(dia) && z.fract() == 0.0 && (1.0..=8.0).contains(&z)) {
        return Err(format!(
            "diameter must be > 0 mm and flutes 1..=8, got {dia} mm, {z}"
        ));
    }
    let tool = millac_plant::Tool {
        diameter_mm: dia,
        flutes: z as u32,
        f_max_n: v.get(2).copied().unwrap_or(d.f_max_n),
        t_max_nm: v.get(3).copied().unwrap_or(d.t_max_nm),
    };
    if !(ok(tool.f_max_n) && ok(tool.t_max_nm)) {
        return Err("F_MAX_N and T_MAX_NM must be > 0".into());
    }
    Ok(tool)
}

/// `--preset`: a whole simulated cut set-up.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum PresetArg {
    /// Munasinghe 1994, table 3.2: the chatter test.
    #[value(name = "thesis-table-3.2")]
    ThesisTable32,
}

/// `--drive`: `millac_plant::DriveModel` on the command line.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum DriveArg {
    Stepper,
    Servo,
}

impl From<DriveArg> for millac_plant::DriveModel {
    fn from(d: DriveArg) -> Self {
        match d {
            DriveArg::Stepper => millac_plant::DriveModel::Stepper,
            DriveArg::Servo => millac_plant::DriveModel::THESIS,
        }
    }
}

/// `--strategy`: `millac::ac::law::Strategy` on the command line.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum StrategyArg {
    /// The paper's FRC (Tlusty, Koren, McNeil).
    Paper,
    /// Fixed-gain integral law (Ulsoy, Koren, Lauderbaugh Eq. 2).
    Integral,
    /// Model reference adaptive control (their Eqs. 3-4).
    Mrac,
    /// Generalized predictive control (Munasinghe's thesis, Eqs. 3.27-3.42).
    Gpc,
}

impl From<StrategyArg> for millac::ac::law::Strategy {
    fn from(s: StrategyArg) -> Self {
        use millac::ac::law::Strategy;
        match s {
            StrategyArg::Paper => Strategy::Paper,
            StrategyArg::Integral => Strategy::Integral,
            StrategyArg::Mrac => Strategy::Mrac,
            StrategyArg::Gpc => Strategy::Gpc,
        }
    }
}

impl CutArgs {
    /// The run's AC settings: the defaults with the strategy (without `--strategy`, the
    /// default feed law, `$251`'s default).
    /// With a process monitor on (`--monitor-breakage`, `--chatter-threshold`), `$267` is the
    /// cut's tool's flutes and `$269` its spindle speed.
    fn ac_settings(&self, cut: &millac_qemu::host::acsim::Cut) -> millac::ac::AcSettings {
        let d = millac::ac::AcSettings::default();
        let monitors = self.monitor_breakage || self.chatter_threshold.is_some();
        millac::ac::AcSettings {
            strategy: self.strategy.map_or(d.strategy, Into::into),
            breakage: self.monitor_breakage,
            chatter_threshold: self.chatter_threshold.unwrap_or(d.chatter_threshold),
            flutes: if monitors { cut.tool.flutes } else { d.flutes },
            monitor_rpm: if monitors {
                cut.spindle_rpm.round() as u32
            } else {
                d.monitor_rpm
            },
            ..d
        }
    }
}

fn main() {
    let cli = Cli::parse();
    // The commands that leave a report in their folder: SIGINT and SIGTERM end them with it.
    let report: Option<(PathBuf, bool)> = match &cli.cmd {
        None => Some((PathBuf::from("out/demo"), false)),
        Some(Cmd::Demo { out, .. }) | Some(Cmd::Run { out, .. }) | Some(Cmd::Host { out, .. }) => {
            Some((out.clone(), false))
        }
        Some(Cmd::Serve { out, .. }) => Some((out.clone(), true)),
        _ => None,
    };
    if report.is_some() {
        millac_qemu::interrupt::install();
    }
    let result = match cli.cmd {
        None => demo(
            Path::new("out/demo"),
            &CutArgs {
                no_ac: false,
                seed: 1,
                stock: None,
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
        ),
        Some(Cmd::Demo { out, cut }) => demo(&out, &cut),
        Some(Cmd::Run {
            program,
            out,
            shift,
            nc_only,
            cut,
        }) => with_program(&program, &out, |text| {
            run(text, &out, shift, (!nc_only).then_some(&cut))
        }),
        Some(Cmd::Analyse { capture, program }) => analyse_file(&capture, &program),
        Some(Cmd::Optimise {
            program,
            out,
            stock,
            tool,
            material,
            fraction,
            air_feed,
            split,
            min_piece_mm,
            model,
            guard,
        }) => (|| {
            let model = match model {
                Some(p) => Some(millac_qemu::evaluation::model::Quadratic::from_json(
                    &std::fs::read_to_string(&p)
                        .with_context(|| format!("reading {}", p.display()))?,
                )?),
                None => None,
            };
            optimise(
                &program,
                &out,
                stock.as_deref(),
                tool,
                material.into(),
                &millac_qemu::evaluation::optimise::Options {
                    fraction,
                    air_feed_ipm: air_feed.unwrap_or(f64::INFINITY),
                    split,
                    min_piece_mm,
                    model,
                    guard,
                },
            )
        })(),
        Some(Cmd::Calibrate {
            out,
            tool,
            material,
            rpm,
            depths,
            feeds,
            logs,
            write_cuts,
        }) => match write_cuts {
            Some(dir) => write_test_cuts(&dir, &depths, &feeds),
            None => calibrate(&out, tool, material.into(), rpm, &depths, &feeds, &logs),
        },
        Some(Cmd::Serve {
            tcp,
            out,
            settings,
            shift,
            nc_only,
            cut,
        }) => (|| {
            if let Some(s) = cut.strategy {
                anyhow::ensure!(
                    settings.is_none(),
                    "--strategy stores $251 only in the session's own record (OUT/settings.bin): \
                     with --settings FILE set $251 in the session instead"
                );
                millac_qemu::emulator::serve::store_strategy(&out, s.into())?;
            }
            let settings =
                settings.unwrap_or_else(|| millac_qemu::emulator::serve::default_settings(&out));
            serve(&tcp, &out, &settings, shift, (!nc_only).then_some(&cut))
        })(),
        Some(Cmd::Host { program, out, cut }) => match program {
            Some(p) => with_program(&p, &out, |text| host(text, &out, &cut)),
            None => host(DEMO, &out, &cut),
        },
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

/// The report of a command that failed once it had begun to write into its folder (a failure
/// of its options writes nothing): `out/summary.json` with `completed` false and `error`
/// {`message`} (no `line`: not a program's rejection), so no earlier run's summary is left to
/// be taken for this one. When it cannot be written, the error carries [`Unreported`]: `main`
/// says in one line which file and why. A folder that holds `serve`'s settings is not a run's
/// folder: `run` refuses it and nothing is written there.
fn reported<T>(out: &Path, serve: bool, r: Result<T>) -> Result<T> {
    let Err(e) = r else { return r };
    let path = out.join("summary.json");
    if !serve && std::fs::symlink_metadata(out.join(millac::wire::SETTINGS_NAME)).is_ok() {
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
struct Unreported {
    error: anyhow::Error,
    line: String,
}

impl std::fmt::Display for Unreported {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:#}", self.error)
    }
}

impl std::error::Error for Unreported {}

/// Reads the program file and runs `f` on its text; a file that is not UTF-8 is rejected like
/// any bad program (summary.json `error` naming the line, status 1).
fn with_program(path: &Path, out: &Path, f: impl FnOnce(&str) -> Result<bool>) -> Result<bool> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    match runner::program_text(&bytes) {
        Ok(text) => f(text),
        Err(r) => runner::write_rejection(out, &r).map(|_| false),
    }
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

fn run(text: &str, out: &Path, shift: u32, cut: Option<&CutArgs>) -> Result<bool> {
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
    let o = reported(
        out,
        false,
        runner::run_until(text, out, shift, ac.as_ref(), Some(stop)),
    )?;
    if o.report.is_some() {
        runner::print_summary(&o.summary, out);
    }
    if !o.ok {
        eprintln!("millac: a check failed, see {}/summary.json", out.display());
    }
    Ok(o.ok)
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

fn serve(
    tcp: &str,
    out: &Path,
    settings: &Path,
    shift: u32,
    cut: Option<&CutArgs>,
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
        millac_qemu::emulator::serve::serve(out, settings, tcp, shift, ac.as_ref(), stop),
    )?;
    println!(
        "{}",
        serde_json::to_string_pretty(&served.summary).unwrap_or_default()
    );
    Ok(true)
}

fn cut_setup(text: &str, args: &CutArgs) -> Result<millac_qemu::host::acsim::Cut> {
    use millac_plant::{Material, Stock};
    let stock = match &args.stock {
        Some(p) => millac_qemu::host::acsim::load_stock(p)?,
        None => Stock::default(),
    };
    let cut = millac_qemu::host::acsim::Cut {
        drive: args.drive.into(),
        material: Material {
            ks_exponent: args.ks_exponent,
            ..Material::STEEL
        },
        runout_mm: args.runout.clone().map_or_else(Vec::new, |r| r.0),
        tooth_events: args
            .chip_tooth
            .iter()
            .chain(&args.break_tooth)
            .copied()
            .collect(),
        ..millac_qemu::host::acsim::Cut::steel(stock, args.seed)
    };
    let cut = match args.preset {
        None => cut.at_program_rpm(text, &Settings::default()),
        Some(PresetArg::ThesisTable32) => {
            use millac_plant::chatter::thesis_table_3_2 as t;
            let preset = millac_qemu::host::acsim::Cut {
                tool: millac_plant::Tool {
                    diameter_mm: t::DIAMETER_MM,
                    flutes: t::FLUTES,
                    ..cut.tool
                },
                material: Material {
                    ks_exponent: args.ks_exponent,
                    ..Material::ALUMINIUM
                },
                spindle_rpm: t::RPM,
                modes: Some((vec![t::MODE], vec![t::MODE])),
                ..cut
            };
            // The program's S, when it has one, sets the speed as in any run.
            match analysis::spindle_rpm(text, &Settings::default()) {
                0 => preset,
                rpm => millac_qemu::host::acsim::Cut {
                    spindle_rpm: f64::from(rpm),
                    ..preset
                },
            }
        }
    };
    // The plant's own checks (e.g. the Ks exponent's range, the teeth of --break-tooth,
    // --chip-tooth and --runout against the tool's flutes), before anything runs.
    cut.process()?;
    Ok(cut)
}

fn host(text: &str, out: &Path, args: &CutArgs) -> Result<bool> {
    use millac_qemu::{evaluation::acreport, host::acsim};
    let settings = Settings::default();
    let prog = match analysis::load_program(text, &settings) {
        Ok(p) => p,
        Err(e) => {
            let r = runner::Rejected {
                line: e.line(),
                message: e.to_string(),
            };
            return runner::write_rejection(out, &r).map(|_| false);
        }
    };
    let cut = cut_setup(text, args)?;
    let acs = args.ac_settings(&cut);
    // From here on the folder is written: a failure leaves its report there.
    reported(
        out,
        false,
        (|| -> Result<bool> {
            std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
            let run = acsim::run_with_faults(
                &prog,
                &settings,
                &cut,
                (!args.no_ac).then_some(acs),
                true,
                &args.faults,
            )?;
            let csv = out.join("ac.csv");
            std::fs::write(&csv, acsim::csv(&run.rows))
                .with_context(|| format!("writing {}", csv.display()))?;
            let f0 = acs.f0_n() as f64;
            let t0 = acs.t0_nm() as f64;
            acreport::plot(
                &out.join("ac.svg"),
                &run.rows,
                f0,
                t0,
                1.0 / acs.optimal_fraction as f64,
                acsim::feed_ipm(&settings, settings.q0),
            )?;
            let load = acsim::load_figures(
                &run.samples,
                &cut.tool,
                acs.optimal_fraction as f64,
                acs.sample_hz,
            );
            // The comparison's runs (constant feeds, the oracle) are left out once a signal has come:
            // they would be cut short too.
            let cmp = match millac_qemu::interrupt::received() {
                None => Some(acreport::compare(&prog, &settings, &cut, &acs)?),
                Some(_) => None,
            };
            let signal = millac_qemu::interrupt::received().map(millac_qemu::interrupt::name);
            let cmp = cmp.filter(|_| signal.is_none());
            println!(
                "millac host run ({}): final position {:?}",
                match (args.no_ac, args.strategy) {
                    (true, _) => "no AC".to_string(),
                    (false, None) => "AC".to_string(),
                    (false, Some(_)) => format!("AC, strategy {}", acs.strategy.name()),
                },
                run.final_position
            );
            if let Some(a) = run.alarm {
                println!("  alarm: {a}");
            }
            // The keys of `run`'s summary.json that apply to a host run.
            let completed = run.blocks_done >= prog.len() && !run.interrupted;
            let [x, y, z] = run.final_position;
            let mut summary = serde_json::json!({
                "blocks": prog.len(),
                "machining_time_s": (run.machining_time_s * 1e6).round() / 1e6,
                "final_position_blu": {"x": x, "y": y, "z": z},
                "completed": completed,
            });
            summary["ac"] = match &cmp {
                Some(cmp) => acreport::ac_json(run.machining_time_s, &load, cmp),
                None => serde_json::json!({}),
            };
            summary["ac"]["enabled"] = serde_json::json!(!args.no_ac);
            summary["ac"]["strategy"] = serde_json::json!(acs.strategy.name());
            summary["ac"]["samples"] = serde_json::json!(run.samples.len());
            summary["ac"]["holds"] = serde_json::json!(run
                .rows
                .iter()
                .filter(|r| r.state.starts_with("hold"))
                .count());
            let hold = (!completed).then(|| runner::Hold {
                alarm: run.alarm.map(|a| a.to_string()).unwrap_or_default(),
                blocks_done: run.blocks_done,
                position: run.final_position,
                signal: signal.clone().filter(|_| run.interrupted),
            });
            if let Some(h) = &hold {
                let key = if h.signal.is_some() {
                    "interrupted"
                } else {
                    "hold"
                };
                summary[key] = runner::hold_json(&prog, h);
            }
            if let (Some(s), false) = (&signal, run.interrupted) {
                // The run itself finished; only the comparison was left out.
                summary["interrupted"] = serde_json::json!({"signal": s, "left_out": "comparison"});
            }
            let why = hold.as_ref().map(|h| runner::held_at(&prog, h));
            match &cmp {
                Some(cmp) => acreport::print_table(
                    run.machining_time_s,
                    &load,
                    cmp,
                    why.as_deref(),
                    acs.strategy,
                ),
                None => println!(
                "  interrupted: {}; the comparison with constant feeds and the oracle is left out",
                why.as_deref().unwrap_or("the run had finished")
            ),
            }
            runner::write_json(&out.join("summary.json"), &summary)?;
            println!(
                "  wrote {}/ac.csv, {}/ac.svg and {}/summary.json",
                out.display(),
                out.display(),
                out.display()
            );
            let end = prog.last().map_or([0; 3], |b| b.end).map(i64::from);
            Ok(completed && run.final_position == end)
        })(),
    )
}

/// `optimise`: the offline feed optimisation (`millac_qemu::evaluation::optimise`), its files and a summary
/// of both programs on the simulated cut (no AC).
fn optimise(
    program: &Path,
    out: &Path,
    stock: Option<&Path>,
    tool: Option<millac_plant::Tool>,
    material: millac_plant::Material,
    opts: &millac_qemu::evaluation::optimise::Options,
) -> Result<bool> {
    use millac_qemu::{evaluation::optimise, host::acsim};
    let bytes = std::fs::read(program).with_context(|| format!("reading {}", program.display()))?;
    let text = std::str::from_utf8(&bytes)
        .map_err(|e| anyhow::anyhow!("{} is not UTF-8: {e}", program.display()))?;
    let stock = match stock {
        Some(p) => acsim::load_stock(p)?,
        None => millac_plant::Stock::default(),
    };
    let settings = Settings::default();
    let cut = acsim::Cut {
        tool: tool.unwrap_or_default(),
        material,
        ..acsim::Cut::steel(stock, 1)
    }
    .at_program_rpm(text, &settings);
    let o = optimise::optimise(text, &settings, &cut, opts)?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(out, &o.text).with_context(|| format!("writing {}", out.display()))?;
    let csv = out.with_extension("csv");
    std::fs::write(&csv, optimise::csv(&o))
        .with_context(|| format!("writing {}", csv.display()))?;
    let svg = out.with_extension("svg");
    let name = program
        .file_name()
        .map_or_else(|| "program".into(), |n| n.to_string_lossy().into_owned());
    optimise::plot(&svg, &name, &o)?;
    let prog = analysis::load_program(&o.text, &settings).map_err(|e| anyhow::anyhow!("{e}"))?;
    let run = acsim::run(&prog, &settings, &cut, None)?;
    let hz = millac::ac::AcSettings::default().sample_hz;
    let before = acsim::load_figures(&o.programmed.samples, &cut.tool, opts.fraction, hz);
    let after = acsim::load_figures(&run.samples, &cut.tool, opts.fraction, hz);
    println!(
        "millac optimise: {} -> {} ({} pieces; {}, {})",
        program.display(),
        out.display(),
        o.pieces.len(),
        csv.display(),
        svg.display()
    );
    println!("| program | time s | peak F / F_max | time above F0 s | time above F_max s |");
    println!("| --- | ---: | ---: | ---: | ---: |");
    for (name, r, l) in [
        ("programmed", &o.programmed, before),
        ("optimised", &run, after),
    ] {
        println!(
            "| {name} | {:.2} | {:.3} | {:.3} | {:.3} |",
            r.machining_time_s, l.peak_force_ratio, l.time_above_f0_s, l.time_above_limit_s
        );
    }
    Ok(true)
}

/// `--log A,F,FILE`: a test cut's depth (mm), feed (ipm) and its run's ac.csv.
fn parse_log(s: &str) -> std::result::Result<(f64, f64, PathBuf), String> {
    let mut it = s.splitn(3, ',');
    let num = |v: Option<&str>, what: &str| {
        v.and_then(|v| v.trim().parse::<f64>().ok())
            .filter(|v| v.is_finite() && *v > 0.0)
            .ok_or_else(|| format!("'{s}': {what} must be a number > 0 (A_MM,F_IPM,AC_CSV)"))
    };
    let a = num(it.next(), "the depth")?;
    let f = num(it.next(), "the feed")?;
    let path = it
        .next()
        .filter(|p| !p.is_empty())
        .ok_or_else(|| format!("'{s}': the ac.csv file is missing (A_MM,F_IPM,AC_CSV)"))?;
    Ok((a, f, PathBuf::from(path)))
}

/// `calibrate --write-cuts DIR`: the test cuts of the grid as programs.
fn write_test_cuts(dir: &Path, depths: &[f64], feeds: &[f64]) -> Result<bool> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for &a in depths {
        for &f in feeds {
            let p = dir.join(format!("cut-{a}-{f}.nc"));
            std::fs::write(&p, millac_qemu::evaluation::model::test_cut(a, f))
                .with_context(|| format!("writing {}", p.display()))?;
        }
    }
    println!(
        "millac calibrate: {} test cuts in {} (stock: {})",
        depths.len() * feeds.len(),
        dir.display(),
        millac_qemu::evaluation::model::TEST_STOCK.trim()
    );
    Ok(true)
}

/// `calibrate`: the quadratic model from test cuts (on the simulated plant, or cut on a machine:
/// their ac.csv files), its file and a table.
fn calibrate(
    out: &Path,
    tool: Option<millac_plant::Tool>,
    material: millac_plant::Material,
    rpm: f64,
    depths: &[f64],
    feeds: &[f64],
    logs: &[(f64, f64, PathBuf)],
) -> Result<bool> {
    use millac_qemu::{evaluation::model, host::acsim};
    let (m, cuts) = if logs.is_empty() {
        let cut = acsim::Cut {
            tool: tool.unwrap_or_default(),
            material,
            spindle_rpm: rpm,
            ..acsim::Cut::steel(millac_plant::Stock::default(), 1)
        };
        model::calibrate(&cut, depths, feeds)?
    } else {
        let mut texts = Vec::new();
        for (a, f, p) in logs {
            let t =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            texts.push((*a, *f, t));
        }
        model::calibrate_from_logs(&texts)?
    };
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(out, m.to_json(&cuts)).with_context(|| format!("writing {}", out.display()))?;
    println!(
        "millac calibrate: {} test cuts -> {}: y = {:.1} + {:.2} a + {:.2} f + {:.3} a f + {:.3} a^2 + {:.4} f^2 (a {}..{} mm, f {}..{} ipm)",
        cuts.len(),
        out.display(),
        m.b[0], m.b[1], m.b[2], m.b[3], m.b[4], m.b[5],
        m.a_range.0, m.a_range.1, m.f_range.0, m.f_range.1
    );
    println!("| a mm | f ipm | y N (test cut) | y N (model) |");
    println!("| ---: | ---: | ---: | ---: |");
    for (a, f, y) in &cuts {
        println!("| {a} | {f} | {y:.0} | {:.0} |", m.eval(*a, *f));
    }
    Ok(true)
}
