//! `serve` (host): the firmware under QEMU in serial mode (no program file), its UART0 on a TCP
//! port for a G-code sender, optionally with the simulated cut and the AC live, until the caller
//! stops it (the command: SIGINT or SIGTERM); then the capture and the report of the whole run in
//! `out`: `capture.vcd`, `summary.json` with the keys of `run` (`runner::summarise`), and with
//! the AC `ac.csv` and `ac.svg`. The session's program is the firmware's log `serve.nc` (every
//! accepted line, jog, early run of a held block and soft reset; `millac::wire::SessionLine`),
//! replayed here ([`replay`]) into exactly the blocks the firmware queued.
//!
//! The serial port is [`crate::emulator::port`]: QEMU's UART on a Unix socket of a small TCP front that
//! takes one client at a time (others get a line saying the port is in use and are closed),
//! greets each client with the grbl banner, and forwards a client's bytes line by line
//! (realtime bytes at once), so a line left unfinished by a client that disconnects is dropped,
//! never glued to the next client's first line. QEMU gets `-monitor none`; stopping first closes
//! the client and asks the firmware for a status report (the state the session ended in), then
//! sends QEMU SIGTERM, which shuts it down cleanly, so the virtual logic analyser's log is
//! complete.
//!
//! The summary's `completed` is true only when the machine ended `Idle` and every block the
//! session queued ran to its end in the capture; otherwise `hold` says what was left: the state
//! the machine ended in, the last alarm it reported, the line of the first block that did not
//! run to its end, the blocks done and the position.
//!
//! Settings persist in the operator's settings file (`--settings`, default `out/settings.bin`):
//! the firmware opens `settings.bin` in its working directory (`out`), which [`link_settings`]
//! makes that file, so the record the firmware stores after a `$N=value` lands there directly and
//! the next session starts with it.
use crate::emulator::capture::{run_capture, CaptureSpec, HandlerSpec};
use crate::emulator::runner::{self, AcRun};
use crate::{analysis, analysis::vcd, emulator::cosim, emulator::firmware};
use anyhow::{anyhow, Context, Result};
use millac::gcode::tape::{finish_block, Tape};
use millac::nc::{FrameConfig, Motion, Sealed};
use millac::protocol::jog::JogRequest;
use millac::wire::SessionLine;
use millac::Settings;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The default address of the serial port.
pub const DEFAULT_TCP: &str = "127.0.0.1:7878";

/// What a serve session produced.
pub struct Served {
    pub summary: Value,
    pub capture: crate::emulator::capture::Capture,
}

/// The settings file of a session in `out` when none is given: the firmware's own name there.
pub fn default_settings(out: &Path) -> PathBuf {
    out.join(crate::lm3s_files::SETTINGS_NAME)
}

/// Makes `out/settings.bin`, the file the firmware opens, the operator's settings file
/// `settings` (which need not exist yet: the firmware's first store creates it): nothing to do
/// when it is that file, otherwise a symbolic link to it (an earlier link is replaced). A file of
/// its own there is refused, never deleted.
pub fn link_settings(out: &Path, settings: &Path) -> Result<()> {
    let name = out.join(crate::lm3s_files::SETTINGS_NAME);
    let target = std::path::absolute(settings)
        .with_context(|| format!("settings file {}", settings.display()))?;
    if let Some(dir) = target.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if std::path::absolute(&name)? == target || same(&name, &target) {
        return Ok(());
    }
    match std::fs::symlink_metadata(&name) {
        Ok(m) if m.file_type().is_symlink() => std::fs::remove_file(&name)
            .with_context(|| format!("removing the old link {}", name.display()))?,
        Ok(_) => anyhow::bail!(
            "{} holds settings of its own: move it, or pass it as --settings",
            name.display()
        ),
        Err(_) => {}
    }
    std::os::unix::fs::symlink(&target, &name)
        .with_context(|| format!("linking {} to {}", name.display(), target.display()))
}

/// `serve --strategy NAME` (no `--settings`): stores the AC strategy (`$251`) in the session's
/// own record `out/settings.bin` before the firmware starts, keeping its other settings (the
/// defaults when there is no record yet), as a `$251=N` in an earlier session would have. Refused
/// when that name is a link to another settings file (a session with `--settings`: set `$251`
/// there) or holds a record the firmware would refuse (it is never overwritten).
pub fn store_strategy(out: &Path, strategy: millac::ac::law::Strategy) -> Result<()> {
    use millac::protocol::table::{record, MachineSettings};
    let path = default_settings(out);
    let mut s = match std::fs::symlink_metadata(&path) {
        Ok(m) if m.file_type().is_symlink() => anyhow::bail!(
            "{} links to another settings file: --strategy writes only the session's own record \
             (set $251 in the session, or remove the link)",
            path.display()
        ),
        Ok(_) => {
            let bytes =
                std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
            record::decode(&bytes, &millac::settings::BoardLimits::GENERIC)
                .map_err(|e| {
                    anyhow!(
                        "{}: {}; --strategy does not overwrite a refused record",
                        path.display(),
                        e.message()
                    )
                })?
                .get()
        }
        Err(_) => MachineSettings::default(),
    };
    s.ac.strategy = strategy;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    std::fs::write(&path, record::encode(&s)).with_context(|| format!("writing {}", path.display()))
}

/// Runs the firmware in serial mode with UART0 on `tcp` until `stop` is set; writes
/// `out/capture.vcd`, `out/serve.nc` (the firmware's session log) and `out/summary.json`. The
/// firmware loads and stores its settings in `settings` ([`link_settings`]). With `ac`, the
/// simulated ADC serves the cutting process as in `run` (`out/ac.log` is the firmware's AC log;
/// `out/ac.csv` and `out/ac.svg` as in `run`). With `machine`, the machine model's limit
/// switches (`out/machine.txt`: the firmware closes them from its own pulses; `$H` homes on
/// them, a move into one trips `ALARM:1`); without, none.
pub fn serve(
    out: &Path,
    settings: &Path,
    tcp: &str,
    shift: u32,
    ac: Option<&AcRun>,
    machine: Option<&millac::inputs::LimitSwitches>,
    stop: Arc<AtomicBool>,
) -> Result<Served> {
    let elf = firmware::build()?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    // No program file: the firmware's loader takes the serial line.
    let _ = std::fs::remove_file(out.join("program.nc"));
    for f in [
        cosim::REQ,
        cosim::RESP,
        cosim::AC_LOG,
        crate::lm3s_files::SERVE_LOG_NAME,
    ] {
        let _ = std::fs::remove_file(out.join(f));
    }
    link_settings(out, settings)?;
    let machine_file = out.join(crate::lm3s_files::MACHINE_NAME);
    match machine {
        Some(m) => std::fs::write(&machine_file, format!("{m}\n"))
            .with_context(|| format!("writing {}", machine_file.display()))?,
        None => {
            let _ = std::fs::remove_file(&machine_file);
        }
    }
    // The settings the firmware will start with (the same checks; a refused record is the
    // defaults there too): the simulated ADC's clock and whether the AC caps the feed.
    let stored = std::fs::read(settings)
        .ok()
        .and_then(|b| {
            millac::protocol::table::record::decode(&b, &millac::settings::BoardLimits::GENERIC)
                .ok()
                .map(millac::settings::Valid::get)
        })
        .unwrap_or_default();
    let port = crate::emulator::port::Port::open(tcp)?;
    let mut spec = CaptureSpec::new(&elf, out);
    spec.icount_shift = shift;
    spec.extra_args = vec![
        "-serial".into(),
        port.qemu_arg(),
        "-monitor".into(),
        "none".into(),
    ];
    spec.handlers = vec![
        HandlerSpec::from_elf(&elf, "TIMER_0A")?,
        HandlerSpec::from_elf(&elf, "TIMER_1A")?,
    ];
    // The caller's stop ends the port first (the client closed, the final state asked for),
    // then QEMU.
    let qemu_stop = Arc::new(AtomicBool::new(false));
    spec.stop = Some(qemu_stop.clone());
    spec.timeout = std::time::Duration::MAX;
    let captured = AtomicBool::new(false);
    let capture = |spec: &CaptureSpec| {
        std::thread::scope(|sc| {
            let watcher = sc.spawn(|| {
                while !stop.load(Ordering::SeqCst) && !captured.load(Ordering::SeqCst) {
                    std::thread::sleep(std::time::Duration::from_millis(20));
                }
                let ending = port.finish();
                qemu_stop.store(true, Ordering::SeqCst);
                ending
            });
            let cap = run_capture(spec);
            captured.store(true, Ordering::SeqCst);
            let ending = watcher.join().unwrap_or_default();
            (cap, ending)
        })
    };
    let truth = Arc::new(std::sync::Mutex::new(Vec::new()));
    // The simulated ADC, the report and the plot take the AC settings the firmware starts with.
    let ac = ac.map(|a| AcRun {
        settings: stored.ac,
        ..a.clone()
    });
    let ac = ac.as_ref();
    let (cap, samples, ending) = match ac {
        None => {
            let (cap, ending) = capture(&spec);
            (cap?, 0, ending)
        }
        Some(a) => {
            let plant = runner::plant_with_truth(a, truth.clone(), Default::default())?;
            let bridge = cosim::Bridge::start(out, plant, stored.ac.sample_hz, a.ac)?;
            let (cap, ending) = capture(&spec);
            let exchanges = bridge.finish().unwrap_or_default();
            (cap?, exchanges.len(), ending)
        }
    };
    drop(port);
    vcd::write_vcd(&out.join("capture.vcd"), 0, &cap.pins, Some(cap.end_ns))?;
    // The session as a program: the blocks the firmware queued, from its log, with the settings
    // the firmware started with.
    let settings: Settings = stored.nc;
    let log_path = out.join(crate::lm3s_files::SERVE_LOG_NAME);
    let log = std::fs::read_to_string(&log_path).unwrap_or_default();
    let replayed =
        replay(&log, &settings).with_context(|| format!("replaying {}", log_path.display()))?;
    let prog = analysis::program_of_blocks(replayed.blocks);
    // What the session left: the blocks that ran to their end in the capture, and the state.
    let [x, y, z] = vcd::positions(0, &cap.pins);
    let ran = analysis::analyse(&prog, &settings, 0, &cap.pins);
    let blocks_done = ran.blocks.iter().take_while(|b| b.completed).count();
    let idle = ending.state.as_deref() == Some("Idle");
    // A session that stopped a move mid-block (homing, probing, a reset or a jog cancel in
    // motion) completed when the machine ended Idle (its cut blocks were cut on purpose), and
    // is analysed block by block up to the first block that did not run to its end: its pulses
    // after that are not a whole number of the replayed blocks.
    let hold = (!idle || (replayed.whole && blocks_done < prog.len())).then(|| runner::Hold {
        alarm: ending.alarm.clone().unwrap_or_default(),
        blocks_done,
        position: [x, y, z],
        signal: None,
    });
    let prog = if replayed.whole || hold.is_some() {
        prog
    } else {
        prog.into_iter().take(blocks_done).collect()
    };
    let truth = truth.lock().map(|v| v.clone()).unwrap_or_default();
    // The host's comparison runs (constant feeds, the bound) at the session's spindle speed: the
    // last S of its log (the plant followed every spindle change live; a session that changes
    // S mid-way is compared at its last one).
    let report = ac.map(|a| AcRun {
        cut: a.cut.clone().at_program_rpm(&log, &settings),
        ..a.clone()
    });
    let ac_in = report.as_ref().map(|a| runner::AcInput {
        run: a,
        samples,
        truth: &truth,
        stocks: &[],
    });
    let (mut summary, _, _) =
        runner::summarise(&prog, &settings, &cap, out, shift, hold.as_ref(), ac_in)?;
    if hold.is_some() {
        summary["hold"]["state"] = json!(ending.state);
        summary["hold"]["alarm"] = json!(ending.alarm);
    }
    if !replayed.whole {
        summary["pulses_match_host"] = Value::Null;
        summary["replay"] = json!({
            "whole": false,
            "blocks_compared": blocks_done,
            "why": "a move was stopped mid-block (homing, probing, a reset or a jog cancel in \
                    motion): the blocks up to it are compared, the pulses after it are not",
        });
    }
    // The end of the whole capture (in `run` the analysis' end equals it when the pulse counts
    // match; here it stays the capture's even if the log missed a block).
    summary["final_position_blu"] = json!({"x": x, "y": y, "z": z});
    summary["virtual_time_s"] = json!(cap.end_ns as f64 * 1e-9);
    if let Some(a) = ac {
        summary["ac"]["enabled"] = json!(a.ac && stored.ac_enabled);
    }
    runner::write_json(&out.join("summary.json"), &summary)?;
    Ok(Served {
        summary,
        capture: cap,
    })
}

/// The blocks the firmware queued in a serial session, in order, from its log `serve.nc` (see
/// `millac::wire::SessionLine`): the same tape, jog planning and block finishing as the loader in
/// serial mode (`millac::rt::loader`), so the session is analysed like a `run` of its program.
pub struct Replayed {
    pub blocks: Vec<Sealed>,
    /// Every block ran whole: no stop marker found the machine short of where the blocks
    /// before it end (a reset or a jog cancel in motion, a homing switch, a probe's contact).
    /// Otherwise the capture's pulses are not a whole number of these blocks and are not
    /// compared with the host's.
    pub whole: bool,
}

/// Replays a session log (see [`Replayed`]).
pub fn replay(log: &str, settings: &Settings) -> Result<Replayed> {
    let mut tape = Tape::new(*settings);
    let cfg = FrameConfig::from_settings(settings);
    let mut blocks = Vec::new();
    let mut whole = true;
    for (i, text) in log.lines().enumerate() {
        let n = u32::try_from(i + 1).unwrap_or(u32::MAX);
        match SessionLine::parse(text) {
            SessionLine::Gcode(l) => tape
                .line(n, l, |b| blocks.push(b))
                .map_err(|e| anyhow!("line {n}: {e}"))?,
            SessionLine::Jog(words) => {
                let words: String = words.chars().filter(|c| !c.is_whitespace()).collect();
                let plan = JogRequest::parse(&words)
                    .and_then(|j| j.plan(tape.parser()))
                    .map_err(|e| anyhow!("line {n}: jog refused: error:{}", e.0))?;
                if let Some(b) = plan.block {
                    let signs = match b.motion {
                        Motion::Linear(l) => l.signs,
                        _ => tape.parser().signs(),
                    };
                    blocks.push(finish_block(b, None, &cfg, settings.q0));
                    tape.jogged_to(plan.end, signs);
                }
            }
            SessionLine::Move(line) => {
                let (block, end, signs) = tape
                    .parser()
                    .plan_aside(line, true)
                    .map_err(|e| anyhow!("line {n}: {}", e.kind))?;
                if let Some(b) = block {
                    blocks.push(finish_block(b, None, &cfg, settings.q0));
                    tape.jogged_to(end, signs);
                }
            }
            SessionLine::Stop { at, signs, cut } => {
                whole &= !cut;
                tape.jogged_to(at, signs);
            }
            SessionLine::Flush => tape.flush(|b| blocks.push(b)),
            // As the loader's reset: the held block dropped, the modes at power-up; the stop
            // marker after it says where the parser stands.
            SessionLine::Reset => {
                let (at, signs) = (tape.parser().position(), tape.parser().signs());
                tape.abort(at, signs);
            }
        }
    }
    Ok(Replayed { blocks, whole })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("millac-link-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// The default file is used as it is; another file is linked (and an older link replaced), so
    /// what the firmware writes under its name lands in the operator's file; a file of its own
    /// under the firmware's name is refused and kept.
    #[test]
    fn the_firmware_name_reaches_the_operators_file() {
        let out = dir("out");
        link_settings(&out, &default_settings(&out)).unwrap();
        assert!(std::fs::symlink_metadata(default_settings(&out)).is_err());
        let (a, b) = (dir("a").join("s.bin"), dir("b").join("s.bin"));
        for target in [&a, &b] {
            link_settings(&out, target).unwrap();
            std::fs::write(default_settings(&out), target.to_string_lossy().as_bytes()).unwrap();
        }
        assert_eq!(std::fs::read_to_string(&a).unwrap(), a.to_string_lossy());
        assert_eq!(std::fs::read_to_string(&b).unwrap(), b.to_string_lossy());
        link_settings(&out, &b).unwrap();
        std::fs::remove_file(default_settings(&out)).unwrap();
        std::fs::write(default_settings(&out), b"own").unwrap();
        let e = link_settings(&out, &a).unwrap_err();
        assert!(e.to_string().contains("holds settings of its own"), "{e}");
        assert_eq!(std::fs::read(default_settings(&out)).unwrap(), b"own");
        // A batch run in that directory would check against the defaults: refused.
        let e = crate::emulator::runner::execute("G0 X1\n", &out, 4).expect_err("refused");
        assert!(e.to_string().contains("settings"), "{e}");
        assert!(!out.join("program.nc").exists());
    }

    /// `serve --strategy`: stored in the session's own record (a fresh one, or the existing one
    /// with its other settings kept); a link to another file and a refused record are refused
    /// and left as they are.
    #[test]
    fn store_strategy_writes_only_the_sessions_own_record() {
        use millac::ac::law::Strategy;
        use millac::protocol::table::{record, MachineSettings};
        let out = dir("strategy");
        let path = default_settings(&out);
        store_strategy(&out, Strategy::Mrac).unwrap();
        let s = record::decode(
            &std::fs::read(&path).unwrap(),
            &millac::settings::BoardLimits::GENERIC,
        )
        .unwrap();
        assert_eq!(s.ac.strategy, Strategy::Mrac);
        let mut mine = MachineSettings::default();
        mine.nc.pulse_width_ns = 7_000;
        std::fs::write(&path, record::encode(&mine)).unwrap();
        store_strategy(&out, Strategy::Integral).unwrap();
        let s = record::decode(
            &std::fs::read(&path).unwrap(),
            &millac::settings::BoardLimits::GENERIC,
        )
        .unwrap();
        assert_eq!(s.ac.strategy, Strategy::Integral);
        assert_eq!(s.nc.pulse_width_ns, 7_000);
        let mut bad = std::fs::read(&path).unwrap();
        bad[20] ^= 1;
        std::fs::write(&path, &bad).unwrap();
        let e = store_strategy(&out, Strategy::Mrac).unwrap_err();
        assert!(e.to_string().contains("checksum"), "{e}");
        assert_eq!(std::fs::read(&path).unwrap(), bad);
        std::fs::remove_file(&path).unwrap();
        let other = dir("strategy-other").join("s.bin");
        link_settings(&out, &other).unwrap();
        let e = store_strategy(&out, Strategy::Mrac).unwrap_err();
        assert!(e.to_string().contains("links to another"), "{e}");
        assert!(!other.exists());
    }
}
