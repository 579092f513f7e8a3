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
//! 1. **Grid scan** (`scan/`): every node (every `stride`-th along each axis,
//!    `stride = max(1, grid/32)`, then the best node's neighbourhood) is scored in f32,
//!    unweighted as `½‖curve‖² − curve·y` (one multiply-add per node and source
//!    position: 10,240 at the default size and `T = 10`, no transcendental functions),
//!    weighted as `Σ w (curve − y)²`; unweighted pixels are scanned four at a time, so
//!    that each curve vector read serves four pixels (AVX-512: 64 nodes per pass, four
//!    curve loads, four broadcasts and sixteen fused multiply-adds per source
//!    position; AVX2: 16 nodes, two loads, four broadcasts, eight). Vector lanes keep
//!    their running minima and the node holding them; nothing is stored per node.
//!    AVX-512F, AVX2 + FMA or portable kernels, chosen at run time (`cpu.rs`); all give
//!    the same nodes. With one band (`max_candidates = 1`, the default) the AVX-512
//!    kernel prunes (`scan/prune.rs`): the coarse nodes in 4 × 4 groups with a centre
//!    curve and a radius, the centres scored first, then one group, then only the
//!    groups whose triangle-inequality bound (with a margin for every f32 rounding)
//!    does not exceed that group's best value: about 11 of 64 groups per pixel, the
//!    full scan's best node bit for bit, the scan's CPU time ~45% lower. The full-resolution scan is worth its cost: it is ~30% of a
//!    fit's instructions (callgrind, AVX2 path, bench problem of
//!    `examples/fit_throughput.rs`), but a coarser scan gives worse starts and the
//!    polish pays more than the scan saves. Measured on that problem: every second node
//!    along both axes (256 nodes) with the best fine node within 1–3 steps of the best
//!    coarse one raised the polish from 5.9 to 8.2–9.4 evaluations per fit (the best
//!    node lies in a thin curved valley that the coarse nodes straddle: it moved for
//!    25–50% of the pixels, often by 4–11 grid steps); every second node along one axis
//!    (512 nodes) raised it to 7.1 and the instructions per fit from 8,646 to 9,082.
//! 2. **Start**: one Gauss–Newton step from the best node with its stored Jacobian (no
//!    model evaluation); the node itself if that start turns out worse. Unweighted,
//!    with one start per pixel, a node's `JᵀJ` is taken from the plan, only the
//!    gradient is summed per pixel, and the step is taken for sixteen pixels at once
//!    in branch-free vector lanes (`starts.rs`; bit for bit the scalar step).
//! 3. **Polish** (`engine.rs`): Levenberg–Marquardt with the analytic Jacobian, 2×2
//!    normal equations in closed form and Marquardt scaling, run for sixteen fits side
//!    by side, one per SIMD lane (two f64x8 or four f64x4 vectors): the `T` values and
//!    gradients of eq. (9) are straight vector arithmetic, the step, accept/reject and
//!    stopping rules are branch-free lane code, and a lane whose fit ends takes the next
//!    fit of the batch at once. A fit's trial points do not depend on its neighbours,
//!    so a pixel gets the same result in any batch and from [`FitPlan::fit`]. For
//!    `k ≥ 1` a step `δN` (`N = n + ik`) is taken along the straight line through
//!    `1/N`, `N' = N²/(N − δN)` (the same step to first order; `lm::arc_step`), and so
//!    is the start: for strongly absorbing media eq. (9) depends to first order in
//!    `1/|N|` on `Re(1/N)` only, so the long curved valleys of χ² of metals (`n ∝ k²`
//!    along the valley) are nearly straight in `1/N`, where Gauss–Newton follows them
//!    instead of overshooting. The polish stops without a further evaluation once the
//!    Gauss–Newton model predicts a relative decrease below `ftol`: on average 3.95
//!    evaluations at `T = 10`, noise sd 0.005, `(n, k)` uniform in `[0.3, 3] × [0, 8]`
//!    (5.75 with straight steps in `(n, k)`; 3–4 for 86% of the fits).
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
//! # A β per pixel
//! With calibrated geometry every pixel has its own angles; [`fit_batch_pixel_beta`]
//! with a [`PixelBetaPlan`] fits such batches by the same method and rules: the scan
//! reads the node curves of each pixel from a cache of *columns* (the grid at one
//! quantised angle, [`BETA_QUANTUM_DEG`]) and only picks the basin; the polish loads
//! each pixel's exact β terms into its lane (see the `pixel` module's documentation).
//!
//! # Uncertainty
//! The covariance is `(JᵀWJ)⁻¹`, multiplied by the reduced χ² `χ²/(T − 2)` when no
//! standard errors are given. Near `k = 0` the model depends on `k` only through `k²`
//! (eq. 14–15), so `∂P/∂k → 0` and the linearised error of `k` diverges; when the
//! linearised interval on `k` reaches 0, the covariance is computed in `(n, u = k²)`
//! and `k_se = √(k² + se_u) − k` (the one-sigma upper deviation).
//!
//! # Files
//! One responsibility per file:
//!
//! | file            | contents                                                          |
//! |-----------------|-------------------------------------------------------------------|
//! | `options.rs`    | [`FitBounds`], [`FitOptions`]                                     |
//! | `result.rs`     | [`NkFit`] (the status type is [`crate::status::FitStatus`])       |
//! | `grid.rs`       | the `(n, k)` grid and the scan layout (options only, no angles)   |
//! | `plan.rs`       | [`FitPlan`]: angle checks, node curves and Jacobians of a β set   |
//! | `scan/`         | the grid scan, one kernel file per instruction set                |
//! | `starts.rs`     | grid refinement, stored-Jacobian starts, competing basins         |
//! | `engine.rs`     | the lane-parallel Levenberg–Marquardt polishes (shared or per-lane β) |
//! | `simd/`         | the engine's vector operations, one backend file per instruction set |
//! | `lanes.rs`      | the β terms padded to whole lanes                                 |
//! | `lm.rs`         | scalar cost, normal equations and damped step                     |
//! | `covariance.rs` | standard errors, correlation and status of a minimum              |
//! | `validate.rs`   | validation of a pixel's measurements                              |
//! | `chunk.rs`      | the chunk driver and its instruction-set dispatch                 |
//! | `single.rs`     | [`FitPlan::fit`], [`FitPlan::fit_with`], [`fit_nk`]               |
//! | `batch.rs`      | [`fit_batch`] (rayon)                                             |
//! | `pixel/`        | [`PixelBetaPlan`], [`fit_batch_pixel_beta`]: a β per pixel (column cache, chunk driver) |
//! | `crb.rs`        | the Cramér–Rao bound ([`crb()`], [`Crb`])                           |
//!
//! # Reference
//! - R. Thilak, C. D. Creusere and D. G. Voelz, "Material classification using passive
//!   polarimetric imagery", *Proc. IEEE ICIP 2007*: the model, eq. (9), and the
//!   inversion, eq. (16).
//! - K. Levenberg, "A method for the solution of certain non-linear problems in least
//!   squares", *Quarterly of Applied Mathematics* 2(2), 164–168, 1944; D. W. Marquardt,
//!   "An algorithm for least-squares estimation of nonlinear parameters", *Journal of
//!   the SIAM* 11(2), 431–441, 1963: the damped Gauss–Newton polish with the scaling
//!   `H + λ diag H`.
//! - J. J. Moré, "The Levenberg–Marquardt algorithm: implementation and theory",
//!   *Numerical Analysis*, Lecture Notes in Mathematics 630, 105–116, Springer, 1978:
//!   the stopping rules on the relative step and the predicted relative decrease.

mod batch;
mod chunk;
mod covariance;
mod crb;
mod engine;
mod grid;
#[cfg(test)]
mod isa_tests;
mod lanes;
mod lm;
mod options;
mod pixel;
mod plan;
mod result;
mod scan;
mod simd;
mod single;
mod starts;
mod validate;

pub use crate::status::FitStatus;
pub use batch::fit_batch;
pub use chunk::FitWorkspace;
pub(crate) use covariance::inv2;
pub use crb::{Crb, crb, crb_weighted};
pub use options::{FitBounds, FitOptions};
pub use pixel::{BETA_QUANTUM_DEG, PixelBetaPlan, fit_batch_pixel_beta};
pub use plan::{DISTINCT_BETA_TOL, FitPlan, MIN_BETA_SPAN};
pub use result::NkFit;
pub use single::fit_nk;
