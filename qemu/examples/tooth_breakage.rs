//! The thesis' Fig. 3.7 on the simulated plant (host example, run by hand): the average resultant
//! force per tooth period of a full-width slot at a constant feed (no AC) with run-out on one
//! tooth and a tooth breaking at a given time; writes out/tooth-breakage.svg and prints the mean
//! per tooth before and after the break.
//!
//! `cargo run -p millac-qemu --release --example tooth_breakage [-- RUNOUT_UM BREAK_S]`
//! (defaults 10 um of run-out on tooth 0, tooth 1 broken at 7 s): 0.5 in four-flute end mill,
//! steel, 600 rpm, 0.2 in deep, 12 ipm (0.127 mm per tooth), X-0.5 to X1.5 in, ADC at 1 kHz.
use anyhow::Result;
use millac_plant::{Material, Process, Stock, Tool, Transducer, DEFAULT_RPM};
use plotters::prelude::*;

fn main() -> Result<()> {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    let runout_um = args.first().copied().unwrap_or(10.0);
    let t_break = args.get(1).copied().unwrap_or(7.0);
    let z = 4u32;
    let mut p = Process::new(
        Stock::parse("blank X0 Y0 W5 H3 Z0")?,
        Tool::default(),
        Material::STEEL,
        DEFAULT_RPM,
        1,
        Transducer::default(),
    )?
    .with_runout(&[runout_um / 1000.0, 0.0, 0.0, 0.0])?
    .break_tooth(1, t_break)?;
    // 12 ipm = 2000 BLU/s from in; half a sample of offset so the periods' samples sit
    // symmetrically about the teeth's entry angles.
    let rate = 1000.0;
    let t0 = 0.5 / rate;
    let per_period = (rate * 60.0 / DEFAULT_RPM / z as f64).round() as usize;
    let mut periods: Vec<(i64, f64, usize)> = Vec::new();
    for i in 0..10_000usize {
        let t = t0 + i as f64 / rate;
        let x = -5000 + (2000.0 * i as f64 / rate).round() as i64;
        let s = p.sample(t, [x, 15000, -2000]);
        let period = (z as f64 * (DEFAULT_RPM / 60.0 * t + 0.25)).floor() as i64;
        match periods.last_mut() {
            Some(o) if o.0 == period => {
                o.1 += s.f_true_n;
                o.2 += 1;
            }
            _ => periods.push((period, s.f_true_n, 1)),
        }
    }
    // Whole periods with the tool fully in the slot (X > 0.3 in: after 4 s).
    let pts: Vec<(i64, f64)> = periods
        .into_iter()
        .filter(|o| o.2 == per_period && o.0 as f64 / (z as f64 * DEFAULT_RPM / 60.0) > 4.0)
        .map(|(n, sum, k)| (n, sum / k as f64))
        .collect();
    let break_period = (z as f64 * (DEFAULT_RPM / 60.0 * t_break + 0.25)).floor() as i64;
    println!("mean resultant force per tooth period, N (tooth entering the cut):");
    println!("| tooth | before the break | after |");
    println!("| ---: | ---: | ---: |");
    for k in 0..z as i64 {
        let m = |after: bool| {
            let v: Vec<f64> = pts
                .iter()
                .filter(|(n, _)| n.rem_euclid(z as i64) == k && (*n > break_period) == after)
                .filter(|(n, _)| *n != break_period)
                .map(|(_, f)| *f)
                .collect();
            v.iter().sum::<f64>() / v.len() as f64
        };
        println!("| {k} | {:.0} | {:.0} |", m(false), m(true));
    }
    std::fs::create_dir_all("out")?;
    let path = std::path::Path::new("out/tooth-breakage.svg");
    let root = SVGBackend::new(path, (1100, 420)).into_drawing_area();
    root.fill(&WHITE)?;
    let (n0, n1) = (pts[0].0, pts[pts.len() - 1].0);
    let f_top = pts.iter().map(|p| p.1).fold(0.0, f64::max) * 1.15;
    let mut c = ChartBuilder::on(&root)
        .caption(
            format!(
                "Mean resultant force per tooth period: slot, 4 flutes, 12 ipm, {runout_um} um \
                 run-out on tooth 0, tooth 1 broken at {t_break} s (period {break_period})"
            ),
            ("sans-serif", 16),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(n0 as f64..n1 as f64, 0.0..f_top)?;
    c.configure_mesh()
        .x_desc("tooth period")
        .y_desc("mean F, N")
        .draw()?;
    c.draw_series(LineSeries::new(
        pts.iter().map(|(n, f)| (*n as f64, *f)),
        &BLUE,
    ))?;
    c.draw_series(LineSeries::new(
        [(break_period as f64, 0.0), (break_period as f64, f_top)],
        &RED,
    ))?;
    root.present()?;
    println!("wrote {}", path.display());
    Ok(())
}
