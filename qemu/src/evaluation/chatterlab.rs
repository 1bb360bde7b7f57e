//! The thesis' chatter test (Munasinghe 1994, table 3.2 and Fig. 3.10) on the host: the plant's
//! time-domain chatter model (`millac_plant::chatter`, the table 3.2 preset) heard by its
//! microphone at 5 kHz, the core's chatter detector (`millac::monitor::chatter`, the firmware's
//! code) judging every 256-sample record. The `chatter_thesis` example draws the figure; the
//! tests check the detection. Host only.
use anyhow::{anyhow, Context, Result};
use millac::monitor::chatter::{ChatterDetector, ChatterSettings, Spectrum, RECORD};
use millac_plant::chatter::{thesis_table_3_2 as t, Listener, Microphone};
use plotters::prelude::*;
use std::path::Path;

/// The table 3.2 preset as a simulated cut of a program: a slot at `depth_in` from X0.2 to
/// `to_x` at F6 (the preset's 0.0508 mm per tooth at 1500 rpm) in an aluminium block, started in
/// a drilled hole; the tool flexible with the preset's mode in X and Y, heard by the microphone.
/// The program's text and the cut (for `acsim` and the QEMU runs alike).
pub fn preset_slot(depth_in: f64, to_x: f64) -> (String, crate::host::acsim::Cut) {
    use millac_plant::{Material, Stock, Tool};
    let text = format!("G20 G90\nG0 X0.2 Y1\nG0 Z-{depth_in}\nG1 X{to_x} F6\nG0 Z0.1\nM2\n");
    let stock = Stock::parse("blank X0 Y0 W4 H2 Z0\nhole X0.2 Y1 D0.625 Z-0.4\n")
        .expect("the preset's stock parses");
    let cut = crate::host::acsim::Cut {
        tool: Tool {
            diameter_mm: t::DIAMETER_MM,
            flutes: t::FLUTES,
            ..Tool::default()
        },
        material: Material::ALUMINIUM,
        spindle_rpm: t::RPM,
        modes: Some((vec![t::MODE], vec![t::MODE])),
        ..crate::host::acsim::Cut::steel(stock, 1)
    };
    (text, cut)
}

/// The table 3.2 cut as a through slot for chatter suppression: from a drilled hole at X0.2 out
/// of a 1 in (25.4 mm) wide aluminium block at `depth_in`, F6, then up. The hole (20.3 mm) is
/// wider than the tool (15.9 mm) and the slot runs out of the block, because the plant's side-chip
/// probe reads up to about 2 mm ahead of the tool (see `millac_plant::process`): a re-plan's lower
/// layer ending at a closed slot end, or a rapid back to a stop next to the wall of a hole of the
/// tool's size, would read material the tool never reaches.
pub fn through_slot(depth_in: f64) -> (String, crate::host::acsim::Cut) {
    let (_, cut) = preset_slot(depth_in, 1.6);
    let text = format!("G20 G90\nG0 X0.2 Y1\nG0 Z-{depth_in}\nG1 X1.6 F6\nG0 Z0.1\nM2\n");
    let stock = millac_plant::Stock::parse("blank X0 Y0 W1 H2 Z0\nhole X0.2 Y1 D0.8 Z-0.4\n")
        .expect("the slot's stock parses");
    (text, crate::host::acsim::Cut { stock, ..cut })
}

/// The table 3.2 tool in a high-speed cut, where its stability lobes are wide (for the chatter
/// reaction by spindle speed, `$277`): the through slot of [`through_slot`] at `depth_in`, the
/// program's `S{rpm}` and F30 (0.027 mm per tooth at 14 000 rpm). In this plant the preset's
/// tool at 4 mm chatters at 14 000 rpm and is stable between about 11 750 and 12 750 rpm and
/// between 15 000 and 17 500 (the time-domain model's lobes; docs/dev/monitors.md).
pub fn high_speed_slot(depth_in: f64, rpm: u32) -> (String, crate::host::acsim::Cut) {
    let (_, cut) = through_slot(depth_in);
    let text =
        format!("G20 G90\nS{rpm} M3\nG0 X0.2 Y1\nG0 Z-{depth_in}\nG1 X1.6 F30\nG0 Z0.1\nM2\n");
    (
        text,
        crate::host::acsim::Cut {
            spindle_rpm: f64::from(rpm),
            ..cut
        },
    )
}

/// The chatter threshold by the thesis' rule: twice the largest amplitude the chatter monitor
/// hears (`AcSettings` `listen`, its threshold out of reach) over `prog` on `cut`, a chatter-free
/// cut, run on the host with the firmware's code.
pub fn thesis_threshold(
    prog: &[crate::analysis::ProgBlock],
    settings: &millac::Settings,
    cut: &crate::host::acsim::Cut,
    listen: millac::ac::AcSettings,
) -> Result<f32> {
    let listen = millac::ac::AcSettings {
        chatter_threshold: f32::MAX,
        ..listen
    };
    let quiet = crate::host::acsim::run_with_faults(prog, settings, cut, Some(listen), true, &[])?
        .spectra
        .iter()
        .map(|(_, sp)| sp.peak_amplitude)
        .fold(0.0, f32::max);
    Ok(2.0 * quiet)
}

/// Sound sample rate, Hz (the detector's default).
pub const SOUND_HZ: u32 = 5000;

/// One cut of the experiment: every detection cycle's spectrum (the detector's threshold is
/// `threshold`), and per cycle the plant's own measure of the regenerative vibration (the RMS of
/// x(t) - x(t - T) over the cycle, m).
#[derive(Clone, Debug)]
pub struct ChatterRun {
    pub depth_mm: f64,
    pub cycles: Vec<Spectrum>,
    pub wave_rms_m: Vec<f64>,
}

/// Cuts the preset's slot at `depth_mm` for `records` detection cycles (each 256 sound samples,
/// 51.2 ms at 5 kHz), the tool disturbed by 1 um after two revolutions as a tooth's impact
/// would, with microphone noise seed `seed`.
pub fn run(depth_mm: f64, records: usize, threshold: f32, seed: u64) -> Result<ChatterRun> {
    let mut sim = t::sim(depth_mm).ok_or_else(|| anyhow!("preset cut at {depth_mm} mm"))?;
    let mut mic = Listener::new(Microphone::default(), f64::from(SOUND_HZ), seed);
    let settings = ChatterSettings {
        sound_hz: SOUND_HZ,
        threshold,
        ..ChatterSettings::default()
    };
    let mut det = ChatterDetector::new(
        settings
            .validated()
            .map_err(|e| anyhow!("{}", e.message()))?,
    );
    let per_tooth = (60.0 / (t::RPM * f64::from(t::FLUTES)) / sim.dt()).round() as usize;
    let perturb_at = 2.0 * 60.0 / t::RPM;
    let mut past: std::collections::VecDeque<(f64, f64)> = std::collections::VecDeque::new();
    let (mut cycles, mut wave_rms_m) = (Vec::new(), Vec::new());
    let (mut sum2, mut count) = (0.0, 0usize);
    let mut perturbed = false;
    while cycles.len() < records {
        if !perturbed && sim.time_s() >= perturb_at {
            sim.perturb(1e-6, 1e-6);
            perturbed = true;
        }
        let s = sim.step();
        past.push_back((s.x_m, s.y_m));
        if past.len() > per_tooth {
            if let Some((x0, y0)) = past.pop_front() {
                sum2 += (s.x_m - x0).powi(2) + (s.y_m - y0).powi(2);
                count += 1;
            }
        }
        if let Some(code) = mic.hear(&s) {
            let v = f32::from(code) - Microphone::default().offset as f32;
            if let Some(spec) = det.push(v, t::RPM as u32, t::FLUTES) {
                cycles.push(spec);
                wave_rms_m.push((sum2 / count.max(1) as f64).sqrt());
                (sum2, count) = (0.0, 0);
            }
        }
    }
    Ok(ChatterRun {
        depth_mm,
        cycles,
        wave_rms_m,
    })
}

/// The thesis' threshold rule: from a chatter-free cut's largest amplitude over its cycles,
/// times `margin`.
pub fn threshold_from(stable: &ChatterRun, margin: f32) -> f32 {
    stable
        .cycles
        .iter()
        .map(|c| c.peak_amplitude)
        .fold(0.0, f32::max)
        * margin
}

/// Fig. 3.10: the largest spectrum amplitude per detection cycle of each run, and the threshold.
pub fn plot(path: &Path, runs: &[ChatterRun], threshold: f32) -> Result<()> {
    let root = SVGBackend::new(path, (900, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let n = runs.iter().map(|r| r.cycles.len()).max().unwrap_or(1);
    let top = runs
        .iter()
        .flat_map(|r| r.cycles.iter().map(|c| c.peak_amplitude))
        .fold(threshold, f32::max)
        * 1.1;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "Largest sound spectrum amplitude per detection cycle ({} points at {} Hz; table 3.2, as Fig. 3.10)",
                RECORD, SOUND_HZ
            ),
            ("sans-serif", 16),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(0f32..n as f32, (0.1f32..top).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("chatter detection cycle")
        .y_desc("amplitude, codes (log)")
        .draw()?;
    let colors = [BLUE, RED, GREEN, MAGENTA];
    for (i, r) in runs.iter().enumerate() {
        let color = colors[i % colors.len()];
        chart
            .draw_series(LineSeries::new(
                r.cycles
                    .iter()
                    .enumerate()
                    .map(|(k, c)| (k as f32, c.peak_amplitude.max(0.1))),
                color.stroke_width(2),
            ))?
            .label(format!("depth {} mm", r.depth_mm))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
    }
    chart
        .draw_series(LineSeries::new(
            [(0.0, threshold), (n as f32, threshold)],
            BLACK.stroke_width(1),
        ))?
        .label("threshold")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Chatter suppression on the host (as the thesis' Fig. 5.15 with the passes): above, the largest
/// sound amplitude of every detection cycle against time with the threshold and the re-plans;
/// below, the tool's height and X position (mm) over the run, one AC period per point.
pub fn plot_suppression(
    path: &Path,
    run: &crate::host::acsim::HostRun,
    threshold: f32,
) -> Result<()> {
    let root = SVGBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let (upper, lower) = root.split_vertically(340);
    let t_end = run.rows.last().map_or(1.0, |r| r.t_ms as f64 / 1000.0);
    let top = run
        .spectra
        .iter()
        .map(|(_, s)| s.peak_amplitude)
        .fold(threshold, f32::max) as f64
        * 1.3;
    let mut chart = ChartBuilder::on(&upper)
        .caption(
            "Table 3.2 slot at 8.89 mm, chatter suppressed by 1 mm depth steps: largest sound amplitude per detection cycle (as Fig. 5.15)",
            ("sans-serif", 15),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(55)
        .build_cartesian_2d(0f64..t_end, (0.1f64..top).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc("amplitude, codes (log)")
        .draw()?;
    chart
        .draw_series(LineSeries::new(
            run.spectra
                .iter()
                .map(|(t, s)| (*t, f64::from(s.peak_amplitude).max(0.1))),
            BLUE.stroke_width(1),
        ))?
        .label("largest amplitude away from the tooth harmonics")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    chart
        .draw_series(LineSeries::new(
            [(0.0, f64::from(threshold)), (t_end, f64::from(threshold))],
            BLACK.stroke_width(1),
        ))?
        .label("threshold (2 x the 2.54 mm cut's largest)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    chart
        .draw_series(
            run.replans
                .iter()
                .map(|(t, _)| PathElement::new(vec![(*t, 0.1), (*t, top)], RED.stroke_width(1))),
        )?
        .label("re-plan: depth reduced by 1 mm")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
    crate::evaluation::plot::legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    // The runs' BLU (the default settings').
    let (num, den) = millac::Settings::default().blu.per_mm();
    let mm = |blu: i64| blu as f64 * den as f64 / num as f64;
    let x_max = run
        .rows
        .iter()
        .map(|r| mm(r.pos_blu[0]))
        .fold(1.0, f64::max);
    let z_min = run
        .rows
        .iter()
        .map(|r| mm(r.pos_blu[2]))
        .fold(0.0, f64::min);
    let mut chart = ChartBuilder::on(&lower)
        .caption(
            "Tool height Z and position X (mm): the passes",
            ("sans-serif", 15),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .right_y_label_area_size(55)
        .build_cartesian_2d(0f64..t_end, (z_min - 0.5)..1.0)?
        .set_secondary_coord(0f64..t_end, 0f64..x_max * 1.05);
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc("Z, mm")
        .draw()?;
    chart.configure_secondary_axes().y_desc("X, mm").draw()?;
    chart
        .draw_series(LineSeries::new(
            run.rows
                .iter()
                .map(|r| (r.t_ms as f64 / 1000.0, mm(r.pos_blu[2]))),
            RED.stroke_width(2),
        ))?
        .label("Z")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
    chart
        .draw_secondary_series(LineSeries::new(
            run.rows
                .iter()
                .map(|r| (r.t_ms as f64 / 1000.0, mm(r.pos_blu[0]))),
            BLUE.stroke_width(1),
        ))?
        .label("X")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    crate::evaluation::plot::legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// The chatter reaction by spindle speed against the depth steps on the same cut
/// ([`high_speed_slot`]): above, the largest sound amplitude per detection cycle of both runs
/// with the threshold, the speed changes and the re-plans; below, the spindle speed of the `$277`
/// run and the X position of both (the depth steps' extra passes).
pub fn plot_speed(
    path: &Path,
    speed: &crate::host::acsim::HostRun,
    depth: &crate::host::acsim::HostRun,
    threshold: f32,
    rpm: u32,
) -> Result<()> {
    let root = SVGBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let (upper, lower) = root.split_vertically(360);
    let end =
        |r: &crate::host::acsim::HostRun| r.rows.last().map_or(1.0, |r| r.t_ms as f64 / 1000.0);
    let t_end = end(speed).max(end(depth));
    let top = speed
        .spectra
        .iter()
        .chain(depth.spectra.iter())
        .map(|(_, s)| s.peak_amplitude)
        .fold(threshold, f32::max) as f64
        * 1.5;
    let grey = RGBColor(150, 150, 150);
    let green = RGBColor(0, 150, 0);
    let mut chart = ChartBuilder::on(&upper)
        .caption(
            "Table 3.2 tool, 4 mm slot at 14 000 rpm: largest sound amplitude per detection cycle",
            ("sans-serif", 15),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(55)
        .build_cartesian_2d(0f64..t_end, (0.1f64..top).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc("amplitude, codes (log)")
        .draw()?;
    let amp = |r: &crate::host::acsim::HostRun| {
        r.spectra
            .iter()
            .map(|(t, s)| (*t, f64::from(s.peak_amplitude).max(0.1)))
            .collect::<Vec<_>>()
    };
    chart
        .draw_series(LineSeries::new(amp(depth), grey.stroke_width(1)))?
        .label("$276 depth steps only")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey));
    chart
        .draw_series(LineSeries::new(amp(speed), BLUE.stroke_width(1)))?
        .label("$277 spindle speed first")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    chart
        .draw_series(LineSeries::new(
            [(0.0, f64::from(threshold)), (t_end, f64::from(threshold))],
            BLACK.stroke_width(1),
        ))?
        .label("threshold (2 x the 2 mm cut's largest)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    chart
        .draw_series(
            speed
                .speeds
                .iter()
                .map(|(t, _)| PathElement::new(vec![(*t, 0.1), (*t, top)], green.stroke_width(2))),
        )?
        .label("spindle speed changed")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], green));
    chart
        .draw_series(
            depth
                .replans
                .iter()
                .map(|(t, _)| PathElement::new(vec![(*t, 0.1), (*t, top)], RED.stroke_width(1))),
        )?
        .label("re-plan: depth reduced by 1 mm")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
    crate::evaluation::plot::legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    let (num, den) = millac::Settings::default().blu.per_mm();
    let mm = |blu: i64| blu as f64 * den as f64 / num as f64;
    let x_max = speed
        .rows
        .iter()
        .chain(depth.rows.iter())
        .map(|r| mm(r.pos_blu[0]))
        .fold(1.0, f64::max);
    // The spindle speed as a step line: the program's, then each change.
    let mut steps = vec![(0.0, f64::from(rpm))];
    for (t, s) in &speed.speeds {
        steps.push((*t, f64::from(s.from)));
        steps.push((*t, f64::from(s.to)));
    }
    steps.push((end(speed), steps.last().map_or(f64::from(rpm), |p| p.1)));
    let mut chart = ChartBuilder::on(&lower)
        .caption(
            "Spindle speed of the $277 run (rpm) and X of both runs (mm)",
            ("sans-serif", 15),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(65)
        .right_y_label_area_size(55)
        .build_cartesian_2d(0f64..t_end, 10_000f64..16_000f64)?
        .set_secondary_coord(0f64..t_end, 0f64..x_max * 1.05);
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc("spindle, rpm")
        .draw()?;
    chart.configure_secondary_axes().y_desc("X, mm").draw()?;
    chart
        .draw_series(LineSeries::new(steps, green.stroke_width(2)))?
        .label("spindle speed ($277 run)")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], green));
    let xs = |r: &crate::host::acsim::HostRun| {
        r.rows
            .iter()
            .map(|r| (r.t_ms as f64 / 1000.0, mm(r.pos_blu[0])))
            .collect::<Vec<_>>()
    };
    chart
        .draw_secondary_series(LineSeries::new(xs(depth), grey.stroke_width(1)))?
        .label("X, depth steps")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey));
    chart
        .draw_secondary_series(LineSeries::new(xs(speed), BLUE.stroke_width(1)))?
        .label("X, spindle speed")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    crate::evaluation::plot::legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
