//! RGB images, PNG and animated GIF files.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use crate::{Error, Result};

/// An 8-bit RGB image, rows top to bottom.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 * width * height` bytes.
    pub data: Vec<u8>,
}

impl RgbImage {
    /// An image filled with one colour.
    pub fn filled(width: u32, height: u32, colour: [u8; 3]) -> Self {
        let data = colour
            .iter()
            .copied()
            .cycle()
            .take(3 * width as usize * height as usize)
            .collect();
        Self {
            width,
            height,
            data,
        }
    }

    /// The pixel at column `x`, row `y`.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// Sets a pixel; coordinates outside the image are ignored.
    pub fn set(&mut self, x: i64, y: i64, colour: [u8; 3]) {
        if x >= 0 && y >= 0 && x < i64::from(self.width) && y < i64::from(self.height) {
            let i = 3 * (y as usize * self.width as usize + x as usize);
            self.data[i..i + 3].copy_from_slice(&colour);
        }
    }

    /// Places `other` with its top left corner at `(x, y)` (clipped).
    pub fn blit(&mut self, other: &RgbImage, x: u32, y: u32) {
        for row in 0..other.height {
            for col in 0..other.width {
                self.set(
                    i64::from(x + col),
                    i64::from(y + row),
                    other.pixel(col, row),
                );
            }
        }
    }

    /// The image shrunk by an integer `factor` (box filter: each output
    /// pixel is the mean of a `factor x factor` block).
    pub fn downscaled(&self, factor: u32) -> RgbImage {
        let factor = factor.max(1);
        let (w, h) = (self.width / factor, self.height / factor);
        let mut out = RgbImage::filled(w.max(1), h.max(1), [0; 3]);
        for y in 0..out.height {
            for x in 0..out.width {
                let mut sum = [0u32; 3];
                for dy in 0..factor {
                    for dx in 0..factor {
                        let p = self.pixel(
                            (x * factor + dx).min(self.width - 1),
                            (y * factor + dy).min(self.height - 1),
                        );
                        for k in 0..3 {
                            sum[k] += u32::from(p[k]);
                        }
                    }
                }
                let n = factor * factor;
                out.set(
                    i64::from(x),
                    i64::from(y),
                    sum.map(|s| ((s + n / 2) / n) as u8),
                );
            }
        }
        out
    }

    /// Number of pixels that differ from `colour`.
    pub fn count_not(&self, colour: [u8; 3]) -> usize {
        self.data.chunks_exact(3).filter(|p| *p != colour).count()
    }
}

fn create(path: &Path) -> Result<BufWriter<File>> {
    File::create(path)
        .map(BufWriter::new)
        .map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })
}

fn encode_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Encode {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Writes an image as an 8-bit RGB PNG.
///
/// # Errors
/// [`Error::Io`] or [`Error::Encode`] naming the file.
pub fn write_png(path: &Path, image: &RgbImage) -> Result<()> {
    let mut encoder = png::Encoder::new(create(path)?, image.width, image.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| encode_error(path, e))?;
    writer
        .write_image_data(&image.data)
        .map_err(|e| encode_error(path, e))?;
    writer.finish().map_err(|e| encode_error(path, e))
}

/// Writes frames of equal size as a looping animated GIF, each shown for
/// `delay_cs` hundredths of a second (colours quantised per frame).
///
/// # Errors
/// [`Error::Input`] for no frames, frames of different sizes or larger
/// than 65535 pixels; [`Error::Io`] or [`Error::Encode`] naming the file.
pub fn write_gif(path: &Path, frames: &[RgbImage], delay_cs: u16) -> Result<()> {
    let Some(first) = frames.first() else {
        return Err(Error::Input("no frames to animate".into()));
    };
    let (Ok(w), Ok(h)) = (u16::try_from(first.width), u16::try_from(first.height)) else {
        return Err(Error::Input("the GIF is too large".into()));
    };
    if frames
        .iter()
        .any(|f| (f.width, f.height) != (first.width, first.height))
    {
        return Err(Error::Input("GIF frames differ in size".into()));
    }
    let mut encoder =
        gif::Encoder::new(create(path)?, w, h, &[]).map_err(|e| encode_error(path, e))?;
    encoder
        .set_repeat(gif::Repeat::Infinite)
        .map_err(|e| encode_error(path, e))?;
    for image in frames {
        // Speed 10 (of 1..=30) is NeuQuant's default balance of quality
        // and time.
        let mut frame = gif::Frame::from_rgb_speed(w, h, &image.data, 10);
        frame.delay = delay_cs;
        encoder
            .write_frame(&frame)
            .map_err(|e| encode_error(path, e))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downscaling_averages_blocks() {
        let mut img = RgbImage::filled(4, 2, [0; 3]);
        img.set(0, 0, [200, 100, 40]);
        img.set(1, 1, [200, 100, 40]);
        let small = img.downscaled(2);
        assert_eq!((small.width, small.height), (2, 1));
        assert_eq!(small.pixel(0, 0), [100, 50, 20]);
        assert_eq!(small.pixel(1, 0), [0, 0, 0]);
    }
}
