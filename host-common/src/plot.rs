//! Plot set-up shared by every figure the project draws: a font compiled into the binary,
//! so PNGs render on machines without any system fonts.

use std::sync::OnceLock;

use anyhow::{Result, bail};
use plotters::style::{FontStyle, register_font};

/// DejaVu Sans (Bitstream Vera licence, `assets/fonts/DejaVuSans-LICENSE`).
static DEJAVU_SANS: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// The family name figures use.
pub const FONT: &str = "sans-serif";

/// Registers the bundled font under [`FONT`]; call before drawing any text. Idempotent.
pub fn ensure_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        [FontStyle::Normal, FontStyle::Bold]
            .into_iter()
            .all(|style| register_font(FONT, style, DEJAVU_SANS).is_ok())
    });
    if !ok {
        bail!("the bundled font assets/fonts/DejaVuSans.ttf does not parse");
    }
    Ok(())
}

/// One line of a chart: a mean per x with a shaded band (lower, upper), or no band.
pub struct Curve {
    /// Legend text.
    pub label: String,
    /// y values, one per x = 1, 2, ...
    pub mean: Vec<f64>,
    /// Band edges, the same length as `mean`; empty for none.
    pub band: Vec<(f64, f64)>,
    /// Dashed instead of solid.
    pub dashed: bool,
}

/// Draws `curves` against x = 1..n into `stem.svg` and `stem.png`.
pub fn line_chart(
    stem: &std::path::Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    curves: &[Curve],
) -> Result<()> {
    use plotters::prelude::*;
    ensure_font()?;
    let svg = stem.with_extension("svg");
    let png = stem.with_extension("png");
    draw(
        SVGBackend::new(&svg, (900, 540)).into_drawing_area(),
        title,
        x_label,
        y_label,
        curves,
    )
    .map_err(|e| {
        anyhow::anyhow!(
            "drawing {}: {}",
            weights::shown(&svg),
            weights::excerpt(&e.to_string())
        )
    })?;
    draw(
        BitMapBackend::new(&png, (900, 540)).into_drawing_area(),
        title,
        x_label,
        y_label,
        curves,
    )
    .map_err(|e| {
        anyhow::anyhow!(
            "drawing {}: {}",
            weights::shown(&png),
            weights::excerpt(&e.to_string())
        )
    })?;
    Ok(())
}

/// The lowest and highest finite value of `curves` (means and band edges), `(0, 1)` where
/// there are none or they are all the same.
fn y_range(curves: &[Curve]) -> (f64, f64) {
    let values = curves
        .iter()
        .flat_map(|c| {
            c.mean
                .iter()
                .copied()
                .chain(c.band.iter().flat_map(|&(a, b)| [a, b]))
        })
        .filter(|v| v.is_finite());
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
        (l.min(v), h.max(v))
    });
    if lo < hi { (lo, hi) } else { (0.0, 1.0) }
}

type Chart<'a, DB> = plotters::prelude::ChartContext<
    'a,
    DB,
    plotters::prelude::Cartesian2d<
        plotters::coord::types::RangedCoordf64,
        plotters::coord::types::RangedCoordf64,
    >,
>;

/// Draws curve `c`, the `i`th, with its band and its legend entry.
fn draw_curve<DB: plotters::prelude::DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    i: usize,
    c: &Curve,
) -> std::result::Result<(), Box<dyn std::error::Error>>
where
    DB::ErrorType: 'static,
{
    use plotters::prelude::*;
    let colour = Palette99::pick(i).to_rgba();
    let xy = |v: &[f64]| -> Vec<(f64, f64)> {
        v.iter()
            .enumerate()
            .map(|(k, &y)| ((k + 1) as f64, y))
            .collect()
    };
    if !c.band.is_empty() {
        let mut poly: Vec<(f64, f64)> = xy(&c.band.iter().map(|b| b.1).collect::<Vec<_>>());
        let lower = xy(&c.band.iter().map(|b| b.0).collect::<Vec<_>>());
        poly.extend(lower.into_iter().rev());
        chart.draw_series(std::iter::once(Polygon::new(
            poly,
            colour.mix(0.18).filled(),
        )))?;
    }
    let style = colour.stroke_width(2);
    let points = xy(&c.mean);
    if c.dashed {
        chart
            .draw_series(DashedLineSeries::new(points, 6, 4, style))?
            .label(c.label.clone())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], style));
    } else {
        chart
            .draw_series(LineSeries::new(points, style))?
            .label(c.label.clone())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], style));
    }
    Ok(())
}

fn draw<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    curves: &[Curve],
) -> std::result::Result<(), Box<dyn std::error::Error>>
where
    DB::ErrorType: 'static,
{
    use plotters::prelude::*;
    root.fill(&WHITE)?;
    let n = curves
        .iter()
        .map(|c| c.mean.len())
        .max()
        .unwrap_or(1)
        .max(2);
    let (lo, hi) = y_range(curves);
    let pad = 0.05 * (hi - lo);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT, 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(1f64..n as f64, (lo - pad)..(hi + pad))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style((FONT, 14))
        .draw()?;
    for (i, c) in curves.iter().enumerate() {
        draw_curve(&mut chart, i, c)?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FONT, 14))
        .position(SeriesLabelPosition::LowerRight)
        .draw()?;
    root.present()?;
    Ok(())
}
