//! Programs run on the firmware under QEMU (host; the built `millac-qemu` binary and QEMU, NC
//! only): FreeCAD's drilling job, whose canned cycles (G81, G82 with its dwell, G83 pecks) the
//! firmware's loader expands line by line into its block queue, and a helical entry (helices and
//! P turns, expanded the same way). Every block runs, each ends
//! exactly where the host's reading of the program says (the analyser's end points from the
//! capture), and the machine ends where `check` says.
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("corpus-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs `program` (under qemu/programs) NC only under QEMU; requires every block of the host's
/// reading to run, each ending exactly where the host says, and the machine to end where the host
/// says. Returns summary.json.
fn runs_block_for_block(program: &str, scratch_name: &str) -> Value {
    let prog = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("programs")
        .join(program);
    let text = std::fs::read(&prog).unwrap();
    let settings = millac::Settings::default();
    let reading = millac_qemu::analysis::read_lines(&text, &settings);
    assert!(reading.refused.is_empty(), "{:?}", reading.refused);
    let want = millac_qemu::analysis::program_of_blocks(reading.blocks);
    let out = scratch(scratch_name).join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_millac-qemu"))
        .args(["run", "--nc-only", "--out"])
        .arg(&out)
        .arg(&prog)
        .output()
        .unwrap();
    let s: Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("summary.json")).unwrap_or_else(|e| {
            panic!("{e}: {}", String::from_utf8_lossy(&o.stderr));
        }),
    )
    .unwrap();
    assert_eq!(o.status.code(), Some(0), "{s:#}");
    assert_eq!(s["completed"], true, "{s:#}");
    assert_eq!(s["blocks"], want.len(), "{s:#}");
    assert_eq!(s["end_points_exact"], true, "{s:#}");
    let end = want.last().unwrap().end;
    let p = &s["final_position_blu"];
    assert_eq!(
        ["x", "y", "z"].map(|k| p[k].as_i64().unwrap()),
        end.map(i64::from)
    );
    s
}

#[test]
fn freecads_drilling_job_runs_under_qemu_block_for_block() {
    let cycles = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("programs/cam/freecad/drill.nc"),
    )
    .unwrap();
    for code in ["G81", "G82", "G83"] {
        assert!(cycles.contains(code), "the job has {code}");
    }
    runs_block_for_block("cam/freecad/drill.nc", "drill");
}

/// A helical entry (helices, a line of P2 turns, a plane circle, an R-form helix) runs on the
/// firmware with every pulse as the host core's and the path within half a BLU of its circles.
#[test]
fn a_helical_entry_runs_under_qemu_within_half_a_blu() {
    let s = runs_block_for_block("helix-entry.nc", "helix");
    assert_eq!(s["pulses_match_host"], true, "{s:#}");
    let dev = s["max_deviation_blu"].as_f64().unwrap();
    assert!(dev <= 0.5, "{dev} BLU off the path");
    // Z's pulses: down 0.1 in to Z0, the helices 0.05 and 0.1 in down, 0.05 in up, 0.2 in out.
    assert_eq!(
        s["pulses"]["z"],
        1000 + 1000 + 500 + 1000 + 500 + 2000,
        "{s:#}"
    );
}

/// Every program of the CAM corpus that millac accepts (FreeCAD's five, LinuxCNC's three; the
/// other two LinuxCNC programs are refused by name, see `cli::linuxcncs_programs_are_accepted_or_refused_by_name`)
/// runs on the firmware under QEMU block for block, ending exactly where the host's reading says
/// (which `rs274::millac_reads_the_corpus_as_linuxcnc_does` holds within 1 BLU of LinuxCNC's).
/// About 45 min of virtual machining: run by hand, two at a time,
/// `cargo test -p millac-qemu --release --test corpus -- --ignored --nocapture`.
#[test]
#[ignore = "about 45 min of machining under QEMU: run by hand"]
fn the_whole_cam_corpus_runs_under_qemu_block_for_block() {
    let programs = [
        "cam/freecad/drill.nc",
        "cam/freecad/pocket.nc",
        "cam/freecad/adaptive.nc",
        "cam/freecad/surface.nc",
        "cam/freecad/multitool.nc",
        "cam/linuxcnc/3dtest.ngc",
        "cam/linuxcnc/arcspiral.ngc",
        "cam/linuxcnc/cds.ngc",
    ];
    let next = std::sync::atomic::AtomicUsize::new(0);
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                let Some(p) = programs.get(i) else { break };
                let started = std::time::Instant::now();
                let summary = runs_block_for_block(p, &p.replace('/', "-"));
                println!(
                    "{p}: {} blocks, end points exact, machining {} s, max deviation {} BLU, \
                     final position {} ({:.0} s wall)",
                    summary["blocks"],
                    summary["machining_time_s"],
                    summary["max_deviation_blu"],
                    summary["final_position_blu"],
                    started.elapsed().as_secs_f64()
                );
            });
        }
    });
}
