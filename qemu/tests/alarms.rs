//! The AC's alarm corpus on the host simulation (`millac_qemu::evaluation::alarmlab`, host tests): no alarm
//! on any ordinary cut (an overload hold only where the true load crossed the overload level),
//! and every injected sensor fault held with its own alarm within its bound. The table of docs/dev/results-ac.md
//! is the `alarm_table` example's print of the same runs.
use millac_qemu::evaluation::alarmlab::{self, Program};
use std::path::Path;

fn corpus() -> Vec<Program> {
    alarmlab::corpus(&Path::new(env!("CARGO_MANIFEST_DIR")).join("programs")).unwrap()
}

/// Ordinary cuts on which a monitor is known to raise a false alarm, each with what it is: a
/// defect to mend, not a licence. The test requires the alarm to be still there, so that the entry
/// goes when the monitor is mended (as rs274's KNOWN_REFUSALS).
const KNOWN_FALSE_ALARMS: &[(&str, &str)] = &[];

#[test]
fn ordinary_cuts_raise_no_false_alarm() {
    let corpus = corpus();
    assert!(corpus.len() >= 30, "{} programs", corpus.len());
    let base = alarmlab::parallel(&corpus, |p| alarmlab::run(p, &[])).unwrap();
    let known = |name: &str| KNOWN_FALSE_ALARMS.iter().find(|(n, _)| *n == name);
    let wrong: Vec<String> = corpus
        .iter()
        .zip(&base)
        .filter(|(p, o)| alarmlab::false_alarm(o) && known(&p.name).is_none())
        .map(|(p, o)| format!("{}: {}", p.name, o.run.alarm.unwrap()))
        .collect();
    assert!(wrong.is_empty(), "false alarms:\n{}", wrong.join("\n"));
    for (name, what) in KNOWN_FALSE_ALARMS {
        let (_, o) = corpus
            .iter()
            .zip(&base)
            .find(|(p, _)| p.name == *name)
            .unwrap_or_else(|| panic!("{name} is not in the corpus"));
        let said = o.run.alarm.map(|a| a.to_string()).unwrap_or_default();
        assert!(
            alarmlab::false_alarm(o) && said.contains(what),
            "{name}: the known false alarm ({what}) is gone (said {said:?}): remove it from \
             KNOWN_FALSE_ALARMS"
        );
    }
    // Every program without a hold ran to its end.
    for (p, o) in corpus.iter().zip(&base) {
        if o.run.alarm.is_none() {
            assert_eq!(o.run.blocks_done, o.blocks, "{}", p.name);
        }
    }
}

#[test]
fn every_injected_fault_is_held_with_its_alarm_within_its_bound() {
    let corpus = corpus();
    let idx = alarmlab::faulted(&corpus).unwrap();
    let base = alarmlab::parallel(&idx, |&i| alarmlab::run(&corpus[i], &[])).unwrap();
    let faulted: Vec<_> = idx.iter().copied().zip(&base).collect();
    let mut cases = alarmlab::fault_cases(&faulted);
    // Every faulted program has its steady times (a corpus change that loses them shows here).
    assert_eq!(
        cases.len(),
        idx.len() * alarmlab::TIMES_PER_PROGRAM * 5,
        "fault cases"
    );
    // And while the tool feeds down (every kind but gain, at two times of each plunge).
    let pidx = alarmlab::indices(&corpus, &alarmlab::PLUNGED).unwrap();
    let pbase = alarmlab::parallel(&pidx, |&i| alarmlab::run(&corpus[i], &[])).unwrap();
    let plunged: Vec<_> = pidx.iter().copied().zip(&pbase).collect();
    let more = alarmlab::plunge_cases(&plunged);
    assert_eq!(more.len(), pidx.len() * 2 * 4, "plunge cases");
    cases.extend(more);
    let found = alarmlab::parallel(&cases, |&(i, f)| alarmlab::detect(&corpus[i], f)).unwrap();
    let missed: Vec<String> = cases
        .iter()
        .zip(&found)
        .filter(|(_, d)| !d.ok)
        .map(|((i, f), d)| {
            format!(
                "{} {}@{}: {:?} after {:?} ms (bound {} ms)",
                corpus[*i].name,
                f.kind.name(),
                f.at_s,
                d.alarm.map(|a| a.to_string()),
                d.to_hold_ms,
                d.bound_ms
            )
        })
        .collect();
    assert!(missed.is_empty(), "missed:\n{}", missed.join("\n"));
}
