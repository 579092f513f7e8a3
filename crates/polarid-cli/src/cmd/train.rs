//! `polarid train FITS.csv -o model.json`: a classification model whose prototypes are the
//! labelled fits (one prototype per target with a `class` and fit status `ok`; several
//! per class allowed), each recording the file, line and target it came from.

use std::path::{Path, PathBuf};

use polarid_core::classify::check_class_name;
use polarid_io::IoError;
use polarid_io::model::{
    Model, ModelPrototype, PrototypeSource, cov_matrix, path_relative_to_output,
};
use polarid_io::table::fits::FitRow;

use super::classify::{estimate_of, read_fits};
use crate::{BadInput, Ctx};

/// Arguments of `polarid train`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Fits CSV written by `polarid fit`; rows with a `class` are the training set.
    pub fits: PathBuf,
    /// Output model (JSON).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Prototypes from labelled fits: one per row with a `class` and status `ok`, each
/// recording `file` (the fits file as the model should name it), the line and the target.
/// Returns the model and the labelled rows skipped because their status is not `ok`
/// (`target (status, line N)`). Errors (exit status 2) name `fits_path`.
pub fn train_model(
    fits: &[(u64, FitRow)],
    fits_path: &Path,
    file: &str,
) -> anyhow::Result<(Model, Vec<String>)> {
    let mut protos = Vec::new();
    let mut unlabelled = 0usize;
    let mut not_ok: Vec<String> = Vec::new();
    for (line, f) in fits {
        let Some(class) = f.class.as_deref() else {
            unlabelled += 1;
            continue;
        };
        check_class_name(class).map_err(|e| IoError::Csv {
            path: fits_path.to_path_buf(),
            line: *line,
            column: "class".into(),
            value: class.into(),
            reason: e.to_string(),
        })?;
        if !f.status.is_ok() {
            not_ok.push(format!("{} ({}, line {line})", f.target, f.status));
            continue;
        }
        let est = estimate_of(f);
        protos.push(ModelPrototype {
            class: class.to_string(),
            n: f.n,
            k: f.k,
            covariance: est.cov.as_ref().map(cov_matrix),
            category: None,
            source: PrototypeSource {
                file: file.to_string(),
                line: *line,
                target: f.target.clone(),
            },
        });
    }
    if protos.is_empty() {
        let mut msg = format!(
            "{}: nothing to train on: no fit has both a class and status `ok` ({} row(s), {} \
             without a class",
            fits_path.display(),
            fits.len(),
            unlabelled
        );
        if !not_ok.is_empty() {
            msg.push_str(&format!(", labelled but not ok: {}", not_ok.join(", ")));
        }
        msg.push(')');
        return Err(BadInput(msg).into());
    }
    Ok((Model::new(protos), not_ok))
}

/// Run `polarid train`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let fits = read_fits(&args.fits)?;
    let file = path_relative_to_output(&args.fits, &args.output);
    let (model, not_ok) = train_model(&fits, &args.fits, &file)?;
    for s in &not_ok {
        ctx.info(format!("skipped labelled fit {s}: its status is not ok"));
    }
    ctx.write_output(Some(&args.output), &[&args.fits], |w| {
        model.write(w, &args.output)
    })?;
    let mut classes: Vec<&str> = model.prototypes.iter().map(|p| p.class.as_str()).collect();
    classes.sort();
    classes.dedup();
    ctx.info(format!(
        "trained {} prototype(s) of {} class(es) ({}) -> {}",
        model.prototypes.len(),
        classes.len(),
        classes.join(", "),
        args.output.display()
    ));
    Ok(())
}
