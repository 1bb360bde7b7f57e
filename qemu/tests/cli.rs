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
/// ac.csv differs from the default, the paper's); `serve` refuses `--strategy` with `--settings`
/// before anything starts.
#[test]
fn host_runs_the_strategy_it_is_given() {
    let dir = scratch("strategy");
    let prog = dir.join("slot.nc");
    std::fs::write(
        &prog,
        "G20 G90\nG0 X-0.5 Y1.5\nG0 Z-0.3\nG1 X0.6 F22\nG0 Z0.1\nM2\n",
    )
    .unwrap();
    let stock = dir.join("stock.txt");
    std::fs::write(&stock, "blank X0 Y0 W5 H3 Z0\n").unwrap();
    let mut csv = Vec::new();
    for (strategy, name) in [(None, "paper"), (Some("integral"), "integral")] {
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
