//! # polarid-io
//!
//! Files for polarid: grayscale PNG/TIFF frames, float32 TIFF outputs, the capture-set
//! manifest (TOML), the CSV tables of `docs/FORMATS.md`, trained models (JSON),
//! material libraries (CSV, refractiveindex.info YAML) and atomic output writing.
#![warn(missing_docs)]

pub mod atomic;
pub mod bands;
pub mod error;
pub mod frames_dir;
pub mod image;
pub mod library;
pub mod limits;
pub mod manifest;
pub mod measure;
pub mod model;
pub mod rii;
pub mod scene;
pub mod stokes_images;
pub mod suggest;
pub mod surfaces;
pub mod table;
pub mod time;
mod toml_span;

pub use error::{IoError, Result};
