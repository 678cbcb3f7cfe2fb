//! A small software renderer for surface frames: orthographic camera fitted
//! once to every frame of every panel (so the view stays fixed over the
//! run), a ground grid at the lowest point reached, flat Lambert shading of
//! triangles with a z-buffer, and side-by-side labelled panels. Open
//! surfaces (cloth) get a lighter back side and a dark outline along their
//! boundary edges (`sheet.rs`).
//!
//! The world's up axis is `+y` (scenes put gravity along `-y`). Images are
//! drawn at twice the requested size and box-filtered down, which smooths
//! edges.

use plotters::prelude::*;

use crate::image::RgbImage;
use crate::obj::Surface;
pub use crate::scenery::Scenery;
use crate::{Error, Result};

/// The background colour.
pub const BACKGROUND: [u8; 3] = [255, 255, 255];
const GROUND: [u8; 3] = [236, 236, 232];
const GRID: [u8; 3] = [190, 190, 185];
const LINE: [u8; 3] = [40, 40, 40];
/// Colour of static solids (colliders).
const SOLID: [f64; 3] = [175.0, 175.0, 170.0];
/// Body colours of successive panels.
const BODY: [[f64; 3]; 5] = [
    [70.0, 120.0, 190.0],
    [200.0, 95.0, 60.0],
    [70.0, 160.0, 90.0],
    [150.0, 90.0, 170.0],
    [190.0, 160.0, 50.0],
];
/// Supersampling factor per axis.
const SUPERSAMPLE: u32 = 2;

/// The most memory one [`render_panels`] call may take, bytes: every
/// frame's picture (3 bytes a pixel, all kept for the caller) and one
/// panel's supersampled canvas with its depth buffer (11 bytes a sample).
pub const MAX_RENDER_BYTES: u64 = 4 << 30;

/// [`Error::Input`] if `count` frames of `panels` panels of `width x
/// height` pixels are empty or would take more than [`MAX_RENDER_BYTES`].
fn check_size(panels: usize, count: usize, width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::Input(format!(
            "a picture needs a positive size, got {width} x {height} pixels"
        )));
    }
    let pixels = u64::from(width) * u64::from(height);
    let pictures = (pixels * 3)
        .saturating_mul(panels as u64)
        .saturating_mul(count as u64);
    let canvas = pixels * u64::from(SUPERSAMPLE * SUPERSAMPLE) * 11;
    let bytes = pictures.saturating_add(canvas);
    if bytes > MAX_RENDER_BYTES {
        return Err(Error::Input(format!(
            "{count} frame(s) of {panels} panel(s) at {width} x {height} pixels would take \
             {:.1} GB of memory, more than the {} GB allowed; draw smaller pictures",
            bytes as f64 / 1e9,
            MAX_RENDER_BYTES >> 30
        )));
    }
    Ok(())
}

/// One panel: a label and a sequence of frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// Drawn at the panel's top left (empty: none).
    pub label: String,
    /// The frames, in time order.
    pub frames: Vec<Surface>,
}

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn normalised(a: V3) -> V3 {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

/// An orthographic camera looking at the scene from the front right and
/// above, and the ground grid, both fixed for a whole animation.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    right: V3,
    up: V3,
    towards_eye: V3,
    /// Screen coordinates of the fitted box's centre, before scaling.
    centre: [f64; 2],
    /// Pixels per metre at the supersampled size.
    scale: f64,
    size: (u32, u32),
    ground_y: f64,
    /// Ground rectangle in x and z: min and max.
    ground: [f64; 4],
    grid_step: f64,
}

impl Camera {
    /// Fits the camera to every vertex of every frame of every panel, for
    /// panels of `width x height` pixels.
    ///
    /// # Errors
    /// [`Error::Input`] if there is no vertex at all or the size is zero.
    pub fn fit(panels: &[Panel], width: u32, height: u32) -> Result<Self> {
        Self::fit_with(panels, &Scenery::default(), width, height)
    }

    /// [`Camera::fit`] that also fits the scenery's solids and puts the
    /// ground grid at the scenery's ground height when it has one.
    ///
    /// # Errors
    /// As [`Camera::fit`].
    pub fn fit_with(panels: &[Panel], scenery: &Scenery, width: u32, height: u32) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::Input("the image size must be positive".into()));
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in panels
            .iter()
            .flat_map(|panel| &panel.frames)
            .flat_map(|f| &f.positions)
        {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if !lo[0].is_finite() {
            return Err(Error::Input("the frames have no vertices to draw".into()));
        }
        scenery.widen(&mut lo, &mut hi);
        let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max).max(1e-9);
        let margin = 0.25 * extent;
        let ground = [
            lo[0] - margin,
            hi[0] + margin,
            lo[2] - margin,
            hi[2] + margin,
        ];
        let grid_step = nice_step((ground[1] - ground[0]).max(ground[3] - ground[2]) / 8.0);
        let towards_eye = normalised([0.6, 0.5, 1.0]);
        let right = normalised(cross([0.0, 1.0, 0.0], towards_eye));
        let up = cross(towards_eye, right);
        let mut camera = Self {
            right,
            up,
            towards_eye,
            centre: [0.0; 2],
            scale: 1.0,
            size: (width * SUPERSAMPLE, height * SUPERSAMPLE),
            ground_y: scenery.ground.unwrap_or(lo[1]),
            ground,
            grid_step,
        };
        // Fit the box of the bodies and the ground rectangle.
        let mut s_lo = [f64::INFINITY; 2];
        let mut s_hi = [f64::NEG_INFINITY; 2];
        let corners = (0..8).map(|i| {
            [
                if i & 1 == 0 { ground[0] } else { ground[1] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { ground[2] } else { ground[3] },
            ]
        });
        for c in corners {
            let s = [dot(c, right), dot(c, up)];
            for k in 0..2 {
                s_lo[k] = s_lo[k].min(s[k]);
                s_hi[k] = s_hi[k].max(s[k]);
            }
        }
        camera.centre = [0.5 * (s_lo[0] + s_hi[0]), 0.5 * (s_lo[1] + s_hi[1])];
        let (w, h) = (f64::from(camera.size.0), f64::from(camera.size.1));
        // 5% margin around, and room at the top for the label.
        camera.scale = (0.9 * w / (s_hi[0] - s_lo[0]).max(1e-12))
            .min(0.82 * h / (s_hi[1] - s_lo[1]).max(1e-12));
        Ok(camera)
    }

    /// Screen position (pixels, y down) and depth (larger is nearer).
    fn project(&self, p: V3) -> (f64, f64, f64) {
        let (w, h) = (f64::from(self.size.0), f64::from(self.size.1));
        let x = 0.5 * w + (dot(p, self.right) - self.centre[0]) * self.scale;
        // Shifted down a little to leave the top for the label.
        let y = 0.54 * h - (dot(p, self.up) - self.centre[1]) * self.scale;
        (x, y, dot(p, self.towards_eye))
    }
}

/// 1, 2 or 5 times a power of ten, at least `raw`.
fn nice_step(raw: f64) -> f64 {
    let power = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * power)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * power)
}

struct Canvas {
    image: RgbImage,
    depth: Vec<f64>,
}

impl Canvas {
    fn triangle(
        &mut self,
        a: (f64, f64, f64),
        b: (f64, f64, f64),
        c: (f64, f64, f64),
        colour: [u8; 3],
        depth_test: bool,
    ) {
        let area = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
        if area.abs() < 1e-12 {
            return;
        }
        let (w, h) = (self.image.width as i64, self.image.height as i64);
        let x0 = (a.0.min(b.0).min(c.0).floor() as i64).max(0);
        let x1 = (a.0.max(b.0).max(c.0).ceil() as i64).min(w - 1);
        let y0 = (a.1.min(b.1).min(c.1).floor() as i64).max(0);
        let y1 = (a.1.max(b.1).max(c.1).ceil() as i64).min(h - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let w0 = ((b.0 - px) * (c.1 - py) - (b.1 - py) * (c.0 - px)) / area;
                let w1 = ((c.0 - px) * (a.1 - py) - (c.1 - py) * (a.0 - px)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let i = (y * w + x) as usize;
                let z = w0 * a.2 + w1 * b.2 + w2 * c.2;
                if depth_test {
                    if z <= self.depth[i] {
                        continue;
                    }
                    self.depth[i] = z;
                }
                self.image.set(x, y, colour);
            }
        }
    }

    fn line(
        &mut self,
        a: (f64, f64, f64),
        b: (f64, f64, f64),
        colour: [u8; 3],
        radius: i64,
        depth_test: bool,
    ) {
        let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
        let (w, h) = (self.image.width as i64, self.image.height as i64);
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let (x, y, z) = (
                a.0 + t * (b.0 - a.0),
                a.1 + t * (b.1 - a.1),
                a.2 + t * (b.2 - a.2),
            );
            for dy in -radius..=radius {
                for dx in -radius..=radius {
                    let (px, py) = (x.floor() as i64 + dx, y.floor() as i64 + dy);
                    if px < 0 || py < 0 || px >= w || py >= h {
                        continue;
                    }
                    let i = (py * w + px) as usize;
                    if depth_test {
                        // Slightly in front, so lines on a surface show.
                        if z + 1e-6 < self.depth[i] {
                            continue;
                        }
                        self.depth[i] = z;
                    }
                    self.image.set(px, py, colour);
                }
            }
        }
    }
}

/// Draws one surface with the camera into a panel-sized image.
pub fn render_surface(camera: &Camera, surface: &Surface, body: usize) -> RgbImage {
    render_surface_with(camera, surface, body, &Scenery::default())
}

/// [`render_surface`] with the scenery's solids drawn (grey) behind and
/// around the body.
pub fn render_surface_with(
    camera: &Camera,
    surface: &Surface,
    body: usize,
    scenery: &Scenery,
) -> RgbImage {
    let (w, h) = camera.size;
    let mut canvas = Canvas {
        image: RgbImage::filled(w, h, BACKGROUND),
        depth: vec![f64::NEG_INFINITY; (w * h) as usize],
    };
    // The ground: a filled rectangle and grid lines, drawn first and without
    // depth, as everything lies above it.
    let g = camera.ground;
    let y = camera.ground_y;
    let corner = |x: f64, z: f64| camera.project([x, y, z]);
    canvas.triangle(
        corner(g[0], g[2]),
        corner(g[1], g[2]),
        corner(g[1], g[3]),
        GROUND,
        false,
    );
    canvas.triangle(
        corner(g[0], g[2]),
        corner(g[1], g[3]),
        corner(g[0], g[3]),
        GROUND,
        false,
    );
    let step = camera.grid_step;
    let mut x = (g[0] / step).ceil() * step;
    while x <= g[1] {
        canvas.line(corner(x, g[2]), corner(x, g[3]), GRID, 0, false);
        x += step;
    }
    let mut z = (g[2] / step).ceil() * step;
    while z <= g[3] {
        canvas.line(corner(g[0], z), corner(g[1], z), GRID, 0, false);
        z += step;
    }

    let light = normalised([0.35, 1.0, 0.6]);
    for solid in &scenery.solids {
        draw_solid(&mut canvas, camera, solid, light);
    }
    let base = BODY[body % BODY.len()];
    let projected: Vec<_> = surface
        .positions
        .iter()
        .map(|&p| camera.project(p))
        .collect();
    // An open surface (cloth) shows its back side lighter and its boundary.
    let open = crate::sheet::open_edges(&surface.triangles);
    for t in &surface.triangles {
        let [a, b, c] = t.map(|i| surface.positions[i]);
        let n = cross(sub(b, a), sub(c, a));
        let len = dot(n, n).sqrt();
        if !(len > 0.0) {
            continue;
        }
        // Two-sided Lambert shading with an ambient term.
        let lambert = (dot(n, light) / len).abs();
        // A hanging sheet is mostly edge-on to the light: more ambient.
        let shade = if open.is_empty() {
            0.3 + 0.7 * lambert
        } else {
            0.5 + 0.5 * lambert
        };
        let side = if !open.is_empty() && dot(n, camera.towards_eye) < 0.0 {
            crate::sheet::back_side(base)
        } else {
            base
        };
        let colour = side.map(|c| (c * shade).round().clamp(0.0, 255.0) as u8);
        canvas.triangle(
            projected[t[0]],
            projected[t[1]],
            projected[t[2]],
            colour,
            true,
        );
    }
    for e in &open {
        canvas.line(
            projected[e[0]],
            projected[e[1]],
            crate::sheet::outline(base),
            SUPERSAMPLE as i64 / 2,
            true,
        );
    }
    for l in &surface.lines {
        canvas.line(
            projected[l[0]],
            projected[l[1]],
            LINE,
            SUPERSAMPLE as i64,
            true,
        );
    }
    canvas.image.downscaled(SUPERSAMPLE)
}

/// Renders every frame index of side-by-side panels (panels with fewer
/// frames keep showing their last one), each panel `width x height`, with
/// its label. One camera is fitted to all frames of all panels.
///
/// # Errors
/// [`Error::Input`] for no panels, a panel without frames, nothing to
/// draw, or pictures of no pixels or too large to hold
/// ([`MAX_RENDER_BYTES`]); [`Error::Encode`] if drawing a label fails.
pub fn render_panels(panels: &[Panel], width: u32, height: u32) -> Result<Vec<RgbImage>> {
    render_panels_with(panels, &Scenery::default(), width, height)
}

/// [`render_panels`] with the static scenery (colliders) in every panel.
///
/// # Errors
/// As [`render_panels`].
pub fn render_panels_with(
    panels: &[Panel],
    scenery: &Scenery,
    width: u32,
    height: u32,
) -> Result<Vec<RgbImage>> {
    if panels.is_empty() {
        return Err(Error::Input("no panels to render".into()));
    }
    if let Some(empty) = panels.iter().find(|p| p.frames.is_empty()) {
        return Err(Error::Input(format!(
            "panel {:?} has no frames",
            empty.label
        )));
    }
    let count = panels.iter().map(|p| p.frames.len()).max().unwrap_or(0);
    check_size(panels.len(), count, width, height)?;
    let camera = Camera::fit_with(panels, scenery, width, height)?;
    let total_width = width * panels.len() as u32;
    let mut images = Vec::with_capacity(count);
    for frame in 0..count {
        let mut image = RgbImage::filled(total_width, height, BACKGROUND);
        for (k, panel) in panels.iter().enumerate() {
            let surface = &panel.frames[frame.min(panel.frames.len() - 1)];
            let picture = render_surface_with(&camera, surface, k, scenery);
            image.blit(&picture, k as u32 * width, 0);
        }
        draw_labels(&mut image, panels, width)?;
        images.push(image);
    }
    Ok(images)
}

/// A static solid: grey Lambert shading, depth-tested; only the faces
/// turned towards the camera are drawn (a closed solid's outside; the
/// inside of an open bowl, whose normals point into it).
fn draw_solid(canvas: &mut Canvas, camera: &Camera, solid: &Surface, light: V3) {
    let projected: Vec<_> = solid.positions.iter().map(|&p| camera.project(p)).collect();
    for t in &solid.triangles {
        let [a, b, c] = t.map(|i| solid.positions[i]);
        let n = cross(sub(b, a), sub(c, a));
        let len = dot(n, n).sqrt();
        if !(len > 0.0) || dot(n, camera.towards_eye) <= 0.0 {
            continue;
        }
        let shade = 0.55 + 0.45 * (dot(n, light) / len).abs();
        let colour = SOLID.map(|c| (c * shade).round().clamp(0.0, 255.0) as u8);
        let [pa, pb, pc] = t.map(|i| projected[i]);
        canvas.triangle(pa, pb, pc, colour, true);
    }
}

fn draw_labels(image: &mut RgbImage, panels: &[Panel], width: u32) -> Result<()> {
    crate::register_font();
    let size = (image.width, image.height);
    let font_px = (f64::from(image.height) / 18.0).clamp(10.0, 24.0);
    let backend = BitMapBackend::with_buffer(&mut image.data, size);
    let area = backend.into_drawing_area();
    for (k, panel) in panels.iter().enumerate() {
        if panel.label.is_empty() {
            continue;
        }
        let style = (crate::FONT_FAMILY, font_px).into_font().color(&BLACK);
        area.draw(&Text::new(
            panel.label.clone(),
            (k as i32 * width as i32 + 8, 6),
            style,
        ))
        .map_err(|e| Error::Encode {
            path: "label".into(),
            message: e.to_string(),
        })?;
        if k > 0 {
            let x = k as i32 * width as i32;
            area.draw(&PathElement::new(
                vec![(x, 0), (x, size.1 as i32)],
                RGBColor(160, 160, 160),
            ))
            .map_err(|e| Error::Encode {
                path: "panel border".into(),
                message: e.to_string(),
            })?;
        }
    }
    area.present().map_err(|e| Error::Encode {
        path: "label".into(),
        message: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(y: f64) -> Surface {
        Surface {
            positions: vec![
                [0.0, y, 0.0],
                [1.0, y, 0.0],
                [1.0, y + 1.0, 0.0],
                [0.0, y + 1.0, 0.0],
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            lines: vec![],
        }
    }

    #[test]
    fn the_body_is_visible_and_moves() {
        let panel = Panel {
            label: "test".into(),
            frames: vec![square(0.0), square(-1.0)],
        };
        let images = render_panels(&[panel], 120, 90).unwrap();
        assert_eq!(images.len(), 2);
        let body = |img: &RgbImage| {
            img.data
                .chunks_exact(3)
                .filter(|p| u16::from(p[2]) > u16::from(p[0]) + 40) // bluish: the first body colour
                .count()
        };
        // A unit square seen at ~30 degrees in a frame about 2.5 m wide
        // covers several hundred of the 10800 pixels.
        assert!(body(&images[0]) > 200, "{}", body(&images[0]));
        assert_ne!(images[0], images[1]);
    }

    #[test]
    fn the_nearer_triangle_hides_the_farther() {
        // Two overlapping squares facing the camera's side; the one at
        // larger z (nearer the eye) must win whatever the drawing order.
        let mut s = square(0.0);
        // Tilted, so that its shade differs from the first square's.
        s.positions.extend([
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.5],
            [1.0, 1.0, 1.5],
            [0.0, 1.0, 1.0],
        ]);
        s.triangles.extend([[4, 5, 6], [4, 6, 7]]);
        let mut reversed = s.clone();
        reversed.triangles.reverse();
        let panels = |s: Surface| {
            vec![Panel {
                label: String::new(),
                frames: vec![s],
            }]
        };
        let a = render_panels(&panels(s), 100, 100).unwrap();
        let b = render_panels(&panels(reversed), 100, 100).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn nothing_to_draw_is_an_error() {
        let empty = Panel {
            label: "x".into(),
            frames: vec![Surface::default()],
        };
        assert!(render_panels(&[empty], 10, 10).is_err());
        assert!(render_panels(&[], 10, 10).is_err());
    }
}
