//! A differential test of millac's G-code reading against LinuxCNC's interpreter rs274 (host: the
//! test harness runs it; rs274 is extracted under the workspace's target/rs274 on first use).
//! Every program of the corpus (qemu/programs/*.nc, millac's own, and qemu/programs/cam/**) is
//! read by millac line by line as `check` reads it (`analysis::read_lines`, blocks integrated by
//! `analysis::program_of_blocks`) and by rs274; the motions must agree: the same end points
//! (machine coordinates, within 1 BLU per axis), the same kinds (traverse = Rapid, feed = Linear,
//! arc = Arc with the same direction and centre within 1 BLU), in the same order, both exhausted
//! at the end. rs274 prints moves that do not move (a traverse to where the tool is); millac queues
//! no block below one BLU, so such a move is skipped (see [`compare`]). A program millac refuses lines of is not
//! compared; its refusals must all be of the constructs [`KNOWN_REFUSALS`] lists.
use millac::nc::{Motion, Plane};
use millac::Settings;
use millac_qemu::analysis::{program_of_blocks, read_lines};
use millac_qemu::emulator::firmware::workspace;
use millac_qemu::emulator::tools::ensure_rs274;
use millac_qemu::host::rs274::{self, Event, Kind};
use std::path::{Path, PathBuf};

/// The constructs millac refuses today that the corpus uses (a refusal must contain one of them),
/// with the programs that use them. The list shrinks as the dialect grows: remove an entry when
/// millac accepts the construct.
const KNOWN_REFUSALS: &[&str] = &[
    // cam/linuxcnc/skeleton.ngc: `G4 P...` on a line with an axis move
    "G4 cannot be combined with an axis move",
    // cam/linuxcnc/hole-circle.ngc: `^60` (LinuxCNC's polar coordinates)
    "polar coordinates (@ radius, ^ angle) are not supported",
];

/// The tool table rs274 reads (its format; values in inches even for mm programs): tools 1 to 20
/// of length 0, as millac's table starts (a program's `T1 M6 G43 H1` moves nothing in either; a
/// program that sets lengths with G10 L1 sets them in both).
fn tool_table() -> String {
    (1..=20)
        .map(|t| format!("T{t} P{t} Z0 D0.125 ;length 0\n"))
        .collect()
}

/// Tolerance of an end point or centre per axis, in BLU, plus the floating-point noise of
/// inch -> mm -> BLU. An inch program's value half-way between two BLU is 1 BLU apart: cds.ngc's
/// Z1.53125 is 1.5312 in rs274's output (it prints 0.0001 in, rounding half to even) and 15313
/// BLU in millac, a difference a hair above 1 in floating point.
///
/// An R-format arc's centre is found from the end points and R: millac's from them in BLU, rs274's
/// from the programmed values, which differ by more than a BLU when the chord is short against R
/// (arcspiral.ngc: R2 in, 0.2 in chords, centres 4-5 BLU apart, as the same formula on the BLU
/// values gives). That program is refused for G64 today; when it is compared, this is what it will
/// show.
const TOLERANCE_BLU: f64 = 1.0 + 1e-6;

/// A millac motion block: its kind, end point (machine BLU) and, for an arc, its centre (BLU on
/// the plane's two axes) and direction.
#[derive(Clone, Copy, Debug)]
enum MillacKind {
    Rapid,
    Linear,
    Arc {
        plane: Plane,
        centre: [i32; 2],
        ccw: bool,
    },
}

/// The motion blocks of `text` as millac reads it, and its refusals' messages.
fn millac_moves(text: &[u8], settings: &Settings) -> (Vec<(MillacKind, [i32; 3])>, Vec<String>) {
    let reading = read_lines(text, settings);
    let moves = program_of_blocks(reading.blocks)
        .into_iter()
        .filter_map(|b| {
            let kind = match b.block.motion {
                Motion::Rapid(_) => MillacKind::Rapid,
                Motion::Linear(_) => MillacKind::Linear,
                Motion::Arc(a) => {
                    let (i, j) = a.plane.axes();
                    MillacKind::Arc {
                        plane: a.plane,
                        centre: [b.start[i] - a.start[0], b.start[j] - a.start[1]],
                        ccw: a.ccw,
                    }
                }
                Motion::Dwell(_) => return None,
            };
            Some((kind, b.end))
        })
        .collect();
    (
        moves,
        reading.refused.into_iter().map(|r| r.message).collect(),
    )
}

/// The corpus: qemu/programs/*.nc and every .nc/.ngc under qemu/programs/cam, sorted.
fn corpus() -> Vec<PathBuf> {
    fn walk(dir: &Path, deep: bool, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                if deep {
                    walk(&p, deep, out);
                }
            } else if matches!(p.extension().and_then(|e| e.to_str()), Some("nc" | "ngc")) {
                out.push(p);
            }
        }
    }
    let programs = Path::new(env!("CARGO_MANIFEST_DIR")).join("programs");
    let mut out = Vec::new();
    walk(&programs, false, &mut out);
    out.retain(|p| p.extension().and_then(|e| e.to_str()) == Some("nc"));
    walk(&programs.join("cam"), true, &mut out);
    out.sort();
    out
}

/// What one program's comparison found.
struct Outcome {
    blocks: usize,
    moves: usize,
    max_dev_blu: f64,
    /// Where the largest deviation was.
    worst: String,
    refusals: Vec<String>,
    compared: bool,
    /// The first disagreement (the program, the move, both sides), if any.
    failure: Option<String>,
}

/// Compares rs274's moves with millac's blocks (see the module's note).
/// The centre's distance (BLU) when millac's arc `mk` is in rs274's arc `kind`'s plane and
/// direction; `None` when it is not, or its centre is more than the tolerance away.
fn same_arc(kind: Kind, mk: MillacKind, blu_per_mm: f64) -> Option<f64> {
    match (kind, mk) {
        (
            Kind::Arc {
                plane, centre, ccw, ..
            },
            MillacKind::Arc {
                plane: mp,
                centre: mc,
                ccw: mccw,
            },
        ) if plane == mp && ccw == mccw => {
            let c = centre.map(|v| v * blu_per_mm);
            let d = (c[0] - mc[0] as f64).abs().max((c[1] - mc[1] as f64).abs());
            (d <= TOLERANCE_BLU).then_some(d)
        }
        _ => None,
    }
}

fn compare(
    name: &str,
    canon: &[rs274::Canon],
    millac: &[(MillacKind, [i32; 3])],
    blu_per_mm: f64,
) -> (f64, String, Option<String>) {
    let to_blu = |mm: [f64; 3]| mm.map(|v| v * blu_per_mm);
    let dev3 = |a: [f64; 3], b: [i32; 3]| {
        (0..3)
            .map(|k| (a[k] - b[k] as f64).abs())
            .fold(0.0, f64::max)
    };
    let mut pos = [0i32; 3];
    // rs274's previous end point (BLU); both start at the machine origin.
    let mut prev = [0.0f64; 3];
    let mut next = 0usize;
    let mut max_dev = 0.0f64;
    let mut worst = String::new();
    let moves = canon.iter().filter_map(|c| match c.event {
        Event::Move { kind, end } => Some((c, kind, end)),
        _ => None,
    });
    for (number, (c, kind, end_mm)) in moves.enumerate() {
        let end = to_blu(end_mm);
        let what = match kind {
            Kind::Arc {
                plane,
                centre,
                ccw,
                turns,
            } => format!(
                "Arc {{ plane: {plane:?}, centre: {:.2?} BLU, ccw: {ccw}, turns: {turns} }}",
                centre.map(|v| v * blu_per_mm)
            ),
            k => format!("{k:?}"),
        };
        let here = format!(
            "{name}: rs274 move {} (its output line {}{}) {what} to {end:.2?} BLU ({end_mm:.4?} mm)",
            number + 1,
            c.seq,
            c.n.map(|n| format!(", N{n}")).unwrap_or_default()
        );
        // An arc of P turns: millac makes P - 1 full circles about the same centre first (one
        // block each), then the programmed arc; rs274 prints one move with its turns.
        let mut circles = 0;
        if let Kind::Arc { turns, .. } = kind {
            while circles + 1 < turns as usize
                && millac
                    .get(next + circles)
                    .is_some_and(|&(mk, _)| same_arc(kind, mk, blu_per_mm).is_some())
            {
                circles += 1;
            }
        }
        // The next millac block when it is this move (kind, end, centre).
        let matched = millac.get(next + circles).and_then(|&(mk, mend)| {
            let d = dev3(end, mend);
            let centre_dev = match (kind, mk) {
                (Kind::Traverse, MillacKind::Rapid) | (Kind::Feed, MillacKind::Linear) => 0.0,
                _ => same_arc(kind, mk, blu_per_mm)?,
            };
            (d <= TOLERANCE_BLU && centre_dev <= TOLERANCE_BLU).then_some(d.max(centre_dev))
        });
        // A move that does not move: rs274 prints it, millac queues no block for it. Its end
        // rounds to millac's position, or it ends where rs274's previous move ended (rs274 did
        // not move) within the tolerance of millac's position. A full circle ends where it
        // starts: an arc that is the next millac block is never skipped.
        let rounds_here = (0..3).all(|k| end[k].round() as i64 == pos[k] as i64);
        let rs_still = (0..3).all(|k| (end[k] - prev[k]).abs() < 1e-6);
        let still = rounds_here || (rs_still && dev3(end, pos) <= TOLERANCE_BLU);
        prev = end;
        let full_circle = matches!(kind, Kind::Arc { .. })
            && matches!(millac.get(next + circles), Some((MillacKind::Arc { .. }, e)) if dev3(end, *e) <= TOLERANCE_BLU);
        if still && !full_circle {
            continue;
        }
        if let Some(d) = matched {
            if d > max_dev {
                max_dev = d;
                if d >= 0.01 {
                    worst = format!(" (at rs274 move {}, millac block {})", number + 1, next + 1);
                }
            }
            next += circles;
            pos = millac[next].1;
            next += 1;
            continue;
        }
        let theirs = match millac.get(next) {
            Some((mk, mend)) => format!("millac block {} {mk:?} to {mend:?} BLU", next + 1),
            None => format!("millac has no block left ({} blocks)", millac.len()),
        };
        return (
            max_dev,
            worst,
            Some(format!("{here}, from {pos:?} BLU; {theirs}")),
        );
    }
    if next < millac.len() {
        let (mk, mend) = millac[next];
        return (
            max_dev,
            worst,
            Some(format!(
                "{name}: rs274's moves are exhausted, millac has {} blocks more, the first: block {} \
                 {mk:?} to {mend:?} BLU",
                millac.len() - next,
                next + 1
            )),
        );
    }
    (max_dev, worst, None)
}

fn check_program(path: &Path, rs: &millac_qemu::emulator::tools::Rs274) -> Outcome {
    let settings = Settings::default();
    let (num, den) = settings.blu.per_mm();
    let blu_per_mm = num as f64 / den as f64;
    let name = path
        .strip_prefix(Path::new(env!("CARGO_MANIFEST_DIR")).join("programs"))
        .unwrap_or(path)
        .display()
        .to_string();
    let text = std::fs::read(path).unwrap();
    let (millac, refusals) = millac_moves(&text, &settings);
    let mut out = Outcome {
        blocks: millac.len(),
        moves: 0,
        max_dev_blu: 0.0,
        worst: String::new(),
        refusals,
        compared: false,
        failure: None,
    };
    let canon = match rs274::run(rs, &String::from_utf8_lossy(&text), Some(&tool_table())) {
        Ok(c) => c,
        Err(e) => {
            out.failure = Some(format!("{name}: {e:#}"));
            return out;
        }
    };
    out.moves = canon
        .iter()
        .filter(|c| matches!(c.event, Event::Move { .. }))
        .count();
    if !out.refusals.is_empty() {
        let unknown: Vec<&String> = out
            .refusals
            .iter()
            .filter(|m| !KNOWN_REFUSALS.iter().any(|k| m.contains(k)))
            .collect();
        if !unknown.is_empty() {
            out.failure = Some(format!(
                "{name}: millac refuses lines for constructs not in KNOWN_REFUSALS: {unknown:?}"
            ));
        }
        return out;
    }
    out.compared = true;
    let (dev, worst, failure) = compare(&name, &canon, &millac, blu_per_mm);
    out.max_dev_blu = dev;
    out.worst = worst;
    out.failure = failure;
    out
}

#[test]
fn millac_reads_the_corpus_as_linuxcnc_does() {
    let rs = ensure_rs274(&workspace().join("target").join("rs274")).expect("rs274");
    let programs = corpus();
    assert!(
        programs.len() > 10,
        "the corpus is missing programs: {programs:?}"
    );
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("programs");
    let mut failures = Vec::new();
    let mut compared = 0;
    for p in &programs {
        let o = check_program(p, &rs);
        let name = p.strip_prefix(&root).unwrap_or(p).display();
        let refusals = if o.refusals.is_empty() {
            "none".to_string()
        } else {
            let mut kinds: Vec<&str> = KNOWN_REFUSALS
                .iter()
                .copied()
                .filter(|k| o.refusals.iter().any(|m| m.contains(k)))
                .collect();
            kinds.dedup();
            format!("{} ({}; not compared)", o.refusals.len(), kinds.join(", "))
        };
        println!(
            "rs274: {name}: {} millac blocks, {} rs274 moves, max deviation {:.3} BLU{}, refusals {refusals}{}",
            o.blocks,
            o.moves,
            o.max_dev_blu,
            o.worst,
            if o.failure.is_some() { ", DIFFERS" } else { "" }
        );
        compared += o.compared as usize;
        if let Some(f) = o.failure {
            failures.push(f);
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} programs differ:\n{}",
        failures.len(),
        programs.len(),
        failures.join("\n")
    );
    assert!(compared > 0, "no program was compared");
}
