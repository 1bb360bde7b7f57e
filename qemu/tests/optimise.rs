//! Offline feed optimisation by virtual machining (issue 11; Karunakaran, Shringi and Singh),
//! host: on the benchmark's programs the optimised program parses in the firmware's parser,
//! reaches every original end point in order with the same pulses per axis between them, and
//! cut on the simulated plant without AC it stays within the cutter's permissible force; the
//! command line writes the program, its table and its figure.
use millac::Settings;
use millac_plant::{DriveModel, Material};
use millac_qemu::analysis::{self, ProgBlock};
use millac_qemu::optimise::{self, Options};
use millac_qemu::{acsim, bench};
use std::path::PathBuf;

/// The output's blocks between the original end points: for each original block, the pulses per
/// axis the output takes from the previous original end point to this one.
fn pulses_per_end_point(original: &[ProgBlock], out: &[ProgBlock]) -> Vec<[u64; 3]> {
    let mut it = out.iter();
    original
        .iter()
        .map(|b| {
            let mut sum = [0u64; 3];
            for o in it.by_ref() {
                for (s, q) in sum.iter_mut().zip(o.pulses) {
                    *s += q;
                }
                if o.end == b.end {
                    return sum;
                }
            }
            panic!("end point {:?} (line {}) not reached", b.end, b.block.line);
        })
        .collect()
}

#[test]
fn the_optimised_programs_keep_the_geometry_and_the_cutter_within_its_limit() {
    let s = Settings::default();
    for case in bench::CASES {
        let cut = case.cut(&s, DriveModel::Stepper, Material::STEEL).unwrap();
        let fraction = f64::from(case.ac_settings().optimal_fraction);
        let o = optimise::optimise(
            case.program,
            &s,
            &cut,
            &Options {
                fraction,
                ..Options::default()
            },
        )
        .unwrap();
        // It parses (the firmware's tape reader), and every original block's end point is
        // reached in order with the original block's pulses per axis.
        let original = case.load(&s).unwrap();
        let out = analysis::load_program(&o.text, &s).unwrap();
        let expected: Vec<[u64; 3]> = original.iter().map(|b| b.pulses).collect();
        assert_eq!(
            pulses_per_end_point(&original, &out),
            expected,
            "{}",
            case.name
        );
        assert!(out.len() >= original.len());
        assert!(o.text.starts_with("(millac optimise"), "{}", case.name);
        // Cut without AC on the plant: never above the permissible force, and faster than the
        // safe constant feed (the benchmark's reference).
        let run = acsim::run(&out, &s, &cut, None).unwrap();
        let l = acsim::load_figures(&run.samples, &cut.tool, fraction, 1000);
        let cmp = millac_qemu::acreport::compare(&original, &s, &cut, &case.ac_settings()).unwrap();
        eprintln!(
            "{}: {} blocks -> {} pieces; optimised {:.2} s, peak F/F_max {:.3}, above F0 {:.3} s; programmed {:.2} s, safe constant {:.2} s, bound {:.2} s",
            case.name,
            original.len(),
            o.pieces.len(),
            run.machining_time_s,
            l.peak_force_ratio,
            l.time_above_f0_s,
            cmp.programmed.machining_time_s,
            cmp.safe.machining_time_s,
            cmp.oracle_time_s
        );
        assert_eq!(l.time_above_limit_s, 0.0, "{}", case.name);
        assert!(
            run.machining_time_s < cmp.safe.machining_time_s,
            "{}",
            case.name
        );
    }
}

/// Bad options are refused with a message and write nothing.
#[test]
fn bad_options_are_refused() {
    let s = Settings::default();
    let case = &bench::CASES[1];
    let cut = case.cut(&s, DriveModel::Stepper, Material::STEEL).unwrap();
    for (opts, what) in [
        (
            Options {
                fraction: 0.0,
                ..Options::default()
            },
            "fraction",
        ),
        (
            Options {
                fraction: 1.5,
                ..Options::default()
            },
            "fraction",
        ),
        (
            Options {
                split: f64::NAN,
                ..Options::default()
            },
            "split",
        ),
        (
            Options {
                min_piece_mm: -1.0,
                ..Options::default()
            },
            "shortest",
        ),
        (
            Options {
                air_feed_ipm: 0.0,
                ..Options::default()
            },
            "air",
        ),
    ] {
        let e = optimise::optimise(case.program, &s, &cut, &opts).unwrap_err();
        assert!(e.to_string().contains(what), "{e}");
    }
    let e = optimise::optimise("G1 X1 F10\nG7 X2\n", &s, &cut, &Options::default()).unwrap_err();
    assert!(e.to_string().contains("line 2"), "{e}");
}

/// `millac optimise` writes the program, the pieces' table and the figure, and its table names
/// both programs.
#[test]
fn the_command_writes_the_program_its_table_and_its_figure() {
    let dir = std::env::temp_dir().join(format!("millac-optimise-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = dir.join("pocket-opt.nc");
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_millac-qemu"))
        .arg("optimise")
        .arg(root.join("programs/pocket.nc"))
        .arg("--stock")
        .arg(root.join("programs/pocket.stock"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout.contains("| programmed |") && stdout.contains("| optimised |"),
        "{stdout}"
    );
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("G20 G90") && text.trim_end().ends_with("M2"));
    let csv = std::fs::read_to_string(out.with_extension("csv")).unwrap();
    assert!(csv.starts_with("line,at_mm,length_mm"));
    assert!(csv.lines().count() > 10);
    let svg = std::fs::read_to_string(out.with_extension("svg")).unwrap();
    assert!(svg.contains("<svg"));
    // A tool option that is not one is refused before anything is written.
    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_millac-qemu"))
        .args(["optimise", "x.nc", "--out"])
        .arg(dir.join("bad.nc"))
        .args(["--tool", "12.7,0"])
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(!dir.join("bad.nc").exists());
}
