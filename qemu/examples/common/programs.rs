//! The programs of the frame budget benchmarks (`frame_budget` for the QEMU board,
//! `frame_budget_f446` for the Nucleo-F446RE under QEMU, and its CI test `board_f446`): one small
//! program per block type, and the table both print (host).
//!
//! The worst frame is the one that ends a line with deceleration and starts the next line
//! (`nc::frame`: the deceleration multiply, the last command with its pulses, the block's end and
//! the chained load in one frame). [`CORNERS`] runs that frame on purpose, with all three axes in
//! the last command. It needs the next line queued before the line ends: the QEMU board reads
//! its program from a file, so every block is queued in time; the F446 benchmark streams with
//! `f446::StreamOptions::queue_first` (the machine held until all but the last line are queued),
//! so the same frames run whatever the host's load (streamed one line per `ok` without it, a
//! quiet host saw the queue run dry before each corner and never measured this frame). Every
//! program fits the F446's block queue for that.

/// Lines that decelerate into the next line: every corner is sharper than 30 degrees (the
/// look-ahead's rule), and each line moves X, Y and Z by the same distance, so its last command
/// pulses all three axes (|d_k| > q / 2). Incremental, back to the start.
pub const CORNERS: &str = "G20 G91\nG1 X0.01 Y0.01 Z0.01 F30\nG1 X-0.01 Y0.01 Z-0.01\n\
                           G1 X0.01 Y-0.01 Z0.01\nG1 X-0.01 Y-0.01 Z-0.01\nM2\n";

/// (name, program). Each runs for well under a second of virtual time.
pub const PROGRAMS: &[(&str, &str)] = &[
    ("G0 rapid", "G20 G90\nG0 X0.3 Y0.2\nG0 X0.1 Y0.25 Z-0.05\nG0 X0 Y0 Z0\nM2\n"),
    (
        "G1 lines",
        "G20 G90\nG1 X0.05 Y0.02 F30\nG1 X0.06 Y0.05 Z-0.01 F20\nG1 X0 Y0 Z0 F30\nM2\n",
    ),
    ("G1 short blocks", ""),
    (
        "G2/G3 arcs",
        "G20 G90\nG0 X0.02 Y0\nG2 X0 Y-0.02 I-0.02 J0 F30\nG3 X0.02 Y0 I0 J0.02 F30\n\
         G3 X0.02 Y0 I-0.02 J0 F30\nG2 X0.01 Y0.01 I-0.01 J0 F30\nG17 G2 X0.01 Y0.01 I0.003 J-0.004 F30\n\
         G18 G3 X0.01 Z0.01 I0.005 K0.005 F30\nG17 G2 X0.01 Y0.01 Z-0.01 I0.01 J0 F30\n\
         G17 G3 X0.01 Y0.01 Z0.05 I0.005 J0 F30\nM2\n",
    ),
    (
        "G0 then G1",
        "G20 G90\nG0 X0.02 Y0.01\nG1 Z-0.01 F10\nG1 X0.05 F12\nG0 Z0.01\nG1 X0.03 Y0.02 Z0 F20\n\
         G0 X0 Y0\nG2 X0.01 Y0.01 I0.01 J0 F30\nM2\n",
    ),
    ("G4 dwell", "G20 G90\nG4 P0.05\nG1 X0.001 F30\nG4 P0.02\nG4 P0.02\nM2\n"),
    ("G1 corners", CORNERS),
];

/// One- and two-BLU blocks back to back (24: they fit the F446's queue, see the module doc): the
/// Initiator loads a block every few frames.
pub fn short_blocks() -> String {
    let mut s = String::from("G20 G91\n");
    for k in 0..24 {
        let (x, y) = match k % 4 {
            0 => ("0.0001", "0"),
            1 => ("0", "0.0002"),
            2 => ("-0.0001", "0.0001"),
            _ => ("0.0002", "-0.0001"),
        };
        s += &format!("G1 X{x} Y{y} F30\n");
    }
    s += "M2\n";
    s
}

/// (name, program text) of every program, the short blocks generated; with `FRAME_BUDGET_ONLY`
/// set, only the programs whose name contains it.
pub fn all() -> Vec<(&'static str, String)> {
    let only = std::env::var("FRAME_BUDGET_ONLY").unwrap_or_default();
    PROGRAMS
        .iter()
        .filter(|(name, _)| name.contains(only.as_str()))
        .map(|&(name, p)| {
            let text = if p.is_empty() {
                short_blocks()
            } else {
                p.to_string()
            };
            (name, text)
        })
        .collect()
}

/// (min, median, max) of instruction counts; zeros when there are none.
pub fn stats(v: &[u64]) -> (u64, u64, u64) {
    if v.is_empty() {
        return (0, 0, 0);
    }
    let mut s = v.to_vec();
    s.sort_unstable();
    (s[0], s[s.len() / 2], s[s.len() - 1])
}

/// The table's header line.
pub fn print_header() {
    println!(
        "{:<16} {:>7} {:>5} {:>5} {:>5}   {:>7} {:>5} {:>5} {:>5}",
        "program", "frames", "min", "med", "max", "pulses", "min", "med", "max"
    );
}

/// One program's line: frame and pulse-end counts with their min / median / max; returns the two
/// maxima.
pub fn print_row(name: &str, frames: &[u64], pulses: &[u64]) -> (u64, u64) {
    let (fmin, fmed, fmax) = stats(frames);
    let (pmin, pmed, pmax) = stats(pulses);
    println!(
        "{name:<16} {:>7} {fmin:>5} {fmed:>5} {fmax:>5}   {:>7} {pmin:>5} {pmed:>5} {pmax:>5}",
        frames.len(),
        pulses.len()
    );
    (fmax, pmax)
}

/// Where the worst frame of a run was: its index among the frames, its virtual time (ms), its
/// count, and the program line whose pulses surround it (from the pins, as `analysis` splits
/// them into blocks); then the traced frames (PCs in hex, entry to return: `addr2line -e ELF`
/// names them).
pub fn print_worst(
    program: &str,
    frames: &[u64],
    starts: &[u64],
    pins: &[(u64, u8)],
    traces: &[millac_qemu::emulator::capture::HandlerTrace],
) {
    let ms = |t: u64| format!("{}.{:03} ms", t / 1_000_000, t / 1_000 % 1_000);
    if let Some((i, n)) = frames
        .iter()
        .enumerate()
        .max_by_key(|&(i, n)| (n, usize::MAX - i))
    {
        let t = starts.get(i).copied().unwrap_or(0);
        let same = frames.iter().filter(|&m| m == n).count();
        println!(
            "  worst frame: #{i} of {} at {}, {n} instructions ({same} frame(s) of that count)",
            frames.len(),
            ms(t)
        );
        let settings = millac::protocol::table::MachineSettings::default().nc;
        if let Ok(prog) = millac_qemu::analysis::load_program(program, &settings) {
            let report = millac_qemu::analysis::analyse(&prog, &settings, 0, pins);
            let text = |line: u32| program.lines().nth(line as usize - 1).unwrap_or("");
            // Blocks with pulses (a dwell has none: its times are 0).
            let mut moved = report.blocks.iter().filter(|b| b.t_end_ns > 0);
            let last = moved.clone().rfind(|b| b.t_start_ns <= t);
            let next = moved.find(|b| b.t_start_ns > t);
            for (what, b) in [("in or after", last), ("before", next)] {
                if let Some(b) = b {
                    println!(
                        "    {what} line {} `{}` (pulses {} to {})",
                        b.line,
                        text(b.line),
                        ms(b.t_start_ns),
                        ms(b.t_end_ns)
                    );
                }
            }
        }
    }
    for tr in traces {
        let pcs: Vec<String> = tr.pcs.iter().map(|p| format!("{p:x}")).collect();
        println!(
            "  trace at {} ns ({}): {}",
            tr.start_ns,
            tr.pcs.len(),
            pcs.join(" ")
        );
    }
}

/// `FRAME_BUDGET_TRACE=N`: trace the frames longer than N instructions (handler 0).
pub fn trace_option() -> Option<(usize, u64)> {
    let n = std::env::var("FRAME_BUDGET_TRACE").ok()?;
    Some((0, n.trim().parse().ok()?))
}
