//! Reports a scientist can send to a colleague: one self-contained HTML file (plots
//! embedded as base64 `data:` URIs, no scripts, no network) and a Markdown version
//! that references the plots' PNG files.
//!
//! The caller (e.g. `polarid demo`) fills a [`Report`]: inputs, geometry, reference
//! indices, estimates with standard errors, classification results and figures
//! (from [`crate::plots`]); [`Report::to_html`] and [`Report::to_markdown`] lay them
//! out with a fixed "Conventions" section (angles, `N = n + ik`, Stokes `S1`, β, the
//! paper's eqs. (3), (5) and (9), exit statuses). Every user string is escaped.

// Nothing calls this module until `polarid demo` is wired to it.
#![allow(dead_code)]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

/// Standard base64 (RFC 4648, with `=` padding) of `data`.
pub fn base64_encode(data: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let sym = |v: u32| ALPHABET[(v & 63) as usize] as char;
    let mut out = String::with_capacity(data.len().div_ceil(3) * 4);
    for chunk in data.chunks(3) {
        let b = [
            chunk.first().copied().unwrap_or(0),
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let v = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        out.push(sym(v >> 18));
        out.push(sym(v >> 12));
        out.push(if chunk.len() > 1 { sym(v >> 6) } else { '=' });
        out.push(if chunk.len() > 2 { sym(v) } else { '=' });
    }
    out
}

/// `s` with `& < > " '` replaced by character references (safe in HTML text and in
/// quoted attribute values).
pub fn html_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// `s` as literal Markdown text on one line: Markdown punctuation backslash-escaped
/// (so user strings cannot open tags, links, emphasis or table cells), newlines as
/// spaces.
pub fn md_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '\\' | '`' | '*' | '_' | '[' | ']' | '<' | '>' | '|' | '#' | '!' | '&' | '$' => {
                out.push('\\');
                out.push(c);
            }
            '\r' | '\n' => out.push(' '),
            _ => out.push(c),
        }
    }
    out
}

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
        plot: &crate::plots::Rendered,
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
         distance minus the distance (the nearest prototype of another class).",
        "",
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

impl Report {
    /// The tables of the report as (section id, caption, headers, rows), formatted.
    fn tables(&self) -> Vec<(&'static str, Table)> {
        let t = |caption: &str, headers: &[&str], rows: Vec<Vec<String>>| Table {
            caption: caption.to_string(),
            headers: headers.iter().map(|h| h.to_string()).collect(),
            rows,
        };
        let mut out = Vec::new();
        out.push((
            "geometry",
            t(
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
            t(
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
            t(
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
            t(
                "Nearest-neighbour classification in (n, k).",
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
                ],
                self.classification
                    .iter()
                    .map(|c| {
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
                        ]
                    })
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

    /// The self-contained HTML report (UTF-8).
    pub fn to_html(&self) -> Result<String> {
        self.check()?;
        let e = html_escape;
        let mut h = String::new();
        let title = if self.title.is_empty() {
            "polarid report"
        } else {
            &self.title
        };
        let _ = write!(
            h,
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
             <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
             <title>{}</title>\n<style>\n{}</style>\n</head>\n<body>\n<main>\n<h1>{}</h1>\n",
            e(title),
            CSS,
            e(title)
        );
        for p in &self.summary {
            let _ = writeln!(h, "<p>{}</p>", e(p));
        }
        h.push_str("<nav><ul>");
        for (id, heading) in SECTIONS {
            let _ = write!(h, "<li><a href=\"#{id}\">{heading}</a></li>");
        }
        h.push_str("</ul></nav>\n");

        // Inputs.
        h.push_str("<section id=\"inputs\">\n<h2>Inputs</h2>\n");
        if self.inputs.is_empty() && self.manifest.is_empty() {
            h.push_str("<p class=\"none\">None.</p>\n");
        }
        if !self.inputs.is_empty() {
            h.push_str("<table>\n<thead><tr><th>Input</th><th>Path</th><th>Details</th></tr></thead>\n<tbody>\n");
            for i in &self.inputs {
                let _ = writeln!(
                    h,
                    "<tr><td>{}</td><td><code>{}</code></td><td>{}</td></tr>",
                    e(&i.role),
                    e(&i.path),
                    e(&i.detail)
                );
            }
            h.push_str("</tbody>\n</table>\n");
        }
        if !self.manifest.is_empty() {
            h.push_str("<h3>Manifest</h3>\n<dl>\n");
            for (k, v) in &self.manifest {
                let _ = writeln!(h, "<dt>{}</dt><dd>{}</dd>", e(k), e(v));
            }
            h.push_str("</dl>\n");
        }
        h.push_str("</section>\n");

        // Tables.
        let tables = self.tables();
        for (id, heading) in SECTIONS.iter().take(5).skip(1) {
            let _ = write!(h, "<section id=\"{id}\">\n<h2>{heading}</h2>\n");
            for (_, t) in tables.iter().filter(|(tid, _)| tid == id) {
                html_table(&mut h, t);
            }
            h.push_str("</section>\n");
        }

        // Figures.
        h.push_str("<section id=\"figures\">\n<h2>Plots</h2>\n");
        if self.figures.is_empty() {
            h.push_str("<p class=\"none\">None.</p>\n");
        }
        for (i, f) in self.figures.iter().enumerate() {
            let alt = if f.title.is_empty() {
                &f.caption
            } else {
                &f.title
            };
            let (w, ht) = png_size(&f.png).unwrap_or((0, 0));
            let size = if w > 0 {
                format!(" width=\"{w}\" height=\"{ht}\"")
            } else {
                String::new()
            };
            let _ = write!(
                h,
                "<figure id=\"figure-{}\">\n<img src=\"data:image/png;base64,{}\" alt=\"{}\"{}>\n\
                 <figcaption><strong>Figure {}. {}</strong> {}</figcaption>\n</figure>\n",
                i + 1,
                base64_encode(&f.png),
                e(alt),
                size,
                i + 1,
                e(&f.title),
                e(&f.caption)
            );
        }
        h.push_str("</section>\n");

        // Conventions.
        h.push_str("<section id=\"conventions\">\n<h2>Conventions</h2>\n<dl>\n");
        for (label, text, eq) in CONVENTIONS {
            let _ = write!(h, "<dt>{}</dt>\n<dd><p>{}</p>", e(label), e(text));
            if !eq.is_empty() {
                let _ = write!(h, "<pre class=\"eq\">{}</pre>", e(eq));
            }
            h.push_str("</dd>\n");
        }
        h.push_str("</dl>\n<p>Equation numbers refer to the paper the project implements, \
                     “Material classification using passive polarimetric imagery”.</p>\n</section>\n");

        // About.
        let gen_line = if self.generator.is_empty() {
            format!("polarid {}", env!("CARGO_PKG_VERSION"))
        } else {
            self.generator.clone()
        };
        let _ = write!(
            h,
            "<section id=\"about\">\n<h2>About this report</h2>\n<p>Generated by {}. \
             This file is self-contained: the plots are embedded, and it loads nothing \
             from the network.</p>\n</section>\n</main>\n</body>\n</html>\n",
            e(&gen_line)
        );
        Ok(h)
    }

    /// The Markdown report; figures are referenced by their file names.
    pub fn to_markdown(&self) -> Result<String> {
        self.check()?;
        let m = md_escape;
        let mut s = String::new();
        let title = if self.title.is_empty() {
            "polarid report"
        } else {
            &self.title
        };
        let _ = writeln!(s, "# {}\n", m(title));
        for p in &self.summary {
            let _ = writeln!(s, "{}\n", m(p));
        }
        s.push_str("## Inputs\n\n");
        if self.inputs.is_empty() && self.manifest.is_empty() {
            s.push_str("None.\n\n");
        }
        if !self.inputs.is_empty() {
            md_table(
                &mut s,
                &Table {
                    caption: String::new(),
                    headers: vec!["Input".into(), "Path".into(), "Details".into()],
                    rows: self
                        .inputs
                        .iter()
                        .map(|i| vec![i.role.clone(), i.path.clone(), i.detail.clone()])
                        .collect(),
                },
            );
        }
        if !self.manifest.is_empty() {
            s.push_str("Manifest:\n\n");
            for (k, v) in &self.manifest {
                let _ = writeln!(s, "- {}: {}", m(k), m(v));
            }
            s.push('\n');
        }
        let tables = self.tables();
        for (id, heading) in SECTIONS.iter().take(5).skip(1) {
            let _ = writeln!(s, "## {heading}\n");
            for (_, t) in tables.iter().filter(|(tid, _)| tid == id) {
                md_table(&mut s, t);
            }
        }
        s.push_str("## Plots\n\n");
        if self.figures.is_empty() {
            s.push_str("None.\n\n");
        }
        for (i, f) in self.figures.iter().enumerate() {
            let _ = writeln!(s, "![{}](<{}>)\n", m(&f.title), md_link_target(&f.png_file));
            let _ = write!(s, "**Figure {}. {}** {}", i + 1, m(&f.title), m(&f.caption));
            if let Some(svg) = &f.svg_file {
                let _ = write!(s, " ([SVG](<{}>))", md_link_target(svg));
            }
            s.push_str("\n\n");
        }
        s.push_str("## Conventions\n\n");
        for (label, text, eq) in CONVENTIONS {
            let _ = writeln!(s, "- **{}.** {}", m(label), m(text));
            if !eq.is_empty() {
                s.push_str("\n  ```text\n");
                for line in eq.lines() {
                    let _ = writeln!(s, "  {line}");
                }
                s.push_str("  ```\n");
            }
        }
        s.push_str(
            "\nEquation numbers refer to the paper the project implements, \
             “Material classification using passive polarimetric imagery”.\n\n",
        );
        let gen_line = if self.generator.is_empty() {
            format!("polarid {}", env!("CARGO_PKG_VERSION"))
        } else {
            self.generator.clone()
        };
        let _ = writeln!(s, "## About this report\n\nGenerated by {}.", m(&gen_line));
        Ok(s)
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

/// A link target inside `<...>`: angle brackets and newlines cannot appear.
fn md_link_target(path: &str) -> String {
    path.chars()
        .map(|c| match c {
            '<' => "%3C".to_string(),
            '>' => "%3E".to_string(),
            ' ' => "%20".to_string(),
            '\n' | '\r' => String::new(),
            c => c.to_string(),
        })
        .collect()
}

/// Width and height from a PNG's IHDR chunk.
fn png_size(png: &[u8]) -> Option<(u32, u32)> {
    let w = png.get(16..20)?;
    let h = png.get(20..24)?;
    Some((
        u32::from_be_bytes(w.try_into().ok()?),
        u32::from_be_bytes(h.try_into().ok()?),
    ))
}

fn html_table(h: &mut String, t: &Table) {
    let e = html_escape;
    h.push_str("<table>\n");
    if !t.caption.is_empty() {
        let _ = writeln!(h, "<caption>{}</caption>", e(&t.caption));
    }
    h.push_str("<thead><tr>");
    for c in &t.headers {
        let _ = write!(h, "<th>{}</th>", e(c));
    }
    h.push_str("</tr></thead>\n<tbody>\n");
    if t.rows.is_empty() {
        let _ = writeln!(
            h,
            "<tr><td class=\"none\" colspan=\"{}\">None.</td></tr>",
            t.headers.len().max(1)
        );
    }
    for r in &t.rows {
        h.push_str("<tr>");
        for c in r {
            let _ = write!(h, "<td>{}</td>", e(c));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</tbody>\n</table>\n");
}

fn md_table(s: &mut String, t: &Table) {
    let m = md_escape;
    if !t.caption.is_empty() {
        let _ = writeln!(s, "{}\n", m(&t.caption));
    }
    if t.headers.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "| {} |",
        t.headers
            .iter()
            .map(|c| m(c))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    let _ = writeln!(s, "|{}", " --- |".repeat(t.headers.len()));
    if t.rows.is_empty() {
        let mut cells = vec!["None.".to_string()];
        cells.resize(t.headers.len(), String::new());
        let _ = writeln!(s, "| {} |", cells.join(" | "));
    }
    for r in &t.rows {
        let mut cells: Vec<String> = r.iter().map(|c| m(c)).collect();
        cells.resize(t.headers.len().max(cells.len()), String::new());
        let _ = writeln!(s, "| {} |", cells.join(" | "));
    }
    s.push('\n');
}

const CSS: &str = "\
body { font-family: 'DejaVu Sans', 'Helvetica Neue', Arial, sans-serif; color: #1a1a1a; \
background: #fff; margin: 0; line-height: 1.45; }
main { max-width: 1060px; margin: 0 auto; padding: 24px 28px 48px; }
h1 { font-size: 1.9em; margin: 0.2em 0 0.4em; }
h2 { font-size: 1.4em; border-bottom: 2px solid #d0d7de; padding-bottom: 0.2em; margin-top: 1.6em; }
nav ul { list-style: none; padding: 0; display: flex; flex-wrap: wrap; gap: 0.4em 1.2em; }
nav a { color: #0b5cad; text-decoration: none; }
table { border-collapse: collapse; margin: 0.6em 0 1.2em; font-size: 0.95em; }
caption { caption-side: top; text-align: left; font-style: italic; padding-bottom: 0.3em; }
th, td { border: 1px solid #c8ced6; padding: 0.3em 0.6em; text-align: left; vertical-align: top; }
th { background: #f0f3f6; }
tbody tr:nth-child(even) { background: #fafbfc; }
td.none, p.none { color: #666; font-style: italic; }
figure { margin: 1.2em 0 2em; }
figure img { max-width: 100%; height: auto; border: 1px solid #e1e4e8; }
figcaption { font-size: 0.95em; margin-top: 0.4em; }
dl dt { font-weight: bold; margin-top: 0.8em; }
dl dd { margin-left: 1.2em; }
dd p { margin: 0.2em 0; }
pre.eq { background: #f6f8fa; padding: 0.6em 0.8em; overflow-x: auto; font-size: 1em; }
code { font-family: 'DejaVu Sans Mono', monospace; font-size: 0.92em; }
";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plots::{self, PlotSize};

    #[test]
    fn base64_rfc4648_vectors() {
        for (input, want) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64_encode(input.as_bytes()), want, "input {input:?}");
        }
        assert_eq!(base64_encode(&[0xff, 0xfe, 0xfd, 0x00]), "//79AA==");
    }

    #[test]
    fn escapes() {
        assert_eq!(
            html_escape(r#"<a href="x">&'</a>"#),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;&lt;/a&gt;"
        );
        assert_eq!(md_escape("a|b *c* <d>\n_e_"), r"a\|b \*c\* \<d\> \_e\_");
    }

    const EVIL: &str = "<script>alert('x')</script> & \"q\" | *b*";

    /// A report filled with synthetic data in the shape of the paper's Tables 1 and 2.
    pub(crate) fn sample_report(evil: bool) -> (Report, Vec<(String, plots::Rendered)>) {
        let train = [
            ("green paint", 1.39, 0.34, 1.47, 0.47, 40.0, 80.0),
            ("aluminum", 1.24, 6.60, 1.64, 4.56, 35.0, 80.0),
            ("copper", 0.40, 2.95, 0.54, 3.19, 35.0, 70.0),
        ];
        let tests = [
            ("test θr=60°", 60.0, 1.37, 3.97),
            ("test θr=50°", 50.0, 1.60, 4.34),
        ];
        let size = PlotSize::REPORT;
        let mut series = Vec::new();
        let mut geometry = Vec::new();
        for &(name, _, _, nh, kh, i0, i1) in &train {
            let pts: Vec<plots::DolpPoint> = (0..=((i1 - i0) / 5.0) as usize)
                .map(|j| {
                    let ti = i0 + 5.0 * j as f64;
                    let beta = 0.5 * (ti + 60.0);
                    plots::DolpPoint {
                        beta_deg: beta,
                        dolp: polarid_core::dop::dop(nh, kh, beta.to_radians())
                            + 0.006 * (j as f64 * 2.1).sin(),
                        dolp_se: Some(0.008),
                    }
                })
                .collect();
            geometry.push(GeometryRow {
                target: name.into(),
                class: Some(name.into()),
                theta_r_deg: 60.0,
                theta_i_deg: (i0, i1),
                phi_deg: 180.0,
                beta_deg: (0.5 * (i0 + 60.0), 0.5 * (i1 + 60.0)),
                captures: pts.len(),
            });
            series.push(plots::DolpSeries {
                label: name.into(),
                points: pts,
                curve: plots::eq9_curve(nh, kh, 45.0, 72.0, 120),
                curve_label: Some(format!("fit n = {nh:.2}, k = {kh:.2}")),
            });
        }
        let dolp = plots::dolp_vs_beta("DoLP against β, training plates (θr = 60°)", &series, size)
            .unwrap();
        let protos: Vec<plots::Prototype> = train
            .iter()
            .map(|t| plots::Prototype {
                class: t.0.into(),
                n: t.3,
                k: t.4,
            })
            .collect();
        let ests: Vec<plots::NkEstimate> = tests
            .iter()
            .map(|t| plots::NkEstimate {
                label: t.0.into(),
                n: t.2,
                k: t.3,
                n_se: 0.09,
                k_se: 0.35,
                corr: 0.7,
                predicted: Some("aluminum".into()),
            })
            .collect();
        let nk =
            plots::nk_plane("Test estimates in the (n, k) plane", &protos, &ests, size).unwrap();
        let (w, h) = (96usize, 64usize);
        let classes: Vec<u16> = (0..w * h)
            .map(|i| match (i % w, i / w) {
                (x, y) if (10..40).contains(&x) && (8..56).contains(&y) => 1,
                (x, y) if (50..86).contains(&x) && (8..30).contains(&y) => 2,
                (x, y) if (50..86).contains(&x) && (34..56).contains(&y) => 3,
                _ => 0,
            })
            .collect();
        let names: Vec<String> = train.iter().map(|t| t.0.to_string()).collect();
        let cmap = plots::class_map("Material map", w, h, &classes, &names, size).unwrap();
        let dolp_img: Vec<f32> = (0..w * h)
            .map(|i| ((i % w) as f32 / w as f32) * 0.6 + ((i / w) as f32 / h as f32) * 0.2)
            .collect();
        let smap =
            plots::scalar_map("DoLP image, θi = 45°", w, h, &dolp_img, None, "DoLP", size).unwrap();

        let tag = if evil { EVIL } else { "" };
        let report = Report {
            title: format!("polarid demo: the paper's experiment in simulation{tag}"),
            summary: vec![format!(
                "Three training plates and one test plate, simulated from the pBRDF, measured \
                 and fitted with eq. (9), then classified by nearest neighbour.{tag}"
            )],
            inputs: vec![InputItem {
                role: "manifest".into(),
                path: format!("captures/manifest{tag}.toml"),
                detail: "3 training plates, 2 test views, rotating polarizer 0/45/90/135°".into(),
            }],
            manifest: vec![
                ("wavelength".into(), "650 nm".into()),
                ("sensor".into(), format!("12 bit, full well 10000 e⁻{tag}")),
            ],
            geometry,
            references: train
                .iter()
                .map(|t| ReferenceRow {
                    material: t.0.into(),
                    n: t.1,
                    k: t.2,
                    source: "paper, Table 1".into(),
                })
                .collect(),
            estimates: train
                .iter()
                .map(|t| EstimateRow {
                    target: t.0.into(),
                    class: Some(t.0.into()),
                    theta_r_deg: Some(60.0),
                    n: t.3,
                    n_se: 0.05,
                    k: t.4,
                    k_se: 0.2,
                    nk_corr: 0.8,
                    rms_residual: 0.0042,
                    measurements: 9,
                    status: polarid_core::FitStatus::Ok,
                })
                .chain(tests.iter().map(|t| EstimateRow {
                    target: format!("{}{tag}", t.0),
                    class: Some("aluminum".into()),
                    theta_r_deg: Some(t.1),
                    n: t.2,
                    n_se: 0.09,
                    k: t.3,
                    k_se: 0.35,
                    nk_corr: 0.7,
                    rms_residual: 0.005,
                    measurements: 10,
                    status: polarid_core::FitStatus::Ok,
                }))
                .collect(),
            classification: tests
                .iter()
                .map(|t| ClassificationRow {
                    target: format!("{}{tag}", t.0),
                    truth: Some("aluminum".into()),
                    predicted: "aluminum".into(),
                    distance: 0.62,
                    runner_up: Some("copper".into()),
                    runner_up_distance: Some(1.27),
                    status: "ok".into(),
                })
                .collect(),
            tables: vec![],
            figures: vec![
                Figure::from_rendered(
                    "DoLP against β",
                    "Measured DoLP (points, ±1 SE bars) and the fitted eq. (9) curves.",
                    &dolp,
                    "dolp_beta.png",
                    Some("dolp_beta.svg".into()),
                ),
                Figure::from_rendered(
                    "The (n, k) plane",
                    format!(
                        "Prototypes, test estimates with 1-σ ellipses, and the \
                         nearest-neighbour regions.{tag}"
                    ),
                    &nk,
                    "nk_plane.png",
                    Some("nk_plane.svg".into()),
                ),
                Figure::from_rendered(
                    "Material map",
                    "Class of each pixel.",
                    &cmap,
                    "class_map.png",
                    None,
                ),
                Figure::from_rendered(
                    "DoLP image",
                    "DoLP of one capture.",
                    &smap,
                    "dolp_map.png",
                    None,
                ),
            ],
            generator: "polarid test suite".into(),
        };
        let plots = vec![
            ("dolp_beta".to_string(), dolp),
            ("nk_plane".to_string(), nk),
            ("class_map".to_string(), cmap),
            ("dolp_map".to_string(), smap),
        ];
        (report, plots)
    }

    #[test]
    fn html_has_every_section_and_embedded_plots() {
        let (report, _) = sample_report(false);
        let html = report.to_html().unwrap();
        assert!(html.starts_with("<!DOCTYPE html>"));
        for (id, heading) in SECTIONS {
            assert!(
                html.contains(&format!("<section id=\"{id}\">")),
                "section {id}"
            );
            assert!(
                html.contains(&format!("<h2>{heading}</h2>")),
                "heading {heading}"
            );
        }
        assert_eq!(html.matches("<img src=\"data:image/png;base64,").count(), 4);
        // The embedded data is exactly the figure's PNG.
        let b64 = base64_encode(&report.figures[1].png);
        assert!(html.contains(&format!("data:image/png;base64,{b64}\"")));
        assert!(html.contains("width=\"1000\" height=\"640\""));
        // Tables carry the values.
        assert!(html.contains("<td>1.370 ± 0.090</td>"), "estimate with SE");
        assert!(html.contains("<td>0.650</td>"), "margin = 1.27 - 0.62");
        assert!(html.contains("<td>6.600</td>"), "reference k of aluminum");
        assert!(html.contains("S1 = I(0°) − I(90°)"));
        assert!(html.contains("P(n, k, β) = 2A sin²β cos β"));
        assert!(html.contains("exp(−tan²θ / (2σ²))"));
        assert!(html.contains("exit with 0 on success, 2 for bad input"));
        // Self-contained: nothing is fetched.
        assert!(!html.contains("http://") && !html.contains("https://"));
        assert!(!html.contains("<script"));
    }

    #[test]
    fn user_strings_are_escaped() {
        let (report, _) = sample_report(true);
        let html = report.to_html().unwrap();
        assert!(!html.contains("<script"), "unescaped script tag");
        assert!(!html.contains("alert('x')"));
        assert!(
            html.contains("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; &quot;q&quot;")
        );
        // Every tag in the document is one the report itself writes.
        let allowed = [
            "!DOCTYPE",
            "html",
            "head",
            "meta",
            "title",
            "style",
            "body",
            "main",
            "h1",
            "h2",
            "h3",
            "p",
            "nav",
            "ul",
            "li",
            "a",
            "section",
            "table",
            "caption",
            "thead",
            "tbody",
            "tr",
            "th",
            "td",
            "code",
            "dl",
            "dt",
            "dd",
            "figure",
            "img",
            "figcaption",
            "strong",
            "pre",
        ];
        for part in html.split('<').skip(1) {
            let name: String = part
                .trim_start_matches('/')
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '!')
                .collect();
            let name = if name.eq_ignore_ascii_case("!DOCTYPE") {
                "!DOCTYPE".into()
            } else {
                name
            };
            assert!(allowed.contains(&name.as_str()), "unexpected tag <{name}");
        }
        let md = report.to_markdown().unwrap();
        // Every '<' in the Markdown is escaped, or opens one of our link targets.
        for (i, _) in md.match_indices('<') {
            let before = &md[..i];
            assert!(
                before.ends_with('\\') || before.ends_with("]("),
                "unescaped '<' at {i}: {}",
                &md[i.saturating_sub(20)..(i + 20).min(md.len())]
            );
        }
        assert!(md.contains(r#"\<script\>alert('x')\</script\> \& "q" \| \*b\*"#));
    }

    #[test]
    fn markdown_references_plot_files() {
        let dir = tempfile::tempdir().unwrap();
        let (report, plots) = sample_report(false);
        for (stem, r) in &plots {
            r.write(dir.path(), stem).unwrap();
        }
        let (html_path, md_path) = report.write(dir.path(), "report").unwrap();
        let md = std::fs::read_to_string(&md_path).unwrap();
        for heading in [
            "## Inputs",
            "## Geometry",
            "## Reference indices",
            "## Estimates",
            "## Classification",
            "## Plots",
            "## Conventions",
        ] {
            assert!(md.contains(heading), "{heading}");
        }
        for f in &report.figures {
            let link = format!("](<{}>)", f.png_file);
            assert!(md.contains(&link), "{link}");
            assert!(dir.path().join(&f.png_file).is_file());
        }
        assert!(md.contains("([SVG](<nk_plane.svg>))"));
        assert!(md.contains(
            "| test θr=60° | aluminum | aluminum | 0.620 | copper | 1.270 | 0.650 | yes | ok |"
        ));
        let html = std::fs::read_to_string(html_path).unwrap();
        assert_eq!(html, report.to_html().unwrap());
    }

    #[test]
    fn empty_report_still_has_all_sections() {
        let r = Report::default();
        let html = r.to_html().unwrap();
        for (id, _) in SECTIONS {
            assert!(html.contains(&format!("<section id=\"{id}\">")), "{id}");
        }
        assert!(html.contains("None."));
        assert!(r.to_markdown().unwrap().contains("## Conventions"));
        let bad = Report {
            figures: vec![Figure {
                title: "x".into(),
                png: b"not a png".to_vec(),
                ..Figure::default()
            }],
            ..Report::default()
        };
        assert!(bad.to_html().unwrap_err().to_string().contains("not a PNG"));
    }

    /// The report opens in headless Chromium without errors and all its plots decode
    /// (`scripts/check_report.sh`; skipped when Chromium is not installed, unless
    /// `POLARID_REQUIRE_BROWSER=1`).
    #[test]
    fn report_renders_in_headless_browser() {
        let dir = tempfile::tempdir().unwrap();
        let (report, _) = sample_report(false);
        let (html, _) = report.write(dir.path(), "report").unwrap();
        let shot = dir.path().join("shot.png");
        let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scripts/check_report.sh");
        let out = match std::process::Command::new("bash")
            .arg(script)
            .arg(&html)
            .arg(&shot)
            .output()
        {
            Ok(o) => o,
            Err(e) => {
                assert!(
                    std::env::var("POLARID_REQUIRE_BROWSER").as_deref() != Ok("1"),
                    "cannot run bash: {e}"
                );
                eprintln!("skipped: cannot run bash: {e}");
                return;
            }
        };
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.success(),
            "check_report.sh failed:\n{stdout}\n{stderr}"
        );
        if stdout.contains("SKIPPED") {
            eprintln!("{stdout}");
            return;
        }
        assert!(
            stdout.contains(": 4 images, 0 not decoded, 0 errors"),
            "{stdout}"
        );
        let img = image::open(&shot).unwrap();
        assert_eq!(img.width(), 1200);
    }

    /// Writes a sample report for the headless-browser check and the README picture:
    /// `POLARID_SAMPLE_REPORT_DIR=DIR cargo test -p polarid-cli --release -- --ignored
    /// write_sample_report`, then `scripts/check_report.sh DIR/report.html OUT.png`.
    #[test]
    #[ignore = "writes files to $POLARID_SAMPLE_REPORT_DIR"]
    fn write_sample_report() {
        let Some(dir) = std::env::var_os("POLARID_SAMPLE_REPORT_DIR") else {
            panic!("set POLARID_SAMPLE_REPORT_DIR");
        };
        let dir = PathBuf::from(dir);
        std::fs::create_dir_all(&dir).unwrap();
        let (report, plots) = sample_report(false);
        for (stem, r) in &plots {
            r.write(&dir, stem).unwrap();
        }
        report.write(&dir, "report").unwrap();
    }
}
