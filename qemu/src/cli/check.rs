//! `millac-qemu check PROGRAM [--json]`: validates a program without running it and says what a
//! machinist asks before pressing start (host: the CLI calls it from `main`): blocks, the tool
//! changes (line, tool, its table entry), the bounding box in machine and work coordinates, the
//! end point, the feeds, the time, and every refused line. Every line goes
//! through the firmware's own line splitter and tape reader (`millac::gcode`, read by
//! `millac_qemu::analysis::read_lines`) as a serial session would stream it: a refused line is
//! reported with its number and the reading goes on (the parser as it was before the line), so
//! one check lists every refusal; the program's end (M2 or M30) ends the reading. The accepted
//! blocks then run through the core's frame (`millac::nc::sim`) for the time estimate: the
//! frame's own arithmetic at the settings' W0 and rapid rate, the feeds as programmed (no adaptive
//! control, 100 % override).
use anyhow::{Context, Result};
use millac::nc::Motion;
use millac::Settings;
use millac_qemu::analysis::{program_of_blocks, read_lines};
use millac_qemu::host::acsim;
use serde_json::json;
use std::path::PathBuf;

/// `check`'s options.
#[derive(clap::Args)]
pub(crate) struct CheckArgs {
    /// The G-code program.
    pub(crate) program: PathBuf,
    /// One JSON object instead of the text (the key names of `run`'s summary.json where they
    /// apply: `blocks`, `final_position_blu`, `error`).
    #[arg(long)]
    pub(crate) json: bool,
}

/// `check`: prints the report; false when a line was refused.
pub(crate) fn command(args: CheckArgs) -> Result<bool> {
    let text = std::fs::read(&args.program)
        .with_context(|| format!("reading {}", args.program.display()))?;
    let settings = Settings::default();
    let mut report = read_lines(&text, &settings);
    let blocks = std::mem::take(&mut report.blocks);
    let prog = program_of_blocks(blocks);
    let (num, den) = settings.blu.per_mm();
    let mm = |blu: i32| blu as f64 * den as f64 / num as f64;
    // The bounding box of every block's start and end (arcs: their end points; an arc's bulge
    // beyond them is not counted), in machine coordinates and in the work coordinates in force
    // for each block (machine minus the origin of its line: system, G92, tool length).
    let pm_per_blu = 1e9 * den as f64 / num as f64;
    let mut lo = [0i32; 3];
    let mut hi = [0i32; 3];
    let mut wlo = [i32::MAX; 3];
    let mut whi = [i32::MIN; 3];
    for b in &prog {
        let o = report.origin_of_line(b.block.line);
        for k in 0..3 {
            lo[k] = lo[k].min(b.start[k]).min(b.end[k]);
            hi[k] = hi[k].max(b.start[k]).max(b.end[k]);
            let shift = (o[k] as f64 / pm_per_blu).round() as i32;
            wlo[k] = wlo[k].min(b.start[k] - shift).min(b.end[k] - shift);
            whi[k] = whi[k].max(b.start[k] - shift).max(b.end[k] - shift);
        }
    }
    if prog.is_empty() {
        (wlo, whi) = ([0; 3], [0; 3]);
    }
    let tools: Vec<serde_json::Value> = report
        .tool_changes
        .iter()
        .map(|t| {
            json!({
                "tool": t.tool,
                "line": t.line,
                "after_blocks": t.after_blocks,
                "diameter_mm": t.entry.map(|e| e.diameter_pm as f64 * 1e-9),
                "length_mm": t.entry.map(|e| e.length_pm as f64 * 1e-9),
            })
        })
        .collect();
    let end = prog.last().map_or([0; 3], |b| b.end);
    let feeds: Vec<f64> = prog
        .iter()
        .filter(|b| matches!(b.block.motion, Motion::Linear(_) | Motion::Arc(_)))
        .map(|b| acsim::programmed_ipm(&settings, &b.block))
        .collect();
    let slowest = feeds.iter().copied().fold(f64::INFINITY, f64::min);
    let fastest = feeds.iter().copied().fold(0.0, f64::max);
    let count = |f: fn(&Motion) -> bool| prog.iter().filter(|b| f(&b.block.motion)).count();
    let rapids = count(|m| matches!(m, Motion::Rapid(_)));
    let lines = count(|m| matches!(m, Motion::Linear(_)));
    let arcs = count(|m| matches!(m, Motion::Arc(_)));
    let seconds = acsim::estimated_time_s(&prog, &settings);
    let first = report.refused.first();
    if args.json {
        let v = json!({
            "program": args.program.display().to_string(),
            "lines": report.lines,
            "blocks": prog.len(),
            "rapids": rapids,
            "linear": lines,
            "arcs": arcs,
            "tools": tools,
            "final_position_blu": end,
            "bounds_blu": { "min": lo, "max": hi },
            "bounds_work_blu": { "min": wlo, "max": whi },
            "estimated_time_s": seconds,
            "feed_min_ipm": (!feeds.is_empty()).then_some(slowest),
            "feed_max_ipm": (!feeds.is_empty()).then_some(fastest),
            "refused": report.refused.iter()
                .map(|r| json!({ "line": r.line, "message": r.message }))
                .collect::<Vec<_>>(),
            "error": first.map(|r| json!({ "line": r.line, "message": r.message })),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "{}: {} lines read, {} blocks ({rapids} rapids, {lines} lines, {arcs} arcs)",
            args.program.display(),
            report.lines,
            prog.len()
        );
        if report.tool_changes.is_empty() {
            println!("tools: no tool change (M6) in the program");
        }
        for t in &report.tool_changes {
            let size = t
                .entry
                .filter(|e| e.diameter_pm != 0 || e.length_pm != 0)
                .map_or(String::from("not described in the tool table"), |e| {
                    format!(
                        "diameter {:.3} mm, length {:.3} mm",
                        e.diameter_pm as f64 * 1e-9,
                        e.length_pm as f64 * 1e-9
                    )
                });
            println!(
                "tool change at line {}: T{} ({size}), after {} blocks",
                t.line, t.tool, t.after_blocks
            );
        }
        let axis = ["X", "Y", "Z"];
        for k in 0..3 {
            println!(
                "{}: {:.4} .. {:.4} mm machine ({} .. {} BLU), {:.4} .. {:.4} mm work",
                axis[k],
                mm(lo[k]),
                mm(hi[k]),
                lo[k],
                hi[k],
                mm(wlo[k]),
                mm(whi[k])
            );
        }
        println!(
            "ends at X {:.4} Y {:.4} Z {:.4} mm",
            mm(end[0]),
            mm(end[1]),
            mm(end[2])
        );
        if feeds.is_empty() {
            println!("feeds: no feed moves");
        } else {
            println!(
                "feeds: {:.2} .. {:.2} in/min ({:.0} .. {:.0} mm/min)",
                slowest,
                fastest,
                slowest * 25.4,
                fastest * 25.4
            );
        }
        println!(
            "estimated time: {seconds:.3} s (the frame at W0 {} Hz and {} Hz rapids, feeds as \
             programmed, no adaptive control)",
            settings.frame_hz, settings.rapid_hz
        );
        for r in &report.refused {
            println!("refused: {}", r.message);
        }
        if report.refused.is_empty() {
            println!("every line accepted");
        }
    }
    Ok(report.refused.is_empty())
}
