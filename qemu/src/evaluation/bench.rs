//! The AC benchmark (host): every feed law on every benchmark program with the stepper and the
//! servo drive against the constant feeds and the bound, as rows of one table. The `ac_bench`
//! example prints it; the bound's tests (qemu/tests/bound.rs) run the same programs.
use crate::analysis::{self, ProgBlock};
use crate::evaluation::acreport::{self, Comparison};
use crate::host::acsim::{self, Cut, HostRun};
use anyhow::{anyhow, Result};
use millac::ac::law::Strategy;
use millac::ac::AcSettings;
use millac::Settings;
use millac_plant::{DriveModel, Material, Stock};

/// One benchmark program: name, G-code and stock description (None: the Fig. 1 die blank).
#[derive(Clone, Copy, Debug)]
pub struct Case {
    pub name: &'static str,
    pub program: &'static str,
    pub stock: Option<&'static str>,
    /// The cutter's permissible force, N, where the program needs another than the default
    /// tool's 4000 N (the plant's truth and the controller's setting `$253` alike). The force
    /// transducer's range is scaled with it (the gain per code of Fu and Fv times limit / 4000,
    /// in the plant and the controller's calibration alike), as one would fit a force sensor to a
    /// weaker cutter: at the default range a 500 N cutter's F0 is 90 codes, and the peak of 30
    /// noisy samples reads several per cent above the true force.
    pub force_limit_n: Option<f64>,
    /// F0 and T0 as a fraction of the permissible limits where the program needs another than
    /// the default 0.9: a program with a known load step of +s runs at F0 = 0.9 / (1 + s), so
    /// the step itself stays under the limit (no 10 ms loop can act within it); the overload
    /// hold stays at 99 % of the limit ([`overload_e_for`]). The bound uses the same F0.
    pub optimal_fraction: Option<f32>,
}

/// The overload hold's `overload_e` for F0 = `fraction` x the limit: the hold at 99 % of the
/// permissible limit (E = 1 - 0.99 / fraction; -0.1 at the default 0.9), no lower than the
/// settings allow (-1: twice F0).
pub fn overload_e_for(fraction: f32) -> f32 {
    (1.0 - 0.99 / fraction).max(-1.0)
}

/// The benchmark's programs.
pub const CASES: &[Case] = &[
    Case {
        name: "Fig. 1 cavity",
        program: include_str!("../../programs/fig1-cavity.nc"),
        stock: None,
        force_limit_n: None,
        optimal_fraction: None,
    },
    Case {
        name: "pocket (Fig. 5.8)",
        program: include_str!("../../programs/pocket.nc"),
        stock: Some(include_str!("../../programs/pocket.stock")),
        force_limit_n: None,
        optimal_fraction: None,
    },
    // Ulsoy, Koren and Lauderbaugh's Figs. 2-3: depths 1, 2, 3 mm. The 0.5 in cutter at 4000 N
    // would reach F0 at none of them below FRM, so the cutter is taken as a weaker one, 500 N,
    // as in the reproduction (`crate::evaluation::repro::DEPTH_STEP_FORCE_LIMIT_N`). Steps of +100 % and
    // +50 %: F0 = 0.45 of the limit.
    Case {
        name: "depth-step slot",
        program: include_str!("../../programs/depth-step.nc"),
        stock: Some(include_str!("../../programs/depth-step.stock")),
        force_limit_n: Some(crate::evaluation::repro::DEPTH_STEP_FORCE_LIMIT_N as f64),
        optimal_fraction: Some(0.45),
    },
    // The thesis' test TIIM: a full slot whose depth steps from 7.62 to 10.5 mm (+38 %): F0 =
    // 0.65 of the limit.
    Case {
        name: "TIIM step",
        program: include_str!("../../programs/tiim.nc"),
        stock: Some(include_str!("../../programs/tiim.stock")),
        force_limit_n: None,
        optimal_fraction: Some(0.65),
    },
];

impl Case {
    pub fn stock(&self) -> Result<Stock> {
        self.stock
            .map_or_else(|| Ok(Stock::default()), Stock::parse)
            .map_err(|e| anyhow!("{}: {e}", self.name))
    }

    pub fn load(&self, settings: &Settings) -> Result<Vec<ProgBlock>> {
        analysis::load_program(self.program, settings).map_err(|e| anyhow!("{}: {e}", self.name))
    }

    /// The benchmark's cut of this program: `material` (steel, or steel with Kienzle's size
    /// effect), the default tool, seed 1, `drive`, at the program's spindle speed (its S word;
    /// 600 rpm without one).
    pub fn cut(&self, settings: &Settings, drive: DriveModel, material: Material) -> Result<Cut> {
        let mut cut = Cut {
            drive,
            material,
            ..Cut::steel(self.stock()?, 1)
        }
        .at_program_rpm(self.program, settings);
        if let Some(f) = self.force_limit_n {
            let scale = f / cut.tool.f_max_n;
            cut.tool.f_max_n = f;
            cut.transducer.gain[1] *= scale;
            cut.transducer.gain[2] *= scale;
        }
        Ok(cut)
    }

    /// The controller's settings for this program: the defaults with the cutter's permissible
    /// force and the program's F0 fraction (and its overload hold).
    pub fn ac_settings(&self) -> AcSettings {
        let d = AcSettings::default();
        let fraction = self.optimal_fraction.unwrap_or(d.optimal_fraction);
        let mut cal = d.cal;
        if let Some(f) = self.force_limit_n {
            let scale = f as f32 / d.force_limit_n;
            cal[1].gain *= scale;
            cal[2].gain *= scale;
        }
        AcSettings {
            cal,
            force_limit_n: self.force_limit_n.map_or(d.force_limit_n, |f| f as f32),
            optimal_fraction: fraction,
            overload_e: self.optimal_fraction.map_or(d.overload_e, overload_e_for),
            ..d
        }
    }
}

/// The drive's name in the table.
pub fn drive_name(drive: DriveModel) -> &'static str {
    if drive == DriveModel::Stepper {
        "stepper"
    } else {
        "servo"
    }
}

/// One row: a schedule's figures on one program with one drive.
#[derive(Clone, Debug)]
pub struct Row {
    pub program: &'static str,
    pub drive: &'static str,
    pub schedule: String,
    /// The feed law of an AC row (None: a constant feed or the bound).
    pub strategy: Option<Strategy>,
    pub time_s: f64,
    pub bound_s: f64,
    pub peak_force_ratio: f64,
    pub time_above_f0_s: f64,
    pub time_above_limit_s: f64,
    /// Largest excess of the true force over F0, % (0 when it never exceeds F0).
    pub overshoot_pct: f64,
    /// "none", or why the run stopped.
    pub holds: String,
}

impl Row {
    /// Finished without a hold and never above the permissible limits.
    pub fn clean(&self) -> bool {
        self.holds == "none" && self.time_above_limit_s == 0.0
    }
}

/// What every row of one program and drive shares.
struct Ctx<'a> {
    case: &'a Case,
    drive: DriveModel,
    cut: &'a Cut,
    prog: &'a [ProgBlock],
    bound_s: f64,
}

impl Ctx<'_> {
    fn row(&self, schedule: String, strategy: Option<Strategy>, run: &HostRun) -> Row {
        let fraction = f64::from(self.case.ac_settings().optimal_fraction);
        let l = acsim::load_figures(
            &run.samples,
            &self.cut.tool,
            fraction,
            AcSettings::default().sample_hz,
        );
        let end = self.prog.last().map_or([0; 3], |b| b.end).map(i64::from);
        let holds = match (&run.alarm, run.final_position == end) {
            (Some(a), _) => format!("held: {}", a.message()),
            (None, true) => "none".to_string(),
            (None, false) => "did not finish".to_string(),
        };
        Row {
            program: self.case.name,
            drive: drive_name(self.drive),
            schedule,
            strategy,
            time_s: run.machining_time_s,
            bound_s: self.bound_s,
            peak_force_ratio: l.peak_force_ratio,
            time_above_f0_s: l.time_above_f0_s,
            time_above_limit_s: l.time_above_limit_s,
            overshoot_pct: ((l.peak_force_ratio / fraction - 1.0) * 100.0).max(0.0),
            holds,
        }
    }
}

/// The rows of one program with one drive: the programmed and safe constant feeds, the paper's FRC
/// as published (`published`), each of `strategies` (with anti-windup and the 3-window peak, the
/// defaults), and the bound. Also the comparison (the bound's and the constant feeds' runs).
pub fn rows(
    case: &Case,
    settings: &Settings,
    drive: DriveModel,
    material: Material,
    strategies: &[Strategy],
    published: bool,
) -> Result<(Vec<Row>, Comparison)> {
    let prog = case.load(settings)?;
    let cut = case.cut(settings, drive, material)?;
    let acs = case.ac_settings();
    let cmp = acreport::compare(&prog, settings, &cut, &acs)?;
    let ctx = Ctx {
        case,
        drive,
        cut: &cut,
        prog: &prog,
        bound_s: cmp.oracle_time_s,
    };
    let mut out = vec![
        ctx.row("constant, programmed feeds".into(), None, &cmp.programmed),
        ctx.row(
            format!("constant, safe {:.2} ipm", cmp.safe_feed_ipm),
            None,
            &cmp.safe,
        ),
    ];
    if published {
        let paper = AcSettings {
            peak_windows: 1,
            ..acs
        };
        let run = acsim::run_with(&prog, settings, &cut, Some(paper), false)?;
        out.push(ctx.row("paper's FRC as published".into(), None, &run));
    }
    for &strategy in strategies {
        let run = acsim::run(&prog, settings, &cut, Some(AcSettings { strategy, ..acs }))?;
        out.push(ctx.row(
            acreport::ac_label(strategy).to_string(),
            Some(strategy),
            &run,
        ));
    }
    Ok((out, cmp))
}

/// The table's header (markdown).
pub const HEADER: &str = "| program | drive | schedule | time s | time / bound | peak F / F_max | time above F0 s | time above F_max s | overshoot % | holds |\n| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |";

/// One row of the table (markdown).
pub fn markdown(r: &Row) -> String {
    format!(
        "| {} | {} | {} | {:.2} | {:.3} | {:.3} | {:.3} | {:.3} | {:.1} | {} |",
        r.program,
        r.drive,
        r.schedule,
        r.time_s,
        r.time_s / r.bound_s,
        r.peak_force_ratio,
        r.time_above_f0_s,
        r.time_above_limit_s,
        r.overshoot_pct,
        r.holds
    )
}

/// The bound's row (markdown).
pub fn bound_markdown(case: &Case, drive: DriveModel, bound_s: f64) -> String {
    format!(
        "| {} | {} | bound (oracle) | {bound_s:.2} | 1.000 | - | - | - | - | - |",
        case.name,
        drive_name(drive)
    )
}
