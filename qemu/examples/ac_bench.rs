//! AC benchmark (host): machining time relative to the oracle and peak force relative to the
//! permissible limit on the Fig. 1 cavity and on a pocket after the thesis' Fig. 5.8, for constant
//! feeds and for the paper's strategy (as published, and with this project's two additions:
//! anti-windup and a peak held over 3 windows). Host-native runs of the same Frame and
//! AcController code as the firmware, against the simulated cut (steel, 0.5 in 4-flute, 600 rpm).
//!
//! ```text
//! cargo run -p millac-qemu --release --example ac_bench [-- --accel IN_PER_S2] [--strategy NAME|all] [--drive stepper|servo]
//! ```
//!
//! `--accel` sets the acceleration limit of every axis (`$120`..`$122`, default the settings'
//! 25 in/s^2): the frame ramps every feed change at it, which the AC's loop sees as actuator lag.
//! `--strategy` chooses the feed law of the AC rows (`$251`: paper, integral, mrac, gpc; default
//! paper, the paper's two rows); `all` gives the paper's rows and one row for each other law
//! (each with the anti-windup and the 3-window peak), before the oracle's.
use anyhow::Result;
use millac::ac::law::Strategy;
use millac::ac::AcSettings;
use millac::Settings;
use millac_plant::Stock;
use millac_qemu::acsim::{self, Cut};
use millac_qemu::{acreport, analysis};

fn main() -> Result<()> {
    let mut settings = Settings::default();
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--accel") {
        let a: f64 = args
            .get(i + 1)
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| anyhow::anyhow!("--accel needs in/s^2"))?;
        // BLU/s^2 at the settings' BLU (0.0001 in).
        let blu = (a * 10_000.0).round() as u32;
        settings.accel_blu_s2 = [blu; 3];
        settings
            .validate()
            .map_err(|e| anyhow::anyhow!("--accel {a}: {}", e.message()))?;
    }
    let strategies: Vec<Strategy> = match args.iter().position(|a| a == "--strategy") {
        None => vec![Strategy::Paper],
        Some(i) => match args.get(i + 1).map(String::as_str) {
            Some("all") => Strategy::ALL.to_vec(),
            Some(name) => vec![Strategy::from_name(name).ok_or_else(|| {
                anyhow::anyhow!("--strategy {name}: not paper, integral, mrac, gpc or all")
            })?],
            None => anyhow::bail!("--strategy needs paper, integral, mrac, gpc or all"),
        },
    };
    let drive = match args.iter().position(|a| a == "--drive") {
        None => millac_plant::DriveModel::Stepper,
        Some(i) => match args.get(i + 1).map(String::as_str) {
            Some("stepper") => millac_plant::DriveModel::Stepper,
            Some("servo") => millac_plant::DriveModel::THESIS,
            _ => anyhow::bail!("--drive needs stepper or servo"),
        },
    };
    println!(
        "acceleration {} in/s^2 per axis, {} drive",
        settings.accel_blu_s2[0] as f64 / 10_000.0,
        if drive == millac_plant::DriveModel::Stepper {
            "stepper"
        } else {
            "servo (thesis appendix B)"
        }
    );
    let cases = [
        (
            "Fig. 1 cavity",
            include_str!("../programs/fig1-cavity.nc"),
            None,
        ),
        (
            "pocket (Fig. 5.8)",
            include_str!("../programs/pocket.nc"),
            Some(include_str!("../programs/pocket.stock")),
        ),
    ];
    println!("| program | strategy | time s | time / oracle | peak F / F_max | time above F0 s | time above F_max s | holds |");
    println!("| --- | --- | ---: | ---: | ---: | ---: | ---: | --- |");
    for (name, text, stock) in cases {
        let prog = analysis::load_program(text, &settings).map_err(|e| anyhow::anyhow!("{e}"))?;
        let stock = stock
            .map_or_else(|| Ok(Stock::default()), Stock::parse)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let cut = Cut {
            drive,
            ..Cut::steel(stock, 1)
        };
        let acs = AcSettings::default();
        let cmp = acreport::compare(&prog, &settings, &cut, &acs)?;
        let oracle = cmp.oracle_time_s;
        let row = |strategy: &str, run: &acsim::HostRun| {
            let l = acsim::load_figures(&run.samples, &cut.tool, 0.9, acs.sample_hz);
            let done = run.final_position == prog.last().map_or([0; 3], |b| b.end).map(i64::from);
            println!(
                "| {name} | {strategy} | {:.2} | {:.3} | {:.3} | {:.3} | {:.3} | {} |",
                run.machining_time_s,
                run.machining_time_s / oracle,
                l.peak_force_ratio,
                l.time_above_f0_s,
                l.time_above_limit_s,
                if run.held {
                    "held (overload), stopped in the cut"
                } else if done {
                    "none"
                } else {
                    "?"
                }
            );
        };
        row("constant, programmed feeds", &cmp.programmed);
        row(
            &format!("constant, safe {:.2} ipm", cmp.safe_feed_ipm),
            &cmp.safe,
        );
        for &strategy in &strategies {
            if strategy == Strategy::Paper {
                let paper = AcSettings {
                    peak_windows: 1,
                    ..acs
                };
                row(
                    "paper's FRC as published",
                    &acsim::run_with(&prog, &settings, &cut, Some(paper), false)?,
                );
                row(
                    "paper's FRC + anti-windup + 3-window peak",
                    &acsim::run(&prog, &settings, &cut, Some(acs))?,
                );
                continue;
            }
            let label = match strategy {
                Strategy::Integral => "integral law (Ulsoy et al. Eq. 2)",
                Strategy::Gpc => "GPC (Munasinghe 3.1.4)",
                _ => "MRAC (Ulsoy et al. Eqs. 3-4)",
            };
            row(
                &format!("{label} + anti-windup + 3-window peak"),
                &acsim::run(&prog, &settings, &cut, Some(AcSettings { strategy, ..acs }))?,
            );
        }
        println!("| {name} | oracle (bound) | {oracle:.2} | 1.000 | - | - | - | - |");
    }
    Ok(())
}
