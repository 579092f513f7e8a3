//! `polarid classify FITS.csv (--model M | --library L) [-o out.csv]`: classify fitted
//! targets against a trained model or a material library (paper section 6), optionally
//! with Wolff's metal/dielectric baseline computed from the measurements.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::ValueEnum;
use polarid_core::classify::{
    Classifier, ClassifierConfig, Cov2, Decision, Estimate, Metric, Reject, WolffConfig,
    WolffObservation, wolff_classify,
};
use polarid_io::library::Library;
use polarid_io::model::Model;
use polarid_io::table::CsvTable;
use polarid_io::table::classification::{self, ClassificationRow};
use polarid_io::table::fits::{self, FitRow};
use polarid_io::table::measurements;

use crate::{BadInput, Ctx};

/// Distance metric on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MetricArg {
    /// Euclidean distance in (n, k): the paper's rule.
    Euclidean,
    /// Mahalanobis distance with the estimates' (and prototypes') covariance.
    Mahalanobis,
}

/// Classifier options shared by `classify` and `evaluate`.
#[derive(Debug, Clone, clap::Args)]
pub struct MethodArgs {
    /// Distance metric.
    #[arg(long, value_enum, default_value_t = MetricArg::Euclidean)]
    pub metric: MetricArg,
    /// Number of nearest prototypes that vote (1: the paper's nearest neighbour; ties in
    /// votes go to the class with the nearest member).
    #[arg(long = "k", value_name = "N", default_value_t = 1)]
    pub neighbours: usize,
    /// Answer `unknown` when the nearest prototype fails a chi-square gate (2 dof) on the
    /// Mahalanobis distance at probability P, e.g. 0.99 (needs standard errors).
    #[arg(long, value_name = "CHI2_P", conflicts_with = "max_distance")]
    pub reject: Option<f64>,
    /// Answer `unknown` when the nearest prototype is farther than D (in the metric's
    /// units).
    #[arg(long, value_name = "D")]
    pub max_distance: Option<f64>,
}

impl MethodArgs {
    /// The classifier settings.
    pub fn config(&self) -> anyhow::Result<ClassifierConfig> {
        let reject = match (self.reject, self.max_distance) {
            (Some(p), _) => Reject::Chi2 { p },
            (None, Some(d)) => Reject::MaxDistance(d),
            (None, None) => Reject::Never,
        };
        let cfg = ClassifierConfig {
            metric: match self.metric {
                MetricArg::Euclidean => Metric::Euclidean,
                MetricArg::Mahalanobis => Metric::Mahalanobis,
            },
            k: self.neighbours,
            reject,
        };
        cfg.validate()
            .map_err(|e| BadInput(format!("invalid classifier option: {e}")))?;
        Ok(cfg)
    }
}

/// Options of Wolff's metal/dielectric baseline, shared by `classify` and `evaluate`.
#[derive(Debug, Clone, clap::Args)]
pub struct WolffArgs {
    /// Also run Wolff's metal/dielectric baseline on these measurements (the CSV given to
    /// `polarid fit`): `classify` adds columns wolff_class, wolff_fr_max, wolff_beta_deg;
    /// `evaluate` reports its metal/dielectric accuracy.
    #[arg(long, value_name = "MEASUREMENTS.csv")]
    pub wolff: Option<PathBuf>,
    /// Wolff's threshold on the Fresnel ratio (1 + P)/(1 - P): dielectric above it.
    #[arg(long, default_value_t = 6.0, requires = "wolff")]
    pub wolff_threshold: f64,
    /// Wolff's window of specular angles beta, degrees: MIN,MAX.
    #[arg(long, value_name = "MIN,MAX", value_delimiter = ',', num_args = 2,
          default_values_t = [40.0, 70.0], requires = "wolff")]
    pub wolff_beta: Vec<f64>,
}

/// Wolff's observations per target, read from a measurements CSV.
pub type WolffObservations = BTreeMap<String, Vec<WolffObservation>>;

impl WolffArgs {
    /// The β window in degrees, `(min, max)`.
    pub fn window_deg(&self) -> (f64, f64) {
        (
            self.wolff_beta.first().copied().unwrap_or(40.0),
            self.wolff_beta.get(1).copied().unwrap_or(70.0),
        )
    }

    /// The settings of Wolff's rule, checked (a bad threshold or window is a usage error).
    pub fn config(&self) -> anyhow::Result<WolffConfig> {
        let (lo, hi) = self.window_deg();
        let cfg = WolffConfig {
            threshold: self.wolff_threshold,
            beta_min: lo.to_radians(),
            beta_max: hi.to_radians(),
        };
        wolff_classify(&[], &cfg).map_err(|e| BadInput(format!("--wolff-*: {e}")))?;
        Ok(cfg)
    }

    /// With `--wolff`: the measurements file, the checked settings and the observations
    /// per target (every row validated by the measurements reader: a bad file, line,
    /// column or value is a bad-input error naming them). `None` without `--wolff`.
    pub fn load(&self) -> anyhow::Result<Option<(&Path, WolffConfig, WolffObservations)>> {
        let Some(m) = &self.wolff else {
            return Ok(None);
        };
        let cfg = self.config()?;
        let mut obs = WolffObservations::new();
        for row in measurements::read(m)? {
            obs.entry(row.target).or_default().push(WolffObservation {
                beta: row.beta_deg.to_radians(),
                dolp: row.dolp,
            });
        }
        Ok(Some((m.as_path(), cfg, obs)))
    }

    /// A one-line description of the rule's settings, e.g. `Fresnel ratio threshold 6,
    /// beta in [40, 70] deg`.
    pub fn describe(&self) -> String {
        let (lo, hi) = self.window_deg();
        format!(
            "Fresnel ratio threshold {}, beta in [{lo}, {hi}] deg",
            self.wolff_threshold
        )
    }
}

/// Arguments of `polarid classify`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("prototypes").required(true).args(["model", "library"])))]
pub struct Args {
    /// Fits CSV written by `polarid fit`.
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
    /// How many nearest prototypes to list per target in the explanation (standard error).
    #[arg(long, default_value_t = 3)]
    pub explain: usize,
}

/// The estimate of a fit row: covariance from `n_se`, `k_se`, `nk_corr` when usable.
pub fn estimate_of(f: &FitRow) -> Estimate {
    let corr = if f.nk_corr.is_nan() { 0.0 } else { f.nk_corr };
    Estimate {
        n: f.n,
        k: f.k,
        cov: Cov2::from_se(f.n_se, f.k_se, corr),
        fit_status: f.status.clone(),
    }
}

/// Read a fits CSV with the line number of each row.
pub fn read_fits(path: &Path) -> anyhow::Result<Vec<(u64, FitRow)>> {
    let t = CsvTable::read(path)?;
    let rows = fits::from_table(&t)?;
    Ok(t.rows.iter().map(|r| r.0).zip(rows).collect())
}

/// Prototypes from `--model` or `--library`, and a label for messages.
fn load_prototypes(
    args: &Args,
) -> anyhow::Result<(Vec<polarid_core::classify::Prototype>, String)> {
    if let Some(m) = &args.model {
        let model = Model::read(m)?;
        return Ok((model.prototypes(), format!("model {}", m.display())));
    }
    let spec = args.library.as_deref().unwrap_or("builtin");
    let lib = Library::load(spec)?;
    Ok((lib.prototypes(), format!("library {spec}")))
}

/// A one-paragraph explanation of a decision: nearest prototypes and, when categories are
/// known, the nearest prototype of another category.
pub fn explain(target: &str, d: &Decision, clf: &Classifier, top: usize) -> String {
    // ok (indexing `protos` below): every index in a decision is one of `clf`'s
    // prototypes, produced by `clf.classify`.
    let protos = clf.prototypes();
    let unit = clf.config().metric.name();
    let cat = |i: usize| {
        protos[i]
            .category
            .as_deref()
            .map(|c| format!(" ({c})"))
            .unwrap_or_default()
    };
    let mut s = format!("{target}: ");
    match (&d.nearest_class, d.nearest) {
        (Some(c), Some(nb)) => {
            if d.predicted == *c {
                s.push_str(c);
            } else {
                s.push_str(&format!("{} (nearest {c})", d.predicted));
            }
            if let Some(category) = &protos[nb.index].category {
                let article = if category.starts_with(['a', 'e', 'i', 'o', 'u']) {
                    "an"
                } else {
                    "a"
                };
                if d.predicted == *c {
                    s.push_str(&format!(", classified as {article} {category}"));
                }
            }
            s.push_str(&format!(" [{unit} distance {:.4}", d.distance));
            if let Some(r) = &d.runner_up {
                s.push_str(&format!(
                    "; runner-up {r} at {:.4}, margin {:.4}",
                    d.runner_up_distance, d.margin
                ));
            }
            s.push(']');
            let near: Vec<String> = d
                .ranked
                .iter()
                .take(top)
                .map(|nb| {
                    format!(
                        "{}{} {:.4}",
                        protos[nb.index].class,
                        cat(nb.index),
                        nb.distance
                    )
                })
                .collect();
            if !near.is_empty() {
                s.push_str(&format!("; nearest: {}", near.join(", ")));
            }
            if let Some(category) = &protos[nb.index].category
                && let Some(other) = d.ranked.iter().find(|o| {
                    protos[o.index]
                        .category
                        .as_ref()
                        .is_some_and(|c| c != category)
                })
            {
                s.push_str(&format!(
                    "; nearest non-{category}: {}{} {:.4}",
                    protos[other.index].class,
                    cat(other.index),
                    other.distance
                ));
            }
            if !d.reason.is_empty() {
                s.push_str(&format!("; {}", d.reason));
            }
        }
        _ => s.push_str(&format!("{} ({})", d.predicted, d.reason)),
    }
    s
}

/// The classification CSV row of fit `f` classified as `d` by `clf` (without Wolff's
/// columns).
pub fn classification_row(f: &FitRow, d: &Decision, clf: &Classifier) -> ClassificationRow {
    let category = d
        .nearest
        // ok: nb.index is an index into clf.prototypes() (from clf.classify).
        .and_then(|nb| clf.prototypes()[nb.index].category.clone());
    ClassificationRow {
        target: f.target.clone(),
        class: f.class.clone(),
        predicted: d.predicted.clone(),
        distance: d.nearest.map(|_| d.distance),
        runner_up: d.runner_up.clone(),
        runner_up_distance: d.runner_up.as_ref().map(|_| d.runner_up_distance),
        status: d.status.label(),
        margin: Some(d.margin),
        nearest: d.nearest_class.clone(),
        category,
        metric: clf.config().metric.name().into(),
        gate: d.gate,
        votes: d.nearest.map(|_| d.votes as u64),
        reason: d.reason.clone(),
        ..Default::default()
    }
}

/// Run `polarid classify`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let cfg = args.method.config()?;
    let fits = read_fits(&args.fits)?;
    if fits.is_empty() {
        return Err(BadInput(format!("{}: no fits to classify", args.fits.display())).into());
    }
    let (protos, label) = load_prototypes(&args)?;
    let clf = Classifier::new(protos, cfg).with_context(|| format!("cannot use {label}"))?;

    // Wolff's baseline, per target.
    let wolff = args.wolff.load()?;

    let mut out = Vec::with_capacity(fits.len());
    let mut notes = Vec::new();
    for (line, f) in &fits {
        let d = clf.classify(&estimate_of(f));
        notes.push(explain(&f.target, &d, &clf, args.explain));
        let mut row = classification_row(f, &d, &clf);
        if let Some((wpath, wcfg, wobs)) = &wolff {
            let obs = wobs.get(&f.target).map(Vec::as_slice).unwrap_or(&[]);
            let w = wolff_classify(obs, wcfg).map_err(|e| {
                BadInput(format!(
                    "{}: target {} (line {line} of {}): {e}",
                    wpath.display(),
                    f.target,
                    args.fits.display()
                ))
            })?;
            row.wolff_class = Some(w.class.name().into());
            row.wolff_fr_max = Some(w.fr_max);
            row.wolff_beta_deg = Some(w.beta_at_max.to_degrees());
            notes.push(format!(
                "{}: Wolff: {} (largest Fresnel ratio {:.3} over {} measurement(s) with beta in \
                 [{}, {}] deg; threshold {})",
                f.target,
                w.class.name(),
                w.fr_max,
                w.used,
                args.wolff.window_deg().0,
                args.wolff.window_deg().1,
                wcfg.threshold
            ));
        }
        out.push(row);
    }
    let out_path = args.output.clone();
    let mut inputs: Vec<&Path> = vec![&args.fits];
    if let Some(m) = &args.model {
        inputs.push(m);
    }
    if let Some(w) = &args.wolff.wolff {
        inputs.push(w);
    }
    ctx.write_output(out_path.as_deref(), &inputs, |w| {
        classification::write(w, out_path.as_deref().unwrap_or(Path::new("-")), &out)
    })?;
    ctx.info(format!(
        "classified {} target(s) against {label} ({} prototypes, {} metric, k = {})",
        out.len(),
        clf.prototypes().len(),
        cfg.metric.name(),
        cfg.k
    ));
    for n in notes {
        ctx.info(n);
    }
    Ok(())
}
