//! The stock as a picture (host: `run`, `demo` and `host` after each tool of a multi-tool job):
//! its height map as a PNG, one pixel a cell, +Y up, coloured by the material's top from the
//! lowest to the highest of the range given (deep blue to pale yellow) and shaded by its slope
//! as if lit from the upper left, so steps, scallops and corners show; air (no material) black.
use anyhow::{Context, Result};
use millac_plant::Stock;
use std::path::Path;

/// The colours from the lowest top to the highest (a perceptual ramp in the manner of viridis).
const RAMP: [[f64; 3]; 5] = [
    [33.0, 49.0, 140.0],
    [32.0, 120.0, 142.0],
    [53.0, 183.0, 121.0],
    [170.0, 220.0, 50.0],
    [253.0, 231.0, 150.0],
];

/// The colour of a top `z` (mm) in `lo..hi`.
fn colour(z: f64, lo: f64, hi: f64) -> [f64; 3] {
    let u = if hi > lo {
        ((z - lo) / (hi - lo)).clamp(0.0, 1.0)
    } else {
        1.0
    };
    let x = u * (RAMP.len() - 1) as f64;
    let i = (x.floor() as usize).min(RAMP.len() - 2);
    let f = x - i as f64;
    [0, 1, 2].map(|k| RAMP[i][k] + f * (RAMP[i + 1][k] - RAMP[i][k]))
}

/// Writes `stock`'s height map to `path` (PNG), the colours spanning tops `lo..hi` (mm).
pub fn write_png(path: &Path, stock: &Stock, lo: f64, hi: f64) -> Result<()> {
    let (nx, ny) = stock.dims();
    let tops = stock.tops();
    let cell = stock.cell_mm();
    let at = |i: usize, j: usize| tops[j * nx + i];
    let mut data = Vec::with_capacity(nx * ny * 3);
    for row in 0..ny {
        // The image's first row is the stock's last (+Y up).
        let j = ny - 1 - row;
        for i in 0..nx {
            let z = at(i, j);
            if !z.is_finite() {
                data.extend([0u8; 3]);
                continue;
            }
            // Lit from the upper left: a surface falling towards +X or -Y is darker.
            let zx = if i + 1 < nx && at(i + 1, j).is_finite() {
                at(i + 1, j) - z
            } else {
                0.0
            };
            let zy = if j > 0 && at(i, j - 1).is_finite() {
                z - at(i, j - 1)
            } else {
                0.0
            };
            let shade = (1.0 + 2.0 * (zx + zy) / cell).clamp(0.55, 1.25);
            let c = colour(z, lo, hi);
            data.extend(c.map(|v| (v * shade).round().clamp(0.0, 255.0) as u8));
        }
    }
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), nx as u32, ny as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()
        .and_then(|mut w| w.write_image_data(&data))
        .with_context(|| format!("writing {}", path.display()))
}

/// Each tool's stock picture, `out/stock-T<n>.png` (the stock as tool n left it), all on one
/// colour range (the lowest and the highest top of them all), and says which it wrote.
pub fn write_tool_stocks(out: &Path, stocks: &[(u8, Stock)]) -> Result<()> {
    if stocks.is_empty() {
        return Ok(());
    }
    let finite = stocks
        .iter()
        .flat_map(|(_, s)| s.tops().iter().copied())
        .filter(|z| z.is_finite());
    let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), z| {
        (l.min(z), h.max(z))
    });
    let mut names = Vec::new();
    for (tool, stock) in stocks {
        let name = format!("stock-T{tool}.png");
        write_png(&out.join(&name), stock, lo, hi)?;
        names.push(name);
    }
    println!(
        "  wrote {}/{} (the stock as each tool left it, its top from {:.2} mm to {:.2} mm)",
        out.display(),
        names.join(", "),
        lo,
        hi
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A blank with a pocket: the picture has the grid's size, the pocket's pixels are the
    /// ramp's low end (darker than the top's), the top's its high end; the bytes are the same
    /// for the same stock.
    #[test]
    fn the_picture_is_the_height_map() {
        let st = Stock::parse("blank X0 Y0 W1 H0.5 Z0\npocket X0.25 Y0.1 W0.5 H0.3 Z-0.2").unwrap();
        let dir = std::env::temp_dir().join(format!("millac-heightmap-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("stock.png");
        write_png(&path, &st, -0.2 * 25.4, 0.0).unwrap();
        let dec = png::Decoder::new(std::fs::File::open(&path).unwrap());
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size()];
        let info = r.next_frame(&mut buf).unwrap();
        let (nx, ny) = st.dims();
        assert_eq!((info.width as usize, info.height as usize), (nx, ny));
        let px = |x_mm: f64, y_mm: f64| {
            let (i, row) = (
                (x_mm / st.cell_mm()) as usize,
                ny - 1 - (y_mm / st.cell_mm()) as usize,
            );
            let k = (row * nx + i) * 3;
            [buf[k], buf[k + 1], buf[k + 2]]
        };
        // Inside the pocket, away from its edges; on the top.
        let deep = px(12.7, 6.35);
        let top = px(2.0, 2.0);
        assert_eq!(
            deep,
            colour(-0.2 * 25.4, -0.2 * 25.4, 0.0).map(|v| v.round() as u8)
        );
        assert_eq!(top, colour(0.0, -0.2 * 25.4, 0.0).map(|v| v.round() as u8));
        let again = dir.join("again.png");
        write_png(&again, &st, -0.2 * 25.4, 0.0).unwrap();
        assert_eq!(
            std::fs::read(&path).unwrap(),
            std::fs::read(&again).unwrap()
        );
    }
}
