//! VCD (value change dump) files of the step/sign pins (host): a writer of millac's own format and a
//! tolerant reader for ours or for VCDs exported by PulseView/sigrok after a real capture.
//!
//! Written format: `$timescale 1 ns $end`, one `$scope module millac $end`, six 1-bit wires
//! `X_STEP X_SIGN Y_STEP Y_SIGN Z_STEP Z_SIGN` (ids `!` to `&`), their initial values at `#0` in
//! `$dumpvars`, then only changes; times in ns.
//!
//! Pin states are bytes in port B order: bit 0 X_STEP, 1 Y_STEP, 2 Z_STEP, 3 X_SIGN, 4 Y_SIGN,
//! 5 Z_SIGN (see [`WIRES`]).
use anyhow::{bail, Context, Result};
use std::collections::HashMap;
use std::fmt::Write as _;

/// Wire names in file order with their bit in the pin byte.
pub const WIRES: [(&str, u8); 6] = [
    ("X_STEP", 0),
    ("X_SIGN", 3),
    ("Y_STEP", 1),
    ("Y_SIGN", 4),
    ("Z_STEP", 2),
    ("Z_SIGN", 5),
];
const IDS: [char; 6] = ['!', '"', '#', '$', '%', '&'];
/// Bits of the STEP and SIGN pins of axes X, Y, Z.
pub const AXES: [(u8, u8); 3] = [(0, 3), (1, 4), (2, 5)];

/// Pin states read from a VCD: initial state, then (time ns, state) after each change.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct PinTrace {
    pub initial: u8,
    pub events: Vec<(u64, u8)>,
    /// Last timestamp in the file, ns.
    pub end_ns: u64,
}

/// Writes a VCD of `events` (time ns, pin byte) starting from `initial` at time 0. Events that
/// change nothing are skipped; events at the same time are merged; `end_ns` adds a final timestamp.
pub fn vcd_string(initial: u8, events: &[(u64, u8)], end_ns: Option<u64>) -> String {
    let mut s = String::from("$timescale 1 ns $end\n$scope module millac $end\n");
    for ((name, _), id) in WIRES.iter().zip(IDS) {
        let _ = writeln!(s, "$var wire 1 {id} {name} $end");
    }
    s += "$upscope $end\n$enddefinitions $end\n#0\n$dumpvars\n";
    let bit = |v: u8, b: u8| (v >> b) & 1;
    // Fold events at time 0 into the initial values.
    let initial = events
        .iter()
        .take_while(|e| e.0 == 0)
        .last()
        .map_or(initial, |e| e.1);
    for ((_, b), id) in WIRES.iter().zip(IDS) {
        let _ = writeln!(s, "{}{id}", bit(initial, *b));
    }
    s += "$end\n";
    let mut last = initial;
    let mut last_t = 0;
    let mut i = 0;
    while i < events.len() {
        let t = events[i].0;
        while i + 1 < events.len() && events[i + 1].0 == t {
            i += 1;
        }
        let v = events[i].1;
        i += 1;
        if v == last || t == 0 {
            continue;
        }
        let _ = writeln!(s, "#{t}");
        for ((_, b), id) in WIRES.iter().zip(IDS) {
            if bit(v, *b) != bit(last, *b) {
                let _ = writeln!(s, "{}{id}", bit(v, *b));
            }
        }
        last = v;
        last_t = t;
    }
    if let Some(end) = end_ns {
        if end > last_t {
            let _ = writeln!(s, "#{end}");
        }
    }
    s
}

/// Writes [`vcd_string`] to a file.
pub fn write_vcd(
    path: &std::path::Path,
    initial: u8,
    events: &[(u64, u8)],
    end_ns: Option<u64>,
) -> Result<()> {
    std::fs::write(path, vcd_string(initial, events, end_ns))
        .with_context(|| format!("writing {}", path.display()))
}

fn timescale_fs(spec: &str) -> Result<u128> {
    let spec = spec.trim();
    let split = spec
        .find(|c: char| !c.is_ascii_digit())
        .with_context(|| format!("bad timescale `{spec}`"))?;
    let n: u128 = spec[..split]
        .parse()
        .with_context(|| format!("bad timescale `{spec}`"))?;
    let unit: u128 = match spec[split..].trim() {
        "s" => 1_000_000_000_000_000,
        "ms" => 1_000_000_000_000,
        "us" => 1_000_000_000,
        "ns" => 1_000_000,
        "ps" => 1_000,
        "fs" => 1,
        u => bail!("unknown timescale unit `{u}`"),
    };
    Ok(n * unit)
}

/// Reads a VCD that has the six wires of [`WIRES`] (matched by name, any scope; a `[n]` bit-index
/// suffix is ignored; other wires are ignored). Accepts any timescale (times are converted to ns,
/// truncated), scalar changes (`1!`) and 1-bit vector changes (`b1 !`); `x`/`z` read as 0. The
/// values at the first timestamp are the initial state.
///
/// What sigrok-cli and PulseView (libsigrok's VCD output) write is read too: unknown `$...`
/// sections (`$date`, `$version`, multi-line `$comment`, `$attrbegin`, ...) are skipped to their
/// `$end`; a line before `$enddefinitions` that is not VCD at all (libsigrok 0.5 starts its files
/// with `META samplerate: ...`) is skipped whole, as is a `META` line later on. Any other unknown
/// token in the value changes is an error naming its line.
pub fn read_vcd(text: &str) -> Result<PinTrace> {
    let mut toks = text
        .lines()
        .enumerate()
        .flat_map(|(n, l)| l.split_whitespace().map(move |t| (n + 1, t)))
        .peekable();
    let mut fs_per_unit: u128 = 1_000_000;
    let mut ids: HashMap<String, Vec<u8>> = HashMap::new();
    let mut found = 0u8;
    let mut trace = PinTrace::default();
    let (mut cur, mut emitted) = (0u8, 0u8);
    let mut time: Option<u64> = None;
    let mut first_time = true;
    let mut in_header = true;
    // The line of the previous token: a token on a new line starts that line.
    let mut prev_line = 0;
    let set = |cur: &mut u8, id: &str, v: bool, ids: &HashMap<String, Vec<u8>>| {
        if let Some(bits) = ids.get(id) {
            for b in bits {
                if v {
                    *cur |= 1 << b;
                } else {
                    *cur &= !(1 << b);
                }
            }
        }
    };
    let flush =
        |trace: &mut PinTrace, cur: u8, emitted: &mut u8, time: Option<u64>, first: bool| {
            if let Some(t) = time {
                if first {
                    trace.initial = cur;
                    *emitted = cur;
                } else if cur != *emitted {
                    trace.events.push((t, cur));
                    *emitted = cur;
                }
            }
        };
    while let Some((line, tok)) = toks.next() {
        let starts_line = line != prev_line;
        prev_line = line;
        match tok {
            "$timescale" => {
                let spec: Vec<&str> = toks
                    .by_ref()
                    .map(|(_, t)| t)
                    .take_while(|t| *t != "$end")
                    .collect();
                fs_per_unit = timescale_fs(&spec.concat())?;
            }
            "$var" => {
                let f: Vec<&str> = toks
                    .by_ref()
                    .map(|(_, t)| t)
                    .take_while(|t| *t != "$end")
                    .collect();
                if f.len() < 4 {
                    bail!("line {line}: bad $var: {}", f.join(" "));
                }
                let name = f[3].split('[').next().unwrap_or("");
                if let Some((_, b)) = WIRES.iter().find(|(n, _)| *n == name) {
                    if found & (1 << b) == 0 {
                        found |= 1 << b;
                        ids.entry(f[2].to_string()).or_default().push(*b);
                    }
                }
            }
            "$dumpvars" | "$dumpall" | "$dumpon" | "$dumpoff" | "$end" => {}
            t if t.starts_with('$') => {
                if t == "$enddefinitions" {
                    in_header = false;
                }
                // $scope, $upscope, $comment, $date, $version, $enddefinitions...: skip to $end.
                toks.by_ref()
                    .map(|(_, t)| t)
                    .take_while(|t| *t != "$end")
                    .for_each(drop);
            }
            t if t.starts_with('#') => {
                let units: u128 = t[1..]
                    .parse()
                    .with_context(|| format!("line {line}: bad time `{t}`"))?;
                flush(&mut trace, cur, &mut emitted, time, first_time);
                if time.is_some() {
                    first_time = false;
                }
                let ns = (units * fs_per_unit / 1_000_000) as u64;
                time = Some(ns);
                trace.end_ns = ns;
            }
            t if t.starts_with(['b', 'B']) => {
                let (_, id) = toks
                    .next()
                    .with_context(|| format!("line {line}: vector change `{t}` without id"))?;
                set(&mut cur, id, t.ends_with('1'), &ids);
            }
            t if t.starts_with(['r', 'R']) => {
                toks.next();
            }
            t if t.len() > 1 && t.starts_with(['0', '1', 'x', 'X', 'z', 'Z']) => {
                set(&mut cur, &t[1..], t.starts_with('1'), &ids);
            }
            t if starts_line && (in_header || t == "META") => {
                // Not VCD: a tool's own line (sigrok's `META samplerate: ...`); skip all of it.
                while toks.next_if(|(l, _)| *l == line).is_some() {}
            }
            t => bail!("line {line}: unexpected VCD token `{t}`"),
        }
    }
    flush(&mut trace, cur, &mut emitted, time, first_time);
    let missing: Vec<&str> = WIRES
        .iter()
        .filter(|(_, b)| found & (1 << b) == 0)
        .map(|(n, _)| *n)
        .collect();
    if !missing.is_empty() {
        bail!("VCD lacks wires {}", missing.join(", "));
    }
    Ok(trace)
}

/// Per axis X, Y, Z: (time ns, +1 or -1) of each rising STEP edge, signed by SIGN at that moment.
pub fn axis_steps(initial: u8, events: &[(u64, u8)]) -> [Vec<(u64, i8)>; 3] {
    let mut out: [Vec<(u64, i8)>; 3] = Default::default();
    let mut prev = initial;
    for &(t, v) in events {
        for (axis, (step, sign)) in AXES.iter().enumerate() {
            if (prev >> step) & 1 == 0 && (v >> step) & 1 == 1 {
                out[axis].push((t, if (v >> sign) & 1 == 1 { 1 } else { -1 }));
            }
        }
        prev = v;
    }
    out
}

/// Final position (BLU) per axis: the sum of [`axis_steps`].
pub fn positions(initial: u8, events: &[(u64, u8)]) -> [i64; 3] {
    axis_steps(initial, events).map(|a| a.iter().map(|&(_, d)| i64::from(d)).sum())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let events = vec![
            (100, 0x09),
            (150, 0x08),
            (150, 0x0a),
            (200, 0x08),
            (300, 0x08),
            (400, 0x01),
        ];
        let s = vcd_string(0x08, &events, Some(1000));
        assert!(s.starts_with(
            "$timescale 1 ns $end\n$scope module millac $end\n$var wire 1 ! X_STEP $end\n"
        ));
        let t = read_vcd(&s).unwrap();
        assert_eq!(t.initial, 0x08);
        assert_eq!(
            t.events,
            vec![(100, 0x09), (150, 0x0a), (200, 0x08), (400, 0x01)]
        );
        assert_eq!(t.end_ns, 1000);
        assert_eq!(positions(t.initial, &t.events), [0, -1, 0]);
    }

    #[test]
    fn reads_foreign_vcd() {
        let s = "$date today $end\n$version PulseView $end\n$timescale 10 us $end\n\
                 $scope module libsigrok $end\n$var wire 1 A CLK $end\n$var wire 1 ! X_STEP [0] $end\n\
                 $var wire 1 \" X_SIGN $end\n$var wire 1 # Y_STEP $end\n$var wire 1 $ Y_SIGN $end\n\
                 $var wire 1 % Z_STEP[0] $end\n$var wire 1 & Z_SIGN $end\n$upscope $end\n\
                 $enddefinitions $end\n#0 1\" 0! 0# 0$ 0% 0& 1A\n#3 1! b1 % 0A\n#5 0! b0 %\n#7 1! 0\"\n#9\n";
        let t = read_vcd(s).unwrap();
        assert_eq!(t.initial, 0x08);
        assert_eq!(
            t.events,
            vec![(30_000, 0x0d), (50_000, 0x08), (70_000, 0x01)]
        );
        assert_eq!(t.end_ns, 90_000);
        assert_eq!(positions(t.initial, &t.events), [0, 0, -1]);
        let steps = axis_steps(t.initial, &t.events);
        assert_eq!(steps[0], vec![(30_000, 1), (70_000, -1)]);
    }

    #[test]
    fn reads_what_libsigrok_writes_and_names_the_line_of_garbage() {
        let head = "META samplerate: 10000000\n$date Mon Nov 23 01:20:37 2026 $end\n\
                    $version libsigrok 0.5.2 $end\n$comment\n  Acquisition with 6/6 channels at 10 MHz\n\
                    $end\n$timescale 100 ns $end\n$scope module libsigrok $end\n\
                    $var wire 1 ! X_STEP $end\n$var wire 1 \" X_SIGN $end\n$var wire 1 # Y_STEP $end\n\
                    $var wire 1 $ Y_SIGN $end\n$var wire 1 % Z_STEP $end\n$var wire 1 & Z_SIGN $end\n\
                    $upscope $end\n$enddefinitions $end\n#0 0! 0\" 0# 0$ 0% 0&\n#4248 1\"\n";
        let t = read_vcd(&format!(
            "{head}#12235 1!\nMETA samplerate: 10000000\n#12291 0!\n#13000\n"
        ))
        .unwrap();
        assert_eq!(t.initial, 0);
        assert_eq!(
            t.events,
            vec![(424_800, 0x08), (1_223_500, 0x09), (1_229_100, 0x08)]
        );
        assert_eq!(t.end_ns, 1_300_000);
        let e = read_vcd(&format!("{head}#12235 1!\nhello 1!\n"))
            .unwrap_err()
            .to_string();
        let line = head.lines().count() + 2;
        assert!(
            e.contains(&format!("line {line}:")) && e.contains("hello"),
            "{e}"
        );
    }

    #[test]
    fn timescales() {
        assert_eq!(timescale_fs("1ps").unwrap(), 1_000);
        assert_eq!(timescale_fs("100 ns").unwrap(), 100_000_000);
        assert!(timescale_fs("1 parsec").is_err());
    }

    #[test]
    fn missing_wire_is_an_error() {
        let s = "$timescale 1 ns $end\n$var wire 1 ! X_STEP $end\n$enddefinitions $end\n#0\n0!\n";
        let e = read_vcd(s).unwrap_err().to_string();
        assert!(e.contains("X_SIGN"), "{e}");
    }
}
