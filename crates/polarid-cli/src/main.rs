//! `polarid`: material classification from passive polarization images.
//!
//! A thin layer over `polarid-core` and `polarid-io`: argument parsing, progress, and
//! the mapping of errors to exit statuses (0 success, 2 bad input or usage, 1 any other
//! failure), as in `docs/FORMATS.md`.

mod cmd;
mod ctx;
mod render;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

pub use ctx::{BadInput, Ctx};

/// Tell what a shiny surface is made of from passive polarization images.
#[derive(Debug, Parser)]
#[command(name = "polarid", version, about, long_about = None, propagate_version = true)]
struct Cli {
    /// Overwrite existing output files.
    #[arg(long, global = true)]
    force: bool,
    /// No progress bars or informational messages on standard error.
    #[arg(long, short, global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Evaluate the forward model (eq. 9 DoLP, or the full pBRDF) for rows of a CSV file.
    Model(cmd::model::Args),
    /// Compute Stokes, DoLP and AoLP images from polarizer frames or a DoFP mosaic.
    Stokes(cmd::stokes::Args),
    /// Measure each region's DoLP per capture of a manifest.
    Measure(cmd::measure::Args),
    /// Fit the complex index (n, k) of each target to its DoLP measurements.
    Fit(cmd::fit::Args),
    /// Build a classification model (prototypes) from labelled fits.
    Train(cmd::train::Args),
    /// Classify fitted targets against a trained model or a material library.
    Classify(cmd::classify::Args),
    /// Leave-one-out evaluation of the classifier on a labelled set of fits.
    Evaluate(cmd::evaluate::Args),
    /// Build a material library CSV for a wavelength band from refractiveindex.info YAML.
    Library(cmd::library::Args),
    /// Per-pixel (n, k) and material maps.
    Map(cmd::map::Args),
    /// Simulate captures of plates from the pBRDF and a sensor model.
    Simulate(cmd::simulate::Args),
    /// Reproduce the paper's experiment in simulation, end to end, with a report.
    Demo(cmd::demo::Args),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            // clap prints help/version with status 0 and usage errors with status 2.
            e.exit();
        }
    };
    let ctx = Ctx::new(cli.force, cli.quiet);
    let result = match cli.command {
        Command::Model(a) => cmd::model::run(a, &ctx),
        Command::Stokes(a) => cmd::stokes::run(a, &ctx),
        Command::Measure(a) => cmd::measure::run(a, &ctx),
        Command::Fit(a) => cmd::fit::run(a, &ctx),
        Command::Train(a) => cmd::train::run(a, &ctx),
        Command::Classify(a) => cmd::classify::run(a, &ctx),
        Command::Evaluate(a) => cmd::evaluate::run(a, &ctx),
        Command::Library(a) => cmd::library::run(a, &ctx),
        Command::Map(a) => cmd::map::run(a, &ctx),
        Command::Simulate(a) => cmd::simulate::run(a, &ctx),
        Command::Demo(a) => cmd::demo::run(a, &ctx),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("polarid: error: {}", ctx::error_message(&e));
            ExitCode::from(ctx::exit_status(&e))
        }
    }
}
