//! Line plots of time series, written as PNG and SVG with plotters.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::image::{RgbImage, write_png};
use crate::{Error, Result};

/// One curve.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// `(x, y)` points; non-finite points are skipped.
    pub points: Vec<(f64, f64)>,
}

/// A plot: title, axis labels and curves.
#[derive(Debug, Clone, PartialEq)]
pub struct Plot {
    /// Title above the plot.
    pub title: String,
    /// Label of the x axis.
    pub x_label: String,
    /// Label of the y axis.
    pub y_label: String,
    /// The curves, coloured in order.
    pub series: Vec<Series>,
}

const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(0, 0, 0),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
];

impl Plot {
    /// The range of the finite data, widened when flat.
    fn ranges(&self) -> Result<((f64, f64), (f64, f64))> {
        let mut x = (f64::INFINITY, f64::NEG_INFINITY);
        let mut y = (f64::INFINITY, f64::NEG_INFINITY);
        for &(a, b) in self.series.iter().flat_map(|s| &s.points) {
            if a.is_finite() && b.is_finite() {
                x = (x.0.min(a), x.1.max(a));
                y = (y.0.min(b), y.1.max(b));
            }
        }
        if !x.0.is_finite() {
            return Err(Error::Input(format!(
                "{:?}: no finite data to plot",
                self.title
            )));
        }
        let widen = |(lo, hi): (f64, f64), fraction: f64| {
            let pad = if hi > lo {
                fraction * (hi - lo)
            } else {
                0.5 * lo.abs().max(1e-9)
            };
            (lo - pad, hi + pad)
        };
        let x = if x.1 > x.0 { x } else { widen(x, 0.0) };
        Ok((x, widen(y, 0.05)))
    }

    fn draw<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), String> {
        let (xr, yr) = self.ranges().map_err(|e| e.to_string())?;
        area.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(area)
            .caption(&self.title, (crate::FONT_FAMILY, 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(80)
            .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style((crate::FONT_FAMILY, 13))
            .y_label_formatter(&|v| format_tick(*v))
            .x_label_formatter(&|v| format_tick(*v))
            .draw()
            .map_err(|e| e.to_string())?;
        for (k, series) in self.series.iter().enumerate() {
            let colour = COLOURS[k % COLOURS.len()];
            chart
                .draw_series(LineSeries::new(
                    series
                        .points
                        .iter()
                        .copied()
                        .filter(|(a, b)| a.is_finite() && b.is_finite()),
                    colour.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?
                .label(series.label.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font((crate::FONT_FAMILY, 13))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| e.to_string())?;
        area.present().map_err(|e| e.to_string())
    }

    /// Writes the plot as a `width x height` PNG.
    ///
    /// # Errors
    /// [`Error::Input`] if no point is finite; [`Error::Encode`] or
    /// [`Error::Io`] naming the file.
    pub fn write_png(&self, path: &Path, width: u32, height: u32) -> Result<()> {
        crate::register_font();
        self.ranges()?;
        let mut image = RgbImage::filled(width, height, [255; 3]);
        {
            let area =
                BitMapBackend::with_buffer(&mut image.data, (width, height)).into_drawing_area();
            self.draw(&area).map_err(|message| Error::Encode {
                path: path.to_path_buf(),
                message,
            })?;
        }
        write_png(path, &image)
    }

    /// Writes the plot as a `width x height` SVG (text stays text).
    ///
    /// # Errors
    /// As [`Plot::write_png`].
    pub fn write_svg(&self, path: &Path, width: u32, height: u32) -> Result<()> {
        crate::register_font();
        self.ranges()?;
        let mut text = String::new();
        {
            let area = SVGBackend::with_string(&mut text, (width, height)).into_drawing_area();
            self.draw(&area).map_err(|message| Error::Encode {
                path: path.to_path_buf(),
                message,
            })?;
        }
        std::fs::write(path, text).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })
    }
}

/// Short tick text: plain for moderate magnitudes, else scientific.
fn format_tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if (1e-3..1e5).contains(&a) {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.2e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_png_and_svg_with_the_data() {
        let dir = std::env::temp_dir().join(format!("pd-viz-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let plot = Plot {
            title: "energy".into(),
            x_label: "t (s)".into(),
            y_label: "E (J)".into(),
            series: vec![Series {
                label: "total".into(),
                points: (0..50)
                    .map(|i| (i as f64 * 0.01, (i as f64 * 0.2).sin()))
                    .collect(),
            }],
        };
        plot.write_png(&dir.join("p.png"), 400, 300).unwrap();
        plot.write_svg(&dir.join("p.svg"), 400, 300).unwrap();
        let svg = std::fs::read_to_string(dir.join("p.svg")).unwrap();
        assert!(svg.contains("<svg") && svg.contains("energy") && svg.contains("polyline"));
        let png = std::fs::read(dir.join("p.png")).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        let empty = Plot {
            series: vec![],
            ..plot
        };
        assert!(empty.write_png(&dir.join("q.png"), 100, 100).is_err());
    }

    #[test]
    fn tick_text() {
        assert_eq!(format_tick(0.25), "0.25");
        assert_eq!(format_tick(3.0), "3");
        assert_eq!(format_tick(-1.5e-6), "-1.50e-6");
    }
}
