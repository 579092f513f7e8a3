//! The [`FitPlan`]: everything a fit needs that depends only on the β set and the
//! options, built once and shared by every pixel. It checks the angles and the
//! options, precomputes the β terms of eq. (9) padded to whole SIMD lanes, the
//! quadratically spaced `(n, k)` grid with every node's DoLP curve (f32) and Jacobian,
//! and the coarse-scan layout (node curves in blocks of `SCAN_BLOCK` nodes, the
//! `½‖curve‖²` of every node, the bands of the competing-basin search); see the
//! module documentation of [`crate::fit`].

use super::FitOptions;
use super::crb::{Crb, crb};
use super::grid::Grid;
use super::lanes::Lanes;
use super::lm;
use super::scan::{Groups, SCAN_BLOCK};
use crate::dop::{BetaTerms, dop_grad_terms, dop_terms};
use crate::error::{CoreError, Result};

/// Smallest β span (radians, 3°) below which the fit is flagged ill-conditioned.
pub const MIN_BETA_SPAN: f64 = 3.0 * std::f64::consts::PI / 180.0;
/// Two β closer than this (radians) count as the same angle.
pub const DISTINCT_BETA_TOL: f64 = 1e-6;

/// Everything a fit needs that depends only on the β set and the options: built once,
/// shared (read-only, `Sync`) by every pixel.
#[derive(Debug, Clone)]
pub struct FitPlan {
    pub(super) betas: Vec<f64>,
    pub(super) terms: Vec<BetaTerms>,
    /// The options, the `(n, k)` grid and the coarse-scan layout.
    pub(super) grid: Grid,
    /// β terms padded to whole SIMD lanes.
    pub(super) lanes: Lanes,
    /// DoLP of node `g` at `β_t`: `node_curves[g * lanes.len + t]` (padding: 0).
    pub(super) node_curves: Vec<f32>,
    /// DoLP of coarse node `c` (column `c % coarse_i.len()`) at `β_t`:
    /// in blocks of [`SCAN_BLOCK`] nodes, block-major:
    /// `coarse_curves[(c / SCAN_BLOCK * T + t) * SCAN_BLOCK + c % SCAN_BLOCK]` (padding: 0).
    pub(super) coarse_curves: Vec<f32>,
    /// `½ Σ_t curve_c(t)²` of coarse node `c` (padding: +∞): the unweighted scan
    /// ranks nodes by `½‖c‖² − c·y = (cost − ‖y‖²)/2`.
    pub(super) coarse_half_norm: Vec<f32>,
    /// The coarse nodes in groups for the pruned unweighted scan (`scan/prune.rs`):
    /// only when the whole grid is one band (`max_candidates = 1`) and has at most
    /// `prune::MAX_GROUPS` groups (the default grid has 64).
    pub(super) groups: Option<Groups>,
    /// Jacobian of node `g`: `jac[g * 2T + t]` = ∂P/∂n, `jac[g * 2T + T + t]` = ∂P/∂k.
    pub(super) jac: Vec<f32>,
    /// `JᵀJ` of every node's stored Jacobian and the node's `(n, k)`: `[h00, h01,
    /// h11, n, k]` (the lane starts of `starts.rs`).
    pub(super) start_nodes: Vec<[f64; 5]>,
    /// Why every fit with this β set is ill-conditioned, if it is.
    pub(super) issue: Option<&'static str>,
}

/// Check one angle: finite and in `(0, π/2)`.
pub(super) fn check_beta(b: f64) -> Result<()> {
    crate::error::ensure_finite("beta", b)?;
    if !(b > 0.0 && b < std::f64::consts::FRAC_PI_2) {
        return Err(CoreError::OutOfRange {
            name: "beta",
            value: b,
            expected: "(0, pi/2) radians",
        });
    }
    Ok(())
}

/// Why a fit at the angles `betas` is ill-conditioned, if it is: fewer than 3
/// distinct angles (closer than [`DISTINCT_BETA_TOL`] count as one), or a span below
/// [`MIN_BETA_SPAN`]. `sorted`: scratch memory.
pub(super) fn beta_issue(betas: &[f64], sorted: &mut Vec<f64>) -> Option<&'static str> {
    sorted.clear();
    sorted.extend_from_slice(betas);
    sorted.sort_by(f64::total_cmp);
    let distinct = 1 + sorted
        .windows(2)
        .filter(|w| w[1] - w[0] > DISTINCT_BETA_TOL)
        .count();
    if distinct < 3 {
        Some("fewer than 3 distinct source positions (beta)")
    } else if sorted[sorted.len() - 1] - sorted[0] < MIN_BETA_SPAN {
        Some("beta range narrower than 3 degrees")
    } else {
        None
    }
}

/// Value and second Jacobian column of node `(n, k)` at `bt`, as the plan and the
/// per-pixel columns store them: `(P, ∂P/∂n, ∂P/∂k)`, with `∂P/∂u` (`u = k²`) instead
/// of `∂P/∂k` below [`lm::K_U`] (see `lm::step`).
#[inline]
pub(super) fn node_values(n: f64, k: f64, bt: &BetaTerms) -> (f32, f32, f32) {
    let d = dop_grad_terms(n, k, bt);
    let j2 = if k >= lm::K_U {
        d.dp_dk
    } else if k > 0.0 {
        d.dp_dk / (2.0 * k)
    } else {
        let du: f64 = 1e-6;
        (dop_terms(n, du.sqrt(), bt) - d.p) / du
    };
    (d.p as f32, d.dp_dn as f32, j2 as f32)
}

impl FitPlan {
    /// Build a plan for measurements at local incidence angles `betas` (radians, in
    /// `(0, π/2)`).
    ///
    /// Errors: fewer than 3 angles, a non-finite or out-of-range angle, or invalid
    /// options (empty box, grid smaller than 4 × 4). Fewer than 3 distinct angles or a
    /// span below [`MIN_BETA_SPAN`] is not an error: every fit then carries the status
    /// [`FitStatus::IllConditioned`](super::FitStatus::IllConditioned).
    pub fn new(betas: &[f64], opts: FitOptions) -> Result<Self> {
        if betas.len() < 3 {
            return Err(CoreError::TooFew {
                what: "DoLP measurements (source positions)",
                needed: 3,
                got: betas.len(),
            });
        }
        for &b in betas {
            check_beta(b)?;
        }
        let grid = Grid::new(opts)?;
        let terms: Vec<BetaTerms> = betas.iter().map(|&b| BetaTerms::new(b)).collect();
        let t_len = betas.len();
        let g = grid.nodes();
        let lanes = Lanes::new(&terms);
        let tp = lanes.len;
        let mut node_curves = vec![0f32; g * tp];
        let mut jac = vec![0f32; g * 2 * t_len];
        for (j, &k) in grid.node_k.iter().enumerate() {
            for (i, &n) in grid.node_n.iter().enumerate() {
                let gi = j * opts.grid_n + i;
                for (t, bt) in terms.iter().enumerate() {
                    let (p, jn, j2) = node_values(n, k, bt);
                    node_curves[gi * tp + t] = p;
                    jac[gi * 2 * t_len + t] = jn;
                    jac[gi * 2 * t_len + t_len + t] = j2;
                }
            }
        }
        let gc = grid.coarse_len();
        let gc_pad = grid.gc_pad;
        let mut coarse_curves = vec![0f32; t_len * gc_pad];
        let mut coarse_half_norm = vec![f32::INFINITY; gc_pad];
        for c in 0..gc {
            let gi = grid.coarse_node(c);
            for t in 0..t_len {
                coarse_curves[(c / SCAN_BLOCK * t_len + t) * SCAN_BLOCK + c % SCAN_BLOCK] =
                    node_curves[gi * tp + t];
            }
            let sq: f64 = (0..t_len)
                .map(|t| f64::from(node_curves[gi * tp + t]).powi(2))
                .sum();
            coarse_half_norm[c] = (0.5 * sq) as f32;
        }
        let groups = (grid.band >= gc_pad)
            .then(|| {
                Groups::new(
                    grid.coarse_i.len(),
                    grid.coarse_j.len(),
                    t_len,
                    |c, t| node_curves[grid.coarse_node(c) * tp + t],
                    &coarse_half_norm,
                )
            })
            .flatten();
        let issue = beta_issue(betas, &mut Vec::with_capacity(t_len));
        let start_nodes = super::grid::start_nodes(&grid, &jac, t_len);
        Ok(Self {
            betas: betas.to_vec(),
            terms,
            grid,
            lanes,
            node_curves,
            coarse_curves,
            coarse_half_norm,
            groups,
            jac,
            start_nodes,
            issue,
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
        &self.grid.opts
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
}
