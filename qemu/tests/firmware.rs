//! QEMU tests of the firmware (host): programs run through the RTIC app on the emulated lm3s6965; the
//! path recovered from the VCD must equal the host core's pulses frame by frame, sigrok's
//! stepper_motor decoder must read the same final positions, pulse timing must hold the settings,
//! runs must be byte-identical, and bad programs must stop safely with exact positions.
use millac::Settings;
use millac_qemu::{analysis, analysis::sigrok, emulator::runner};
use std::path::PathBuf;

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("millac-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Runs `program`, checks everything a run promises, returns the outcome.
fn run_checked(name: &str, program: &str) -> runner::Outcome {
    let out = out_dir(name);
    let o = runner::run(program, &out, 4).expect("run");
    let s = &o.summary;
    assert!(o.ok, "{name}: checks failed: {s:#}");
    assert_eq!(s["pulses_match_host"], true, "{name}");
    assert_eq!(s["end_points_exact"], true, "{name}");
    let settings = Settings::default();
    assert!(
        s["min_pulse_width_ns"].as_u64().unwrap() >= settings.pulse_width_ns as u64,
        "{name}: {s:#}"
    );
    assert!(
        s["min_sign_setup_ns"].as_u64().unwrap_or(u64::MAX) >= settings.sign_setup_ns as u64,
        "{name}: {s:#}"
    );
    // The programmed end point, from the parser alone.
    let prog = analysis::load_program(program, &settings).unwrap();
    let end = prog.last().unwrap().end;
    let fp = &s["final_position_blu"];
    assert_eq!(
        [
            fp["x"].as_i64().unwrap(),
            fp["y"].as_i64().unwrap(),
            fp["z"].as_i64().unwrap()
        ],
        end.map(i64::from)
    );
    // An independent decoder reads the same positions from the same file.
    let decoded = sigrok::decode_positions(&out.join("capture.vcd")).expect("sigrok");
    assert_eq!(decoded, end.map(i64::from), "{name}: sigrok disagrees");
    o
}

#[test]
fn lines_in_two_and_three_axes_with_deceleration() {
    let o = run_checked(
        "lines",
        "G20 G91 F30\nG1 X0.1 Y0.05\nG1 X-0.03 Y0.07 F12\nG1 X0.02 Y0.02 Z-0.01 F25\n\
         G1 Y-0.04 F6\nG0 X0.01\nG1 X-0.05 Y-0.05 F20\nM2\n",
    );
    assert!(o.summary["max_deviation_blu"].as_f64().unwrap() <= 1.0);
    assert!(
        o.summary["max_feed_error_pct"].as_f64().unwrap() < 2.0,
        "{:#}",
        o.summary
    );
}

#[test]
fn arcs_in_all_planes_both_directions_and_full_circles() {
    let o = run_checked(
        "arcs",
        "G20 G90 G17 F30\nG1 X0.06 Y0\nG3 X-0.06 Y0 I-0.06 J0\nG2 X0 Y0.06 I0.06 J0\n\
         G3 X0 Y0.06 I0 J-0.03\nG18 G2 X0.03 Z0.02 R0.05\nG19 G3 Y0.08 Z0 R-0.03\nG17 G2 X0.06 Y0 R0.07\nM30\n",
    );
    assert!(
        o.summary["max_deviation_blu"].as_f64().unwrap() <= 1.5,
        "{:#}",
        o.summary
    );
}

/// Short blocks from CAM run at their programmed feed on the firmware (issue 6, defect 7): 400
/// absolute lines of 10 BLU at F30 (FRM) take their path length over the feed within 1 %, the
/// last block's deceleration included (a load
/// frame per block made them 10 % slow), and a lone CR ends a line like LF (defect 2: here every
/// other line ends in CR only).
#[test]
fn chained_short_blocks_run_at_the_programmed_feed() {
    let mut program = String::from("G20 G90 G1 F30\n");
    let mut path = 0.0f64;
    let (mut x, mut y) = (0i64, 0i64);
    for k in 0..400 {
        // Turns of 16 degrees: below the look-ahead's 30, so no block decelerates but the last;
        // exactly 10 BLU each (q = L = 10 commands, no rounding of the DDA's path length).
        let (dx, dy) = [(8, 6), (6, 8)][k % 2];
        x += dx;
        y += dy;
        path += ((dx * dx + dy * dy) as f64).sqrt();
        let end = if k % 2 == 0 { "\r" } else { "\n" };
        program += &format!("X{:.4} Y{:.4}{end}", x as f64 / 1e4, y as f64 / 1e4);
    }
    program += "M2\n";
    let o = run_checked("chain", &program);
    assert_eq!(o.summary["blocks"], 400);
    // 30 ipm = 5000 BLU/s; machining time runs from the first to the last rising edge. The
    // chain starts from a stop: the ramp to 5000 BLU/s at the path acceleration (both segment
    // directions let the path accelerate at 10/8 of the axes' limit, see `Block::seal`) costs
    // v / 2a; the junctions cost nothing.
    let a = Settings::default().accel_blu_s2[0] as f64 * 10.0 / 8.0;
    let ideal = path / 5000.0 + 5000.0 / (2.0 * a);
    let t = o.summary["machining_time_s"].as_f64().unwrap();
    assert!(
        (t - ideal).abs() / ideal < 0.01,
        "path {path} BLU at F30: {t} s, ideal {ideal} s"
    );
}

#[test]
fn rapids_and_dwell() {
    let o = run_checked(
        "rapid",
        "G20 G90\nG0 X0.2 Y-0.1 Z0.05\nG4 P0.05\nG0 X0 Y0 Z0\nM2\n",
    );
    assert_eq!(o.summary["blocks"], 3);
}

#[test]
fn runs_are_byte_identical() {
    let prog = "G20 G91 F20\nG1 X0.03 Y0.01\nG2 X0.02 Y0 I0.01 J0\nG0 Y-0.02\nM2\n";
    let (a, b) = (out_dir("det-a"), out_dir("det-b"));
    runner::run(prog, &a, 4).unwrap();
    runner::run(prog, &b, 4).unwrap();
    let va = std::fs::read(a.join("capture.vcd")).unwrap();
    assert!(va.len() > 1000);
    assert_eq!(va, std::fs::read(b.join("capture.vcd")).unwrap());
    assert_eq!(
        std::fs::read(a.join("summary.json")).unwrap(),
        std::fs::read(b.join("summary.json")).unwrap()
    );
}

#[test]
fn bad_line_stops_after_the_accepted_blocks_with_exact_position() {
    // No host pre-check: the firmware itself meets the bad line.
    let good = "G20 G91 F30\nG1 X0.02 Y0.01\nG2 X0.01 Y0 I0.005 J0\n";
    let prog = format!("{good}G1 X0.01 Q3\nG1 X0.5\nM2\n");
    let out = out_dir("bad");
    let cap = runner::execute(&prog, &out, 4).unwrap();
    assert_eq!(cap.status, Some(1), "{}", cap.stdout);
    // In the log (decoded defmt) and in the result file.
    assert!(cap.stdout.contains("error: line 4:"), "{}", cap.stdout);
    assert!(cap.result.starts_with("error: line 4:"), "{}", cap.result);
    let settings = Settings::default();
    let accepted = analysis::load_program(good, &settings).unwrap();
    let end = accepted.last().unwrap().end;
    assert_eq!(
        runner::firmware_position(&cap.result),
        Some(end.map(i64::from)),
        "{}",
        cap.result
    );
    // The pins agree: every accepted block ran, nothing after the error moved.
    let r = analysis::analyse(&accepted, &settings, 0, &cap.pins);
    assert!(r.counts_match && r.blocks.iter().all(|b| b.end_exact));
}

#[test]
fn rejected_program_writes_the_error_and_runs_nothing() {
    let out = out_dir("rejected");
    let o = runner::run("G20\nG1 X1 F10\nG2 X1 Y1 I0.3 J0\nM2\n", &out, 4).unwrap();
    assert!(!o.ok && o.capture.is_none());
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["error"]["line"], 3);
    assert!(
        s["error"]["message"].as_str().unwrap().contains("circle"),
        "{s}"
    );
    assert!(!out.join("capture.vcd").exists());
}

/// The AC under QEMU against the cutting process: the cut ends exactly, ac.csv and the summary's
/// `ac` object are written, and a host AcController fed the same samples makes the same decisions.
#[test]
fn ac_against_the_cutting_process_and_host_replay() {
    use millac::ac::AcSettings;
    let program = "G20 G90\nG0 X-0.5 Y1.5\nG0 Z-0.3\nG1 X0.6 F22\nG0 Z0.1\nM2\n";
    let out = out_dir("ac");
    let ac = runner::AcRun {
        cut: slot_cut(),
        ac: true,
        faults: Vec::new(),
        settings: millac::ac::AcSettings::default(),
    };
    let o = runner::run_with(program, &out, 4, Some(&ac)).unwrap();
    assert!(o.ok, "{:#}", o.summary);
    let a = &o.summary["ac"];
    for key in [
        "time_s",
        "time_constant_programmed_s",
        "time_constant_safe_s",
        "time_oracle_s",
        "peak_force_ratio",
        "peak_torque_ratio",
        "time_above_f0_s",
        "time_above_limit_s",
    ] {
        assert!(a[key].is_number(), "{key}: {a:#}");
    }
    assert_eq!(a["holds"], 0);
    assert!(
        a["peak_force_ratio"].as_f64().unwrap() > 0.8,
        "the cut was loaded: {a:#}"
    );
    let csv = std::fs::read_to_string(out.join("ac.csv")).unwrap();
    assert_eq!(
        csv.lines().next().unwrap(),
        "t_ms,x_blu,y_blu,z_blu,feed_ipm,f_meas_n,t_meas_nm,f_true_n,t_true_nm,e,state,tool"
    );
    assert_eq!(csv.lines().count(), o.ac_log.len() + 1);
    // Replay: the same samples, ten per period, through the host's controller.
    let host = millac_qemu::emulator::cosim::replay(
        &o.ac_log,
        &o.exchanges,
        &Settings::default(),
        AcSettings::default(),
    )
    .unwrap();
    assert_eq!(host.len(), o.ac_log.len());
    for (k, (d, r)) in host.iter().zip(&o.ac_log).enumerate() {
        assert_eq!((d.feed_cap, d.e), (r.feed_cap, r.e), "period {k}");
    }
}

/// `--strategy mrac` (the runner's `AcRun::settings`) reaches the firmware: its AC log differs
/// from the paper's on the same cut, a host controller with the same settings replays its
/// decisions period by period, summary.json names the strategy, and the run's settings record
/// is gone afterwards (the next run in the directory is not refused).
#[test]
fn the_strategy_reaches_the_firmware_and_the_replay() {
    use millac::ac::law::Strategy;
    use millac::ac::AcSettings;
    let program = "G20 G90\nG0 X-0.5 Y1.5\nG0 Z-0.3\nG1 X0.6 F22\nG0 Z0.1\nM2\n";
    let out = out_dir("strategy");
    let mut logs = Vec::new();
    for strategy in [Strategy::Paper, Strategy::Mrac] {
        let settings = AcSettings {
            strategy,
            ..AcSettings::default()
        };
        let ac = runner::AcRun {
            cut: slot_cut(),
            ac: true,
            faults: Vec::new(),
            settings,
        };
        let o = runner::run_with(program, &out, 4, Some(&ac)).unwrap();
        assert!(o.ok, "{:#}", o.summary);
        assert_eq!(o.summary["ac"]["strategy"], strategy.name());
        assert!(!out.join(millac_qemu::lm3s_files::SETTINGS_NAME).exists());
        let host = millac_qemu::emulator::cosim::replay(
            &o.ac_log,
            &o.exchanges,
            &Settings::default(),
            settings,
        )
        .unwrap();
        assert_eq!(host.len(), o.ac_log.len());
        for (k, (d, r)) in host.iter().zip(&o.ac_log).enumerate() {
            assert_eq!(
                (d.feed_cap, d.e.to_bits()),
                (r.feed_cap, r.e.to_bits()),
                "{} period {k}",
                strategy.name()
            );
        }
        logs.push((o.ac_log, o.exchanges));
    }
    let caps = |l: &[millac_qemu::emulator::cosim::AcRecord]| -> Vec<u32> {
        l.iter().map(|r| r.feed_cap).collect()
    };
    let (mrac_log, mrac_exchanges) = &logs[1];
    assert_ne!(
        caps(&logs[0].0),
        caps(mrac_log),
        "MRAC ran the paper's feeds"
    );
    // The check has teeth: the paper's controller does not replay the MRAC run.
    let paper = millac_qemu::emulator::cosim::replay(
        mrac_log,
        mrac_exchanges,
        &Settings::default(),
        AcSettings::default(),
    )
    .unwrap();
    assert_ne!(
        paper.iter().map(|d| d.feed_cap).collect::<Vec<_>>(),
        caps(mrac_log)
    );
}

/// The frame and pulse-end interrupts have no panic path and call nothing: no BL/BLX, no UDF trap,
/// no BKPT/SVC anywhere in their code (everything is inlined; a panic would be a call or a trap).
#[test]
fn interrupts_have_no_calls_and_no_panic_path() {
    let elf = millac_qemu::emulator::firmware::build().unwrap();
    for name in ["TIMER_0A", "TIMER_1A"] {
        let f = millac_qemu::emulator::elf::find_function(&elf, name).unwrap();
        assert!(f.size > 40, "{name}: {} bytes", f.size);
        assert!(
            f.calls_and_traps.is_empty(),
            "{name} calls or traps at {:x?}",
            f.calls_and_traps
        );
    }
    // The scan does see calls in real code: the reset handler calls main.
    let reset = millac_qemu::emulator::elf::find_function(&elf, "Reset").unwrap();
    assert!(!reset.calls_and_traps.is_empty());
}

/// The QEMU board's firmware fits its flash and RAM budgets (hal/lm3s6965/budget.txt, an eighth
/// of the LM3S6965's flash free).
#[test]
fn fits_its_flash_and_ram_budgets() {
    use millac_qemu::emulator::firmware::LM3S6965;
    let elf = millac_qemu::emulator::firmware::build().unwrap();
    LM3S6965.check_budgets(&elf).unwrap();
}

/// Program mode with a refused settings record (one flipped byte): the firmware says why and
/// exits with failure before anything moves (there is no `$X` to acknowledge the defaults); with
/// the same record intact it runs the program on the record's settings (step pulse 7 us).
#[test]
fn program_mode_refuses_a_corrupt_settings_record_and_runs_on_a_valid_one() {
    use millac::protocol::table::{record, MachineSettings};
    use millac_qemu::emulator::capture::{run_capture, CaptureSpec};
    let out = out_dir("settings-record");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("program.nc"), "G91 G1 F30 X0.01\nM2\n").unwrap();
    let mut m = MachineSettings::default();
    m.set_line("$0=7").unwrap();
    let good = record::encode(&m);
    let mut bad = good;
    bad[30] ^= 0x04;
    let spec = CaptureSpec::new(millac_qemu::emulator::firmware::build().unwrap(), &out);
    let file = out.join(millac_qemu::lm3s_files::SETTINGS_NAME);
    std::fs::write(&file, bad).unwrap();
    let cap = run_capture(&spec).unwrap();
    assert_eq!(cap.status, Some(1), "{}", cap.stdout);
    // The firmware's log is its defmt frames, decoded by the host with their levels; the result
    // file has the same error and the (unmoved) position for the tools.
    let why =
        "settings: settings record checksum mismatch; nothing runs (fix or remove settings.bin)";
    assert_eq!(
        cap.stdout,
        format!("error: {why}\ninfo: done: blocks=0 position=0,0,0\n")
    );
    assert_eq!(
        cap.result,
        format!("error: {why}\nmillac: blocks=0 position=0,0,0\n")
    );
    assert!(cap.pins.is_empty(), "nothing moves");
    std::fs::write(&file, good).unwrap();
    let cap = run_capture(&spec).unwrap();
    assert_eq!(cap.status, Some(0), "{}", cap.stdout);
    assert_eq!(cap.stdout, "info: done: blocks=1 position=100,0,0\n");
    assert_eq!(cap.result, "millac: blocks=1 position=100,0,0\n");
    let e = analysis::edges(0, &cap.pins);
    assert_eq!(e.edges.len(), 100);
    assert!((7000..9000).contains(&e.min_pulse_width_ns.unwrap()));
}

/// The firmware's log is defmt, not text: QEMU's raw stdout holds format-string indices and
/// arguments (no `blocks=`), which the host decodes with the ELF's `.defmt` table; the results the
/// tools read are in the result file, and only there.
#[test]
fn the_log_is_a_defmt_stream_and_the_results_are_in_the_result_file() {
    let out = out_dir("defmt");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("program.nc"), "G91 G1 F30 X0.01 Y-0.02\nM2\n").unwrap();
    let elf = millac_qemu::emulator::firmware::build().unwrap();
    // QEMU alone, as `cargo fw-run` runs it: stdout is the raw defmt stream.
    let o = std::process::Command::new("qemu-system-arm")
        .current_dir(&out)
        .args(["-cpu", "cortex-m3", "-machine", "lm3s6965evb", "-nographic"])
        .args(["-semihosting-config", "enable=on,target=native"])
        .args(["-icount", "shift=4,sleep=off", "-kernel"])
        .arg(&elf)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0));
    let raw = &o.stdout;
    assert!(!raw.is_empty());
    assert!(
        !raw.windows(7).any(|w| w == b"blocks="),
        "text in the defmt stream: {raw:?}"
    );
    let log = millac_qemu::emulator::defmtlog::decode_file(&elf, raw).unwrap();
    assert_eq!(log, "info: done: blocks=1 position=100,-200,0\n");
    // The result, from the file: the line the tools parse is not in the log.
    let result = std::fs::read_to_string(out.join(millac_qemu::lm3s_files::RESULT_NAME)).unwrap();
    assert_eq!(result, "millac: blocks=1 position=100,-200,0\n");
    assert_eq!(runner::firmware_position(&result), Some([100, -200, 0]));
    assert_eq!(runner::firmware_position(&log), None);
    // A run through the host tool reports from the file: its summary has the position.
    let run = runner::run("G91 G1 F30 X0.01 Y-0.02\nM2\n", &out_dir("defmt-run"), 4).unwrap();
    assert!(run.ok);
    let cap = run.capture.unwrap();
    assert_eq!(cap.result, result);
    assert_eq!(cap.stdout, log);
    assert_eq!(
        run.summary["firmware_position_blu"],
        serde_json::json!({"x": 100, "y": -200, "z": 0})
    );
}

/// The AC tests' cut: a 5 x 3 in steel blank, a default tool at 600 rpm, transducer seed 3.
fn slot_cut() -> millac_qemu::host::acsim::Cut {
    let stock = millac_plant::Stock::parse("blank X0 Y0 W5 H3 Z0\n").unwrap();
    millac_qemu::host::acsim::Cut::steel(stock, 3)
}

/// The largest `--shift` the host tool allows keeps every step pulse of rapids in three axes;
/// at the next one the frames overrun the rapid period and the program does not run to its end
/// (the firmware holds with its frame overrun alarm; before it had that check it lost pulses),
/// which is why `runner::check_shift` refuses it.
#[test]
fn the_largest_shift_allowed_keeps_every_pulse_and_the_next_does_not() {
    let program = "G21 G90\nG0 X10 Y-7 Z3\nG1 X20 F500\nG0 X0 Y0 Z0\nM2\n";
    let kept = runner::run(program, &out_dir("shift-max"), runner::MAX_SHIFT).expect("run");
    assert!(kept.ok, "{:#}", kept.summary);
    assert_eq!(kept.summary["pulses_match_host"], true);
    let lost = runner::run(program, &out_dir("shift-over"), runner::MAX_SHIFT + 1).expect("run");
    assert!(!lost.ok, "{:#}", lost.summary);
    let alarm = lost.summary["hold"]["alarm"].as_str().unwrap_or("");
    assert!(alarm.starts_with("frame overrun"), "{:#}", lost.summary);
    assert!(runner::check_shift(runner::MAX_SHIFT).is_ok());
    assert!(runner::check_shift(runner::MAX_SHIFT + 1).is_err());
}
