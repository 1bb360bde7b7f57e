//! The breakage detector's residuals on the simulated cut (host; as the thesis' Figs. 3.7-3.9
//! and 5.12-5.14): the average force per tooth period and the residuals of its two first-order
//! adaptive filters (first differences, once-per-revolution differences) against their adaptive
//! thresholds, on
//!
//! - the breakage slot (`programs/breakage-slot.nc`, 5/0/-3/0 um of run-out, F8, no AC), tooth 1
//!   broken at 6 s: `out/breakage/residuals-slot.svg`;
//! - the pocket (Fig. 5.8) with the same run-out and the AC (GPC), a sound tool:
//!   `out/breakage/residuals-pocket.svg`.
//!
//! The firmware's code (`millac::monitor::breakage`, its defaults) on every sample's measured
//! force. Prints the detection, its delay in revolutions, and the largest residual / threshold
//! of each filter over the learned periods.
//!
//! ```text
//! cargo run -p millac-qemu --release --example breakage_residuals
//! ```
use anyhow::Result;
use millac::ac::AcSettings;
use millac::monitor::BreakageSettings;
use millac::Settings;
use millac_plant::DriveModel;
use millac_qemu::evaluation::breaklab::{self, PeriodRow};
use millac_qemu::{analysis, evaluation::bench, host::acsim};

const BREAK_S: f64 = 6.0;

fn worst(rows: &[PeriodRow]) -> (f64, f64) {
    rows.iter()
        .filter_map(|r| {
            r.th_n
                .map(|(t1, t2)| (r.e1_n.abs() / t1, r.e2_n.abs() / t2))
        })
        .fold((0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)))
}

fn main() -> Result<()> {
    let s = Settings::default();
    std::fs::create_dir_all("out/breakage")?;
    // The slot, tooth 1 broken.
    let cut = breaklab::slot_cut(Some(BREAK_S));
    let prog = analysis::load_program(breaklab::SLOT, &s).map_err(|e| anyhow::anyhow!("{e}"))?;
    let run = acsim::run(&prog, &s, &cut, None)?;
    let (rows, det) = breaklab::trace(&run, &cut, BreakageSettings::default())?;
    let rev_s = 60.0 / cut.spindle_rpm;
    match det {
        Some((t, b)) => println!(
            "slot: tooth 1 broken at {BREAK_S} s, declared at {t:.3} s ({:.2} revolutions), tooth period {}: e1 {:.0} N (threshold {:.0}), e2 {:.0} N (threshold {:.0})",
            (t - BREAK_S) / rev_s,
            b.tooth_period,
            b.e1,
            b.th1,
            b.e2,
            b.th2
        ),
        None => println!("slot: the break was not declared"),
    }
    let before: Vec<PeriodRow> = rows.iter().copied().filter(|r| r.t_s < BREAK_S).collect();
    let (w1, w2) = worst(&before);
    println!(
        "slot before the break: largest |e1|/th1 {w1:.2}, |e2|/th2 {w2:.2} over {} tooth periods",
        before.len()
    );
    breaklab::plot_residuals(
        std::path::Path::new("out/breakage/residuals-slot.svg"),
        "breakage slot, tooth 1 broken at 6 s",
        &rows,
        Some(BREAK_S),
        det.map(|d| d.0),
    )?;
    // The pocket, sound tool, with the AC.
    let case = &bench::CASES[1];
    let cut = acsim::Cut {
        runout_mm: vec![0.005, 0.0, -0.003, 0.0],
        ..case.cut(&s, DriveModel::Stepper, millac_plant::Material::STEEL)?
    };
    let prog = case.load(&s)?;
    let run = acsim::run(&prog, &s, &cut, Some(AcSettings::default()))?;
    let (rows, det) = breaklab::trace(&run, &cut, BreakageSettings::default())?;
    let (w1, w2) = worst(&rows);
    println!(
        "{}: sound tool with the AC, {} tooth periods ({} learned), declared {:?}; largest |e1|/th1 {w1:.2}, |e2|/th2 {w2:.2}",
        case.name,
        rows.len(),
        rows.iter().filter(|r| r.th_n.is_some()).count(),
        det.map(|d| d.0)
    );
    breaklab::plot_residuals(
        std::path::Path::new("out/breakage/residuals-pocket.svg"),
        "pocket (Fig. 5.8), sound tool, AC",
        &rows,
        None,
        det.map(|d| d.0),
    )?;
    println!("wrote out/breakage/residuals-slot.svg, out/breakage/residuals-pocket.svg");
    Ok(())
}
