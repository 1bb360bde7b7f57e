//! Tests of the host tool's command line (host): the built `millac-qemu` binary on programs that
//! are rejected before anything runs (no QEMU, no firmware build), for `run` and `host`.
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("cli-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A full slot 0.3 in deep at F22 and its steel block, written into `dir`: (program, stock).
fn slot_files(dir: &std::path::Path) -> (PathBuf, PathBuf) {
    let prog = dir.join("slot.nc");
    std::fs::write(
        &prog,
        "G20 G90\nG0 X-0.5 Y1.5\nG0 Z-0.3\nG1 X0.6 F22\nG0 Z0.1\nM2\n",
    )
    .unwrap();
    let stock = dir.join("stock.txt");
    std::fs::write(&stock, "blank X0 Y0 W5 H3 Z0\n").unwrap();
    (prog, stock)
}

fn millac(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_millac-qemu"))
        .args(args)
        .output()
        .expect("running millac-qemu")
}

fn summary(out: &Path) -> Value {
    let p = out.join("summary.json");
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    serde_json::from_str(&text).unwrap()
}

/// A program whose line `bad_line` (1-based) holds the byte 0xff after `prefix`.
fn non_utf8_program(bad_line: usize, prefix: &str) -> Vec<u8> {
    let lines = ["G20 G90", "G1 X0.1 F10", "G1 Y0.1", "G1 X0 Y0", "M2"];
    let mut p = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        if i + 1 == bad_line {
            p.extend_from_slice(prefix.as_bytes());
            p.push(0xff);
        }
        p.extend_from_slice(l.as_bytes());
        p.push(b'\n');
    }
    p
}

fn assert_rejected(o: &Output, out: &Path, line: usize, what: &[&str]) {
    assert_eq!(
        o.status.code(),
        Some(1),
        "stdout: {}\nstderr: {}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let s = summary(out);
    assert_eq!(s["error"]["line"], line, "{s:#}");
    let m = s["error"]["message"].as_str().unwrap();
    assert!(m.starts_with(&format!("line {line}: ")), "{m}");
    for w in what {
        assert!(m.contains(w), "{m} lacks {w}");
    }
}

#[test]
fn non_utf8_program_is_rejected_with_its_line_by_run_and_host() {
    let dir = scratch("utf8");
    let (line, prefix) = (3, "G1 ");
    let prog = dir.join("bad.nc");
    std::fs::write(&prog, non_utf8_program(line, prefix)).unwrap();
    let column = format!("column {}", prefix.len() + 1);
    let run_out = dir.join("run");
    let o = millac(&[
        "run".as_ref(),
        prog.as_os_str(),
        "--out".as_ref(),
        run_out.as_os_str(),
        "--nc-only".as_ref(),
    ]);
    assert_rejected(&o, &run_out, line, &["UTF-8", "0xff", &column]);
    let host_out = dir.join("host");
    let o = millac(&[
        "host".as_ref(),
        prog.as_os_str(),
        "--out".as_ref(),
        host_out.as_os_str(),
    ]);
    assert_rejected(&o, &host_out, line, &["UTF-8", "0xff", &column]);
    // The first line too.
    std::fs::write(&prog, non_utf8_program(1, "")).unwrap();
    let o = millac(&[
        "host".as_ref(),
        prog.as_os_str(),
        "--out".as_ref(),
        host_out.as_os_str(),
    ]);
    assert_rejected(&o, &host_out, 1, &["column 1"]);
}

#[test]
fn host_rejects_a_bad_program_like_run() {
    let dir = scratch("host-reject");
    let prog = dir.join("bad.nc");
    std::fs::write(&prog, "G20 G90\nG1 X0.1 F10\nG1 Q7\nM2\n").unwrap();
    let out = dir.join("host");
    let o = millac(&[
        "host".as_ref(),
        prog.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert_rejected(&o, &out, 3, &[]);
}

/// `host --strategy integral` runs the integral law (summary.json `ac.strategy`, its own feeds:
/// ac.csv differs from the default law's, GPC); `serve` refuses `--strategy` with `--settings`
/// before anything starts.
#[test]
fn host_runs_the_strategy_it_is_given() {
    let dir = scratch("strategy");
    let (prog, stock) = slot_files(&dir);
    let mut csv = Vec::new();
    for (strategy, name) in [(None, "gpc"), (Some("integral"), "integral")] {
        let out = dir.join(name);
        let mut args: Vec<&std::ffi::OsStr> = vec![
            "host".as_ref(),
            prog.as_os_str(),
            "--out".as_ref(),
            out.as_os_str(),
            "--stock".as_ref(),
            stock.as_os_str(),
        ];
        if let Some(s) = strategy {
            args.extend::<[&std::ffi::OsStr; 2]>(["--strategy".as_ref(), s.as_ref()]);
        }
        let o = millac(&args);
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "{stdout}\n{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let s = summary(&out);
        assert_eq!(s["ac"]["strategy"], name, "{s:#}");
        assert_eq!(s["completed"], true, "{s:#}");
        csv.push(std::fs::read_to_string(out.join("ac.csv")).unwrap());
    }
    assert_ne!(csv[0], csv[1], "the integral law ran the paper's feeds");
    let out = dir.join("serve");
    let settings = dir.join("s.bin");
    let o = millac(&[
        "serve".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
        "--settings".as_ref(),
        settings.as_os_str(),
        "--strategy".as_ref(),
        "mrac".as_ref(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("--strategy"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!settings.exists() && !out.exists());
}

/// Bad tooth options are refused with a clear message (status 2) before anything runs or writes:
/// a tooth the 4-flute tool does not have, a run-out list of the wrong length, a malformed or
/// negative value; by `run`, `host`, `demo` and `serve` alike.
#[test]
fn bad_tooth_options_are_refused_before_anything_runs() {
    let dir = scratch("teeth-refused");
    let prog = dir.join("slot.nc");
    std::fs::write(&prog, "G20 G90\nG0 X-0.5 Y1.5\nG1 X0.6 F22\nM2\n").unwrap();
    let cases: [(&[&str], &str); 6] = [
        (&["--break-tooth", "7@1"], "tooth 7 does not exist"),
        (&["--chip-tooth", "4@1"], "tooth 4 does not exist"),
        (&["--runout", "10,0"], "one value per tooth"),
        (&["--runout", "10,x,0,0"], "not a run-out"),
        (&["--chip-tooth", "1@2:-0.1"], "depth"),
        (&["--break-tooth", "1"], "N@SECONDS"),
    ];
    for (i, (opts, msg)) in cases.iter().enumerate() {
        let out = dir.join(format!("out{i}"));
        let cmds: [Vec<&std::ffi::OsStr>; 4] = [
            vec!["host".as_ref(), prog.as_os_str()],
            vec!["run".as_ref(), prog.as_os_str()],
            vec!["demo".as_ref()],
            vec!["serve".as_ref(), "--tcp".as_ref(), "127.0.0.1:0".as_ref()],
        ];
        for mut args in cmds {
            args.extend::<[&std::ffi::OsStr; 2]>(["--out".as_ref(), out.as_os_str()]);
            args.extend(opts.iter().map(std::ffi::OsStr::new));
            let o = millac(&args);
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
            assert!(err.contains(msg), "{args:?}: {err} lacks {msg}");
            assert!(!out.exists(), "{args:?} wrote {}", out.display());
        }
    }
}

/// `host` cuts with the tool it is given: with 10 um of run-out (and -5 um on tooth 2) the slot
/// completes with other true forces than the intact tool's (ac.csv); with tooth 1 breaking at
/// 1 s, the next tooth's doubled chip overloads the cutter under the AC's feed and the run ends in
/// the overload hold (status 1).
#[test]
fn host_cuts_with_the_damaged_tool_it_is_given() {
    let dir = scratch("teeth-host");
    let (prog, stock) = slot_files(&dir);
    let host = |name: &str, opts: &[&str]| {
        let out = dir.join(name);
        let mut args: Vec<&std::ffi::OsStr> = vec![
            "host".as_ref(),
            prog.as_os_str(),
            "--out".as_ref(),
            out.as_os_str(),
            "--stock".as_ref(),
            stock.as_os_str(),
        ];
        args.extend(opts.iter().map(std::ffi::OsStr::new));
        let o = millac(&args);
        let csv = std::fs::read_to_string(out.join("ac.csv")).unwrap();
        (o, summary(&out), csv)
    };
    let (o, s, intact) = host("intact", &[]);
    assert!(o.status.success(), "{s:#}");
    let (o, s, runout) = host("runout", &["--runout", "10,0,-5,0"]);
    assert!(o.status.success(), "{s:#}");
    assert_eq!(s["completed"], true, "{s:#}");
    assert_ne!(intact, runout, "the run-out changed nothing");
    let (o, s, _) = host("broken", &["--break-tooth", "1@1"]);
    assert_eq!(o.status.code(), Some(1), "{s:#}");
    assert_eq!(s["completed"], false, "{s:#}");
    let alarm = s["hold"]["alarm"].as_str().unwrap();
    assert!(alarm.starts_with("overload hold"), "{alarm}");
    assert!(s["ac"]["time_s"].as_f64().unwrap() > 1.0, "{s:#}");
}

/// `--preset thesis-table-3.2` (issue 10) cuts with the table 3.2 tool, flexible in X and Y: a
/// slot at 8.89 mm chatters (its peak force is more than twice what the depth ratio to the
/// 2.54 mm slot would give a rigid tool), the 2.54 mm slot does not.
#[test]
fn the_thesis_preset_chatters_at_8_89_mm_and_not_at_2_54() {
    let dir = scratch("preset");
    let stock = dir.join("al.stock");
    std::fs::write(&stock, "blank X0 Y0 W4 H2 Z0\nhole X0.2 Y1 D0.625 Z-0.4\n").unwrap();
    let mut peaks = Vec::new();
    for (name, z) in [("stable", "-0.1"), ("chatter", "-0.35")] {
        let prog = dir.join(format!("{name}.nc"));
        std::fs::write(
            &prog,
            format!("G20 G90\nG0 X0.2 Y1\nG0 Z{z}\nG1 X2 F6\nG0 Z0.1\nM2\n"),
        )
        .unwrap();
        let out = dir.join(name);
        let o = millac(&[
            "host".as_ref(),
            prog.as_os_str(),
            "--out".as_ref(),
            out.as_os_str(),
            "--stock".as_ref(),
            stock.as_os_str(),
            "--preset".as_ref(),
            "thesis-table-3.2".as_ref(),
            "--no-ac".as_ref(),
        ]);
        assert!(
            o.status.success(),
            "{}\n{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        let s = summary(&out);
        peaks.push(s["ac"]["peak_force_ratio"].as_f64().unwrap());
    }
    let depth_ratio = 0.35 / 0.1;
    assert!(
        peaks[1] > 2.0 * depth_ratio * peaks[0],
        "peaks {peaks:?}: no chatter at 8.89 mm?"
    );
}

/// `--shift` the firmware cannot keep is refused by the command line, before anything is built
/// or run, saying why: 99 is no QEMU shift, at 8 the frame overruns in rapids. Before, 99
/// reached QEMU, whose "Invalid shift value" came last in a message about the plugin, and 8 ran
/// (and lost pulses, until the firmware learnt to hold on a frame overrun).
#[test]
fn a_shift_the_firmware_cannot_keep_is_refused_with_why() {
    let dir = scratch("shift");
    let (prog, _) = slot_files(&dir);
    let out = dir.join("out");
    for (cmd, shift, why) in [
        ("run", "99", "not a QEMU -icount shift"),
        ("run", "8", "cannot keep its frame in rapids"),
        ("serve", "8", "cannot keep its frame in rapids"),
        ("run", "x", "is not a shift"),
    ] {
        let mut args: Vec<&std::ffi::OsStr> = vec![cmd.as_ref()];
        if cmd == "run" {
            args.push(prog.as_os_str());
        }
        args.extend([
            "--out".as_ref(),
            out.as_os_str(),
            "--shift".as_ref(),
            shift.as_ref(),
        ]);
        let o = millac(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{cmd} --shift {shift}: {err}");
        assert!(err.contains("--shift"), "{err}");
        assert!(err.contains(why), "{cmd} --shift {shift}: {err}");
        assert!(err.contains("use 0..=7") || shift == "x", "{err}");
        assert!(!err.contains("plugin"), "{err}");
        assert!(!out.exists(), "nothing is written: {err}");
    }
}

/// A stock reaching outside the machine's travel (`Z1e6`: a blank a thousand inches high) is
/// refused at once with its file, line and what lies where, by `host`, `run` and `optimise`,
/// before anything is written. Before, `host` simulated a cut kilometres deep for hours with no
/// output.
#[test]
fn a_stock_outside_the_machines_travel_is_refused_with_its_line() {
    let dir = scratch("stock-travel");
    let (prog, _) = slot_files(&dir);
    let stock = dir.join("tall.txt");
    std::fs::write(&stock, "# a typo\nblank X0 Y0 W5 H3 Z1e6\n").unwrap();
    let out = dir.join("out");
    for cmd in ["host", "run", "optimise"] {
        let o = millac(&[
            cmd.as_ref(),
            prog.as_os_str(),
            "--stock".as_ref(),
            stock.as_os_str(),
            "--out".as_ref(),
            out.as_os_str(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{cmd}: {err}");
        let want = format!(
            "{}: stock line 2: blank: top Z at 1000000 in lies outside the Z range -4..4 in",
            stock.display()
        );
        assert!(err.contains(&want), "{cmd}: {err}");
        assert!(!out.exists(), "{cmd} wrote {}", out.display());
    }
}

/// `check` reads a program as a serial session streams it: every refused line is reported with
/// its number and the reading goes on; M2 ends it (the line after it is not read); the blocks and
/// the end point are those of the lines it accepted (the same program without the refused lines,
/// read whole by the firmware's tape); the time is the frame's (a 1 in move at 30 in/min: 2 s
/// plus the start and stop ramps). Exits 1 when a line is refused, 0 when none is.
#[test]
fn check_lists_every_refusal_and_reports_the_accepted_program() {
    let dir = scratch("check");
    let good = [
        "G20 G90",
        "G0 X0.5 Y0.25",
        "G1 Z-0.1 F30",
        "G2 X1.0 Y0.25 I0.25 J0",
        "G1 X0 Y0",
        "M2",
    ];
    // Two refused lines among them (cutter compensation, a LinuxCNC parameter), and a line
    // after the program's end.
    let mut lines: Vec<&str> = good.to_vec();
    lines.insert(1, "G41 D1");
    lines.insert(4, "#1 = 2");
    lines.push("G1 X9");
    let prog = dir.join("p.nc");
    std::fs::write(&prog, lines.join("\n")).unwrap();
    let o = millac(&["check".as_ref(), prog.as_os_str(), "--json".as_ref()]);
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    let refused: Vec<u64> = v["refused"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["line"].as_u64().unwrap())
        .collect();
    assert_eq!(refused, [2, 5], "{v}");
    assert_eq!(v["error"]["line"], 2);
    assert!(v["refused"][0]["message"]
        .as_str()
        .unwrap()
        .contains("cutter radius compensation (G41/G42) is not supported"));
    assert_eq!(v["lines"], lines.len() as u64 - 1, "M2 ends the reading");
    let settings = millac::Settings::default();
    let whole = millac_qemu::analysis::load_program(&good.join("\n"), &settings).unwrap();
    assert_eq!(v["blocks"], whole.len() as u64);
    let end = whole.last().unwrap().end;
    assert_eq!(v["final_position_blu"], serde_json::json!(end));
    // The same program without the refused lines: accepted, exit 0.
    std::fs::write(&prog, good.join("\n")).unwrap();
    let o = millac(&["check".as_ref(), prog.as_os_str()]);
    assert_eq!(o.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&o.stdout).contains("every line accepted"));
    // The time of one straight inch at 30 in/min is the frame's: 2 s and its ramps (under 5 %).
    std::fs::write(&prog, "G20 G90 G1 X1 F30\n").unwrap();
    let o = millac(&["check".as_ref(), prog.as_os_str(), "--json".as_ref()]);
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    let t = v["estimated_time_s"].as_f64().unwrap();
    assert!((2.0..2.1).contains(&t), "{t}");
}

/// `check` names each tool change (line, tool, its size when the program describes it with
/// G10 L1) and gives the box in work coordinates as well as in machine ones: a part programmed in
/// G55 at (10, 20) mm with a 50 mm tool under G43 spans 0..5 mm in work X and 10..15 in machine X.
#[test]
fn check_names_the_tool_changes_and_the_work_box() {
    let dir = scratch("check-tools");
    let prog = dir.join("p.nc");
    std::fs::write(
        &prog,
        "G21 G90\nG10 L2 P2 X10 Y20\nG10 L1 P3 Z50 R1.5\nG55 G0 X0 Y0 Z60\nT3 M6\nG43 H3\n\
         G0 Z5\nG1 Z-1 F100\nX5\nT4 M6\nM30\n",
    )
    .unwrap();
    let o = millac(&["check".as_ref(), prog.as_os_str(), "--json".as_ref()]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    let tools = v["tools"].as_array().unwrap();
    assert_eq!(tools.len(), 2, "{v}");
    assert_eq!(
        (&tools[0]["tool"], &tools[0]["line"]),
        (&3.into(), &5.into())
    );
    assert!((tools[0]["diameter_mm"].as_f64().unwrap() - 3.0).abs() < 1e-9);
    assert!((tools[0]["length_mm"].as_f64().unwrap() - 50.0).abs() < 1e-9);
    assert_eq!(
        (&tools[1]["tool"], &tools[1]["line"]),
        (&4.into(), &10.into())
    );
    assert_eq!(tools[1]["length_mm"], 0.0, "T4 is not described");
    // BLU of mm at the default 0.0001 in.
    let blu = |mm: f64| (mm / 0.00254).round() as i64;
    let at = |key: &str, end: &str, k: usize| v[key][end][k].as_i64().unwrap();
    // After the first move (from the machine origin) every block is in G55 with the tool's
    // length: machine X reaches 15 mm, work X 5 mm; work Z goes down to -1 mm (machine 49).
    assert_eq!(at("bounds_blu", "max", 0), blu(15.0));
    assert_eq!(at("bounds_work_blu", "max", 0), blu(5.0));
    assert_eq!(at("bounds_work_blu", "max", 2), blu(60.0));
    assert_eq!(v["final_position_blu"][2].as_i64().unwrap(), blu(49.0));
    let text = millac(&["check".as_ref(), prog.as_os_str()]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains("tool change at line 5: T3 (diameter 3.000 mm, length 50.000 mm)"),
        "{text}"
    );
    assert!(
        text.contains("T4 (not described in the tool table)"),
        "{text}"
    );
}

/// The programs FreeCAD's CAM wrote (qemu/programs/cam/freecad) are accepted whole: every line,
/// `G54` and the `K0.000` its grbl post writes on G17 arcs included (`check` exits 0).
#[test]
fn the_cam_corpus_is_accepted_whole() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("programs/cam/freecad");
    let mut checked = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().and_then(|e| e.to_str()) != Some("nc") {
            continue;
        }
        let o = millac(&["check".as_ref(), p.as_os_str(), "--json".as_ref()]);
        let v: Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| {
            panic!(
                "{}: {e}: {}",
                p.display(),
                String::from_utf8_lossy(&o.stderr)
            )
        });
        assert!(v["blocks"].as_u64().unwrap() > 100, "{}: {v}", p.display());
        assert_eq!(v["refused"], serde_json::json!([]), "{}", p.display());
        assert_eq!(o.status.code(), Some(0), "{}", p.display());
        checked += 1;
    }
    assert_eq!(checked, 5, "pocket, adaptive, drill, surface, multitool");
}

/// LinuxCNC's example programs of the corpus (qemu/programs/cam/linuxcnc): `check --json` reads
/// each; a program is accepted whole unless it uses a construct outside the dialect, and then
/// every refusal names that construct (the two of the corpus: LinuxCNC's polar coordinates in
/// hole-circle, a dwell on a line that moves in skeleton).
#[test]
fn linuxcncs_programs_are_accepted_or_refused_by_name() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("programs/cam/linuxcnc");
    let named = [
        (
            "hole-circle.ngc",
            "polar coordinates (@ radius, ^ angle) are not supported",
        ),
        ("skeleton.ngc", "G4 cannot be combined with an axis move"),
    ];
    let mut checked = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().and_then(|e| e.to_str()) != Some("ngc") {
            continue;
        }
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        let o = millac(&["check".as_ref(), p.as_os_str(), "--json".as_ref()]);
        let v: Value = serde_json::from_slice(&o.stdout).unwrap();
        let refused = v["refused"].as_array().unwrap();
        match named.iter().find(|(n, _)| *n == name) {
            None => {
                assert!(refused.is_empty(), "{name}: {v}");
                assert_eq!(o.status.code(), Some(0), "{name}");
            }
            Some((_, why)) => {
                assert!(!refused.is_empty(), "{name}");
                for r in refused {
                    let m = r["message"].as_str().unwrap();
                    assert!(m.contains(why), "{name}: {m}");
                }
                assert_eq!(o.status.code(), Some(1), "{name}");
            }
        }
        checked += 1;
    }
    assert_eq!(checked, 5, "3dtest, arcspiral, cds, hole-circle, skeleton");
}
