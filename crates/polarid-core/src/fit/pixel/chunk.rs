//! The chunk driver of the fit with a β per pixel: the same steps as the shared-β
//! driver (`fit/chunk.rs`), with every pixel's node curves gathered from the column
//! cache for the scan and the starts, and its exact β terms loaded into its lane of
//! the polish. Instruction sets are dispatched as there.

use super::super::NkFit;
use super::super::chunk::best_polish;
use super::super::engine::{self, LaneTerms};
use super::super::grid::Grid;
use super::super::lanes::{LANES, Lanes};
use super::super::plan::{beta_issue, check_beta};
use super::super::scan::{self, Scan};
use super::super::simd::{Portable, Simd};
use super::super::starts::Nodes;
use super::super::validate::{check_pixel, invalid_reason};
use super::PixelBetaPlan;
use super::columns::{Column, ColumnView};
use crate::cpu::{Isa, cpu_features};
use crate::dop::BetaTerms;

/// Reason of a pixel whose angles cannot be used.
const BAD_BETA: &str = "beta not finite or outside (0, 90) degrees";

/// Per-thread scratch memory of the per-pixel-β fit.
#[derive(Debug, Default)]
pub(super) struct PixelWorkspace {
    bands: Vec<scan::BandMin>,
    valid: Vec<usize>,
    wall: Vec<f64>,
    /// f32 measurements and weights of one pixel, padded to whole lanes.
    yf: Vec<f32>,
    wf: Vec<f32>,
    /// β terms of every pixel of the chunk, row by row.
    terms: Vec<BetaTerms>,
    lane_terms: Vec<LaneTerms>,
    /// Why each pixel's β set is ill-conditioned, if it is.
    issue: Vec<Option<&'static str>>,
    sorted: Vec<f64>,
    /// Column index of every angle of the chunk.
    qs: Vec<usize>,
    jobs: Vec<engine::Job>,
    spans: Vec<(usize, usize)>,
    outs: Vec<engine::JobOut>,
    lane: engine::LaneScratch,
}

impl PixelWorkspace {
    /// Size the buffers for a chunk of `npix` pixels of `t_len` captures (`tp`: padded
    /// to whole lanes; `bands` of the grid) and fill the weights `1/se²` when `se` is
    /// given.
    #[inline(always)]
    fn reset(&mut self, bands: usize, tp: usize, npix: usize, t_len: usize, se: Option<&[f64]>) {
        self.bands.clear();
        self.bands.resize(bands, scan::BandMin::default());
        self.yf.clear();
        self.yf.resize(tp, 0.0);
        self.wf.clear();
        self.wf.resize(tp, 0.0);
        if let Some(se) = se {
            self.wall.clear();
            self.wall.extend(se.iter().map(|&s| 1.0 / (s * s)));
        }
        self.terms.clear();
        self.terms.resize(npix * t_len, BetaTerms::new(0.5));
        self.lane_terms.clear();
        self.lane_terms.resize(npix * t_len, LaneTerms::default());
        self.qs.clear();
        self.qs.resize(npix * t_len, 0);
        self.issue.clear();
        self.issue.resize(npix, None);
        self.jobs.clear();
        self.spans.clear();
        self.spans.resize(npix, (0, 0));
    }
}

/// The node curves of one pixel: row `t` from the column of its `β_t`.
struct PixelNodes<'a> {
    cols: &'a [&'a Column],
    tp: usize,
}

impl Nodes for PixelNodes<'_> {
    #[inline(always)]
    fn t_len(&self) -> usize {
        self.cols.len()
    }
    #[inline(always)]
    fn t_pad(&self) -> usize {
        self.tp
    }
    #[inline(always)]
    fn curve(&self, g: usize, t: usize) -> f32 {
        match self.cols.get(t) {
            Some(c) => c.nodes[g][0],
            None => 0.0,
        }
    }
    #[inline(always)]
    fn jac(&self, g: usize, t: usize) -> (f32, f32) {
        let v = self.cols[t].nodes[g];
        (v[1], v[2])
    }
}

impl PixelBetaPlan {
    /// Fit the pixels of one chunk: `betas`, `y` (and `se`) hold `out.len()` rows of
    /// `T` values; `cols` the columns of every quantised angle the chunk uses. Runs the
    /// instruction set `isa`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn fit_chunk_isa(
        &self,
        isa: Isa,
        cols: &ColumnView,
        betas: &[f64],
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut PixelWorkspace,
    ) {
        match isa {
            // SAFETY: the token `t` proves the CPU has AVX-512F, AVX2 and FMA.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(t) => unsafe { self.fit_chunk_avx512(t, cols, betas, y, se, out, ws) },
            // SAFETY: the token `t` proves the CPU has AVX2 and FMA.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2Fma(t) => unsafe { self.fit_chunk_avx2(t, cols, betas, y, se, out, ws) },
            Isa::Portable => self.fit_chunk_body(Portable, cols, betas, y, se, out, ws),
        }
    }

    /// [`PixelBetaPlan::fit_chunk_isa`] with the detected instruction set.
    pub(super) fn fit_chunk(
        &self,
        cols: &ColumnView,
        betas: &[f64],
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut PixelWorkspace,
    ) {
        self.fit_chunk_isa(cpu_features().best(), cols, betas, y, se, out, ws)
    }

    /// [`PixelBetaPlan::fit_chunk_body`] with the AVX-512 backend, compiled for
    /// AVX-512F.
    ///
    /// # Safety
    /// The CPU has AVX-512F, AVX2 and FMA (the caller holds the token `t`, which
    /// proves it).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn fit_chunk_avx512(
        &self,
        t: crate::cpu::Avx512,
        cols: &ColumnView,
        betas: &[f64],
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut PixelWorkspace,
    ) {
        self.fit_chunk_body(t, cols, betas, y, se, out, ws)
    }

    /// [`PixelBetaPlan::fit_chunk_body`] with the AVX2 backend, compiled for AVX2 +
    /// FMA.
    ///
    /// # Safety
    /// The CPU has AVX2 and FMA (the caller holds the token `t`, which proves it).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn fit_chunk_avx2(
        &self,
        t: crate::cpu::Avx2Fma,
        cols: &ColumnView,
        betas: &[f64],
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut PixelWorkspace,
    ) {
        self.fit_chunk_body(t, cols, betas, y, se, out, ws)
    }

    /// Validation, scan and starts of every pixel with its own columns, the polishes
    /// of all of them side by side with every lane's exact β terms, then the best
    /// polish of each pixel and its uncertainties.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn fit_chunk_body<K: Simd + Scan>(
        &self,
        k: K,
        cols: &ColumnView,
        betas: &[f64],
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut PixelWorkspace,
    ) {
        let grid: &Grid = &self.grid;
        let t_len = if out.is_empty() {
            0
        } else {
            y.len() / out.len()
        };
        let tp = t_len.div_ceil(LANES) * LANES;
        ws.reset(grid.bands(), tp, out.len(), t_len, se);
        self.check_pixels(betas, y, se, out, t_len, ws);
        let wall: Option<&[f64]> = se.map(|_| &ws.wall[..]);
        let PixelWorkspace {
            bands,
            valid,
            yf,
            wf,
            lane_terms,
            qs,
            jobs,
            spans,
            outs,
            lane,
            ..
        } = ws;
        let mut pcols: Vec<&Column> = Vec::with_capacity(t_len);
        let mut rows: Vec<&[f32]> = Vec::with_capacity(t_len);
        for &p in valid.iter() {
            let r = p * t_len..(p + 1) * t_len;
            pcols.clear();
            rows.clear();
            for &q in &qs[r.clone()] {
                // The caller builds the view from the same angles: never missing.
                if let Some(c) = cols.get(q).and_then(Option::as_ref) {
                    pcols.push(c);
                    rows.push(c.coarse());
                }
            }
            if pcols.len() != t_len {
                out[p] = NkFit::invalid("internal error: no beta column");
                continue;
            }
            let w = wall.map(|w| &w[r.clone()]);
            for t in 0..tp {
                let (yt, wt) = if t < t_len {
                    (y[p * t_len + t], w.map_or(1.0, |w| w[t]))
                } else {
                    (0.0, 0.0)
                };
                yf[t] = yt as f32;
                wf[t] = wt as f32;
            }
            let wscan = w.is_some().then_some(&wf[..]);
            k.scan_rows(&rows, &grid.coarse_base, yf, wscan, grid.band, bands);
            let first = jobs.len();
            let nodes = PixelNodes { cols: &pcols, tp };
            grid.queue(&nodes, p, bands, &y[r.clone()], w, yf, wf, jobs);
            spans[p] = (first, jobs.len() - first);
        }
        outs.clear();
        outs.resize(jobs.len(), engine::JobOut::default());
        let settings = engine::Settings::new(&grid.opts);
        engine::run::<K, true>(
            k,
            &Lanes::default(),
            lane_terms,
            t_len,
            &settings,
            jobs,
            y,
            wall,
            outs,
            lane,
        );
        self.finish_pixels(out, y, wall, t_len, ws);
    }

    /// Validate every pixel of the chunk (`out.len()` rows of `t_len` values of `betas`,
    /// `y` and `se`): an invalid pixel gets its invalid fit; a valid one its β terms,
    /// column indices and β-set issue in `ws`, and a place in `ws.valid`.
    #[inline(always)]
    fn check_pixels(
        &self,
        betas: &[f64],
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        t_len: usize,
        ws: &mut PixelWorkspace,
    ) {
        let PixelWorkspace {
            valid,
            terms,
            lane_terms,
            issue,
            sorted,
            qs,
            ..
        } = ws;
        valid.clear();
        for (p, o) in out.iter_mut().enumerate() {
            let rows = p * t_len..(p + 1) * t_len;
            if let Err(e) = check_pixel(&y[rows.clone()], se.map(|s| &s[rows.clone()])) {
                *o = NkFit::invalid(invalid_reason(&e));
                continue;
            }
            let b = &betas[rows.clone()];
            if b.iter().any(|&b| check_beta(b).is_err()) {
                *o = NkFit::invalid(BAD_BETA);
                continue;
            }
            for (t, &bv) in b.iter().enumerate() {
                let bt = BetaTerms::new(bv);
                terms[p * t_len + t] = bt;
                lane_terms[p * t_len + t] = LaneTerms::new(&bt);
                qs[p * t_len + t] = self.column_index(bv);
            }
            issue[p] = beta_issue(b, sorted);
            valid.push(p);
        }
    }

    /// The best polish of every fitted pixel of the chunk and its uncertainties, into
    /// `out` (`wall`: the weights, as the polishes had them).
    #[inline(always)]
    fn finish_pixels(
        &self,
        out: &mut [NkFit],
        y: &[f64],
        wall: Option<&[f64]>,
        t_len: usize,
        ws: &PixelWorkspace,
    ) {
        let grid: &Grid = &self.grid;
        let PixelWorkspace {
            terms,
            issue,
            spans,
            outs,
            ..
        } = ws;
        for (p, o) in out.iter_mut().enumerate() {
            let (first, count) = spans[p];
            if count == 0 {
                continue;
            }
            let (best, iters, evals) = best_polish(&outs[first..first + count]);
            let rows = p * t_len..(p + 1) * t_len;
            let mut fit = grid.finish(
                &terms[rows.clone()],
                issue[p],
                &best,
                &y[rows.clone()],
                wall.map(|w| &w[rows]),
            );
            fit.iterations = iters;
            fit.evaluations = evals;
            fit.starts = count as u32;
            *o = fit;
        }
    }
}
