//! Broken teeth under the AC with the breakage monitor on (host example): teeth 0 and 1 broken
//! at 15 .. 90 % of the machining time of the Fig. 1 cavity and the pocket (24 runs of the host
//! simulation, stepper drive, steel), each with the alarm its hold got: 108 (tool breakage, told
//! at the sampler's trip or by the monitor) or 100 (an overload: the doubled chip crossed the
//! overload level before the broken tooth's loss showed in the samples). The count in docs/dev/results-ac.md ("Hold latency").
//!
//! ```text
//! cargo run -p millac-qemu --release --example breaks_under_ac [-- --spread N]
//! ```
//!
//! `--spread N` breaks each tooth also at N - 1 later instants 7 ms apart (default 1): whether
//! the doubled chip crosses the overload level before the loss shows depends on where the break
//! falls among the samples and the tooth passes, so one instant per case is a sample, not a rate.
//! Only the count is printed then.
use millac::ac::AcSettings;
use millac::Settings;
use millac_plant::teeth::{Damage, ToothEvent};
use millac_plant::DriveModel;
use millac_qemu::host::acsim::{self, Cut};
use millac_qemu::{evaluation::alarmlab, evaluation::bench};
fn main() -> anyhow::Result<()> {
    let s = Settings::default();
    let acs = AcSettings {
        breakage: millac::ac::Breakage::On,
        ..AcSettings::default()
    };
    let args: Vec<String> = std::env::args().collect();
    let spread: usize = match args.iter().position(|a| a == "--spread") {
        Some(i) => args
            .get(i + 1)
            .and_then(|v| v.parse().ok())
            .filter(|&n| n >= 1)
            .ok_or_else(|| anyhow::anyhow!("--spread needs a count of instants, 1 or more"))?,
        None => 1,
    };
    let mut cases = Vec::new();
    for ci in [0usize, 1] {
        let case = &bench::CASES[ci];
        let prog = case.load(&s)?;
        let base = acsim::run(
            &prog,
            &s,
            &case.cut(&s, DriveModel::Stepper, millac_plant::Material::STEEL)?,
            Some(acs),
        )?;
        let total = base.machining_time_s;
        for tooth in [0u32, 1] {
            for pct in [15, 30, 45, 60, 75, 90] {
                for k in 0..spread {
                    cases.push((ci, tooth, total * pct as f64 / 100.0 + 0.007 * k as f64));
                }
            }
        }
    }
    let res = alarmlab::parallel(&cases, |&(ci, tooth, t_s)| {
        let case = &bench::CASES[ci];
        let prog = case.load(&s)?;
        let cut = Cut {
            tooth_events: vec![ToothEvent {
                tooth,
                t_s,
                damage: Damage::Broken,
            }],
            ..case.cut(&s, DriveModel::Stepper, millac_plant::Material::STEEL)?
        };
        let r = acsim::run(&prog, &s, &cut, Some(acs))?;
        Ok(r.alarm.map(|a| millac::protocol::codes::ac_alarm(&a)))
    })?;
    let n108 = res.iter().filter(|r| **r == Some(108)).count();
    // Every case with one instant; with a spread, those held for neither.
    let told = |r: &Option<u8>| matches!(r, Some(100 | 108));
    for ((ci, tooth, t_s), r) in cases
        .iter()
        .zip(&res)
        .filter(|(_, r)| spread == 1 || !told(r))
    {
        let alarm = r.map_or("none".to_string(), |a| a.to_string());
        println!(
            "{} tooth {tooth} broken at {t_s:.2} s: alarm {alarm}",
            bench::CASES[*ci].name
        );
    }
    let n100 = res.iter().filter(|r| **r == Some(100)).count();
    println!(
        "told as breakage (108): {n108} of {}; held as an overload (100): {n100}",
        res.len()
    );
    Ok(())
}
