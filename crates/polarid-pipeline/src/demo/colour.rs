//! `polarid demo --color`: a colour polarization camera (Sony IMX250MYR-type, RGGB blocks
//! of 90/45/135/0° polarizers) tells aluminum, copper, gold, brass, a green paint and a
//! clear plastic (PET) apart with three bands, where the 650 nm band alone cannot tell
//! copper from gold (docs/BANDS.md, "Acceptance from images").
//!
//! **From images.** For every seed, each material has two training plates and one test
//! plate; each plate is its own far-field scene (`polarid simulate`'s colour scenes:
//! per-band `(n, k)` from the built-in three-band library `builtin-rgb`, paint given per
//! band) seen at the nominal θr = 60° with the source at θi = 30, 37, …, 79° (β = 45 to
//! 69.5°, eq. 5). The geometry is off as on a real bench: the true camera zenith by
//! N(0, 0.2°) per plate and the true source zenith by N(0, 0.2°) per capture — the same
//! in the three bands of a capture, which share one frame. Each capture is one raw 12-bit
//! colour mosaic (32 × 32 pixels, auto exposure, shot and read noise, the blue band's
//! response half the others'). Then every capture is measured as `polarid measure`
//! measures it (`polarid_io::measure`: the mosaic demosaiced per band, bilinear per
//! lattice; the DoLP of the plate's 24 × 24 region and its standard error from the
//! region's mean Stokes vector), one measurement row per band with the nominal angles;
//! `fit` fits each band (eq. 9), `train` makes three-band prototypes from the training
//! plates, and every test plate is classified on its three bands at once, and again on
//! its 650 nm rows alone, as `polarid classify` classifies by default: the set rule and
//! the Mahalanobis rule compare each test plate's noise covariance with the prototypes'
//! sample covariance (the same bench, docs/CLASSIFY.md).
//!
//! Seed 0's captures are written to files (scene, manifest with `bands` and
//! `dofp.color`, raw mosaics, truth per band), measured from those files, and its
//! measurements, fits, model and classification are written and returned for the
//! report's figures. The accuracy table runs the whole chain on `seeds` seeds, in
//! memory (the same frames: the same scene text and noise seeds), under the fit's
//! default error model (with its 3 nm surface-layer allowance) and without the
//! allowance (`--film-sd-nm 0`), for the nearest (Euclidean, Mahalanobis) and set rules.
//!
//! **Real plates are not their tabulated index.** Every metal plate (aluminum, copper,
//! gold, brass; training and test alike) carries its material's native surface layer as
//! found ([`native_surface`]: Al₂O₃ 2–5 nm on aluminum, Cu₂O 0.5–3 nm on copper,
//! contamination 0.5–1.5 nm on gold, ZnO 1–3 nm on brass), of a thickness uniform in
//! that range, the same layer in all three bands, each band at the layer's own index.
//! The colour scenes have no layers, so each such plate is given, per band, the index a
//! single-interface fit sees on the layered surface at the demo's β ([`apparent_index`]);
//! paint and plastic keep their index.

use std::path::Path;

use polarid_core::classify::{ClassifierConfig, Metric, MultiPrototype};
use polarid_io::atomic::StagedDir;
use polarid_io::image::{Frame, SampleKind};
use polarid_io::library::Library;
use polarid_io::manifest;
use polarid_io::model::Model;
use polarid_io::table::classification::ClassificationRow;
use polarid_io::table::fits::FitRow;
use polarid_io::table::measurements::Measurement;
use rayon::prelude::*;

use super::steps::{self, parse_scene};
use crate::classify::{
    Comparison, classification_row, group_fits, multi_classifier, multi_estimate_for, same_bench,
};
use crate::fit::{FitConfig, fit};
use crate::progress::{Progress, Warning};
use crate::{PipelineError, Result};

/// The bands of the demo's camera, nm (B, G, R).
pub const COLOUR_BANDS_NM: [f64; 3] = [450.0, 550.0, 650.0];
/// Nominal camera zenith, degrees.
pub const COLOUR_THETA_R: f64 = 60.0;
/// Nominal source zeniths, degrees.
pub const COLOUR_THETA_I: [f64; 8] = [30.0, 37.0, 44.0, 51.0, 58.0, 65.0, 72.0, 79.0];
/// Standard deviation of the true angles about the nominal ones, degrees.
pub const COLOUR_ANGLE_SD: f64 = 0.2;
/// Frame side, pixels (one plate fills the frame; its region is the default inset).
pub const COLOUR_SIDE: usize = 32;
/// The default number of seeds of the accuracy table.
pub const COLOUR_SEEDS: u64 = 100;
/// The native surface of a metal plate of class `class` (`polarid_io::surfaces`; brass
/// is the built-in `brass_Cu70Zn30`).
pub fn native_surface(class: &str) -> Option<&'static polarid_io::surfaces::BuiltinSurface> {
    let name = if class == "brass" {
        "brass_Cu70Zn30"
    } else {
        class
    };
    polarid_io::surfaces::builtin_surface(name)
}

/// One material of the colour demo.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourMaterial {
    /// Class (and target name stem).
    pub class: &'static str,
    /// How the scene gives its index: `material = "..."` or per-band `n`, `k`.
    pub scene_keys: String,
    /// Roughness σ.
    pub sigma: f64,
    /// `(n, k)` at 450, 550, 650 nm.
    pub nk: [(f64, f64); 3],
    /// Whether its plates carry a native surface layer (the metals).
    pub layered: bool,
}

/// The six materials: aluminum, copper, gold, brass (Cu70Zn30) and PET from
/// `builtin-rgb`, a green paint given per band (the paper's 1.39 + 0.34i at 650 nm).
pub fn colour_materials() -> Result<Vec<ColourMaterial>> {
    let lib = Library::builtin_rgb()?;
    let from_lib = |class: &'static str, name: &str, sigma: f64| -> Result<ColourMaterial> {
        let mut nk = [(0.0, 0.0); 3];
        for (i, wl) in COLOUR_BANDS_NM.iter().enumerate() {
            let m = lib
                .materials
                .iter()
                .find(|m| m.name == name && m.wavelength_nm == Some(*wl))
                .ok_or_else(|| PipelineError::Data {
                    path: "builtin-rgb".into(),
                    reason: format!("internal error: no {name} at {wl} nm"),
                })?;
            nk[i] = (m.n, m.k);
        }
        Ok(ColourMaterial {
            class,
            scene_keys: format!("material = \"{name}\"\nclass = \"{class}\""),
            sigma,
            nk,
            layered: matches!(class, "aluminum" | "copper" | "gold" | "brass"),
        })
    };
    let paint = [(1.45, 0.30), (1.42, 0.12), (1.39, 0.34)];
    Ok(vec![
        from_lib("aluminum", "aluminum", 0.2)?,
        from_lib("copper", "copper", 0.2)?,
        from_lib("gold", "gold", 0.2)?,
        from_lib("brass", "brass_Cu70Zn30", 0.2)?,
        ColourMaterial {
            class: "paint",
            scene_keys: format!(
                "class = \"paint\"\nn = {{ B = {}, G = {}, R = {} }}\nk = {{ B = {}, G = {}, R = {} }}",
                paint[0].0, paint[1].0, paint[2].0, paint[0].1, paint[1].1, paint[2].1
            ),
            sigma: 0.25,
            nk: paint,
            layered: false,
        },
        from_lib("plastic", "PET", 0.2)?,
    ])
}

/// splitmix64 with Box–Muller: the demo's deterministic normal numbers.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// One plate of one seed: its target name, class, and its scene's text (true angles).
#[derive(Debug, Clone)]
pub struct ColourPlate {
    /// Target name (`copper_train1`, `copper_test`).
    pub target: String,
    /// Class.
    pub class: String,
    /// Training plate (else test).
    pub training: bool,
    /// The scene file's text.
    pub scene: String,
}

/// The plates of seed `seed` (two training plates and one test plate per material, in
/// material order), each with its scene text: true angles drawn about the nominal ones.
pub fn colour_plates(materials: &[ColourMaterial], seed: u64) -> Vec<ColourPlate> {
    colour_plates_with(materials, seed, true)
}

/// The `(n, k)` a single-interface fit sees on a substrate `nk` under a layer of index
/// `film` and thickness `d_nm` at `wl` nm: the least-squares fit (Gauss–Newton from
/// `nk`) of eq. (9) to the layered surface's DoLP ([`polarid_core::film::thin_film`]) at
/// the demo's nominal β. `nk` itself when `d_nm` is 0 or the fit fails.
pub fn apparent_index(nk: (f64, f64), film: (f64, f64), d_nm: f64, wl: f64) -> (f64, f64) {
    let betas: Vec<f64> = COLOUR_THETA_I
        .iter()
        .map(|t| (0.5 * (t + COLOUR_THETA_R)).to_radians())
        .collect();
    apparent_index_at(nk, film, d_nm, wl, &betas)
}

/// [`apparent_index`] at the incidence angles `betas` (radians).
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN-safe on purpose
pub fn apparent_index_at(
    nk: (f64, f64),
    film: (f64, f64),
    d_nm: f64,
    wl: f64,
    betas: &[f64],
) -> (f64, f64) {
    use polarid_core::dop::dop_grad;
    if d_nm <= 0.0 {
        return nk;
    }
    let mut y = Vec::with_capacity(betas.len());
    for &b in betas {
        match polarid_core::film::thin_film(film, d_nm / wl, nk, b, 1.0) {
            Ok(r) => y.push(r.signed_dolp()),
            Err(_) => return nk,
        }
    }
    let (mut n, mut k) = nk;
    for _ in 0..40 {
        let (mut h, mut r0, mut r1) = ([0.0f64; 3], 0.0, 0.0);
        for (&b, &yt) in betas.iter().zip(&y) {
            let g = dop_grad(n, k, b);
            let r = yt - g.p;
            h[0] += g.dp_dn * g.dp_dn;
            h[1] += g.dp_dn * g.dp_dk;
            h[2] += g.dp_dk * g.dp_dk;
            r0 += g.dp_dn * r;
            r1 += g.dp_dk * r;
        }
        let det = h[0] * h[2] - h[1] * h[1];
        if !(det > 0.0) {
            return nk;
        }
        n += (h[2] * r0 - h[1] * r1) / det;
        k += (h[0] * r1 - h[1] * r0) / det;
    }
    if n.is_finite() && k.is_finite() && n > 0.0 && k >= 0.0 {
        (n, k)
    } else {
        nk
    }
}

/// [`colour_plates`] with the metal plates' native layers (`layers`) or without (every
/// plate exactly at its tabulated index).
pub fn colour_plates_with(
    materials: &[ColourMaterial],
    seed: u64,
    layers: bool,
) -> Vec<ColourPlate> {
    let mut rng = Rng(0xC010_0000 ^ seed.wrapping_mul(0x1000_0001));
    // The layers come from their own stream, so the angles and noise of a seed do not
    // depend on them.
    let mut layer_rng = Rng(0x1A7E_0000 ^ seed.wrapping_mul(0x1000_0001));
    let mut out = Vec::new();
    for (mi, m) in materials.iter().enumerate() {
        for p in 0..3 {
            let training = p < 2;
            let target = if training {
                format!("{}_train{}", m.class, p + 1)
            } else {
                format!("{}_test", m.class)
            };
            let tr = COLOUR_THETA_R + COLOUR_ANGLE_SD * rng.normal();
            let ti: Vec<String> = COLOUR_THETA_I
                .iter()
                .map(|t| format!("{:.4}", t + COLOUR_ANGLE_SD * rng.normal()))
                .collect();
            let noise_seed = seed * 1000 + mi as u64 * 10 + p as u64;
            let u = layer_rng.uniform();
            let surface = native_surface(m.class).filter(|_| m.layered && layers);
            let keys = if let Some(sf) = surface {
                let d_nm = sf.min_nm + (sf.max_nm - sf.min_nm) * u;
                let nk: Vec<(f64, f64)> =
                    m.nk.iter()
                        .zip(COLOUR_BANDS_NM)
                        .map(|(&nk, wl)| {
                            match polarid_io::surfaces::layer_index_builtin_band(sf.layer, wl) {
                                Ok(Some(film)) => apparent_index(nk, film, d_nm, wl),
                                _ => nk,
                            }
                        })
                        .collect();
                format!(
                    "class = \"{}\"\n# {} with a native layer of {d_nm:.2} nm of {}: \
                     the index a single-interface fit sees per band\n\
                     n = {{ B = {:.6}, G = {:.6}, R = {:.6} }}\nk = {{ B = {:.6}, G = {:.6}, R = {:.6} }}",
                    m.class,
                    m.class,
                    sf.layer,
                    nk[0].0,
                    nk[1].0,
                    nk[2].0,
                    nk[0].1,
                    nk[1].1,
                    nk[2].1
                )
            } else {
                m.scene_keys.clone()
            };
            let scene = format!(
                "# polarid demo --color: {target} (seed {seed}); true angles (the manifest \
                 the demo measures records the nominal ones)\n\
                 name = \"{target}\"\nwidth = {s}\nheight = {s}\ntheta_r_deg = {tr:.4}\n\
                 theta_i_deg = [{ti}]\nseed = {noise_seed}\nbands = {{ R = 650.0, G = 550.0, \
                 B = 450.0 }}\n\n[sensor]\nbit_depth = 12\nfull_well_e = 10000.0\n\
                 read_noise_e = 3.0\ndark_level_dn = 64.0\nband_response = {{ R = 1.0, G = 1.0, \
                 B = 0.5 }}\n\n[capture]\nkind = \"dofp\"\npattern = [90, 45, 135, 0]\n\
                 color = \"RGGB\"\n\n[[plate]]\nname = \"{target}\"\n{keys}\nsigma = {sigma}\n\
                 rect = [0, 0, {s}, {s}]\n",
                s = COLOUR_SIDE,
                ti = ti.join(", "),
                keys = keys,
                sigma = m.sigma,
            );
            out.push(ColourPlate {
                target,
                class: m.class.to_string(),
                training,
                scene,
            });
        }
    }
    out
}

/// Give the captures of a plate's manifest (as `polarid simulate` writes it, with the
/// scene's true angles) the nominal angles the demo measures with: θr =
/// [`COLOUR_THETA_R`], θi = [`COLOUR_THETA_I`].
fn nominal_manifest(m: &mut manifest::Manifest) {
    for (c, ti) in m.captures.iter_mut().zip(COLOUR_THETA_I) {
        c.theta_i_deg = ti;
        c.theta_r_deg = COLOUR_THETA_R;
    }
}

/// Every row of one plate's scene, rendered and measured in memory as `polarid measure`
/// measures the files (per capture, per band in increasing wavelength), with the
/// nominal angles.
fn plate_rows(plate: &ColourPlate) -> Result<Vec<Measurement>> {
    let path = Path::new("scene.toml");
    let scene = parse_scene(path, &plate.scene)?;
    let set = crate::simulate::render_colour_set(&scene)?;
    let text = crate::simulate::manifest_text(&scene, &set.exposures);
    let mut man = manifest::parse_in_memory(Path::new("manifest.toml"), &text)?;
    nominal_manifest(&mut man);
    let mut rows = Vec::new();
    for (c, raw) in man.captures.iter().zip(&set.frames) {
        let f = Frame {
            path: path.to_path_buf(),
            width: set.width,
            height: raw.len() / set.width.max(1),
            kind: SampleKind::U16,
            data: raw.iter().map(|&v| f32::from(v)).collect(),
            recorded_max: None,
        };
        rows.extend(polarid_io::measure::measure_colour_frame(&man, c, f)?);
    }
    Ok(rows)
}

/// One line of the accuracy table: a classifier (bands, fit error model, rule) over the
/// test plates of every seed.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AccuracyRow {
    /// `three bands (450, 550, 650 nm)` or `one band (650 nm)`.
    pub bands: String,
    /// The fit's error model: `default` or `--film-sd-nm 0`.
    pub fit: String,
    /// `nearest, Euclidean`, `nearest, Mahalanobis` or `set, 95%`.
    pub rule: String,
    /// Copper test plates classified copper / all copper test plates.
    pub copper: (u64, u64),
    /// Gold test plates classified gold / all.
    pub gold: (u64, u64),
    /// Copper and gold test plates answered `ambiguous`.
    pub ambiguous: u64,
    /// Copper and gold test plates answered `unknown`.
    pub unknown: u64,
    /// All six materials' test plates right / all.
    pub all: (u64, u64),
}

impl AccuracyRow {
    /// Copper and gold test plates right, as a fraction.
    pub fn copper_gold(&self) -> f64 {
        (self.copper.0 + self.gold.0) as f64 / (self.copper.1 + self.gold.1).max(1) as f64
    }
}

/// The classifiers of the table: `(label, config)`.
fn rules() -> [(&'static str, ClassifierConfig); 3] {
    [
        ("nearest, Euclidean", ClassifierConfig::default()),
        (
            "nearest, Mahalanobis",
            ClassifierConfig {
                metric: Metric::Mahalanobis,
                ..Default::default()
            },
        ),
        ("set, 95%", ClassifierConfig::set(0.95)),
    ]
}

/// The fits of `rows` (lines from 2) under `cfg`, keeping only the bands in `keep`.
fn fits_of(rows: &[Measurement], keep: &[f64], cfg: &FitConfig) -> Result<Vec<(u64, FitRow)>> {
    let kept = rows
        .iter()
        .filter(|m| m.wavelength_nm.is_some_and(|w| keep.contains(&w)));
    let rows = from_line_2(kept.cloned());
    let no_progress = &crate::progress::no_progress;
    let out = fit(Path::new("measurements.csv"), &rows, cfg, no_progress)?;
    Ok(from_line_2(out.rows()))
}

/// `items` numbered as the lines of a CSV file, from line 2.
fn from_line_2<T>(items: impl IntoIterator<Item = T>) -> Vec<(u64, T)> {
    (2..).zip(items).collect()
}

/// The multi-band prototypes trained on `train` (three-band or one-band fits).
fn prototypes(train: &[(u64, FitRow)]) -> Result<(Vec<MultiPrototype>, Comparison)> {
    let t = crate::train::train(train, Path::new("fits.csv"), "fits.csv")?;
    Ok(same_bench(&t.model))
}

/// Per (bands, fit, rule), per test plate: `(class, predicted)`.
type Outcomes = Vec<((usize, usize, usize), Vec<(String, String)>)>;

/// The fit error models of the table: `(label, config)`.
fn fit_configs() -> [(&'static str, FitConfig); 2] {
    [
        ("default (3 nm surface layer)", FitConfig::default()),
        (
            "--film-sd-nm 0",
            FitConfig {
                film_sd_nm: 0.0,
                ..FitConfig::default()
            },
        ),
    ]
}

/// The band sets of the table: `(label, bands kept)`.
const BAND_SETS: [(&str, &[f64]); 2] = [
    ("three bands (450, 550, 650 nm)", &COLOUR_BANDS_NM),
    ("one band (650 nm)", &[650.0]),
];

/// The fits of `fits` (lines from 2) in the bands `keep`, renumbered from line 2.
///
/// Every (target, band) is fitted on its own rows alone (`fit`), so these are the fits
/// [`fits_of`] makes of the same rows restricted to `keep`, without fitting again.
fn fits_in(fits: &[(u64, FitRow)], keep: &[f64]) -> Vec<(u64, FitRow)> {
    let kept = fits.iter().map(|(_, f)| f);
    from_line_2(
        kept.filter(|f| f.wavelength_nm.is_some_and(|w| keep.contains(&w)))
            .cloned(),
    )
}

/// Classify the test plates of one seed's rows under every (bands, fit, rule). Each
/// plate is fitted once per fit error model in all bands; the 650 nm classifiers use
/// those fits' 650 nm rows.
fn seed_outcomes(train: &[Measurement], test: &[Measurement]) -> Result<Outcomes> {
    let mut fitted = Vec::new();
    for (_, cfg) in fit_configs().iter() {
        fitted.push((
            fits_of(train, &COLOUR_BANDS_NM, cfg)?,
            fits_of(test, &COLOUR_BANDS_NM, cfg)?,
        ));
    }
    let mut out = Vec::new();
    for (bi, (_, keep)) in BAND_SETS.iter().enumerate() {
        for (fi, (tr, te)) in fitted.iter().enumerate() {
            let (tr, te) = (fits_in(tr, keep), fits_in(te, keep));
            let (protos, cmp) = prototypes(&tr)?;
            for (ri, (_, rcfg)) in rules().iter().enumerate() {
                let clf = multi_classifier(protos.clone(), "the trained prototypes", *rcfg)?;
                let mut v = Vec::new();
                for g in group_fits(&te) {
                    let f = &te[g[0]].1;
                    let d =
                        clf.classify_multi(&multi_estimate_for(g.iter().map(|&i| &te[i].1), cmp));
                    v.push((f.class.clone().unwrap_or_default(), d.predicted));
                }
                out.push(((bi, fi, ri), v));
            }
        }
    }
    Ok(out)
}

/// Split rows into training and test plates' rows.
fn split(plates: &[ColourPlate], rows: Vec<Measurement>) -> (Vec<Measurement>, Vec<Measurement>) {
    rows.into_iter()
        .partition(|m| plates.iter().any(|p| p.training && p.target == m.target))
}

/// The accuracy table over seeds `first..first + seeds` (in parallel over seeds),
/// everything in memory; progress stage `seeds`.
pub fn colour_accuracy(first: u64, seeds: u64, progress: Progress<'_>) -> Result<Vec<AccuracyRow>> {
    colour_accuracy_with(first, seeds, true, progress)
}

/// [`colour_accuracy`] with the metal plates' native layers (`layers`) or without (every
/// plate exactly at its tabulated index).
pub fn colour_accuracy_with(
    first: u64,
    seeds: u64,
    layers: bool,
    progress: Progress<'_>,
) -> Result<Vec<AccuracyRow>> {
    let materials = colour_materials()?;
    let done = std::sync::atomic::AtomicU64::new(0);
    let per_seed: Vec<Outcomes> = (first..first + seeds)
        .into_par_iter()
        .map(|seed| -> Result<Outcomes> {
            let plates = colour_plates_with(&materials, seed, layers);
            let mut rows = Vec::new();
            for p in &plates {
                rows.extend(plate_rows(p)?);
            }
            let (train, test) = split(&plates, rows);
            let o = seed_outcomes(&train, &test)?;
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress("seeds", d, seeds);
            Ok(o)
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(tally(&per_seed))
}

/// Count the outcomes of every seed into the table's rows.
fn tally(per_seed: &[Outcomes]) -> Vec<AccuracyRow> {
    let mut rows = Vec::new();
    for (bi, (bl, _)) in BAND_SETS.iter().enumerate() {
        for (fi, (fl, _)) in fit_configs().iter().enumerate() {
            for (ri, (rl, _)) in rules().iter().enumerate() {
                let mut r = AccuracyRow {
                    bands: bl.to_string(),
                    fit: fl.to_string(),
                    rule: rl.to_string(),
                    ..AccuracyRow::default()
                };
                for o in per_seed {
                    let Some((_, v)) = o.iter().find(|(k, _)| *k == (bi, fi, ri)) else {
                        continue;
                    };
                    for (class, pred) in v {
                        let right = u64::from(class == pred);
                        r.all.0 += right;
                        r.all.1 += 1;
                        let slot = match class.as_str() {
                            "copper" => &mut r.copper,
                            "gold" => &mut r.gold,
                            _ => continue,
                        };
                        slot.0 += right;
                        slot.1 += 1;
                        r.ambiguous += u64::from(pred == "ambiguous");
                        r.unknown += u64::from(pred == "unknown");
                    }
                }
                rows.push(r);
            }
        }
    }
    rows
}

/// The accuracy table as Markdown (docs/BANDS.md's format), `seeds` seeds.
pub fn accuracy_table(rows: &[AccuracyRow], seeds: u64) -> String {
    let pct = |a: u64, n: u64| format!("{:.1}%", 100.0 * a as f64 / n.max(1) as f64);
    let mut t = format!(
        "Copper against gold from simulated colour images, {seeds} seeds (one copper and one \
         gold test plate per seed; two training plates per material; every metal plate under \
         its native layer as found).\n\n\
         | classifier | fit error model | rule | copper right | gold right | copper+gold right \
         | ambiguous | unknown | all six right |\n|---|---|---|---|---|---|---|---|---|\n"
    );
    for r in rows {
        let cg = r.copper.1 + r.gold.1;
        t.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            r.bands,
            r.fit,
            r.rule,
            pct(r.copper.0, r.copper.1),
            pct(r.gold.0, r.gold.1),
            pct(r.copper.0 + r.gold.0, cg),
            pct(r.ambiguous, cg),
            pct(r.unknown, cg),
            pct(r.all.0, r.all.1)
        ));
    }
    t
}

/// Everything the colour demo produced besides its files.
#[derive(Debug, Clone)]
pub struct ColourDemoOutput {
    /// The materials (true `(n, k)` per band).
    pub materials: Vec<ColourMaterial>,
    /// Staged names of seed 0's scene files, one per plate.
    pub scenes: Vec<String>,
    /// Staged names of seed 0's manifests, one per plate.
    pub manifests: Vec<String>,
    /// Seed 0's plates.
    pub plates: Vec<ColourPlate>,
    /// Seed 0's measurements (per capture, band, plate), as re-read from
    /// `measurements.csv`.
    pub measurements: Vec<(u64, Measurement)>,
    /// Seed 0's three-band fits (default error model), as re-read from `fits.csv`.
    pub fits: Vec<(u64, FitRow)>,
    /// The three-band model trained on seed 0's training plates.
    pub model: Model,
    /// Seed 0's test plates classified on three bands (set rule, 95%).
    pub classification: Vec<ClassificationRow>,
    /// Seed 0's test plates classified on the 650 nm rows alone (set rule, 95%).
    pub classification_650: Vec<ClassificationRow>,
    /// The accuracy table's rows.
    pub accuracy: Vec<AccuracyRow>,
    /// Seeds of the table.
    pub seeds: u64,
    /// The table as Markdown.
    pub table: String,
    /// Simulation and training warnings.
    pub warnings: Vec<Warning>,
}

/// Run the colour demo into `staged` with `seeds` seeds for the accuracy table (module
/// documentation). Progress stages: `simulating` (seed 0's plates), `seeds`.
pub fn run_colour(staged: &StagedDir, seeds: u64, progress: Progress) -> Result<ColourDemoOutput> {
    crate::error::ensure(seeds > 0, "--seeds", seeds, "must be at least 1")?;
    let materials = colour_materials()?;
    let plates = colour_plates(&materials, 0);
    let mut warnings = Vec::new();
    let (mut scenes, mut manifests) = (Vec::new(), Vec::new());
    let mut rows: Vec<Measurement> = Vec::new();
    for (i, p) in plates.iter().enumerate() {
        progress("simulating", i as u64, plates.len() as u64);
        let dir = format!("captures/{}/", p.target);
        let scene_path = staged.final_path(&format!("{dir}scene.toml"));
        let scene = parse_scene(&scene_path, &p.scene)?;
        let sim = crate::simulate::simulate_into(&scene, staged, &dir, progress)?;
        warnings.extend(sim.warnings);
        // Measure from the files as `polarid measure` does: the manifest the simulator
        // wrote, with the nominal angles.
        let mut man = manifest::load(&staged.path(&sim.manifest)?)?;
        nominal_manifest(&mut man);
        let measured = crate::measure::measure(&man, &crate::progress::no_progress)?;
        warnings.extend(measured.warnings);
        rows.extend(measured.rows);
        scenes.push(format!("{dir}scene.toml"));
        manifests.push(sim.manifest);
    }
    progress("simulating", plates.len() as u64, plates.len() as u64);
    // Rows in measurement order: by capture set, band, capture.
    let (meas, all_fits) = steps::fit_staged(staged, &rows, progress)?;
    let is_training = |t: &str| plates.iter().any(|p| p.training && p.target == t);
    type Fits = Vec<(u64, FitRow)>;
    let (train, test): (Fits, Fits) = all_fits
        .iter()
        .cloned()
        .partition(|(_, f)| is_training(&f.target));
    let model = steps::train_staged(staged, &train, &mut warnings)?;
    let classify_rows = |fits: &[(u64, FitRow)],
                         (protos, cmp): (Vec<MultiPrototype>, Comparison)|
     -> Result<Vec<ClassificationRow>> {
        let clf = multi_classifier(protos, "model.json", ClassifierConfig::set(0.95))?;
        Ok(group_fits(fits)
            .iter()
            .map(|g| {
                let d = clf.classify_multi(&multi_estimate_for(g.iter().map(|&i| &fits[i].1), cmp));
                classification_row(&fits[g[0]].1, &d, &clf)
            })
            .collect())
    };
    let classification = classify_rows(&test, same_bench(&model))?;
    steps::stage_classification(staged, "classification.csv", &classification)?;
    let only = |f: &[(u64, FitRow)]| -> Vec<(u64, FitRow)> {
        f.iter()
            .filter(|(_, r)| r.wavelength_nm == Some(650.0))
            .cloned()
            .collect()
    };
    let classification_650 = classify_rows(&only(&test), prototypes(&only(&train))?)?;
    steps::stage_classification(staged, "classification_650nm.csv", &classification_650)?;

    let accuracy = colour_accuracy(0, seeds, progress)?;
    let table = accuracy_table(&accuracy, seeds);
    let tpath = staged.path("accuracy.md")?;
    polarid_io::atomic::write_atomic(&tpath, false, |w| {
        w.write_all(table.as_bytes())
            .map_err(|e| polarid_io::IoError::io(&tpath, e))
    })?;
    Ok(ColourDemoOutput {
        materials,
        scenes,
        manifests,
        plates,
        measurements: meas,
        fits: all_fits,
        model,
        classification,
        classification_650,
        accuracy,
        seeds,
        table,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The acceptance from images: over many seeds, the three-band classifier
    /// (Mahalanobis nearest neighbour ≥ 99%, the set rule with the fit's default error
    /// model ≥ 98% and never another material) gets the copper and gold test plates
    /// right; on the 650 nm rows alone of plates under native layers no rule reaches 99%.
    ///
    /// Size: 25 seeds (50 copper and gold test plates, about 11 CPU-s), 100 with
    /// `POLARID_FULL=1` (`COLOUR_SEEDS` overrides both). At the quick size the rates
    /// claimed as "at least" allow the misses that a rule at exactly that rate makes
    /// with probability 10⁻³ ([`polarid_testkit::max_misses`]: 5 of 50 for 98%), and
    /// the 650 nm Mahalanobis nearest neighbour under the default error model (97%
    /// right over 200 seeds: 50 plates cannot tell that from 99%) is held only to the
    /// three bands' rate; the Euclidean rule (55%), the set rules (64-67%, the rest
    /// `ambiguous` or `unknown`) and the Mahalanobis rule without the allowance (86%)
    /// still show at 650 nm that one band cannot. The full size asserts every rate as
    /// a plain fraction. `COLOUR_LAYERS=0` runs plates without native layers.
    /// `COLOUR_TABLE=1 cargo test --release -p polarid-pipeline --lib demo::colour --
    /// --nocapture` prints docs/BANDS.md's table (`COLOUR_SEEDS=100` for its size).
    #[test]
    fn three_bands_from_images_tell_copper_from_gold_where_650nm_cannot() {
        let full = polarid_testkit::full();
        let seeds = std::env::var("COLOUR_SEEDS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| polarid_testkit::seeds(25, COLOUR_SEEDS));
        let layers = std::env::var("COLOUR_LAYERS").map_or(true, |s| s != "0");
        let rows = colour_accuracy_with(0, seeds, layers, &crate::progress::no_progress).unwrap();
        if std::env::var_os("COLOUR_TABLE").is_some() {
            println!("{}", accuracy_table(&rows, seeds));
        }
        let get = |bands: &str, fit: &str, rule: &str| {
            rows.iter()
                .find(|r| r.bands.starts_with(bands) && r.fit.starts_with(fit) && r.rule == rule)
                .unwrap()
                .clone()
        };
        // No copper or gold plate given the other material (or another): each is right,
        // `ambiguous` or `unknown`.
        let never_wrong = |r: &AccuracyRow| {
            r.copper.0 + r.gold.0 + r.ambiguous + r.unknown == r.copper.1 + r.gold.1
        };
        // Three bands, the fit's default error model (its surface-layer allowance is ONE
        // layer over a plate's bands): the Mahalanobis nearest neighbour gets ≥ 99% of
        // copper and gold right, the set rule (the default, on the same bench as
        // `classify`) ≥ 98%, never another material (docs/BANDS.md: 99.7% over 300
        // seeds, two gold plates `unknown`).
        // At least `rate` right: the fraction at full size, else no more misses than a
        // rule right exactly at `rate` makes with probability 10⁻³.
        let at_least = |r: &AccuracyRow, rate: f64| {
            let n = r.copper.1 + r.gold.1;
            let misses = n - (r.copper.0 + r.gold.0);
            if full {
                r.copper_gold() >= rate
            } else {
                misses <= polarid_testkit::max_misses(n, 1.0 - rate, 1e-3)
            }
        };
        let r = get("three", "default", "nearest, Mahalanobis");
        assert!(at_least(&r, 0.99), "{r:?}");
        let r = get("three", "default", "set, 95%");
        let cg = (r.copper.1 + r.gold.1) as f64;
        assert!(at_least(&r, 0.98), "three bands, default, set: {r:?}");
        assert!(never_wrong(&r), "three bands, default, set: {r:?}");
        let r = get("three", "--film", "set, 95%");
        if layers {
            // The metal plates carry native layers: without the allowance
            // (`--film-sd-nm 0`) the set rule rejects many of them, the reason for it.
            assert!(
                r.unknown as f64 >= 0.2 * cg,
                "three bands, --film 0, set: {r:?}"
            );
        } else {
            // Clean plates: the 95% set on the same bench holds the plate's material
            // about 95% of the time, else it is `unknown` (docs/BANDS.md: 94.5%).
            assert!(
                at_least(&r, 0.9) && never_wrong(&r),
                "clean plates, --film 0, set: {r:?}"
            );
        }
        // 650 nm alone: the set rule (the default) is never wrong, and the paper's
        // Euclidean rule is near chance (copper and gold are 0.09 apart in n there). On
        // plates under their native layers as found, the Mahalanobis nearest neighbour
        // and the set rule tell them apart at 650 nm too (docs/BANDS.md).
        let r = get("one", "default", "set, 95%");
        assert!(never_wrong(&r), "650 nm, default, set: {r:?}");
        for fit in ["default", "--film"] {
            let r = get("one", fit, "nearest, Euclidean");
            assert!(r.copper_gold() < 0.99, "650 nm, {fit}, Euclidean: {r:?}");
            for rule in ["nearest, Euclidean", "nearest, Mahalanobis"] {
                let (r3, r1) = (get("three", fit, rule), get("one", fit, rule));
                assert!(
                    r3.copper_gold() >= r1.copper_gold(),
                    "{fit}, {rule}: three bands {r3:?}, one band {r1:?}"
                );
            }
        }
        assert_eq!(get("three", "--film", "set, 95%").copper.1, seeds);
    }

    /// Seed 0 measured from the written files equals the in-memory chain, and the files
    /// are a colour capture set `measure` can read (manifest with `bands`, `dofp.color`).
    #[test]
    fn files_and_memory_give_the_same_rows() {
        let dir = tempfile::tempdir().unwrap();
        let staged = StagedDir::new(&dir.path().join("out"), false).unwrap();
        let out = run_colour(&staged, 1, &crate::progress::no_progress).unwrap();
        staged.commit().unwrap();
        let mut mem = Vec::new();
        for p in &out.plates {
            mem.extend(plate_rows(p).unwrap());
        }
        let files: Vec<Measurement> = out.measurements.iter().map(|(_, m)| m.clone()).collect();
        assert_eq!(files.len(), 18 * 8 * 3);
        assert_eq!(files.len(), mem.len());
        for (a, b) in files.iter().zip(&mem) {
            assert_eq!((&a.target, a.wavelength_nm), (&b.target, b.wavelength_nm));
            assert!((a.dolp - b.dolp).abs() < 1e-9, "{a:?} {b:?}");
        }
        let m = manifest::load(&dir.path().join("out").join(&out.manifests[0])).unwrap();
        let bands = polarid_io::bands::capture_band_images(&m, &m.captures[0]).unwrap();
        let wl: Vec<Option<f64>> = bands.iter().map(|b| b.wavelength_nm).collect();
        assert_eq!(wl, vec![Some(450.0), Some(550.0), Some(650.0)]);
        // Three fits per target, the test plates classified on three bands.
        assert_eq!(out.fits.len(), 18 * 3);
        assert_eq!(out.classification.len(), 6);
        assert!(
            out.classification
                .iter()
                .all(|c| c.bands_used == "450;550;650")
        );
        assert!(out.classification_650.iter().all(|c| c.bands_used == "650"));
    }
}
