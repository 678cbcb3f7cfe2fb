//! Pictures of pd runs, pure Rust and headless (no system libraries):
//!
//! - [`render`]: a small z-buffer rasteriser that draws surface frames
//!   (flat Lambert shading, an orthographic camera fitted once to every
//!   frame, a ground grid, side-by-side labelled panels), and
//!   [`image`]: RGB images written as PNG and animated GIF;
//! - [`plot`]: line plots of time series as PNG and SVG (plotters).
//!
//! Text is drawn with the DejaVu Sans Mono font embedded from
//! `assets/DejaVuSansMono.ttf` (Bitstream Vera licence, in
//! `assets/DejaVu-LICENSE.txt`): plotters' bitmap backend needs a font at
//! run time, and embedding one keeps pictures identical on every machine.
//!
//! This crate is used by the `pd` command line only; the computational
//! crates do not depend on it.

pub mod image;
pub mod obj;
pub mod plot;
pub mod render;
pub mod scenery;
mod sheet;

use std::path::PathBuf;

/// The font every picture uses.
const FONT: &[u8] = include_bytes!("../assets/DejaVuSansMono.ttf");
/// The family name the font is registered under.
const FONT_FAMILY: &str = "sans-serif";

/// Registers the embedded font with plotters (once; later calls do nothing).
fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The embedded font is a valid TrueType file (a test draws with it).
        let _ =
            plotters::style::register_font(FONT_FAMILY, plotters::style::FontStyle::Normal, FONT);
    });
}

/// Errors of reading frames and writing pictures.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A frame file is malformed.
    #[error("{}:{line}: {message}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Nothing to draw, or inconsistent input.
    #[error("{0}")]
    Input(String),
    /// Encoding or drawing failed.
    #[error("{}: {message}", path.display())]
    Encode {
        /// The file being written.
        path: PathBuf,
        /// What failed.
        message: String,
    },
}

/// Results of this crate.
pub type Result<T> = std::result::Result<T, Error>;
