//! Prediction and feedback together in the firmware under QEMU (host, issue 11): the hidden-boss
//! program, optimised with the guard on its described stock, runs on the stock as it is with the
//! AC under the plan (`$263=2`): the firmware's frame multiplies every block's feed by the plan
//! ratio its AC task publishes, the program ends without a hold, the logged ratio follows the
//! host simulation of the same code, and no AC period overruns.
use millac::ac::{AcSettings, FeedCeiling, PLAN_START};
use millac::Settings;
use millac_qemu::evaluation::optimise::{self, Options};
use millac_qemu::host::acsim::{self, Cut};
use millac_qemu::{analysis, emulator::runner};
use std::path::PathBuf;

fn read(f: &str) -> String {
    std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("programs")
            .join(f),
    )
    .unwrap()
}

#[test]
fn the_combined_controller_in_the_firmware_as_on_the_host() {
    let s = Settings::default();
    let program = read("hidden-boss.nc");
    let stock = |f: &str| millac_plant::Stock::parse(&read(f)).unwrap();
    let described =
        Cut::steel(stock("hidden-boss.described.stock"), 1).at_program_rpm(&program, &s);
    let actual = Cut {
        stock: stock("hidden-boss.actual.stock"),
        ..described.clone()
    };
    let plan = optimise::optimise(&program, &s, &described, &Options::default())
        .unwrap()
        .text;
    let acs = AcSettings {
        ceiling: FeedCeiling::Plan,
        ..AcSettings::default()
    };
    let prog = analysis::load_program(&plan, &s).unwrap();
    let host = acsim::run(&prog, &s, &actual, Some(acs)).unwrap();
    let out = std::env::temp_dir().join(format!("millac-predict-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let ac = runner::AcRun {
        cut: actual,
        ac: true,
        faults: Vec::new(),
        settings: acs,
    };
    let o = runner::run_with(&plan, &out, 4, Some(&ac)).unwrap();
    assert_eq!(o.summary["completed"], true, "{}", o.summary);
    assert!(o.ac_log.iter().all(|r| r.hold.is_none()), "a hold");
    let last = o.ac_log.last().expect("AC periods ran");
    assert_eq!(last.overruns, 0, "AC periods overran");
    // The plan ratio as logged (k x f_max): it starts at PLAN_START, the first contact sets it
    // near 1 in the same period as on the host, and the firmware's values follow the host's
    // within 4 % at every time and 1 % at the end. (At the boss the load sits at the edge of the
    // plan's tolerance, 1.05 F0: whether and when a window's noise lowers k by 2.5 % depends on
    // the frame's timing under QEMU by a pulse or two.)
    let k = |cap: u32| f64::from(cap) / f64::from(acs.f_max);
    let fw: Vec<(u64, f64)> = o.ac_log.iter().map(|r| (r.t_ms, k(r.feed_cap))).collect();
    let hs: Vec<(u64, f64)> = host.rows.iter().map(|r| (r.t_ms, k(r.feed_cap))).collect();
    assert!(
        (fw[0].1 - f64::from(PLAN_START)).abs() < 1e-3,
        "{:?}",
        fw[0]
    );
    let first_change = |v: &[(u64, f64)]| v.iter().find(|p| (p.1 - v[0].1).abs() > 1e-3).copied();
    let (f1, h1) = (first_change(&fw).unwrap(), first_change(&hs).unwrap());
    eprintln!(
        "first contact: firmware {f1:?}, host {h1:?}; periods {} / {}; last k {:.3} / {:.3}",
        fw.len(),
        hs.len(),
        fw[fw.len() - 1].1,
        hs[hs.len() - 1].1
    );
    assert!(
        f1.0.abs_diff(h1.0) <= 20 && (f1.1 - h1.1).abs() < 0.01,
        "{f1:?} {h1:?}"
    );
    for &(t, kf) in &fw {
        if let Some(&(_, kh)) = hs.iter().find(|p| p.0 == t) {
            assert!(
                (kf - kh).abs() < 0.04 || t.abs_diff(h1.0) < 40,
                "at {t} ms: firmware {kf}, host {kh}"
            );
        }
    }
    assert!((fw[fw.len() - 1].1 - hs[hs.len() - 1].1).abs() < 0.01);
    let peak = o.ac_log.iter().map(|r| r.f_n).fold(0.0, f32::max);
    assert!(peak < acs.force_limit_n, "peak {peak} N");
}
