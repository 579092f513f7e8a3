//! Figures and reports of a user's own tables (`fit --report DIR`, `classify --report
//! DIR`; docs/BANDS.md "Per-band plots of your data"), from the measurement, fit and
//! classification rows and a set of references (a library or a model's prototypes).
//!
//! Tables with several bands (`wavelength_nm`, two or more distinct) get, under `plots/`:
//! `dolp_bands` (DoLP against β per band with each target's fitted eq. (9) curve; with
//! measurements), `nk_bands` (the `(n, k)` plane per band: references and the targets'
//! estimates with 1-σ ellipses) and `nk_spectra` (`n(λ)`, `k(λ)` of each target with
//! ±1 SE bars against the references' curves: the refractiveindex.info data of the
//! built-in materials, else lines through the library's or model's bands). One band (or
//! none): `dolp_vs_beta` and `nk_plane`, the single-band figures.

use std::path::{Path, PathBuf};

use anyhow::Result;
use polarid_core::classify::{MultiPrototype, same_band};
use polarid_io::library::{BUILTIN_SOURCES, RiiData};
use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::FitRow;
use polarid_io::table::measurements::{Measurement, RowStatus};

use super::plots::bands::{Spectrum, SpectrumPoint, nk_spectra};
use super::plots::panels::{DolpBand, NkBand, band_label, dolp_by_band, nk_by_band};
use super::plots::{self, PlotSize};
use super::report::{self, Report};
use super::{Rendered, colour_demo::ColourFigure};

/// At most this many targets are drawn (the first ones, in table order).
pub const MAX_TARGETS: usize = 12;
/// At most this many reference classes are drawn.
pub const MAX_REFERENCES: usize = 8;
/// Spacing of the built-in materials' curves, nm.
const CURVE_STEP_NM: f64 = 5.0;

/// The references drawn against the targets.
#[derive(Debug, Clone, Default)]
pub struct References {
    /// E.g. `library builtin-rgb`, `model model.json`.
    pub label: String,
    /// The prototypes (library materials or a model's training targets), with their bands.
    pub profiles: Vec<MultiPrototype>,
    /// Whether the classes are built-in materials whose refractiveindex.info data give
    /// continuous `n(λ)`, `k(λ)` curves ([`BUILTIN_SOURCES`]).
    pub builtin_curves: bool,
}

/// The rows a report is drawn from.
#[derive(Debug, Clone, Copy, Default)]
pub struct Tables<'a> {
    /// Measurement rows (empty: no DoLP figure).
    pub measurements: &'a [Measurement],
    /// Fit rows, one per target per band.
    pub fits: &'a [FitRow],
    /// Classification rows, one per target (may be empty).
    pub classification: &'a [ClassificationRow],
}

/// The distinct bands of `fits` (wavelengths within the band tolerance are one band), in
/// increasing order; rows without a wavelength are not counted.
pub fn bands_of(fits: &[FitRow]) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for w in fits.iter().filter_map(|f| f.wavelength_nm) {
        if w.is_finite() && !out.iter().any(|&x| same_band(Some(x), Some(w))) {
            out.push(w);
        }
    }
    out.sort_by(f64::total_cmp);
    out
}

/// Target names in first-appearance order.
fn targets_of(fits: &[FitRow]) -> Vec<&str> {
    let mut out: Vec<&str> = Vec::new();
    for f in fits {
        if !out.contains(&f.target.as_str()) {
            out.push(&f.target);
        }
    }
    out
}

/// `(n, k)` of profile `p` in band `w`.
fn band_nk(p: &MultiPrototype, w: Option<f64>) -> Option<(f64, f64)> {
    p.bands
        .iter()
        .find(|b| same_band(b.wavelength_nm, w) || (b.wavelength_nm.is_none() && w.is_none()))
        .map(|b| (b.n, b.k))
}

/// The reference classes worth drawing: those the classification names (answer,
/// runner-up, consistent set, nearest), else the two nearest to each target over its
/// bands; at most [`MAX_REFERENCES`], in that order.
pub fn relevant_classes(t: &Tables, refs: &References) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let known = |c: &str| refs.profiles.iter().any(|p| p.class == c);
    let add = |c: &str, out: &mut Vec<String>| {
        if known(c) && !out.iter().any(|x| x == c) && out.len() < MAX_REFERENCES {
            out.push(c.to_string());
        }
    };
    for r in t.classification {
        add(&r.predicted, &mut out);
        for c in r.runner_up.iter().chain(&r.candidates).chain(&r.nearest) {
            add(c, &mut out);
        }
    }
    if !out.is_empty() {
        return out;
    }
    for target in targets_of(t.fits) {
        let rows: Vec<&FitRow> = t.fits.iter().filter(|f| f.target == target).collect();
        let mut dist: Vec<(f64, &str)> = refs
            .profiles
            .iter()
            .filter_map(|p| {
                let d: Vec<f64> = rows
                    .iter()
                    .filter_map(|f| {
                        let (n, k) = band_nk(p, f.wavelength_nm)?;
                        let d = (n - f.n).hypot(k - f.k);
                        d.is_finite().then_some(d * d)
                    })
                    .collect();
                (!d.is_empty()).then(|| (d.iter().sum::<f64>() / d.len() as f64, p.class.as_str()))
            })
            .collect();
        dist.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut taken = 0;
        for (_, c) in dist {
            if taken == 2 {
                break;
            }
            if !out.iter().any(|x| x == c) {
                taken += 1;
            }
            add(c, &mut out);
        }
    }
    out
}

/// `n(λ)`, `k(λ)` of built-in material `class` from `lo_nm` to `hi_nm` (within its data).
fn builtin_curve(class: &str, lo_nm: f64, hi_nm: f64) -> Vec<(f64, f64, f64)> {
    let Some(src) = BUILTIN_SOURCES.iter().find(|s| s.name == class) else {
        return Vec::new();
    };
    let Ok(data) = RiiData::parse(Path::new(src.file), src.text) else {
        return Vec::new();
    };
    let steps = ((hi_nm - lo_nm) / CURVE_STEP_NM).ceil().max(0.0) as usize;
    (0..=steps)
        .map(|i| lo_nm + i as f64 * CURVE_STEP_NM)
        .filter_map(|w| data.nk(w / 1000.0).ok().map(|(n, k)| (w, n, k)))
        .collect()
}

/// The figures of the tables (see the module documentation), titled after `what`.
pub fn figures(t: &Tables, refs: Option<&References>, what: &str) -> Result<Vec<ColourFigure>> {
    let bands = bands_of(t.fits);
    let names = targets_of(t.fits);
    let shown: Vec<&str> = names.iter().copied().take(MAX_TARGETS).collect();
    let more = if names.len() > shown.len() {
        format!(
            " The first {} of {} targets are drawn.",
            shown.len(),
            names.len()
        )
    } else {
        String::new()
    };
    let classes = refs.map(|r| relevant_classes(t, r)).unwrap_or_default();
    // In the order of `classes`, so that a class has the same colour in every figure.
    let chosen: Vec<&MultiPrototype> = classes
        .iter()
        .flat_map(|c| {
            refs.into_iter()
                .flat_map(|r| r.profiles.iter())
                .filter(move |p| &p.class == c)
        })
        .collect();
    let ref_text = match refs {
        Some(r) if !chosen.is_empty() => {
            format!(" References: {} ({}).", r.label, classes.join(", "))
        }
        _ => String::new(),
    };
    let drawn = Drawn {
        t: *t,
        refs,
        what,
        shown,
        classes,
        chosen,
        more,
        ref_text,
    };
    if bands.len() < 2 {
        drawn.one_band(bands.first().copied())
    } else {
        drawn.per_band(&bands)
    }
}

/// What the figures of the tables share: the targets drawn, the references chosen and
/// the sentences the captions end with.
struct Drawn<'a> {
    t: Tables<'a>,
    refs: Option<&'a References>,
    what: &'a str,
    shown: Vec<&'a str>,
    classes: Vec<String>,
    chosen: Vec<&'a MultiPrototype>,
    more: String,
    ref_text: String,
}

/// A figure drawn as `plots/<stem>.png`.
fn fig(stem: &str, title: String, caption: String, plot: Rendered) -> ColourFigure {
    ColourFigure {
        stem: stem.into(),
        title,
        caption,
        plot,
    }
}

impl<'a> Drawn<'a> {
    /// The fit of `target` in band `w` (`None`: the row without a wavelength).
    fn fit_of(&self, target: &str, w: Option<f64>) -> Option<&'a FitRow> {
        self.t.fits.iter().find(|f| {
            f.target == target
                && (same_band(f.wavelength_nm, w) || (w.is_none() && f.wavelength_nm.is_none()))
        })
    }

    /// The DoLP of `target` (in band `w`; `None`: every row) and its fitted curve.
    fn series(&self, target: &str, w: Option<f64>) -> plots::DolpSeries {
        let ms: Vec<&Measurement> = self
            .t
            .measurements
            .iter()
            .filter(|m| m.target == target && m.status == RowStatus::Ok)
            .filter(|m| w.is_none() || same_band(m.wavelength_nm, w))
            .collect();
        let f = self
            .fit_of(target, w)
            .filter(|f| f.n.is_finite() && f.k.is_finite());
        super::demo::common::dolp_series(target.to_string(), f, &ms)
    }

    /// The chosen references' `(n, k)` in band `w` (`or_first`: else in their first band).
    fn references(&self, w: Option<f64>, or_first: bool) -> Vec<plots::Prototype> {
        let first = |p: &MultiPrototype| p.bands.first().filter(|_| or_first).map(|b| (b.n, b.k));
        self.chosen
            .iter()
            .filter_map(|p| {
                let (n, k) = band_nk(p, w).or_else(|| first(p))?;
                Some(plots::Prototype {
                    class: p.class.clone(),
                    n,
                    k,
                })
            })
            .collect()
    }

    fn estimate(&self, f: &FitRow) -> plots::NkEstimate {
        plots::NkEstimate::from_fit(f.target.clone(), f, self.t.classification, None)
    }

    /// The single-band figures (band `w`, or none): `dolp_vs_beta` and `nk_plane`.
    fn one_band(&self, w: Option<f64>) -> Result<Vec<ColourFigure>> {
        let (what, more, ref_text) = (self.what, &self.more, &self.ref_text);
        let mut figs = Vec::new();
        let at = w
            .map(|w| format!(" at {} nm", band_label(w)))
            .unwrap_or_default();
        if !self.t.measurements.is_empty() {
            let s: Vec<plots::DolpSeries> =
                self.shown.iter().map(|n| self.series(n, None)).collect();
            figs.push(fig(
                "dolp_vs_beta",
                format!("DoLP against β{at}"),
                format!("Each target's DoLP (points, ±1 SE) and the eq. (9) curve of its fitted (n, k).{more}"),
                plots::dolp_vs_beta(&format!("DoLP against β{at} ({what})"), &s, PlotSize::REPORT)?,
            ));
        }
        let protos = self.references(w, true);
        let ests: Vec<plots::NkEstimate> = self
            .shown
            .iter()
            .filter_map(|n| self.t.fits.iter().find(|f| f.target == *n))
            .map(|f| self.estimate(f))
            .collect();
        figs.push(fig(
            "nk_plane",
            format!("The (n, k) plane{at}"),
            format!("Each target's (n, k) with its 1-σ ellipse, and the references (shaded: their nearest-neighbour regions).{ref_text}{more}"),
            plots::nk_plane(&format!("(n, k){at} ({what})"), &protos, &ests, PlotSize::REPORT)?,
        ));
        Ok(figs)
    }

    /// The figures of two bands or more: `dolp_bands`, `nk_bands` and `nk_spectra`.
    fn per_band(&self, bands: &[f64]) -> Result<Vec<ColourFigure>> {
        let (what, more, ref_text) = (self.what, &self.more, &self.ref_text);
        let mut figs = Vec::new();
        let tags: Vec<String> = bands.iter().map(|w| band_label(*w)).collect();
        let tags = tags.join(", ");
        if !self.t.measurements.is_empty() {
            let dolp: Vec<DolpBand> = bands
                .iter()
                .map(|&w| DolpBand {
                    wavelength_nm: w,
                    series: self.shown.iter().map(|n| self.series(n, Some(w))).collect(),
                })
                .collect();
            figs.push(fig(
                "dolp_bands",
                "DoLP against β per band".into(),
                format!("One panel per band ({tags} nm): each target's DoLP in the band (points, ±1 SE) and the eq. (9) curve of its fit in that band.{more}"),
                dolp_by_band(&format!("DoLP against β per band ({what})"), &dolp)?,
            ));
        }
        let nk: Vec<NkBand> = bands
            .iter()
            .map(|&w| NkBand {
                wavelength_nm: w,
                references: self.references(Some(w), false),
                estimates: self
                    .shown
                    .iter()
                    .map(|n| self.fit_of(n, Some(w)).map(|f| self.estimate(f)))
                    .collect(),
            })
            .collect();
        figs.push(fig(
            "nk_bands",
            "The (n, k) plane per band".into(),
            format!("One panel per band ({tags} nm): each target's (n, k) in the band with its 1-σ ellipse, and the references' values in that band (circles).{ref_text}{more}"),
            nk_by_band(&format!("(n, k) per band ({what})"), &nk)?,
        ));
        figs.push(self.spectra(bands)?);
        Ok(figs)
    }

    /// `nk_spectra`: each target's n and k per band against the references' curves.
    fn spectra(&self, bands: &[f64]) -> Result<ColourFigure> {
        let (what, more, ref_text, refs) = (self.what, &self.more, &self.ref_text, self.refs);
        let targets: Vec<Spectrum> = self
            .shown
            .iter()
            .map(|name| Spectrum {
                label: name.to_string(),
                points: self
                    .t
                    .fits
                    .iter()
                    .filter(|f| f.target == *name)
                    .filter_map(|f| {
                        Some(SpectrumPoint {
                            wavelength_nm: f.wavelength_nm?,
                            n: f.n,
                            k: f.k,
                            n_se: Some(f.n_se),
                            k_se: Some(f.k_se),
                        })
                    })
                    .collect(),
                curve: Vec::new(),
            })
            .collect();
        let (lo, hi) = (bands[0] - 60.0, bands[bands.len() - 1] + 60.0);
        let library: Vec<Spectrum> = self
            .classes
            .iter()
            .map(|class| {
                let members: Vec<&&MultiPrototype> =
                    self.chosen.iter().filter(|p| &p.class == class).collect();
                let points = bands
                    .iter()
                    .filter_map(|&w| {
                        let v: Vec<(f64, f64)> =
                            members.iter().filter_map(|p| band_nk(p, Some(w))).collect();
                        (!v.is_empty()).then(|| SpectrumPoint {
                            wavelength_nm: w,
                            n: v.iter().map(|x| x.0).sum::<f64>() / v.len() as f64,
                            k: v.iter().map(|x| x.1).sum::<f64>() / v.len() as f64,
                            n_se: None,
                            k_se: None,
                        })
                    })
                    .collect();
                let curve = match refs {
                    Some(r) if r.builtin_curves => builtin_curve(class, lo, hi),
                    _ => Vec::new(),
                };
                Spectrum {
                    label: class.clone(),
                    points,
                    curve,
                }
            })
            .collect();
        let curve_text = match refs {
            Some(r) if r.builtin_curves => {
                "lines: the materials' refractiveindex.info data, circles: their band values"
            }
            Some(_) => {
                "lines through the references' bands (a model's class: the mean of its prototypes)"
            }
            None => "no references given",
        };
        Ok(fig(
            "nk_spectra",
            "n(λ) and k(λ)".into(),
            format!(
                "Each target's fitted n and k per band (markers, ±1 SE) against the references ({curve_text}).{ref_text}{more}"
            ),
            nk_spectra(
                &format!("n(λ) and k(λ) ({what})"),
                &targets,
                &library,
                PlotSize::REPORT,
            )?,
        ))
    }
}

/// The report of `polarid CMD INPUT`: its tables with `figs` (files under `plots/`).
pub fn report(
    cmd: &str,
    input: &Path,
    inputs: Vec<report::InputItem>,
    t: &Tables,
    figs: &[ColourFigure],
) -> Report {
    let estimates = t
        .fits
        .iter()
        .map(|f| report::EstimateRow {
            target: match f.wavelength_nm {
                Some(w) => format!("{} @ {} nm", f.target, band_label(w)),
                None => f.target.clone(),
            },
            ..super::demo::common::estimate_row(f, f.theta_r_deg)
        })
        .collect();
    let numbered: Vec<(u64, FitRow)> = t.fits.iter().map(|f| (0, f.clone())).collect();
    Report {
        title: format!("polarid {cmd}: {}", input.display()),
        summary: vec![describe(t.fits)],
        inputs,
        estimates,
        classification: super::demo::report_classification(&numbered, t.classification, None, None),
        figures: super::colour_demo::report_figures(figs),
        generator: format!("polarid {} {cmd}", env!("CARGO_PKG_VERSION")),
        ..Default::default()
    }
}

/// Write `dir/report.html`, `dir/report.md` and `dir/plots/STEM.{png,svg}`, staged (a
/// failure leaves nothing behind; existing files are replaced only with `--force`), and
/// say so (`polarid CMD: report written to DIR`).
pub fn write(
    dir: &Path,
    ctx: &crate::Ctx,
    cmd: &str,
    rep: &Report,
    figs: &[ColourFigure],
) -> Result<()> {
    let staged = polarid_io::atomic::StagedDir::new(dir, ctx.force)?;
    for f in figs {
        let png = staged.path(&format!("plots/{}.png", f.stem))?;
        let sub = png.parent().map(Path::to_path_buf).unwrap_or_default();
        f.plot.write(&sub, &f.stem)?;
    }
    let html = staged.path("report.html")?;
    let root = html.parent().map(Path::to_path_buf).unwrap_or_default();
    rep.write(&root, "report")?;
    staged.commit()?;
    ctx.info(format!(
        "polarid {cmd}: report written to {}",
        dir.display()
    ));
    Ok(())
}

/// `--report DIR` of `classify` (docs/BANDS.md, "Per-band plots of your data").
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ReportArgs {
    /// Also write DIR/report.html, DIR/report.md and DIR/plots/: with several bands one
    /// panel per band of the (n, k) plane (and of DoLP against β for `fit`), and n(λ),
    /// k(λ) of each target against the references' curves.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
}

impl ReportArgs {
    /// Before any work: the report directory must not be a file, and without `--force`
    /// must not hold a report already.
    pub fn check(&self, ctx: &crate::Ctx) -> Result<()> {
        let Some(dir) = &self.report else {
            return Ok(());
        };
        if dir.exists() && !dir.is_dir() {
            anyhow::bail!(crate::BadInput(format!(
                "--report {}: the output must be a directory, and this is a file",
                dir.display()
            )));
        }
        let html = dir.join("report.html");
        if !ctx.force && html.exists() {
            return Err(polarid_io::IoError::OutputExists { path: html }.into());
        }
        Ok(())
    }
}

/// `--report DIR` and `--report-library LIB` of `fit`.
#[derive(Debug, Clone, clap::Args)]
pub struct FitReportArgs {
    /// The report.
    #[command(flatten)]
    pub dir: ReportArgs,
    /// The report's references: a library (`builtin-rgb`: the built-in materials, drawn
    /// with their refractiveindex.info curves; `builtin`, `paper2007` or a CSV file).
    #[arg(long, value_name = "LIB", default_value = "builtin-rgb")]
    pub report_library: String,
}

impl FitReportArgs {
    /// Before any work: [`ReportArgs::check`], and the references' library must load.
    pub fn check(&self, ctx: &crate::Ctx) -> Result<()> {
        self.dir.check(ctx)?;
        if self.dir.report.is_some() {
            polarid_io::library::Library::load(&self.report_library)?;
        }
        Ok(())
    }
}

/// The references of library `spec` for `fits`: a built-in library evaluated at the fits'
/// bands (fits without a wavelength: at 650 nm, as `classify` compares them).
pub fn library_references(spec: &str, fits: &[FitRow]) -> Result<References> {
    use polarid_io::library::Library;
    let lib = Library::load(spec)?;
    let builtin = Library::is_dispersive_builtin(spec);
    let bands = bands_of(fits);
    let mut profiles = if builtin {
        let at = if bands.is_empty() {
            vec![650.0]
        } else {
            bands.clone()
        };
        lib.at_wavelengths(&at)?.0.multi_prototypes()
    } else {
        lib.multi_prototypes()
    };
    if bands.is_empty() {
        for b in profiles.iter_mut().flat_map(|p| p.bands.iter_mut()) {
            b.wavelength_nm = None;
        }
    }
    Ok(References {
        label: format!("library {spec}"),
        profiles,
        builtin_curves: builtin,
    })
}

/// A summary line: the targets and bands of `fits`.
fn describe(fits: &[FitRow]) -> String {
    let bands = bands_of(fits);
    let b = match bands.len() {
        0 => "one band without a wavelength".to_string(),
        _ => format!(
            "{} band(s): {} nm",
            bands.len(),
            super::join(bands.iter().map(|w| band_label(*w)), ", ")
        ),
    };
    format!("{} target(s), {b}.", targets_of(fits).len())
}

/// Write the report of `fit` (after its fits CSV): `input` is the measurements file.
pub fn write_fit_report(
    args: &FitReportArgs,
    ctx: &crate::Ctx,
    input: &Path,
    meas: &[(u64, Measurement)],
    fits: &[FitRow],
) -> Result<()> {
    let Some(dir) = &args.dir.report else {
        return Ok(());
    };
    let refs = library_references(&args.report_library, fits)?;
    let measurements: Vec<Measurement> = meas.iter().map(|(_, m)| m.clone()).collect();
    let t = Tables {
        measurements: &measurements,
        fits,
        classification: &[],
    };
    let figs = figures(&t, Some(&refs), "fit")?;
    let inputs = vec![report::InputItem::new(
        "measurements",
        input.display().to_string(),
        format!("{} row(s)", meas.len()),
    )];
    let rep = report("fit", input, inputs, &t, &figs);
    write(dir, ctx, "fit", &rep, &figs)
}

/// The hypothesis tests' tables of `classify MEASUREMENTS.csv`: the in-scene
/// references' calibration (when the table has references) and, per target, every
/// tested material with its probability, `χ²` (p-value) and the layer thickness, scale
/// and offset it needed, most probable first. Empty without hypothesis tests.
pub fn hypothesis_tables(
    hyps: &[polarid_pipeline::classify::TargetHypotheses],
    cal: Option<&polarid_pipeline::classify::reference::SceneCalibration>,
) -> Vec<report::Table> {
    let mut out = Vec::new();
    if let Some(c) = cal {
        let bounds = match c.bounds {
            Some(b) => format!(
                "The other targets were tested with the scale in [{:.4}, {:.4}] and the common \
                 angle offset in [{:+.3}°, {:+.3}°] (the error model alone: scale in [{:.4}, 1], \
                 offset within ±{:.3}°).",
                b.scale.0,
                b.scale.1,
                b.offset.0.to_degrees(),
                b.offset.1.to_degrees(),
                c.prior.scale_min,
                c.prior.offset_max.to_degrees()
            ),
            None => "No reference was usable: the targets were tested with the error model's \
                     scale and offset."
                .into(),
        };
        out.push(report::Table::new(
            format!(
                "In-scene references: the polarimeter scale and the common angle offset their \
                 rows measure (± 1 SE), with their own native layer. {bounds}"
            ),
            &[
                "Target",
                "Material",
                "Scale",
                "Offset (°)",
                "Layer (nm)",
                "χ² (dof)",
                "p-value",
                "Used",
            ],
            c.references
                .iter()
                .map(|r| {
                    let mut row = vec![r.target.clone(), r.reference.to_string()];
                    match &r.calibration {
                        Some(k) => row.extend([
                            format!("{:.4} ± {:.4}", k.scale, k.scale_se),
                            format!(
                                "{:+.3} ± {:.3}",
                                k.offset.to_degrees(),
                                k.offset_se.to_degrees()
                            ),
                            format!("{:.2}", k.thickness_nm),
                            format!("{:.2} ({:.0})", k.chi2, k.dof),
                            format!("{:.3}", k.p_value),
                        ]),
                        None => row.extend(std::iter::repeat_n("—".to_string(), 5)),
                    }
                    row.push(if r.used { "yes" } else { "no" }.into());
                    row
                })
                .collect(),
        ));
    }
    if !hyps.is_empty() {
        let mut rows = Vec::new();
        for h in hyps {
            for c in &h.tested {
                let Some(f) = c.fit else { continue };
                rows.push(vec![
                    h.target.clone(),
                    c.class.clone(),
                    format!("{:.3}", c.probability.unwrap_or(f64::NAN)),
                    if f.consistent { "yes" } else { "no" }.into(),
                    format!("{:.2} ({:.1})", f.chi2, f.dof),
                    format!("{:.3}", f.p_value),
                    format!("{:.2}", f.thickness_nm),
                    format!("{:.4}", f.scale),
                    format!("{:+.3}", f.offset.to_degrees()),
                    if h.calibrated {
                        "reference"
                    } else {
                        "error model"
                    }
                    .into(),
                ]);
            }
        }
        out.push(report::Table::new(
            "Each material tested against each target's measured rows, most probable first: \
             its probability, whether it passes at the confidence, χ² (effective dof) and \
             p-value, and the native-layer thickness, polarimeter scale and common angle \
             offset it needed (bounded by the in-scene reference when there is one, else by \
             the error model).",
            &[
                "Target",
                "Material",
                "Probability",
                "Passes",
                "χ² (dof)",
                "p-value",
                "Layer (nm)",
                "Scale",
                "Offset (°)",
                "Bounds",
            ],
            rows,
        ));
    }
    out
}

/// Write the report of `classify` (its output `out`): `refs` are the classifier's
/// prototypes; the hypothesis tests and in-scene references of `classify
/// MEASUREMENTS.csv` (none for fits) are tables after the classification
/// ([`hypothesis_tables`]).
pub fn write_classify_report(
    args: &ReportArgs,
    ctx: &crate::Ctx,
    input: &Path,
    fits: &[FitRow],
    out: &polarid_pipeline::classify::ClassifyOutput,
    refs: &References,
) -> Result<()> {
    let Some(dir) = &args.report else {
        return Ok(());
    };
    let t = Tables {
        measurements: &[],
        fits,
        classification: &out.rows,
    };
    let figs = figures(&t, Some(refs), "classify")?;
    let inputs = vec![
        report::InputItem::new("fits", input.display().to_string(), describe(fits)),
        report::InputItem::new(
            "prototypes",
            refs.label.clone(),
            format!("{} prototype(s)", refs.profiles.len()),
        ),
    ];
    let mut rep = report("classify", input, inputs, &t, &figs);
    rep.tables
        .extend(hypothesis_tables(&out.hypotheses, out.calibration.as_ref()));
    write(dir, ctx, "classify", &rep, &figs)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows of two targets (copper- and gold-like) in `bands` (`None`: no wavelength),
    /// with eq. (9) measurements at β = 45…70°.
    fn tables(bands: &[Option<f64>]) -> (Vec<Measurement>, Vec<FitRow>) {
        let (mut ms, mut fs) = (Vec::new(), Vec::new());
        for (t, (n0, k0)) in [("plate_cu", (0.9, 2.6)), ("plate_au", (0.5, 2.4))] {
            for (i, &w) in bands.iter().enumerate() {
                let (n, k) = (n0 + 0.2 * i as f64, k0 + 0.4 * i as f64);
                for j in 0..6 {
                    let beta = 45.0 + 5.0 * j as f64;
                    ms.push(Measurement {
                        target: t.into(),
                        beta_deg: beta,
                        phi_deg: 180.0,
                        dolp: polarid_core::dop::dop(n, k, f64::to_radians(beta)),
                        dolp_se: Some(0.004),
                        wavelength_nm: w,
                        ..Default::default()
                    });
                }
                fs.push(FitRow {
                    target: t.into(),
                    wavelength_nm: w,
                    n,
                    k,
                    n_se: 0.03,
                    k_se: 0.1,
                    nk_corr: 0.5,
                    measurements: 6,
                    ..Default::default()
                });
            }
        }
        (ms, fs)
    }

    fn stems(figs: &[ColourFigure]) -> Vec<&str> {
        figs.iter().map(|f| f.stem.as_str()).collect()
    }

    #[test]
    fn multi_band_tables_draw_one_panel_per_band() {
        let (ms, fs) = tables(&[Some(650.0), Some(450.0), Some(550.0)]);
        let t = Tables {
            measurements: &ms,
            fits: &fs,
            classification: &[],
        };
        let refs = library_references("builtin-rgb", &fs).unwrap();
        let figs = figures(&t, Some(&refs), "test").unwrap();
        assert_eq!(stems(&figs), ["dolp_bands", "nk_bands", "nk_spectra"]);
        for f in &figs[..2] {
            for w in ["450", "550", "650"] {
                // One titled panel per band, its axes naming the band.
                assert_eq!(
                    f.plot.svg.matches(&format!("λ = {w} nm")).count(),
                    1,
                    "{}",
                    f.stem
                );
                let axis = if f.stem == "dolp_bands" {
                    format!("DoLP at {w} nm")
                } else {
                    format!("k at {w} nm")
                };
                assert!(f.plot.svg.contains(&axis), "{} {axis}", f.stem);
            }
            assert!(f.plot.svg.contains("plate_cu") && f.plot.svg.contains("plate_au"));
        }
        // The nearest built-in materials are the references, with their curves.
        let classes = relevant_classes(&t, &refs);
        assert!(classes.contains(&"copper".to_string()), "{classes:?}");
        assert!(figs[2].plot.svg.contains("copper"));
        assert!(figs[2].plot.svg.contains("wavelength (nm)"));
        let curve = builtin_curve("copper", 390.0, 710.0);
        assert!(curve.len() > 50, "{}", curve.len());
        let at_650 = curve.iter().find(|c| c.0 == 650.0).unwrap();
        assert!(
            (at_650.1 - 0.21).abs() < 0.1 && (at_650.2 - 3.67).abs() < 0.2,
            "{at_650:?}"
        );
    }

    #[test]
    fn single_band_tables_draw_the_single_band_figures() {
        for band in [None, Some(650.0)] {
            let (ms, fs) = tables(&[band]);
            let t = Tables {
                measurements: &ms,
                fits: &fs,
                classification: &[],
            };
            let refs = library_references("builtin-rgb", &fs).unwrap();
            let figs = figures(&t, Some(&refs), "test").unwrap();
            assert_eq!(stems(&figs), ["dolp_vs_beta", "nk_plane"]);
            assert!(figs.iter().all(|f| !f.plot.svg.contains("λ = ")));
            // Fits without a wavelength are compared with the 650 nm values.
            let cu = refs.profiles.iter().find(|p| p.class == "copper").unwrap();
            assert_eq!(cu.bands.len(), 1);
            assert!((cu.bands[0].n - 0.25).abs() < 0.02, "{:?}", cu.bands);
        }
    }

    #[test]
    fn classification_names_the_references() {
        let (_, fs) = tables(&[Some(450.0), Some(550.0), Some(650.0)]);
        let rows = vec![ClassificationRow {
            target: "plate_cu".into(),
            predicted: "gold".into(),
            runner_up: Some("silver".into()),
            candidates: vec!["gold".into()],
            ..Default::default()
        }];
        let t = Tables {
            measurements: &[],
            fits: &fs,
            classification: &rows,
        };
        let refs = library_references("builtin-rgb", &fs).unwrap();
        assert_eq!(relevant_classes(&t, &refs), ["gold", "silver"]);
        let figs = figures(&t, Some(&refs), "test").unwrap();
        assert_eq!(stems(&figs), ["nk_bands", "nk_spectra"]);
        assert!(figs[0].plot.svg.contains("plate_cu: gold"));
    }
}
