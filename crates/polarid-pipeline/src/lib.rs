//! # polarid-pipeline
//!
//! polarid's workflows as library functions, called alike by the `polarid` command-line
//! program and the Python package, so that the two front ends agree by construction.
//!
//! Every workflow takes a validated configuration (built and checked before any work,
//! in the manner of ripgrep's flags), reports progress through a [`Progress`] callback,
//! and returns its data together with [`Warning`]s. Nothing here prints, and nothing
//! here decides where a front end's outputs go: writing tables, images and reports is
//! the caller's job (the functions that must produce files as part of their work, such
//! as the demo's simulated captures, write them where the configuration says).
//!
//! | workflow | module |
//! |---|---|
//! | frames → Stokes images → region DoLP rows | [`measure`] (kernels from `polarid_io::measure`) |
//! | measurement table → one `(n, k)` fit per target | [`fit`] |
//! | a folder of frames → a commented manifest skeleton | [`init`] |
//! | labelled fits → prototypes (model) | [`train`] |
//! | fits → decisions against a model or library | [`classify`] |
//! | leave-one-out evaluation, Wolff's baseline | [`evaluate`] |
//! | refractiveindex.info YAML → a material library for a band | [`library`] |
//! | scene → simulated captures | [`simulate`] |
//! | manifest → per-pixel `(n, k)` and class maps | [`map`] |
//! | a bench and candidate materials → where to put the lamp | [`plan`] |
//! | frames or a DoFP mosaic → Stokes, DoLP, AoLP images per band | [`stokes`] |
//! | the classifier's options, checked once | [`options`] |
//! | the paper's experiment end to end | [`demo`] |
#![warn(missing_docs)]

pub mod classify;
pub mod demo;
pub mod error;
pub mod evaluate;
pub mod fit;
pub mod init;
pub mod library;
pub mod map;
pub mod measure;
pub mod options;
pub mod plan;
pub mod progress;
pub mod simulate;
pub mod stokes;
pub mod train;

pub use error::{PipelineError, Result};
pub use progress::{Progress, Warning};
