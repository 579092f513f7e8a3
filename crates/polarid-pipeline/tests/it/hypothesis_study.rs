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
//! The native layers are a test-local table (approximate literature values: Al₂O₃ on
//! aluminium 2–5 nm, n ≈ 1.65, Evangelisti et al. and the field literature on native
//! oxides; Cu₂O on copper 0.5–3 nm, 2.9 + 0.1i; NiO 1–2 nm, 2.25; Cr₂O₃ 1–3 nm, 2.3; TiO₂ on
//! titanium 2–6 nm, 2.3; SiO₂ on silicon 1–2 nm, 1.46; adsorbed hydrocarbons, n ≈ 1.5,
//! on gold and silver 0.5–1.5 nm and on glasses and plastics 0–2 nm; iron oxide on iron
//! 1–3 nm, 2.9 + 0.3i), and every other library material is given 0–2 nm of
//! contamination (n = 1.5).

#![allow(clippy::type_complexity)] // the study's case tables read as tuples

use polarid_core::classify::{
    HypRow, HypothesisConfig, MultiPrototype, NativeLayer, Nuisances, Status, classify_rows,
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

/// `(material, layer name, layer index, min nm, max nm)`.
const LAYERS: [(&str, &str, (f64, f64), f64, f64); 12] = [
    ("aluminum", "Al2O3", (1.65, 0.0), 2.0, 5.0),
    ("copper", "Cu2O", (2.9, 0.1), 0.5, 3.0),
    ("silver", "contamination", (1.5, 0.0), 0.5, 1.5),
    ("gold", "contamination", (1.5, 0.0), 0.5, 1.5),
    ("nickel", "NiO", (2.25, 0.0), 1.0, 2.0),
    ("chromium", "Cr2O3", (2.3, 0.0), 1.0, 3.0),
    ("stainless_steel_austenitic", "Cr2O3", (2.3, 0.0), 1.0, 3.0),
    ("iron", "iron oxide", (2.9, 0.3), 1.0, 3.0),
    ("titanium", "TiO2", (2.3, 0.0), 2.0, 6.0),
    ("silicon", "SiO2", (1.46, 0.0), 1.0, 2.0),
    ("N-BK7", "contamination", (1.5, 0.0), 0.0, 2.0),
    ("PMMA", "contamination", (1.5, 0.0), 0.0, 2.0),
];

const WL: f64 = 650.0;
const ANGLE_SD_DEG: f64 = 0.2;
const FLOOR: f64 = 0.002;

fn library() -> Vec<MultiPrototype> {
    let mut protos = Library::builtin().unwrap().multi_prototypes();
    for p in &mut protos {
        let (name, index, lo, hi) = LAYERS
            .iter()
            .find(|l| l.0 == p.class)
            .map_or(("contamination", (1.5, 0.0), 0.0, 2.0), |l| {
                (l.1, l.2, l.3, l.4)
            });
        for b in &mut p.bands {
            b.layer = Some(index);
        }
        p.surface = Some(NativeLayer {
            name: name.into(),
            min_nm: lo,
            max_nm: hi,
        });
    }
    protos
}

fn config(p: f64) -> HypothesisConfig {
    HypothesisConfig {
        confidence: p,
        // FitConfig's defaults: extinction ratio 100, no retardance, 0.2°.
        nuisances: Nuisances::from_error_model(100.0, 0.0, ANGLE_SD_DEG.to_radians()),
    }
}

/// One simulated target of `bulk` under `layer` (index, thickness nm).
fn target(rng: &mut StdRng, bulk: (f64, f64), layer: (f64, f64), d: f64) -> Vec<HypRow> {
    let t = 6 + (rng.next() % 5) as usize;
    let se = rng.range(0.002, 0.005);
    let er = rng.range(100.0, 500.0);
    let s = (er - 1.0) / (er + 1.0);
    let off = rng.range(-0.3, 0.3).to_radians();
    let angle_sd = ANGLE_SD_DEG.to_radians();
    let sd = (se * se + FLOOR * FLOOR).sqrt();
    (0..t)
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
        .collect()
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

#[test]
fn library_materials_as_found() {
    let full = polarid_testkit::full();
    let per = polarid_testkit::seeds(20, 300) as usize;
    let protos = library();
    let cfg = config(0.95);
    let mut rng = StdRng::seed_from_u64(2027);
    let mut all = Tally::default();
    // Reliability: (stated probability, truth?) of every tested material.
    let mut rel: Vec<(f64, bool)> = Vec::new();
    let mut lines = Vec::new();
    for &(name, _, layer, lo, hi) in LAYERS.iter() {
        let p = protos.iter().find(|p| p.class == name).unwrap();
        let bulk = (p.bands[0].n, p.bands[0].k);
        let mut t = Tally::default();
        for _ in 0..per {
            let d = rng.range(lo, hi);
            let rows = target(&mut rng, bulk, layer, d);
            let out = classify_rows(&rows, &[WL], &protos, None, &cfg).unwrap();
            t.add(Some(name), &out.decision);
            all.add(Some(name), &out.decision);
            for c in &out.tested {
                rel.push((c.probability.unwrap(), c.class == name));
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
    let cov = all.frac(all.covered);
    // 95% confidence: the truth among the answers near 95% (binomial margin of the
    // cheap run), named alone often, another material named alone almost never.
    let margin = if full { 0.02 } else { 0.06 };
    assert!((0.95 - margin..=0.99).contains(&cov), "coverage {cov}");
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
/// material alone (beyond 1%). Measured (full run, 300 per case): 1.1% overall —
/// aluminium under 8–15 nm of Al₂O₃ is named as another metal alone for 5.3%, so the full
/// run's 1% bound is not met yet (docs/CLASSIFY.md).
#[test]
fn surfaces_outside_the_hypotheses() {
    let full = polarid_testkit::full();
    let per = polarid_testkit::seeds(20, 300) as usize;
    let protos = library();
    let cfg = config(0.95);
    let mut rng = StdRng::seed_from_u64(99);
    let bulk = |name: &str| {
        let p = protos.iter().find(|p| p.class == name).unwrap();
        (p.bands[0].n, p.bands[0].k)
    };
    // (label, bulk, layer, thickness range, library without the truth?)
    let cases: Vec<(&str, (f64, f64), (f64, f64), (f64, f64), Option<&str>)> = vec![
        (
            "aluminum under 8-15 nm Al2O3",
            bulk("aluminum"),
            (1.65, 0.0),
            (8.0, 15.0),
            None,
        ),
        (
            "copper under 6-12 nm Cu2O",
            bulk("copper"),
            (2.9, 0.1),
            (6.0, 12.0),
            None,
        ),
        (
            "silicon under 5-10 nm SiO2",
            bulk("silicon"),
            (1.46, 0.0),
            (5.0, 10.0),
            None,
        ),
        (
            "nickel, missing",
            bulk("nickel"),
            (2.25, 0.0),
            (1.0, 2.0),
            Some("nickel"),
        ),
        (
            "copper, missing",
            bulk("copper"),
            (2.9, 0.1),
            (0.5, 3.0),
            Some("copper"),
        ),
        (
            "titanium, missing",
            bulk("titanium"),
            (2.3, 0.0),
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
            // LSAT's index is within 0.02 of ZnO's (in the library): DoLP at these errors
            // cannot tell them apart, so it is reported, not counted.
            if !label.starts_with("LSAT") {
                total.add(truth, &out.decision);
            }
        }
        eprintln!(
            "| {label} | {:.3} | {:.3} | {:.3} | {:.2} |",
            t.frac(t.unknown),
            t.frac(t.wrong_alone),
            t.frac(t.alone),
            t.size as f64 / t.n as f64
        );
        // (columns: unknown, another material alone, the material itself alone, mean set)
    }
    let wrong = total.frac(total.wrong_alone);
    eprintln!("wrong alone overall {wrong:.3} of {}", total.n);
    assert!(
        wrong <= if full { 0.01 } else { 0.05 },
        "wrong alone {wrong}"
    );
}
