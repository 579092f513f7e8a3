//! The self-contained HTML layout of a [`Report`].

use std::fmt::Write as _;

use anyhow::Result;

use super::{CONVENTIONS, Report, SECTIONS, Table};
use crate::render::base64;

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

impl Report {
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
                base64::encode(&f.png),
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
