//! Wolff's metal/dielectric baseline on the command line: the options shared by
//! `classify` and `evaluate`, and `evaluate`'s rendering of the scores.

use std::path::PathBuf;

use polarid_io::table::fmt_f64;
use polarid_pipeline::classify::{WolffRequest, WolffSettings};
use polarid_pipeline::evaluate::{WolffEval, ratio};

use super::common::matrix;
use crate::BadInput;

/// Options of Wolff's metal/dielectric baseline, shared by `classify` and `evaluate`.
#[derive(Debug, Clone, clap::Args)]
pub struct WolffArgs {
    /// Also run Wolff's metal/dielectric baseline on these measurements (the CSV given to
    /// `polarid fit`): `classify` adds columns wolff_class, wolff_fr_max, wolff_beta_deg;
    /// `evaluate` reports its metal/dielectric accuracy.
    #[arg(long, value_name = "MEASUREMENTS.csv")]
    pub wolff: Option<PathBuf>,
    /// Wolff's threshold on the Fresnel ratio (1 + P)/(1 - P): dielectric above it
    /// (a finite number > 1).
    #[arg(long, value_name = "RATIO", default_value_t = 6.0, requires = "wolff")]
    pub wolff_threshold: f64,
    /// Wolff's window of specular angles beta, degrees, as one word MIN,MAX
    /// (0 <= MIN <= MAX <= 90), e.g. `--wolff-beta 40,70`.
    #[arg(long, value_name = "MIN,MAX", default_value = "40,70",
          value_parser = parse_beta_window, requires = "wolff")]
    pub wolff_beta: (f64, f64),
}

/// `s` cut to 40 characters (with an ellipsis) for a message.
fn shorten(s: &str) -> String {
    if s.chars().count() <= 40 {
        format!("{s:?}")
    } else {
        format!("{:?}…", s.chars().take(40).collect::<String>())
    }
}

/// `--wolff-beta MIN,MAX`: degrees, finite, `0 <= MIN <= MAX <= 90`.
fn parse_beta_window(s: &str) -> Result<(f64, f64), String> {
    let short = shorten(s);
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("expected MIN,MAX in degrees (one word), got {short}"))?;
    let parse = |t: &str| -> Result<f64, String> {
        let v: f64 = t
            .trim()
            .parse()
            .map_err(|_| format!("{} is not a number (degrees)", shorten(t)))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{} is not finite", shorten(t)))
        }
    };
    let (lo, hi) = (parse(a)?, parse(b)?);
    if !(0.0..=90.0).contains(&lo) || !(0.0..=90.0).contains(&hi) {
        return Err(format!("beta must be in [0, 90] degrees, got {short}"));
    }
    if lo > hi {
        return Err(format!("MIN must be <= MAX, got {short} degrees"));
    }
    Ok((lo, hi))
}

impl WolffArgs {
    /// With `--wolff`: the measurements file and the checked settings (a bad threshold or
    /// window is a usage error). `None` without `--wolff`.
    pub fn request(&self) -> anyhow::Result<Option<WolffRequest>> {
        let Some(m) = &self.wolff else {
            return Ok(None);
        };
        let t = self.wolff_threshold;
        if !(t.is_finite() && t > 1.0) {
            return Err(BadInput(format!(
                "--wolff-threshold must be a finite number > 1, got {}",
                shorten(&t.to_string()).trim_matches('"')
            ))
            .into());
        }
        let settings = WolffSettings {
            threshold: t,
            beta_deg: self.wolff_beta,
        };
        // The options are checked above in degrees; this is the core rule's own check.
        settings.check().map_err(|e| {
            BadInput(format!(
                "--wolff-threshold {t} --wolff-beta {},{} (degrees) is not usable: {e}",
                settings.beta_deg.0, settings.beta_deg.1
            ))
        })?;
        Ok(Some(WolffRequest {
            measurements: m.clone(),
            settings,
        }))
    }
}

/// Wolff's part of the printed summary.
pub fn wolff_table(w: &WolffEval) -> String {
    let mut s = format!(
        "Wolff's baseline, metal vs dielectric ({}; measurements {}; true categories from {}): \
         confusion matrix (rows: true category, columns: Wolff)\n",
        w.settings,
        w.measurements.display(),
        w.categories
    );
    s.push_str(&matrix(&w.confusion, "true\\wolff"));
    s.push_str(&format!(
        "wolff accuracy (metal/dielectric): {:.4} ({}/{})\n",
        w.accuracy,
        w.confusion.correct(),
        w.confusion.total()
    ));
    s.push_str(&format!(
        "nearest neighbour on the same targets: {:.4} ({}/{}) by material, {:.4} ({}/{}) by \
         metal/dielectric\n",
        ratio(w.nn_material),
        w.nn_material.0,
        w.nn_material.1,
        ratio(w.nn_binary),
        w.nn_binary.0,
        w.nn_binary.1
    ));
    for (t, c, cat) in &w.not_scored {
        match cat {
            Some(cat) => s.push_str(&format!(
                "wolff: not scored {t}: class `{c}` has category `{cat}`, not metal or \
                 dielectric\n"
            )),
            None => s.push_str(&format!(
                "wolff: not scored {t}: class `{c}` has no category (give one with \
                 --wolff-category '{c}=metal|dielectric')\n"
            )),
        }
    }
    for t in &w.no_rows {
        s.push_str(&format!(
            "wolff: warning: target {t} has no row in {}; Wolff answers unknown\n",
            w.measurements.display()
        ));
    }
    s
}

/// Wolff's lines of the CSV output (`#` comments after the classifier's header line).
pub fn wolff_csv_header(w: &WolffEval) -> String {
    let c = &w.confusion;
    let mut s = format!(
        "# wolff, metal vs dielectric ({}; measurements {}; true categories from {}): \
         accuracy {} ({}/{}); nearest neighbour on the same targets: {} ({}/{}) by material, \
         {} ({}/{}) by metal/dielectric\n",
        w.settings,
        w.measurements.display(),
        w.categories,
        fmt_f64(w.accuracy),
        c.correct(),
        c.total(),
        fmt_f64(ratio(w.nn_material)),
        w.nn_material.0,
        w.nn_material.1,
        fmt_f64(ratio(w.nn_binary)),
        w.nn_binary.0,
        w.nn_binary.1
    );
    s.push_str(&format!(
        "# wolff confusion: truth,{},total\n",
        c.predicted.join(",")
    ));
    // ok (c.counts[r]): one row of counts per true category.
    for (r, t) in c.truth.iter().enumerate() {
        let counts: Vec<String> = c.counts[r].iter().map(u64::to_string).collect();
        s.push_str(&format!(
            "# wolff confusion: {t},{},{}\n",
            counts.join(","),
            c.counts[r].iter().sum::<u64>()
        ));
    }
    for (t, cl, cat) in &w.not_scored {
        s.push_str(&format!(
            "# wolff not scored: {t} (class {cl}, category {})\n",
            cat.as_deref().unwrap_or("none")
        ));
    }
    s
}

/// A finite number as JSON, else `null`.
pub fn num(x: f64) -> serde_json::Value {
    if x.is_finite() {
        serde_json::json!(x)
    } else {
        serde_json::Value::Null
    }
}

/// Wolff's part of the JSON output.
pub fn wolff_json(w: &WolffEval) -> serde_json::Value {
    let c = &w.confusion;
    serde_json::json!({
        "settings": w.settings,
        "measurements": w.measurements.display().to_string(),
        "categories_from": w.categories,
        "accuracy": num(w.accuracy),
        "correct": c.correct(),
        "total": c.total(),
        "truth": c.truth,
        "predicted": c.predicted,
        "counts": c.counts,
        "classifier_accuracy_material": num(ratio(w.nn_material)),
        "classifier_correct_material": w.nn_material.0,
        "classifier_accuracy_metal_dielectric": num(ratio(w.nn_binary)),
        "classifier_correct_metal_dielectric": w.nn_binary.0,
        "not_scored": w.not_scored.iter().map(|(t, c, cat)| serde_json::json!({
            "target": t, "class": c, "category": cat,
        })).collect::<Vec<_>>(),
        "no_rows": w.no_rows,
        "items": w.items.iter().map(|i| serde_json::json!({
            "target": i.target,
            "class": i.class,
            "category": i.category,
            "category_from": i.category_source,
            "wolff": i.decision.class.name(),
            "fr_max": num(i.decision.fr_max),
            "beta_deg": num(i.decision.beta_at_max.to_degrees()),
            "used": i.decision.used,
            "predicted": i.predicted,
            "predicted_category": i.predicted_category,
        })).collect::<Vec<_>>(),
    })
}
