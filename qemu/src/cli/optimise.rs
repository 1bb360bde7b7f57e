//! `millac-qemu optimise PROGRAM --out OUT`: a program's feeds optimised offline by virtual
//! machining, no QEMU (host: the CLI calls it from `main`).
use super::args::{parse_tool, MaterialArg};
use anyhow::{Context, Result};
use millac::Settings;
use millac_qemu::analysis;
use std::path::{Path, PathBuf};

/// `optimise`'s options.
#[derive(clap::Args)]
pub(crate) struct OptimiseArgs {
    pub(crate) program: PathBuf,
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// Stock description file (default: the Fig. 1 die blank with its drilled start hole).
    #[arg(long)]
    pub(crate) stock: Option<PathBuf>,
    /// The cutter: DIAMETER_MM,FLUTES[,F_MAX_N[,T_MAX_NM]] (default: the 0.5 in 4-flute end
    /// mill, 4000 N, 80 N*m).
    #[arg(long, value_name = "D_MM,Z[,F_MAX_N[,T_MAX_NM]]", value_parser = parse_tool)]
    pub(crate) tool: Option<millac_plant::Tool>,
    /// The machine's tool table for the program's M6s (`$T` lines, as `run --tools`): each
    /// tool's part is planned with its own limits, flutes and speed, and the M6s are kept.
    #[arg(long, value_name = "FILE")]
    pub(crate) tools: Option<PathBuf>,
    /// The workpiece material.
    #[arg(long, value_enum, default_value = "steel")]
    pub(crate) material: MaterialArg,
    /// F0 and T0 as a fraction of the cutter's permissible force and torque (the AC's $256).
    #[arg(long, default_value_t = 0.9)]
    pub(crate) fraction: f64,
    /// Feed of the pieces that cut nothing, ipm [default: FRM, the machine's fastest feed].
    #[arg(long, value_name = "IPM")]
    pub(crate) air_feed: Option<f64>,
    /// A new piece where the feed the cut allows leaves the piece's band by this ratio.
    #[arg(long, default_value_t = 0.03)]
    pub(crate) split: f64,
    /// Shortest piece, mm.
    #[arg(long, default_value_t = 1.0)]
    pub(crate) min_piece_mm: f64,
    /// A fitted model (`calibrate`'s file): Georgiev and Chetrokov's quadratic model sets the
    /// feeds instead of the full force model, where it covers the depth.
    #[arg(long, value_name = "FILE")]
    pub(crate) model: Option<PathBuf>,
    /// The guard against a stock that is not as described: where the description says air
    /// but the stock's blanks could still hold material, at most the feed that would load
    /// such material to this fraction of the permissible force, so that the AC under the
    /// plan ($263=2) can catch it; 0 trusts the description.
    #[arg(long, default_value_t = 0.95)]
    pub(crate) guard: f64,
}

/// `optimise`: the model file read, then [`optimise`].
pub(crate) fn command(args: OptimiseArgs) -> Result<bool> {
    let OptimiseArgs {
        program,
        out,
        stock,
        tool,
        tools,
        material,
        fraction,
        air_feed,
        split,
        min_piece_mm,
        model,
        guard,
    } = args;
    let model = match model {
        Some(p) => Some(millac_qemu::evaluation::model::Quadratic::from_json(
            &std::fs::read_to_string(&p).with_context(|| format!("reading {}", p.display()))?,
        )?),
        None => None,
    };
    optimise(
        &program,
        &out,
        stock.as_deref(),
        tool,
        tools.as_deref(),
        material.into(),
        &millac_qemu::evaluation::optimise::Options {
            fraction,
            air_feed_ipm: air_feed.unwrap_or(f64::INFINITY),
            split,
            min_piece_mm,
            model,
            guard,
        },
    )
}

/// `optimise`: the offline feed optimisation (`millac_qemu::evaluation::optimise`), its files and a summary
/// of both programs on the simulated cut (no AC).
fn optimise(
    program: &Path,
    out: &Path,
    stock: Option<&Path>,
    tool: Option<millac_plant::Tool>,
    tools: Option<&Path>,
    material: millac_plant::Material,
    opts: &millac_qemu::evaluation::optimise::Options,
) -> Result<bool> {
    use millac_qemu::{evaluation::optimise, host::acsim};
    let bytes = std::fs::read(program).with_context(|| format!("reading {}", program.display()))?;
    let text = std::str::from_utf8(&bytes)
        .map_err(|e| anyhow::anyhow!("{} is not UTF-8: {e}", program.display()))?;
    let stock = match stock {
        Some(p) => acsim::load_stock(p)?,
        None => millac_plant::Stock::default(),
    };
    let settings = Settings::default();
    let cut = acsim::Cut {
        tool: tool.unwrap_or_default(),
        material,
        ..acsim::Cut::steel(stock, 1)
    }
    .at_program_rpm(text, &settings);
    let table = match tools {
        Some(p) => acsim::load_tools(p)?,
        None => Default::default(),
    };
    let cut = cut.with_tool_changes(text, &settings, &table);
    let o = millac_qemu::progress::with_bar("optimise", 0, || {
        optimise::optimise(text, &settings, &cut, opts)
    })?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(out, &o.text).with_context(|| format!("writing {}", out.display()))?;
    let csv = out.with_extension("csv");
    std::fs::write(&csv, optimise::csv(&o))
        .with_context(|| format!("writing {}", csv.display()))?;
    let svg = out.with_extension("svg");
    let name = program
        .file_name()
        .map_or_else(|| "program".into(), |n| n.to_string_lossy().into_owned());
    optimise::plot(&svg, &name, &o)?;
    let prog = analysis::load_program(&o.text, &settings).map_err(|e| anyhow::anyhow!("{e}"))?;
    let run = millac_qemu::progress::with_bar("optimised program", prog.len(), || {
        let record = acsim::Record::figures(opts.fraction);
        // The optimised program's own blocks (its pieces) between its M6s.
        let cut = cut.clone().with_tool_changes(&o.text, &settings, &table);
        acsim::run_recorded(&prog, &settings, &cut, None, &[], record, None)
    })?;
    let (before, after) = (o.programmed.load, run.load);
    println!(
        "millac optimise: {} -> {} ({} pieces; {}, {})",
        program.display(),
        out.display(),
        o.pieces.len(),
        csv.display(),
        svg.display()
    );
    println!("| program | time s | peak F / F_max | time above F0 s | time above F_max s |");
    println!("| --- | ---: | ---: | ---: | ---: |");
    for (name, r, l) in [
        ("programmed", &o.programmed, before),
        ("optimised", &run, after),
    ] {
        println!(
            "| {name} | {:.2} | {:.3} | {:.3} | {:.3} |",
            r.machining_time_s, l.peak_force_ratio, l.time_above_f0_s, l.time_above_limit_s
        );
    }
    Ok(true)
}
