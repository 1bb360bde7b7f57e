//! A run whose adaptive controller holds leaves a full report (host): `run` under QEMU against the
//! simulated cut and `host` on the same program. The program enters the cut at full depth at
//! F30, the overload the paper's loop cannot catch in 10 ms: the firmware prints `alarm: ...` and
//! `millac: hold blocks=N position=...` and stops. Whatever the alarm's text, the run must write
//! all its files, say it did not complete, carry the alarm, the running block and the exact
//! position, and exit with status 1 (a check failed), never 2 (the tool failed).
use millac::Settings;
use millac_qemu::analysis;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Stock: the plain Fig. 1 blank, no start hole (so the entry cuts at full depth).
const STOCK: &str = "blank X0 Y0 W5 H3 Z0\n";
/// Rapid beside the blank, down to full depth, then into the blank at F30.
const HELD: &str = "G0 X-1 Y1.5\nG0 Z-0.3\nG1 X2.5 F30\n";

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("hold-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the host tool with `args` and the stock and program files written to `dir`.
fn millac(dir: &Path, program: &str, args: &[&str]) -> Output {
    std::fs::write(dir.join("stock.txt"), STOCK).unwrap();
    std::fs::write(dir.join("p.nc"), program).unwrap();
    Command::new(env!("CARGO_BIN_EXE_millac-qemu"))
        .current_dir(dir)
        .args(args)
        .args(["--stock", "stock.txt"])
        .output()
        .expect("running millac-qemu")
}

fn summary(out: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

fn xyz(v: &Value) -> [i64; 3] {
    [&v["x"], &v["y"], &v["z"]].map(|c| c.as_i64().unwrap())
}

/// The line of the block that was running when the firmware reported `blocks` done.
fn running_line(program: &str, blocks: usize) -> u32 {
    let prog = analysis::load_program(program, &Settings::default()).unwrap();
    prog[blocks].block.line
}

fn check_held(o: &Output, out: &Path, s: &Value) {
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stdout}\n{stderr}");
    assert_eq!(s["completed"], false, "{s:#}");
    let hold = &s["hold"];
    let alarm = hold["alarm"].as_str().unwrap();
    assert!(!alarm.is_empty(), "{s:#}");
    let blocks = hold["blocks_done"].as_u64().unwrap() as usize;
    assert_eq!(hold["block"], running_line(HELD, blocks), "{s:#}");
    assert_eq!(
        xyz(&hold["position_blu"]),
        xyz(&s["final_position_blu"]),
        "{s:#}"
    );
    // The held position is not the programmed end.
    let end = analysis::load_program(HELD, &Settings::default())
        .unwrap()
        .last()
        .unwrap()
        .end;
    assert_ne!(xyz(&s["final_position_blu"]), end.map(i64::from));
    assert!(s["ac"]["time_s"].as_f64().unwrap() > 0.0, "{s:#}");
    assert!(
        stdout.contains(&format!("did not finish: held at line {}", hold["block"])),
        "{stdout}"
    );
    for f in ["summary.json", "ac.csv", "ac.svg"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    // ac.csv shows the hold.
    let csv = std::fs::read_to_string(out.join("ac.csv")).unwrap();
    assert!(csv.lines().any(|l| l.contains(",hold:")));
}

#[test]
fn a_held_qemu_run_writes_its_report_and_says_it_did_not_complete() {
    let dir = scratch("run");
    let o = millac(&dir, HELD, &["run", "p.nc", "--out", "out"]);
    let out = dir.join("out");
    let s = summary(&out);
    check_held(&o, &out, &s);
    assert!(out.join("capture.vcd").is_file());
    assert!(s["ac"]["holds"].as_u64().unwrap() >= 1, "{s:#}");
    // The firmware's own position report is the hold's.
    let fw = s["firmware_position_blu"].clone();
    assert_eq!(xyz(&fw), xyz(&s["hold"]["position_blu"]), "{s:#}");
    // ac.csv ends held, at the hold's position (encoder counts).
    let csv = std::fs::read_to_string(out.join("ac.csv")).unwrap();
    let last: Vec<&str> = csv.lines().last().unwrap().split(',').collect();
    assert!(last[10].starts_with("hold:"), "{last:?}");
    let enc = [1, 2, 3].map(|i| last[i].parse::<i64>().unwrap());
    assert_eq!(enc, xyz(&s["hold"]["position_blu"]));
    // Only the blocks that ran are checked: those that completed ended exactly.
    assert_eq!(s["end_points_exact"], true, "{s:#}");
    // The capture itself ends where the hold says.
    let trace = millac_qemu::analysis::vcd::read_vcd(
        &std::fs::read_to_string(out.join("capture.vcd")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        millac_qemu::analysis::vcd::positions(trace.initial, &trace.events),
        xyz(&s["hold"]["position_blu"])
    );
}

#[test]
fn a_held_host_run_writes_summary_json_too() {
    let dir = scratch("host");
    let o = millac(&dir, HELD, &["host", "p.nc", "--out", "out"]);
    let out = dir.join("out");
    let s = summary(&out);
    check_held(&o, &out, &s);
    assert!(s["machining_time_s"].as_f64().is_some(), "{s:#}");
}

#[test]
fn a_completed_host_run_says_so() {
    let dir = scratch("host-done");
    // In the air above the blank: nothing to hold on.
    let program = "G0 Z0.1\nG1 X0.5 F20\nG0 X0\n";
    let o = millac(&dir, program, &["host", "p.nc", "--out", "out"]);
    let out = dir.join("out");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = summary(&out);
    assert_eq!(s["completed"], true, "{s:#}");
    assert!(s.get("hold").is_none(), "{s:#}");
    let end = analysis::load_program(program, &Settings::default())
        .unwrap()
        .last()
        .unwrap()
        .end;
    assert_eq!(xyz(&s["final_position_blu"]), end.map(i64::from));
    assert!(s["ac"]["time_s"].as_f64().is_some(), "{s:#}");
}
