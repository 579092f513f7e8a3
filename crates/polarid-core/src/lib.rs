//! # polarid-core
//!
//! The pure core of polarid: physics (complex Fresnel reflection, the paper's closed-form
//! degree of linear polarization, the Priest–Meier microfacet pBRDF), Stokes kernels,
//! the (n, k) inversion and classification. No file I/O and no printing: kernels write
//! into caller-owned buffers and return [`Result`].
//!
//! Conventions (geometry, Stokes, angles) are those of the project's
//! `docs/CONVENTIONS.md`: angles are radians inside this crate,
//! `N = n + ik` with `k >= 0`, `S1 = I(0°) − I(90°)`, `S2 = I(45°) − I(135°)`.
//!
//! Equation numbers refer to Thilak, Creusere & Voelz, "Material classification using
//! passive polarimetric imagery", ICIP 2007 (the paper).
#![warn(missing_docs)]

pub mod classify;
mod cpu;
pub mod dop;
pub mod error;
pub mod film;
pub mod fit;
pub mod fresnel;
pub mod geometry;
pub mod map;
pub mod mixed;
pub mod mosaic;
pub mod pbrdf;
pub mod region;
pub mod simulate;
pub mod status;
pub mod stokes;
pub mod sun;
pub mod systematic;

pub use error::{CoreError, Result};
pub use status::FitStatus;
