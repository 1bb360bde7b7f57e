//! AC benchmark (host): every feed law on every benchmark program (`millac_qemu::evaluation::bench::CASES`),
//! with the stepper and the servo drive, against the constant feeds and the bound: machining time
//! relative to the bound, peak force relative to the permissible limit, time above F0 and above
//! the limit, overshoot and holds, as one markdown table; then the best clean law per program
//! and drive. Host-native runs of the same Frame and AcController code as the firmware, against
//! the simulated cut (steel, 0.5 in 4-flute, the program's S or 600 rpm).
//!
//! ```text
//! cargo run -p millac-qemu --release --example ac_bench [-- --accel IN_PER_S2] [--strategy NAME|all] [--drive stepper|servo|both] [--published] [--ks-exponent M] [--f0-fraction F]
//! ```
//!
//! `--accel` sets the acceleration limit of every axis (`$120`..`$122`, default the settings'
//! 25 in/s^2): the frame ramps every feed change at it, which the AC's loop sees as actuator lag.
//! `--strategy` chooses the feed laws of the AC rows (`$251`: paper, integral, mrac, gpc; default
//! all); `--drive` the feed drives (default both); `--published` adds the paper's FRC as
//! published (no anti-windup, the peak of one window). `--ks-exponent M` gives the steel
//! Kienzle's size effect, Ks(h) = 2000 N/mm^2 x (h / 0.1 mm)^-M (default 0: constant Ks).
//! `--f0-fraction F` runs every program at F0 = F x the permissible limits (the overload hold
//! at 99 % of them), instead of each program's own (`bench::Case::optimal_fraction`): with 0.9,
//! the default, the step programs show what a step larger than the hold's margin does.
use anyhow::Result;
use millac::ac::law::Strategy;
use millac::Settings;
use millac_plant::DriveModel;
use millac_qemu::evaluation::bench::{self, Row};

fn main() -> Result<()> {
    let mut settings = Settings::default();
    let args: Vec<String> = std::env::args().collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .map(|i| args.get(i + 1).map(String::as_str))
    };
    if let Some(v) = value("--accel") {
        let a: f64 = v
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| anyhow::anyhow!("--accel needs in/s^2"))?;
        // BLU/s^2 at the settings' BLU (0.0001 in).
        let blu = (a * 10_000.0).round() as u32;
        settings.accel_blu_s2 = [blu; 3];
        settings
            .validate(&millac::settings::BoardLimits::GENERIC)
            .map_err(|e| anyhow::anyhow!("--accel {a}: {}", e.message()))?;
    }
    let strategies: Vec<Strategy> = match value("--strategy") {
        None | Some(Some("all")) => Strategy::ALL.to_vec(),
        Some(Some(name)) => vec![Strategy::from_name(name).ok_or_else(|| {
            anyhow::anyhow!("--strategy {name}: not paper, integral, mrac, gpc or all")
        })?],
        Some(None) => anyhow::bail!("--strategy needs paper, integral, mrac, gpc or all"),
    };
    let drives = match value("--drive") {
        None | Some(Some("both")) => vec![DriveModel::Stepper, DriveModel::THESIS],
        Some(Some("stepper")) => vec![DriveModel::Stepper],
        Some(Some("servo")) => vec![DriveModel::THESIS],
        _ => anyhow::bail!("--drive needs stepper, servo or both"),
    };
    let published = args.iter().any(|a| a == "--published");
    let ks_exponent: f64 = match value("--ks-exponent") {
        None => 0.0,
        Some(v) => v
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| anyhow::anyhow!("--ks-exponent needs a number in [0, 1)"))?,
    };
    let fraction: Option<f32> = match value("--f0-fraction") {
        None => None,
        Some(v) => Some(
            v.and_then(|v| v.parse().ok())
                .filter(|f: &f32| *f > 0.0 && *f < 1.0)
                .ok_or_else(|| anyhow::anyhow!("--f0-fraction needs a number in (0, 1)"))?,
        ),
    };
    let cases: Vec<bench::Case> = bench::CASES
        .iter()
        .map(|c| bench::Case {
            optimal_fraction: fraction.or(c.optimal_fraction),
            ..*c
        })
        .collect();
    let material = millac_plant::Material {
        ks_exponent,
        ..millac_plant::Material::STEEL
    };
    println!(
        "acceleration {} in/s^2 per axis; servo = the thesis' position loop (appendix B); Ks exponent {ks_exponent}\n",
        settings.accel_blu_s2[0] as f64 / 10_000.0
    );
    println!("{}", bench::HEADER);
    let mut all: Vec<Row> = Vec::new();
    for case in &cases {
        for &drive in &drives {
            // A bar on a terminal (stderr) while the program's schedules run.
            let label = format!("{} ({})", case.name, bench::drive_name(drive));
            let (rows, cmp) =
                millac_qemu::progress::with_bar(&label, case.load(&settings)?.len(), || {
                    bench::rows(case, &settings, drive, material, &strategies, published)
                })?;
            for r in &rows {
                println!("{}", bench::markdown(r));
            }
            println!("{}", bench::bound_markdown(case, drive, cmp.oracle_time_s));
            all.extend(rows);
        }
    }
    println!("\nBest law per program and drive (finished, no hold, never above the limit):\n");
    println!("| program | drive | best law | time / bound |");
    println!("| --- | --- | --- | ---: |");
    for case in &cases {
        for &drive in &drives {
            let best = all
                .iter()
                .filter(|r| r.program == case.name && r.drive == bench::drive_name(drive))
                .filter(|r| r.strategy.is_some() && r.clean())
                .min_by(|a, b| a.time_s.total_cmp(&b.time_s));
            match best {
                Some(r) => println!(
                    "| {} | {} | {} | {:.3} |",
                    r.program,
                    r.drive,
                    r.strategy.map_or("", |s| s.name()),
                    r.time_s / r.bound_s
                ),
                None => println!(
                    "| {} | {} | none finished cleanly | - |",
                    case.name,
                    bench::drive_name(drive)
                ),
            }
        }
    }
    Ok(())
}
