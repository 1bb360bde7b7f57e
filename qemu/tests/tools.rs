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
