//! The programs of the frame budget benchmarks (`frame_budget` for the QEMU board,
//! `frame_budget_f446` for the Nucleo-F446RE under QEMU): one small program per block type, and
//! the table both print.

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
         G18 G3 X0.01 Z0.01 I0.005 K0.005 F30\nM2\n",
    ),
    (
        "G0 then G1",
        "G20 G90\nG0 X0.02 Y0.01\nG1 Z-0.01 F10\nG1 X0.05 F12\nG0 Z0.01\nG1 X0.03 Y0.02 Z0 F20\n\
         G0 X0 Y0\nG2 X0.01 Y0.01 I0.01 J0 F30\nM2\n",
    ),
    ("G4 dwell", "G20 G90\nG4 P0.05\nG1 X0.001 F30\nG4 P0.02\nG4 P0.02\nM2\n"),
];

/// Many one- and two-BLU blocks back to back: the Initiator loads a block every few frames.
pub fn short_blocks() -> String {
    let mut s = String::from("G20 G91\n");
    for k in 0..200 {
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

/// (name, program text) of every program, the short blocks generated.
pub fn all() -> Vec<(&'static str, String)> {
    PROGRAMS
        .iter()
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
