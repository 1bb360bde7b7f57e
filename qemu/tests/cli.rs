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
