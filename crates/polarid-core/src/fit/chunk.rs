//! The chunk driver: grid scan and starts of every valid pixel of a chunk, the
//! polishes of all of them side by side (`engine.rs`), then the best polish of each
//! pixel and its uncertainties (`covariance.rs`).
//!
//! # Instruction sets
//! [`FitPlan::fit_chunk`] asks [`cpu_features`] for the widest instruction set and runs
//! the generic body with that backend: the token of [`crate::cpu`] for AVX-512F or
//! AVX2 + FMA, [`Portable`] otherwise. For a vector backend the body is inlined into an
//! `unsafe fn` compiled with `#[target_feature(enable = ...)]` for its features, so the
//! scan kernels and the engine (all `#[inline(always)]`) become vector code; the call
//! is sound because the caller holds the token that proves the CPU has them.

use super::covariance::FinishLanes;
use super::engine;
use super::scan::{self, Scan};
use super::simd::{Portable, Simd};
use super::starts;
use super::validate::{check_pixel, invalid_reason};
use super::{FitPlan, NkFit};
use crate::cpu::{Isa, cpu_features};

/// The best of the polishes of one pixel (the lowest cost; a converged polish over one
/// that is not when their costs agree to 1e-9), and the iterations and evaluations of
/// all of them.
#[inline(always)]
pub(super) fn best_polish(polished: &[engine::JobOut]) -> (engine::JobOut, u32, u32) {
    let (best, iters, evals) = best_index(polished);
    (polished[best], iters, evals)
}

/// [`best_polish`] as the index of the best polish in `polished`.
#[inline(always)]
fn best_index(polished: &[engine::JobOut]) -> (usize, u32, u32) {
    let mut best = 0;
    let (mut iters, mut evals) = (0u32, 0u32);
    for (i, other) in polished.iter().enumerate() {
        iters += other.iters;
        evals += other.evals;
        let b = &polished[best];
        if other.ev.cost < b.ev.cost
            || (!b.converged && other.converged && other.ev.cost <= b.ev.cost * (1.0 + 1e-9))
        {
            best = i;
        }
    }
    (best, iters, evals)
}

/// Validate every pixel of a chunk (`out.len()` rows of `t_len` values of `y` and
/// `se`): an invalid pixel gets its invalid fit, a valid one a place in `valid`.
#[inline(always)]
fn check_chunk(
    t_len: usize,
    y: &[f64],
    se: Option<&[f64]>,
    out: &mut [NkFit],
    valid: &mut Vec<usize>,
) {
    valid.clear();
    for (p, o) in out.iter_mut().enumerate() {
        let rows = p * t_len..(p + 1) * t_len;
        match check_pixel(&y[rows.clone()], se.map(|s| &s[rows])) {
            Ok(()) => valid.push(p),
            Err(e) => *o = NkFit::invalid(invalid_reason(&e)),
        }
    }
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
    /// Best nodes and gradients of the pixels whose starts are taken in lanes.
    sums: Vec<starts::StartSums>,
    /// Results of the polishes.
    outs: Vec<engine::JobOut>,
    /// Lane-major measurements of the polishes in flight.
    lane: engine::LaneScratch,
}

impl FitPlan {
    /// Scratch memory for [`FitPlan::fit_with`].
    pub fn workspace(&self) -> FitWorkspace {
        let tp = self.lanes.len;
        FitWorkspace {
            bands: vec![scan::BandMin::default(); self.grid.bands()],
            bands4: vec![scan::BandMin::default(); 4 * self.grid.bands()],
            yf4: vec![0.0; 4 * self.len()],
            valid: Vec::new(),
            wall: Vec::new(),
            yf: vec![0.0; tp],
            wf: vec![0.0; tp],
            jobs: Vec::new(),
            spans: Vec::new(),
            sums: Vec::new(),
            outs: Vec::new(),
            lane: engine::LaneScratch::default(),
        }
    }

    /// Fit the pixels of one batch chunk: `y` (and `se`) hold `out.len()` rows of `T`
    /// values. Runs the widest instruction set the CPU has ([`cpu_features`]).
    pub(super) fn fit_chunk(
        &self,
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut FitWorkspace,
    ) {
        self.fit_chunk_isa(cpu_features().best(), y, se, out, ws)
    }

    /// [`FitPlan::fit_chunk`] with the instruction set `isa` (tests compare them).
    pub(super) fn fit_chunk_isa(
        &self,
        isa: Isa,
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut FitWorkspace,
    ) {
        if ws.bands.len() != self.grid.bands() || ws.yf.len() != self.lanes.len {
            *ws = self.workspace();
        }
        match isa {
            // SAFETY: the token `t` proves the CPU has AVX-512F, AVX2 and FMA.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(t) => unsafe { self.fit_chunk_avx512(t, y, se, out, ws) },
            // SAFETY: the token `t` proves the CPU has AVX2 and FMA.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2Fma(t) => unsafe { self.fit_chunk_avx2(t, y, se, out, ws) },
            Isa::Portable => self.fit_chunk_body(Portable, y, se, out, ws),
        }
    }

    /// [`FitPlan::fit_chunk_body`] with the AVX-512 backend, compiled for AVX-512F.
    ///
    /// # Safety
    /// The CPU has AVX-512F, AVX2 and FMA (the caller holds the token `t`, which
    /// proves it).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma")]
    unsafe fn fit_chunk_avx512(
        &self,
        t: crate::cpu::Avx512,
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut FitWorkspace,
    ) {
        self.fit_chunk_body(t, y, se, out, ws)
    }

    /// [`FitPlan::fit_chunk_body`] with the AVX2 backend, compiled for AVX2 + FMA.
    ///
    /// # Safety
    /// The CPU has AVX2 and FMA (the caller holds the token `t`, which proves it).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn fit_chunk_avx2(
        &self,
        t: crate::cpu::Avx2Fma,
        y: &[f64],
        se: Option<&[f64]>,
        out: &mut [NkFit],
        ws: &mut FitWorkspace,
    ) {
        self.fit_chunk_body(t, y, se, out, ws)
    }

    /// Grid scan and starts of every valid pixel, the polishes of all of them side by
    /// side (`engine.rs`), then the best polish of each pixel and its uncertainties.
    /// `k`: the backend (scan kernels and engine operations) of the instruction set
    /// the caller is compiled for.
    #[inline(always)]
    fn fit_chunk_body<K: Simd + Scan>(
        &self,
        k: K,
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
            sums,
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
        sums.clear();
        // Unweighted one-start pixels: starts in lanes after the scans (no padded
        // f32 copy of the pixel needed for them).
        let in_lanes = wall.is_none() && self.lane_starts();
        spans.clear();
        spans.resize(out.len(), (0, 0));
        check_chunk(t_len, y, se, out, valid);
        // Unweighted pixels four at a time (one read of the grid curves per four).
        let quads = if wall.is_none() && K::FOUR {
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
            let nbands = bands.len();
            self.scan_quad(k, ps, y, yf4, bands4, nbands);
            if in_lanes {
                for (i, &p) in ps.iter().enumerate() {
                    sums.push(self.start_sums::<true>(
                        p,
                        &bands4[i * nbands..(i + 1) * nbands],
                        &yf4[i * t_len..(i + 1) * t_len],
                        &y[p * t_len..(p + 1) * t_len],
                    ));
                }
                continue;
            }
            for (i, &p) in ps.iter().enumerate() {
                let first = jobs.len();
                self.pad_pixel(&y[p * t_len..(p + 1) * t_len], None, yf, wf);
                self.grid.queue(
                    self,
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
            self.scan_one(k, t_len, w.is_some(), yf, wf, bands);
            if in_lanes {
                sums.push(self.start_sums::<false>(p, bands, yf, &y[rows]));
                continue;
            }
            self.grid.queue(self, p, bands, &y[rows], w, yf, wf, jobs);
            spans[p] = (first, jobs.len() - first);
        }
        if in_lanes {
            self.push_starts(k, sums, jobs, spans);
        }
        outs.clear();
        outs.resize(jobs.len(), engine::JobOut::default());
        let settings = engine::Settings::new(&self.grid.opts);
        engine::run::<K, false>(
            k,
            &self.lanes,
            &[],
            t_len,
            &settings,
            jobs,
            y,
            wall,
            outs,
            lane,
        );
        self.finish_chunk(k, spans, outs, y, wall, out);
    }

    /// The grid scans of the four unweighted pixels `ps` (one read of the grid curves
    /// per four): their negated f32 measurements into `yf4`, their band minima into
    /// `bands4` (`nbands` each).
    #[inline(always)]
    fn scan_quad<K: Simd + Scan>(
        &self,
        k: K,
        ps: [usize; 4],
        y: &[f64],
        yf4: &mut [f32],
        bands4: &mut [scan::BandMin],
        nbands: usize,
    ) {
        let t_len = self.len();
        for (dst, &p) in yf4.chunks_exact_mut(t_len).zip(&ps) {
            for (d, &v) in dst.iter_mut().zip(&y[p * t_len..(p + 1) * t_len]) {
                *d = -(v as f32);
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
        let mut parts = bands4.chunks_exact_mut(nbands);
        let b4 = [(); 4].map(|_| parts.next().unwrap_or_default());
        let groups = self.groups.as_ref();
        scan::scan4_grid(k, groups, curves, base, y4, self.grid.band, b4);
    }

    /// The best of the polishes `outs` of every fitted pixel (`spans`: its first job
    /// and number of jobs), its uncertainties and status, into `out`.
    #[inline(always)]
    fn finish_chunk<K: Simd>(
        &self,
        k: K,
        spans: &[(usize, usize)],
        outs: &[engine::JobOut],
        y: &[f64],
        wall: Option<&[f64]>,
        out: &mut [NkFit],
    ) {
        // The best polish of every fitted pixel, its uncertainties and status W
        // pixels at a time in the vector lanes (`covariance.rs`).
        let mut fin = FinishLanes::default();
        for (p, &(first, count)) in spans.iter().enumerate() {
            if count == 0 {
                continue;
            }
            let (best, iters, evals) = best_index(&outs[first..first + count]);
            fin.push(
                p,
                first + best,
                &outs[first + best],
                iters,
                evals,
                count as u32,
            );
            if fin.is_full() {
                self.finish_lanes(k, &mut fin, outs, y, wall, out);
            }
        }
        if !fin.is_empty() {
            self.finish_lanes(k, &mut fin, outs, y, wall, out);
        }
    }

    /// The f32 measurements and weights of one pixel, padded to whole lanes (weight 0
    /// on padding).
    #[inline(always)]
    fn pad_pixel(&self, y: &[f64], w: Option<&[f64]>, yf: &mut [f32], wf: &mut [f32]) {
        let t_len = self.len();
        let (yd, yp) = yf.split_at_mut(t_len);
        let (wd, wp) = wf.split_at_mut(t_len);
        for (d, &v) in yd.iter_mut().zip(y) {
            *d = v as f32;
        }
        match w {
            Some(w) => {
                for (d, &v) in wd.iter_mut().zip(w) {
                    *d = v as f32;
                }
            }
            None => wd.fill(1.0),
        }
        yp.fill(0.0);
        wp.fill(0.0);
    }

    /// Scan the grid for one pixel (padded f32 data from [`FitPlan::pad_pixel`]):
    /// the best node of every band.
    #[inline(always)]
    fn scan_one<K: Scan>(
        &self,
        k: K,
        t_len: usize,
        weighted: bool,
        yf: &[f32],
        wf: &[f32],
        bands: &mut [scan::BandMin],
    ) {
        let base = if weighted {
            &self.grid.coarse_base
        } else {
            &self.coarse_half_norm
        };
        let wf_opt = weighted.then(|| &wf[..t_len]);
        let (curves, yt) = (&self.coarse_curves[..], &yf[..t_len]);
        k.scan(curves, base, yt, wf_opt, self.grid.band, bands);
    }
}
