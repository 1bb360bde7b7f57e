//! The scale benchmark (host): how the host simulation, the bound and the commands a user runs
//! grow with the program. For each program (the Fig. 1 cavity, the pocket, FreeCAD's 3D surface
//! job on its block, and finishing rasters of 1 000 to 35 000 blocks (any with `--blocks`) made by
//! `millac_qemu::evaluation::raster`): blocks, virtual cutting time, the wall time of each host
//! schedule on one thread (the programmed feeds, the AC, the bound, the safe constant feed) and
//! its ratio to real time; then the wall time and peak memory (the child's max RSS) of
//! `millac-qemu host` (its schedules on two threads) and `optimise`, and with `--run` of the
//! firmware under QEMU (`run`, programs up to 2 minutes of cutting: QEMU runs near real time).
//! Writes `out/scale/scale.svg` (wall time against blocks) and the table as markdown.
//!
//! ```text
//! cargo run -p millac-qemu --release --example scale_bench [-- --blocks 1000,3000,10000,35000] [--only NAME] [--run] [--no-commands]
//! ```
//!
//! Not a test: wall times depend on the machine (docs/dev/results-scale.md has this machine's).
use anyhow::{bail, Context, Result};
use millac::ac::AcSettings;
use millac::Settings;
use millac_qemu::analysis;
use millac_qemu::evaluation::{acreport, raster};
use millac_qemu::host::acsim::{self, Cut};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One program of the benchmark: its name, text and stock description (None: Fig. 1's blank).
struct Program {
    name: String,
    text: String,
    stock: Option<String>,
}

/// The measured figures of one program.
#[derive(Default)]
struct Measured {
    blocks: usize,
    virtual_s: f64,
    /// (schedule, wall s, its virtual s).
    schedules: Vec<(&'static str, f64, f64)>,
    /// (command, wall s, peak RSS MB).
    commands: Vec<(&'static str, f64, f64)>,
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut sizes = vec![1000, 3000, 10_000, 35_000];
    let (mut with_run, mut commands) = (false, true);
    let mut only: Option<String> = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--blocks" => {
                let v = it
                    .next()
                    .context("--blocks needs a list, e.g. 1000,10000")?;
                sizes = v
                    .split(',')
                    .map(|s| s.trim().parse::<usize>())
                    .collect::<Result<_, _>>()
                    .with_context(|| format!("--blocks {v}"))?;
            }
            "--run" => with_run = true,
            "--only" => {
                only = Some(
                    it.next()
                        .context("--only needs a part of a program's name")?
                        .clone(),
                )
            }
            "--no-commands" => commands = false,
            other => {
                bail!("unknown option {other} (--blocks LIST, --only NAME, --run, --no-commands)")
            }
        }
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = PathBuf::from("out/scale");
    std::fs::create_dir_all(&out)?;
    let read = |p: &str| std::fs::read_to_string(dir.join(p)).with_context(|| p.to_string());
    let mut programs = vec![
        Program {
            name: "Fig. 1 cavity".into(),
            text: read("programs/fig1-cavity.nc")?,
            stock: None,
        },
        Program {
            name: "pocket (Fig. 5.8)".into(),
            text: read("programs/pocket.nc")?,
            stock: Some(read("programs/pocket.stock")?),
        },
        Program {
            name: "FreeCAD 3D surface".into(),
            text: read("programs/cam/freecad/surface.nc")?,
            stock: Some(read("programs/cam/freecad/block.stock")?),
        },
    ];
    for &n in &sizes {
        let (text, stock) = raster::raster(n);
        programs.push(Program {
            name: format!("raster {n}"),
            text,
            stock: Some(stock),
        });
    }
    if let Some(o) = &only {
        programs.retain(|p| p.name.contains(o.as_str()));
    }
    let exe = millac_qemu_binary()?;
    println!("| program | blocks | cutting s | schedule | wall s | x real time |");
    println!("| --- | ---: | ---: | --- | ---: | ---: |");
    let mut all = Vec::new();
    for p in &programs {
        let m = measure(p, &out, commands.then_some(exe.as_path()), with_run)?;
        for (schedule, wall, virt) in &m.schedules {
            println!(
                "| {} | {} | {:.0} | {schedule} | {wall:.2} | {:.0} |",
                p.name,
                m.blocks,
                m.virtual_s,
                virt / wall
            );
        }
        all.push((p.name.clone(), m));
    }
    if commands {
        println!(
            "\n| program | blocks | cutting s | command | wall s | x real time | peak RSS MB |"
        );
        println!("| --- | ---: | ---: | --- | ---: | ---: | ---: |");
        for (name, m) in &all {
            for (command, wall, rss) in &m.commands {
                let ratio = m.virtual_s / wall;
                let digits = usize::from(ratio < 10.0);
                println!(
                    "| {name} | {} | {:.0} | {command} | {wall:.1} | {ratio:.digits$} | {rss:.0} |",
                    m.blocks, m.virtual_s,
                );
            }
        }
    }
    let svg = out.join("scale.svg");
    plot(&svg, &all)?;
    println!("\nwrote {}", svg.display());
    Ok(())
}

/// The host binary next to this example (`target/release/millac-qemu`), built if missing.
fn millac_qemu_binary() -> Result<PathBuf> {
    let me = std::env::current_exe()?;
    let bin = me
        .parent()
        .and_then(Path::parent)
        .context("the example's directory")?
        .join("millac-qemu");
    if !bin.exists() {
        let ok = std::process::Command::new(env!("CARGO"))
            .args([
                "build",
                "--release",
                "-p",
                "millac-qemu",
                "--bin",
                "millac-qemu",
            ])
            .status()?
            .success();
        if !ok {
            bail!("building millac-qemu failed");
        }
    }
    Ok(bin)
}

/// Times the schedules of `p` on this thread, then its commands as child processes.
fn measure(p: &Program, out: &Path, exe: Option<&Path>, with_run: bool) -> Result<Measured> {
    let s = Settings::default();
    let stock = match &p.stock {
        Some(src) => millac_plant::Stock::parse(src).map_err(|e| anyhow::anyhow!("{e:?}"))?,
        None => millac_plant::Stock::default(),
    };
    let cut = Cut::steel(stock, 1).at_program_rpm(&p.text, &s);
    let acs = AcSettings::default();
    let prog = analysis::load_program(&p.text, &s).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut m = Measured {
        blocks: prog.len(),
        ..Measured::default()
    };
    // Each schedule under a bar on a terminal (stderr; the bar's drawing is in its wall time,
    // as a user's is).
    let blocks = prog.len();
    let label = p.name.clone();
    let timed = |f: &mut dyn FnMut() -> Result<f64>| -> Result<(f64, f64)> {
        millac_qemu::progress::with_bar(&label, blocks, || {
            let t = Instant::now();
            let v = f()?;
            Ok((t.elapsed().as_secs_f64(), v))
        })
    };
    // Each run keeps its figures alone, as `host` and `optimise` run them.
    let record = acsim::Record::figures(f64::from(acs.optimal_fraction));
    let run = |prog: &[analysis::ProgBlock], ac| -> Result<f64> {
        Ok(acsim::run_recorded(prog, &s, &cut, ac, &[], record, None)?.machining_time_s)
    };
    let (w, v) = timed(&mut || run(&prog, None))?;
    m.virtual_s = v;
    m.schedules.push(("programmed feeds", w, v));
    let (w, v) = timed(&mut || run(&prog, Some(acs)))?;
    m.schedules.push(("AC (GPC)", w, v));
    let limits = acreport::bound_limits(&cut, &acs);
    let mut min_limit = f64::INFINITY;
    let (w, v) = timed(&mut || {
        // The frames on a thread of their own feeding the walk (as `host` runs it).
        let b = acreport::bound_summary(&prog, &s, &cut, &acs, &limits)?;
        min_limit = b.min_cut_limit_ipm;
        Ok(b.time_s)
    })?;
    m.schedules.push(("bound (oracle)", w, v));
    let ceilings = acreport::ceiling_blocks(&prog, &s, &acs);
    let safe = acsim::with_constant_feed(&ceilings, acreport::safe_feed(min_limit, &s), &s);
    let (w, v) = timed(&mut || run(&safe, None))?;
    m.schedules.push(("safe constant feed", w, v));
    let Some(exe) = exe else { return Ok(m) };
    // The commands, on files as a user has them.
    let slug: String = p
        .name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    let nc = out.join(format!("{slug}.nc"));
    std::fs::write(&nc, &p.text)?;
    let mut stock_args = Vec::new();
    if let Some(src) = &p.stock {
        let path = out.join(format!("{slug}.stock"));
        std::fs::write(&path, src)?;
        stock_args = vec!["--stock".to_string(), path.display().to_string()];
    }
    let nc = nc.display().to_string();
    let dir = |c: &str| out.join(format!("{slug}-{c}")).display().to_string();
    let mut cmds: Vec<(&'static str, Vec<String>)> = vec![
        (
            "host",
            vec!["host".into(), nc.clone(), "--out".into(), dir("host")],
        ),
        (
            "optimise",
            vec!["optimise".into(), nc.clone(), "--out".into(), dir("opt")],
        ),
    ];
    if with_run && m.virtual_s <= 120.0 {
        cmds.push((
            "run (QEMU)",
            vec!["run".into(), nc, "--out".into(), dir("run")],
        ));
    }
    for (name, mut a) in cmds {
        a.extend(stock_args.iter().cloned());
        let (wall, rss_mb) = run_child(exe, &a)?;
        m.commands.push((name, wall, rss_mb));
    }
    Ok(m)
}

/// Runs `exe --quiet args` and returns its wall time (s) and peak resident memory (MB, the
/// kernel's max RSS of the child).
fn run_child(exe: &Path, args: &[String]) -> Result<(f64, f64)> {
    let t = Instant::now();
    let child = std::process::Command::new(exe)
        .arg("--quiet")
        .args(args)
        .stdout(std::process::Stdio::null())
        .spawn()
        .with_context(|| format!("starting {}", exe.display()))?;
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: a zeroed rusage is a valid value for wait4 to fill; pid is our own child, reaped
    // here once (the Child is not waited on again).
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let r = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    if r != pid {
        bail!("waiting for {args:?}: {}", std::io::Error::last_os_error());
    }
    let wall = t.elapsed().as_secs_f64();
    if !(libc::WIFEXITED(status) && libc::WEXITSTATUS(status) == 0) {
        bail!("millac-qemu {args:?} failed (status {status})");
    }
    Ok((wall, usage.ru_maxrss as f64 / 1024.0))
}

/// Wall time against blocks, one line per schedule and command (the rasters; the other programs
/// as points).
fn plot(path: &Path, all: &[(String, Measured)]) -> Result<()> {
    use plotters::prelude::*;
    let root = SVGBackend::new(path, (900, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let max_blocks = all.iter().map(|(_, m)| m.blocks).max().unwrap_or(1) as f64;
    let max_wall = all
        .iter()
        .flat_map(|(_, m)| {
            let s = m.schedules.iter().map(|s| s.1);
            s.chain(
                m.commands
                    .iter()
                    .filter(|c| c.0 != "run (QEMU)")
                    .map(|c| c.1),
            )
        })
        .fold(0.0f64, f64::max);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "host wall time against program length (rasters; F10, 0.3 s of cutting per block)",
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..max_blocks * 1.05, 0.0..max_wall * 1.1)?;
    chart
        .configure_mesh()
        .x_desc("blocks")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .y_desc("wall time, s")
        .draw()?;
    let rasters: Vec<&Measured> = all
        .iter()
        .filter(|(n, _)| n.starts_with("raster"))
        .map(|(_, m)| m)
        .collect();
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for (k, _) in rasters
        .first()
        .map_or(&[][..], |m| &m.schedules[..])
        .iter()
        .enumerate()
    {
        let pts = rasters
            .iter()
            .map(|m| (m.blocks as f64, m.schedules[k].1))
            .collect();
        series.push((format!("{} (one thread)", rasters[0].schedules[k].0), pts));
    }
    for (k, c) in rasters
        .first()
        .map_or(&[][..], |m| &m.commands[..])
        .iter()
        .enumerate()
    {
        if c.0 == "run (QEMU)" {
            continue;
        }
        let pts = rasters
            .iter()
            .filter_map(|m| m.commands.get(k).map(|c| (m.blocks as f64, c.1)))
            .collect();
        series.push((format!("millac-qemu {}", c.0), pts));
    }
    for (i, (label, pts)) in series.into_iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))?
            .label(label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], colour.stroke_width(2)));
        chart.draw_series(pts.into_iter().map(|p| Circle::new(p, 3, colour.filled())))?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
