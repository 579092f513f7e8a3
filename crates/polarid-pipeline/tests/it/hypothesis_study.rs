//! Simulated study of the hypothesis tests against the measured rows
//! (`polarid_core::classify::hypothesis`; docs/CLASSIFY.md "Testing each material against
//! the rows"): library materials as they are found (bulk under their native layer, a
//! polarization camera of extinction 100–500:1, a common angle offset, per-row source angle
//! errors and DoLP noise) at the paper's geometry (β 47.5–70°, 6–10 positions, 650 nm),
//! classified against the built-in library.
//!
//! Cheap by default (20 targets per material); `POLARID_FULL=1` runs 300 per material and
//! prints the tables of docs/CLASSIFY.md.
//!
//! The library is `builtin` exactly as `classify --library builtin` loads it, every
//! material with its built-in native surface (`polarid_io::surfaces`, docs/MATERIALS.md);
//! each target is simulated under that same layer, its thickness uniform in the declared
//! range (the prior the probabilities assume).

#![allow(clippy::type_complexity)] // the study's case tables read as tuples

use polarid_core::classify::hypothesis::{angle_slope, chi2_quantile_any};
use polarid_core::classify::{
    CandidateModel, HypRow, HypothesisConfig, MultiPrototype, Nuisances, Status, classify_rows,
    layered_dolp,
};
use polarid_io::library::Library;

/// A small deterministic generator (SplitMix64; Box–Muller normals), so the study needs
/// no extra dependency.
struct StdRng(u64);

impl StdRng {
    fn seed_from_u64(s: u64) -> Self {
        Self(s)
    }
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in `[0, 1)`.
    fn uniform(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
    fn normal(&mut self, sd: f64) -> f64 {
        let u = 1.0 - self.uniform();
        let v = self.uniform();
        sd * (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// The study's materials: metals, semiconductors, a glass and a plastic of `builtin`.
const MATERIALS: [&str; 12] = [
    "aluminum",
    "copper",
    "silver",
    "gold",
    "nickel",
    "chromium",
    "stainless_steel_austenitic",
    "iron",
    "titanium",
    "silicon",
    "N-BK7",
    "PMMA",
];

const WL: f64 = 650.0;
const ANGLE_SD_DEG: f64 = 0.2;
const FLOOR: f64 = 0.002;

/// The built-in library as `classify --library builtin` loads it: every material with
/// its built-in native surface (polarid_io::surfaces).
fn library() -> Vec<MultiPrototype> {
    Library::builtin().unwrap().multi_prototypes()
}

/// A material's bulk, native layer index and thickness range in `protos` (650 nm).
fn as_found(protos: &[MultiPrototype], name: &str) -> ((f64, f64), (f64, f64), f64, f64) {
    let p = protos.iter().find(|p| p.class == name).unwrap();
    let b = p
        .bands
        .iter()
        .find(|b| b.wavelength_nm.is_none_or(|w| (w - WL).abs() < 1.0))
        .unwrap();
    let s = p.surface.as_ref().expect("builtin surface");
    (
        (b.n, b.k),
        b.layer.expect("layer index"),
        s.min_nm,
        s.max_nm,
    )
}

fn config(p: f64) -> HypothesisConfig {
    HypothesisConfig {
        confidence: p,
        // FitConfig's defaults: extinction ratio 100, no retardance, 0.2°.
        nuisances: Nuisances::from_error_model(100.0, 0.0, ANGLE_SD_DEG.to_radians()),
        open_world: true,
    }
}

/// One simulated target of `bulk` under `layer` (index, thickness nm).
fn target(rng: &mut StdRng, bulk: (f64, f64), layer: (f64, f64), d: f64) -> Vec<HypRow> {
    target_truth(rng, bulk, layer, d).0
}

/// [`target`] and its true scale and offset.
fn target_truth(
    rng: &mut StdRng,
    bulk: (f64, f64),
    layer: (f64, f64),
    d: f64,
) -> (Vec<HypRow>, f64, f64) {
    let t = 6 + (rng.next() % 5) as usize;
    let se = rng.range(0.002, 0.005);
    let er = rng.range(100.0, 500.0);
    let s = (er - 1.0) / (er + 1.0);
    let off = rng.range(-0.3, 0.3).to_radians();
    let angle_sd = ANGLE_SD_DEG.to_radians();
    let sd = (se * se + FLOOR * FLOOR).sqrt();
    let rows = (0..t)
        .map(|i| {
            let beta = (47.5 + 22.5 * i as f64 / (t - 1) as f64).to_radians();
            let b = beta + off + rng.normal(angle_sd / 2.0);
            HypRow {
                beta,
                dolp: s * layered_dolp(bulk, layer, d / WL, b) + rng.normal(sd),
                dolp_sd: sd,
                angle_sd,
                band: 0,
            }
        })
        .collect();
    (rows, s, off)
}

/// The hypothesis `name` of `protos` as the tests model it at the study's band.
fn hypothesis(protos: &[MultiPrototype], name: &str) -> CandidateModel {
    let p = protos.iter().find(|p| p.class == name).unwrap();
    CandidateModel::from_prototype(p, &[WL]).unwrap()
}

/// `χ²` of `rows` at the true nuisances (thickness `d`, scale `s`, offset `off`) of the
/// truth `bulk` under `layer`, with the row variance of the module's model of hypothesis
/// `cand` (its angle term from [`angle_slope`]; `bulk_slope`: from eq. 9's slope at the
/// bulk index instead, the model before the angle term took the layer).
#[allow(clippy::too_many_arguments)]
fn chi2_true(
    rows: &[HypRow],
    cand: &CandidateModel,
    bulk: (f64, f64),
    layer: (f64, f64),
    d: f64,
    s: f64,
    off: f64,
    bulk_slope: bool,
) -> f64 {
    rows.iter()
        .map(|r| {
            let m = s * layered_dolp(bulk, layer, d / WL, r.beta + off);
            let slope = if bulk_slope {
                polarid_core::dop::dop_beta_derivs(bulk.0, bulk.1, r.beta).dp_dbeta
            } else {
                angle_slope(cand, &[WL], r.band, r.beta)
            };
            let a = 0.5 * slope * r.angle_sd;
            (r.dolp - m).powi(2) / (r.dolp_sd.powi(2) + a * a)
        })
        .sum()
}

/// The study's seed: `default`, or `POLARID_STUDY_SEED` added to it (to see how much of
/// a figure is the luck of one sample).
fn study_seed(default: u64) -> u64 {
    default
        + std::env::var("POLARID_STUDY_SEED")
            .ok()
            .and_then(|v| v.parse::<u64>().ok())
            .unwrap_or(0)
}

/// Draw the reliability diagram of `rel` ((stated probability, truth?) pairs) binned at
/// `edges` into the PNG `path`: observed frequency against mean stated probability, with
/// 95% Wilson intervals, and the number of materials per bin.
fn reliability_png(path: &std::path::Path, rel: &[(f64, bool)], edges: &[f64], caption: &str) {
    use plotters::prelude::*;
    static FONT: &[u8] = include_bytes!("../../../polarid-cli/assets/fonts/DejaVuSans.ttf");
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| "font")
        .unwrap();
    let (w, h) = (900usize, 820usize);
    let mut buf = vec![0u8; w * h * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w as u32, h as u32)).into_drawing_area();
        root.fill(&WHITE).unwrap();
        let mut chart = ChartBuilder::on(&root)
            .caption(caption, ("sans-serif", 24))
            .margin(20)
            .x_label_area_size(60)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0f64..1.0, 0.0f64..1.0)
            .unwrap();
        chart
            .configure_mesh()
            .x_desc("stated probability (bin mean)")
            .y_desc("observed frequency of the truth")
            .label_style(("sans-serif", 18))
            .axis_desc_style(("sans-serif", 20))
            .draw()
            .unwrap();
        chart
            .draw_series(LineSeries::new(
                [(0.0, 0.0), (1.0, 1.0)],
                BLACK.mix(0.4).stroke_width(2),
            ))
            .unwrap()
            .label("perfectly reliable")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK.mix(0.4)));
        let blue = RGBColor(31, 119, 180);
        let mut pts = Vec::new();
        for w in edges.windows(2) {
            let sel: Vec<&(f64, bool)> = rel.iter().filter(|r| r.0 >= w[0] && r.0 < w[1]).collect();
            if sel.is_empty() {
                continue;
            }
            let n = sel.len() as f64;
            let mean = sel.iter().map(|r| r.0).sum::<f64>() / n;
            let obs = sel.iter().filter(|r| r.1).count() as f64 / n;
            // Wilson score interval, z = 1.96.
            let z = 1.96f64;
            let c = (obs + z * z / (2.0 * n)) / (1.0 + z * z / n);
            let h = z * (obs * (1.0 - obs) / n + z * z / (4.0 * n * n)).sqrt() / (1.0 + z * z / n);
            pts.push((mean, obs, c - h, c + h, sel.len()));
        }
        chart
            .draw_series(pts.iter().map(|&(x, _, lo, hi, _)| {
                PathElement::new([(x, lo), (x, hi)], blue.stroke_width(2))
            }))
            .unwrap();
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|p| (p.0, p.1)),
                blue.stroke_width(2),
            ))
            .unwrap()
            .label("observed (95% interval), materials per bin")
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], blue.stroke_width(2)));
        chart
            .draw_series(
                pts.iter()
                    .map(|&(x, y, _, _, _)| Circle::new((x, y), 6, blue.filled())),
            )
            .unwrap();
        chart
            .draw_series(pts.iter().map(|&(x, y, _, _, n)| {
                let (dx, dy) = if y > 0.9 { (-80, 12) } else { (10, -22) };
                EmptyElement::at((x, y))
                    + Text::new(
                        format!("{n}"),
                        (dx, dy),
                        ("sans-serif", 17).into_font().color(&BLACK),
                    )
            }))
            .ok();
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(("sans-serif", 18))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK.mix(0.3))
            .draw()
            .unwrap();
        root.present().unwrap();
    }
    polarid_io::image::write_rgb8_png(path, true, w, h, &buf).unwrap();
}

#[derive(Default, Debug)]
struct Tally {
    n: usize,
    covered: usize,
    alone: usize,
    wrong_alone: usize,
    unknown: usize,
    size: usize,
}

impl Tally {
    fn add(&mut self, truth: Option<&str>, d: &polarid_core::classify::Decision) {
        self.n += 1;
        let has = truth.is_some_and(|t| d.candidates.iter().any(|c| c.class == t));
        self.covered += usize::from(has);
        self.size += d.candidates.len();
        match d.status {
            Status::Ok if has => self.alone += 1,
            Status::Ok => self.wrong_alone += 1,
            Status::Rejected => self.unknown += 1,
            _ => {}
        }
    }
    fn frac(&self, x: usize) -> f64 {
        x as f64 / self.n.max(1) as f64
    }
}

/// The row variance of the hypothesis tests (module `polarid_core::classify::hypothesis`:
/// noise, floor and the angle term with the slope of the hypothesis' own layered model,
/// `angle_slope`) is calibrated: over many simulated targets of the study's materials
/// under their native layers, the `χ²` of the true material at the true nuisances exceeds
/// its `χ²_T` quantile as often as stated, at 90, 95 and 99%, in BOTH directions (pooled,
/// and per material), within 4 binomial standard errors. Measured (full, 12,000 targets
/// per material): 0.9010 / 0.9510 / 0.9902 pooled; with eq. 9's slope at the bulk index
/// (the model before) 0.9027 / 0.9521 / 0.9905, iron 0.9059 / 0.9551 / 0.9924 (the bare
/// metal's curve is steeper than under its oxide: the variance was too large).
#[test]
fn row_variance_model_is_calibrated() {
    let per = polarid_testkit::seeds(4000, 12000) as usize;
    let protos = library();
    let levels = [0.9, 0.95, 0.99];
    let mut rng = StdRng::seed_from_u64(study_seed(31));
    // Per material and pooled: targets whose χ² is within the quantile, with the module's
    // slope and with the bulk's slope.
    let mut pooled = [[0usize; 3]; 2];
    let mut n_all = 0usize;
    let mut failures = Vec::new();
    let se = |p: f64, n: usize| (p * (1.0 - p) / n as f64).sqrt();
    eprintln!(
        "| material | targets | within chi2_T(0.90) | (0.95) | (0.99) | bulk slope: (0.90) | (0.95) | (0.99) |"
    );
    for &name in MATERIALS.iter() {
        let (bulk, layer, lo, hi) = as_found(&protos, name);
        let cand = hypothesis(&protos, name);
        let mut within = [[0usize; 3]; 2];
        for _ in 0..per {
            let d = rng.range(lo, hi);
            let (rows, s, off) = target_truth(&mut rng, bulk, layer, d);
            let q: Vec<f64> = levels
                .iter()
                .map(|&p| chi2_quantile_any(p, rows.len() as f64))
                .collect();
            for (m, bulk_slope) in [false, true].into_iter().enumerate() {
                let c2 = chi2_true(&rows, &cand, bulk, layer, d, s, off, bulk_slope);
                for (j, q) in q.iter().enumerate() {
                    within[m][j] += usize::from(c2 <= *q);
                }
            }
        }
        let frac = |m: usize, j: usize| within[m][j] as f64 / per as f64;
        eprintln!(
            "| {name} | {per} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} |",
            frac(0, 0),
            frac(0, 1),
            frac(0, 2),
            frac(1, 0),
            frac(1, 1),
            frac(1, 2)
        );
        for (j, &p) in levels.iter().enumerate() {
            if (frac(0, j) - p).abs() > 4.0 * se(p, per) {
                failures.push(format!("{name} at {p}: {:.4}", frac(0, j)));
            }
            for m in 0..2 {
                pooled[m][j] += within[m][j];
            }
        }
        n_all += per;
    }
    let frac = |m: usize, j: usize| pooled[m][j] as f64 / n_all as f64;
    eprintln!(
        "| all | {n_all} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} |",
        frac(0, 0),
        frac(0, 1),
        frac(0, 2),
        frac(1, 0),
        frac(1, 1),
        frac(1, 2)
    );
    for (j, &p) in levels.iter().enumerate() {
        if (frac(0, j) - p).abs() > 4.0 * se(p, n_all) {
            failures.push(format!("all at {p}: {:.4}", frac(0, j)));
        }
    }
    assert!(failures.is_empty(), "not calibrated: {failures:?}");
}

/// The true material's own test (`test_hypothesis`: `χ²_min` over the nuisance box
/// against its null) over many targets of the study's materials, at 90, 95 and 99%: it
/// passes as often as stated in BOTH directions, within 4 binomial standard errors of
/// the pooled targets. The targets' oracle (their `χ²` at the true nuisances against
/// `χ²_T`) is printed beside it. Measured (full, 2,000 per material, 24,000 targets):
/// 0.9016 / 0.9503 / 0.9902 (oracle 0.9009 / 0.9500 / 0.9902); with the null's normal
/// draws taken coordinate by coordinate from Halton points (a light tail of `zᵀz`)
/// 0.8967 / 0.9474 / 0.9893; before the null's ridge was made consistent
/// 0.8915 / 0.9446 / 0.9885 (N-BK7 0.927 at 95%).
#[test]
fn truths_own_test_passes_at_the_confidence() {
    use polarid_core::classify::test_hypothesis;
    let per = polarid_testkit::seeds(300, 2000) as usize;
    let protos = library();
    let levels = [0.9, 0.95, 0.99];
    let mut rng = StdRng::seed_from_u64(study_seed(77));
    let (mut pass, mut oracle) = ([0usize; 3], [0usize; 3]);
    let mut n_all = 0usize;
    eprintln!("| material | passes at 0.90 | 0.95 | 0.99 |");
    for &name in MATERIALS.iter() {
        let (bulk, layer, lo, hi) = as_found(&protos, name);
        let cand = hypothesis(&protos, name);
        let mut own = [0usize; 3];
        for _ in 0..per {
            let d = rng.range(lo, hi);
            let (rows, s, off) = target_truth(&mut rng, bulk, layer, d);
            let c2t = chi2_true(&rows, &cand, bulk, layer, d, s, off, false);
            for (j, &p) in levels.iter().enumerate() {
                let f = test_hypothesis(&rows, &[WL], &cand, &config(p)).unwrap();
                own[j] += usize::from(f.consistent);
                oracle[j] += usize::from(c2t <= chi2_quantile_any(p, rows.len() as f64));
            }
        }
        let frac = |j: usize| own[j] as f64 / per as f64;
        eprintln!(
            "| {name} | {:.4} | {:.4} | {:.4} |",
            frac(0),
            frac(1),
            frac(2)
        );
        for j in 0..3 {
            pass[j] += own[j];
        }
        n_all += per;
    }
    let frac = |x: &[usize; 3], j: usize| x[j] as f64 / n_all as f64;
    eprintln!(
        "| all ({n_all}) | {:.4} | {:.4} | {:.4} | oracle {:.4} / {:.4} / {:.4} |",
        frac(&pass, 0),
        frac(&pass, 1),
        frac(&pass, 2),
        frac(&oracle, 0),
        frac(&oracle, 1),
        frac(&oracle, 2)
    );
    for (j, &p) in levels.iter().enumerate() {
        let se = (p * (1.0 - p) / n_all as f64).sqrt();
        let got = frac(&pass, j);
        assert!((got - p).abs() <= 4.0 * se, "at {p}: {got}");
    }
}

#[test]
fn library_materials_as_found() {
    let full = polarid_testkit::full();
    let per = polarid_testkit::seeds(20, 300) as usize;
    let protos = library();
    let cfg = config(0.95);
    let mut rng = StdRng::seed_from_u64(study_seed(2027));
    let mut all = Tally::default();
    // Reliability: (stated probability, truth?) of every tested material.
    let mut rel: Vec<(f64, bool)> = Vec::new();
    // The truth's test: (p-value, χ²_min, rows, thickness at a bound, scale at a bound,
    // offset at a bound).
    let mut truth_tests: Vec<(f64, f64, usize, [bool; 3])> = Vec::new();
    // (χ² at the truth, χ²_min, the test's dof, rows).
    let mut diag: Vec<(f64, f64, f64, usize)> = Vec::new();
    let mut lines = Vec::new();
    for &name in MATERIALS.iter() {
        let (bulk, layer, lo, hi) = as_found(&protos, name);
        let cand = hypothesis(&protos, name);
        let mut t = Tally::default();
        for _ in 0..per {
            let d = rng.range(lo, hi);
            let (rows, s_true, off_true) = target_truth(&mut rng, bulk, layer, d);
            let c2t = chi2_true(&rows, &cand, bulk, layer, d, s_true, off_true, false);
            let out = classify_rows(&rows, &[WL], &protos, None, &cfg).unwrap();
            t.add(Some(name), &out.decision);
            all.add(Some(name), &out.decision);
            for c in &out.tested {
                rel.push((c.probability.unwrap(), c.class == name));
                if c.class == name {
                    let f = c.fit.unwrap();
                    diag.push((c2t, f.chi2, f.dof, rows.len()));
                    let near = |x: f64, a: f64| (x - a).abs() < 1e-6 * (1.0 + a.abs());
                    let off = cfg.nuisances.offset_max;
                    truth_tests.push((
                        f.p_value,
                        f.chi2,
                        rows.len(),
                        [
                            near(f.thickness_nm, lo) || near(f.thickness_nm, hi),
                            near(f.scale, cfg.nuisances.scale_min) || near(f.scale, 1.0),
                            near(f.offset, -off) || near(f.offset, off),
                        ],
                    ));
                }
            }
        }
        lines.push(format!(
            "| {name} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} |",
            t.frac(t.covered),
            t.frac(t.alone),
            t.frac(t.wrong_alone),
            t.frac(t.unknown),
            t.size as f64 / t.n as f64
        ));
    }
    eprintln!(
        "| material | truth among answers | right alone | wrong alone | unknown | mean set |"
    );
    for l in &lines {
        eprintln!("{l}");
    }
    eprintln!(
        "| all ({}) | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} |",
        all.n,
        all.frac(all.covered),
        all.frac(all.alone),
        all.frac(all.wrong_alone),
        all.frac(all.unknown),
        all.size as f64 / all.n as f64
    );
    // Reliability of the probabilities: stated against observed, binned.
    let edges = [0.0, 0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 1.0 + 1e-12];
    eprintln!("| stated probability | materials | mean stated | observed (truth) |");
    for w in edges.windows(2) {
        let sel: Vec<&(f64, bool)> = rel.iter().filter(|r| r.0 >= w[0] && r.0 < w[1]).collect();
        if sel.is_empty() {
            continue;
        }
        let mean = sel.iter().map(|r| r.0).sum::<f64>() / sel.len() as f64;
        let obs = sel.iter().filter(|r| r.1).count() as f64 / sel.len() as f64;
        eprintln!(
            "| {:.2}–{:.2} | {} | {mean:.3} | {obs:.3} |",
            w[0],
            w[1].min(1.0),
            sel.len()
        );
    }
    if let Some(path) = std::env::var_os("POLARID_RELIABILITY_PNG") {
        reliability_png(
            std::path::Path::new(&path),
            &rel,
            &edges,
            &format!(
                "Hypothesis probabilities: {} targets x {} materials",
                all.n,
                rel.len() / all.n.max(1)
            ),
        );
    }
    // Calibration of the truth's test in both directions: the fraction of targets whose
    // own material passes at each stated confidence.
    // The oracle: χ² at the true nuisances against χ²_T, what the noise of this sample
    // alone gives.
    eprintln!(
        "| stated confidence | truth passes | truth passes, chi2_T bound | chi2 at the truth <= chi2_T quantile |"
    );
    let mut passes = Vec::new();
    for p in [0.9, 0.95, 0.99] {
        let n = truth_tests.len() as f64;
        let pass = truth_tests.iter().filter(|t| t.0 >= 1.0 - p).count() as f64 / n;
        let naive = truth_tests
            .iter()
            .filter(|t| t.1 <= chi2_quantile_any(p, t.2 as f64))
            .count() as f64
            / n;
        let oracle = diag
            .iter()
            .filter(|x| x.0 <= chi2_quantile_any(p, x.3 as f64))
            .count() as f64
            / n;
        eprintln!("| {p} | {pass:.3} | {naive:.3} | {oracle:.3} |");
        passes.push(pass);
    }
    for t in 6..=10 {
        let sel: Vec<_> = diag.iter().filter(|x| x.3 == t).collect();
        let n = sel.len() as f64;
        let m =
            |f: &dyn Fn(&(f64, f64, f64, usize)) -> f64| sel.iter().map(|x| f(x)).sum::<f64>() / n;
        let q = chi2_quantile_any(0.95, t as f64);
        eprintln!(
            "T={t}: n {n}, mean chi2_true {:.2}, P(chi2_true > q95_T) {:.3}, mean chi2_min {:.2}, mean dof {:.2}",
            m(&|x| x.0),
            sel.iter().filter(|x| x.0 > q).count() as f64 / n,
            m(&|x| x.1),
            m(&|x| x.2)
        );
    }
    // The search's misses: a minimum above the χ² at the truth (inside the box).
    let missed = diag.iter().filter(|x| x.1 > x.0 + 1e-6).count();
    eprintln!(
        "chi2_min above chi2 at the truth: {missed} of {}",
        diag.len()
    );
    for (i, what) in ["thickness", "scale", "offset"].iter().enumerate() {
        let at: Vec<_> = truth_tests.iter().filter(|t| t.3[i]).collect();
        let fail = at.iter().filter(|t| t.0 < 0.05).count();
        eprintln!(
            "{what} at a bound: {} of {} (fail at 95%: {fail})",
            at.len(),
            truth_tests.len()
        );
    }
    let cov = all.frac(all.covered);
    // 95% confidence: the truth among the answers near 95% (binomial margin of the
    // cheap run), named alone often, another material named alone almost never. The
    // truth's test at 90% and 99% neither under- nor over-covers beyond the margin.
    // Measured (full): 0.891 / 0.944 / 0.987 at 90 / 95 / 99% (the sample's oracle, χ² at
    // the true nuisances against χ²_T: 0.886 / 0.943 / 0.988).
    let margin = if full { 0.02 } else { 0.06 };
    assert!(
        (0.95 - margin..=0.95 + margin).contains(&cov),
        "coverage {cov}"
    );
    assert!(
        (0.90 - margin..=0.90 + margin).contains(&passes[0]),
        "coverage at 90%: {}",
        passes[0]
    );
    assert!(
        (0.99 - margin / 2.0..=0.999).contains(&passes[2]),
        "coverage at 99%: {}",
        passes[2]
    );
    assert!(
        all.frac(all.alone) >= 0.4,
        "right alone {}",
        all.frac(all.alone)
    );
    assert!(
        all.frac(all.wrong_alone) <= if full { 0.01 } else { 0.02 },
        "wrong alone {}",
        all.frac(all.wrong_alone)
    );
}

/// Surfaces the hypotheses do not describe: layers thicker than the material's range, and
/// materials missing from the library. They may be `unknown` or a set, never another
/// material alone (beyond 1%). Measured (full run, 300 per case): 0.2% overall (4 of
/// 1800) — aluminium under 8–15 nm of Al₂O₃ is named brass (under its ZnO) alone for
/// 1.3% (3.3% before the widened-layer test): at one band the two DoLP curves agree
/// within the noise (docs/CLASSIFY.md); silicon under 5–10 nm SiO₂: GaAs alone 0%.
#[test]
fn surfaces_outside_the_hypotheses() {
    let full = polarid_testkit::full();
    let per = polarid_testkit::seeds(20, 300) as usize;
    let protos = library();
    let cfg = config(0.95);
    let mut rng = StdRng::seed_from_u64(study_seed(99));
    let bulk = |name: &str| as_found(&protos, name).0;
    let layer = |name: &str| as_found(&protos, name).1;
    // (label, bulk, layer, thickness range, library without the truth?)
    let cases: Vec<(&str, (f64, f64), (f64, f64), (f64, f64), Option<&str>)> = vec![
        (
            "aluminum under 8-15 nm Al2O3",
            bulk("aluminum"),
            layer("aluminum"),
            (8.0, 15.0),
            None,
        ),
        (
            "copper under 6-12 nm Cu2O",
            bulk("copper"),
            layer("copper"),
            (6.0, 12.0),
            None,
        ),
        (
            "silicon under 5-10 nm SiO2",
            bulk("silicon"),
            layer("silicon"),
            (5.0, 10.0),
            None,
        ),
        (
            "nickel, missing",
            bulk("nickel"),
            layer("nickel"),
            (1.0, 2.0),
            Some("nickel"),
        ),
        (
            "copper, missing",
            bulk("copper"),
            layer("copper"),
            (0.5, 3.0),
            Some("copper"),
        ),
        (
            "titanium, missing",
            bulk("titanium"),
            layer("titanium"),
            (2.0, 6.0),
            Some("titanium"),
        ),
        (
            "LSAT 2.02 (not in the library)",
            (2.02, 0.0),
            (1.5, 0.0),
            (0.0, 2.0),
            None,
        ),
    ];
    let mut total = Tally::default();
    for (label, b, layer, (lo, hi), missing) in cases {
        let lib: Vec<MultiPrototype> = protos
            .iter()
            .filter(|p| Some(p.class.as_str()) != missing)
            .cloned()
            .collect();
        let mut t = Tally::default();
        let mut wrong_as = std::collections::BTreeMap::new();
        // The truth of the thick-layer cases is the material itself: naming it alone is
        // right; anything else alone is wrong.
        let truth = if label.contains("under") {
            label.split(' ').next()
        } else {
            None
        };
        for _ in 0..per {
            let d = rng.range(lo, hi);
            let rows = target(&mut rng, b, layer, d);
            let out = classify_rows(&rows, &[WL], &lib, None, &cfg).unwrap();
            t.add(truth, &out.decision);
            if out.decision.status == Status::Ok && Some(out.decision.predicted.as_str()) != truth {
                if std::env::var_os("POLARID_STUDY_VERBOSE").is_some() {
                    let c = &out.decision.candidates[0];
                    let own = out.tested.iter().find(|c| Some(c.class.as_str()) == truth);
                    eprintln!(
                        "  {label} d={d:.1}: {} {:?}; truth {:?}",
                        c.class,
                        c.fit,
                        own.and_then(|c| c.fit)
                    );
                }
                *wrong_as
                    .entry(out.decision.predicted.clone())
                    .or_insert(0usize) += 1;
            }
            // LSAT's index is within 0.02 of ZnO's (in the library): a transparent
            // material passing alone is an index, not a name (an open world).
            total.add(truth, &out.decision);
        }
        eprintln!(
            "| {label} | {:.3} | {:.3} | {:.3} | {:.2} |",
            t.frac(t.unknown),
            t.frac(t.wrong_alone),
            t.frac(t.alone),
            t.size as f64 / t.n as f64
        );
        // (columns: unknown, another material alone, the material itself alone, mean set)
        if !wrong_as.is_empty() {
            eprintln!("  named alone instead: {wrong_as:?}");
        }
    }
    let wrong = total.frac(total.wrong_alone);
    eprintln!("wrong alone overall {wrong:.3} of {}", total.n);
    assert!(
        wrong <= if full { 0.01 } else { 0.05 },
        "wrong alone {wrong}"
    );
}
