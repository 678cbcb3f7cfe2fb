//! `pd render` and `pd plot`.

use std::path::{Path, PathBuf};

use pd_io::recorder::MetricsRow;
use pd_viz::image::{write_gif, write_png};
use pd_viz::obj::read_obj;
use pd_viz::plot::{Plot, Series};
use pd_viz::render::{Panel, render_panels_with};
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
pub(crate) fn obj_frames(dir: &Path) -> Result<Vec<PathBuf>, Failure> {
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
    // The colliders of the first run's scene (panels compare one scene).
    let scenery = runs
        .first()
        .map(|(_, dir)| crate::scenery::of_run(dir))
        .unwrap_or_default();
    let images = render_panels_with(&panels, &scenery, options.width, options.height)
        .map_err(|e| Failure::Input(e.to_string()))?;
    std::fs::create_dir_all(out).map_err(|e| Failure::Output(format!("{}: {e}", out.display())))?;
    for (i, image) in images.iter().enumerate() {
        let path = out.join(format!("frame_{i:05}.png"));
        write_png(&path, image).map_err(|e| Failure::Output(e.to_string()))?;
    }
    // Pictures of an earlier, longer render would read as this one's.
    pd_io::frames::remove_frames_from(out, images.len())
        .map_err(|e| Failure::Output(e.to_string()))?;
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

/// A run's `metrics.csv` rows; a malformed file is bad input, named with
/// its line.
pub(crate) fn read_metrics(dir: &Path) -> Result<Vec<MetricsRow>, Failure> {
    MetricsRow::read_all(&dir.join(MetricsRow::FILE)).map_err(|e| Failure::Input(e.to_string()))
}

/// `(time, value)` points of one quantity of the rows.
pub(crate) fn series(rows: &[MetricsRow], label: &str, value: fn(&MetricsRow) -> f64) -> Series {
    Series {
        label: label.to_string(),
        points: rows.iter().map(|r| (r.time, value(r))).collect(),
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
    let rows = read_metrics(dir)?;
    let out = dir.join("plots");
    std::fs::create_dir_all(&out)
        .map_err(|e| Failure::Output(format!("{}: {e}", out.display())))?;
    type Curves<'a> = &'a [(&'a str, fn(&MetricsRow) -> f64)];
    let plots: [(&str, &str, &str, Curves<'_>); 3] = [
        (
            "energy",
            "Energy",
            "energy (J)",
            &[
                ("kinetic", |r| r.kinetic),
                ("elastic", |r| r.elastic),
                ("gravity", |r| r.gravity),
                ("total", |r| r.total),
            ],
        ),
        (
            "linear_momentum",
            "Linear momentum",
            "momentum (kg m/s)",
            &[("p_x", |r| r.px), ("p_y", |r| r.py), ("p_z", |r| r.pz)],
        ),
        (
            "angular_momentum",
            "Angular momentum about the origin",
            "angular momentum (kg m^2/s)",
            &[("L_x", |r| r.jx), ("L_y", |r| r.jy), ("L_z", |r| r.jz)],
        ),
    ];
    for (stem, title, y_label, curves) in plots {
        let plot = Plot {
            title: title.to_string(),
            x_label: "time (s)".into(),
            y_label: y_label.to_string(),
            series: curves
                .iter()
                .map(|&(label, value)| series(&rows, label, value))
                .collect(),
        };
        write_plot(&plot, &out, stem)?;
    }
    info!(
        "energy, linear_momentum and angular_momentum (.png, .svg) in {}",
        out.display()
    );
    Ok(())
}
