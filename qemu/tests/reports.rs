//! Every exit of the host tool leaves its report (host; the built `millac-qemu` binary, QEMU for
//! `run`): a run stopped by SIGINT or SIGTERM writes summary.json with `completed` false and
//! `interrupted`, and the capture of what ran; a folder that cannot be written and a full disk
//! are said in one line naming the file; an output file with a folder in its way is named.
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("reports-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The tool, with SIGINT and SIGTERM at their default action: a test run from a shell's
/// background job inherits SIGINT ignored (POSIX: `cmd &` in a non-interactive shell), which the
/// tool keeps, as a shell's child should, and the SIGINT test would see a run that went on.
fn tool() -> Command {
    use std::os::unix::process::CommandExt;
    let mut c = Command::new(env!("CARGO_BIN_EXE_millac-qemu"));
    // SAFETY: signal(2) is async-signal-safe; nothing else runs between fork and exec.
    unsafe {
        c.pre_exec(|| {
            libc::signal(libc::SIGINT, libc::SIG_DFL);
            libc::signal(libc::SIGTERM, libc::SIG_DFL);
            Ok(())
        });
    }
    c
}

fn summary(out: &Path) -> Value {
    let p = out.join("summary.json");
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    serde_json::from_str(&text).unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Waits (at most 5 min, the firmware may be building) until `path` exists, while `child` runs.
fn wait_for(path: &Path, child: &mut std::process::Child) {
    let t0 = Instant::now();
    while !path.exists() {
        if let Some(status) = child.try_wait().unwrap() {
            panic!(
                "the tool ended ({status}) before {} appeared",
                path.display()
            );
        }
        assert!(
            t0.elapsed() < Duration::from_secs(300),
            "{} never appeared",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// `run` of a long feed (1 min of virtual time), sent `signal` once the firmware runs: the
/// status is 128 + the signal, summary.json says `completed` false and `interrupted` with the
/// signal, the line that was running, the blocks done and the position, which is where the
/// capture of what ran (capture.vcd) ends; the blocks done ended exactly.
fn interrupted_run(tag: &str, signal: libc::c_int, name: &str) {
    let dir = scratch(tag);
    let prog = dir.join("long.nc");
    std::fs::write(&prog, "G20 G91 G1 F30 X0.01\nG1 X5 F5\nM2\n").unwrap();
    let out = dir.join("out");
    let mut child = tool()
        .args(["run", "--nc-only", "--out"])
        .arg(&out)
        .arg(&prog)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The firmware creates its result file first thing.
    wait_for(&out.join("result.txt"), &mut child);
    // SAFETY: kill(2) with our child's pid.
    unsafe { libc::kill(child.id() as libc::pid_t, signal) };
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(128 + signal), "{}", text(&o));
    let s = summary(&out);
    assert_eq!(s["completed"], false, "{s:#}");
    let i = &s["interrupted"];
    assert_eq!(i["signal"], name, "{s:#}");
    assert!(s.get("hold").is_none(), "{s:#}");
    let done = i["blocks_done"].as_u64().unwrap();
    assert!(done < 2, "{s:#}");
    assert_eq!(i["block"], done + 1, "{s:#}");
    assert_eq!(i["position_blu"], s["final_position_blu"], "{s:#}");
    assert_eq!(s["end_points_exact"], true, "{s:#}");
    let vcd = std::fs::read_to_string(out.join("capture.vcd")).unwrap();
    let trace = millac_qemu::analysis::vcd::read_vcd(&vcd).unwrap();
    let end = millac_qemu::analysis::vcd::positions(trace.initial, &trace.events);
    let p = &s["final_position_blu"];
    assert_eq!(end, ["x", "y", "z"].map(|k| p[k].as_i64().unwrap()));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains(&format!("interrupted by {name}")), "{err}");
}

/// SIGINT (Ctrl-C) to `run` mid-program. Before, the tool died with no capture and no summary.
#[test]
fn sigint_to_run_leaves_the_report_of_what_ran() {
    interrupted_run("sigint", libc::SIGINT, "SIGINT");
}

/// SIGTERM to `run` mid-program, the same.
#[test]
fn sigterm_to_run_leaves_the_report_of_what_ran() {
    interrupted_run("sigterm", libc::SIGTERM, "SIGTERM");
}

/// SIGTERM to `host` during a long run (the host's simulation, no QEMU): the status is 143 and
/// the report says `interrupted` with the blocks done; ac.csv holds what ran.
#[test]
fn sigterm_to_host_leaves_the_report_of_what_ran() {
    let dir = scratch("host-sigterm");
    let prog = dir.join("long.nc");
    std::fs::write(
        &prog,
        "G20 G90\nG0 X-0.5 Y1.5\nG0 Z-0.3\nG1 X4.5 F1\nG0 Z0.1\nM2\n",
    )
    .unwrap();
    let stock = dir.join("stock.txt");
    std::fs::write(&stock, "blank X0 Y0 W5 H3 Z0\n").unwrap();
    let out = dir.join("out");
    let mut child = tool()
        .args(["host", "--stock"])
        .arg(&stock)
        .arg("--out")
        .arg(&out)
        .arg(&prog)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The output folder is made just before the run starts.
    wait_for(&out, &mut child);
    // SAFETY: kill(2) with our child's pid.
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(128 + libc::SIGTERM), "{}", text(&o));
    let s = summary(&out);
    assert_eq!(s["completed"], false, "{s:#}");
    assert_eq!(s["interrupted"]["signal"], "SIGTERM", "{s:#}");
    assert!(
        s["interrupted"]["blocks_done"].as_u64().unwrap() < 5,
        "{s:#}"
    );
    assert!(out.join("ac.csv").exists());
}

/// Runs `args` of the tool with `dir` a fresh tmpfs mounted with `options` (a mount namespace of
/// its own: `unshare -m` as root, else `unshare -rm`, an unprivileged user namespace); the last
/// line of its stdout is `files left: NAME ...`, what the folder held after the run.
fn in_tmpfs(dir: &Path, options: &str, args: &[&std::ffi::OsStr]) -> Output {
    let root = millac_qemu::emulator::tools::is_root();
    let mut cmd = Command::new("unshare");
    cmd.arg(if root { "-m" } else { "-rm" })
        .args([
            "sh",
            "-c",
            "d=$2; mount -t tmpfs -o \"$1\" millac-test \"$d\" || exit 99; shift 2; \"$@\"; \
             rc=$?; echo \"files left: $(ls -A \"$d\" | tr '\\n' ' ')\"; exit $rc",
            "sh",
            options,
        ])
        .arg(dir)
        .arg(env!("CARGO_BIN_EXE_millac-qemu"))
        .args(args);
    cmd.output().expect("unshare (util-linux)")
}

/// A program of 1.2 s of feed in X and Y: a few megabytes of QEMU logs.
fn feed_program(dir: &Path) -> PathBuf {
    let prog = dir.join("feed.nc");
    std::fs::write(&prog, "G21 G91 G1 F600 X10 Y-2\nM2\n").unwrap();
    prog
}

/// An output folder that cannot be written (a read-only file system): the error names the file
/// that could not be written, and one line says the report could not be written and where.
#[test]
fn an_unwritable_folder_is_named_in_one_line() {
    let dir = scratch("readonly");
    let prog = feed_program(&dir);
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let o = in_tmpfs(
        &out,
        "ro,size=64k",
        &[
            "run".as_ref(),
            prog.as_os_str(),
            "--nc-only".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    let lines: Vec<&str> = err.lines().collect();
    let summary = out.join("summary.json");
    let said = lines
        .iter()
        .filter(|l| l.contains("no report written") && l.contains(&*summary.to_string_lossy()))
        .count();
    assert_eq!(said, 1, "{err}");
    assert!(err.contains("Read-only file system"), "{err}");
    assert!(
        lines[0].starts_with("millac: ") && lines[0].contains(&*out.to_string_lossy()),
        "{err}"
    );
}

/// A full disk (a 200 KiB tmpfs: room for the tool's plugin and the program, not for QEMU's
/// logs of the run): one line says which log could not be written and that the disk is full,
/// and one line that the report could not be written, where. Before: "plugin log line N:
/// unexpected line" and nothing about the disk.
#[test]
fn a_full_disk_is_said_with_the_file_that_could_not_be_written() {
    let dir = scratch("full");
    let prog = feed_program(&dir);
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    let o = in_tmpfs(
        &out,
        "size=200k",
        &[
            "run".as_ref(),
            prog.as_os_str(),
            "--nc-only".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    let first = err.lines().next().unwrap_or("");
    assert!(first.starts_with("millac: "), "{err}");
    assert!(
        first.contains(&*out.join(".millac-capture").to_string_lossy()),
        "{err}"
    );
    assert!(
        first.contains("No space left on device") || first.contains("the disk is full"),
        "{err}"
    );
    assert!(!first.contains("unexpected line"), "{err}");
    let summary = out.join("summary.json");
    assert!(
        err.lines()
            .any(|l| l.contains("no report written") && l.contains(&*summary.to_string_lossy())),
        "{err}"
    );
    // No cut summary.json is left (it would be read as a report).
    let out_text = String::from_utf8_lossy(&o.stdout);
    let left = out_text
        .lines()
        .find_map(|l| l.strip_prefix("files left: "))
        .unwrap_or_else(|| panic!("{}", text(&o)));
    assert!(
        !left.split_whitespace().any(|f| f == "summary.json"),
        "{left}"
    );
}

/// A folder in the way of an output file: the error names the file (`host`: ac.csv, ac.svg,
/// summary.json). Before, ac.svg's said only "Is a directory (os error 21)".
#[test]
fn a_folder_in_the_way_of_an_output_file_is_named() {
    let dir = scratch("in-the-way");
    let prog = dir.join("slot.nc");
    std::fs::write(
        &prog,
        "G20 G90\nG0 X-0.5 Y1.5\nG0 Z-0.3\nG1 X0.6 F22\nG0 Z0.1\nM2\n",
    )
    .unwrap();
    let stock = dir.join("stock.txt");
    std::fs::write(&stock, "blank X0 Y0 W5 H3 Z0\n").unwrap();
    for name in ["ac.csv", "ac.svg", "summary.json"] {
        let out = dir.join(format!("out-{name}"));
        let blocked = out.join(name);
        std::fs::create_dir_all(&blocked).unwrap();
        let o = tool()
            .args(["host", "--stock"])
            .arg(&stock)
            .arg("--out")
            .arg(&out)
            .arg(&prog)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{name}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        let first = err.lines().next().unwrap_or("");
        assert!(first.contains(&*blocked.to_string_lossy()), "{name}: {err}");
    }
}
