//! placeholder (being written)
mod error;
pub mod frames;
pub mod state;
pub mod tetgen;

pub use error::{Error, Result};
