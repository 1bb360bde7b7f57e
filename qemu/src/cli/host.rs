//! `millac-qemu host [PROGRAM]`: a program with adaptive control natively on the host against the
//! simulated cut, no QEMU (host: the CLI calls it from `main`).
use super::args::{cut_setup, CutArgs};
use super::{demo_job, reported, with_program};
use anyhow::{Context, Result};
use millac::Settings;
use millac_qemu::{analysis, emulator::runner};
use std::path::{Path, PathBuf};

/// The AC periods ac.svg draws in full (`acsim::PlotRows`: up to twice this, 1000 s of cutting;
/// a longer run's plot shows the highest load of each stretch of periods).
const PLOT_ROWS: usize = 50_000;

/// `host`'s options.
#[derive(clap::Args)]
pub(crate) struct HostArgs {
    pub(crate) program: Option<PathBuf>,
    #[arg(long, default_value = "out/host")]
    pub(crate) out: PathBuf,
    #[command(flatten)]
    pub(crate) cut: CutArgs,
}

/// `host`: the program file, or the demo's job without one, through [`host`].
pub(crate) fn command(args: HostArgs) -> Result<bool> {
    let HostArgs { program, out, cut } = args;
    match program {
        Some(p) => with_program(&p, &out, |text| host(text, &out, &cut)),
        None => {
            let (j, cut) = demo_job(&cut);
            host(&j.program, &out, &cut)
        }
    }
}

fn host(text: &str, out: &Path, args: &CutArgs) -> Result<bool> {
    use millac_qemu::{evaluation::acreport, host::acsim};
    let settings = Settings::default();
    let prog = match analysis::load_program(text, &settings) {
        Ok(p) => p,
        Err(e) => {
            let r = runner::Rejected {
                line: e.line(),
                message: e.to_string(),
            };
            return runner::write_rejection(out, &r).map(|_| false);
        }
    };
    let cut = cut_setup(text, args)?;
    let acs = args.ac_settings(&cut);
    // From here on the folder is written: a failure leaves its report there.
    reported(
        out,
        false,
        (|| -> Result<bool> {
            std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
            // The AC's run and the comparison's (the programmed feeds on a thread of their own,
            // the oracle on the pulses, then the safe constant feed, which needs the oracle)
            // are independent: threads, the same results as one after the other.
            // ac.csv is written as the run goes; the plot keeps a bounded number of rows; the
            // holds are counted: a long program's rows are not held in memory.
            let csv = out.join("ac.csv");
            let file = std::fs::File::create(&csv)
                .with_context(|| format!("writing {}", csv.display()))?;
            let mut writer = std::io::BufWriter::new(file);
            let mut written = std::io::Write::write_all(&mut writer, acsim::CSV_HEADER.as_bytes());
            let mut plot_rows = acsim::PlotRows::new(PLOT_ROWS);
            let mut holds = 0usize;
            let (run, cmp) = std::thread::scope(|s| {
                let comparison = s.spawn(|| {
                    millac_qemu::progress::with_bar("comparison", prog.len(), || {
                        let record = acsim::Record::figures(f64::from(acs.optimal_fraction));
                        acreport::compare_recorded(&prog, &settings, &cut, &acs, record)
                    })
                });
                let label = if args.no_ac {
                    "programmed feeds"
                } else {
                    "AC run"
                };
                let run = millac_qemu::progress::with_bar(label, prog.len(), || {
                    // The rows to ac.csv and the plot; the samples as their load figures.
                    let record = acsim::Record::figures(f64::from(acs.optimal_fraction));
                    acsim::run_recorded(
                        &prog,
                        &settings,
                        &cut,
                        (!args.no_ac).then_some(acs),
                        &args.faults,
                        record,
                        Some(&mut |r| {
                            if written.is_ok() {
                                written = std::io::Write::write_all(
                                    &mut writer,
                                    acsim::csv_line(r).as_bytes(),
                                );
                            }
                            holds += usize::from(r.state.starts_with("hold"));
                            plot_rows.push(r);
                        }),
                    )
                });
                let cmp = comparison
                    .join()
                    .unwrap_or_else(|p| std::panic::resume_unwind(p));
                (run, cmp)
            });
            let run = run?;
            written
                .and_then(|()| std::io::Write::flush(&mut writer))
                .with_context(|| format!("writing {}", csv.display()))?;
            let plot_rows = plot_rows.finish();
            acreport::plot_against(&out.join("ac.svg"), &plot_rows.rows, &acs, &settings)?;
            // Each tool its own figure, against its own F0 and T0 (ac.svg's are the machine's).
            let figures = acreport::plot_tools(out, &plot_rows.rows, &cut, &acs, &settings)?;
            millac_qemu::evaluation::heightmap::write_tool_stocks(out, &run.stocks)?;
            let load = run.load;
            // The comparison's runs (constant feeds, the oracle) are left out once a signal has come:
            // they were cut short too.
            let signal = millac_qemu::interrupt::received().map(millac_qemu::interrupt::name);
            let cmp = match signal {
                None => Some(cmp?),
                Some(_) => None,
            };
            println!(
                "millac host run ({}): final position {:?}",
                match (args.no_ac, args.strategy) {
                    (true, _) => "no AC".to_string(),
                    (false, None) => "AC".to_string(),
                    (false, Some(_)) => format!("AC, strategy {}", acs.strategy.name()),
                },
                run.final_position
            );
            if let Some(a) = run.alarm {
                println!("  alarm: {a}");
            }
            // The keys of `run`'s summary.json that apply to a host run.
            let completed = run.blocks_done >= prog.len() && !run.interrupted;
            let [x, y, z] = run.final_position;
            let mut summary = serde_json::json!({
                "blocks": prog.len(),
                "machining_time_s": (run.machining_time_s * 1e6).round() / 1e6,
                "final_position_blu": {"x": x, "y": y, "z": z},
                "completed": completed,
            });
            summary["ac"] = match &cmp {
                Some(cmp) => acreport::ac_json(run.machining_time_s, &load, cmp),
                None => serde_json::json!({}),
            };
            summary["ac"]["enabled"] = serde_json::json!(!args.no_ac);
            summary["ac"]["strategy"] = serde_json::json!(acs.strategy.name());
            summary["ac"]["samples"] = serde_json::json!(run.sample_count);
            summary["ac"]["holds"] = serde_json::json!(holds);
            let hold = (!completed).then(|| runner::Hold {
                alarm: run.alarm.map(|a| a.to_string()).unwrap_or_default(),
                blocks_done: run.blocks_done,
                position: run.final_position,
                signal: signal.clone().filter(|_| run.interrupted),
            });
            if let Some(h) = &hold {
                let key = if h.signal.is_some() {
                    "interrupted"
                } else {
                    "hold"
                };
                summary[key] = runner::hold_json(&prog, h);
            }
            if let (Some(s), false) = (&signal, run.interrupted) {
                // The run itself finished; only the comparison was left out.
                summary["interrupted"] = serde_json::json!({"signal": s, "left_out": "comparison"});
            }
            if let Some(cmp) = &cmp {
                let log = acreport::tool_log(&run.tools, cmp);
                if !log.is_empty() {
                    summary["tools"] = serde_json::json!(log);
                }
            }
            let why = hold.as_ref().map(|h| runner::held_at(&prog, h));
            match &cmp {
                Some(cmp) => acreport::print_table(
                    run.machining_time_s,
                    &load,
                    cmp,
                    why.as_deref(),
                    acs.strategy,
                ),
                None => println!(
                "  interrupted: {}; the comparison with constant feeds and the oracle is left out",
                why.as_deref().unwrap_or("the run had finished")
            ),
            }
            if let Some(log) = summary["tools"].as_array() {
                acreport::print_tool_log(log);
            }
            runner::write_json(&out.join("summary.json"), &summary)?;
            acreport::print_figures(out, &figures);
            println!(
                "  wrote {}/ac.csv, {}/ac.svg and {}/summary.json",
                out.display(),
                out.display(),
                out.display()
            );
            if plot_rows.stride > 1 {
                println!(
                    "  ac.svg: one AC period in {} (the highest true force of each {}); ac.csv has them all",
                    plot_rows.stride, plot_rows.stride
                );
            }
            let end = prog.last().map_or([0; 3], |b| b.end).map(i64::from);
            Ok(completed && run.final_position == end)
        })(),
    )
}
