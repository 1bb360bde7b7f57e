//! Broken teeth under the AC with the breakage monitor on (host example): teeth 0 and 1 broken
//! at 15 .. 90 % of the machining time of the Fig. 1 cavity and the pocket (24 runs of the host
//! simulation, stepper drive, steel), each with the alarm its hold got: 108 (tool breakage, told
//! at the sampler's trip or by the monitor) or 100 (an overload: the doubled chip crossed the
//! overload level before the broken tooth's loss showed in the samples). The count in docs/dev/results-ac.md ("Hold latency").
//!
//! ```text
//! cargo run -p millac-qemu --release --example breaks_under_ac
//! ```
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
                cases.push((ci, tooth, total * pct as f64 / 100.0));
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
    for ((ci, tooth, t_s), r) in cases.iter().zip(&res) {
        let alarm = r.map_or("none".to_string(), |a| a.to_string());
        println!(
            "{} tooth {tooth} broken at {t_s:.2} s: alarm {alarm}",
            bench::CASES[*ci].name
        );
    }
    println!("told as breakage (108): {n108} of {}", res.len());
    Ok(())
}
