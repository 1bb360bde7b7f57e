//! Sensor faults injected under QEMU (host): `millac run --fault KIND@SECONDS` feeds the firmware's
//! lockstep ADC the codes of a failing transducer (the same `fault::Injector` as `millac host
//! --fault`). A full-depth slot in the blank (from a start hole) at F22 (near F0, cutting from about 0.3 s on),
//! each kind injected at 1.5 s: the firmware must hold with that kind's own alarm within the
//! kind's bound, at an exact position (the capture ends where the hold says), the true force
//! must stay below the permissible limit, and the run must leave all its report files and exit
//! with status 1. The host simulation with the same `--fault` must hold with the same alarm.
use millac::ac::AcSettings;
use millac_qemu::host::fault::FaultKind;
use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;
use std::sync::OnceLock;

/// Stock: the Fig. 1 blank with a start hole at the slot's start (the tool there overlaps the
/// blank's edge by 0.15 in, and the end face cuts: without the hole the rapid down to full depth
/// would be a crash into the edge, an overload hold before the fault).
const STOCK: &str = "blank X0 Y0 W5 H3 Z0\nhole X-0.1 Y1.5 D0.5 Z-0.3\n";
/// Beside the blank at full depth, then a straight slot at F22.
const SLOT: &str = "G20 G90\nG0 X-0.1 Y1.5\nG0 Z-0.3\nG1 X3 F22\nM2\n";
/// The fault's time: well inside the cut, after the entry has settled.
const AT_MS: u64 = 1500;

/// The longest time from the fault to the first AC period in hold (ms, period deadlines):
/// - `rail`, `spike`: the jump is judged at the sample that follows it (which may fall in the next
///   period): 2 periods;
/// - `dropout`: the period the fault starts in may still hold fresh samples, the next has none:
///   2 periods;
/// - `frozen`: `frozen_samples` samples without change, then the period that ends: that + 2
///   periods;
/// - `gain`: `ft_periods` windows out of the F*R/T band, the first one may be partly before the
///   fault: `ft_periods` + 2 periods.
fn bound_ms(kind: FaultKind) -> u64 {
    let s = AcSettings::default();
    let period = u64::from(s.period_ms);
    match kind {
        FaultKind::Rail | FaultKind::Spike | FaultKind::Dropout => 2 * period,
        FaultKind::Frozen => {
            u64::from(s.frozen_samples) * 1000 / u64::from(s.sample_hz) + 2 * period
        }
        FaultKind::Gain => (u64::from(s.ft_periods) + 2) * period,
    }
}

/// The kind's own alarm (summary.json `hold.alarm`, the firmware's `alarm:` line).
fn alarm_matches(kind: FaultKind, alarm: &str) -> bool {
    match kind {
        FaultKind::Rail => {
            (alarm.starts_with("sensor hold: T jumped from code") && alarm.ends_with("to 4095"))
                || alarm == "sensor hold: T stuck at code 4095"
        }
        FaultKind::Frozen => alarm.contains(" frozen at code "),
        FaultKind::Dropout => alarm == "sensor hold: no fresh samples in an AC period",
        FaultKind::Spike => alarm.starts_with("sensor hold: Fu jumped from code"),
        FaultKind::Gain => alarm.starts_with("sensor hold: force and torque disagree: F*R/T = "),
    }
}

/// One run's results.
struct Run {
    status: Option<i32>,
    stdout: String,
    out: PathBuf,
    summary: Value,
    /// ac.csv rows, split at the commas (header dropped).
    rows: Vec<Vec<String>>,
}

impl Run {
    /// The first row in hold: (t_ms, state).
    fn first_hold(&self) -> Option<(u64, &str)> {
        self.rows
            .iter()
            .find(|r| r[10].starts_with("hold:"))
            .map(|r| (r[0].parse().unwrap(), r[10].as_str()))
    }
}

/// Runs `millac-qemu MODE p.nc --out out --stock stock.txt --fault KIND@1.5` in its own directory.
fn millac(mode: &str, kind: FaultKind) -> Run {
    millac_in(mode, kind, "")
}

/// As [`millac`], in a directory named with `tag`.
fn millac_in(mode: &str, kind: FaultKind, tag: &str) -> Run {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("faults-{mode}-{}{tag}", kind.name()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("stock.txt"), STOCK).unwrap();
    std::fs::write(dir.join("p.nc"), SLOT).unwrap();
    let fault = format!("{}@{}", kind.name(), AT_MS as f64 / 1000.0);
    let o = Command::new(env!("CARGO_BIN_EXE_millac-qemu"))
        .current_dir(&dir)
        .args([
            mode,
            "p.nc",
            "--out",
            "out",
            "--stock",
            "stock.txt",
            "--fault",
            &fault,
        ])
        .output()
        .expect("running millac-qemu");
    let stdout = format!(
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let out = dir.join("out");
    let summary = std::fs::read_to_string(out.join("summary.json"))
        .map(|s| serde_json::from_str(&s).unwrap())
        .unwrap_or_else(|e| panic!("{mode} {fault}: no summary.json ({e}):\n{stdout}"));
    let csv = std::fs::read_to_string(out.join("ac.csv"))
        .unwrap_or_else(|e| panic!("{mode} {fault}: no ac.csv ({e}):\n{stdout}"));
    let rows = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_string).collect::<Vec<_>>())
        .collect::<Vec<_>>();
    let columns = millac_qemu::host::acsim::CSV_HEADER
        .trim_end()
        .split(',')
        .count();
    assert!(
        rows.iter().all(|r| r.len() == columns),
        "{mode} {fault}: ac.csv rows"
    );
    Run {
        status: o.status.code(),
        stdout,
        out,
        summary,
        rows,
    }
}

/// The QEMU run of each kind, made once and shared by the tests.
fn qemu(kind: FaultKind) -> &'static Run {
    static RUNS: [OnceLock<Run>; 5] = [const { OnceLock::new() }; 5];
    let i = FaultKind::ALL.iter().position(|&k| k == kind).unwrap();
    RUNS[i].get_or_init(|| millac("run", kind))
}

fn xyz(v: &Value) -> [i64; 3] {
    [&v["x"], &v["y"], &v["z"]].map(|c| c.as_i64().unwrap())
}

/// Everything a faulted QEMU run must show; returns the time from the fault to the hold (ms).
fn check_qemu(kind: FaultKind) -> u64 {
    let r = qemu(kind);
    let (name, s) = (kind.name(), &r.summary);
    assert_eq!(r.status, Some(1), "{name}: {}", r.stdout);
    for f in ["summary.json", "capture.vcd", "ac.csv", "ac.svg"] {
        assert!(r.out.join(f).is_file(), "{name}: {f} missing");
    }
    assert_eq!(s["completed"], false, "{name}: {s:#}");
    let alarm = s["hold"]["alarm"].as_str().unwrap();
    assert!(alarm_matches(kind, alarm), "{name}: alarm `{alarm}`");
    assert!(
        r.stdout
            .contains("the program did not finish: held at line 4")
            && r.stdout.contains(&format!("BLU): {alarm}")),
        "{name}: {}",
        r.stdout
    );
    // Held after the fault, within the kind's bound.
    let (t_hold, state) = r.first_hold().expect("a hold row in ac.csv");
    assert!(
        t_hold >= AT_MS,
        "{name}: held at {t_hold} ms, before the fault"
    );
    let dt = t_hold - AT_MS;
    println!(
        "{name}@{}: held {dt} ms after the fault (bound {} ms): {alarm}",
        AT_MS as f64 / 1000.0,
        bound_ms(kind)
    );
    assert!(dt <= bound_ms(kind), "{name}: {dt} ms to hold");
    assert_eq!(
        state.strip_prefix("hold:").unwrap(),
        hold_message(kind, alarm),
        "{name}"
    );
    // The hold's position is exact: the capture, the firmware and ac.csv end there.
    let pos = xyz(&s["hold"]["position_blu"]);
    let trace = millac_qemu::analysis::vcd::read_vcd(
        &std::fs::read_to_string(r.out.join("capture.vcd")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        millac_qemu::analysis::vcd::positions(trace.initial, &trace.events),
        pos,
        "{name}"
    );
    assert_eq!(xyz(&s["final_position_blu"]), pos, "{name}");
    assert_eq!(xyz(&s["firmware_position_blu"]), pos, "{name}");
    let last = r.rows.last().unwrap();
    assert_eq!(
        [1, 2, 3].map(|i| last[i].parse::<i64>().unwrap()),
        pos,
        "{name}"
    );
    assert!(
        pos[0] > 0 && pos[0] < 30_000,
        "{name}: held in the cut, {pos:?}"
    );
    // Nothing moved after the hold settled: the last rows are at the hold's position.
    assert!(r.rows[r.rows.len() - 50..]
        .iter()
        .all(|row| [1, 2, 3].map(|i| row[i].parse::<i64>().unwrap()) == pos));
    // The true force never reached the permissible limit, before or after the fault.
    let limit = f64::from(AcSettings::default().force_limit_n);
    let peak = r
        .rows
        .iter()
        .map(|row| row[7].parse::<f64>().unwrap())
        .fold(0.0, f64::max);
    assert!(peak < limit, "{name}: true force peak {peak} N");
    assert!(
        s["ac"]["peak_force_ratio"].as_f64().unwrap() < 1.0,
        "{name}: {s:#}"
    );
    assert!(
        s["ac"]["time_above_limit_s"].as_f64().unwrap() == 0.0,
        "{name}: {s:#}"
    );
    dt
}

/// The fixed text of ac.csv's `hold:` state for the alarm (`Alarm::message`).
fn hold_message(kind: FaultKind, alarm: &str) -> &'static str {
    match kind {
        FaultKind::Rail if alarm.contains("stuck") => "sensor stuck at an ADC rail",
        FaultKind::Rail | FaultKind::Spike => "sensor jump larger than plausible",
        FaultKind::Frozen => "sensor frozen while the axes feed",
        FaultKind::Dropout => "no fresh sensor samples in an AC period",
        FaultKind::Gain => "force and torque disagree (transducer gain)",
    }
}

#[test]
fn rail_under_qemu_holds_with_its_alarm() {
    check_qemu(FaultKind::Rail);
}

#[test]
fn frozen_under_qemu_holds_with_its_alarm() {
    check_qemu(FaultKind::Frozen);
}

/// The wire's NO_CONVERSION: the firmware's AC periods see no samples and hold; the run is a
/// hold with its report (status 1), not a lost ADC (no report, status 2).
#[test]
fn dropout_under_qemu_holds_with_no_samples_and_leaves_its_report() {
    check_qemu(FaultKind::Dropout);
    let r = qemu(FaultKind::Dropout);
    assert!(!r.stdout.contains("simulated ADC lost"), "{}", r.stdout);
    // Every period from the hold on saw nothing new: measured F, T and E stay as they were.
    let i = r
        .rows
        .iter()
        .position(|row| row[10].starts_with("hold:"))
        .unwrap();
    let held = &r.rows[i..];
    assert!(held
        .iter()
        .all(|row| row[5..7] == held[0][5..7] && row[9] == held[0][9]));
}

#[test]
fn spike_under_qemu_holds_with_its_alarm() {
    check_qemu(FaultKind::Spike);
}

/// A loose transducer: the force codes alone look like a light cut; the force/torque
/// plausibility check (`millac::ac::plaus`) holds under QEMU as on the host.
#[test]
fn gain_under_qemu_holds_on_the_force_torque_check() {
    check_qemu(FaultKind::Gain);
}

/// One code path: the host simulation and the firmware under QEMU, given the same `--fault`, hold
/// with the same kind of alarm (the same `hold:` state in ac.csv and the same alarm text up to
/// its numbers).
#[test]
fn host_and_qemu_faults_hold_with_the_same_alarm() {
    for kind in FaultKind::ALL {
        let q = qemu(kind);
        let h = millac("host", kind);
        let name = kind.name();
        assert_eq!(h.status, Some(1), "{name}: {}", h.stdout);
        let (tq, sq) = q.first_hold().expect("QEMU hold");
        let (th, sh) = h.first_hold().expect("host hold");
        println!("{name}: QEMU held at {tq} ms, host at {th} ms: {sq}");
        assert_eq!(sq, sh, "{name}");
        let words = |v: &Value| {
            v["hold"]["alarm"]
                .as_str()
                .unwrap()
                .split(|c: char| c.is_ascii_digit() || c == '.' || c == '=')
                .next()
                .unwrap()
                .to_string()
        };
        assert_eq!(words(&q.summary), words(&h.summary), "{name}");
        assert!(alarm_matches(
            kind,
            h.summary["hold"]["alarm"].as_str().unwrap()
        ));
    }
}

/// Same inputs, same bytes out: a faulted run repeated writes the same report files.
#[test]
fn a_faulted_run_is_deterministic() {
    let a = qemu(FaultKind::Dropout);
    let b = millac_in("run", FaultKind::Dropout, "-again");
    for f in ["summary.json", "ac.csv", "capture.vcd"] {
        let read = |r: &Run| std::fs::read(r.out.join(f)).unwrap();
        assert!(read(a) == read(&b), "{f} differs");
    }
}

/// `--fault` is refused where there is no simulated ADC to fail.
#[test]
fn fault_needs_the_simulated_adc() {
    let o = Command::new(env!("CARGO_BIN_EXE_millac-qemu"))
        .args(["run", "p.nc", "--nc-only", "--fault", "rail@1"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--fault"));
}
