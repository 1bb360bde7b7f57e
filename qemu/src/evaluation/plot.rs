//! What the host's figures share (host: the examples and commands that draw SVGs with plotters):
//! the legend box, and a check that no two texts of a figure overlap (tick labels, axis
//! descriptions, captions).
use anyhow::Result;
use plotters::coord::CoordTranslate;
use plotters::prelude::*;

/// The series labels of `chart` in a white, half-transparent box with a black border at `pos`
/// (every figure's legend).
pub fn legend<'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, SVGBackend<'a>, CT>,
    pos: SeriesLabelPosition,
) -> Result<()> {
    chart
        .configure_series_labels()
        .position(pos)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// A text of an SVG plotters wrote: its content and its box (x0, y0, x1, y1), estimated from its
/// position, anchor, baseline shift and font size (a glyph 0.55 of the font size wide on average,
/// ascent 0.75 and descent 0.25 of it). Rotated texts (the y axis descriptions) have their box
/// turned.
#[derive(Clone, Debug, PartialEq)]
pub struct TextBox {
    pub text: String,
    pub bbox: (f64, f64, f64, f64),
}

/// The texts of `svg` with their boxes.
pub fn text_boxes(svg: &str) -> Vec<TextBox> {
    let attr = |tag: &str, name: &str| -> Option<String> {
        let key = format!(" {name}=\"");
        let i = tag.find(&key)? + key.len();
        Some(tag[i..].split('"').next()?.to_string())
    };
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(i) = rest.find("<text ") {
        rest = &rest[i..];
        let Some(end_tag) = rest.find('>') else { break };
        let tag = &rest[..end_tag];
        let Some(close) = rest.find("</text>") else {
            break;
        };
        let text = rest[end_tag + 1..close].trim().to_string();
        rest = &rest[close..];
        let num = |n: &str| attr(tag, n).and_then(|v| v.parse::<f64>().ok());
        let (Some(x), Some(y), Some(fs)) = (num("x"), num("y"), num("font-size")) else {
            continue;
        };
        let w = 0.55 * fs * text.chars().count() as f64;
        let baseline = match attr(tag, "dy").as_deref() {
            Some("0.76em") => y + 0.76 * fs,
            Some("-0.5ex") => y - 0.25 * fs,
            Some("0.5ex") => y + 0.25 * fs,
            _ => y,
        };
        let (top, bottom) = (baseline - 0.75 * fs, baseline + 0.25 * fs);
        let (left, right) = match attr(tag, "text-anchor").as_deref() {
            Some("middle") => (x - w / 2.0, x + w / 2.0),
            Some("end") => (x - w, x),
            _ => (x, x + w),
        };
        let bbox = if attr(tag, "transform").is_some_and(|t| t.starts_with("rotate(270")) {
            // Turned about (x, y): the text runs upwards from it.
            let (dx0, dx1) = (left - x, right - x);
            let (dy0, dy1) = (top - y, bottom - y);
            (x + dy0, y - dx1, x + dy1, y - dx0)
        } else {
            (left, top, right, bottom)
        };
        out.push(TextBox { text, bbox });
    }
    out
}

/// The pairs of texts of `svg` whose boxes overlap (empty: every label is clear of the others).
pub fn overlapping_texts(svg: &str) -> Vec<(String, String)> {
    let boxes = text_boxes(svg);
    let mut out = Vec::new();
    for (i, a) in boxes.iter().enumerate() {
        for b in &boxes[i + 1..] {
            let (a0, a1) = (a.bbox, b.bbox);
            if a0.0 < a1.2 && a1.0 < a0.2 && a0.1 < a1.3 && a1.1 < a0.3 {
                out.push((a.text.clone(), b.text.clone()));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two texts at the same place overlap; side by side they do not; a rotated y description
    /// left of its tick labels does not.
    #[test]
    fn overlapping_texts_are_found() {
        let t = |x: u32, y: u32, anchor: &str, dy: &str, s: &str| {
            format!(
                "<text x=\"{x}\" y=\"{y}\" dy=\"{dy}\" text-anchor=\"{anchor}\" font-size=\"10\">\n{s}\n</text>"
            )
        };
        let clash =
            t(100, 100, "middle", "0.76em", "30.0") + &t(100, 104, "middle", "-0.5ex", "t (s)");
        assert_eq!(
            overlapping_texts(&clash),
            vec![("30.0".to_string(), "t (s)".to_string())]
        );
        let clear =
            t(100, 100, "middle", "0.76em", "30.0") + &t(100, 130, "middle", "-0.5ex", "t (s)");
        assert!(overlapping_texts(&clear).is_empty());
        let rotated = "<text x=\"10\" y=\"100\" dy=\"0.76em\" text-anchor=\"middle\" font-size=\"10\" transform=\"rotate(270, 10, 100)\">\nfeed (ipm)\n</text>".to_string()
            + &t(46, 100, "end", "0.5ex", "25.0");
        assert!(
            overlapping_texts(&rotated).is_empty(),
            "{:?}",
            text_boxes(&rotated)
        );
    }
}
