//! The AC's false alarms and fault detections over the alarm corpus (host example,
//! `millac_qemu::evaluation::alarmlab`): every ordinary cut with the alarm it got (none expected), then each
//! sensor fault injected at three steady-cutting times into a selection of them, with the alarm,
//! the time from the fault to the hold and its bound. The table of docs/dev/results-ac.md.
//!
//! ```text
//! cargo run -p millac-qemu --release --example alarm_table
//! cargo run -p millac-qemu --release --example alarm_table -- --print "3D raster 0.2 in step-over" > raster.nc
//! ```
//!
//! `--print NAME` writes one program of the corpus (to run it with `millac host ...
//! --monitor-breakage --fault KIND@SECONDS` and look at its ac.csv and ac.svg).
use anyhow::Result;
use millac_qemu::evaluation::alarmlab;
use millac_qemu::host::fault::FaultKind;
use std::path::Path;

fn main() -> Result<()> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("programs");
    let corpus = alarmlab::corpus(&dir)?;
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let [flag, name] = args.as_slice() {
        anyhow::ensure!(flag == "--print", "usage: alarm_table [--print NAME]");
        let p = corpus
            .iter()
            .find(|p| &p.name == name)
            .ok_or_else(|| anyhow::anyhow!("{name}: not in the corpus"))?;
        print!("{}", p.text);
        return Ok(());
    }
    let base = alarmlab::parallel(&corpus, |p| alarmlab::run(p, &[]))?;
    println!("| program | machining time (s) | peak F/Fmax | alarm | |");
    println!("| --- | ---: | ---: | --- | --- |");
    let mut false_alarms = 0;
    for (p, o) in corpus.iter().zip(&base) {
        let peak = o.run.samples.iter().map(|s| s.0).fold(0.0, f64::max);
        let wrong = alarmlab::false_alarm(o);
        if wrong {
            false_alarms += 1;
        }
        println!(
            "| {} | {:.2} | {:.2} | {} | {} |",
            p.name,
            o.run.machining_time_s,
            peak / f64::from(o.ac.force_limit_n),
            o.run.alarm.map_or("none".to_string(), |a| format!(
                "ALARM:{} {a}",
                alarmlab::code(Some(&a))
            )),
            match (o.run.alarm, wrong) {
                (None, _) => "ok",
                (Some(_), false) => "ok: a true overload",
                (Some(_), true) => "FALSE ALARM",
            }
        );
    }
    println!(
        "\nfalse alarms: {false_alarms} of {} programs\n",
        corpus.len()
    );

    let faulted: Vec<_> = alarmlab::faulted(&corpus)?
        .into_iter()
        .map(|i| (i, &base[i]))
        .collect();
    let plunged: Vec<_> = alarmlab::indices(&corpus, &alarmlab::PLUNGED)?
        .into_iter()
        .map(|i| (i, &base[i]))
        .collect();
    let mut cases = alarmlab::fault_cases(&faulted);
    cases.extend(alarmlab::plunge_cases(&plunged));
    let found = alarmlab::parallel(&cases, |&(i, f)| alarmlab::detect(&corpus[i], f))?;
    println!("| program | fault | at (s) | alarm | fault to hold (ms) | bound (ms) | |");
    println!("| --- | --- | ---: | --- | ---: | ---: | --- |");
    let mut missed = 0;
    for ((i, f), d) in cases.iter().zip(&found) {
        if !d.ok {
            missed += 1;
        }
        println!(
            "| {} | {} | {:.3} | {} | {} | {:.0} | {} |",
            corpus[*i].name,
            f.kind.name(),
            f.at_s,
            alarmlab::code(d.alarm.as_ref()),
            d.to_hold_ms.map_or("-".into(), |t| format!("{t:.0}")),
            d.bound_ms,
            if d.ok { "ok" } else { "MISSED" }
        );
    }
    println!(
        "\ndetected within bound: {} of {} injected faults\n",
        cases.len() - missed,
        cases.len()
    );
    // The same, one cell per program and fault: the alarm(s) and the fault-to-hold times.
    let kinds = FaultKind::ALL;
    let names: Vec<&str> = kinds.iter().map(|k| k.name()).collect();
    println!("| program | {} |", names.join(" | "));
    println!("| --- |{}", " --- |".repeat(kinds.len()));
    for &(i, _) in faulted.iter().chain(&plunged) {
        let cells: Vec<String> = kinds
            .iter()
            .map(|&k| {
                let runs: Vec<_> = cases
                    .iter()
                    .zip(&found)
                    .filter(|((j, f), _)| *j == i && f.kind == k)
                    .map(|(_, d)| d)
                    .collect();
                let mut codes: Vec<String> = runs
                    .iter()
                    .map(|d| alarmlab::code(d.alarm.as_ref()))
                    .collect();
                codes.dedup();
                let times: Vec<String> = runs
                    .iter()
                    .map(|d| d.to_hold_ms.map_or("-".into(), |t| format!("{t:.0}")))
                    .collect();
                if runs.is_empty() {
                    return "-".to_string();
                }
                let all = if runs.iter().all(|d| d.ok) {
                    ""
                } else {
                    " MISSED"
                };
                format!("{}: {} ms{all}", codes.join("/"), times.join(", "))
            })
            .collect();
        println!("| {} | {} |", corpus[i].name, cells.join(" | "));
    }
    let ac = &base[0].ac;
    let bounds: Vec<String> = kinds
        .iter()
        .map(|&k| format!("{:.0} ms", alarmlab::bound_ms(k, ac)))
        .collect();
    println!("| bound | {} |", bounds.join(" | "));
    Ok(())
}
