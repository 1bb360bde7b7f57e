//! The AC's alarm corpus (host): ordinary cuts that must run to their end with no alarm, and
//! the sensor faults of [`crate::host::fault`] injected into some of them, each of which must hold the
//! machine with a sensor alarm within its bound. Both sides are measured on the host simulation
//! (the firmware's own AC task and sampler, [`crate::host::acsim`]) with the default AC settings and the
//! breakage monitor on. The `alarm_table` example prints the table of docs/dev/results-ac.md; `qemu/tests/alarms.rs`
//! asserts it.
//!
//! The corpus: every program in `qemu/programs` (on its `.stock`, with its `.tools` for its M6s; `hidden-boss` on the stock as
//! it really is), and cuts written here as CAM writes them, on the Fig. 1 blank (X 0..5 in,
//! Y 0..3 in, top Z0, the start hole at X1.25 Y1.5): plunges and ramps at several feeds, slot
//! entries from outside the blank, shallow face cuts 0.1..1 mm deep in mm and in inch, side cuts
//! along the blank's edge at 5..100 % immersion, a square pocket spiralling out from the start
//! hole (inside corners), and a 3D raster over a curved surface (Z down and up in every row).
//!
//! A fault starts at a time the program cuts steadily (the peak torque of every AC period of the
//! run without the fault above a tenth of T0 for the 100 ms before and the 200 ms after, and Z
//! not feeding down): a transducer reading half the force is a fault of side milling, which is
//! what the band can judge (see `millac::ac::plaus`); at a plunge's end face force against
//! torque says nothing, and below the band's floor (5 N*m) neither does a light cut.
use crate::analysis;
use crate::host::acsim::{self, Cut, HostRun};
use crate::host::fault::{Fault, FaultKind};
use anyhow::{Context, Result};
use millac::ac::{AcSettings, Alarm};
use millac::Settings;
use millac_plant::Stock;
use std::path::Path;

/// One program of the corpus, with the stock it cuts.
pub struct Program {
    pub name: String,
    pub text: String,
    pub stock: Stock,
    /// The machine's tool table for its M6s (`<stem>.tools` beside it; else empty).
    pub tools: millac::gcode::tools::ToolTable,
}

/// The programs the faults are injected into (names in [`corpus`]).
pub const FAULTED: [&str; 6] = [
    "fig1-cavity.nc",
    "pocket.nc",
    "slot entry 0.2 in F20",
    "side 50 % 0.2 in F20",
    "face 2 mm plunged F1000 (mm)",
    "3D raster 0.2 in step-over",
];

/// Fault starts per faulted program (each with every kind).
pub const TIMES_PER_PROGRAM: usize = 3;

/// The indices in `corpus` of [`FAULTED`].
pub fn faulted(corpus: &[Program]) -> Result<Vec<usize>> {
    indices(corpus, &FAULTED)
}

/// Every (program index, fault) to inject: each kind at [`TIMES_PER_PROGRAM`] steady times of
/// each faulted program's run without a fault (`base`: (index, its outcome)).
pub fn fault_cases(base: &[(usize, &Outcome)]) -> Vec<(usize, Fault)> {
    let mut cases = Vec::new();
    for &(i, o) in base {
        for at_s in fault_times(o, TIMES_PER_PROGRAM) {
            for kind in FaultKind::ALL {
                cases.push((i, Fault { kind, at_s }));
            }
        }
    }
    cases
}

/// The programs the faults are also injected into while the tool feeds down (names in
/// [`corpus`]): every kind but `gain` (a transducer reading half the force is not seen at an end
/// face, which makes torque without force; it is caught once the cut loads the side).
pub const PLUNGED: [&str; 2] = ["plunge 0.25 in F5", "ramp 7 deg F10"];

/// The indices in `corpus` of `names`.
pub fn indices(corpus: &[Program], names: &[&str]) -> Result<Vec<usize>> {
    names
        .iter()
        .map(|name| {
            corpus
                .iter()
                .position(|p| p.name == *name)
                .ok_or_else(|| anyhow::anyhow!("{name}: not in the corpus"))
        })
        .collect()
}

/// Every (program index, fault) to inject while Z feeds down: each kind but `gain` at a half and
/// three quarters of each program's first block that moves Z down (`base`: (index, its outcome)).
pub fn plunge_cases(base: &[(usize, &Outcome)]) -> Vec<(usize, Fault)> {
    let mut cases = Vec::new();
    for &(i, o) in base {
        let Some(&(_, start, end)) = o.run.spans.iter().find(|s| block_feeds_down(&o.run, s.0))
        else {
            continue;
        };
        for share in [0.5, 0.75] {
            let t = start as f64 + share * (end - start) as f64;
            let at_s = (t * 1e-6).round() / 1000.0;
            for kind in FaultKind::ALL.into_iter().filter(|&k| k != FaultKind::Gain) {
                cases.push((i, Fault { kind, at_s }));
            }
        }
    }
    cases
}

/// `f` over `items` on every core, results in order (the host simulation is single-threaded).
pub fn parallel<T: Sync, R: Send>(
    items: &[T],
    f: impl Fn(&T) -> Result<R> + Sync,
) -> Result<Vec<R>> {
    let n = std::thread::available_parallelism().map_or(1, |n| n.get());
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut out: Vec<(usize, Result<R>)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..n)
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(item) = items.get(i) else { break };
                        mine.push((i, f(item)));
                    }
                    mine
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("a corpus run panicked"))
            .collect()
    });
    out.sort_by_key(|(i, _)| *i);
    out.into_iter().map(|(_, r)| r).collect()
}

/// The corpus's AC settings: the defaults with the breakage monitor on (at the cut's flutes and
/// spindle speed, as `millac host --monitor-breakage` sets them).
pub fn settings(cut: &Cut) -> AcSettings {
    AcSettings {
        breakage: millac::ac::Breakage::On,
        flutes: cut.tool.flutes,
        monitor_rpm: cut.spindle_rpm.round() as u32,
        ..AcSettings::default()
    }
}

/// The bound on fault-to-hold (ms) of each kind: the period the fault is seen in and one more
/// (rail, spike, dropout), plus the check's own count (`frozen_samples` samples, `ft_periods`
/// periods) for frozen and gain. As `qemu/tests/faults.rs` asserts under QEMU.
pub fn bound_ms(kind: FaultKind, ac: &AcSettings) -> f64 {
    let period = f64::from(ac.period_ms);
    let per_sample = 1000.0 / f64::from(ac.sample_hz);
    match kind {
        FaultKind::Rail | FaultKind::Spike | FaultKind::Dropout => 2.0 * period,
        FaultKind::Frozen => f64::from(ac.frozen_samples) * per_sample + 2.0 * period,
        FaultKind::Gain => f64::from(ac.ft_periods) * period + 2.0 * period,
    }
}

/// Whether `alarm` is the one `kind` should raise: a sensor alarm (a jump or a stuck channel for
/// rail and spike, no samples for dropout, frozen for frozen, force against torque for gain).
pub fn expected(kind: FaultKind, alarm: &Alarm) -> bool {
    use millac::ac::SensorFault as S;
    match kind {
        FaultKind::Rail | FaultKind::Spike => {
            matches!(alarm, Alarm::Sensor(S::Jump { .. } | S::Stuck { .. }))
        }
        FaultKind::Dropout => matches!(alarm, Alarm::NoSamples),
        FaultKind::Frozen => matches!(alarm, Alarm::Sensor(S::Frozen { .. })),
        FaultKind::Gain => matches!(alarm, Alarm::ForceTorqueMismatch { .. }),
    }
}

const HEAD_IN: &str = "G20 G90 G17 G94\nS600 M3\n";
const HEAD_MM: &str = "G21 G90 G17 G94\nS600 M3\n";
const TAIL: &str = "M5\nM30\n";

/// The programs written here (see the module docs), with the default stock.
pub fn generated() -> Vec<(String, String)> {
    let mut v = Vec::new();
    // Plunges into the solid blank, away from the start hole.
    for f in [2, 5, 10] {
        v.push((
            format!("plunge 0.25 in F{f}"),
            format!("{HEAD_IN}G0 X3 Y1.5 Z0.1\nG1 Z-0.25 F{f}\nG0 Z0.1\n{TAIL}"),
        ));
    }
    // Ramps down into the blank along X (about 7 degrees), then back along the ramp's floor.
    for f in [5, 10, 20] {
        v.push((
            format!("ramp 7 deg F{f}"),
            format!("{HEAD_IN}G0 X0.5 Y1 Z0.05\nG1 X2.5 Z-0.2 F{f}\nG1 X0.5\nG0 Z0.1\n{TAIL}"),
        ));
    }
    // Slots entered from outside the blank.
    for f in [10, 20, 30] {
        v.push((
            format!("slot entry 0.2 in F{f}"),
            format!("{HEAD_IN}G0 X-0.5 Y2.2\nG0 Z-0.2\nG1 X2.5 F{f}\nG0 Z0.1\n{TAIL}"),
        ));
    }
    // Shallow face cuts: a zig-zag of three rows at 60 % step-over from outside the blank.
    for d in [0.1, 0.25, 0.5, 1.0] {
        let step = 0.6 * 12.7;
        let mut s = format!("{HEAD_MM}G0 X-10 Y3 Z5\nG0 Z-{d}\n");
        for row in 0..3 {
            let y = 3.0 + step * f64::from(row);
            let x = if row % 2 == 0 { 60 } else { -10 };
            s += &format!("G1 Y{y:.2} F500\nG1 X{x}\n");
        }
        s += &format!("G0 Z5\n{TAIL}");
        v.push((format!("face {d} mm (mm)"), s));
        let d_in = d / 25.4;
        let step_in = 0.6 * 0.5;
        let mut s = format!("{HEAD_IN}G0 X-0.4 Y0.12 Z0.2\nG0 Z-{d_in:.4}\n");
        for row in 0..3 {
            let y = 0.12 + step_in * f64::from(row);
            let x = if row % 2 == 0 { 2.4 } else { -0.4 };
            s += &format!("G1 Y{y:.4} F20\nG1 X{x}\n");
        }
        s += &format!("G0 Z0.2\n{TAIL}");
        v.push((format!("face {d_in:.4} in (inch)"), s));
    }
    // The same at 0.25 mm, 1 mm and 2 mm in mm as a hand-written job does it: plunged inside the
    // blank, then rows at F1000 and 60 % step-over.
    for d in [0.25, 1.0, 2.0] {
        let mut s = format!("{HEAD_MM}G0 X12 Y12 Z5\nG1 Z-{d} F100\n");
        for row in 0..4 {
            let y = 12.0 + 7.6 * f64::from(row);
            let x = if row % 2 == 0 { 110 } else { 12 };
            s += &format!("G1 Y{y:.1} F1000\nG1 X{x}\n");
        }
        s += &format!("G0 Z5\n{TAIL}");
        v.push((format!("face {d} mm plunged F1000 (mm)"), s));
    }
    // Side cuts along the blank's Y0 edge at 0.2 in deep: the tool's centre at ae - R.
    for p in [5, 25, 50, 75, 100] {
        let y = f64::from(p) / 100.0 * 0.5 - 0.25;
        v.push((
            format!("side {p} % 0.2 in F20"),
            format!("{HEAD_IN}G0 X-0.5 Y{y:.4}\nG0 Z-0.2\nG1 X3 F20\nG0 Z0.1\n{TAIL}"),
        ));
    }
    // A square pocket 0.15 in deep spiralling out from the start hole at 50 % step-over: every
    // ring turns four inside corners.
    {
        let (cx, cy) = (1.25, 1.5);
        let mut s = format!("{HEAD_IN}G0 X{cx} Y{cy} Z0.1\nG1 Z-0.15 F10\n");
        for ring in 1..=3 {
            let h = 0.25 * f64::from(ring);
            s += &format!(
                "G1 X{:.3} F20\nG1 Y{:.3}\nG1 X{:.3}\nG1 Y{:.3}\nG1 X{:.3}\nG1 Y{cy:.3}\n",
                cx + h,
                cy + h,
                cx - h,
                cy - h,
                cx + h,
            );
        }
        s += &format!("G0 Z0.1\n{TAIL}");
        v.push(("pocket corners 0.15 in".into(), s));
    }
    // A 3D raster: rows along X over Z = -0.05 - 0.15 sin(pi (x - 0.5) / 4), 0.1 in segments,
    // 0.2 in step-over, from outside the blank.
    {
        let mut s = format!("{HEAD_IN}G0 X0.1 Y0.4 Z0.1\n");
        for row in 0..4 {
            let y = 0.4 + 0.2 * f64::from(row);
            let xs: Vec<f64> = (0..=40).map(|k| 0.5 + 0.1 * f64::from(k)).collect();
            let xs: Vec<f64> = if row % 2 == 0 {
                xs
            } else {
                xs.into_iter().rev().collect()
            };
            s += &format!("G0 Y{y:.3}\n");
            for (k, x) in xs.iter().enumerate() {
                let z = -0.05 - 0.15 * (std::f64::consts::PI * (x - 0.5) / 4.0).sin();
                let f = if k == 0 { " F20" } else { "" };
                s += &format!("G1 X{x:.3} Z{z:.4}{f}\n");
            }
            s += "G0 Z0.1\n";
            let next = if row % 2 == 0 { 4.5 } else { 0.5 };
            s += &format!("G0 X{next:.3}\n");
        }
        s += TAIL;
        v.push(("3D raster 0.2 in step-over".into(), s));
    }
    v
}

/// The whole corpus: `qemu/programs` (read from `dir`) and [`generated`].
pub fn corpus(dir: &Path) -> Result<Vec<Program>> {
    let mut v = Vec::new();
    let mut names: Vec<_> = std::fs::read_dir(dir)
        .with_context(|| format!("reading {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "nc"))
        .collect();
    names.sort();
    for p in names {
        let text =
            std::fs::read_to_string(&p).with_context(|| format!("reading {}", p.display()))?;
        let stem = p
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .to_string();
        let stock = [".stock", ".actual.stock"]
            .iter()
            .map(|e| dir.join(format!("{stem}{e}")))
            .find(|s| s.exists());
        let stock = match stock {
            Some(s) => acsim::load_stock(&s)?,
            None => Stock::default(),
        };
        let tools = dir.join(format!("{stem}.tools"));
        let tools = if tools.exists() {
            acsim::load_tools(&tools)?
        } else {
            Default::default()
        };
        v.push(Program {
            name: format!("{stem}.nc"),
            text,
            stock,
            tools,
        });
    }
    for (name, text) in generated() {
        v.push(Program {
            name,
            text,
            stock: Stock::default(),
            tools: Default::default(),
        });
    }
    Ok(v)
}

/// One run of a corpus program, with or without a fault.
pub struct Outcome {
    pub run: HostRun,
    pub ac: AcSettings,
    /// The program's blocks (the run completed when it did them all).
    pub blocks: usize,
}

/// Runs `p` on the host simulation with the corpus settings and `faults`.
pub fn run(p: &Program, faults: &[Fault]) -> Result<Outcome> {
    let s = Settings::default();
    let prog =
        analysis::load_program(&p.text, &s).map_err(|e| anyhow::anyhow!("{}: {e}", p.name))?;
    let cut = Cut::steel(p.stock.clone(), 1)
        .at_program_rpm(&p.text, &s)
        .with_tool_changes(&p.text, &s, &p.tools);
    let ac = settings(&cut);
    let run = acsim::run_with_faults(&prog, &s, &cut, Some(ac), true, faults)
        .with_context(|| p.name.clone())?;
    Ok(Outcome {
        run,
        ac,
        blocks: prog.len(),
    })
}

/// Times (s) at which a fault starts in a steadily cutting stretch of `o` (see the module docs):
/// up to `n`, spread over the program's steady stretches.
pub fn fault_times(o: &Outcome, n: usize) -> Vec<f64> {
    let t0 = f64::from(o.ac.t0_nm());
    let rows = &o.run.rows;
    let per_s = f64::from(o.ac.period_ms) / 1000.0;
    let (before, after) = ((0.1 / per_s) as usize, (0.2 / per_s) as usize);
    let down = z_down_times(&o.run);
    let steady: Vec<usize> = (before..rows.len().saturating_sub(after))
        .filter(|&r| {
            rows[r - before..r + after]
                .iter()
                .all(|row| row.t_true_nm.abs() > 0.1 * t0)
                && !down(rows[r].t_ms as f64 / 1000.0)
        })
        .collect();
    if steady.is_empty() || n == 0 {
        return Vec::new();
    }
    (0..n)
        .map(|k| {
            let r = steady[(steady.len() * (2 * k + 1)) / (2 * n)];
            // 3 ms into the period after the row's (a sample's nominal time, see `crate::host::fault`).
            (rows[r].t_ms + 3) as f64 / 1000.0
        })
        .collect()
}

/// Whether Z fed down within 0.3 s around a time (s) of the run's path.
fn z_down_times(run: &HostRun) -> impl Fn(f64) -> bool + '_ {
    move |t: f64| {
        run.spans.iter().any(|&(i, start, end)| {
            let (a, b) = (start as f64 * 1e-9 - 0.3, end as f64 * 1e-9 + 0.3);
            t >= a && t <= b && block_feeds_down(run, i)
        })
    }
}

/// Whether block `i` of the run moved Z down (from its path).
fn block_feeds_down(run: &HostRun, i: usize) -> bool {
    let mut zs = run.path.iter().filter(|p| p.2 == i).map(|p| p.0[2]);
    match zs.next() {
        Some(first) => zs.any(|z| z < first),
        None => false,
    }
}

/// Whether the alarm of a run without a fault was earned: an overload hold where the true force
/// or torque did cross the overload hold's level ((1 - `overload_e`) F0 or T0) at some sample.
/// Every other alarm of an ordinary cut is a false one.
pub fn false_alarm(o: &Outcome) -> bool {
    let k = f64::from(1.0 - o.ac.overload_e);
    let (f, t) = (k * f64::from(o.ac.f0_n()), k * f64::from(o.ac.t0_nm()));
    match o.run.alarm {
        None => false,
        Some(Alarm::Overload { .. }) => !o.run.samples.iter().any(|s| s.0 > f || s.1.abs() > t),
        Some(_) => true,
    }
}

/// A fault run's verdict.
pub struct Detection {
    pub alarm: Option<Alarm>,
    /// Fault to hold, ms (None: no hold).
    pub to_hold_ms: Option<f64>,
    pub bound_ms: f64,
    pub ok: bool,
}

/// Injects `fault` into `p` and judges the hold.
pub fn detect(p: &Program, fault: Fault) -> Result<Detection> {
    let o = run(p, &[fault])?;
    let to_hold_ms = o
        .run
        .hold_ns
        .map(|ns| (ns as f64 * 1e-9 - fault.at_s) * 1e3);
    let bound = bound_ms(fault.kind, &o.ac);
    let ok = matches!((o.run.alarm, to_hold_ms), (Some(a), Some(t)) if expected(fault.kind, &a) && t >= 0.0 && t <= bound);
    Ok(Detection {
        alarm: o.run.alarm,
        to_hold_ms,
        bound_ms: bound,
        ok,
    })
}

/// The ALARM code of an alarm (as the firmware reports it), or "-".
pub fn code(a: Option<&Alarm>) -> String {
    a.map_or_else(
        || "-".into(),
        |a| millac::protocol::codes::ac_alarm(a).to_string(),
    )
}
