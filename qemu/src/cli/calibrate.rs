//! `millac-qemu calibrate --out FILE`: Georgiev and Chetrokov's quadratic force model fitted from
//! test cuts (the simulated plant or a machine's logs), or the test cuts written as programs
//! (host: the CLI calls it from `main`).
use super::args::{parse_tool, MaterialArg};
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// `calibrate`'s options.
#[derive(clap::Args)]
pub(crate) struct CalibrateArgs {
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// The cutter: DIAMETER_MM,FLUTES[,F_MAX_N[,T_MAX_NM]].
    #[arg(long, value_name = "D_MM,Z[,F_MAX_N[,T_MAX_NM]]", value_parser = parse_tool)]
    pub(crate) tool: Option<millac_plant::Tool>,
    #[arg(long, value_enum, default_value = "steel")]
    pub(crate) material: MaterialArg,
    /// Spindle speed, rpm.
    #[arg(long, default_value_t = 600.0)]
    pub(crate) rpm: f64,
    /// Depths of the test cuts, mm.
    #[arg(long, value_delimiter = ',', default_value = "1,3,5,7,9")]
    pub(crate) depths: Vec<f64>,
    /// Feeds of the test cuts, ipm.
    #[arg(long, value_delimiter = ',', default_value = "5,10,15,20,25,30")]
    pub(crate) feeds: Vec<f64>,
    /// A test cut cut on a machine: its depth (mm), its feed (ipm) and its run's ac.csv
    /// (repeat for every cut; at least six, over two depths and two feeds or more). With
    /// logs the model is fitted from them, not from the simulated plant.
    #[arg(long = "log", value_name = "A_MM,F_IPM,AC_CSV", value_parser = parse_log)]
    pub(crate) logs: Vec<(f64, f64, PathBuf)>,
    /// Write the test cuts of the grid (--depths x --feeds) as programs into this folder
    /// (cut-A-F.nc, on the blank `blank X0 Y0 W3 H2 Z0`, the top face at Z0) and stop: cut
    /// them on the machine with the AC measuring, then fit with --log.
    #[arg(long, value_name = "DIR")]
    pub(crate) write_cuts: Option<PathBuf>,
}

/// `calibrate`: the test cuts written ([`write_test_cuts`]) or the model fitted ([`calibrate`]).
pub(crate) fn command(args: CalibrateArgs) -> Result<bool> {
    let CalibrateArgs {
        out,
        tool,
        material,
        rpm,
        depths,
        feeds,
        logs,
        write_cuts,
    } = args;
    match write_cuts {
        Some(dir) => write_test_cuts(&dir, &depths, &feeds),
        None => calibrate(&out, tool, material.into(), rpm, &depths, &feeds, &logs),
    }
}

/// `--log A,F,FILE`: a test cut's depth (mm), feed (ipm) and its run's ac.csv.
fn parse_log(s: &str) -> std::result::Result<(f64, f64, PathBuf), String> {
    let mut it = s.splitn(3, ',');
    let num = |v: Option<&str>, what: &str| {
        v.and_then(|v| v.trim().parse::<f64>().ok())
            .filter(|v| v.is_finite() && *v > 0.0)
            .ok_or_else(|| format!("'{s}': {what} must be a number > 0 (A_MM,F_IPM,AC_CSV)"))
    };
    let a = num(it.next(), "the depth")?;
    let f = num(it.next(), "the feed")?;
    let path = it
        .next()
        .filter(|p| !p.is_empty())
        .ok_or_else(|| format!("'{s}': the ac.csv file is missing (A_MM,F_IPM,AC_CSV)"))?;
    Ok((a, f, PathBuf::from(path)))
}

/// `calibrate --write-cuts DIR`: the test cuts of the grid as programs.
fn write_test_cuts(dir: &Path, depths: &[f64], feeds: &[f64]) -> Result<bool> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for &a in depths {
        for &f in feeds {
            let p = dir.join(format!("cut-{a}-{f}.nc"));
            std::fs::write(&p, millac_qemu::evaluation::model::test_cut(a, f))
                .with_context(|| format!("writing {}", p.display()))?;
        }
    }
    println!(
        "millac calibrate: {} test cuts in {} (stock: {})",
        depths.len() * feeds.len(),
        dir.display(),
        millac_qemu::evaluation::model::TEST_STOCK.trim()
    );
    Ok(true)
}

/// `calibrate`: the quadratic model from test cuts (on the simulated plant, or cut on a machine:
/// their ac.csv files), its file and a table.
fn calibrate(
    out: &Path,
    tool: Option<millac_plant::Tool>,
    material: millac_plant::Material,
    rpm: f64,
    depths: &[f64],
    feeds: &[f64],
    logs: &[(f64, f64, PathBuf)],
) -> Result<bool> {
    use millac_qemu::{evaluation::model, host::acsim};
    let (m, cuts) = if logs.is_empty() {
        let cut = acsim::Cut {
            tool: tool.unwrap_or_default(),
            material,
            spindle_rpm: rpm,
            ..acsim::Cut::steel(millac_plant::Stock::default(), 1)
        };
        model::calibrate(&cut, depths, feeds)?
    } else {
        let mut texts = Vec::new();
        for (a, f, p) in logs {
            let t =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            texts.push((*a, *f, t));
        }
        model::calibrate_from_logs(&texts)?
    };
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(out, m.to_json(&cuts)).with_context(|| format!("writing {}", out.display()))?;
    println!(
        "millac calibrate: {} test cuts -> {}: y = {:.1} + {:.2} a + {:.2} f + {:.3} a f + {:.3} a^2 + {:.4} f^2 (a {}..{} mm, f {}..{} ipm)",
        cuts.len(),
        out.display(),
        m.b[0], m.b[1], m.b[2], m.b[3], m.b[4], m.b[5],
        m.a_range.0, m.a_range.1, m.f_range.0, m.f_range.1
    );
    println!("| a mm | f ipm | y N (test cut) | y N (model) |");
    println!("| ---: | ---: | ---: | ---: |");
    for (a, f, y) in &cuts {
        println!("| {a} | {f} | {y:.0} | {:.0} |", m.eval(*a, *f));
    }
    Ok(true)
}
