//! Long finishing rasters of any length, made reproducibly (host: the scale benchmark and the
//! tests that need a long real-sized program): a 0.5 in flat end mill finishing a wavy surface
//! in zig-zag passes along X, one G1 block per 0.05 in of path, 0.01 in step-over, at F10 (about
//! 0.3 s of cutting per block: 35 000 blocks are a 3-hour job, as the public relief job the
//! scale issue measured), over a blank it cuts into by 0.02 to 0.06 in.

/// Blocks per pass (X 0..2.5 in in 0.05 in steps).
const PER_PASS: usize = 50;
/// Step along X and across passes, inches.
const STEP_IN: f64 = 0.05;
const STEP_OVER_IN: f64 = 0.01;

/// The surface's depth below the blank's top at (x, y), inches (0.02 to 0.06).
fn depth_in(x: f64, y: f64) -> f64 {
    use std::f64::consts::TAU;
    0.04 + 0.02 * (TAU * x / 1.25).sin() * (TAU * y / 1.75).sin()
}

/// A raster of about `blocks` feed blocks (whole passes: at least one) and the stock
/// description of its blank (the `--stock` format), the raster's name in the header comment.
pub fn raster(blocks: usize) -> (String, String) {
    let passes = blocks.div_ceil(PER_PASS + 1).max(1);
    let width = (passes - 1) as f64 * STEP_OVER_IN;
    let mut p = String::with_capacity(passes * (PER_PASS + 1) * 24);
    p += &format!(
        "(millac raster: {passes} passes of {PER_PASS} blocks, 0.5 in flat end mill, F10)\n\
         G20 G90 G17\nS600 M3\nG0 Z0.1\nG0 X0 Y0\n"
    );
    let z = |x: f64, y: f64| -depth_in(x, y);
    p += &format!("G1 Z{:.4} F10\n", z(0.0, 0.0));
    for k in 0..passes {
        let y = k as f64 * STEP_OVER_IN;
        if k > 0 {
            let x = if k % 2 == 1 {
                PER_PASS as f64 * STEP_IN
            } else {
                0.0
            };
            p += &format!("Y{y:.4} Z{:.4}\n", z(x, y));
        }
        for i in 1..=PER_PASS {
            let i = if k % 2 == 0 { i } else { PER_PASS - i };
            let x = i as f64 * STEP_IN;
            p += &format!("X{x:.4} Z{:.4}\n", z(x, y));
        }
    }
    p += "G0 Z0.1\nM5\nM2\n";
    // The blank: a margin of the tool's radius and more around the raster, its top at Z0.
    let stock = format!(
        "# blank of the millac raster: {passes} passes\nblank X-0.5 Y-0.5 W{:.4} H{:.4} Z0\n",
        PER_PASS as f64 * STEP_IN + 1.0,
        width + 1.0
    );
    (p, stock)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The raster parses whole, has the blocks asked for (whole passes), and every Z is within
    /// the surface's depths; the same length gives the same bytes.
    #[test]
    fn a_raster_has_its_blocks_and_parses() {
        let s = millac::Settings::default();
        for n in [1, 51, 1000] {
            let (text, stock) = raster(n);
            assert_eq!(raster(n), (text.clone(), stock.clone()));
            let prog = crate::analysis::load_program(&text, &s).unwrap();
            let feeds = text
                .lines()
                .filter(|l| l.starts_with('X') || l.starts_with('Y'));
            let passes = n.div_ceil(PER_PASS + 1).max(1);
            assert_eq!(feeds.count(), passes * PER_PASS + passes - 1);
            assert!(prog.len() >= passes * (PER_PASS + 1));
            millac_plant::Stock::parse(&stock).unwrap();
            for l in text.lines().filter(|l| l.starts_with('X')) {
                let z: f64 = l.split('Z').nth(1).unwrap().parse().unwrap();
                assert!((-0.0601..=-0.0199).contains(&z), "{l}");
            }
        }
    }
}
