//! Integration tests of the `polarid` program, one module per topic, in one test binary
//! (one link instead of one per file). `common` holds the helpers they share.
//!
//! A new test file `foo.rs` goes in this directory with a line `mod foo;` below.

mod common;

mod bad_input_matrix;
mod band_reports_cli;
mod bands_cli;
mod capture_walkthrough;
mod classify_cmd;
mod classify_sets_cli;
mod colour_cli;
mod colour_measure_map;
mod commands_page;
mod demo_cmd;
mod e2e_classify;
mod error_chain;
mod evaluate_wolff;
mod explain_messages_cli;
mod fit_cmd;
mod fit_mixed_cli;
mod geometry_manifest;
mod golden_outputs;
mod heldout_proxies;
mod hostile_acceptance;
mod library_cmd;
mod library_names;
mod map_calibrated;
mod map_cmd;
mod map_decide;
mod measure_calibrated_cli;
mod measure_cli;
mod model_cmd;
mod newcomer_traps;
mod partial_failure;
mod plan_cli;
mod reference_region;
mod reliability;
mod renders_bench;
mod renders_colour;
mod renders_measure;
mod same_bench_cli;
mod simulate_calibrated;
mod simulate_cmd;
mod simulate_colour_calibrated;
mod stokes_cli;
mod stokes_colour;
mod stokes_views;
