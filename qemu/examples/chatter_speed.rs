//! The chatter reaction by spindle speed (`$277`, issue 10) on the host, against the depth steps
//! (`$276`) on the same cut: the table 3.2 tool in a 4 mm slot at 14 000 rpm, where its lobes
//! are wide (`chatterlab::high_speed_slot`); the threshold by the thesis' rule from the same slot
//! at 2 mm. The firmware's code (the AC period, the chatter monitor, the loader's reaction) on
//! the simulated cut. Prints the changes and times, writes `out/chatter/speed.svg`.
//!
//! ```text
//! cargo run -p millac-qemu --release --example chatter_speed
//! ```
use anyhow::Result;
use millac::ac::AcSettings;
use millac::Settings;
use millac_plant::chatter::thesis_table_3_2 as t;
use millac_qemu::{analysis, evaluation::chatterlab, host::acsim};

const RPM: u32 = 14_000;

fn main() -> Result<()> {
    let s = Settings::default();
    let listen = AcSettings {
        flutes: t::FLUTES,
        monitor_rpm: RPM,
        chatter_step_mm: 1.0,
        ..AcSettings::default()
    };
    let load = |text: &str| analysis::load_program(text, &s).map_err(|e| anyhow::anyhow!("{e}"));
    let (text, cut) = chatterlab::high_speed_slot(0.08, RPM);
    let threshold = chatterlab::thesis_threshold(&load(&text)?, &s, &cut, listen)?;
    let (text, cut) = chatterlab::high_speed_slot(0.157, RPM);
    let prog = load(&text)?;
    let with = |max_rpm: u32| AcSettings {
        chatter_threshold: threshold,
        chatter_max_rpm: max_rpm,
        ..listen
    };
    let speed = acsim::run_with_faults(&prog, &s, &cut, Some(with(30_000)), true, &[])?;
    let depth = acsim::run_with_faults(&prog, &s, &cut, Some(with(0)), true, &[])?;
    let rigid = acsim::run_with_faults(
        &prog,
        &s,
        &acsim::Cut {
            modes: None,
            ..cut.clone()
        },
        None,
        true,
        &[],
    )?;
    println!("threshold {threshold:.2} codes (2 x the largest amplitude of the 2 mm slot)");
    println!("| t s | change | from rpm | to rpm | chatter Hz | m | held at X mm |");
    println!("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    let (num, den) = s.blu.per_mm();
    let mm = |blu: i32| f64::from(blu) * den as f64 / num as f64;
    for (t, c) in &speed.speeds {
        println!(
            "| {t:.3} | {} | {} | {} | {} | {} | {:.2} |",
            c.count,
            c.from,
            c.to,
            c.chatter_hz,
            c.m,
            mm(c.at[0])
        );
    }
    let first = speed.spectra.iter().find(|(_, sp)| sp.chatter).map(|p| p.0);
    println!("first chatter record ends {first:.3?} s");
    let differ = |r: &acsim::HostRun| match (&r.stock, &rigid.stock) {
        (Some(a), Some(b)) => a
            .tops()
            .iter()
            .zip(b.tops())
            .filter(|(x, y)| x != y)
            .count(),
        _ => usize::MAX,
    };
    println!(
        "spindle speed: machining {:.2} s, {} re-plans, {} stock cells differ from the rigid cut",
        speed.machining_time_s,
        speed.replans.len(),
        differ(&speed)
    );
    println!(
        "depth steps:   machining {:.2} s, {} re-plans, {} stock cells differ",
        depth.machining_time_s,
        depth.replans.len(),
        differ(&depth)
    );
    println!("rigid tool:    machining {:.2} s", rigid.machining_time_s);
    std::fs::create_dir_all("out/chatter")?;
    let svg = std::path::Path::new("out/chatter/speed.svg");
    chatterlab::plot_speed(svg, &speed, &depth, threshold, RPM)?;
    println!("wrote {}", svg.display());
    Ok(())
}
