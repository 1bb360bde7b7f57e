//! The thesis' chatter test on the host (Munasinghe 1994, table 3.2, Fig. 3.10): the table 3.2
//! preset cut at 2.54 mm (stable) and 8.89 mm (chatter), heard at 5 kHz, judged by the core's
//! chatter detector every 256 samples; the threshold by the thesis' rule (twice the stable cut's
//! largest amplitude). Writes `out/chatter/fig3-10.svg` and prints the cycles.
//!
//! ```text
//! cargo run -p millac-qemu --release --example chatter_thesis
//! ```
use anyhow::Result;
use millac_plant::chatter::thesis_table_3_2 as t;
use millac_qemu::evaluation::chatterlab;

fn main() -> Result<()> {
    let records = 40;
    let stable = chatterlab::run(t::DEPTH_STABLE_MM, records, f32::MAX, 1)?;
    let threshold = chatterlab::threshold_from(&stable, 2.0);
    let stable = chatterlab::run(t::DEPTH_STABLE_MM, records, threshold, 2)?;
    let chatter = chatterlab::run(t::DEPTH_CHATTER_MM, records, threshold, 2)?;
    println!("threshold {threshold:.2} codes (2 x the largest amplitude of a 2.54 mm cut, seed 1)");
    println!("| cycle | 2.54 mm amplitude | 8.89 mm amplitude | 8.89 mm peak Hz | 8.89 mm chatter | 8.89 mm wave RMS um |");
    println!("| ---: | ---: | ---: | ---: | --- | ---: |");
    for k in 0..records {
        let (s, c) = (&stable.cycles[k], &chatter.cycles[k]);
        println!(
            "| {k} | {:.2} | {:.2} | {:.0} | {} | {:.3} |",
            s.peak_amplitude,
            c.peak_amplitude,
            c.peak_hz,
            c.chatter,
            chatter.wave_rms_m[k] * 1e6
        );
    }
    let dir = std::path::Path::new("out/chatter");
    std::fs::create_dir_all(dir)?;
    let path = dir.join("fig3-10.svg");
    chatterlab::plot(&path, &[stable, chatter], threshold)?;
    println!("wrote {}", path.display());
    Ok(())
}
