//! `polarid classify FITS.csv (--model M | --library L) [-o out.csv]`: classify fitted
//! targets against a trained model or a material library (paper section 6), optionally
//! with Wolff's metal/dielectric baseline computed from the measurements. The work is
//! `polarid_pipeline::classify`.
//!
//! Given a measurements table instead (columns `dolp` and `beta_deg` or `theta_i_deg`, no
//! `n`), each target is fitted and every material is tested directly against its rows
//! (`polarid_pipeline::classify::rows`, docs/CLASSIFY.md); `--rule nearest` fits and
//! applies the paper's rule to the fits.

use std::path::{Path, PathBuf};

use polarid_io::table::classification;
use polarid_pipeline::classify::{self as pipe, ClassifyConfig, PrototypeSource, read_fits};

pub use super::common::MetricArg;
use super::common::{MethodArgs, PipeResult};
use super::wolff::WolffArgs;
use crate::Ctx;
use crate::render::table_report::{self, References};

/// Arguments of `polarid classify`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("prototypes").required(true).args(["model", "library"])))]
pub struct Args {
    /// Fits CSV written by `polarid fit`, or a measurements CSV (`polarid measure`; then
    /// every material is tested against the measured rows, docs/CLASSIFY.md).
    pub fits: PathBuf,
    /// Trained model (JSON) written by `polarid train`.
    #[arg(long, value_name = "MODEL.json")]
    pub model: Option<PathBuf>,
    /// Material library: `builtin` (39 materials at 650 nm, refractiveindex.info),
    /// `paper2007` (the paper's Table 1 references) or a CSV file `name,n,k[,category]`
    /// (`n_band`, `k_band` are used when `n`, `k` are absent).
    #[arg(long, value_name = "LIB")]
    pub library: Option<String>,
    /// Output CSV (default: standard output).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub method: MethodArgs,
    #[command(flatten)]
    pub wolff: WolffArgs,
    /// How many nearest prototypes to list per target in the explanation (standard error);
    /// the consistent set is listed whole, with the confidence region(s) that decide it
    /// (the range of n and k they span; docs/CLASSIFY.md).
    #[arg(long, default_value_t = 3)]
    pub explain: usize,
    /// Wavelength (nm) of the fit rows that carry no `wavelength_nm`. The built-in
    /// libraries are evaluated at the fits' wavelengths (docs/CLASSIFY.md "Wavelength");
    /// fits without one are compared with `builtin`'s 650 nm values.
    #[arg(long, value_name = "NM")]
    pub wavelength_nm: Option<f64>,
    /// Where the model was trained: `same` (the default) — on the bench the fits come
    /// from, whose shared errors (angles, DoLP floor, extinction) cancel: the estimate's
    /// noise against each prototype's noise and surface-layer variation; `other` — another
    /// bench: both sides' total covariance (docs/CLASSIFY.md "Trained models"). No effect
    /// with --library.
    #[arg(long, value_enum, default_value_t = BenchArg::Same)]
    pub bench: BenchArg,
    /// Prior weight of a material for the tests against measured rows, `NAME=W` (W >= 0;
    /// repeatable; materials not named weigh 1).
    #[arg(long = "prior", value_name = "NAME=W", value_parser = parse_prior)]
    pub priors: Vec<(String, f64)>,
    /// `--report DIR`: the (n, k) plane per band and n(λ), k(λ) (docs/BANDS.md).
    #[command(flatten)]
    pub report: table_report::ReportArgs,
}

/// `--bench`: where the model was trained.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchArg {
    /// The bench the fits come from.
    Same,
    /// Another bench.
    Other,
}

/// `NAME=W` of `--prior` (the weight is checked by the pipeline).
fn parse_prior(s: &str) -> Result<(String, f64), String> {
    let (name, w) = s
        .rsplit_once('=')
        .ok_or_else(|| format!("expected NAME=WEIGHT, got {s:?}"))?;
    let w: f64 = w
        .trim()
        .parse()
        .map_err(|_| format!("the weight of {name:?} is not a number: {w:?}"))?;
    Ok((name.trim().to_string(), w))
}

impl Args {
    /// The prototypes and the pipeline's settings (with the `--prior` weights, which
    /// only the tests against measured rows use).
    fn pipe_config(
        &self,
        classifier: polarid_core::classify::ClassifierConfig,
    ) -> anyhow::Result<(PrototypeSource, ClassifyConfig)> {
        let source = match &self.model {
            Some(m) => PrototypeSource::Model(m.clone()),
            None => PrototypeSource::Library(self.library.clone().unwrap_or("builtin".into())),
        };
        let cfg = ClassifyConfig {
            classifier,
            explain: self.explain,
            wolff: self.wolff.request()?,
            wavelength_nm: self.wavelength_nm,
            bench: match self.bench {
                BenchArg::Same => polarid_core::classify::Bench::Same,
                BenchArg::Other => polarid_core::classify::Bench::Other,
            },
            priors: self.priors.clone(),
        };
        Ok((source, cfg))
    }
}

/// Run `polarid classify`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let classifier = args.method.config()?;
    args.report.check(ctx)?;
    let table = polarid_io::table::CsvTable::read(&args.fits)?;
    if pipe::rows::is_measurements(&table) {
        return run_measurements(args, ctx, classifier, &table);
    }
    if !args.priors.is_empty() {
        return Err(crate::BadInput(
            "--prior applies to the tests against measured rows: give a measurements CSV \
             (columns dolp and beta_deg), not fits"
                .into(),
        )
        .into());
    }
    let fits = read_fits(&args.fits).cli()?;
    let (source, cfg) = args.pipe_config(classifier)?;
    let out = pipe::classify(&args.fits, &fits, &source, &cfg).cli()?;
    let what = format!(
        "against {} ({} prototypes, rule {}, {} metric{})",
        out.label,
        out.classifier.prototypes().len(),
        classifier.rule.name(),
        classifier.distance_metric().name(),
        match classifier.rule {
            polarid_core::classify::Rule::Set => format!(", confidence {}", classifier.confidence),
            polarid_core::classify::Rule::Nearest => format!(", k = {}", classifier.k),
        },
    );
    let rows: Vec<_> = fits.iter().map(|(_, f)| f.clone()).collect();
    finish(&args, ctx, &out, &rows, &what)
}

/// `polarid classify MEASUREMENTS.csv`: the hypothesis tests against the measured rows
/// (default), or the fits and the paper's rule (`--rule nearest`).
fn run_measurements(
    args: Args,
    ctx: &Ctx,
    classifier: polarid_core::classify::ClassifierConfig,
    table: &polarid_io::table::CsvTable,
) -> anyhow::Result<()> {
    let rows = polarid_io::table::measurements::from_table(table)?;
    let rows: Vec<_> = table.rows.iter().map(|(l, _)| *l).zip(rows).collect();
    let (source, cfg) = args.pipe_config(classifier)?;
    let fit_cfg = polarid_pipeline::fit::FitConfig::default();
    let nearest = classifier.rule == polarid_core::classify::Rule::Nearest;
    let (out, fits) = if nearest {
        if !cfg.priors.is_empty() {
            return Err(crate::BadInput(
                "--prior applies to the tests against measured rows, not --rule nearest".into(),
            )
            .into());
        }
        let mut with_wl = rows.clone();
        for (_, m) in &mut with_wl {
            m.wavelength_nm = m.wavelength_nm.or(args.wavelength_nm);
        }
        let fitted =
            polarid_pipeline::fit::fit(&args.fits, &with_wl, &fit_cfg, &|_, _, _| {}).cli()?;
        let fits: Vec<(u64, _)> = fitted.rows().into_iter().map(|f| (0, f)).collect();
        let out = pipe::classify(&args.fits, &fits, &source, &cfg).cli()?;
        (out, fits.into_iter().map(|(_, f)| f).collect::<Vec<_>>())
    } else {
        if cfg.wolff.is_some() {
            return Err(crate::BadInput(
                "--wolff needs a fits CSV (or --rule nearest with measurements)".into(),
            )
            .into());
        }
        pipe::rows::classify_measurements(&args.fits, &rows, &source, &cfg, &fit_cfg).cli()?
    };
    let what = format!(
        "from their measured rows against {} ({} materials, {}, confidence {})",
        out.label,
        out.classifier.prototypes().len(),
        if nearest {
            "fits, rule nearest"
        } else {
            "each material tested against the rows"
        },
        classifier.confidence,
    );
    finish(&args, ctx, &out, &fits, &what)
}

/// Write the rows to `--output` (or standard output; the inputs are never overwritten),
/// then the summary (`classified N target(s) WHAT: ...`), the warnings and notes of a
/// classification, and its `--report` (both inputs).
fn finish(
    args: &Args,
    ctx: &Ctx,
    out: &pipe::ClassifyOutput,
    fits: &[polarid_io::table::fits::FitRow],
    what: &str,
) -> anyhow::Result<()> {
    let out_path = args.output.as_deref();
    let mut inputs: Vec<&Path> = vec![&args.fits];
    inputs.extend(args.model.as_deref());
    inputs.extend(args.wolff.wolff.as_deref());
    ctx.write_output(out_path, &inputs, |w, p| {
        classification::write(w, p, &out.rows)
    })?;
    let count = |s: &str| out.rows.iter().filter(|r| r.status == s).count();
    let (ok, amb, rej) = (count("ok"), count("ambiguous"), count("rejected"));
    ctx.info(format!(
        "classified {} target(s) {what}: {ok} ok, {amb} ambiguous, {rej} rejected, {} other",
        out.rows.len(),
        out.rows.len() - ok - amb - rej
    ));
    super::common::warn_all(ctx, &out.warnings);
    for n in &out.notes {
        ctx.info(n);
    }
    let refs = References {
        label: out.label.clone(),
        profiles: out.classifier.profiles().to_vec(),
        builtin_curves: args.model.is_none()
            && polarid_io::library::Library::is_dispersive_builtin(
                args.library.as_deref().unwrap_or("builtin"),
            ),
    };
    table_report::write_classify_report(&args.report, ctx, &args.fits, fits, out, &refs)
}
