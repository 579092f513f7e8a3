//! Reports a scientist can send to a colleague: one self-contained HTML file (plots
//! embedded as base64 `data:` URIs, no scripts, no network) and a Markdown version
//! that references the plots' PNG files.
//!
//! The caller (e.g. `polarid demo`) fills a [`Report`]: inputs, geometry, reference
//! indices, estimates with standard errors, classification results and figures
//! (from [`crate::render::plots`], as [`Rendered`](crate::render::Rendered)); [`Report::to_html`] and [`Report::to_markdown`] lay them
//! out with a fixed "Conventions" section (angles, `N = n + ik`, Stokes `S1`, β, the
//! paper's eqs. (3), (5) and (9), exit statuses). Every user string is escaped.
//!
//! This module holds the content ([`Report`] and its rows) and the formatting shared
//! by both layouts; [`html`] and [`markdown`] lay it out.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

mod html;
mod markdown;
#[cfg(test)]
mod tests;

/// One input file or setting.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct InputItem {
    /// What it is, e.g. `"manifest"`, `"measurements"`.
    pub role: String,
    /// Path (as given on the command line, or relative to the report).
    pub path: String,
    /// Short description, e.g. `"3 regions, 10 captures, rotating polarizer"`.
    pub detail: String,
}

impl InputItem {
    /// An input: its role, path and details.
    pub fn new(role: &str, path: impl Into<String>, detail: impl Into<String>) -> Self {
        let (role, path, detail) = (role.to_string(), path.into(), detail.into());
        Self { role, path, detail }
    }
}

/// The observation geometry of one target.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GeometryRow {
    /// Target name.
    pub target: String,
    /// Known class, if any.
    pub class: Option<String>,
    /// Camera zenith θr, degrees.
    pub theta_r_deg: f64,
    /// Smallest and largest source zenith θi, degrees.
    pub theta_i_deg: (f64, f64),
    /// φ = φr − φi, degrees (180 in the plane of incidence).
    pub phi_deg: f64,
    /// Smallest and largest β (eq. 5), degrees.
    pub beta_deg: (f64, f64),
    /// Number of source positions (captures).
    pub captures: usize,
}

/// A reference (literature) index of refraction.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReferenceRow {
    /// Material name.
    pub material: String,
    /// Real part.
    pub n: f64,
    /// Imaginary part.
    pub k: f64,
    /// Where it comes from, e.g. `"paper Table 1"`.
    pub source: String,
}

/// One fitted (n, k) estimate (the fits CSV's columns, plus the view angle).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EstimateRow {
    /// Target name.
    pub target: String,
    /// Known class, if any.
    pub class: Option<String>,
    /// View angle θr, degrees, when one per target.
    pub theta_r_deg: Option<f64>,
    /// Estimated n.
    pub n: f64,
    /// Standard error of n.
    pub n_se: f64,
    /// Estimated k.
    pub k: f64,
    /// Standard error of k.
    pub k_se: f64,
    /// Correlation of the n and k errors.
    pub nk_corr: f64,
    /// RMS of the DoLP residuals.
    pub rms_residual: f64,
    /// Number of measurements fitted.
    pub measurements: usize,
    /// `ok` or why the estimate should not be trusted.
    pub status: polarid_core::FitStatus,
}

/// One classification result (the classification CSV's columns).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ClassificationRow {
    /// Target name.
    pub target: String,
    /// Known class (ground truth), if any.
    pub truth: Option<String>,
    /// Predicted class, or `unknown`.
    pub predicted: String,
    /// Distance to the nearest prototype in (n, k).
    pub distance: f64,
    /// The nearest prototype of another class.
    pub runner_up: Option<String>,
    /// Its distance.
    pub runner_up_distance: Option<f64>,
    /// `ok` or why the result should not be trusted.
    pub status: String,
    /// The consistent set (every material the estimate cannot be told apart from at
    /// `confidence`), best first; `None` when it was not tested.
    pub candidates: Option<Vec<String>>,
    /// The set's confidence, e.g. 0.95.
    pub confidence: Option<f64>,
    /// The confidence region(s) that decide the set, as text
    /// (`polarid_pipeline::classify::regions_text`).
    pub region: Option<String>,
    /// The rule of the answer (the classification CSV's `rule`: `set`, `hypothesis`,
    /// `nearest`; empty when not known).
    pub rule: String,
}

/// The caption of the classification table: the rule(s) the answers used, in words.
fn classification_caption(rows: &[ClassificationRow]) -> String {
    let mut rules: Vec<&str> = Vec::new();
    for r in rows {
        if !r.rule.is_empty() && !rules.contains(&r.rule.as_str()) {
            rules.push(&r.rule);
        }
    }
    let rule = match rules.as_slice() {
        ["set"] => "the set rule (a material when it is the only one consistent)",
        ["hypothesis"] => "hypothesis tests against the measured rows",
        ["nearest"] => "the nearest prototype in (n, k) (the paper's rule)",
        [] => "the classifier's rule",
        _ => "the rule of each row",
    };
    format!(
        "Answers under {rule}: a material, `ambiguous` or `unknown` (the status says why); \
         the consistent set: every material inside the estimate's confidence region \
         (Mahalanobis distance with the estimate's and the prototype's covariance within \
         the χ² quantile)."
    )
}

impl ClassificationRow {
    /// Runner-up distance minus distance (how far the decision is from a tie).
    pub fn margin(&self) -> Option<f64> {
        self.runner_up_distance
            .map(|r| r - self.distance)
            .filter(|m| m.is_finite())
    }
}

/// A generic extra table.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Table {
    /// Caption.
    pub caption: String,
    /// Column headers.
    pub headers: Vec<String>,
    /// Rows of cells (already formatted).
    pub rows: Vec<Vec<String>>,
}

/// A figure: its PNG bytes (embedded in the HTML) and file names (linked from the
/// Markdown, relative to the Markdown file).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Figure {
    /// Short title.
    pub title: String,
    /// Caption: what is shown, and how to read it.
    pub caption: String,
    /// The PNG file's bytes.
    pub png: Vec<u8>,
    /// The PNG file, relative to the Markdown report.
    pub png_file: String,
    /// The SVG file, relative to the Markdown report, if written.
    pub svg_file: Option<String>,
}

impl Figure {
    /// A figure from a rendered plot and the names it was written under.
    pub fn from_rendered(
        title: impl Into<String>,
        caption: impl Into<String>,
        plot: &crate::render::Rendered,
        png_file: impl Into<String>,
        svg_file: Option<String>,
    ) -> Self {
        Self {
            title: title.into(),
            caption: caption.into(),
            png: plot.png.clone(),
            png_file: png_file.into(),
            svg_file,
        }
    }
}

/// The content of a report; the sections are laid out in this order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Report {
    /// Title.
    pub title: String,
    /// Opening paragraphs (plain text).
    pub summary: Vec<String>,
    /// Input files and settings.
    pub inputs: Vec<InputItem>,
    /// Manifest summary as key/value pairs (e.g. `("wavelength", "650 nm")`).
    pub manifest: Vec<(String, String)>,
    /// Observation geometry per target.
    pub geometry: Vec<GeometryRow>,
    /// Reference indices of refraction.
    pub references: Vec<ReferenceRow>,
    /// Fitted indices with standard errors.
    pub estimates: Vec<EstimateRow>,
    /// Classification results.
    pub classification: Vec<ClassificationRow>,
    /// Extra tables, after the classification.
    pub tables: Vec<Table>,
    /// Figures.
    pub figures: Vec<Figure>,
    /// Generator line, e.g. `"polarid 0.1.0 demo"`.
    pub generator: String,
}

/// The report's sections: (HTML id, heading).
pub const SECTIONS: [(&str, &str); 8] = [
    ("inputs", "Inputs"),
    ("geometry", "Geometry"),
    ("reference", "Reference indices"),
    ("estimates", "Estimates"),
    ("classification", "Classification"),
    ("figures", "Plots"),
    ("conventions", "Conventions"),
    ("about", "About this report"),
];

/// Text of the conventions section: (label, text, equation block).
const CONVENTIONS: &[(&str, &str, &str)] = &[
    (
        "Angles",
        "Angles are in degrees in every file, on the command line and in this report \
         (radians inside the code only). θi and θr are the source and camera zenith \
         angles from the target's mean surface normal; φ = φr − φi (180° = scattering in \
         the plane of incidence, the paper's geometry).",
        "",
    ),
    (
        "Index of refraction",
        "The complex index of refraction is N = n + ik with k ≥ 0 for an absorbing \
         medium; the ambient medium is air (N = 1).",
        "",
    ),
    (
        "Stokes parameters and DoLP",
        "Linear Stokes parameters (S0, S1, S2) with S1 = I(0°) − I(90°) and \
         S2 = I(45°) − I(135°); polarizer angles are measured in the image plane from the \
         image's +x axis, counter-clockwise as displayed. DoLP = √(S1² + S2²) / S0.",
        "",
    ),
    (
        "β",
        "β is half the angle between the source and camera directions, the angle of \
         incidence on the microfacets that send light to the camera (eq. 5; in the plane \
         of incidence eq. 10).",
        "cos 2β = cos θi cos θr + sin θi sin θr cos φ        (5)\n\
         β = (θi + θr) / 2   when φ = 180°                 (10)",
    ),
    (
        "DoLP model, eq. (9)",
        "The degree of linear polarization of unpolarized light specularly reflected by \
         the microfacets, fitted to the measurements by Levenberg–Marquardt (§ 5); the \
         standard errors are 1-σ errors from the fit's covariance.",
        "P(n, k, β) = 2A sin²β cos β / (A² cos²β + sin⁴β + B² cos²β)    (9)\n\
         A = √((√C + D) / 2),  B = √((√C − D) / 2)                       (12, 13)\n\
         C = 4n²k² + D²,  D = n² − k² − sin²β                            (14, 15)",
    ),
    (
        "pBRDF, eq. (3)",
        "The Priest–Meier microfacet polarimetric BRDF (sr⁻¹): m_jl are the elements of \
         the Fresnel reflectance Mueller matrix, σ the surface roughness and θ the facet \
         tilt from the mean normal (eq. 4).",
        "f_jl(θi, θr, φ) = m_jl / (8π σ² cos⁴θ) · exp(−tan²θ / (2σ²)) / (cos θr cos θi)   (3)\n\
         θ = arccos((cos θi + cos θr) / (2 cos β))                                      (4)",
    ),
    (
        "Classification",
        "Nearest neighbour with the Euclidean distance in the (n, k) plane (§ 6): a test \
         estimate takes the class of the nearest prototype. The margin is the runner-up \
         distance minus the distance (the nearest prototype of another class). The \
         consistent set at confidence p holds every material whose Mahalanobis distance \
         d_M (the estimate's covariance plus the prototype's, from the fit's standard \
         errors with the systematic error model) is within the χ²₂ quantile: one → that \
         material, several → ambiguous, none → unknown. The confidence region is where \
         that test passes: an ellipse in (n, k), or in (n, u = k²) near k = 0 where the \
         DoLP depends on k only through k² (drawn in the (n, k) plane, cut at k = 0); \
         with a prototype's own covariance the region is wider for that prototype \
         (dashed in the plot).",
        "d_M² = Δᵀ (Σ_est + Σ_proto)⁻¹ Δ ≤ χ²₂(p) = −2 ln(1 − p)     (p = 0.95: d_M ≤ 2.448)",
    ),
    (
        "Exit statuses",
        "polarid commands exit with 0 on success, 2 for bad input or usage (the message \
         names the file, field and value at fault) and 1 for any other failure; a failed \
         command leaves no partial output behind.",
        "",
    ),
];

/// `v` with `decimals` decimals, or an em dash when not finite.
fn num(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        "—".to_string()
    }
}

fn opt_num(v: Option<f64>, decimals: usize) -> String {
    v.map_or_else(|| "—".to_string(), |v| num(v, decimals))
}

fn opt_str(s: &Option<String>) -> String {
    s.clone().unwrap_or_else(|| "—".to_string())
}

fn range(r: (f64, f64), decimals: usize) -> String {
    if r.0 == r.1 {
        num(r.0, decimals)
    } else {
        format!("{}–{}", num(r.0, decimals), num(r.1, decimals))
    }
}

fn value_se(v: f64, se: f64) -> String {
    format!("{} ± {}", num(v, 3), num(se, 3))
}

/// The cells of a classification row in the report's table.
fn classification_cells(c: &ClassificationRow) -> Vec<String> {
    let correct = match &c.truth {
        Some(t) if t == &c.predicted => "yes",
        Some(_) => "no",
        None => "—",
    };
    vec![
        c.target.clone(),
        opt_str(&c.truth),
        c.predicted.clone(),
        num(c.distance, 3),
        opt_str(&c.runner_up),
        opt_num(c.runner_up_distance, 3),
        opt_num(c.margin(), 3),
        correct.to_string(),
        c.status.clone(),
        match (&c.candidates, c.confidence) {
            (Some(v), p) => {
                let set = if v.is_empty() {
                    "none".to_string()
                } else {
                    v.join(", ")
                };
                match p {
                    Some(p) => format!("{set} (at {}%)", p * 100.0),
                    None => set,
                }
            }
            (None, _) => "—".to_string(),
        },
        opt_str(&c.region),
    ]
}

impl Table {
    /// A table of `rows` under `headers`.
    pub fn new(caption: impl Into<String>, headers: &[&str], rows: Vec<Vec<String>>) -> Self {
        Self {
            caption: caption.into(),
            headers: headers.iter().map(|h| h.to_string()).collect(),
            rows,
        }
    }
}

impl Report {
    /// The tables of the report as (section id, caption, headers, rows), formatted.
    fn tables(&self) -> Vec<(&'static str, Table)> {
        let mut out = Vec::new();
        out.push((
            "geometry",
            Table::new(
                "Observation geometry per target (degrees).",
                &["Target", "Class", "θr", "θi", "φ", "β", "Captures"],
                self.geometry
                    .iter()
                    .map(|g| {
                        vec![
                            g.target.clone(),
                            opt_str(&g.class),
                            num(g.theta_r_deg, 1),
                            range(g.theta_i_deg, 1),
                            num(g.phi_deg, 1),
                            range(g.beta_deg, 1),
                            g.captures.to_string(),
                        ]
                    })
                    .collect(),
            ),
        ));
        out.push((
            "reference",
            Table::new(
                "Reference indices of refraction N = n + ik.",
                &["Material", "n", "k", "Source"],
                self.references
                    .iter()
                    .map(|r| {
                        vec![
                            r.material.clone(),
                            num(r.n, 3),
                            num(r.k, 3),
                            r.source.clone(),
                        ]
                    })
                    .collect(),
            ),
        ));
        out.push((
            "estimates",
            Table::new(
                "Fitted indices with 1-σ standard errors (eq. 9).",
                &[
                    "Target",
                    "Class",
                    "θr (°)",
                    "n̂ ± SE",
                    "k̂ ± SE",
                    "corr(n, k)",
                    "RMS residual",
                    "Measurements",
                    "Status",
                ],
                self.estimates
                    .iter()
                    .map(|e| {
                        vec![
                            e.target.clone(),
                            opt_str(&e.class),
                            opt_num(e.theta_r_deg, 1),
                            value_se(e.n, e.n_se),
                            value_se(e.k, e.k_se),
                            num(e.nk_corr, 2),
                            num(e.rms_residual, 4),
                            e.measurements.to_string(),
                            e.status.to_string(),
                        ]
                    })
                    .collect(),
            ),
        ));
        out.push((
            "classification",
            Table::new(
                classification_caption(&self.classification),
                &[
                    "Target",
                    "Known class",
                    "Predicted",
                    "Distance",
                    "Runner-up",
                    "Runner-up distance",
                    "Margin",
                    "Correct",
                    "Status",
                    "Consistent set",
                    "Confidence region",
                ],
                self.classification
                    .iter()
                    .map(classification_cells)
                    .collect(),
            ),
        ));
        for extra in &self.tables {
            out.push(("classification", extra.clone()));
        }
        out
    }

    fn check(&self) -> Result<()> {
        for f in &self.figures {
            if !f.png.starts_with(b"\x89PNG\r\n\x1a\n") {
                bail!("figure {:?} is not a PNG image", f.title);
            }
        }
        Ok(())
    }

    /// Write `dir/stem.html` and `dir/stem.md` (overwriting: callers that must not
    /// overwrite write into a `polarid_io::atomic::StagedDir`). The figures' PNG files
    /// are not written here; the Markdown refers to them by `Figure::png_file`.
    pub fn write(&self, dir: &Path, stem: &str) -> Result<(PathBuf, PathBuf)> {
        if stem.is_empty() || stem.contains(['/', '\\']) {
            bail!("report file stem {stem:?} must be a non-empty file name");
        }
        let html = dir.join(format!("{stem}.html"));
        let md = dir.join(format!("{stem}.md"));
        std::fs::write(&html, self.to_html()?)
            .with_context(|| format!("cannot write {}", html.display()))?;
        std::fs::write(&md, self.to_markdown()?)
            .with_context(|| format!("cannot write {}", md.display()))?;
        Ok((html, md))
    }
}
