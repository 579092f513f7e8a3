//! Integration tests of polarid-core, one module per topic, in one test binary (one link
//! instead of one per file). `tests/loo_memory.rs` stays a binary of its own: it installs
//! a counting global allocator.
//!
//! A new test file `foo.rs` goes in this directory with a line `mod foo;` below.

mod classify_bands;
mod classify_sets;
mod dop_beta_props;
mod fit_acceptance;
mod fit_batch;
mod mixed_props;
mod mixed_sim;
mod mosaic_roundtrip;
mod oracles;
mod physics_props;
mod stokes_roundtrip;
mod sun;
