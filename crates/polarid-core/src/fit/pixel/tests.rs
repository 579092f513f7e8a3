//! The fit with a β per pixel: equal to the shared-β fit where the angles agree,
//! recovery of `(n, k)` with varying angles, per-pixel statuses, and agreement of the
//! instruction sets.

use super::super::{FitOptions, FitPlan, FitStatus, NkFit, fit_batch};
use super::*;
use crate::cpu::{Isa, cpu_features};
use crate::dop::dop;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};

/// `pixels` pixels with `T` angles: `β_t = 38° + 33° t/(T−1)` plus, per pixel, a
/// smooth offset of up to `±spread` degrees (different at every source position);
/// `(n, k)` uniform in `[0.2, 4] × [0, 10]`, DoLP noise sd 0.005.
#[allow(clippy::type_complexity)]
fn data(
    pixels: usize,
    t_len: usize,
    spread: f64,
    seed: u64,
) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<(f64, f64)>) {
    let mut rng = StdRng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.005).unwrap();
    let (mut b, mut y, mut se, mut truth) = (vec![], vec![], vec![], vec![]);
    for p in 0..pixels {
        let (n, k) = (rng.random_range(0.2..4.0), rng.random_range(0.0..10.0));
        truth.push((n, k));
        let u = p as f64 / pixels as f64;
        for t in 0..t_len {
            let off = spread * (2.0 * u - 1.0) * (1.0 + 0.3 * t as f64).cos();
            let beta = (38.0 + 33.0 * t as f64 / (t_len - 1) as f64 + off).to_radians();
            b.push(beta);
            y.push((dop(n, k, beta) + noise.sample(&mut rng)).clamp(0.0, 1.0));
            // The noise's sd, the last digit varied (the weights are not all equal).
            se.push(0.005 * (1.0 + 1e-3 * ((p + t) % 3) as f64));
        }
    }
    (b, y, se, truth)
}

/// The cost of `(n, k)` at a pixel's own angles.
fn cost(betas: &[f64], y: &[f64], se: Option<&[f64]>, n: f64, k: f64) -> f64 {
    let mut c = 0.0;
    for t in 0..y.len() {
        let r = dop(n, k, betas[t]) - y[t];
        let w = se.map_or(1.0, |s| 1.0 / (s[t] * s[t]));
        c += w * r * r;
    }
    c
}

/// A batch whose pixels all have the same angles gives exactly `fit_batch`'s fits.
#[test]
fn equal_angles_give_fit_batch() {
    let (b, y, se, _) = data(700, 8, 0.0, 1);
    let plan = FitPlan::with_defaults(&b[..8]).unwrap();
    let pp = PixelBetaPlan::with_defaults().unwrap();
    for s in [None, Some(&se[..])] {
        let mut want = vec![NkFit::default(); 700];
        fit_batch(&plan, &y, s, &mut want).unwrap();
        let mut got = vec![NkFit::default(); 700];
        fit_batch_pixel_beta(&pp, &b, &y, s, &mut got).unwrap();
        assert_eq!(got, want);
        // One pixel: the same fit.
        let one = pp
            .fit(&b[16..24], &y[16..24], s.map(|s| &s[16..24]))
            .unwrap();
        assert_eq!(one, want[2]);
    }
}

/// With the angles on the columns' grid (`β = q·Δ`), the per-pixel driver (no
/// shortcut) reads the plan's node curves bit for bit and loads the plan's β terms
/// into every lane: on the portable path (whose grid scan is the same arithmetic),
/// weighted fits are `fit_batch`'s bit for bit; otherwise the same minima, and
/// bitwise the same fits for almost every pixel (a scan of different arithmetic may
/// break a near-tie between grid nodes the other way).
#[test]
fn per_pixel_driver_matches_the_shared_fit_at_equal_angles() {
    let pp = PixelBetaPlan::with_defaults().unwrap();
    let q = BETA_QUANTUM_DEG.to_radians();
    let t_len = 7;
    // 40° + 5.5° t, on the columns' grid.
    let beta: Vec<f64> = (0..t_len)
        .map(|t| ((40.0 + 5.5 * t as f64) / BETA_QUANTUM_DEG).round() * q)
        .collect();
    let plan = FitPlan::with_defaults(&beta).unwrap();
    let (_, y, se, _) = data(600, t_len, 0.0, 2);
    // Fresh noise-free DoLP at these angles would do as well; reuse the noisy data.
    let b: Vec<f64> = (0..600).flat_map(|_| beta.iter().copied()).collect();
    for s in [Some(&se[..]), None] {
        for isa in cpu_features().all() {
            let mut want = vec![NkFit::default(); 600];
            let mut ws = plan.workspace();
            plan.fit_chunk_isa(isa, &y, s, &mut want, &mut ws);
            let mut got = vec![NkFit::default(); 600];
            pp.fit_isa(isa, &b, &y, s, &mut got);
            let same = got.iter().zip(&want).filter(|(a, b)| a == b).count();
            if s.is_some() && matches!(isa, Isa::Portable) {
                assert_eq!(same, 600, "portable weighted");
            }
            assert!(
                same >= 594,
                "{isa:?} weighted {}: {same} of 600",
                s.is_some()
            );
            for (p, (g, w)) in got.iter().zip(&want).enumerate() {
                assert_eq!(g.status, w.status, "pixel {p}");
                let r = p * t_len..(p + 1) * t_len;
                let sp = s.map(|s| &s[r.clone()]);
                let (cg, cw) = (
                    plan.cost(g.n, g.k, &y[r.clone()], sp),
                    plan.cost(w.n, w.k, &y[r.clone()], sp),
                );
                assert!(
                    (cg - cw).abs() <= 1e-9 * cw + 1e-15,
                    "pixel {p}: {cg} vs {cw}"
                );
            }
        }
    }
}

/// Noisy pixels whose angles vary by up to ±6° from pixel to pixel: the fit reaches
/// the global minimum at the pixel's own angles (cost at or below the truth's) for
/// every pixel, and the truth lies within 3 reported standard errors (in `n` and in
/// `k`) as often as with the shared fit on pixels that all have the same angles
/// (96.4% of the `ok` fits there over this wide box, strong metals included: the
/// linearised errors are not exact), within one percentage point; fitting the
/// varying-angle data at one shared set of angles does not.
#[test]
fn recovers_nk_with_varying_angles() {
    let np = 3000;
    let t_len = 8;
    let (b, y, se, truth) = data(np, t_len, 6.0, 3);
    let pp = PixelBetaPlan::with_defaults().unwrap();
    let mut out = vec![NkFit::default(); np];
    fit_batch_pixel_beta(&pp, &b, &y, Some(&se), &mut out).unwrap();
    let (mut ok, mut within, mut global) = (0, 0, 0);
    for (p, (f, &(n, k))) in out.iter().zip(&truth).enumerate() {
        let r = p * t_len..(p + 1) * t_len;
        let s = Some(&se[r.clone()]);
        let c_fit = cost(&b[r.clone()], &y[r.clone()], s, f.n, f.k);
        let c_true = cost(&b[r.clone()], &y[r.clone()], s, n, k);
        global += usize::from(c_fit <= c_true * (1.0 + 1e-9) + 1e-14);
        if f.status == FitStatus::Ok {
            ok += 1;
            within +=
                usize::from((f.n - n).abs() <= 3.0 * f.n_se && (f.k - k).abs() <= 3.0 * f.k_se);
        }
    }
    assert_eq!(global, np, "global minimum");
    assert!(ok >= np * 9 / 10, "{ok} ok of {np}");
    // The same count for the shared fit on data at one set of angles.
    let (b0, y0, se0, truth0) = data(np, t_len, 0.0, 3);
    let plan0 = FitPlan::with_defaults(&b0[..t_len]).unwrap();
    let mut o0 = vec![NkFit::default(); np];
    fit_batch(&plan0, &y0, Some(&se0), &mut o0).unwrap();
    let w0 = o0
        .iter()
        .zip(&truth0)
        .filter(|(f, (n, k))| {
            f.status == FitStatus::Ok
                && (f.n - n).abs() <= 3.0 * f.n_se
                && (f.k - k).abs() <= 3.0 * f.k_se
        })
        .count();
    let ok0 = o0.iter().filter(|f| f.status == FitStatus::Ok).count();
    let (rate, rate0) = (within as f64 / ok as f64, w0 as f64 / ok0 as f64);
    assert!(
        rate >= 0.95 && (rate - rate0).abs() <= 0.01,
        "{within} within 3 SE of {ok}; shared angles: {w0} of {ok0}"
    );
    // The same data at the angles of pixel 0 for everybody: far from the truth.
    let shared = FitPlan::with_defaults(&b[..t_len]).unwrap();
    let mut far = vec![NkFit::default(); np];
    fit_batch(&shared, &y, Some(&se), &mut far).unwrap();
    let within_far = far
        .iter()
        .zip(&truth)
        .filter(|(f, (n, k))| {
            f.status == FitStatus::Ok
                && (f.n - n).abs() <= 3.0 * f.n_se
                && (f.k - k).abs() <= 3.0 * f.k_se
        })
        .count();
    assert!(
        within_far * 2 < within,
        "shared angles: {within_far}, per pixel: {within}"
    );
}

/// Statuses are per pixel: bad angles give `invalid_input`, too few distinct angles
/// or too narrow a span `ill_conditioned` with the shared fit's reasons, in the same
/// batch as good pixels, which are unaffected.
#[test]
fn ill_conditioning_and_bad_angles_are_per_pixel() {
    let t_len = 5;
    let (mut b, y, _, _) = data(40, t_len, 3.0, 4);
    let d = 1.0f64.to_radians();
    let r = |p: usize| p * t_len..(p + 1) * t_len;
    b[r(3)].copy_from_slice(&[0.7, 0.7, 0.7, 0.9, 0.9]);
    b[r(5)].copy_from_slice(&[0.7, 0.7 + 0.5 * d, 0.7 + d, 0.7 + 1.5 * d, 0.7 + 2.0 * d]);
    b[12 * t_len + 2] = f64::NAN;
    b[13 * t_len] = 1.6;
    let pp = PixelBetaPlan::with_defaults().unwrap();
    let mut out = vec![NkFit::default(); 40];
    fit_batch_pixel_beta(&pp, &b, &y, None, &mut out).unwrap();
    assert_eq!(out[3].status, FitStatus::IllConditioned);
    assert_eq!(
        out[3].reason,
        "fewer than 3 distinct source positions (beta)"
    );
    assert_eq!(out[5].status, FitStatus::IllConditioned);
    assert_eq!(out[5].reason, "beta range narrower than 3 degrees");
    for p in [12, 13] {
        assert_eq!(out[p].status, FitStatus::InvalidInput, "pixel {p}");
        assert!(out[p].n.is_nan());
    }
    // The others are as fitted alone in another batch (a pixel's fit does not depend
    // on its batch).
    let good: Vec<usize> = (0..40).filter(|p| ![3, 5, 12, 13].contains(p)).collect();
    let bb: Vec<f64> = good.iter().flat_map(|&p| b[r(p)].to_vec()).collect();
    let yy: Vec<f64> = good.iter().flat_map(|&p| y[r(p)].to_vec()).collect();
    let mut again = vec![NkFit::default(); good.len()];
    fit_batch_pixel_beta(&pp, &bb, &yy, None, &mut again).unwrap();
    for (i, &p) in good.iter().enumerate() {
        assert_eq!(again[i], out[p], "pixel {p}");
        assert_ne!(out[p].status, FitStatus::IllConditioned, "pixel {p}");
    }
    // Lengths.
    let mut one = vec![NkFit::default(); 39];
    assert!(fit_batch_pixel_beta(&pp, &b, &y, None, &mut one).is_err());
    assert!(fit_batch_pixel_beta(&pp, &b[..10], &y, None, &mut out).is_err());
    let mut two = vec![NkFit::default(); 100];
    assert!(matches!(
        fit_batch_pixel_beta(&pp, &b, &y, None, &mut two),
        Err(CoreError::TooFew { .. })
    ));
}

/// Every instruction set gives the same fits with per-pixel angles: AVX2 and AVX-512
/// bit for bit, the portable path the same minima; with competing-basin starts and a
/// grid whose coarse scan skips nodes too.
#[test]
fn kernels_agree_with_per_pixel_angles() {
    for (opts, t_len) in [
        (FitOptions::default(), 6),
        (
            FitOptions {
                max_candidates: 3,
                ..Default::default()
            },
            7,
        ),
        (
            FitOptions {
                grid_n: 70,
                grid_k: 66,
                max_candidates: 2,
                ..Default::default()
            },
            5,
        ),
    ] {
        let (b, y, se, _) = data(203, t_len, 5.0, 5);
        let pp = PixelBetaPlan::new(opts).unwrap();
        for s in [None, Some(&se[..])] {
            let run = |isa| {
                let mut o = vec![NkFit::default(); 203];
                pp.fit_isa(isa, &b, &y, s, &mut o);
                o
            };
            let portable = run(Isa::Portable);
            let runs: Vec<Vec<NkFit>> = cpu_features().all()[1..].iter().map(|&i| run(i)).collect();
            if runs.len() == 2 {
                assert_eq!(runs[0], runs[1], "AVX2 and AVX-512 differ");
            }
            for r in &runs {
                for (p, (a, c)) in r.iter().zip(&portable).enumerate() {
                    assert_eq!(a.status, c.status, "pixel {p}");
                    let rr = p * t_len..(p + 1) * t_len;
                    let sp = s.map(|s| &s[rr.clone()]);
                    let ca = cost(&b[rr.clone()], &y[rr.clone()], sp, a.n, a.k);
                    let cc = cost(&b[rr.clone()], &y[rr.clone()], sp, c.n, c.k);
                    assert!((ca - cc).abs() <= 1e-9 * ca.max(cc) + 1e-15, "pixel {p}");
                }
            }
            // The public entry point runs the detected path.
            let mut batch = vec![NkFit::default(); 203];
            fit_batch_pixel_beta(&pp, &b, &y, s, &mut batch).unwrap();
            assert_eq!(batch, run(cpu_features().best()));
        }
        assert!(pp.cached_columns() > 0);
    }
}

/// The quantum is checked; a coarser one still finds the same minima.
#[test]
fn quantum_option() {
    assert!(
        PixelBetaPlan::with_defaults()
            .unwrap()
            .with_beta_quantum_deg(0.0)
            .is_err()
    );
    assert!(
        PixelBetaPlan::with_defaults()
            .unwrap()
            .with_beta_quantum_deg(2.0)
            .is_err()
    );
    let (b, y, _, _) = data(300, 6, 4.0, 6);
    let fine = PixelBetaPlan::with_defaults()
        .unwrap()
        .with_beta_quantum_deg(0.05)
        .unwrap();
    let coarse = PixelBetaPlan::with_defaults()
        .unwrap()
        .with_beta_quantum_deg(0.5)
        .unwrap();
    assert_eq!(coarse.beta_quantum_deg(), 0.5);
    let mut a = vec![NkFit::default(); 300];
    let mut c = vec![NkFit::default(); 300];
    fit_batch_pixel_beta(&fine, &b, &y, None, &mut a).unwrap();
    fit_batch_pixel_beta(&coarse, &b, &y, None, &mut c).unwrap();
    for (p, (a, c)) in a.iter().zip(&c).enumerate() {
        let r = p * 6..(p + 1) * 6;
        let (ca, cc) = (
            cost(&b[r.clone()], &y[r.clone()], None, a.n, a.k),
            cost(&b[r.clone()], &y[r.clone()], None, c.n, c.k),
        );
        assert!(
            (ca - cc).abs() <= 1e-9 * ca.max(cc) + 1e-15,
            "pixel {p}: {ca} vs {cc}"
        );
    }
}
