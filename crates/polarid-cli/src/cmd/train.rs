//! `polarid train FITS.csv -o model.json`: a classification model whose prototypes are the
//! labelled fits (one prototype per target with a `class` and fit status `ok`; several
//! per class allowed), each recording the file, line and target it came from. The work
//! is `polarid_pipeline::train`.

use std::path::PathBuf;

use polarid_io::model::path_relative_to_output;
use polarid_pipeline::classify::read_fits;
use polarid_pipeline::train::{classes, refuse_not_ok, train};

use super::common::PipeResult;
use crate::Ctx;

/// Arguments of `polarid train`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Fits CSV written by `polarid fit`; rows with a `class` are the training set.
    pub fits: PathBuf,
    /// Output model (JSON).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Train on the `ok` labelled fits and skip the others with a warning, instead of
    /// stopping (exit status 2) when a labelled fit's status is not `ok`.
    #[arg(long)]
    pub allow_not_ok: bool,
}

/// Run `polarid train`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let fits = read_fits(&args.fits).cli()?;
    if !args.allow_not_ok {
        refuse_not_ok(&fits, &args.fits).cli()?;
    }
    let file = path_relative_to_output(&args.fits, &args.output);
    let out = train(&fits, &args.fits, &file).cli()?;
    for w in &out.warnings {
        ctx.info(w.to_string());
    }
    let model = &out.model;
    ctx.write_output(Some(&args.output), &[&args.fits], |w, p| model.write(w, p))?;
    let classes = classes(model);
    ctx.info(format!(
        "trained {} prototype(s) of {} class(es) ({}) -> {}",
        model.prototypes.len(),
        classes.len(),
        classes.join(", "),
        args.output.display()
    ));
    Ok(())
}
