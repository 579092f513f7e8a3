//! The figures of `polarid map`: the material map (`class.png`, every map) and, for
//! colour captures (docs/BANDS.md "Per-band plots of your data"), per band the `n` and
//! `k` images (`n_450.png`, `k_450.png`, ... with `.svg`, one colour scale per quantity
//! over all bands) and, when the manifest labels regions, `nk_bands` (the `(n, k)` plane
//! per band) and `nk_spectra` (`n(λ)`, `k(λ)`) of each region's median against the
//! references (the model's prototypes or the library's materials).

use anyhow::Result;
use polarid_core::FitStatus;
use polarid_core::classify::MultiPrototype;
use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::FitRow;
use polarid_pipeline::map::MapResult;

use super::Rendered;
use super::plots::panels::band_label;
use super::plots::{ClassMap, MapRegion, PlotSize, answer_map, scalar_map};
use super::table_report::{References, Tables, figures};

/// `, 2x2 binning` in the titles of a binned map's figures (empty at full resolution).
fn binning(r: &MapResult) -> String {
    if r.bin > 1 {
        format!(", {0}x{0} binning", r.bin)
    } else {
        String::new()
    }
}

/// `class.png`: the material map with its legend, the `unknown` pixels by reason and
/// the manifest's regions outlined.
pub fn class_figure(r: &MapResult) -> Result<Rendered> {
    let (w, h) = (r.width, r.height);
    let title = format!("Material map ({w}x{h}{})", binning(r));
    answer_map(&title, &class_map(r), PlotSize::REPORT)
}

/// The material map of `r` with the manifest's regions in map pixels (their rectangles
/// divided by the binning), to outline.
pub fn class_map(r: &MapResult) -> ClassMap<'_> {
    let b = r.bin.max(1) as f64;
    let regions = r.regions.iter().map(|g| MapRegion {
        name: g.name.clone(),
        rect: g.rect.map(|v| v as f64 / b),
    });
    ClassMap {
        width: r.width,
        height: r.height,
        classes: &r.class,
        names: &r.class_names,
        reasons: Some(&r.reason),
        regions: regions.collect(),
    }
}

/// The references of a map: `profiles` (a model's or a library's), drawn with the
/// refractiveindex.info curves when `library` is a built-in one and no model was given.
pub fn references(
    label: &str,
    profiles: &[MultiPrototype],
    library: Option<&str>,
    model: bool,
) -> References {
    References {
        label: label.to_string(),
        profiles: profiles.to_vec(),
        builtin_curves: !model
            && polarid_io::library::Library::is_dispersive_builtin(
                library.unwrap_or("builtin-rgb"),
            ),
    }
}

/// The extra files of a colour map whose per-band images are `files` (the map's output
/// names, `n_450.tif`, ...): `n_450.png`, `n_450.svg`, `k_450.png`, `k_450.svg` per band,
/// and `nk_bands`, `nk_spectra` (`.png`, `.svg`). Empty for a single-band map.
pub fn band_files(files: &[String]) -> Vec<String> {
    let tags: Vec<&str> = files
        .iter()
        .filter_map(|f| f.strip_prefix("n_")?.strip_suffix(".tif"))
        .filter(|t| t.parse::<f64>().is_ok())
        .collect();
    if tags.is_empty() {
        return Vec::new();
    }
    let mut stems: Vec<String> = tags
        .iter()
        .flat_map(|t| [format!("n_{t}"), format!("k_{t}")])
        .collect();
    stems.extend(["nk_bands".to_string(), "nk_spectra".to_string()]);
    stems
        .iter()
        .flat_map(|s| [format!("{s}.png"), format!("{s}.svg")])
        .collect()
}

/// The `lo`..`hi` quantiles of the finite values (a colour scale that outliers do not
/// flatten), `None` without finite values or with a zero span.
fn quantile_range(values: impl Iterator<Item = f32>, lo: f64, hi: f64) -> Option<(f64, f64)> {
    let mut v: Vec<f64> = values.map(f64::from).filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    let (a, b) = (at(lo), at(hi));
    (b > a).then_some((a, b))
}

/// Median of `v` (sorted in place) and the standard error of the median from the median
/// absolute deviation: `1.2533 · 1.4826 · MAD / √N`.
fn median_se(v: &mut [f64]) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    let med = |v: &[f64]| {
        let m = v.len() / 2;
        if v.len() % 2 == 1 {
            v[m]
        } else {
            0.5 * (v[m - 1] + v[m])
        }
    };
    let m = med(v);
    let mut dev: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    dev.sort_by(f64::total_cmp);
    (m, 1.2533 * 1.4826 * med(&dev) / (v.len() as f64).sqrt())
}

/// Per labelled region and band, the median `(n, k)` of its fitted blocks as a fit row
/// (`measurements` = blocks), and per region its most frequent class as the answer.
fn region_rows(r: &MapResult) -> (Vec<FitRow>, Vec<ClassificationRow>) {
    let (mut fits, mut answers) = (Vec::new(), Vec::new());
    for reg in &r.regions {
        let [x, y, w, h] = reg.rect;
        let (x0, y0) = (x.div_ceil(r.bin), y.div_ceil(r.bin));
        let (x1, y1) = (
            ((x + w) / r.bin).min(r.width),
            ((y + h) / r.bin).min(r.height),
        );
        let idx: Vec<usize> = (y0..y1.max(y0))
            .flat_map(|yy| (x0..x1.max(x0)).map(move |xx| yy * r.width + xx))
            .collect();
        for b in &r.bands {
            let (mut ns, mut ks) = (Vec::new(), Vec::new());
            for &i in &idx {
                if let (Some(n), Some(k)) = (b.n.get(i), b.k.get(i))
                    && n.is_finite()
                    && k.is_finite()
                {
                    ns.push(f64::from(*n));
                    ks.push(f64::from(*k));
                }
            }
            if ns.is_empty() {
                continue;
            }
            let ((n, n_se), (k, k_se)) = (median_se(&mut ns), median_se(&mut ks));
            fits.push(FitRow {
                target: reg.name.clone(),
                class: reg.class.clone(),
                wavelength_nm: Some(b.wavelength_nm),
                n,
                k,
                n_se,
                k_se,
                nk_corr: 0.0,
                measurements: ns.len() as u64,
                status: FitStatus::Ok,
                ..Default::default()
            });
        }
        let top = reg
            .classes
            .iter()
            .filter(|(c, _)| c != "unknown")
            .max_by_key(|(_, count)| *count);
        answers.push(ClassificationRow {
            target: reg.name.clone(),
            class: reg.class.clone(),
            predicted: top.map_or("unknown".into(), |(c, _)| c.clone()),
            candidates: reg.class.iter().cloned().collect(),
            ..Default::default()
        });
    }
    (fits, answers)
}

/// The colour map's figures as `(file stem, drawing)` ([`band_files`]); empty for a
/// single-band map.
pub fn band_figures(r: &MapResult, refs: &References) -> Result<Vec<(String, Rendered)>> {
    let mut out = Vec::new();
    if !r.is_colour() {
        return Ok(out);
    }
    let bin = binning(r);
    for (q, get) in [
        (
            "n",
            (|b| &b.n) as fn(&polarid_pipeline::map::BandMap) -> &Vec<f32>,
        ),
        ("k", |b| &b.k),
    ] {
        let range = quantile_range(
            r.bands.iter().flat_map(|b| get(b).iter().copied()),
            0.01,
            0.99,
        );
        for b in &r.bands {
            let tag = band_label(b.wavelength_nm);
            let title = format!("{q} at {tag} nm ({}x{}{bin})", r.width, r.height);
            let plot = scalar_map(
                &title,
                r.width,
                r.height,
                get(b),
                range,
                &format!("{q} at {tag} nm"),
                PlotSize::REPORT,
            )?;
            out.push((format!("{q}_{tag}"), plot));
        }
    }
    let (fits, answers) = region_rows(r);
    let t = Tables {
        measurements: &[],
        fits: &fits,
        classification: &answers,
    };
    if super::table_report::bands_of(&fits).len() >= 2 {
        for f in figures(&t, Some(refs), "map regions, median of blocks")? {
            out.push((f.stem, f.plot));
        }
    }
    Ok(out)
}
