//! What the host's figures share (host: the examples and commands that draw SVGs with plotters):
//! the legend box.
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
