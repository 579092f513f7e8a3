//! Integration tests of polarid-pipeline, one module per topic, in one test binary (one
//! link instead of one per file).
//!
//! A new test file `foo.rs` goes in this directory with a line `mod foo;` below.

mod bands_classify;
mod colour_measure;
mod fit_choices;
mod fit_train_classify;
mod hypothesis_study;
mod imperfect_acceptance;
mod measure_fit_calibrated;
mod paper_acceptance;
mod pixel_hypothesis;
mod plan;
mod reference_region;
mod systematic_errors;
