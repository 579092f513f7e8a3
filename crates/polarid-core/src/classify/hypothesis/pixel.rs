//! The hypothesis tests of [`classify_rows`](super::classify_rows) decided for millions
//! of pixels: the same consistent set, without the probabilities, and without testing the
//! materials that cannot pass.
//!
//! A pixel's answer needs only which classes pass (none → unknown, one → that class,
//! two or more → ambiguous). For each material, a **lower bound** of its `χ²_min` is
//! computed from tables made once per material and band; a material whose bound exceeds
//! the largest `χ²_min` that can pass ([`chi2_pass_bound`](super::chi2_pass_bound)) fails
//! without its test. The others are tested exactly as `classify_rows` tests them
//! ([`fit_checked`](super::fit_checked), without the evidence), most promising first,
//! until a second class passes (ambiguous). A single passing class is then questioned as
//! `classify_rows` questions it: the other materials under their layers widened to
//! [`EXTENDED_LAYER_NM`](super::EXTENDED_LAYER_NM), bounded the same way (their own tables)
//! with the answer's `χ²_min` as a second limit, tested exactly when the bound leaves them
//! open; one that passes and fits better makes the pixel ambiguous.
//!
//! # The lower bound
//!
//! With `P_t(d, δ) = |P_layer(β_t + δ, d)|` (module [`super`]), for any `(d, δ)` in the
//! box `P_t ∈ [L_t, H_t]`, the range of `|P_layer|` over `β ∈ [β_t − Δ, β_t + Δ]` and
//! `d ∈ [d_min, d_max]`; and the row's weight `1/σ_t² ≥ w_t = 1/(σ_y² + (P'_max σ_a/2)²)`
//! with `P'_max` the largest `|P'|` over the row's `β` cell, `P'` the slope the test's
//! row variance takes ([`angle_slope`](super::angle_slope): the material under its layer
//! at the middle of the layer's range). Then for every
//! point of the box
//!
//! ```text
//! χ²(d, s, δ) ≥ g(s) = Σ_t w_t dist(y_t, [s L_t, s H_t])²
//! ```
//!
//! (each row gets its own `d` and `δ`), and `g` is convex in `s` (each term is
//! `(s L − y)₊² + (y − s H)₊²`), so its minimum over `[s_min, 1]` is bounded below by a
//! tangent at the end of a bisection on `g'`. The reported `χ²_min` is the exact `χ²` at a
//! point of the box, so it is at least this bound.
//!
//! The ranges come from tables over `β ∈ [0, 90°]` in steps of 0.1° and over the layer's
//! thickness range in steps of at most 0.05 rad of layer phase: each cell's range is its
//! corners' range widened by the corners' spread and the largest second difference
//! around the cell (a smooth function departs from its corners' interpolant by at most
//! `h² max|f''|/8` inside a cell; the widening is several times that). A layer too thick
//! for the table gets no bound (`[0, 1]`), so its material is always tested. That the
//! answers equal `classify_rows`' is tested over many random pixels
//! (`crates/polarid-core/tests/it/pixel_hypothesis.rs`).

use std::cell::RefCell;
use std::f64::consts::FRAC_PI_2;
use std::sync::{Arc, OnceLock, RwLock};

use super::{
    CandidateModel, Detail, EXTENDED_LAYER_NM, HypRow, HypothesisConfig, band_slope,
    check_candidate, check_rows, chi2_pass_bound, fit_checked, layered_dolp,
};
use crate::classify::MultiPrototype;
use crate::dop::dop;
use crate::error::Result;

/// Cells of the `β` tables over `[0, π/2]` (0.1°).
const BETA_CELLS: usize = 900;

/// Largest layer-phase step of the thickness grid, radians.
const PHASE_STEP: f64 = 0.05;

/// Most thickness nodes of a table (thicker layers get no bound).
const MAX_D_NODES: usize = 257;

/// Row counts whose pass bound is cached.
const CACHED_ROWS: usize = 1024;

thread_local! {
    /// Per thread: the open materials and the rows' terms of a pixel.
    static SCRATCH: RefCell<ScratchVecs> = RefCell::default();
}

type ScratchVecs = (Vec<(f64, usize)>, Vec<(f64, f64, f64, f64)>);

/// The answer of one pixel's tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Verdict {
    /// No material has the rows' bands.
    NoBand,
    /// No material passes.
    None,
    /// One class passes (its index into the sorted class names).
    One(u16),
    /// Two or more classes pass.
    Several,
}

/// Bounds of `|P_layer|` and `|∂P/∂β|` per `β` cell for one material at one band.
#[derive(Debug)]
struct Table {
    /// Lowest `|P|` over the cell and the thickness range.
    lo: Vec<f64>,
    /// Highest `|P|` over the cell and the thickness range.
    hi: Vec<f64>,
    /// Highest `|P'|` over the cell, `P'` the slope of the row variance's angle term
    /// ([`angle_slope`](super::angle_slope): under the layer at mid range).
    dp: Vec<f64>,
}

/// The cell of `beta` (radians, clamped into the table).
fn cell(beta: f64) -> usize {
    let h = FRAC_PI_2 / BETA_CELLS as f64;
    ((beta / h).floor().max(0.0) as usize).min(BETA_CELLS - 1)
}

/// Largest second difference of `f` at nodes `i` and `i + 1` (where they have both
/// neighbours).
fn second_diff(f: impl Fn(usize) -> f64, i: usize, n: usize) -> f64 {
    let mut m = 0.0f64;
    for c in [i, i + 1] {
        if c >= 1 && c + 1 < n {
            m = m.max((f(c - 1) - 2.0 * f(c) + f(c + 1)).abs());
        }
    }
    m
}

impl Table {
    /// The table of candidate `cand` at band `b` (wavelength `w`, nm).
    fn new(cand: &CandidateModel, b: usize, w: f64) -> Self {
        let bulk = cand.bulk[b];
        let nb = BETA_CELLS + 1;
        let h = FRAC_PI_2 / BETA_CELLS as f64;
        let betas: Vec<f64> = (0..nb).map(|i| (i as f64 * h).min(FRAC_PI_2)).collect();
        // Thickness nodes.
        let (layer, d_lo, d_hi) = match &cand.layer {
            Some(l) if l.max_nm > 0.0 => (Some(l.index[b]), l.min_nm, l.max_nm),
            _ => (None, 0.0, 0.0),
        };
        let nd = match layer {
            Some((n, k)) if d_hi > d_lo => {
                let phase = 4.0 * std::f64::consts::PI * (d_hi - d_lo) * (n.hypot(k) + 1.0) / w;
                let m = (phase / PHASE_STEP).ceil() as usize + 1;
                if m > MAX_D_NODES {
                    return Self::unbounded(cand, b, w, &betas);
                }
                m.max(3)
            }
            _ => 1,
        };
        let ds: Vec<f64> = (0..nd)
            .map(|j| {
                if nd == 1 {
                    d_lo
                } else {
                    d_lo + (d_hi - d_lo) * j as f64 / (nd - 1) as f64
                }
            })
            .collect();
        // f[i * nd + j] = |P| at betas[i], ds[j] (eq. 9 at d = 0, as the test evaluates).
        let mut f = vec![0.0; nb * nd];
        for (i, &beta) in betas.iter().enumerate() {
            for (j, &d) in ds.iter().enumerate() {
                f[i * nd + j] = match layer {
                    Some(l) if d > 0.0 => layered_dolp(bulk, l, d / w, beta),
                    _ => dop(bulk.0, bulk.1, beta),
                };
            }
        }
        let at = |i: usize, j: usize| f[i * nd + j];
        let mut lo = vec![0.0; BETA_CELLS];
        let mut hi = vec![0.0; BETA_CELLS];
        for i in 0..BETA_CELLS {
            let (mut l, mut u) = (f64::INFINITY, f64::NEG_INFINITY);
            for j in 0..nd.saturating_sub(1).max(1) {
                let j1 = (j + 1).min(nd - 1);
                let c = [at(i, j), at(i + 1, j), at(i, j1), at(i + 1, j1)];
                let cmin = c.iter().copied().fold(f64::INFINITY, f64::min);
                let cmax = c.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let mut curv = 0.0f64;
                for jj in [j, j1] {
                    curv = curv.max(second_diff(|x| at(x, jj), i, nb));
                }
                if nd > 1 {
                    for ii in [i, i + 1] {
                        curv = curv.max(second_diff(|y| at(ii, y), j, nd));
                    }
                }
                let slack = (cmax - cmin) + curv;
                l = l.min(cmin - slack);
                u = u.max(cmax + slack);
            }
            lo[i] = if l.is_finite() { l.max(0.0) } else { 0.0 };
            hi[i] = if u.is_finite() { u.min(1.0) } else { 1.0 };
        }
        Self {
            lo,
            hi,
            dp: Self::slopes(cand, b, w, &betas),
        }
    }

    /// A table that bounds nothing (`|P| ∈ [0, 1]`).
    fn unbounded(cand: &CandidateModel, b: usize, w: f64, betas: &[f64]) -> Self {
        Self {
            lo: vec![0.0; BETA_CELLS],
            hi: vec![1.0; BETA_CELLS],
            dp: Self::slopes(cand, b, w, betas),
        }
    }

    /// Highest `|P'|` per cell, `P'` the slope of the row variance of `cand` at band `b`
    /// (wavelength `w`; [`band_slope`]), corners widened as the ranges are.
    fn slopes(cand: &CandidateModel, b: usize, w: f64, betas: &[f64]) -> Vec<f64> {
        let g: Vec<f64> = betas
            .iter()
            .map(|&beta| band_slope(cand, b, w, beta).abs())
            .collect();
        (0..BETA_CELLS)
            .map(|i| {
                let (a, b) = (g[i], g[i + 1]);
                let v = a.max(b) + (a - b).abs() + second_diff(|x| g[x], i, g.len());
                if v.is_finite() { v } else { f64::INFINITY }
            })
            .collect()
    }
}

/// One material at one set of bands.
#[derive(Debug)]
struct Material {
    /// Its class (index into the sorted class names).
    class: u16,
    cand: CandidateModel,
    /// Per band of the set.
    tables: Vec<Arc<Table>>,
    /// The material under its layer widened to `[d_min, EXTENDED_LAYER_NM]`, with its
    /// tables (a layer whose range already reaches that has none): the test that questions
    /// a single answer (`classify_rows`, "Layers beyond their range").
    widened: Option<(CandidateModel, Vec<Arc<Table>>)>,
}

/// The materials at one set of bands.
#[derive(Debug)]
struct BandSet {
    wavelengths: Vec<u64>,
    materials: Vec<Material>,
    /// The first material whose model is bad (its error is `classify_rows`' error).
    bad: Option<usize>,
}

/// Tables made so far, by prototype, band index and wavelength.
#[derive(Debug, Default)]
struct Cache {
    sets: Vec<Arc<BandSet>>,
    /// Keyed by prototype, wavelength and layer (0 none, 1 its own, 2 widened).
    tables: Vec<((usize, u64, u8), Arc<Table>)>,
}

/// The per-pixel hypothesis tests of a [`super::super::HypothesisDecider`].
#[derive(Debug, Clone)]
pub(crate) struct PixelTests {
    protos: Arc<Vec<MultiPrototype>>,
    /// Class index of each prototype.
    class_of: Vec<u16>,
    cache: Arc<RwLock<Cache>>,
    /// `chi2_pass_bound` by row count, per confidence of the decider.
    bounds: Arc<Vec<OnceLock<f64>>>,
}

impl PixelTests {
    /// The tests of `protos` whose classes are `classes` (sorted names).
    pub(crate) fn new(protos: &[MultiPrototype], classes: &[String]) -> Self {
        let class_of = protos
            .iter()
            .map(|p| classes.iter().position(|c| *c == p.class).unwrap_or(0) as u16)
            .collect();
        Self {
            protos: Arc::new(protos.to_vec()),
            class_of,
            cache: Arc::default(),
            bounds: Arc::new((0..CACHED_ROWS).map(|_| OnceLock::new()).collect()),
        }
    }

    /// The materials at `wavelengths` (made once per set of bands).
    fn band_set(&self, wavelengths: &[f64]) -> Arc<BandSet> {
        let same = |s: &BandSet| {
            s.wavelengths.len() == wavelengths.len()
                && s.wavelengths
                    .iter()
                    .zip(wavelengths)
                    .all(|(a, b)| *a == b.to_bits())
        };
        if let Ok(c) = self.cache.read()
            && let Some(s) = c.sets.iter().find(|s| same(s))
        {
            return s.clone();
        }
        let mut c = match self.cache.write() {
            Ok(c) => c,
            Err(p) => p.into_inner(),
        };
        if let Some(s) = c.sets.iter().find(|s| same(s)) {
            return s.clone();
        }
        let mut materials = Vec::new();
        let mut bad = None;
        for (i, p) in self.protos.iter().enumerate() {
            let Some(cand) = CandidateModel::from_prototype(p, wavelengths) else {
                continue;
            };
            if check_candidate(&cand, wavelengths).is_err() {
                bad.get_or_insert(materials.len());
                materials.push(Material {
                    class: self.class_of[i],
                    cand,
                    tables: Vec::new(),
                    widened: None,
                });
                continue;
            }
            let layer_key = u8::from(cand.layer.is_some());
            let tables = band_tables(&mut c.tables, i, layer_key, &cand, wavelengths);
            let widened = match &cand.layer {
                Some(l) if l.max_nm < EXTENDED_LAYER_NM => {
                    let mut w = cand.clone();
                    if let Some(l) = w.layer.as_mut() {
                        l.max_nm = EXTENDED_LAYER_NM;
                    }
                    let t = band_tables(&mut c.tables, i, 2, &w, wavelengths);
                    Some((w, t))
                }
                _ => None,
            };
            materials.push(Material {
                class: self.class_of[i],
                cand,
                tables,
                widened,
            });
        }
        let set = Arc::new(BandSet {
            wavelengths: wavelengths.iter().map(|w| w.to_bits()).collect(),
            materials,
            bad,
        });
        c.sets.push(set.clone());
        set
    }

    /// The largest `χ²_min` that can pass with `rows` rows.
    fn pass_bound(&self, rows: usize, confidence: f64) -> f64 {
        match self.bounds.get(rows) {
            Some(b) => *b.get_or_init(|| chi2_pass_bound(rows, confidence)),
            None => chi2_pass_bound(rows, confidence),
        }
    }

    /// Which classes pass for `rows` (bands indexing `wavelengths`) under `cfg`: the
    /// consistent set of [`classify_rows`](super::classify_rows) with uniform priors.
    /// Errors: as `classify_rows`.
    pub(crate) fn decide(
        &self,
        rows: &[HypRow],
        wavelengths: &[f64],
        cfg: &HypothesisConfig,
    ) -> Result<Verdict> {
        cfg.validate()?;
        check_rows(rows, wavelengths)?;
        let set = self.band_set(wavelengths);
        if let Some(b) = set.bad {
            check_candidate(&set.materials[b].cand, wavelengths)?;
        }
        if set.materials.is_empty() {
            return Ok(Verdict::NoBand);
        }
        SCRATCH.with(|s| {
            let mut s = s.borrow_mut();
            let (open, terms) = &mut *s;
            self.decide_with(rows, wavelengths, cfg, &set, open, terms)
        })
    }

    fn decide_with(
        &self,
        rows: &[HypRow],
        wavelengths: &[f64],
        cfg: &HypothesisConfig,
        set: &BandSet,
        open: &mut Vec<(f64, usize)>,
        terms: &mut Vec<(f64, f64, f64, f64)>,
    ) -> Result<Verdict> {
        let cap = self.pass_bound(rows.len(), cfg.confidence);
        let limit = cap + 1e-6 * (1.0 + cap);
        let off = cfg.nuisances.offset_max;
        let s_min = cfg.nuisances.scale_min;
        open.clear();
        for (m, mat) in set.materials.iter().enumerate() {
            fill_terms(&mat.tables, rows, off, terms);
            if !exceeds(terms, s_min, limit) {
                open.push((lower_hint(terms, s_min), m));
            }
        }
        // Most promising first; stop at the second class that passes.
        open.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut found: Option<u16> = None;
        let mut found_chi2 = f64::NAN;
        for &(_, m) in open.iter() {
            let mat = &set.materials[m];
            if found == Some(mat.class) {
                continue;
            }
            let fit = fit_checked(rows, wavelengths, &mat.cand, cfg, Detail::Verdict);
            if fit.consistent {
                if found.is_some() {
                    return Ok(Verdict::Several);
                }
                found = Some(mat.class);
                found_chi2 = fit.chi2;
            }
        }
        let Some(class) = found else {
            return Ok(Verdict::None);
        };
        // A single answer is questioned by every other material under its widened layer
        // (`classify_rows`): one that passes and fits better than the answer's most
        // probable prototype joins it. Bounded as above, with the answer's `χ²_min` as a
        // second limit.
        // A class of one prototype: the test just made; several: the most probable one's.
        let several = set.materials.iter().filter(|m| m.class == class).count() > 1;
        let bar = if several {
            match self.answer_chi2(rows, wavelengths, cfg, set, class) {
                Some(b) => b,
                None => return Ok(Verdict::One(class)),
            }
        } else {
            found_chi2
        };
        let limit = limit.min(bar + 1e-6 * (1.0 + bar));
        open.clear();
        for (m, mat) in set.materials.iter().enumerate() {
            if mat.class == class {
                continue;
            }
            if let Some((_, tables)) = &mat.widened {
                fill_terms(tables, rows, off, terms);
                if !exceeds(terms, s_min, limit) {
                    open.push((lower_hint(terms, s_min), m));
                }
            }
        }
        open.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(_, m) in open.iter() {
            if let Some((cand, _)) = &set.materials[m].widened {
                let fit = fit_checked(rows, wavelengths, cand, cfg, Detail::Verdict);
                if fit.consistent && fit.chi2 < bar {
                    return Ok(Verdict::Several);
                }
            }
        }
        Ok(Verdict::One(class))
    }

    /// The `χ²_min` of the most probable of `class`'s several prototypes (highest evidence,
    /// as `classify_rows` ranks them), the bar of the widened test (`None` if none).
    fn answer_chi2(
        &self,
        rows: &[HypRow],
        wavelengths: &[f64],
        cfg: &HypothesisConfig,
        set: &BandSet,
        class: u16,
    ) -> Option<f64> {
        let mut best: Option<(f64, f64)> = None;
        for mat in set.materials.iter().filter(|m| m.class == class) {
            let f = fit_checked(rows, wavelengths, &mat.cand, cfg, Detail::Evidence);
            let key = f.log_evidence;
            let better = match best {
                None => true,
                Some((k, chi2)) => key > k || (key == k && f.chi2 < chi2),
            };
            if better {
                best = Some((key, f.chi2));
            }
        }
        best.map(|b| b.1)
    }
}

/// The tables of prototype `proto` as `cand` (layer key `layer`: 0 none, 1 its own, 2
/// widened) at each of `wavelengths`, made once and kept in `cache`.
fn band_tables(
    cache: &mut Vec<((usize, u64, u8), Arc<Table>)>,
    proto: usize,
    layer: u8,
    cand: &CandidateModel,
    wavelengths: &[f64],
) -> Vec<Arc<Table>> {
    wavelengths
        .iter()
        .enumerate()
        .map(|(b, &w)| {
            let key = (proto, w.to_bits(), layer);
            match cache.iter().find(|(k, _)| *k == key) {
                Some((_, t)) => t.clone(),
                None => {
                    let t = Arc::new(Table::new(cand, b, w));
                    cache.push((key, t.clone()));
                    t
                }
            }
        })
        .collect()
}

/// The terms `(w_t, y_t, L_t, H_t)` of `rows` against a material's `tables` for the
/// offset bound `off` (module documentation).
fn fill_terms(
    tables: &[Arc<Table>],
    rows: &[HypRow],
    off: f64,
    terms: &mut Vec<(f64, f64, f64, f64)>,
) {
    terms.clear();
    for r in rows {
        let t = &tables[r.band];
        let (c0, c1) = (
            cell((r.beta - off).max(0.0)),
            cell((r.beta + off).min(FRAC_PI_2)),
        );
        let (mut l, mut h) = (f64::INFINITY, 0.0f64);
        for c in c0..=c1 {
            l = l.min(t.lo[c]);
            h = h.max(t.hi[c]);
        }
        let a = if r.angle_sd > 0.0 {
            0.5 * t.dp[cell(r.beta)] * r.angle_sd
        } else {
            0.0
        };
        // A weight no larger than the row's (0 when the slope is unbounded).
        let w = if a.is_finite() {
            1.0 / (r.dolp_sd * r.dolp_sd + a * a)
        } else {
            0.0
        };
        terms.push((w, r.dolp, l, h));
    }
}

/// `g(s)` and `g'(s)` (module documentation) of the terms `(w, y, L, H)`.
fn g_and_slope(terms: &[(f64, f64, f64, f64)], s: f64) -> (f64, f64) {
    let (mut g, mut dg) = (0.0, 0.0);
    for &(w, y, l, h) in terms {
        let below = s * l - y;
        if below > 0.0 {
            g += w * below * below;
            dg += 2.0 * w * l * below;
        }
        let above = y - s * h;
        if above > 0.0 {
            g += w * above * above;
            dg -= 2.0 * w * h * above;
        }
    }
    (g, dg)
}

/// Whether `min over s ∈ [s_min, 1] of g(s)` exceeds `limit` (a tangent of the convex `g`
/// below it on the whole interval).
fn exceeds(terms: &[(f64, f64, f64, f64)], s_min: f64, limit: f64) -> bool {
    let (mut a, mut b) = (s_min.min(1.0), 1.0);
    let (ga, da) = g_and_slope(terms, a);
    if !(ga.is_finite() && da.is_finite()) || ga <= limit {
        return false;
    }
    if da >= 0.0 {
        return true; // g increases from s_min: its minimum is g(s_min).
    }
    let (gb, db) = g_and_slope(terms, b);
    if !(gb.is_finite() && db.is_finite()) || gb <= limit {
        return false;
    }
    if db <= 0.0 {
        return true; // g decreases to 1: its minimum is g(1).
    }
    // The minimiser lies in (a, b) with g'(a) < 0 < g'(b).
    let (mut ga, mut da) = (ga, da);
    let (mut gb, mut db) = (gb, db);
    for _ in 0..60 {
        // Tangents at both ends bound g below on [a, b]: the falling one by
        // g(a) + g'(a)(b − a), the rising one by g(b) − g'(b)(b − a).
        let lower = (ga + da * (b - a)).max(gb - db * (b - a));
        if lower > limit {
            return true;
        }
        let m = 0.5 * (a + b);
        if !(m > a && m < b) {
            return false;
        }
        let (gm, dm) = g_and_slope(terms, m);
        if !(gm.is_finite() && dm.is_finite()) || gm <= limit {
            return false;
        }
        if dm < 0.0 {
            (a, ga, da) = (m, gm, dm);
        } else if dm > 0.0 {
            (b, gb, db) = (m, gm, dm);
        } else {
            return true; // g'(m) = 0: g(m) is the minimum, above the limit.
        }
    }
    false
}

/// The order in which open materials are tested: the lower of `g(s_min)` and `g(1)`.
fn lower_hint(terms: &[(f64, f64, f64, f64)], s_min: f64) -> f64 {
    g_and_slope(terms, s_min).0.min(g_and_slope(terms, 1.0).0)
}

#[cfg(test)]
mod tests;
