//! `pd render` and `pd plot`.

use std::path::{Path, PathBuf};

use pd_viz::image::{write_gif, write_png};
use pd_viz::obj::read_obj;
use pd_viz::plot::{Plot, Series};
use pd_viz::render::{Panel, render_panels};
use tracing::info;

use crate::Failure;

/// Options of `pd render`.
pub(crate) struct RenderOptions {
    pub width: u32,
    pub height: u32,
    pub gif_frames: usize,
    pub gif_downscale: u32,
}

/// A panel's default label: the run folder's name.
pub(crate) fn label_of(dir: &Path) -> String {
    dir.file_name().map_or_else(
        || dir.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// The OBJ frames of a run, in order.
fn obj_frames(dir: &Path) -> Result<Vec<PathBuf>, Failure> {
    let frames = dir.join("frames");
    let entries = std::fs::read_dir(&frames).map_err(|e| {
        Failure::Input(format!(
            "{}: {e} (is {} the output folder of `pd run`?)",
            frames.display(),
            dir.display()
        ))
    })?;
    let mut paths = Vec::new();
    for entry in entries {
        let path = entry
            .map_err(|e| Failure::Input(format!("{}: {e}", frames.display())))?
            .path();
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
        if name.is_some_and(|n| n.starts_with("frame_") && n.ends_with(".obj")) {
            paths.push(path);
        }
    }
    if paths.is_empty() {
        return Err(Failure::Input(format!(
            "{}: no OBJ frames (frame_NNNNN.obj); run the scene with \"obj\" in output.formats",
            frames.display()
        )));
    }
    // Zero-padded numbers: name order is time order.
    paths.sort();
    Ok(paths)
}

/// Frame indices in the GIF: every `stride`-th frame so that at most `max`
/// are kept.
pub(crate) fn gif_indices(frames: usize, max: usize) -> Vec<usize> {
    let stride = frames.div_ceil(max.max(1)).max(1);
    (0..frames).step_by(stride).collect()
}

/// `pd render`: panels of `(label, run folder)`.
pub(crate) fn render(
    runs: &[(String, PathBuf)],
    out: &Path,
    options: &RenderOptions,
) -> Result<(), Failure> {
    if options.width == 0 || options.height == 0 || options.gif_downscale == 0 {
        return Err(Failure::Input(
            "--width, --height and --gif-downscale must be positive".into(),
        ));
    }
    let mut panels = Vec::new();
    for (label, dir) in runs {
        let frames = obj_frames(dir)?
            .iter()
            .map(|p| read_obj(p).map_err(|e| Failure::Input(e.to_string())))
            .collect::<Result<Vec<_>, _>>()?;
        panels.push(Panel {
            label: label.clone(),
            frames,
        });
    }
    let images = render_panels(&panels, options.width, options.height)
        .map_err(|e| Failure::Input(e.to_string()))?;
    std::fs::create_dir_all(out).map_err(|e| Failure::Output(format!("{}: {e}", out.display())))?;
    for (i, image) in images.iter().enumerate() {
        let path = out.join(format!("frame_{i:05}.png"));
        write_png(&path, image).map_err(|e| Failure::Output(e.to_string()))?;
    }
    let gif_frames: Vec<_> = gif_indices(images.len(), options.gif_frames)
        .into_iter()
        .map(|i| images[i].downscaled(options.gif_downscale))
        .collect();
    let gif = out.join("animation.gif");
    // 8 hundredths of a second per frame: 12.5 frames per second.
    write_gif(&gif, &gif_frames, 8).map_err(|e| Failure::Output(e.to_string()))?;
    info!(
        "{} PNG frames and {} ({} frames) in {}",
        images.len(),
        gif.display(),
        gif_frames.len(),
        out.display()
    );
    Ok(())
}

/// A run's `metrics.csv`: column names and numeric rows.
pub(crate) struct Metrics {
    columns: Vec<String>,
    rows: Vec<Vec<f64>>,
}

impl Metrics {
    /// Reads `metrics.csv`; a malformed file is bad input, named with its
    /// line.
    pub(crate) fn read(path: &Path) -> Result<Self, Failure> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Failure::Input(format!("{}: {e}", path.display())))?;
        let mut lines = text.lines();
        let columns: Vec<String> = lines
            .next()
            .ok_or_else(|| Failure::Input(format!("{}: empty file", path.display())))?
            .split(',')
            .map(str::to_owned)
            .collect();
        let mut rows = Vec::new();
        for (i, line) in lines.enumerate() {
            let row = line
                .split(',')
                .map(|f| f.parse::<f64>())
                .collect::<Result<Vec<_>, _>>()
                .ok()
                .filter(|r| r.len() == columns.len())
                .ok_or_else(|| {
                    Failure::Input(format!(
                        "{}:{}: expected {} numbers",
                        path.display(),
                        i + 2,
                        columns.len()
                    ))
                })?;
            rows.push(row);
        }
        if rows.is_empty() {
            return Err(Failure::Input(format!("{}: no rows", path.display())));
        }
        Ok(Self { columns, rows })
    }

    /// A column's values.
    pub(crate) fn column(&self, name: &str, path: &Path) -> Result<Vec<f64>, Failure> {
        let index = self
            .columns
            .iter()
            .position(|c| c == name)
            .ok_or_else(|| Failure::Input(format!("{}: no column `{name}`", path.display())))?;
        Ok(self.rows.iter().map(|r| r[index]).collect())
    }

    /// `(time, column)` points.
    pub(crate) fn series(&self, name: &str, label: &str, path: &Path) -> Result<Series, Failure> {
        let t = self.column("time", path)?;
        let y = self.column(name, path)?;
        Ok(Series {
            label: label.to_string(),
            points: t.into_iter().zip(y).collect(),
        })
    }
}

/// Plot size in pixels.
pub(crate) const PLOT_SIZE: (u32, u32) = (800, 500);

/// Writes a plot as `stem.png` and `stem.svg` in `dir`.
pub(crate) fn write_plot(plot: &Plot, dir: &Path, stem: &str) -> Result<(), Failure> {
    let (w, h) = PLOT_SIZE;
    plot.write_png(&dir.join(format!("{stem}.png")), w, h)
        .and_then(|()| plot.write_svg(&dir.join(format!("{stem}.svg")), w, h))
        .map_err(|e| match e {
            pd_viz::Error::Input(m) => Failure::Input(m),
            e => Failure::Output(e.to_string()),
        })
}

/// `pd plot DIR`.
pub(crate) fn plot(dir: &Path) -> Result<(), Failure> {
    let path = dir.join("metrics.csv");
    let metrics = Metrics::read(&path)?;
    let out = dir.join("plots");
    std::fs::create_dir_all(&out)
        .map_err(|e| Failure::Output(format!("{}: {e}", out.display())))?;
    let plots = [
        (
            "energy",
            "Energy",
            "energy (J)",
            &[
                ("kinetic", "kinetic"),
                ("elastic", "elastic"),
                ("gravity", "gravity"),
                ("total", "total"),
            ][..],
        ),
        (
            "linear_momentum",
            "Linear momentum",
            "momentum (kg m/s)",
            &[("px", "p_x"), ("py", "p_y"), ("pz", "p_z")][..],
        ),
        (
            "angular_momentum",
            "Angular momentum about the origin",
            "angular momentum (kg m^2/s)",
            &[("jx", "L_x"), ("jy", "L_y"), ("jz", "L_z")][..],
        ),
    ];
    for (stem, title, y_label, columns) in plots {
        let series = columns
            .iter()
            .map(|(column, label)| metrics.series(column, label, &path))
            .collect::<Result<Vec<_>, _>>()?;
        let plot = Plot {
            title: title.to_string(),
            x_label: "time (s)".into(),
            y_label: y_label.to_string(),
            series,
        };
        write_plot(&plot, &out, stem)?;
    }
    info!(
        "energy, linear_momentum and angular_momentum (.png, .svg) in {}",
        out.display()
    );
    Ok(())
}
