//! Tool breakage detection on the simulated cut (host; issue 10): a program run on the host
//! (`acsim`, the firmware's frame and AC code) with the plant's run-out and tooth damage
//! (`millac_plant::teeth`), the measured force of every sample (the codes the controller got,
//! calibrated as the DRR calibrates them) fed to the core's breakage detector
//! (`millac::monitor::breakage`, the firmware's code) at the cut's spindle speed and flutes.
use crate::acsim::{self, Cut, HostRun};
use crate::analysis::ProgBlock;
use anyhow::{anyhow, Result};
use millac::ac::AcSettings;
use millac::monitor::{Breakage, BreakageDetector, BreakageSettings};
use millac::Settings;

/// The breakage slot (`programs/breakage-slot.nc`): a full slot 0.3 in deep in steel at F8, so
/// that a broken tooth (which doubles the next tooth's chip) stays below the AC's overload hold.
pub const SLOT: &str = include_str!("../programs/breakage-slot.nc");

/// The slot's cut (stock `programs/entry-exit.stock`) with 5/0/-3/0 um of run-out; tooth 1
/// breaks at `break_s` s of virtual time, or never.
pub fn slot_cut(break_s: Option<f64>) -> Cut {
    use millac_plant::teeth::{Damage, ToothEvent};
    let stock = millac_plant::Stock::parse(include_str!("../programs/entry-exit.stock"))
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
    let cal = AcSettings::default().cal;
    let sample_hz = f64::from(bs.sample_hz);
    let mut det = BreakageDetector::new(bs).map_err(|e| anyhow!("{e:?}"))?;
    let flutes = u8::try_from(cut.tool.flutes).map_err(|_| anyhow!("too many flutes"))?;
    det.set_spindle(cut.spindle_rpm as f32, flutes);
    for (i, c) in run.codes.iter().enumerate() {
        // A missed conversion: no sample for the detector (its tooth period takes the others).
        let Some([_, fu, fv]) = c else { continue };
        let f = cal[1].value(*fu).hypot(cal[2].value(*fv));
        if let Some(b) = det.sample(f) {
            return Ok(Some(((i + 1) as f64 / sample_hz, b)));
        }
    }
    Ok(None)
}
