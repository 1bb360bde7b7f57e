//! Chatter suppression by depth reduction on the host (Munasinghe 1994, sections 3.3, 4.4.4 and
//! 5.3.2): the thesis' table 3.2 cut at 8.89 mm through the block, the chatter monitor's
//! threshold by the thesis' rule from the 2.54 mm cut, `$276` = 1 mm (the thesis' step). The
//! firmware's code (the AC period, the chatter monitor, the loader's re-plan) on the simulated
//! cut. Prints the detections and re-plans, writes `out/chatter/suppression.svg`.
//!
//! ```text
//! cargo run -p millac-qemu --release --example chatter_suppression
//! ```
use anyhow::Result;
use millac::ac::AcSettings;
use millac::Settings;
use millac_plant::chatter::thesis_table_3_2 as t;
use millac_qemu::{analysis, evaluation::chatterlab, host::acsim};

fn main() -> Result<()> {
    let s = Settings::default();
    let listen = AcSettings {
        flutes: t::FLUTES,
        monitor_rpm: t::RPM as u32,
        chatter_step_mm: 1.0,
        ..AcSettings::default()
    };
    let (text, cut) = chatterlab::through_slot(0.1);
    let prog = analysis::load_program(&text, &s).map_err(|e| anyhow::anyhow!("{e}"))?;
    let threshold = chatterlab::thesis_threshold(&prog, &s, &cut, listen)?;
    let acs = AcSettings {
        chatter_threshold: threshold,
        ..listen
    };
    let (text, cut) = chatterlab::through_slot(0.35);
    let prog = analysis::load_program(&text, &s).map_err(|e| anyhow::anyhow!("{e}"))?;
    let run = acsim::run_with_faults(&prog, &s, &cut, Some(acs), true, &[])?;
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
    println!("threshold {threshold:.2} codes (2 x the largest amplitude of the 2.54 mm slot)");
    println!("| t s | record | peak Hz | amplitude | chatter |");
    println!("| ---: | --- | ---: | ---: | --- |");
    for (k, (t, sp)) in run.spectra.iter().enumerate() {
        if sp.chatter {
            println!(
                "| {t:.3} | {k} | {:.0} | {:.2} | yes |",
                sp.peak_hz, sp.peak_amplitude
            );
        }
    }
    println!("| t s | re-plan | held at X, Z mm | upper pass depth after it, mm |");
    println!("| ---: | ---: | --- | ---: |");
    for (t, r) in &run.replans {
        let (num, den) = s.blu.per_mm();
        let mm = |blu: i32| f64::from(blu) * den as f64 / num as f64;
        println!(
            "| {t:.3} | {} | {:.2}, {:.2} | {:.2} |",
            r.count,
            mm(r.at[0]),
            mm(r.at[2]),
            -mm(r.at[2] + r.lift as i32)
        );
    }
    println!(
        "machining {:.2} s (the same slot with a rigid tool {:.2} s); blocks {} (programmed {})",
        run.machining_time_s,
        rigid.machining_time_s,
        run.blocks_done,
        prog.len()
    );
    let same = match (&run.stock, &rigid.stock) {
        (Some(a), Some(b)) => a
            .tops()
            .iter()
            .zip(b.tops())
            .filter(|(x, y)| x != y)
            .count(),
        _ => usize::MAX,
    };
    println!("stock cells that differ from the rigid tool's cut: {same}");
    let dir = std::path::Path::new("out/chatter");
    std::fs::create_dir_all(dir)?;
    let path = dir.join("suppression.svg");
    chatterlab::plot_suppression(&path, &run, threshold)?;
    println!("wrote {}", path.display());
    Ok(())
}
