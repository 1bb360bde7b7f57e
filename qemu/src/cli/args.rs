//! The options several subcommands share (host: the CLI's parser and subcommands): the simulated
//! cut ([`CutArgs`], made a cut by [`cut_setup`]), `--shift`, `--tool`, `--material` and the
//! value enums.
use anyhow::Result;
use clap::ValueEnum;
use millac::Settings;
use millac_qemu::{analysis, emulator::runner};
use std::path::PathBuf;

/// The simulated cutting process.
#[derive(clap::Args, Clone, Debug)]
pub(crate) struct CutArgs {
    /// Run without adaptive control (programmed feeds).
    #[arg(long)]
    pub(crate) no_ac: bool,
    /// Seed of the transducer noise.
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// Stock description file (default: the Fig. 1 die blank with its drilled start hole).
    #[arg(long)]
    pub(crate) stock: Option<PathBuf>,
    /// The machine's tool table: `$T` lines as typed at the console (`$T2=D3 N2 K0`, one per
    /// line; `#` starts a comment line). The program's M6s fit them: the AC takes each tool's
    /// limits (its F and M, else from its diameter and kind), the simulated cut its diameter and
    /// flutes, the part of the program after it its S. Without: a tool an M6 fits has no limits
    /// and the AC only measures it.
    #[arg(long, value_name = "FILE")]
    pub(crate) tools: Option<PathBuf>,
    /// A stock description's text when no `--stock` is given (the demo's generated job).
    #[arg(skip)]
    pub(crate) stock_text: Option<String>,
    /// A tool table's text when no `--tools` is given (the demo's generated job).
    #[arg(skip)]
    pub(crate) tools_text: Option<String>,
    /// Inject a sensor fault into the simulated ADC from KIND@SECONDS of virtual time on (rail,
    /// frozen, dropout, spike, gain; repeatable), e.g. --fault gain@2.5. The same transformation
    /// under QEMU (run, demo) and on the host (host); millac_qemu::host::fault lists each alarm.
    #[arg(long = "fault", value_name = "KIND@SECONDS")]
    pub(crate) faults: Vec<millac_qemu::host::fault::Fault>,
    /// The AC's feed law ($251) [default: gpc]: the same settings reach the firmware (a
    /// settings record in the run directory) and the host's simulation, replay and report. In
    /// `serve` it is stored in the session's record OUT/settings.bin (not with --settings).
    #[arg(long, value_enum)]
    pub(crate) strategy: Option<StrategyArg>,
    /// The feed drives of the simulated machine: a stepper (the tool where the pulses put it) or
    /// the thesis' servo position loop (wn^2 = 60318, 2 zeta wn = 400: the tool lags).
    #[arg(long, value_enum, default_value = "stepper")]
    pub(crate) drive: DriveArg,
    /// Kienzle exponent m of the steel's specific cutting pressure, Ks(h) = 2000 N/mm^2 x
    /// (h / 0.1 mm)^-m, 0 <= m < 1 (steel's usual m is about 0.25): the thesis' "non linear
    /// region" of the cutting forces, the force growing as the feed per tooth to the 1 - m.
    /// 0 (the default) keeps Ks constant.
    #[arg(long, default_value_t = 0.0, value_name = "M")]
    pub(crate) ks_exponent: f64,
    /// A whole cut set-up: `thesis-table-3.2` is Munasinghe's chatter test (a 15.875 mm 2-flute
    /// end mill, 76.2 mm overhang, flexible in X and Y with a 1600 Hz mode and heard by a
    /// microphone at 5 kHz; Al 7075; 1500 rpm unless the program's S says otherwise): chatter at
    /// 8.89 mm depth, stable at 2.54 mm (millac_plant::chatter::thesis_table_3_2).
    #[arg(long, value_enum)]
    pub(crate) preset: Option<PresetArg>,
    /// Tooth N (counted from 0 in cutting order: tooth 0 on +X at t = 0, tooth 1 the next to cut)
    /// breaks at SECONDS of virtual time: it cuts nothing from then on and the next tooth takes
    /// its chip (repeatable), e.g. --break-tooth 1@2.5. millac_plant::teeth has the model.
    #[arg(long = "break-tooth", value_name = "N@SECONDS", value_parser = millac_qemu::host::acsim::parse_break_tooth)]
    pub(crate) break_tooth: Vec<millac_plant::ToothEvent>,
    /// Tooth N's edge chips at SECONDS: it loses DEPTH_MM of radius (default 0.05 mm), the next
    /// tooth takes it (repeatable; a tooth's deepest chip so far counts), e.g.
    /// --chip-tooth 0@3:0.1.
    #[arg(long = "chip-tooth", value_name = "N@SECONDS[:DEPTH_MM]", value_parser = millac_qemu::host::acsim::parse_chip_tooth)]
    pub(crate) chip_tooth: Vec<millac_plant::ToothEvent>,
    /// Radial run-out of the teeth in micrometres, one value per tooth from tooth 0 (signed, +
    /// cuts deeper; |value| <= 1000), e.g. --runout 10,0,0,0.
    #[arg(long, value_name = "UM,UM,...")]
    pub(crate) runout: Option<millac_qemu::host::acsim::RunoutUm>,
    /// Tool breakage detection in the AC task ($268=1): a declared breakage holds the feed
    /// (ALARM:108) and stops the spindle; the tool's flutes and the program's S set its tooth
    /// period. `run`, `demo`, `host` (in `serve`, set $268 in the session).
    #[arg(long)]
    pub(crate) monitor_breakage: bool,
    /// The chatter threshold ($266): the sound spectrum's largest amplitude away from the tooth
    /// harmonics above which a record is chatter, in sound codes (set it from a chatter-free cut:
    /// twice its largest amplitude); without it the default's automatic rule (four times the
    /// tooth harmonics'). A record above it holds the feed (ALARM:107). The chatter monitor runs
    /// where there is a microphone (`--preset thesis-table-3.2`). `run`, `demo`, `host` (in
    /// `serve`, set $266).
    #[arg(long, value_name = "CODES")]
    pub(crate) chatter_threshold: Option<f32>,
}

/// `--shift N`: a number the firmware can keep ([`runner::check_shift`]).
pub(crate) fn parse_shift(s: &str) -> Result<u32, String> {
    let n: u32 = s
        .trim()
        .parse()
        .map_err(|e| format!("'{s}' is not a shift (0..={}): {e}", runner::MAX_SHIFT))?;
    runner::check_shift(n)
}

/// `--material`: the plant's materials.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MaterialArg {
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
pub(crate) fn parse_tool(s: &str) -> Result<millac_plant::Tool, String> {
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
        ..d
    };
    if !(ok(tool.f_max_n) && ok(tool.t_max_nm)) {
        return Err("F_MAX_N and T_MAX_NM must be > 0".into());
    }
    Ok(tool)
}

/// `--preset`: a whole simulated cut set-up.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PresetArg {
    /// Munasinghe 1994, table 3.2: the chatter test.
    #[value(name = "thesis-table-3.2")]
    ThesisTable32,
}

/// `--drive`: `millac_plant::DriveModel` on the command line.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum DriveArg {
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
pub(crate) enum StrategyArg {
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
    pub(crate) fn ac_settings(
        &self,
        cut: &millac_qemu::host::acsim::Cut,
    ) -> millac::ac::AcSettings {
        let d = millac::ac::AcSettings::default();
        // A microphone (the flexible tool's modes) turns the chatter monitor on by default.
        let monitors =
            self.monitor_breakage || self.chatter_threshold.is_some() || cut.modes.is_some();
        millac::ac::AcSettings {
            strategy: self.strategy.map_or(d.strategy, Into::into),
            // --monitor-breakage: on for every tool, the cut's own too; else the machine's
            // default (on for each tool an M6 fits whose flutes the table gives).
            breakage: if self.monitor_breakage {
                millac::ac::Breakage::On
            } else {
                d.breakage
            },
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

pub(crate) fn cut_setup(text: &str, args: &CutArgs) -> Result<millac_qemu::host::acsim::Cut> {
    use millac_plant::{Material, Stock};
    let stock = match (&args.stock, &args.stock_text) {
        (Some(p), _) => millac_qemu::host::acsim::load_stock(p)?,
        (None, Some(t)) => millac_qemu::host::acsim::parse_stock(t, "the job's stock")?,
        (None, None) => Stock::default(),
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
    let tools = match (&args.tools, &args.tools_text) {
        (Some(p), _) => millac_qemu::host::acsim::load_tools(p)?,
        (None, Some(t)) => millac_qemu::host::acsim::parse_tools(t, "the job's tool table")?,
        (None, None) => Default::default(),
    };
    let cut = cut.with_tool_changes(text, &Settings::default(), &tools);
    // The plant's own checks (e.g. the Ks exponent's range, the teeth of --break-tooth,
    // --chip-tooth and --runout against the tool's flutes), before anything runs.
    cut.process()?;
    Ok(cut)
}
