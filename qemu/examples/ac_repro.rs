//! The papers' feed-law experiments reproduced on the simulated cut (host; issue 9): runs every
//! strategy on the depth-step slot (Ulsoy, Koren and Lauderbaugh's Figs. 2-3), the thesis' test
//! TIIM and pocket (Munasinghe's Figs. 5.9-5.11) and an entry from air and exit, with the
//! scenarios and figures of merit of `millac_qemu::evaluation::repro` (the `repro` tests use the same
//! functions). Writes the SVGs under `out/repro/` and prints the tables of docs/dev/results-ac.md (markdown).
//!
//! ```text
//! cargo run -p millac-qemu --release --example ac_repro
//! ```
use anyhow::Result;
use millac_qemu::evaluation::repro::{self, Trace};
use std::path::Path;

fn main() -> Result<()> {
    let dir = Path::new("out/repro");
    std::fs::create_dir_all(dir)?;

    // Depth-step slot.
    let (sc, nominal) = repro::depth_step()?;
    let mut traces = sc.run_all()?;
    let detuned = repro::depth_step_integral_detuned(&sc, nominal)?;
    traces.insert(2, detuned);
    println!(
        "Depth-step slot (F0 = {:.0} N, `$264` = {nominal:.2} ipm: the feed at which the 1 mm \
         section reaches F0)\n",
        sc.acs.f0_n()
    );
    println!(
        "| law | depth mm | max abs(F/F0 - 1) from 1 s after the step | peak-to-peak F/F0, last 1 s | \
         mean F/F0, last 1 s | mean feed ipm, last 1 s | above the default hold (1.1 F0) |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | --- |");
    let mut marks = Vec::new();
    for tr in &traces {
        let figs = repro::depth_figures(tr);
        for (d, f) in figs.iter().enumerate() {
            let (x0, x1) = repro::depth_section_x(d);
            let r = tr.span_x(x0, x1);
            let above = tr.load[r].iter().any(|&v| v > repro::DEFAULT_HOLD_LOAD);
            println!(
                "| {} | {} | {:.3} | {:.3} | {:.3} | {:.2} | {} |",
                tr.name,
                repro::DEPTHS_MM[d],
                f.worst,
                f.ptp_last,
                f.mean_last,
                f.feed_last_ipm,
                if above { "yes" } else { "no" }
            );
        }
    }
    if let Some(tr) = traces.first() {
        for d in 1..3 {
            let r = tr.span_x(repro::depth_section_x(d).0, 99.0);
            if r.start < tr.t_s.len() {
                marks.push(tr.t_s[r.start]);
            }
        }
    }
    let p = dir.join("depth-step.svg");
    repro::plot_load_and_feed(
        &p,
        "Depth-step slot 1 -> 2 -> 3 mm, every law tuned at 1 mm (lines: the first law's steps)",
        &traces,
        &marks,
    )?;
    println!("\nwrote {}", p.display());
    let p = dir.join("depth-step-estimates.svg");
    repro::plot_estimates(&p, "Depth-step slot: estimates", &traces, &marks)?;
    println!("wrote {}\n", p.display());

    // TIIM.
    let sc = repro::tiim();
    let traces = sc.run_all()?;
    println!("TIIM (7.62 -> 10.5 mm, F0 = {:.0} N)\n", sc.acs.f0_n());
    println!(
        "| law | F/F0 before the step (mean, 1 s) | peak F/F0 after | overshoot | settling s (+-5 %) | \
         final F/F0 | above the default hold (1.1 F0) |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | --- |");
    let mut step_marks = Vec::new();
    for tr in &traces {
        let s = tiim_response(tr);
        let step = tr
            .span_x(repro::TIIM_STEP_X - repro::STEP_MARGIN_IN, 99.0)
            .start;
        step_marks.push(tr.t_s[step]);
        let before = repro::mean(&tr.load[step.saturating_sub(105)..step.saturating_sub(5)]);
        println!(
            "| {} | {:.3} | {:.3} | {:+.3} | {:.2} | {:.3} | {} |",
            tr.name,
            before,
            s.peak,
            s.overshoot,
            s.settling_s,
            s.final_level,
            if s.peak > repro::DEFAULT_HOLD_LOAD {
                "yes"
            } else {
                "no"
            }
        );
    }
    let p = dir.join("tiim.svg");
    repro::plot_load_and_feed(
        &p,
        "Test TIIM: depth 7.62 -> 10.5 mm (lines: the step under the tool, per law)",
        &traces,
        &step_marks,
    )?;
    println!("\nwrote {}", p.display());
    let p = dir.join("tiim-estimates.svg");
    repro::plot_estimates(&p, "Test TIIM: estimates (as Fig. 5.11)", &traces, &[])?;
    println!("wrote {}\n", p.display());

    // Pocket.
    let sc = repro::pocket();
    let traces = sc.run_all()?;
    println!("Pocket (Fig. 5.8), default settings\n");
    println!(
        "| law | time s | peak F/F0 | periods above F0 | peak F/F0 at the island entry | held |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | --- |");
    for tr in &traces {
        let peak = tr.load.iter().cloned().fold(0.0, f64::max);
        let above = tr.load.iter().filter(|&&v| v > 1.0).count();
        let island_peak = island_entry_peak(tr);
        println!(
            "| {} | {:.2} | {:.3} | {} | {:.3} | {} |",
            tr.name,
            tr.run.machining_time_s,
            peak,
            above,
            island_peak,
            held(tr)
        );
    }
    let p = dir.join("pocket.svg");
    repro::plot_load_and_feed(
        &p,
        "Pocket after Fig. 5.8: peak force and feed (as Figs. 5.9-5.10)",
        &traces,
        &[],
    )?;
    println!("\nwrote {}", p.display());
    let p = dir.join("pocket-estimates.svg");
    repro::plot_estimates(
        &p,
        "Pocket: estimated parameters (as Fig. 5.11)",
        &traces,
        &[],
    )?;
    println!("wrote {}\n", p.display());

    // Entry and exit.
    for feed in repro::ENTRY_FEEDS_IPM {
        let sc = repro::entry_exit(feed);
        let traces = sc.run_all()?;
        println!("Entry from air and exit, programmed F{feed}\n");
        println!(
            "| law | feed in air ipm | entry peak F/F0 (1 s) | held | F/F0 in the cut | feed in the cut ipm | \
             feed recovery after exit s (to 95 % of F{feed}) |"
        );
        println!("| --- | ---: | ---: | --- | ---: | ---: | ---: |");
        for tr in &traces {
            let e = repro::entry_exit_figures(tr, feed);
            println!(
                "| {} | {:.2} | {:.3} | {} | {} | {} | {} |",
                tr.name,
                e.air_feed_ipm,
                e.entry_peak,
                held(tr),
                if e.held {
                    "-".into()
                } else {
                    format!("{:.3}", e.settled)
                },
                if e.held {
                    "-".into()
                } else {
                    format!("{:.2}", e.exit_feed_ipm)
                },
                match (e.held, e.recovery_s) {
                    (true, _) => "-".into(),
                    (false, Some(s)) => format!("{s:.2}"),
                    (false, None) => "never".into(),
                }
            );
        }
        let p = dir.join(format!("entry-exit-f{feed}.svg"));
        repro::plot_load_and_feed(
            &p,
            &format!("Entry from air into a 0.3 in full slot and exit, programmed F{feed}"),
            &traces,
            &[],
        )?;
        println!("\nwrote {}\n", p.display());
    }
    Ok(())
}

fn tiim_response(tr: &Trace) -> repro::StepResponse {
    repro::tiim_response(tr)
}

fn island_entry_peak(tr: &Trace) -> f64 {
    repro::pocket_island_entry_peak(tr)
}

fn held(tr: &Trace) -> String {
    match tr.run.alarm {
        Some(a) if tr.run.held => format!("held ({})", a.message()),
        _ => "no".into(),
    }
}
