//! `serve` (host): the firmware under QEMU in serial mode (no program file), its UART0 on a TCP
//! port for a G-code sender, optionally with the simulated cut and the AC live, until the caller
//! stops it (the command: SIGINT or SIGTERM); then the capture and the report of the whole run in
//! `out`: `capture.vcd`, `summary.json` with the keys of `run` (`runner::summarise`), and with
//! the AC `ac.csv` and `ac.svg`. The session's program is the firmware's log `serve.nc` (every
//! accepted line, jog, early run of a held block and soft reset; `millac::wire::SessionLine`),
//! replayed here ([`replay`]) into exactly the blocks the firmware queued.
//!
//! QEMU gets `-serial tcp:ADDR,server=on,wait=off` (a sender can connect, disconnect and reconnect
//! while the machine runs) and `-monitor none`; stopping sends QEMU SIGTERM, which shuts it down
//! cleanly, so the virtual logic analyser's log is complete.
use crate::capture::{run_capture, CaptureSpec, HandlerSpec};
use crate::runner::{self, AcRun};
use crate::{analysis, cosim, firmware, vcd};
use anyhow::{anyhow, Context, Result};
use millac::gcode::tape::{finish_block, Tape};
use millac::nc::{Block, FrameConfig, Motion};
use millac::protocol::jog::JogRequest;
use millac::wire::{self, SessionLine};
use millac::Settings;
use serde_json::{json, Value};
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// The default address of the serial port.
pub const DEFAULT_TCP: &str = "127.0.0.1:7878";

/// What a serve session produced.
pub struct Served {
    pub summary: Value,
    pub capture: crate::capture::Capture,
}

/// Runs the firmware in serial mode with UART0 on `tcp` until `stop` is set; writes
/// `out/capture.vcd`, `out/serve.nc` (the firmware's session log) and `out/summary.json`. With
/// `ac`, the simulated ADC serves the cutting process as in `run` (`out/ac.log` is the firmware's
/// AC log; `out/ac.csv` and `out/ac.svg` as in `run`).
pub fn serve(
    out: &Path,
    tcp: &str,
    shift: u32,
    ac: Option<&AcRun>,
    stop: Arc<AtomicBool>,
) -> Result<Served> {
    let elf = firmware::build()?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    // No program file: the firmware's loader takes the serial line.
    let _ = std::fs::remove_file(out.join("program.nc"));
    for f in [cosim::REQ, cosim::RESP, cosim::AC_LOG, wire::SERVE_LOG_NAME] {
        let _ = std::fs::remove_file(out.join(f));
    }
    let mut spec = CaptureSpec::new(&elf, out);
    spec.icount_shift = shift;
    spec.extra_args = vec![
        "-serial".into(),
        format!("tcp:{tcp},server=on,wait=off"),
        "-monitor".into(),
        "none".into(),
    ];
    spec.handlers = vec![
        HandlerSpec::from_elf(&elf, "TIMER_0A")?,
        HandlerSpec::from_elf(&elf, "TIMER_1A")?,
    ];
    spec.stop = Some(stop);
    let truth = Arc::new(std::sync::Mutex::new(Vec::new()));
    let (cap, samples) = match ac {
        None => (run_capture(&spec)?, 0),
        Some(a) => {
            let plant = runner::plant_with_truth(a, truth.clone())?;
            let sample_hz = millac::ac::AcSettings::default().sample_hz;
            let bridge = cosim::Bridge::start(out, plant, sample_hz, a.ac)?;
            let cap = run_capture(&spec);
            let exchanges = bridge.finish().unwrap_or_default();
            (cap?, exchanges.len())
        }
    };
    vcd::write_vcd(&out.join("capture.vcd"), 0, &cap.pins, Some(cap.end_ns))?;
    // The session as a program: the blocks the firmware queued, from its log.
    let settings = Settings::default();
    let log_path = out.join(wire::SERVE_LOG_NAME);
    let log = std::fs::read_to_string(&log_path).unwrap_or_default();
    let prog = analysis::program_of_blocks(
        replay(&log, &settings).with_context(|| format!("replaying {}", log_path.display()))?,
    );
    let hold = runner::firmware_hold(&cap.stdout);
    let truth = truth.lock().map(|v| v.clone()).unwrap_or_default();
    let ac_in = ac.map(|a| runner::AcInput {
        run: a,
        samples,
        truth: &truth,
    });
    let (mut summary, _, _) =
        runner::summarise(&prog, &settings, &cap, out, shift, hold.as_ref(), ac_in)?;
    // The end of the whole capture (in `run` the analysis' end equals it when the pulse counts
    // match; here it stays the capture's even if the log missed a block).
    let [x, y, z] = vcd::positions(0, &cap.pins);
    summary["final_position_blu"] = json!({"x": x, "y": y, "z": z});
    summary["virtual_time_s"] = json!(cap.end_ns as f64 * 1e-9);
    runner::write_json(&out.join("summary.json"), &summary)?;
    Ok(Served {
        summary,
        capture: cap,
    })
}

/// The blocks the firmware queued in a serial session, in order, from its log `serve.nc` (see
/// `millac::wire::SessionLine`): the same tape, jog planning and block finishing as the loader in
/// serial mode (`millac_hal::serial`), so the session is analysed like a `run` of its program.
pub fn replay(log: &str, settings: &Settings) -> Result<Vec<Block>> {
    let mut tape = Tape::new(*settings);
    let cfg = FrameConfig::from_settings(settings);
    let mut blocks = Vec::new();
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
            SessionLine::Flush => tape.flush(|b| blocks.push(b)),
            SessionLine::Reset => tape.reset(|b| blocks.push(b)),
        }
    }
    Ok(blocks)
}
