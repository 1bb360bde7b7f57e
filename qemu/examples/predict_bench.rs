//! The predictive-control benchmark of issue 11 (host; a first version: no combined controller
//! yet): on the benchmark's four programs, the stepped die cavity and the hidden-boss program,
//! the programmed feeds, the safe constant feed, the offline optimised program (full force
//! model), the model-based one (Georgiev and Chetrokov's quadratic, calibrated on the plant),
//! the AC alone (GPC, the default law), the optimised program with the AC under it, and the
//! bound: the oracle with FRM as the only ceiling (any schedule may go up to the machine's
//! fastest feed). Time / bound, peak force / the permissible limit, time above F0 and above the
//! limit, and holds; steel, stepper drive, the firmware's frame and AC code on the host.
//! The hidden-boss program is planned on its described stock and cut on its actual one (the
//! bound on the actual one).
//!
//! ```text
//! cargo run -p millac-qemu --release --example predict_bench
//! ```
use anyhow::Result;
use millac::ac::{AcSettings, FeedCeiling};
use millac::Settings;
use millac_plant::{DriveModel, Material, Stock};

/// The harder material of the model-error rows: Ks this much above the plan's.
const HARDER: f64 = 1.15;
use millac_qemu::acsim::{self, Cut, HostRun};
use millac_qemu::analysis::{self, ProgBlock};
use millac_qemu::optimise::{self, Options};
use millac_qemu::{acreport, bench, model};

struct Program {
    name: &'static str,
    text: &'static str,
    /// The stock the plan is made on, and the stock that is cut.
    described: &'static str,
    actual: &'static str,
    force_limit_n: Option<f64>,
    fraction: Option<f32>,
}

fn programs() -> Vec<Program> {
    let mut v: Vec<Program> = bench::CASES
        .iter()
        .map(|c| Program {
            name: c.name,
            text: c.program,
            described: c.stock.unwrap_or(millac_plant::stock::FIG1_STOCK),
            actual: c.stock.unwrap_or(millac_plant::stock::FIG1_STOCK),
            force_limit_n: c.force_limit_n,
            fraction: c.optimal_fraction,
        })
        .collect();
    v.push(Program {
        name: "stepped die cavity",
        text: include_str!("../programs/stepped-die.nc"),
        described: include_str!("../programs/stepped-die.stock"),
        actual: include_str!("../programs/stepped-die.stock"),
        force_limit_n: None,
        fraction: None,
    });
    v.push(Program {
        name: "hidden boss (pocket, wrong stock)",
        text: include_str!("../programs/hidden-boss.nc"),
        described: include_str!("../programs/hidden-boss.described.stock"),
        actual: include_str!("../programs/hidden-boss.actual.stock"),
        force_limit_n: None,
        fraction: None,
    });
    v
}

fn main() -> Result<()> {
    let only: Option<String> = std::env::args().nth(1);
    let s = Settings::default();
    let steel = Cut::steel(Stock::default(), 1);
    let (m, _) = model::calibrate(
        &steel,
        &[1.0, 4.0, 7.0, 10.0, 13.0, 16.0],
        &[2.0, 7.0, 12.0, 17.0, 22.0, 27.0],
    )?;
    println!("| program | schedule | time s | time / bound | peak F / F_max | time above F0 s | time above F_max s | holds |");
    println!("| --- | --- | ---: | ---: | ---: | ---: | ---: | --- |");
    for p in programs() {
        if only.as_deref().is_some_and(|o| !p.name.contains(o)) {
            continue;
        }
        let case = bench::Case {
            name: p.name,
            program: p.text,
            stock: Some(p.actual),
            force_limit_n: p.force_limit_n,
            optimal_fraction: p.fraction,
        };
        let acs = case.ac_settings();
        let fraction = f64::from(acs.optimal_fraction);
        let actual = case.cut(&s, DriveModel::Stepper, Material::STEEL)?;
        let described = Cut {
            stock: Stock::parse(p.described).map_err(|e| anyhow::anyhow!("{e}"))?,
            ..actual.clone()
        };
        let prog = case.load(&s)?;
        let bound = acreport::compare(
            &prog,
            &s,
            &actual,
            &AcSettings {
                ceiling: FeedCeiling::Frm,
                ..acs
            },
        )?;
        let cmp = acreport::compare(&prog, &s, &actual, &acs)?;
        let opts = Options {
            fraction,
            ..Options::default()
        };
        let load = |text: &str| -> Result<Vec<ProgBlock>> {
            analysis::load_program(text, &s).map_err(|e| anyhow::anyhow!("{e}"))
        };
        let planned = load(&optimise::optimise(p.text, &s, &described, &opts)?.text)?;
        let trusted = load(
            &optimise::optimise(p.text, &s, &described, &Options { guard: 0.0, ..opts })?.text,
        )?;
        let harder = Cut {
            material: Material {
                ks_n_mm2: actual.material.ks_n_mm2 * HARDER,
                ..actual.material
            },
            ..actual.clone()
        };
        let plan = AcSettings {
            ceiling: FeedCeiling::Plan,
            ..acs
        };
        let modelled = load(
            &optimise::optimise(
                p.text,
                &s,
                &described,
                &Options {
                    model: Some(m),
                    ..opts
                },
            )?
            .text,
        )?;
        let rows: Vec<(String, HostRun)> = vec![
            ("programmed feeds".into(), cmp.programmed.clone()),
            (
                format!("safe constant {:.2} ipm", cmp.safe_feed_ipm),
                cmp.safe.clone(),
            ),
            (
                "offline optimised, trusting the stock".into(),
                acsim::run(&trusted, &s, &actual, None)?,
            ),
            (
                "offline optimised, guarded".into(),
                acsim::run(&planned, &s, &actual, None)?,
            ),
            (
                "model-based".into(),
                acsim::run(&modelled, &s, &actual, None)?,
            ),
            (
                "AC alone (GPC)".into(),
                acsim::run(&prog, &s, &actual, Some(acs))?,
            ),
            (
                "optimised + AC (plan as ceiling)".into(),
                acsim::run(&planned, &s, &actual, Some(acs))?,
            ),
            (
                "optimised + AC ($263=2)".into(),
                acsim::run(&planned, &s, &actual, Some(plan))?,
            ),
            (
                "harder: offline optimised".to_string(),
                acsim::run(&planned, &s, &harder, None)?,
            ),
            (
                "harder: optimised + AC ($263=2)".to_string(),
                acsim::run(&planned, &s, &harder, Some(plan))?,
            ),
        ];
        let end = prog.last().map_or([0; 3], |b| b.end).map(i64::from);
        for (name, r) in rows {
            let l = acsim::load_figures(&r.samples, &actual.tool, fraction, acs.sample_hz);
            let holds = match (&r.alarm, r.final_position == end) {
                (Some(a), _) => format!("held: {}", a.message()),
                (None, true) => "none".into(),
                (None, false) => "did not finish".into(),
            };
            println!(
                "| {} | {name} | {:.2} | {:.3} | {:.3} | {:.3} | {:.3} | {holds} |",
                p.name,
                r.machining_time_s,
                r.machining_time_s / bound.oracle_time_s,
                l.peak_force_ratio,
                l.time_above_f0_s,
                l.time_above_limit_s
            );
        }
        println!(
            "| {} | bound (oracle, FRM ceilings) | {:.2} | 1.000 | - | - | - | - |",
            p.name, bound.oracle_time_s
        );
    }
    Ok(())
}
