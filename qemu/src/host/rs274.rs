//! LinuxCNC's interpreter as a reference reading of G-code (host: the rs274 comparison test,
//! qemu/tests/rs274.rs, calls it): runs LinuxCNC's standalone `rs274` (found or extracted by
//! [`crate::emulator::tools::ensure_rs274`]) on a program and parses the canonical machining
//! calls it prints into moves in machine coordinates (mm) and the non-motion events (dwell,
//! stops, tool changes, the program's end), in the order rs274 printed them.
//!
//! rs274 prints positions in program coordinates and program units; the offsets come as separate
//! calls (`SET_G5X_OFFSET`, `SET_G92_OFFSET`, `USE_TOOL_LENGTH_OFFSET`) and the units as
//! `USE_LENGTH_UNITS`. Machine = program + G5x + G92 + tool length offset, each converted to mm
//! with the units in force when it was printed (rs274 does not print the offsets again when the
//! units change: it keeps them in machine terms).
use crate::emulator::tools::Rs274;
use anyhow::{bail, Context, Result};
use millac::nc::Plane;
use std::process::{Command, Stdio};

/// mm per inch.
const MM_PER_INCH: f64 = 25.4;

/// What kind of move a canonical motion call is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// `STRAIGHT_TRAVERSE` (G0).
    Traverse,
    /// `STRAIGHT_FEED` (G1, and the feed moves of canned cycles).
    Feed,
    /// `ARC_FEED` (G2/G3) in `plane` (millac's naming: (a, b) = [`Plane::axes`]), its centre in
    /// machine mm on (a, b), counter-clockwise (G3) or not, and the number of turns (|rotation|:
    /// 1 for an ordinary arc, more with a P word).
    Arc {
        plane: Plane,
        centre: [f64; 2],
        ccw: bool,
        turns: u32,
    },
    /// `STRAIGHT_PROBE` (G38.n).
    Probe,
}

/// One canonical call kept from rs274's output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// A motion to `end` (machine coordinates, mm).
    Move { kind: Kind, end: [f64; 3] },
    /// `DWELL(seconds)` (G4).
    Dwell { seconds: f64 },
    /// `PROGRAM_STOP()` (M0).
    ProgramStop,
    /// `OPTIONAL_PROGRAM_STOP()` (M1).
    OptionalProgramStop,
    /// `SELECT_TOOL(n)` (T).
    SelectTool(i64),
    /// `CHANGE_TOOL(n)` (M6).
    ChangeTool(i64),
    /// `PROGRAM_END()` (M2/M30).
    ProgramEnd,
}

/// A kept canonical call with where rs274 printed it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Canon {
    /// rs274's own count of its output lines (the first column): the order, not a program line.
    pub seq: u32,
    /// The block's N word when the program numbers its blocks (rs274 prints `N.....` when it
    /// does not: None). rs274 prints no program line numbers.
    pub n: Option<u32>,
    pub event: Event,
}

/// The program text rs274 is given: LinuxCNC refuses a K word on a G17 arc, which FreeCAD's grbl
/// post writes as ` K0.000` (grbl ignores it); ` K0.000` and ` K-0.000` are removed when they are
/// exactly zero (not followed by another digit), nothing else is changed.
pub fn strip_zero_k(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find(" K") {
        out.push_str(&rest[..i]);
        let after = &rest[i + 2..];
        let num = after.strip_prefix('-').unwrap_or(after);
        let zero = num.starts_with("0.000")
            && !num[5..].starts_with(|c: char| c.is_ascii_digit() || c == '.');
        if zero {
            rest = &num[5..];
        } else {
            out.push_str(" K");
            rest = after;
        }
    }
    out.push_str(rest);
    out
}

/// Runs rs274 on `program` (after [`strip_zero_k`]) in batch mode with the tool table `tools`
/// (rs274's format, values in inches even for mm programs; None: an empty table) and parses its
/// output. An interpreter error (rs274 exits nonzero) is an error with its message.
pub fn run(rs274: &Rs274, program: &str, tools: Option<&str>) -> Result<Vec<Canon>> {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let k = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("millac-rs274-{}-{k}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let prog = dir.join("program.ngc");
    let table = dir.join("tools.tbl");
    let result = (|| {
        std::fs::write(&prog, strip_zero_k(program))?;
        std::fs::write(&table, tools.unwrap_or(""))?;
        let out = Command::new(&rs274.program)
            .arg("-g")
            .arg("-t")
            .arg(&table)
            .arg(&prog)
            .env("LD_LIBRARY_PATH", &rs274.library_path)
            .stdin(Stdio::null())
            .output()
            .with_context(|| format!("running {}", rs274.program.display()))?;
        let stdout = String::from_utf8_lossy(&out.stdout);
        if !out.status.success() {
            let stderr = String::from_utf8_lossy(&out.stderr);
            let err: Vec<&str> = stderr.lines().filter(|l| *l != "executing").collect();
            bail!(
                "rs274 refused the program ({}): {}",
                out.status,
                err.join(" | ")
            );
        }
        parse(&stdout)
    })();
    let _ = std::fs::remove_dir_all(&dir);
    result
}

/// The numbers in a call's argument list (commas between groups, spaces inside them), in order.
fn numbers(args: &str) -> Result<Vec<f64>> {
    args.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<f64>()
                .with_context(|| format!("not a number: {s:?}"))
        })
        .collect()
}

/// Parses rs274's canonical output (`  SEQ N.....  CALL(ARGS)` per line) into the motions (in
/// machine mm, see the module's note) and the non-motion events; the other calls (feed rate,
/// spindle, comments, ...) only update the state or are dropped.
pub fn parse(text: &str) -> Result<Vec<Canon>> {
    let mut mm_per_unit = 1.0;
    let mut g5x = [0.0f64; 3];
    let mut g92 = [0.0f64; 3];
    let mut tlo = [0.0f64; 3];
    let mut plane = Plane::XY;
    let mut events = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let ctx = || format!("rs274 output line {}: {line:?}", i + 1);
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let mut cols = line.splitn(3, char::is_whitespace);
        let seq: u32 = cols.next().unwrap_or("").parse().with_context(ctx)?;
        let nword = cols.next().unwrap_or("");
        let n = match nword.strip_prefix('N') {
            Some(d) if d.chars().all(|c| c == '.') => None,
            Some(d) => Some(d.parse().with_context(ctx)?),
            None => bail!("{}: no N column", ctx()),
        };
        let call = cols.next().unwrap_or("").trim();
        let (name, args) = call
            .split_once('(')
            .and_then(|(n, a)| Some((n, a.strip_suffix(')')?)))
            .with_context(ctx)?;
        // Comments and messages hold free text: never parsed as numbers.
        if matches!(name, "COMMENT" | "MESSAGE") {
            continue;
        }
        let num = || numbers(args).with_context(ctx);
        let need = |v: &[f64], k: usize| -> Result<()> {
            if v.len() < k {
                bail!("{}: {k} numbers expected", ctx());
            }
            Ok(())
        };
        let machine = |p: [f64; 3], u: f64| [0, 1, 2].map(|k| p[k] * u + g5x[k] + g92[k] + tlo[k]);
        let event = match name {
            "USE_LENGTH_UNITS" => {
                mm_per_unit = match args {
                    "CANON_UNITS_MM" => 1.0,
                    "CANON_UNITS_INCHES" => MM_PER_INCH,
                    "CANON_UNITS_CM" => 10.0,
                    _ => bail!("{}: unknown units", ctx()),
                };
                None
            }
            "SET_G5X_OFFSET" => {
                let v = num()?;
                need(&v, 4)?;
                g5x = [v[1], v[2], v[3]].map(|x| x * mm_per_unit);
                None
            }
            "SET_G92_OFFSET" => {
                let v = num()?;
                need(&v, 3)?;
                g92 = [v[0], v[1], v[2]].map(|x| x * mm_per_unit);
                None
            }
            "USE_TOOL_LENGTH_OFFSET" => {
                let v = num()?;
                need(&v, 3)?;
                tlo = [v[0], v[1], v[2]].map(|x| x * mm_per_unit);
                None
            }
            "SELECT_PLANE" => {
                plane = match args {
                    "CANON_PLANE_XY" => Plane::XY,
                    "CANON_PLANE_XZ" => Plane::ZX,
                    "CANON_PLANE_YZ" => Plane::YZ,
                    _ => bail!("{}: a plane millac does not have", ctx()),
                };
                None
            }
            "STRAIGHT_TRAVERSE" | "STRAIGHT_FEED" | "STRAIGHT_PROBE" => {
                let v = num()?;
                need(&v, 3)?;
                let kind = match name {
                    "STRAIGHT_TRAVERSE" => Kind::Traverse,
                    "STRAIGHT_FEED" => Kind::Feed,
                    _ => Kind::Probe,
                };
                Some(Event::Move {
                    kind,
                    end: machine([v[0], v[1], v[2]], mm_per_unit),
                })
            }
            "ARC_FEED" => {
                // first_end, second_end, first_centre, second_centre, rotation, axis_end, ...
                let v = num()?;
                need(&v, 6)?;
                let (a, b) = plane.axes();
                let c = 3 - a - b;
                let mut p = [0.0; 3];
                p[a] = v[0];
                p[b] = v[1];
                p[c] = v[5];
                let end = machine(p, mm_per_unit);
                let centre = [
                    v[2] * mm_per_unit + g5x[a] + g92[a] + tlo[a],
                    v[3] * mm_per_unit + g5x[b] + g92[b] + tlo[b],
                ];
                if v[4] == 0.0 {
                    bail!("{}: rotation 0", ctx());
                }
                Some(Event::Move {
                    kind: Kind::Arc {
                        plane,
                        centre,
                        ccw: v[4] > 0.0,
                        turns: v[4].abs().round() as u32,
                    },
                    end,
                })
            }
            "DWELL" => {
                let v = num()?;
                need(&v, 1)?;
                Some(Event::Dwell { seconds: v[0] })
            }
            "PROGRAM_STOP" => Some(Event::ProgramStop),
            "OPTIONAL_PROGRAM_STOP" => Some(Event::OptionalProgramStop),
            "PROGRAM_END" => Some(Event::ProgramEnd),
            "SELECT_TOOL" | "CHANGE_TOOL" => {
                let v = num()?;
                need(&v, 1)?;
                let t = v[0] as i64;
                Some(if name == "SELECT_TOOL" {
                    Event::SelectTool(t)
                } else {
                    Event::ChangeTool(t)
                })
            }
            _ => None,
        };
        if let Some(event) = event {
            events.push(Canon { seq, n, event });
        }
    }
    Ok(events)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < 1e-9)
    }

    fn end(c: &Canon) -> [f64; 3] {
        match c.event {
            Event::Move { end, .. } => end,
            e => panic!("not a move: {e:?}"),
        }
    }

    #[test]
    fn offsets_and_units_make_machine_millimetres() {
        let text = "\
    1 N..... USE_LENGTH_UNITS(CANON_UNITS_MM)
    2 N..... SET_G5X_OFFSET(1, 10.0000, 20.0000, -5.0000, 0.0000, 0.0000, 0.0000)
    3 N..... SET_G92_OFFSET(1.0000, 2.0000, 3.0000, 0.0000, 0.0000, 0.0000)
    4 N..... COMMENT(\"a comment, with 1, 2 (numbers)\")
    5 N0010  USE_TOOL_LENGTH_OFFSET(0.0000 0.0000 7.5000, 0.0000 0.0000 0.0000, 0.0000 0.0000 0.0000)
    6 N0020  STRAIGHT_TRAVERSE(1.0000, 2.0000, 3.0000, 0.0000, 0.0000, 0.0000)
    7 N..... USE_LENGTH_UNITS(CANON_UNITS_INCHES)
    8 N..... STRAIGHT_FEED(1.0000, -1.0000, 0.5000, 0.0000, 0.0000, 0.0000)
    9 N..... SET_G92_OFFSET(0.1000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)
   10 N..... STRAIGHT_PROBE(0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)
   11 N..... DWELL(0.5000)
   12 N..... SELECT_TOOL(3)
   13 N..... CHANGE_TOOL(3)
   14 N..... PROGRAM_STOP()
   15 N..... OPTIONAL_PROGRAM_STOP()
   16 N..... PROGRAM_END()
";
        let c = parse(text).unwrap();
        assert_eq!(c.len(), 9, "{c:#?}");
        assert_eq!((c[0].seq, c[0].n), (6, Some(20)));
        assert!(matches!(
            c[0].event,
            Event::Move {
                kind: Kind::Traverse,
                ..
            }
        ));
        // 1 + 10 + 1, 2 + 20 + 2, 3 - 5 + 3 + 7.5
        assert!(close(end(&c[0]), [12.0, 24.0, 8.5]), "{:?}", c[0]);
        // Inches: 25.4, -25.4, 12.7 plus the offsets printed in mm before.
        assert!(matches!(
            c[1].event,
            Event::Move {
                kind: Kind::Feed,
                ..
            }
        ));
        assert!(close(end(&c[1]), [36.4, -3.4, 18.2]), "{:?}", c[1]);
        assert_eq!(c[1].n, None);
        // The G92 offset printed in inches: 2.54 mm.
        assert!(matches!(
            c[2].event,
            Event::Move {
                kind: Kind::Probe,
                ..
            }
        ));
        assert!(close(end(&c[2]), [12.54, 20.0, 2.5]), "{:?}", c[2]);
        let rest: Vec<Event> = c[3..].iter().map(|c| c.event).collect();
        assert_eq!(
            rest,
            [
                Event::Dwell { seconds: 0.5 },
                Event::SelectTool(3),
                Event::ChangeTool(3),
                Event::ProgramStop,
                Event::OptionalProgramStop,
                Event::ProgramEnd
            ]
        );
    }

    #[test]
    fn an_arc_in_each_plane() {
        let text = "\
    1 N..... USE_LENGTH_UNITS(CANON_UNITS_MM)
    2 N..... SET_G5X_OFFSET(1, 100.0000, 200.0000, 300.0000, 0.0000, 0.0000, 0.0000)
    3 N..... SELECT_PLANE(CANON_PLANE_XY)
    4 N..... ARC_FEED(1.0000, 2.0000, 3.0000, 4.0000, -2, 5.0000, 0.0000, 0.0000, 0.0000)
    5 N..... SELECT_PLANE(CANON_PLANE_XZ)
    6 N..... ARC_FEED(1.0000, 2.0000, 3.0000, 4.0000, 1, 5.0000, 0.0000, 0.0000, 0.0000)
    7 N..... SELECT_PLANE(CANON_PLANE_YZ)
    8 N..... USE_LENGTH_UNITS(CANON_UNITS_INCHES)
    9 N..... ARC_FEED(1.0000, 2.0000, 3.0000, 4.0000, -1, 5.0000, 0.0000, 0.0000, 0.0000)
";
        let c = parse(text).unwrap();
        let arcs: Vec<(Kind, [f64; 3])> = c
            .iter()
            .map(|c| match c.event {
                Event::Move { kind, end } => (kind, end),
                e => panic!("{e:?}"),
            })
            .collect();
        assert_eq!(arcs.len(), 3);
        // G17: first/second = X/Y, axis Z; CW two turns.
        assert_eq!(
            arcs[0].0,
            Kind::Arc {
                plane: Plane::XY,
                centre: [103.0, 204.0],
                ccw: false,
                turns: 2
            }
        );
        assert!(close(arcs[0].1, [101.0, 202.0, 305.0]));
        // G18: first/second = Z/X, axis Y; CCW.
        assert_eq!(
            arcs[1].0,
            Kind::Arc {
                plane: Plane::ZX,
                centre: [303.0, 104.0],
                ccw: true,
                turns: 1
            }
        );
        assert!(close(arcs[1].1, [102.0, 205.0, 301.0]));
        // G19: first/second = Y/Z, axis X; inches.
        let Kind::Arc {
            plane,
            centre,
            ccw,
            turns,
        } = arcs[2].0
        else {
            panic!("{:?}", arcs[2]);
        };
        assert_eq!((plane, ccw, turns), (Plane::YZ, false, 1));
        assert!((centre[0] - (200.0 + 76.2)).abs() < 1e-9, "{centre:?}");
        assert!((centre[1] - (300.0 + 101.6)).abs() < 1e-9, "{centre:?}");
        assert!(close(arcs[2].1, [227.0, 225.4, 350.8]), "{:?}", arcs[2].1);
    }

    #[test]
    fn garbage_is_an_error() {
        assert!(parse("    1 N..... STRAIGHT_FEED(1.0000, x, 3.0000)\n").is_err());
        assert!(parse("    1 N..... STRAIGHT_FEED(1.0000, 2.0000)\n").is_err());
        assert!(parse("hello\n").is_err());
    }

    #[test]
    fn only_exactly_zero_k_words_are_stripped() {
        assert_eq!(
            strip_zero_k("G2 X1 Y1 I1 J0 K0.000\nG3 X0 K-0.000 F5\n"),
            "G2 X1 Y1 I1 J0\nG3 X0 F5\n"
        );
        let kept = "G2 X1 K0.0005\nG2 X1 K0.001\nG2 K-1.000\nG19 G2 Y1 K0.5\n";
        assert_eq!(strip_zero_k(kept), kept);
    }
}
