//! Inversion of DoLP measurements for the complex index `N = n + ik` (paper section 5,
//! eq. 16): a global, bounded, weighted least-squares fit with uncertainties.
//!
//! Given `T ≥ 3` DoLP values `y_t` measured at known local incidence angles `β_t`, the
//! fit minimises
//!
//! ```text
//! χ²(n, k) = Σ_t w_t (P(n, k, β_t) − y_t)²,    w_t = 1/se_t²  (or 1)
//! ```
//!
//! over the box `n ∈ [n_min, n_max]`, `k ∈ [k_min, k_max]` (default `[0.01, 10] ×
//! [0, 15]`), where `P` is eq. (9).
//!
//! # Method
//! A [`FitPlan`] is built once per β set. It holds the β terms of eq. (9) and a
//! precomputed grid of `G = grid_n × grid_k` nodes (default 32 × 32, spaced
//! quadratically, `n_i = n_min + (n_max − n_min)(i/(grid_n − 1))²`, so that nodes are
//! denser at small `n` and `k`, where the curves change fastest) with the DoLP curve of
//! every node (f32, in blocks of 128 nodes so that a block is one contiguous read) and
//! its Jacobian. Fits are run a batch (chunk) at a time:
//!
//! 1. **Grid scan** (`scan.rs`): every node (every `stride`-th along each axis,
//!    `stride = max(1, grid/32)`, then the best node's neighbourhood) is scored in f32,
//!    unweighted as `½‖curve‖² − curve·y` (one multiply-add per node and source
//!    position: 10,240 at the default size and `T = 10`, no transcendental functions),
//!    weighted as `Σ w (curve − y)²`; unweighted pixels are scanned four at a time, so
//!    that each curve vector read serves four pixels. Vector lanes keep their running
//!    minima and the node holding them; nothing is stored per node. AVX-512F, AVX2 + FMA
//!    or portable kernels, chosen at run time; all give the same nodes.
//! 2. **Start**: one Gauss–Newton step from the best node with its stored Jacobian (no
//!    model evaluation); the node itself if that start turns out worse.
//! 3. **Polish** (`engine.rs`): Levenberg–Marquardt with the analytic Jacobian, 2×2
//!    normal equations in closed form and Marquardt scaling, run for sixteen fits side
//!    by side, one per SIMD lane (two f64x8 or four f64x4 vectors): the `T` values and
//!    gradients of eq. (9) are straight vector arithmetic, the step, accept/reject and
//!    stopping rules are branch-free lane code, and a lane whose fit ends takes the next
//!    fit of the batch at once. A fit's trial points do not depend on its neighbours,
//!    so a pixel gets the same result in any batch and from [`FitPlan::fit`]. The
//!    polish stops without a further evaluation once the Gauss–Newton model predicts a
//!    relative decrease below `ftol`: on average 5.9 evaluations at `T = 10`, noise sd
//!    0.005, `(n, k)` uniform in `[0.3, 3] × [0, 8]` (3–4 for 70% of the fits; up to ~25
//!    in the long curved valleys of strong metals, where `k` is poorly determined).
//! 4. **Competing basins** (only with [`FitOptions::max_candidates`] > 1): the scan
//!    also keeps the best node of every band of 256 nodes (eight rows of the grid, a
//!    range of `k`); a band's best node not next to the best node, whose Gauss–Newton
//!    step stays near it (a minimum, not a slope into another basin), does not land in
//!    the best node's basin and predicts a cost within 10% of the best node's
//!    prediction, is polished too, and the lowest minimum wins. Off by default: on
//!    10⁵-pixel sets of six kinds (the benchmark problem, the whole default box, noise
//!    sd 0.03, T = 4 angles, a 15° β range, low β) it changed no result, at a 30% cost
//!    (`examples/fit_global.rs`).
//!
//! Bounds are handled by projection: a step leaving the box is clamped (reflected at a
//! lower bound of 0, which is exact because eq. 9 is even in `n` and in `k`), and a
//! parameter on a bound whose descent direction points outwards is held fixed. A
//! solution on a bound other than `k = 0` is reported with status
//! [`FitStatus::AtBound`]: no fit leaves the box, and none sits on its edge silently.
//!
//! # Uncertainty
//! The covariance is `(JᵀWJ)⁻¹`, multiplied by the reduced χ² `χ²/(T − 2)` when no
//! standard errors are given. Near `k = 0` the model depends on `k` only through `k²`
//! (eq. 14–15), so `∂P/∂k → 0` and the linearised error of `k` diverges; when the
//! linearised interval on `k` reaches 0, the covariance is computed in `(n, u = k²)`
//! and `k_se = √(k² + se_u) − k` (the one-sigma upper deviation).

mod crb;
mod engine;
mod lm;
mod scan;
mod simd;

pub use crb::{Crb, crb, crb_weighted};

use rayon::prelude::*;

use crate::dop::{BetaTerms, dop_grad_terms, dop_terms};
use crate::error::{CoreError, Result};

use lm::Eval;
use scan::SCAN_BLOCK;
use simd::Lanes;

/// Instruction sets of the fit kernels (chosen at run time).
const ISA_PORTABLE: u8 = 0;
/// AVX2 + FMA.
const ISA_AVX2: u8 = 1;
/// AVX-512F (+ AVX2 + FMA).
const ISA_AVX512: u8 = 2;

/// The box of admissible `(n, k)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitBounds {
    /// Smallest `n` (> 0 or = 0).
    pub n_min: f64,
    /// Largest `n`.
    pub n_max: f64,
    /// Smallest `k` (≥ 0).
    pub k_min: f64,
    /// Largest `k`.
    pub k_max: f64,
}

impl Default for FitBounds {
    fn default() -> Self {
        Self {
            n_min: 0.01,
            n_max: 10.0,
            k_min: 0.0,
            k_max: 15.0,
        }
    }
}

/// Settings of a [`FitPlan`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// The box of admissible `(n, k)`.
    pub bounds: FitBounds,
    /// Grid nodes along `n` for the global start (≥ 4).
    pub grid_n: usize,
    /// Grid nodes along `k` for the global start (≥ 4).
    pub grid_k: usize,
    /// At most this many starts are polished per fit (≥ 1).
    pub max_candidates: usize,
    /// Iteration limit of one Levenberg–Marquardt polish.
    pub max_iter: u32,
    /// Relative step tolerance.
    pub xtol: f64,
    /// Relative cost-decrease tolerance.
    pub ftol: f64,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            bounds: FitBounds::default(),
            grid_n: 32,
            grid_k: 32,
            max_candidates: 1,
            max_iter: 1000,
            xtol: 1e-10,
            ftol: 1e-12,
        }
    }
}

pub use crate::status::FitStatus;

/// The result of one fit.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NkFit {
    /// Fitted `n`.
    pub n: f64,
    /// Fitted `k`.
    pub k: f64,
    /// Standard error of `n`.
    pub n_se: f64,
    /// Standard error of `k` (one-sigma upper deviation near `k = 0`, see the module
    /// documentation).
    pub k_se: f64,
    /// Correlation of the `n` and `k` estimates.
    pub nk_corr: f64,
    /// Root-mean-square (unweighted) DoLP residual.
    pub rms_residual: f64,
    /// The minimised cost `Σ w_t r_t²` (χ² when standard errors were given).
    pub cost: f64,
    /// Levenberg–Marquardt iterations, summed over the polished starts.
    pub iterations: u32,
    /// Model evaluations (each: `T` values and gradients), summed over the starts.
    pub evaluations: u32,
    /// Number of starts polished.
    pub starts: u32,
    /// Trust status.
    pub status: FitStatus,
    /// Why the status is not [`FitStatus::Ok`] (empty when it is).
    pub reason: &'static str,
}

impl NkFit {
    fn invalid(reason: &'static str) -> Self {
        Self {
            n: f64::NAN,
            k: f64::NAN,
            n_se: f64::NAN,
            k_se: f64::NAN,
            nk_corr: f64::NAN,
            rms_residual: f64::NAN,
            cost: f64::NAN,
            status: FitStatus::InvalidInput,
            reason,
            ..Default::default()
        }
    }
}

/// Smallest β span (radians, 3°) below which the fit is flagged ill-conditioned.
pub const MIN_BETA_SPAN: f64 = 3.0 * std::f64::consts::PI / 180.0;
/// Two β closer than this (radians) count as the same angle.
pub const DISTINCT_BETA_TOL: f64 = 1e-6;

/// Everything a fit needs that depends only on the β set and the options: built once,
/// shared (read-only, `Sync`) by every pixel.
#[derive(Debug, Clone)]
pub struct FitPlan {
    betas: Vec<f64>,
    terms: Vec<BetaTerms>,
    opts: FitOptions,
    /// `n` of the grid columns.
    node_n: Vec<f64>,
    /// `k` of the grid rows.
    node_k: Vec<f64>,
    /// β terms padded to whole SIMD lanes.
    lanes: Lanes,
    /// DoLP of node `g` at `β_t`: `node_curves[g * lanes.len + t]` (padding: 0).
    node_curves: Vec<f32>,
    /// Grid columns of the coarse scan (every `stride`-th, and the last).
    coarse_i: Vec<usize>,
    /// Grid rows of the coarse scan.
    coarse_j: Vec<usize>,
    /// Spacing of the coarse nodes in grid steps.
    stride: usize,
    /// Padded coarse node count (multiple of [`SCAN_BLOCK`]).
    gc_pad: usize,
    /// Nodes per band of the scan: [`scan::BAND`] when competing basins are searched
    /// (`max_candidates > 1`), else the whole grid.
    band: usize,
    /// DoLP of coarse node `c` (column `c % coarse_i.len()`) at `β_t`:
    /// in blocks of [`SCAN_BLOCK`] nodes, block-major:
    /// `coarse_curves[(c / SCAN_BLOCK * T + t) * SCAN_BLOCK + c % SCAN_BLOCK]` (padding: 0).
    coarse_curves: Vec<f32>,
    /// `½ Σ_t curve_c(t)²` of coarse node `c` (padding: +∞): the unweighted scan
    /// ranks nodes by `½‖c‖² − c·y = (cost − ‖y‖²)/2`.
    coarse_half_norm: Vec<f32>,
    /// 0 for coarse nodes, +∞ for padding: the start of the weighted scan's sums.
    coarse_base: Vec<f32>,
    /// Jacobian of node `g`: `jac[g * 2T + t]` = ∂P/∂n, `jac[g * 2T + T + t]` = ∂P/∂k.
    jac: Vec<f32>,
    /// Why every fit with this β set is ill-conditioned, if it is.
    issue: Option<&'static str>,
    /// `1 / (n_max − n_min)`, `1 / (k_max − k_min)` (grid cell lookup).
    inv_span: (f64, f64),
}

/// Per-thread scratch memory of a fit (no allocation per fit).
#[derive(Debug, Clone)]
pub struct FitWorkspace {
    /// Band minima of the scan of one pixel.
    bands: Vec<scan::BandMin>,
    /// Band minima of the scans of four pixels.
    bands4: Vec<scan::BandMin>,
    /// f32 measurements of four pixels.
    yf4: Vec<f32>,
    /// Valid pixels of a chunk.
    valid: Vec<usize>,
    /// Weights `1/se²` of a chunk.
    wall: Vec<f64>,
    /// Measurements and weights of one pixel padded to whole lanes (weight 0 on
    /// padding), f32.
    yf: Vec<f32>,
    wf: Vec<f32>,
    /// Polishes of a chunk.
    jobs: Vec<engine::Job>,
    /// First job and number of jobs of each pixel of a chunk.
    spans: Vec<(usize, usize)>,
    /// Results of the polishes.
    outs: Vec<engine::JobOut>,
    /// Lane-major measurements of the polishes in flight.
    lane: engine::LaneScratch,
}

fn warp(lo: f64, hi: f64, m: usize) -> Vec<f64> {
    (0..m)
        .map(|i| {
            let u = i as f64 / (m - 1) as f64;
            lo + (hi - lo) * u * u
        })
        .collect()
}

impl FitPlan {
    /// Build a plan for measurements at local incidence angles `betas` (radians, in
    /// `(0, π/2)`).
    ///
    /// Errors: fewer than 3 angles, a non-finite or out-of-range angle, or invalid
    /// options (empty box, grid smaller than 4 × 4). Fewer than 3 distinct angles or a
    /// span below [`MIN_BETA_SPAN`] is not an error: every fit then carries the status
    /// [`FitStatus::IllConditioned`].
    pub fn new(betas: &[f64], opts: FitOptions) -> Result<Self> {
        if betas.len() < 3 {
            return Err(CoreError::TooFew {
                what: "DoLP measurements (source positions)",
                needed: 3,
                got: betas.len(),
            });
        }
        for &b in betas {
            crate::error::ensure_finite("beta", b)?;
            if !(b > 0.0 && b < std::f64::consts::FRAC_PI_2) {
                return Err(CoreError::OutOfRange {
                    name: "beta",
                    value: b,
                    expected: "(0, pi/2) radians",
                });
            }
        }
        let b = &opts.bounds;
        for (name, v) in [
            ("n_min", b.n_min),
            ("n_max", b.n_max),
            ("k_min", b.k_min),
            ("k_max", b.k_max),
        ] {
            crate::error::ensure_finite(name, v)?;
        }
        if !(b.n_min >= 0.0 && b.n_max > b.n_min) {
            return Err(CoreError::OutOfRange {
                name: "n_max",
                value: b.n_max,
                expected: "n_max > n_min >= 0",
            });
        }
        if !(b.k_min >= 0.0 && b.k_max > b.k_min) {
            return Err(CoreError::OutOfRange {
                name: "k_max",
                value: b.k_max,
                expected: "k_max > k_min >= 0",
            });
        }
        if opts.grid_n < 4 || opts.grid_k < 4 || opts.grid_n * opts.grid_k > 1 << 20 {
            return Err(CoreError::OutOfRange {
                name: "grid size",
                value: (opts.grid_n * opts.grid_k) as f64,
                expected: "at least 4 x 4 and at most 2^20 nodes",
            });
        }
        if !(b.n_max <= simd::MAX_BOUND && b.k_max <= simd::MAX_BOUND) {
            return Err(CoreError::OutOfRange {
                name: "n_max/k_max",
                value: b.n_max.max(b.k_max),
                expected: "at most 1e100",
            });
        }
        if opts.max_candidates == 0 {
            return Err(CoreError::OutOfRange {
                name: "max_candidates",
                value: 0.0,
                expected: ">= 1",
            });
        }
        let terms: Vec<BetaTerms> = betas.iter().map(|&b| BetaTerms::new(b)).collect();
        let t_len = betas.len();
        let node_n = warp(b.n_min, b.n_max, opts.grid_n);
        let node_k = warp(b.k_min, b.k_max, opts.grid_k);
        let g = opts.grid_n * opts.grid_k;
        let lanes = Lanes::new(&terms);
        let tp = lanes.len;
        let mut node_curves = vec![0f32; g * tp];
        let mut jac = vec![0f32; g * 2 * t_len];
        for (j, &k) in node_k.iter().enumerate() {
            for (i, &n) in node_n.iter().enumerate() {
                let gi = j * opts.grid_n + i;
                for (t, bt) in terms.iter().enumerate() {
                    let d = dop_grad_terms(n, k, bt);
                    node_curves[gi * tp + t] = d.p as f32;
                    jac[gi * 2 * t_len + t] = d.dp_dn as f32;
                    // Below K_U the second column is ∂P/∂u, u = k² (see lm::step).
                    let j2 = if k >= lm::K_U {
                        d.dp_dk
                    } else if k > 0.0 {
                        d.dp_dk / (2.0 * k)
                    } else {
                        let du: f64 = 1e-6;
                        (dop_terms(n, du.sqrt(), bt) - d.p) / du
                    };
                    jac[gi * 2 * t_len + t_len + t] = j2 as f32;
                }
            }
        }
        // Coarse scan: every `stride`-th node along each axis, and the last.
        let stride = (opts.grid_n.min(opts.grid_k) / 32).max(1);
        let sub = |m: usize| -> Vec<usize> {
            let mut v: Vec<usize> = (0..m).step_by(stride).collect();
            if v.last() != Some(&(m - 1)) {
                v.push(m - 1);
            }
            v
        };
        let coarse_i = sub(opts.grid_n);
        let coarse_j = sub(opts.grid_k);
        let gc = coarse_i.len() * coarse_j.len();
        let gc_pad = gc.div_ceil(SCAN_BLOCK) * SCAN_BLOCK;
        let mut coarse_curves = vec![0f32; t_len * gc_pad];
        let mut coarse_half_norm = vec![f32::INFINITY; gc_pad];
        let mut coarse_base = vec![f32::INFINITY; gc_pad];
        for (cj, &j) in coarse_j.iter().enumerate() {
            for (ci, &i) in coarse_i.iter().enumerate() {
                let c = cj * coarse_i.len() + ci;
                let gi = j * opts.grid_n + i;
                for t in 0..t_len {
                    coarse_curves[(c / SCAN_BLOCK * t_len + t) * SCAN_BLOCK + c % SCAN_BLOCK] =
                        node_curves[gi * tp + t];
                }
                let sq: f64 = (0..t_len)
                    .map(|t| f64::from(node_curves[gi * tp + t]).powi(2))
                    .sum();
                coarse_half_norm[c] = (0.5 * sq) as f32;
                coarse_base[c] = 0.0;
            }
        }
        let mut sorted = betas.to_vec();
        sorted.sort_by(f64::total_cmp);
        let distinct = 1 + sorted
            .windows(2)
            .filter(|w| w[1] - w[0] > DISTINCT_BETA_TOL)
            .count();
        let issue = if distinct < 3 {
            Some("fewer than 3 distinct source positions (beta)")
        } else if sorted[sorted.len() - 1] - sorted[0] < MIN_BETA_SPAN {
            Some("beta range narrower than 3 degrees")
        } else {
            None
        };
        Ok(Self {
            betas: betas.to_vec(),
            terms,
            opts,
            node_n,
            node_k,
            lanes,
            node_curves,
            coarse_i,
            coarse_j,
            stride,
            gc_pad,
            band: if opts.max_candidates > 1 {
                scan::BAND
            } else {
                gc_pad
            },
            coarse_curves,
            coarse_half_norm,
            coarse_base,
            jac,
            issue,
            inv_span: (1.0 / (b.n_max - b.n_min), 1.0 / (b.k_max - b.k_min)),
        })
    }

    /// A plan with the default options.
    pub fn with_defaults(betas: &[f64]) -> Result<Self> {
        Self::new(betas, FitOptions::default())
    }

    /// The angles `β_t` (radians), in measurement order.
    pub fn betas(&self) -> &[f64] {
        &self.betas
    }

    /// Number of measurements `T` per fit.
    pub fn len(&self) -> usize {
        self.betas.len()
    }

    /// Always false (a plan has at least 3 angles).
    pub fn is_empty(&self) -> bool {
        self.betas.is_empty()
    }

    /// The options the plan was built with.
    pub fn options(&self) -> &FitOptions {
        &self.opts
    }

    /// Number of grid nodes scanned per fit.
    pub fn grid_nodes(&self) -> usize {
        self.opts.grid_n * self.opts.grid_k
    }

    /// Scratch memory for [`FitPlan::fit_with`].
    pub fn workspace(&self) -> FitWorkspace {
        let tp = self.lanes.len;
        FitWorkspace {
            bands: vec![scan::BandMin::default(); self.gc_pad.div_ceil(self.band)],
            bands4: vec![scan::BandMin::default(); 4 * (self.gc_pad.div_ceil(self.band))],
            yf4: vec![0.0; 4 * self.len()],
            valid: Vec::new(),
            wall: Vec::new(),
            yf: vec![0.0; tp],
            wf: vec![0.0; tp],
            jobs: Vec::new(),
            spans: Vec::new(),
            outs: Vec::new(),
            lane: engine::LaneScratch::default(),
        }
    }

    /// The cost `Σ w_t (P(n, k, β_t) − y_t)²` (`w_t = 1/se_t²`, or 1).
    pub fn cost(&self, n: f64, k: f64, dolp: &[f64], dolp_se: Option<&[f64]>) -> f64 {
        let mut c = 0.0;
        for (t, (bt, &y)) in self.terms.iter().zip(dolp).enumerate() {
            let r = dop_terms(n, k, bt) - y;
            let w = dolp_se.map_or(1.0, |s| 1.0 / (s[t] * s[t]));
            c += w * r * r;
        }
        c
    }

    /// Cramér–Rao bound at `(n, k)` for this β set and DoLP noise `noise_sd`.
    pub fn crb(&self, n: f64, k: f64, noise_sd: f64) -> Result<Crb> {
        crb(n, k, &self.betas, noise_sd)
    }

    /// Fit one target (allocates a workspace; see [`FitPlan::fit_with`]).
    pub fn fit(&self, dolp: &[f64], dolp_se: Option<&[f64]>) -> Result<NkFit> {
        let mut ws = self.workspace();
        self.fit_with(dolp, dolp_se, &mut ws)
    }

    /// Fit one target with caller-owned scratch memory.
    ///
    /// `dolp[t]` is measured at `betas[t]`; `dolp_se[t]`, when given, is its standard
    /// error (weights `1/se²`). Errors: wrong lengths, non-finite values, DoLP outside
    /// `[0, 1]`, standard errors that are not positive.
    pub fn fit_with(
        &self,
        dolp: &[f64],
        dolp_se: Option<&[f64]>,
        ws: &mut FitWorkspace,
    ) -> Result<NkFit> {
        let t_len = self.len();
        if dolp.len() != t_len {
            return Err(CoreError::LengthMismatch {
                name: "dolp",
                expected: t_len,
                got: dolp.len(),
            });
        }
        if let Some(se) = dolp_se
            && se.len() != t_len
        {
            return Err(CoreError::LengthMismatch {
                name: "dolp_se",
                expected: t_len,
                got: se.len(),
            });
        }
        check_pixel(dolp, dolp_se)?;
        let mut out = [NkFit::default()];
        self.fit_chunk(dolp, dolp_se, &mut out, ws);
        Ok(out[0])
    }

    /// Fit the pixels of one batch chunk: `y` (and `se`) hold `out.len()` rows of `T`
    /// values. Runs [`FitPlan::fit_chunk_body`] compiled for AVX2 + FMA when the CPU has
    /// them.
    fn fit_chunk(&self, y: &[f64], se: Option<&[f64]>, out: &mut [NkFit], ws: &mut FitWorkspace) {
        if ws.bands.len() != self.gc_pad.div_ceil(self.band) || ws.yf.len() != self.lanes.len {
            *ws = self.workspace();
        }
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU supports the features the function is compiled for.
                return unsafe { self.fit_chunk_avx512(y, se, out, ws) };
            }
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU supports the features the function is compiled for.
                return unsafe { self.fit_chunk_avx2(y, se, out, ws) };
            }
        }
        self.fit_chunk_body::<ISA_PORTABLE>(y, se, out, ws)
    }

    /// [`FitPlan::fit_chunk_body`] compiled for AVX-512F (selected at run time).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma")]
    fn fit_chunk_avx512(
        &self,
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut FitWorkspace,
    ) {
        self.fit_chunk_body::<ISA_AVX512>(y, se, out, ws)
    }

    /// [`FitPlan::fit_chunk_body`] compiled for AVX2 + FMA (selected at run time).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn fit_chunk_avx2(
        &self,
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut FitWorkspace,
    ) {
        self.fit_chunk_body::<ISA_AVX2>(y, se, out, ws)
    }

    /// Grid scan and starts of every valid pixel, the polishes of all of them side by
    /// side (`engine.rs`), then the best polish of each pixel and its uncertainties.
    /// `ISA`: the instruction set the caller is compiled for (`ISA_*`).
    #[inline(always)]
    fn fit_chunk_body<const ISA: u8>(
        &self,
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut FitWorkspace,
    ) {
        let t_len = self.len();
        let FitWorkspace {
            bands,
            bands4,
            yf4,
            valid,
            wall,
            yf,
            wf,
            jobs,
            spans,
            outs,
            lane,
        } = ws;
        let wall: Option<&[f64]> = match se {
            Some(se) => {
                wall.clear();
                wall.extend(se.iter().map(|&s| 1.0 / (s * s)));
                Some(&wall[..])
            }
            None => None,
        };
        jobs.clear();
        spans.clear();
        spans.resize(out.len(), (0, 0));
        valid.clear();
        for (p, o) in out.iter_mut().enumerate() {
            let rows = p * t_len..(p + 1) * t_len;
            match check_pixel(&y[rows.clone()], se.map(|s| &s[rows])) {
                Ok(()) => valid.push(p),
                Err(e) => *o = NkFit::invalid(invalid_reason(&e)),
            }
        }
        // Unweighted pixels four at a time (one read of the grid curves per four).
        let quads = if wall.is_none() && ISA != ISA_PORTABLE {
            valid.len() / 4
        } else {
            0
        };
        for q in 0..quads {
            let ps = [
                valid[4 * q],
                valid[4 * q + 1],
                valid[4 * q + 2],
                valid[4 * q + 3],
            ];
            for (i, &p) in ps.iter().enumerate() {
                for t in 0..t_len {
                    yf4[i * t_len + t] = -(y[p * t_len + t] as f32);
                }
            }
            let y4 = [
                &yf4[..t_len],
                &yf4[t_len..2 * t_len],
                &yf4[2 * t_len..3 * t_len],
                &yf4[3 * t_len..4 * t_len],
            ];
            let curves = &self.coarse_curves[..];
            let base = &self.coarse_half_norm[..];
            let nbands = bands.len();
            let mut parts = bands4.chunks_exact_mut(nbands);
            let b4 = [(); 4].map(|_| parts.next().unwrap_or_default());
            match ISA {
                // SAFETY: the caller is compiled for AVX2 + FMA (`fit_chunk_avx2`).
                #[cfg(target_arch = "x86_64")]
                ISA_AVX2 => unsafe { scan::scan4_avx2(curves, base, y4, self.band, b4) },
                // SAFETY: the caller is compiled for AVX-512F (`fit_chunk_avx512`).
                #[cfg(target_arch = "x86_64")]
                ISA_AVX512 => unsafe { scan::scan4_avx512(curves, base, y4, self.band, b4) },
                _ => unreachable!("no four-pixel scan without AVX2"),
            }
            for (i, &p) in ps.iter().enumerate() {
                let first = jobs.len();
                self.pad_pixel(&y[p * t_len..(p + 1) * t_len], None, yf, wf);
                self.queue(
                    p,
                    &bands4[i * nbands..(i + 1) * nbands],
                    &y[p * t_len..(p + 1) * t_len],
                    None,
                    yf,
                    wf,
                    jobs,
                );
                spans[p] = (first, jobs.len() - first);
            }
        }
        for &p in &valid[4 * quads..] {
            let rows = p * t_len..(p + 1) * t_len;
            let first = jobs.len();
            let w = wall.map(|w| &w[rows.clone()]);
            self.pad_pixel(&y[rows.clone()], w, yf, wf);
            self.scan_one::<ISA>(t_len, w.is_some(), yf, wf, bands);
            self.queue(p, bands, &y[rows], w, yf, wf, jobs);
            spans[p] = (first, jobs.len() - first);
        }
        outs.clear();
        outs.resize(jobs.len(), engine::JobOut::default());
        let settings = engine::Settings {
            bounds: self.opts.bounds,
            max_iter: self.opts.max_iter,
            xtol: self.opts.xtol,
            ftol: self.opts.ftol,
        };
        match ISA {
            #[cfg(target_arch = "x86_64")]
            ISA_AVX512 => engine::run::<engine::Avx512>(
                &self.lanes,
                t_len,
                &settings,
                jobs,
                y,
                wall,
                outs,
                lane,
            ),
            #[cfg(target_arch = "x86_64")]
            ISA_AVX2 => engine::run::<engine::Avx2>(
                &self.lanes,
                t_len,
                &settings,
                jobs,
                y,
                wall,
                outs,
                lane,
            ),
            _ => engine::run::<engine::Portable>(
                &self.lanes,
                t_len,
                &settings,
                jobs,
                y,
                wall,
                outs,
                lane,
            ),
        }
        for (p, o) in out.iter_mut().enumerate() {
            let (first, count) = spans[p];
            if count == 0 {
                continue;
            }
            let polished = &outs[first..first + count];
            let mut best = polished[0];
            let (mut iters, mut evals) = (0u32, 0u32);
            for other in polished {
                iters += other.iters;
                evals += other.evals;
                if other.ev.cost < best.ev.cost
                    || (!best.converged
                        && other.converged
                        && other.ev.cost <= best.ev.cost * (1.0 + 1e-9))
                {
                    best = *other;
                }
            }
            let rows = p * t_len..(p + 1) * t_len;
            let mut fit = self.finish(&best, &y[rows.clone()], wall.map(|w| &w[rows]));
            fit.iterations = iters;
            fit.evaluations = evals;
            fit.starts = count as u32;
            *o = fit;
        }
    }

    /// The f32 measurements and weights of one pixel, padded to whole lanes (weight 0
    /// on padding).
    #[inline(always)]
    fn pad_pixel(&self, y: &[f64], w: Option<&[f64]>, yf: &mut [f32], wf: &mut [f32]) {
        let t_len = self.len();
        for t in 0..yf.len() {
            let (yt, wt) = if t < t_len {
                (y[t], w.map_or(1.0, |w| w[t]))
            } else {
                (0.0, 0.0)
            };
            yf[t] = yt as f32;
            wf[t] = wt as f32;
        }
    }

    /// Scan the grid for one pixel (padded f32 data from [`FitPlan::pad_pixel`]):
    /// the best node of every band.
    #[inline(always)]
    fn scan_one<const ISA: u8>(
        &self,
        t_len: usize,
        weighted: bool,
        yf: &[f32],
        wf: &[f32],
        bands: &mut [scan::BandMin],
    ) {
        let base = if weighted {
            &self.coarse_base
        } else {
            &self.coarse_half_norm
        };
        let wf_opt = weighted.then(|| &wf[..t_len]);
        let (curves, yt) = (&self.coarse_curves[..], &yf[..t_len]);
        match ISA {
            // SAFETY: the caller is compiled for AVX2 + FMA (`fit_chunk_avx2`).
            #[cfg(target_arch = "x86_64")]
            ISA_AVX2 => unsafe { scan::scan_avx2(curves, base, yt, wf_opt, self.band, bands) },
            // SAFETY: the caller is compiled for AVX-512F (`fit_chunk_avx512`).
            #[cfg(target_arch = "x86_64")]
            ISA_AVX512 => unsafe { scan::scan_avx512(curves, base, yt, wf_opt, self.band, bands) },
            _ => scan::scan_portable::<false>(curves, base, yt, wf_opt, self.band, bands),
        }
    }

    /// Queue the polishes of pixel `p` from the band minima of its scan: the best
    /// node's, then (with [`FitOptions::max_candidates`] > 1) those of competing
    /// basins: the best nodes of other bands (other `k` ranges) that are not next to
    /// the best node, whose stored-Jacobian Gauss–Newton step stays near them (a
    /// minimum, not a slope into another basin), does not land in the best node's
    /// basin, and predicts a cost within 10% of the best node's prediction.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn queue(
        &self,
        p: usize,
        bands: &[scan::BandMin],
        y: &[f64],
        w: Option<&[f64]>,
        yf: &[f32],
        wf: &[f32],
        jobs: &mut Vec<engine::Job>,
    ) {
        let best = scan::best_of(bands);
        // Every value +∞ or NaN cannot happen for validated data; node 0 then.
        let c0 = if best.node == u32::MAX {
            0
        } else {
            best.node as usize
        };
        let (g0, cost0) = self.refine(c0, yf, wf);
        let (job0, pred0) = self.job(p, g0, cost0, y, w);
        jobs.push(job0);
        if self.opts.max_candidates < 2 {
            return;
        }
        let land0 = self.cell(job0.start.0, job0.start.1);
        let cn = self.coarse_i.len();
        let (i0, j0) = (c0 % cn, c0 / cn);
        let mut extra = 0;
        for bm in bands {
            if bm.node == u32::MAX || bm.node == best.node {
                continue;
            }
            let c = bm.node as usize;
            if (c % cn).abs_diff(i0) <= 2 && (c / cn).abs_diff(j0) <= 2 {
                continue;
            }
            let (g, cost) = self.refine(c, yf, wf);
            let (job, pred) = self.job(p, g, cost, y, w);
            if pred > pred0 * 1.1 + 1e-12 {
                continue;
            }
            let (i, j, _, _) = self.node(g);
            let (i1, j1) = self.cell(job.start.0, job.start.1);
            if i1.abs_diff(i) > 2 || j1.abs_diff(j) > 2 {
                continue;
            }
            if i1.abs_diff(land0.0) <= 2 && j1.abs_diff(land0.1) <= 2 {
                continue;
            }
            jobs.push(job);
            extra += 1;
            if extra + 1 >= self.opts.max_candidates {
                break;
            }
        }
    }

    /// The polish job of pixel `p` from grid node `g` (grid cost `cost`): one
    /// stored-Jacobian Gauss–Newton step gives the start; also the cost that step's
    /// quadratic model predicts.
    #[inline(always)]
    fn job(
        &self,
        p: usize,
        g: usize,
        cost: f32,
        y: &[f64],
        w: Option<&[f64]>,
    ) -> (engine::Job, f64) {
        let b = &self.opts.bounds;
        let k_floor = if b.k_min == 0.0 { lm::K_FLOOR } else { b.k_min };
        let (n1, k1, pred) = self.node_step(g, cost as f64, y, w);
        let (_, _, nn, kk) = self.node(g);
        (
            engine::Job {
                pixel: p,
                start: (n1, k1.max(k_floor)),
                node: (nn, kk.max(k_floor)),
                grid_cost: cost as f64,
            },
            pred,
        )
    }

    /// The best grid node within `stride − 1` grid steps of coarse node `c` (at least
    /// the coarse node itself), and its cost `Σ_t w_t (curve_g(t) − y_t)²` in f32.
    #[inline(always)]
    fn refine(&self, c: usize, yf: &[f32], wf: &[f32]) -> (usize, f32) {
        const L: usize = simd::LANES;
        let tp = self.lanes.len;
        let cn = self.coarse_i.len();
        let (ic, jc) = (self.coarse_i[c % cn], self.coarse_j[c / cn]);
        let h = self.stride.saturating_sub(1);
        let (gn, gk) = (self.opts.grid_n, self.opts.grid_k);
        let (yf, wf) = (&yf[..tp], &wf[..tp]);
        let mut best = (jc * gn + ic, f32::INFINITY);
        for j in jc.saturating_sub(h)..(jc + h + 1).min(gk) {
            for i in ic.saturating_sub(h)..(ic + h + 1).min(gn) {
                let g = j * gn + i;
                let curve = &self.node_curves[g * tp..(g + 1) * tp];
                let mut a = [0f32; L];
                for ch in 0..tp / L {
                    for l in 0..L {
                        let t = ch * L + l;
                        let d = curve[t] - yf[t];
                        a[l] += wf[t] * d * d;
                    }
                }
                let v = (a[0] + a[2]) + (a[1] + a[3]);
                if v < best.1 {
                    best = (g, v);
                }
            }
        }
        best
    }

    /// Grid coordinates of node `g`.
    #[inline]
    fn node(&self, g: usize) -> (usize, usize, f64, f64) {
        let i = g % self.opts.grid_n;
        let j = g / self.opts.grid_n;
        (i, j, self.node_n[i], self.node_k[j])
    }

    /// One Gauss–Newton step from node `g` with its stored Jacobian: the start point
    /// and the cost its quadratic model predicts there.
    #[inline(always)]
    fn node_step(&self, g: usize, cost: f64, y: &[f64], w: Option<&[f64]>) -> (f64, f64, f64) {
        let t_len = self.len();
        let tp = self.lanes.len;
        let (_, _, n, k) = self.node(g);
        let jn = &self.jac[g * 2 * t_len..g * 2 * t_len + t_len];
        let jk = &self.jac[g * 2 * t_len + t_len..(g + 1) * 2 * t_len];
        let curve = &self.node_curves[g * tp..g * tp + t_len];
        let mut ev = Eval {
            cost,
            ..Default::default()
        };
        match w {
            // The same sums with w_t = 1 (bitwise: 1·x = x).
            None => {
                for t in 0..t_len {
                    let r = curve[t] as f64 - y[t];
                    let (a, b) = (jn[t] as f64, jk[t] as f64);
                    ev.h00 += a * a;
                    ev.h01 += a * b;
                    ev.h11 += b * b;
                    ev.g0 += a * r;
                    ev.g1 += b * r;
                }
            }
            Some(w) => {
                for t in 0..t_len {
                    let r = curve[t] as f64 - y[t];
                    let wt = w[t];
                    let (a, b) = (jn[t] as f64, jk[t] as f64);
                    ev.h00 += wt * a * a;
                    ev.h01 += wt * a * b;
                    ev.h11 += wt * b * b;
                    ev.g0 += wt * a * r;
                    ev.g1 += wt * b * r;
                }
            }
        }
        let det = ev.h00 * ev.h11 - ev.h01 * ev.h01;
        let (dn, dk) = if det > 1e-12 * ev.h00 * ev.h11 && det > 0.0 {
            (
                -(ev.h11 * ev.g0 - ev.h01 * ev.g1) / det,
                -(ev.h00 * ev.g1 - ev.h01 * ev.g0) / det,
            )
        } else if ev.h00 > 0.0 {
            (-ev.g0 / ev.h00, 0.0)
        } else {
            (0.0, 0.0)
        };
        let pred = (cost + dn * ev.g0 + dk * ev.g1).max(0.0);
        let b = &self.opts.bounds;
        let k_new = if k < lm::K_U {
            (k * k + dk).clamp(0.0, b.k_max * b.k_max).sqrt()
        } else {
            k + dk
        };
        let (n1, k1) = lm::project(n + dn, k_new, b);
        (n1, k1, pred)
    }

    /// Grid cell (column, row) nearest above `(n, k)`: the first node `≥` the value
    /// along each axis (the last node beyond the box).
    #[inline]
    fn cell(&self, n: f64, k: f64) -> (usize, usize) {
        let b = &self.opts.bounds;
        (
            axis_cell_inv(&self.node_n, b.n_min, self.inv_span.0, n),
            axis_cell_inv(&self.node_k, b.k_min, self.inv_span.1, k),
        )
    }

    /// Standard errors, correlation and status of a polished minimum.
    fn finish(&self, out: &engine::JobOut, y: &[f64], w: Option<&[f64]>) -> NkFit {
        let t_len = self.len();
        let b = &self.opts.bounds;
        let ev = &out.ev;
        let (n, k) = (out.n, out.k);
        // The lane evaluation returns the weighted cost; the rms residual is unweighted.
        let ss = match w {
            Some(_) => lm::eval(&self.terms, y, None, n, k).ss,
            None => ev.cost,
        };
        let s2 = match w {
            Some(_) => 1.0,
            None => ev.cost / (t_len as f64 - 2.0),
        };
        // The u-steps stop at k = K_FLOOR when the lower bound is 0: that is k = 0.
        let k = if b.k_min == 0.0 && k <= lm::K_FLOOR {
            0.0
        } else {
            k
        };
        let mut fit = NkFit {
            n,
            k,
            rms_residual: (ss / t_len as f64).sqrt(),
            cost: ev.cost,
            ..Default::default()
        };
        // Linearised covariance in (n, k).
        let lin = inv2(ev.h00, ev.h01, ev.h11);
        let k_se_lin = lin.map_or(f64::INFINITY, |(_, _, c11)| (c11 * s2).sqrt());
        let use_u = b.k_min == 0.0 && (lin.is_none() || k < k_se_lin);
        let mut singular = false;
        if use_u {
            // (n, u = k²): P depends on k through k² only (eq. 14–15), so
            // ∂P/∂u = (∂P/∂k)/(2k) exactly: the polish's normal equations give the
            // (n, u) ones for k ≥ 1e-4; closer to 0 (where ∂P/∂k vanishes with k),
            // ∂P/∂u by a secant over Δu = 1e-6.
            let (a00, a01, a11) = if out.k >= 1e-4 {
                let s = 0.5 / out.k;
                (ev.h00, ev.h01 * s, ev.h11 * s * s)
            } else {
                let du = 1e-6;
                let k1 = (k * k + du).sqrt();
                let (mut a00, mut a01, mut a11) = (0.0, 0.0, 0.0);
                for (t, bt) in self.terms.iter().enumerate() {
                    let d = dop_grad_terms(n, k, bt);
                    let ju = (dop_terms(n, k1, bt) - d.p) / (k1 * k1 - k * k);
                    let wt = w.map_or(1.0, |w| w[t]);
                    a00 += wt * d.dp_dn * d.dp_dn;
                    a01 += wt * d.dp_dn * ju;
                    a11 += wt * ju * ju;
                }
                (a00, a01, a11)
            };
            match inv2(a00, a01, a11) {
                Some((c00, c01, c11)) => {
                    let se_u = (c11 * s2).sqrt();
                    fit.n_se = (c00 * s2).sqrt();
                    fit.k_se = (k * k + se_u).sqrt() - k;
                    fit.nk_corr = c01 / (c00 * c11).sqrt();
                }
                None => singular = true,
            }
        } else if let Some((c00, c01, c11)) = lin {
            fit.n_se = (c00 * s2).sqrt();
            fit.k_se = (c11 * s2).sqrt();
            fit.nk_corr = c01 / (c00 * c11).sqrt();
        } else {
            singular = true;
        }
        if singular {
            fit.n_se = f64::NAN;
            fit.k_se = f64::NAN;
            fit.nk_corr = f64::NAN;
        }
        let (ymin, ymax) = y
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let (status, reason) = if let Some(r) = self.issue {
            (FitStatus::IllConditioned, r)
        } else if ymax - ymin <= 1e-9 {
            (
                FitStatus::IllConditioned,
                "flat DoLP curve: the same DoLP at every beta",
            )
        } else if singular {
            (
                FitStatus::IllConditioned,
                "singular J^T W J: the DoLP curve does not determine n and k here",
            )
        } else if !out.converged {
            (
                FitStatus::NotConverged,
                "Levenberg-Marquardt did not converge within the iteration limit",
            )
        } else if b.n_min > 0.0 && n <= b.n_min {
            (FitStatus::AtBound, "n at the lower bound of the box")
        } else if n >= b.n_max {
            (FitStatus::AtBound, "n at the upper bound of the box")
        } else if b.k_min > 0.0 && k <= b.k_min {
            (FitStatus::AtBound, "k at the lower bound of the box")
        } else if k >= b.k_max {
            (FitStatus::AtBound, "k at the upper bound of the box")
        } else {
            (FitStatus::Ok, "")
        };
        fit.status = status;
        fit.reason = reason;
        fit
    }
}

/// First index of the quadratically spaced `nodes` (see `warp`) holding a value `≥ x`,
/// at most the last: `nodes.partition_point(|&v| v < x).min(len − 1)`, from the
/// inverse of the spacing and at most a few corrections.
#[cfg(test)]
fn axis_cell(nodes: &[f64], lo: f64, hi: f64, x: f64) -> usize {
    axis_cell_inv(nodes, lo, 1.0 / (hi - lo), x)
}

/// `axis_cell` with the inverse span `1 / (hi − lo)` precomputed (a multiplication
/// instead of a division; the corrections make the result exact either way).
#[inline]
fn axis_cell_inv(nodes: &[f64], lo: f64, inv_span: f64, x: f64) -> usize {
    let m = nodes.len();
    let u = ((x - lo) * inv_span).clamp(0.0, 1.0).sqrt() * (m - 1) as f64;
    let mut i = (u.ceil() as usize).min(m - 1);
    while i > 0 && nodes[i - 1] >= x {
        i -= 1;
    }
    while i < m - 1 && nodes[i] < x {
        i += 1;
    }
    i
}

#[cfg(test)]
mod cell_tests {
    use super::{axis_cell, warp};

    /// The inverse-spacing lookup equals the binary search it replaces.
    #[test]
    fn axis_cell_matches_partition_point() {
        for &(lo, hi, m) in &[(0.01, 10.0, 32), (0.0, 15.0, 32), (0.5, 2.0, 7)] {
            let nodes = warp(lo, hi, m);
            let mut xs: Vec<f64> = (0..5000)
                .map(|i| lo - 0.1 + (hi - lo + 0.2) * i as f64 / 4999.0)
                .collect();
            xs.extend(nodes.iter().copied());
            xs.extend(nodes.iter().map(|v| v * (1.0 + 1e-15)));
            for x in xs {
                let want = nodes.partition_point(|&v| v < x).min(m - 1);
                assert_eq!(axis_cell(&nodes, lo, hi, x), want, "x = {x}");
            }
        }
    }
}

/// Inverse of the symmetric 2×2 `[[a, b], [b, c]]` as `(i00, i01, i11)`, or `None`
/// when it is singular (a zero diagonal or `1 − ρ² < 1e-12`).
fn inv2(a: f64, b: f64, c: f64) -> Option<(f64, f64, f64)> {
    if !(a > 0.0 && c > 0.0) || !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return None;
    }
    let det = a * c - b * b;
    if !(det > 1e-12 * a * c) {
        return None;
    }
    Some((c / det, -b / det, a / det))
}

/// Reason a pixel's data cannot be fitted.
fn check_pixel(dolp: &[f64], dolp_se: Option<&[f64]>) -> Result<()> {
    for &v in dolp {
        crate::error::ensure_range("dolp", v, 0.0, 1.0, "[0, 1]")?;
    }
    if let Some(se) = dolp_se {
        for &s in se {
            crate::error::ensure_finite("dolp_se", s)?;
            if !(s > 0.0) {
                return Err(CoreError::OutOfRange {
                    name: "dolp_se",
                    value: s,
                    expected: "> 0",
                });
            }
        }
    }
    Ok(())
}

fn invalid_reason(e: &CoreError) -> &'static str {
    match e {
        CoreError::NonFinite { name: "dolp", .. } => "non-finite DoLP",
        CoreError::OutOfRange { name: "dolp", .. } => "DoLP outside [0, 1]",
        _ => "non-finite or non-positive DoLP standard error",
    }
}

/// Fit every pixel of a batch in parallel (rayon).
///
/// `dolp` holds `pixels × T` values, row-major (pixel `p`'s measurements at
/// `dolp[p*T .. (p+1)*T]`, in the plan's β order); `dolp_se`, when given, has the same
/// layout; `out` receives one [`NkFit`] per pixel. Pixels with unusable data get the
/// status [`FitStatus::InvalidInput`] (and NaN values) rather than failing the batch.
/// Errors: inconsistent lengths.
pub fn fit_batch(
    plan: &FitPlan,
    dolp: &[f64],
    dolp_se: Option<&[f64]>,
    out: &mut [NkFit],
) -> Result<()> {
    let t_len = plan.len();
    if dolp.len() != out.len() * t_len {
        return Err(CoreError::LengthMismatch {
            name: "dolp",
            expected: out.len() * t_len,
            got: dolp.len(),
        });
    }
    if let Some(se) = dolp_se
        && se.len() != dolp.len()
    {
        return Err(CoreError::LengthMismatch {
            name: "dolp_se",
            expected: dolp.len(),
            got: se.len(),
        });
    }
    const CHUNK: usize = 1024;
    match dolp_se {
        None => out
            .par_chunks_mut(CHUNK)
            .zip(dolp.par_chunks(CHUNK * t_len))
            .for_each_init(
                || plan.workspace(),
                |ws, (o, y)| plan.fit_chunk(y, None, o, ws),
            ),
        Some(se) => out
            .par_chunks_mut(CHUNK)
            .zip(dolp.par_chunks(CHUNK * t_len))
            .zip(se.par_chunks(CHUNK * t_len))
            .for_each_init(
                || plan.workspace(),
                |ws, ((o, y), s)| plan.fit_chunk(y, Some(s), o, ws),
            ),
    }
    Ok(())
}

/// Fit one target with the default options: convenience over
/// [`FitPlan::with_defaults`] + [`FitPlan::fit`] (builds the grid: for many targets
/// with the same β set, build the plan once).
pub fn fit_nk(betas: &[f64], dolp: &[f64], dolp_se: Option<&[f64]>) -> Result<NkFit> {
    if dolp.len() != betas.len() {
        return Err(CoreError::LengthMismatch {
            name: "dolp",
            expected: betas.len(),
            got: dolp.len(),
        });
    }
    FitPlan::with_defaults(betas)?.fit(dolp, dolp_se)
}

#[cfg(test)]
mod isa_tests {
    use super::*;
    use crate::dop::dop;
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};
    use rand_distr::{Distribution, Normal};

    fn data(pixels: usize, t_len: usize, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let betas: Vec<f64> = (0..t_len)
            .map(|i| (40.0 + 30.0 * i as f64 / (t_len - 1) as f64).to_radians())
            .collect();
        let mut rng = StdRng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 0.005).unwrap();
        let mut y = Vec::new();
        let mut se = Vec::new();
        for p in 0..pixels {
            let (n, k) = (rng.random_range(0.2..4.0), rng.random_range(0.0..10.0));
            for (t, &b) in betas.iter().enumerate() {
                y.push((dop(n, k, b) + noise.sample(&mut rng)).clamp(0.0, 1.0));
                se.push(0.004 + 0.001 * ((p + t) % 3) as f64);
            }
        }
        (betas, y, se)
    }

    /// Every kernel the CPU has gives the same fits: AVX2 and AVX-512 bit for bit (the
    /// same fused operations in the same order), the portable kernel (separate
    /// multiply and add) to rounding. Weighted and unweighted, with and without
    /// competing-basin starts, for a pixel count that leaves a remainder after the
    /// four-pixel scans, and for a grid whose bands do not divide it evenly.
    #[test]
    fn kernels_agree() {
        for (opts, t_len) in [
            (FitOptions::default(), 10),
            (
                FitOptions {
                    max_candidates: 3,
                    ..Default::default()
                },
                7,
            ),
            (
                FitOptions {
                    grid_n: 20,
                    grid_k: 22,
                    max_candidates: 2,
                    ..Default::default()
                },
                5,
            ),
        ] {
            let (betas, y, se) = data(203, t_len, 4);
            let plan = FitPlan::new(&betas, opts).unwrap();
            for s in [None, Some(&se[..])] {
                let mut portable = vec![NkFit::default(); 203];
                let mut ws = plan.workspace();
                plan.fit_chunk_body::<ISA_PORTABLE>(&y, s, &mut portable, &mut ws);
                let mut runs = vec![];
                #[cfg(target_arch = "x86_64")]
                {
                    if std::arch::is_x86_feature_detected!("avx2")
                        && std::arch::is_x86_feature_detected!("fma")
                    {
                        let mut o = vec![NkFit::default(); 203];
                        // SAFETY: the CPU has AVX2 + FMA (checked above).
                        unsafe { plan.fit_chunk_avx2(&y, s, &mut o, &mut ws) };
                        runs.push(o);
                    }
                    if std::arch::is_x86_feature_detected!("avx512f")
                        && std::arch::is_x86_feature_detected!("avx2")
                        && std::arch::is_x86_feature_detected!("fma")
                    {
                        let mut o = vec![NkFit::default(); 203];
                        // SAFETY: the CPU has AVX-512F, AVX2 and FMA (checked above).
                        unsafe { plan.fit_chunk_avx512(&y, s, &mut o, &mut ws) };
                        runs.push(o);
                    }
                }
                if runs.len() == 2 {
                    assert_eq!(runs[0], runs[1], "AVX2 and AVX-512 differ");
                }
                for run in &runs {
                    for (p, (a, b)) in run.iter().zip(&portable).enumerate() {
                        assert_eq!(a.status, b.status, "pixel {p}: {a:?} vs {b:?}");
                        let yp = &y[p * t_len..(p + 1) * t_len];
                        let sp = s.map(|s| &s[p * t_len..(p + 1) * t_len]);
                        let (ca, cb) = (plan.cost(a.n, a.k, yp, sp), plan.cost(b.n, b.k, yp, sp));
                        assert!(
                            (ca - cb).abs() <= 1e-9 * ca.max(cb) + 1e-15,
                            "pixel {p}: cost {ca} vs {cb}"
                        );
                    }
                }
            }
        }
    }
}
