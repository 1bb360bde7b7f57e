//! Crossing-to-standstill of the AC's holds on the simulated plant (host example): for an
//! overload step (the thesis' TIIM depth step, +38 %), a broken tooth (the pocket, tooth 0 at
//! 6.08 s, the breakage monitor on) and a rail fault (T at its rail from 1.5 s on the cavity),
//! the time from the crossing (the first sample whose true force is above the permissible limit
//! F_max, or the fault's start) to the hold (the frame's cap at 0: the sampler's trip, see
//! `millac::rt::ac`) and to standstill (the last pulse), with the alarm the hold was given. The
//! last column is when the AC period alone would have held: its next period boundary after the
//! first sample above the hold's level.
//!
//! ```text
//! cargo run -p millac-qemu --release --example hold_latency
//! ```
use anyhow::Result;
use millac::ac::AcSettings;
use millac::Settings;
use millac_plant::teeth::{Damage, ToothEvent};
use millac_plant::DriveModel;
use millac_qemu::evaluation::bench;
use millac_qemu::host::acsim::{self, Cut, HostRun};
use millac_qemu::host::fault::{Fault, FaultKind};

fn main() -> Result<()> {
    let s = Settings::default();
    let ac = AcSettings {
        breakage: millac::ac::Breakage::On,
        ..AcSettings::default()
    };
    let f_max = f64::from(ac.force_limit_n);
    let level = f64::from((1.0 - ac.overload_e) * ac.f0_n());
    let period_s = f64::from(ac.period_ms) / 1000.0;
    let steel = millac_plant::Material::STEEL;
    let cases: Vec<(&str, &bench::Case, Vec<ToothEvent>, Vec<Fault>)> = vec![
        ("overload step (TIIM)", &bench::CASES[3], vec![], vec![]),
        (
            "broken tooth (pocket, tooth 0 at 6.08 s)",
            &bench::CASES[1],
            vec![ToothEvent {
                tooth: 0,
                t_s: 6.08,
                damage: Damage::Broken,
            }],
            vec![],
        ),
        (
            "rail fault (cavity, T at 1.5 s)",
            &bench::CASES[0],
            vec![],
            vec![Fault {
                kind: FaultKind::Rail,
                at_s: 1.5,
            }],
        ),
    ];
    println!(
        "| case | crossing (s) | to hold (ms) | to standstill (ms) | alarm | AC period alone (ms) |"
    );
    println!("| --- | ---: | ---: | ---: | --- | ---: |");
    for (name, case, events, faults) in cases {
        let prog = case.load(&s)?;
        let cut = Cut {
            tooth_events: events,
            ..case.cut(&s, DriveModel::Stepper, steel)?
        };
        let run = acsim::run_with_faults(&prog, &s, &cut, Some(ac), true, &faults)?;
        // The crossing: the fault's start, or the first sample above F_max.
        let crossing = match faults.first() {
            Some(f) => Some(f.at_s),
            None => first_above(&run, f_max),
        };
        let (Some(c), Some(hold)) = (crossing, run.hold_ns) else {
            println!("| {name} | - | no hold | - | {:?} | - |", run.alarm);
            continue;
        };
        let hold_s = hold as f64 * 1e-9;
        let stop_s = run.last_pulse_ns as f64 * 1e-9;
        // The AC period alone: the period boundary after the first sample above the hold's level.
        let over = first_above(&run, level).unwrap_or(c);
        let period_alone = ((over / period_s).floor() + 1.0) * period_s;
        println!(
            "| {name} | {c:.3} | {:.0} | {:.0} | {} | {:.0} |",
            (hold_s - c) * 1e3,
            (stop_s - c).max(0.0) * 1e3,
            run.alarm.map_or("none", |a| a.message()),
            (period_alone - c) * 1e3,
        );
    }
    Ok(())
}

/// The time (s) of the first sample whose true force is above `f_n`.
fn first_above(run: &HostRun, f_n: f64) -> Option<f64> {
    run.samples
        .iter()
        .position(|x| x.0 > f_n)
        .map(|i| (i + 1) as f64 / 1000.0)
}
