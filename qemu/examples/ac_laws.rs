//! The feed laws on Ulsoy, Koren and Lauderbaugh's simulated process (host): their Figs. 2 and 3
//! reproduced with millac's laws (`millac::ac::law::depth_step_model`: y(k) = 0.1 y(k-1) + b0
//! u(k-1), the depth of cut 1 -> 2 -> 3 mm at equal lengths, every law tuned for 1 mm). Writes
//! `out/laws/depth-steps.svg` (load F/F0 against time, one panel per law) and prints, per law
//! and depth, the largest deviation from the reference after 20 periods and the spread of the
//! last 100 periods.
//!
//! ```text
//! cargo run -p millac-qemu --release --example ac_laws
//! ```
//!
//! This is the papers' own process model, not the simulated cut: the reproduction on the
//! simulated cutting process (a slot whose depth steps) is the next step of issue 9.
use anyhow::Result;
use millac::ac::law::{depth_step_model, Strategy};
use plotters::prelude::*;

const PERIODS: usize = 300;
/// The papers' 10 s at three depths: 10 ms AC periods would be 1000 per depth; 300 show the
/// same behaviour and keep the figure readable.
const PERIOD_S: f64 = 0.01;

fn main() -> Result<()> {
    let laws = [
        ("paper's FRC", Strategy::Paper),
        ("integral (Eq. 2)", Strategy::Integral),
        ("MRAC (Eqs. 3-4)", Strategy::Mrac),
        ("GPC (thesis 3.1.4)", Strategy::Gpc),
    ];
    let runs: Vec<(&str, Vec<f32>)> = laws
        .iter()
        .map(|(name, s)| {
            let mut y = Vec::new();
            depth_step_model(*s, PERIODS, |v, _| y.push(v));
            (*name, y)
        })
        .collect();

    println!(
        "| law | depth mm | max abs(F/F0 - 1) after 20 periods | spread of the last 100 periods |"
    );
    println!("| --- | ---: | ---: | ---: |");
    for (name, y) in &runs {
        for d in 0..3 {
            let seg = &y[d * PERIODS + 20..(d + 1) * PERIODS];
            let worst = seg.iter().map(|v| (v - 1.0).abs()).fold(0.0f32, f32::max);
            let last = &y[(d + 1) * PERIODS - 100..(d + 1) * PERIODS];
            let hi = last.iter().cloned().fold(f32::MIN, f32::max);
            let lo = last.iter().cloned().fold(f32::MAX, f32::min);
            println!("| {name} | {} | {worst:.3} | {:.3} |", d + 1, hi - lo);
        }
    }

    let dir = std::path::Path::new("out/laws");
    std::fs::create_dir_all(dir)?;
    let path = dir.join("depth-steps.svg");
    {
        let root = SVGBackend::new(&path, (1100, 1000)).into_drawing_area();
        root.fill(&WHITE)?;
        let panels = root.split_evenly((runs.len(), 1));
        let t_end = (3 * PERIODS) as f64 * PERIOD_S;
        for (panel, (name, y)) in panels.iter().zip(&runs) {
            let mut chart = ChartBuilder::on(panel)
                .caption(
                    format!("{name}: depth 1 -> 2 -> 3 mm, tuned at 1 mm"),
                    ("sans-serif", 18),
                )
                .margin(8)
                .x_label_area_size(30)
                .y_label_area_size(50)
                .build_cartesian_2d(0.0..t_end, 0.0f64..2.5)?;
            chart
                .configure_mesh()
                .x_desc("time s (10 ms periods)")
                .y_desc("F / F0")
                .draw()?;
            chart.draw_series(LineSeries::new(
                [(0.0, 1.0), (t_end, 1.0)],
                BLACK.mix(0.4).stroke_width(1),
            ))?;
            for d in 1..3 {
                let x = (d * PERIODS) as f64 * PERIOD_S;
                chart.draw_series(LineSeries::new(
                    [(x, 0.0), (x, 2.5)],
                    BLACK.mix(0.25).stroke_width(1),
                ))?;
            }
            chart.draw_series(LineSeries::new(
                y.iter()
                    .enumerate()
                    .map(|(k, v)| (k as f64 * PERIOD_S, (*v as f64).clamp(0.0, 2.5))),
                BLUE.stroke_width(2),
            ))?;
        }
        root.present()?;
    }
    println!("wrote {}", path.display());
    Ok(())
}
