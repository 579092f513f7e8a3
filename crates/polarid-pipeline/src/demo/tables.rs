//! The demo's text tables: the analogues of the paper's Tables 1 and 2.

use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::FitRow;

use super::plates::{PLATES, paper_estimate};

/// `v ± se` with at least 3 decimals, more (up to 5) so that `se` shows two
/// significant digits.
pub fn pm(v: f64, se: f64) -> String {
    if se.is_finite() && se > 0.0 {
        let d = (1.0 - se.log10().floor()).clamp(3.0, 5.0) as usize;
        format!("{v:.d$} ± {se:.d$}")
    } else {
        format!("{v:.3} ± —")
    }
}

/// Pad `s` to `w` characters (by chars, not bytes).
fn pad(s: &str, w: usize) -> String {
    let n = s.chars().count();
    format!("{s}{}", " ".repeat(w.saturating_sub(n)))
}

/// Render a text table with a title.
pub fn text_table(title: &str, headers: &[&str], rows: &[Vec<String>]) -> String {
    let mut widths: Vec<usize> = headers.iter().map(|h| h.chars().count()).collect();
    for r in rows {
        for (i, c) in r.iter().enumerate() {
            if let Some(w) = widths.get_mut(i) {
                *w = (*w).max(c.chars().count());
            }
        }
    }
    let mut s = format!("{title}\n");
    let line = |cells: Vec<String>| -> String {
        cells
            .iter()
            .zip(&widths)
            .map(|(c, w)| pad(c, *w))
            .collect::<Vec<_>>()
            .join("  ")
            .trim_end()
            .to_string()
    };
    s.push_str(&line(headers.iter().map(|h| h.to_string()).collect()));
    s.push('\n');
    s.push_str(&"-".repeat(widths.iter().sum::<usize>() + 2 * (widths.len() - 1)));
    s.push('\n');
    for r in rows {
        s.push_str(&line(r.clone()));
        s.push('\n');
    }
    s
}

/// The name of a class's native layer.
fn layer_name(class: &str) -> &'static str {
    match class {
        "aluminum" => "Al₂O₃",
        "copper" => "Cu₂O",
        _ => "contamination",
    }
}

/// Tables 1 (training set) and 2 (test plate) as text, from the fits and the test
/// plate's classification rows.
pub fn paper_tables(
    all_fits: &[(u64, FitRow)],
    class_rows: &[ClassificationRow],
) -> (String, String) {
    let fit_of = |t: &str| all_fits.iter().map(|(_, f)| f).find(|f| f.target == t);
    let mut t1 = Vec::new();
    for p in PLATES.iter().filter(|p| p.training) {
        let Some(f) = fit_of(p.target) else { continue };
        let (pn, pk) = paper_estimate(p.target).unwrap_or((f64::NAN, f64::NAN));
        t1.push(vec![
            p.label.to_string(),
            format!("{:.0}-{:.0}", p.theta_i.0, p.theta_i.1),
            format!("{:.2}", p.n),
            format!("{:.2}", p.k),
            format!("{:.1} nm of {}", p.layer.1, layer_name(p.class)),
            pm(f.n, f.n_se),
            pm(f.k, f.k_se),
            f.status.to_string(),
            format!("{pn:.2}, {pk:.2}"),
        ]);
    }
    let table1 = text_table(
        "Table 1. Training set (simulated), view angle 60°. n, k: the plates' bulk index \
         (the paper's references), under their native layer; n̂, k̂: estimates ± 1 standard \
         error (total: noise and the bench's systematic errors).",
        &[
            "Material",
            "θi (°)",
            "n",
            "k",
            "layer",
            "n̂",
            "k̂",
            "fit",
            "paper n̂, k̂",
        ],
        &t1,
    );
    // The paper's rule (§ 6): the nearest training estimate, Euclidean in (n, k).
    let training: Vec<(&str, f64, f64)> = PLATES
        .iter()
        .filter(|p| p.training)
        .filter_map(|p| fit_of(p.target).map(|f| (p.class, f.n, f.k)))
        .collect();
    let nearest = |n: f64, k: f64| {
        training
            .iter()
            .map(|&(c, pn, pk)| (c, (n - pn).hypot(k - pk)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    };
    let mut t2 = Vec::new();
    for p in PLATES.iter().filter(|p| !p.training) {
        let Some(f) = fit_of(p.target) else { continue };
        let c = class_rows.iter().find(|c| c.target == p.target);
        let (pn, pk) = paper_estimate(p.target).unwrap_or((f64::NAN, f64::NAN));
        let set = c
            .map(|c| {
                let d: Vec<String> = c.candidates.iter().map(|x| x.to_string()).collect();
                if d.is_empty() {
                    "none".to_string()
                } else {
                    d.join(", ")
                }
            })
            .unwrap_or_default();
        t2.push(vec![
            format!("{:.0}", p.theta_r),
            pm(f.n, f.n_se),
            pm(f.k, f.k_se),
            c.map(|c| c.predicted.clone()).unwrap_or_default(),
            set,
            c.and_then(|c| c.distance)
                .map(|d| format!("{d:.3}"))
                .unwrap_or_default(),
            c.and_then(|c| {
                c.runner_up
                    .as_ref()
                    .map(|r| format!("{r} ({:.3})", c.runner_up_distance.unwrap_or(f64::NAN)))
            })
            .unwrap_or_default(),
            nearest(f.n, f.k)
                .map(|(c, d)| format!("{c} ({d:.3})"))
                .unwrap_or_default(),
            format!("{pn:.2}, {pk:.2}"),
        ]);
    }
    let table2 = text_table(
        "Table 2. Test aluminum plate (σ = 0.30, the training aluminum has 0.20; its own \
         oxide layer), θi = 35-80°; classified as `polarid classify --model` does: the \
         materials consistent at 95% (Mahalanobis distance, the estimate's noise and each \
         prototype's noise and layer variation: one bench); the paper's rule (nearest \
         training estimate, Euclidean in (n, k)) beside it.",
        &[
            "View angle (°)",
            "n̂",
            "k̂",
            "Classification",
            "consistent at 95%",
            "distance",
            "runner-up (distance)",
            "paper's rule: nearest (Euclidean)",
            "paper n̂, k̂",
        ],
        &t2,
    );

    (table1, table2)
}
