//! Cross-check of step counts with sigrok (host): decodes a VCD of the step/sign pins with
//! sigrok-cli's `stepper_motor` protocol decoder and returns the final position of each axis.
//!
//! Verified with sigrok-cli 0.7.2 (Debian bookworm). sigrok's VCD input names each logic channel after
//! the `$var` reference name (`X_STEP`, ...), so the exact command is:
//!
//! ```text
//! sigrok-cli -i FILE.vcd -I vcd:compress=10 \
//!   -P stepper_motor:step=X_STEP:dir=X_SIGN:unit=steps \
//!   -P stepper_motor:step=Y_STEP:dir=Y_SIGN:unit=steps \
//!   -P stepper_motor:step=Z_STEP:dir=Z_SIGN:unit=steps \
//!   -A stepper_motor=position
//! ```
//!
//! Each `-P` is an independent decoder instance, named `stepper_motor-1`, `-2`, `-3` in order; output
//! lines look like `stepper_motor-2: -1 steps`. `compress=10` clips idle periods to 10 samples (the
//! VCD input otherwise expands a 1 ns timescale into one sample per ns: 10^10 samples for 10 s);
//! positions only depend on edge order, so they are unchanged (speeds would not be).
//!
//! The decoder annotates, at each rising step edge after the first, the position *before* that edge,
//! so the last step's result is never printed. [`decode_positions`] therefore re-writes the VCD with
//! one extra sentinel step pulse on every axis after the end; the last annotation of each instance is
//! then the final position (no annotation = 0).
use anyhow::{bail, ensure, Context, Result};
use std::path::Path;
use std::process::Command;

/// The sigrok-cli command decoding the three axes of `vcd` (see the module docs).
pub fn sigrok_command(vcd: &Path) -> Command {
    let mut cmd = Command::new("sigrok-cli");
    cmd.arg("-i").arg(vcd).args(["-I", "vcd:compress=10"]);
    for axis in ["X", "Y", "Z"] {
        cmd.arg("-P").arg(format!(
            "stepper_motor:step={axis}_STEP:dir={axis}_SIGN:unit=steps"
        ));
    }
    cmd.args(["-A", "stepper_motor=position"]);
    cmd
}

/// Parses sigrok-cli's position annotations: the last value of each instance `stepper_motor-N`.
pub fn parse_positions(output: &str) -> Result<[i64; 3]> {
    let mut pos = [0i64; 3];
    for line in output.lines().filter(|l| !l.trim().is_empty()) {
        let (inst, rest) = line
            .split_once(": ")
            .with_context(|| format!("unexpected sigrok output `{line}`"))?;
        let n: usize = inst
            .strip_prefix("stepper_motor-")
            .and_then(|n| n.parse().ok())
            .with_context(|| format!("unexpected sigrok output `{line}`"))?;
        ensure!(
            (1..=3).contains(&n),
            "unexpected decoder instance in `{line}`"
        );
        let v: f64 = rest
            .trim()
            .strip_suffix("steps")
            .and_then(|v| v.trim().parse().ok())
            .with_context(|| format!("unexpected sigrok output `{line}`"))?;
        pos[n - 1] = v.round() as i64;
    }
    Ok(pos)
}

/// Final position per axis (X, Y, Z) of the VCD at `vcd` (any VCD [`crate::analysis::vcd::read_vcd`]
/// accepts), decoded by sigrok-cli's `stepper_motor` decoder.
pub fn decode_positions(vcd: &Path) -> Result<[i64; 3]> {
    crate::emulator::tools::ensure_tool("sigrok-cli")?;
    let text =
        std::fs::read_to_string(vcd).with_context(|| format!("reading {}", vcd.display()))?;
    let trace = crate::analysis::vcd::read_vcd(&text)
        .with_context(|| format!("parsing {}", vcd.display()))?;
    // Sentinel: all STEP pins low, then high, after the end.
    const STEPS: u8 = 0b111;
    let mut events = trace.events.clone();
    let last = events.last().map_or(trace.initial, |e| e.1);
    let t0 = trace.end_ns.max(events.last().map_or(0, |e| e.0)) + 10;
    events.push((t0, last & !STEPS));
    events.push((t0 + 10, last | STEPS));
    let tmp = std::env::temp_dir().join(format!(
        "millac-sigrok-{}-{:?}.vcd",
        std::process::id(),
        std::thread::current().id()
    ));
    crate::analysis::vcd::write_vcd(&tmp, trace.initial, &events, Some(t0 + 20))?;
    let out = sigrok_command(&tmp).output().context("running sigrok-cli");
    let _ = std::fs::remove_file(&tmp);
    let out = out?;
    if !out.status.success() {
        bail!(
            "sigrok-cli failed ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
    }
    parse_positions(&String::from_utf8_lossy(&out.stdout))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_annotations() {
        let out = "stepper_motor-1: 1 steps\nstepper_motor-1: 2 steps\nstepper_motor-3: -4 steps\n";
        assert_eq!(parse_positions(out).unwrap(), [2, 0, -4]);
        assert!(parse_positions("garbage\n").is_err());
    }
}
