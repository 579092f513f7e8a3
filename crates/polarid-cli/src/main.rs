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
#[command(name = "polarid", version, long_about = None, propagate_version = true)]
struct Cli {
    /// Overwrite existing output files.
    #[arg(long, global = true)]
    force: bool,
    /// No progress bars or informational messages on standard error.
    #[arg(long, short, global = true)]
    quiet: bool,
    /// Memory budget of the run, e.g. 8G or 512M (default 4G, or the environment
    /// variable POLARID_MEMORY_LIMIT): larger frames and inputs are refused before they
    /// are read (docs/RELIABILITY.md).
    #[arg(long, global = true, value_name = "SIZE", value_parser = polarid_io::limits::parse_size)]
    memory_limit: Option<u64>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Evaluate the forward model (eq. 9 DoLP, or the full pBRDF) for rows of a CSV file.
    Model(cmd::model::Args),
    /// Compute Stokes, DoLP and AoLP images from polarizer frames or a DoFP mosaic.
    Stokes(cmd::stokes::Args),
    /// Write a commented manifest skeleton from a folder of frames.
    Init(cmd::init::Args),
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
    /// Plan the captures: which materials the bench's source positions can tell apart,
    /// and where to put the lamp.
    Plan(cmd::plan::Args),
    /// Reproduce the paper's experiment in simulation, end to end, with a report.
    Demo(cmd::demo::Args),
}

/// Remove the run's staging, say so, and exit with 128 + the signal's number.
fn stop_after_signal(sig: i32) -> ! {
    polarid_io::atomic::remove_registered();
    eprintln!("polarid: interrupted; partial outputs removed");
    std::process::exit(polarid_io::atomic::exit_status_of_signal(sig));
}

/// Remove the run's staging directories and temporary files on SIGINT, SIGTERM and
/// SIGHUP, then exit with status 128 + the signal's number: 130, 143, 129
/// (docs/RELIABILITY.md).
fn install_signal_handler() {
    #[cfg(unix)]
    let _ = polarid_io::atomic::on_termination_signal(|sig| stop_after_signal(sig));
    #[cfg(not(unix))]
    let _ = ctrlc::set_handler(|| {
        // Ctrl-C: SIGINT's number (2), as the shell would report it.
        polarid_io::atomic::note_signal_received(2);
        stop_after_signal(2)
    });
}

/// Bytes a command keeps per pixel of an input frame besides the frame (for the memory
/// budget, `polarid_io::limits::work_per_pixel`).
fn work_per_pixel(c: &Command) -> u64 {
    match c {
        // S0, S1, S2, DoLP, AoLP (f32), a mask, two RGB views.
        Command::Stokes(_) => 5 * 4 + 1 + 2 * 3,
        // S0, S1, S2 (f32) and a mask per capture, then per output pixel the DoLP of
        // every capture and the maps (n, k, errors, classes): 16 f32 planes in all.
        Command::Map(_) => 16 * 4,
        // Stokes planes and masks of a capture, per-region statistics.
        Command::Measure(_) | Command::Demo(_) | Command::Simulate(_) => 4 * 4,
        _ => 0,
    }
}

fn main() -> ExitCode {
    install_signal_handler();
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            // clap prints help/version with status 0 and usage errors with status 2.
            e.exit();
        }
    };
    let env_limit = std::env::var(polarid_io::limits::MEMORY_LIMIT_ENV).ok();
    let limit = match (cli.memory_limit, env_limit) {
        (Some(b), _) => b,
        (None, Some(v)) => match polarid_io::limits::parse_size(&v) {
            Ok(b) => b,
            Err(e) => {
                eprintln!(
                    "polarid: error: {}: {e}",
                    polarid_io::limits::MEMORY_LIMIT_ENV
                );
                return ExitCode::from(2);
            }
        },
        (None, None) => polarid_io::limits::DEFAULT_MEMORY_LIMIT,
    };
    polarid_io::limits::set_memory_limit(limit);
    polarid_io::limits::set_work_per_pixel(work_per_pixel(&cli.command));
    let ctx = Ctx::new(cli.force, cli.quiet);
    let result = match cli.command {
        Command::Model(a) => cmd::model::run(a, &ctx),
        Command::Stokes(a) => cmd::stokes::run(a, &ctx),
        Command::Init(a) => cmd::init::run(a, &ctx),
        Command::Measure(a) => cmd::measure::run(a, &ctx),
        Command::Fit(a) => cmd::fit::run(a, &ctx),
        Command::Train(a) => cmd::train::run(a, &ctx),
        Command::Classify(a) => cmd::classify::run(a, &ctx),
        Command::Evaluate(a) => cmd::evaluate::run(a, &ctx),
        Command::Library(a) => cmd::library::run(a, &ctx),
        Command::Map(a) => cmd::map::run(a, &ctx),
        Command::Simulate(a) => cmd::simulate::run(a, &ctx),
        Command::Plan(a) => cmd::plan::run(a, &ctx),
        Command::Demo(a) => cmd::demo::run(a, &ctx),
    };
    if polarid_io::atomic::terminating() {
        // A signal arrived: its handler is removing the staging (this thread may have
        // failed because of it); finish the cleaning here and exit as the handler would.
        stop_after_signal(polarid_io::atomic::signal_received().unwrap_or(2));
    }
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // The error and its causes, joined by `: ` (the text the Python package raises
            // too): each level is printed once.
            let msg = polarid_io::error::chain_message(e.as_ref());
            eprintln!("polarid: error: {msg}");
            ExitCode::from(ctx::exit_status(&e))
        }
    }
}
