//! Python bindings of polarid (the extension module `polarid._polarid`).
//!
//! Layout: one Rust module per topic, each with a `register(m)` function that adds its
//! `#[pyfunction]`s to the extension module (`model.rs`: the eq. (9) forward model;
//! `stokes.rs`: Stokes/DoFP/DoLP/AoLP images; `colour.rs`: colour DoFP mosaics per band; `pbrdf.rs`: eq. (3); `fit.rs`: the
//! `(n, k)` fit; `classify.rs`; `files.rs`: manifests and `measure`; `simulate.rs`; `block.rs`: one block of a map
//! (single-band or colour), for `polarid.dask`). Shared pieces: `errors.rs` (the
//! one mapping of `CoreError`/`IoError` to Python exceptions) and `arrays.rs` (array-like
//! arguments, broadcasting, zero-copy output). The pure-Python package `polarid`
//! (`python/polarid/`) re-exports the functions and carries the type stubs.

#![warn(missing_docs)]

use pyo3::prelude::*;

pub mod arrays;
pub mod block;
pub mod classify;
pub mod colour;
pub mod errors;
pub mod files;
pub mod fit;
pub mod map;
pub mod mixed;
pub mod model;
pub mod pbrdf;
pub mod simulate;
pub mod stokes;

/// `dict[name] = value.name` for each named field of `value` (`set_fields!(d, f, n, k)`
/// sets `d["n"] = f.n`, `d["k"] = f.k`), in that order.
#[macro_export]
macro_rules! set_fields {
    ($d:expr, $v:expr, $($field:ident),+ $(,)?) => {
        $($d.set_item(stringify!($field), &$v.$field)?;)+
    };
}

/// Recover the complex refractive index of shiny surfaces from passive polarization
/// images, and classify the material (Rust extension module of `polarid`).
#[pymodule]
fn _polarid(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    model::register(m)?;
    stokes::register(m)?;
    colour::register(m)?;
    pbrdf::register(m)?;
    fit::register(m)?;
    mixed::register(m)?;
    classify::register(m)?;
    files::register(m)?;
    simulate::register(m)?;
    map::register(m)?;
    block::register(m)?;
    m.add("_MAP_DEFAULTS", map_defaults(m.py())?)?;
    Ok(())
}

/// The defaults of `polarid map`'s options that `polarid.dask` repeats in its
/// signature (the pipeline's [`polarid_pipeline::map::MapErrors::default`] and
/// [`polarid_pipeline::map::DEFAULT_TILE`]), so that Python reads them from Rust.
fn map_defaults(py: Python<'_>) -> PyResult<Bound<'_, pyo3::types::PyDict>> {
    let e = polarid_pipeline::map::MapErrors::default();
    let d = pyo3::types::PyDict::new(py);
    d.set_item("angle_sd_deg", e.angle_sd_deg)?;
    d.set_item("dolp_floor", e.dolp_floor)?;
    d.set_item("extinction_ratio", e.extinction_ratio)?;
    d.set_item("retardance_deg", e.retardance_deg)?;
    d.set_item("tile", polarid_pipeline::map::DEFAULT_TILE)?;
    Ok(d)
}
