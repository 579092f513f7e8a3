//! Integration tests of polarid-io, one module per topic, in one test binary (one link
//! instead of one per file).
//!
//! A new test file `foo.rs` goes in this directory with a line `mod foo;` below.

mod bad_input_roundtrip;
mod bit_depth;
mod geometry_manifest;
mod image_io;
mod library_paper;
mod library_yaml;
mod manifest_colour;
mod manifest_validation;
mod measure_api;
mod measure_calibrated;
mod measure_hdr;
mod model_json;
mod opencv_filestorage;
