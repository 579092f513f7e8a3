//! The [`FitPlan`]: everything a fit needs that depends only on the β set and the
//! options, built once and shared by every pixel. It checks the angles and the
//! options, precomputes the β terms of eq. (9) padded to whole SIMD lanes, the
//! quadratically spaced `(n, k)` grid with every node's DoLP curve (f32) and Jacobian,
//! and the coarse-scan layout (node curves in blocks of `SCAN_BLOCK` nodes, the
//! `½‖curve‖²` of every node, the bands of the competing-basin search); see the
//! module documentation of [`crate::fit`].

use super::FitOptions;
use super::crb::{Crb, crb};
use super::lanes::{self, Lanes};
use super::lm;
use super::scan::{self, SCAN_BLOCK};
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
    pub(super) opts: FitOptions,
    /// `n` of the grid columns.
    pub(super) node_n: Vec<f64>,
    /// `k` of the grid rows.
    pub(super) node_k: Vec<f64>,
    /// β terms padded to whole SIMD lanes.
    pub(super) lanes: Lanes,
    /// DoLP of node `g` at `β_t`: `node_curves[g * lanes.len + t]` (padding: 0).
    pub(super) node_curves: Vec<f32>,
    /// Grid columns of the coarse scan (every `stride`-th, and the last).
    pub(super) coarse_i: Vec<usize>,
    /// Grid rows of the coarse scan.
    pub(super) coarse_j: Vec<usize>,
    /// Spacing of the coarse nodes in grid steps.
    pub(super) stride: usize,
    /// Padded coarse node count (multiple of [`SCAN_BLOCK`]).
    pub(super) gc_pad: usize,
    /// Nodes per band of the scan: [`scan::BAND`] when competing basins are searched
    /// (`max_candidates > 1`), else the whole grid.
    pub(super) band: usize,
    /// DoLP of coarse node `c` (column `c % coarse_i.len()`) at `β_t`:
    /// in blocks of [`SCAN_BLOCK`] nodes, block-major:
    /// `coarse_curves[(c / SCAN_BLOCK * T + t) * SCAN_BLOCK + c % SCAN_BLOCK]` (padding: 0).
    pub(super) coarse_curves: Vec<f32>,
    /// `½ Σ_t curve_c(t)²` of coarse node `c` (padding: +∞): the unweighted scan
    /// ranks nodes by `½‖c‖² − c·y = (cost − ‖y‖²)/2`.
    pub(super) coarse_half_norm: Vec<f32>,
    /// 0 for coarse nodes, +∞ for padding: the start of the weighted scan's sums.
    pub(super) coarse_base: Vec<f32>,
    /// Jacobian of node `g`: `jac[g * 2T + t]` = ∂P/∂n, `jac[g * 2T + T + t]` = ∂P/∂k.
    pub(super) jac: Vec<f32>,
    /// Why every fit with this β set is ill-conditioned, if it is.
    pub(super) issue: Option<&'static str>,
    /// `1 / (n_max − n_min)`, `1 / (k_max − k_min)` (grid cell lookup).
    pub(super) inv_span: (f64, f64),
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
        if !(b.n_max <= lanes::MAX_BOUND && b.k_max <= lanes::MAX_BOUND) {
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

    /// Grid coordinates of node `g`.
    #[inline]
    pub(super) fn node(&self, g: usize) -> (usize, usize, f64, f64) {
        let i = g % self.opts.grid_n;
        let j = g / self.opts.grid_n;
        (i, j, self.node_n[i], self.node_k[j])
    }

    /// Grid cell (column, row) nearest above `(n, k)`: the first node `≥` the value
    /// along each axis (the last node beyond the box).
    #[inline]
    pub(super) fn cell(&self, n: f64, k: f64) -> (usize, usize) {
        let b = &self.opts.bounds;
        (
            axis_cell_inv(&self.node_n, b.n_min, self.inv_span.0, n),
            axis_cell_inv(&self.node_k, b.k_min, self.inv_span.1, k),
        )
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
mod tests {
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
