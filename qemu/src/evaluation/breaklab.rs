//! Tool breakage detection on the simulated cut (host; issue 10): a program run on the host
//! (`acsim`, the firmware's frame and AC code) with the plant's run-out and tooth damage
//! (`millac_plant::teeth`), the measured force of every sample (the codes the controller got,
//! calibrated as the DRR calibrates them) fed to the core's breakage detector
//! (`millac::monitor::breakage`, the firmware's code) at the cut's spindle speed and flutes.
use crate::analysis::ProgBlock;
use crate::host::acsim::{self, Cut, HostRun};
use anyhow::{anyhow, Context, Result};
use millac::ac::AcSettings;
use millac::monitor::{Breakage, BreakageDetector, BreakageSettings};
use millac::rt::ac::FeedNotice;
use millac::Settings;

/// The breakage slot (`programs/breakage-slot.nc`): a full slot 0.3 in deep in steel at F8, so
/// that a broken tooth (which doubles the next tooth's chip) stays below the AC's overload hold.
pub const SLOT: &str = include_str!("../../programs/breakage-slot.nc");

/// The slot's cut (stock `programs/entry-exit.stock`) with 5/0/-3/0 um of run-out; tooth 1
/// breaks at `break_s` s of virtual time, or never.
pub fn slot_cut(break_s: Option<f64>) -> Cut {
    use millac_plant::teeth::{Damage, ToothEvent};
    let stock = millac_plant::Stock::parse(include_str!("../../programs/entry-exit.stock"))
        .expect("entry-exit.stock parses");
    Cut {
        runout_mm: vec![0.005, 0.0, -0.003, 0.0],
        tooth_events: break_s
            .map(|t_s| ToothEvent {
                tooth: 1,
                t_s,
                damage: Damage::Broken,
            })
            .into_iter()
            .collect(),
        ..Cut::steel(stock, 1).at_program_rpm(SLOT, &Settings::default())
    }
}

/// The detector's verdict on a run: the first breakage declared and when (s of virtual time, the
/// sample's), and the average force of every tooth period it judged.
#[derive(Clone, Debug)]
pub struct BreakRun {
    pub run: HostRun,
    pub detection: Option<(f64, Breakage)>,
}

/// Runs `prog` on `cut` (with the AC `ac`, or measuring only) and the breakage detector over
/// every sample's measured force.
pub fn run(
    prog: &[ProgBlock],
    settings: &Settings,
    cut: &Cut,
    ac: Option<AcSettings>,
    bs: BreakageSettings,
) -> Result<BreakRun> {
    let run = acsim::run(prog, settings, cut, ac)?;
    let detection = detect(&run, cut, bs)?;
    Ok(BreakRun { run, detection })
}

/// The breakage detector over the codes of `run` (the controller's calibration, the default
/// AC settings'), the first declaration and its time.
pub fn detect(run: &HostRun, cut: &Cut, bs: BreakageSettings) -> Result<Option<(f64, Breakage)>> {
    Ok(trace(run, cut, bs)?.1)
}

/// One tooth period as the breakage detector judged it: when it closed (s), the average force
/// over it (N), the residuals of the first-difference and once-per-revolution filters (N) and
/// their thresholds (None while the detector learns).
#[derive(Clone, Copy, Debug)]
pub struct PeriodRow {
    pub t_s: f64,
    pub fa_n: f64,
    pub e1_n: f64,
    pub e2_n: f64,
    pub th_n: Option<(f64, f64)>,
}

/// Every tooth period's row, and the first declaration and its time (s).
pub type Trace = (Vec<PeriodRow>, Option<(f64, Breakage)>);

/// As [`detect`], every tooth period's row as well (for the figures like the thesis' 3.8-3.9 and
/// 5.13-5.14), to the end of the run (after a declaration the detector stays latched: no rows).
pub fn trace(run: &HostRun, cut: &Cut, bs: BreakageSettings) -> Result<Trace> {
    let flutes = u8::try_from(cut.tool.flutes).map_err(|_| anyhow!("too many flutes"))?;
    trace_span(run, 0..run.codes.len(), cut.spindle_rpm, flutes, bs)
}

/// As [`trace`], over the samples `span` of `run` only, at `rpm` with `flutes` (one tool's part
/// of a job; its tooth periods start at the span's first sample: a later start is another phase
/// of them against the tooth passes). Times are the run's.
pub fn trace_span(
    run: &HostRun,
    span: std::ops::Range<usize>,
    rpm: f64,
    flutes: u8,
    bs: BreakageSettings,
) -> Result<Trace> {
    let cal = AcSettings::default().cal;
    let sample_hz = f64::from(bs.sample_hz);
    let mut det = BreakageDetector::new(bs.validated().map_err(|e| anyhow!("{e:?}"))?);
    det.set_spindle(rpm as f32, flutes);
    let (mut rows, mut detection) = (Vec::new(), None);
    let (mut sum, mut count, mut periods) = (0.0, 0u32, det.periods());
    // With the AC, the AC period's feed notices, as the firmware's (`millac::rt::ac::AcPeriod`
    // runs the detector and tells it of feed steps and ramps, `FeedNotice`): after every
    // period's samples, from the positions the rows log. (Without the AC the firmware has no AC
    // period to tell it; the host's runs at the programmed feeds have none either.)
    let with_ac = run.rows.iter().any(|r| r.state != "off");
    let per_period = samples_per_period(&bs);
    let mut feed = FeedNotice::new();
    let period_ms = AcSettings::default().period_ms;
    let rpm = rpm.round() as u32;
    let first = span.start;
    // The firmware's notices run all along: the AC periods before the span (as many as the
    // notices remember, `MOTION_RING`) set the last position and motion they start from.
    if with_ac {
        let done = first / per_period;
        for r in run
            .rows
            .iter()
            .take(done)
            .skip(done.saturating_sub(millac::rt::ac::MOTION_RING))
        {
            let enc = r.pos_blu.map(|v| i32::try_from(v).unwrap_or(i32::MAX));
            let _ = feed.period(enc, rpm, period_ms);
        }
    }
    for (i, c) in run.codes.iter().enumerate().take(span.end).skip(first) {
        if let Some([_, fu, fv]) = c {
            let f = cal[1].value(*fu).hypot(cal[2].value(*fv));
            sum += f64::from(f);
            count += 1;
            let b = det.sample(f);
            let t_s = (i + 1) as f64 / sample_hz;
            if det.periods() != periods {
                periods = det.periods();
                let (e1, e2) = det.residuals();
                let (th1, th2) = det.thresholds();
                rows.push(PeriodRow {
                    t_s,
                    fa_n: sum / f64::from(count.max(1)),
                    e1_n: f64::from(e1),
                    e2_n: f64::from(e2),
                    th_n: (!det.learning()).then_some((f64::from(th1), f64::from(th2))),
                });
                (sum, count) = (0.0, 0);
            }
            if let Some(b) = b {
                detection.get_or_insert((t_s, b));
            }
        }
        // The period that this sample closes: its feed-step notice.
        let Some(r) = (with_ac && (i + 1) % per_period == 0)
            .then(|| run.rows.get((i + 1) / per_period - 1))
            .flatten()
        else {
            continue;
        };
        let enc = r.pos_blu.map(|v| i32::try_from(v).unwrap_or(i32::MAX));
        if let Some(change) = feed.period(enc, rpm, period_ms) {
            det.feed_step(change);
        }
    }
    Ok((rows, detection))
}

/// Samples per AC period at the detector's sample rate (the rows' spacing in `HostRun::codes`).
fn samples_per_period(bs: &BreakageSettings) -> usize {
    (u64::from(bs.sample_hz) * u64::from(AcSettings::default().period_ms) / 1000).max(1) as usize
}

/// A job's tool under the breakage detector at every phase of its tooth periods: the samples
/// of `run` while tool `tool` was first fitted (the AC rows' tool, its first run of them),
/// replayed by [`trace_span`] at
/// `rpm` with `flutes`, the tooth periods starting 0, 1, .. samples after the tool's first
/// sample, one tooth period's worth of starts (rounded up). The firmware's tooth periods start
/// where its M6 and S happened to fall, which moves with its timing: a sound tool must pass at
/// every phase. The declarations (time, breakage), one per phase at most.
pub fn phases(
    run: &HostRun,
    tool: u8,
    rpm: f64,
    flutes: u8,
    bs: BreakageSettings,
) -> Result<Vec<(usize, f64, Breakage)>> {
    let per_period = samples_per_period(&bs);
    let Some(first) = run.rows.iter().position(|r| r.tool == tool) else {
        return Err(anyhow!("T{tool} never fitted in the run"));
    };
    let end = run
        .rows
        .iter()
        .skip(first)
        .position(|r| r.tool != tool)
        .map_or(run.rows.len(), |n| first + n);
    let span = first * per_period..(end * per_period).min(run.codes.len());
    let period = 60.0 * f64::from(bs.sample_hz) / (rpm * f64::from(flutes.max(1)));
    let mut out = Vec::new();
    for phase in 0..period.ceil() as usize {
        let (_, d) = trace_span(run, span.start + phase..span.end, rpm, flutes, bs)?;
        if let Some((t, b)) = d {
            out.push((phase, t, b));
        }
    }
    Ok(out)
}

/// The breakage detector's view of a run (as the thesis' Figs. 3.7-3.9 and 5.12-5.14): above,
/// the average force per tooth period; then the residuals of the first-difference filter and of
/// the once-per-revolution filter with their adaptive thresholds (+-); the break and the
/// declaration marked.
pub fn plot_residuals(
    path: &std::path::Path,
    title: &str,
    rows: &[PeriodRow],
    break_s: Option<f64>,
    detection: Option<f64>,
) -> Result<()> {
    use plotters::prelude::*;
    let root = SVGBackend::new(path, (1000, 900)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((3, 1));
    let t_end = rows.last().map_or(1.0, |r| r.t_s);
    let marks = |chart: &mut ChartContext<_, Cartesian2d<_, _>>, lo: f64, hi: f64| -> Result<()> {
        for (t, colour, label) in [
            (break_s, RED, "tooth broken"),
            (detection, GREEN, "breakage declared"),
        ] {
            if let Some(t) = t {
                chart
                    .draw_series([PathElement::new(
                        vec![(t, lo), (t, hi)],
                        colour.stroke_width(2),
                    )])?
                    .label(label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            }
        }
        Ok(())
    };
    // Average force.
    let f_max = rows.iter().map(|r| r.fa_n).fold(1.0, f64::max) * 1.1;
    let mut chart = ChartBuilder::on(&panels[0])
        .caption(
            format!("{title}: average force per tooth period (Fig. 3.7, 5.12)"),
            ("sans-serif", 15),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d(0f64..t_end, 0f64..f_max)?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc("Fa, N")
        .draw()?;
    chart
        .draw_series(
            rows.iter()
                .map(|r| Circle::new((r.t_s, r.fa_n), 1, BLUE.filled())),
        )?
        .label("Fa")
        .legend(|(x, y)| Circle::new((x + 10, y), 2, BLUE.filled()));
    marks(&mut chart, 0.0, f_max)?;
    crate::evaluation::plot::legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    // The residuals against their thresholds.
    for (k, (panel, name)) in panels[1..]
        .iter()
        .zip([
            "residual e1 of the first differences (Fig. 3.8, 5.13)",
            "residual e2 of the once-per-revolution differences (Fig. 3.9, 5.14)",
        ])
        .enumerate()
    {
        let e = |r: &PeriodRow| if k == 0 { r.e1_n } else { r.e2_n };
        let th = |r: &PeriodRow| r.th_n.map(|t| if k == 0 { t.0 } else { t.1 });
        let lim = rows
            .iter()
            .map(|r| e(r).abs().max(th(r).unwrap_or(0.0)))
            .fold(1.0, f64::max)
            * 1.1;
        let mut chart = ChartBuilder::on(panel)
            .caption(format!("{title}: {name}"), ("sans-serif", 15))
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(0f64..t_end, -lim..lim)?;
        chart
            .configure_mesh()
            .x_desc("time, s")
            .y_desc("N")
            .draw()?;
        chart
            .draw_series(
                rows.iter()
                    .map(|r| Circle::new((r.t_s, e(r)), 1, BLUE.filled())),
            )?
            .label("residual")
            .legend(|(x, y)| Circle::new((x + 10, y), 2, BLUE.filled()));
        // The thresholds: one segment per run of learned periods (gaps while learning).
        let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
        let mut open = false;
        for r in rows {
            match th(r) {
                Some(v) if open => runs.last_mut().into_iter().for_each(|s| s.push((r.t_s, v))),
                Some(v) => {
                    runs.push(vec![(r.t_s, v)]);
                    open = true;
                }
                None => open = false,
            }
        }
        for (i, sign) in [1.0, -1.0].into_iter().enumerate() {
            let s = chart.draw_series(runs.iter().map(|seg| {
                PathElement::new(
                    seg.iter().map(|&(t, v)| (t, sign * v)).collect::<Vec<_>>(),
                    BLACK.stroke_width(1),
                )
            }))?;
            if i == 0 {
                s.label("adaptive threshold (+-)")
                    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
            }
        }
        marks(&mut chart, -lim, lim)?;
        crate::evaluation::plot::legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    }
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
