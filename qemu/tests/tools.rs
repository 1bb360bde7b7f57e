//! The machine's tool table and a program's tool changes (host): `run` under QEMU and `host` on
//! a two-tool program with `--tools`. The firmware gets the table in its settings record, its
//! loader fits each tool at the M6 (its limits to the AC, its number to the simulated spindle),
//! the co-simulated plant cuts with it; `host` makes the same changes. The small tool's head-on
//! entry at the big tool's feed is held on the small tool's own limit, under QEMU and on the
//! host, and `ac.csv` names the tool of every AC period.
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const STOCK: &str = "blank X0 Y0 W3 H3 Z0\n";
const TOOLS: &str = "# the Fig. 1 cutter and a 3 mm end mill\n$T1=D12.7 N4 K0 F4000 M80\n\
                     $T2=D3 N2 K0 (limits from its geometry)\n";
/// A short slot with T1, then T2 into the blank head on at full depth and T1's feed.
const PROGRAM: &str = "G20 G90 G94\nT1 M6\nM3 S600\nG0 X-0.5 Y2.5\nG0 Z-0.3\nG1 X1.0 F20\n\
                       G0 Z0.2\nT2 M6\nM3 S1500\nG0 X1.0 Y-0.5\nG0 Z-0.08\nG1 Y2.0 F20\nG0 Z0.2\nM2\n";

fn millac(dir: &Path, args: &[&str]) -> Output {
    std::fs::write(dir.join("stock.txt"), STOCK).unwrap();
    std::fs::write(dir.join("tools.txt"), TOOLS).unwrap();
    std::fs::write(dir.join("p.nc"), PROGRAM).unwrap();
    Command::new(env!("CARGO_BIN_EXE_millac-qemu"))
        .current_dir(dir)
        .args(args)
        .args(["p.nc", "--stock", "stock.txt", "--tools", "tools.txt"])
        .output()
        .expect("running millac-qemu")
}

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("tools-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The tool column of ac.csv, one entry per AC period.
fn tools_of(csv: &str) -> Vec<u8> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let k = header
        .iter()
        .position(|h| *h == "tool")
        .expect("a tool column");
    lines
        .map(|l| l.split(',').nth(k).unwrap().parse().unwrap())
        .collect()
}

#[test]
fn the_small_tool_is_held_on_its_own_limit_under_qemu_and_on_the_host() {
    for cmd in ["run", "host"] {
        let dir = scratch(cmd);
        let o = millac(&dir, &[cmd, "--out", "out"]);
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert_eq!(o.status.code(), Some(1), "{cmd}: {stdout}");
        let out = dir.join("out");
        let s: Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        let alarm = s["hold"]["alarm"].as_str().unwrap_or_default();
        assert!(alarm.contains("limit 226.2 N"), "{cmd}: {s:#}");
        // The load figures take each sample against its own tool's limits: the head-on entry
        // loads the small tool beyond its 226 N before the hold (0.85 of the big tool's 4000 N
        // is its own slot's).
        let peak = s["ac"]["peak_force_ratio"].as_f64().unwrap();
        assert!(peak > 1.0, "{cmd}: {s:#}");
        let tools = tools_of(&std::fs::read_to_string(out.join("ac.csv")).unwrap());
        assert!(
            tools.windows(2).all(|w| w[0] <= w[1]),
            "{cmd}: the tools in order"
        );
        assert!(tools.contains(&1), "{cmd}");
        assert_eq!(tools.last(), Some(&2), "{cmd}: held with T2");
        if cmd == "host" {
            let log = s["tools"].as_array().unwrap();
            assert_eq!(log.len(), 2, "{s:#}");
            assert_eq!((&log[0]["tool"], &log[1]["tool"]), (&1.into(), &2.into()));
            assert_eq!(log[1]["holds"], 1, "{s:#}");
        }
    }
}

/// The demo, `cargo run --release` with no arguments (here the test build of the same binary):
/// the whole Fig. 1 job under QEMU, generated from the cavity's geometry, runs to its end with
/// no hold, every tool within its own limits (summary.json's AFC log, one entry per tool), and
/// leaves each tool's figure and stock picture and the job's files beside its report.
#[test]
fn the_demo_machines_the_whole_job_without_a_hold_within_every_tools_limits() {
    let dir = scratch("demo");
    let o = Command::new(env!("CARGO_BIN_EXE_millac-qemu"))
        .current_dir(&dir)
        .output()
        .expect("running millac-qemu");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let out = dir.join("out/demo");
    let s: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["completed"], true);
    let tools = s["tools"].as_array().expect("the AFC log");
    let numbers: Vec<u64> = tools.iter().map(|t| t["tool"].as_u64().unwrap()).collect();
    assert_eq!(numbers, [1, 2, 3, 4]);
    for t in tools {
        let f = |k: &str| t[k].as_f64().unwrap_or(f64::NAN);
        assert!(
            f("peak_force_ratio") < 1.0
                && f("peak_torque_ratio") < 1.0
                && f("time_above_limit_s") == 0.0
                && t["holds"] == 0,
            "{t}"
        );
        assert!(f("cutting_s") > 1.0, "{t}");
        // No faster than the bound of its part.
        assert!(f("time_s") >= f("time_bound_s"), "{t}");
    }
    for n in 1..=4 {
        for f in [format!("ac-T{n}.svg"), format!("stock-T{n}.png")] {
            assert!(out.join(&f).is_file(), "{f}");
        }
    }
    let shipped = include_str!("../programs/fig1-job.nc");
    assert_eq!(
        std::fs::read_to_string(out.join("fig1-job.nc")).unwrap(),
        shipped
    );
    assert!(stdout.contains("per tool (AFC log)"), "{stdout}");
}
