//! Log-log line plots as PNG for `bench-report`, with `plotters` (pure
//! Rust: bitmap backend, PNG encoder, `ab_glyph` text). The bitmap backend
//! draws text only with a registered font, so a font file is committed with
//! its licence (`crates/pd-viz/assets/`, shared with pd-viz; DejaVu Sans Mono, Bitstream Vera
//! licence) and compiled in: the figures then look the same on every
//! machine (docs/design/performance.md says why).

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;

/// The font, compiled into the xtask binary.
static FONT: &[u8] = include_bytes!("../../crates/pd-viz/assets/DejaVuSansMono.ttf");

/// One curve: a name for the legend and `(x, y)` points.
pub struct Series {
    /// Legend text.
    pub name: String,
    /// The points; those with a non-positive or non-finite coordinate are
    /// left out (log axes).
    pub points: Vec<(f64, f64)>,
}

fn register_font() -> Result<(), String> {
    static ONCE: Once = Once::new();
    let mut result = Ok(());
    ONCE.call_once(|| {
        result = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .map_err(|_| "the bundled font cannot be read".to_string());
    });
    result
}

fn err<E: std::fmt::Display>(e: E) -> String {
    format!("plotting failed: {e}")
}

/// Writes a PNG with one log-log panel per entry of `panels` (its y-axis
/// label and curves), side by side, sharing the x-axis label.
pub fn log_log(
    path: &Path,
    title: &str,
    x_label: &str,
    panels: &[(&str, &[Series])],
) -> Result<(), String> {
    register_font()?;
    let colours = [RED, BLUE, GREEN, BLACK, MAGENTA, CYAN];
    let width = 600 * panels.len().max(1) as u32;
    let root = BitMapBackend::new(path, (width, 460)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let root = root.titled(title, ("sans-serif", 18)).map_err(err)?;
    let areas = root.split_evenly((1, panels.len().max(1)));
    for (area, (y_label, series)) in areas.iter().zip(panels) {
        let usable = |p: &&(f64, f64)| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite();
        let all: Vec<(f64, f64)> = series
            .iter()
            .flat_map(|s| s.points.iter().filter(usable).copied())
            .collect();
        let range = |values: &mut dyn Iterator<Item = f64>| {
            let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
            if lo.is_finite() {
                (lo / 1.5, hi * 1.5)
            } else {
                (0.1, 10.0)
            }
        };
        let (x0, x1) = range(&mut all.iter().map(|p| p.0));
        let (y0, y1) = range(&mut all.iter().map(|p| p.1));
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(75)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(*y_label)
            .x_label_formatter(&|v| {
                if *v >= 1.0 {
                    format!("{v:.0}")
                } else {
                    format!("{v:.2}")
                }
            })
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .label_style(("sans-serif", 13))
            .draw()
            .map_err(err)?;
        for (i, s) in series.iter().enumerate() {
            let colour = colours[i % colours.len()];
            let points: Vec<(f64, f64)> = s.points.iter().filter(usable).copied().collect();
            chart
                .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))
                .map_err(err)?
                .label(s.name.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(err)?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font(("sans-serif", 13))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}
