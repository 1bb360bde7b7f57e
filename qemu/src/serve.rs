//! `serve` (host): the firmware under QEMU in serial mode (no program file), its UART0 on a TCP
//! port for a G-code sender, optionally with the simulated cut and the AC live, until the caller
//! stops it (the command: SIGINT or SIGTERM); then the capture and the report of the whole run in
//! `out`: `capture.vcd` and `summary.json`.
//!
//! QEMU gets `-serial tcp:ADDR,server=on,wait=off` (a sender can connect, disconnect and reconnect
//! while the machine runs) and `-monitor none`; stopping sends QEMU SIGTERM, which shuts it down
//! cleanly, so the virtual logic analyser's log is complete.
use crate::capture::{run_capture, CaptureSpec, HandlerSpec};
use crate::runner::{self, AcRun};
use crate::{cosim, firmware, vcd};
use anyhow::{Context, Result};
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
/// `out/capture.vcd` and `out/summary.json`. With `ac`, the simulated ADC serves the cutting
/// process as in `run` (and `out/ac.log` is the firmware's AC log).
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
    for f in [cosim::REQ, cosim::RESP, cosim::AC_LOG] {
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
    let (cap, samples) = match ac {
        None => (run_capture(&spec)?, 0),
        Some(a) => {
            let plant = runner::process_plant(a)?;
            let sample_hz = millac::ac::AcSettings::default().sample_hz;
            let bridge = cosim::Bridge::start(out, plant, sample_hz, a.ac)?;
            let cap = run_capture(&spec);
            let exchanges = bridge.finish().unwrap_or_default();
            (cap?, exchanges.len())
        }
    };
    vcd::write_vcd(&out.join("capture.vcd"), 0, &cap.pins, Some(cap.end_ns))?;
    let [x, y, z] = vcd::positions(0, &cap.pins);
    let rises: Vec<u64> = crate::analysis::edges(0, &cap.pins)
        .edges
        .iter()
        .map(|e| e.t_ns)
        .collect();
    let machining = match (rises.first(), rises.last()) {
        (Some(a), Some(b)) => (b - a) as f64 * 1e-9,
        _ => 0.0,
    };
    let mut summary = json!({
        "final_position_blu": {"x": x, "y": y, "z": z},
        "machining_time_s": (machining * 1e6).round() / 1e6,
        "frame_instructions": runner::stats(&cap.handlers[0].1),
        "pulse_end_instructions": runner::stats(&cap.handlers[1].1),
        "frames": cap.handlers[0].1.len(),
        "icount_shift": shift,
        "virtual_time_s": cap.end_ns as f64 * 1e-9,
    });
    if let Some(a) = ac {
        summary["ac"] = json!({"enabled": a.ac, "samples": samples});
    }
    runner::write_json(&out.join("summary.json"), &summary)?;
    Ok(Served {
        summary,
        capture: cap,
    })
}
