//! docs/BANDS.md, "The surface-layer allowance over bands (measured)": how far a 3 nm
//! surface layer of each error-model index moves the fitted `(n, k)` of gold and copper in
//! each band (linearised `h = A g` and a nonlinear refit) at the acceptance geometry,
//! whether ONE layer (one thickness in all bands) can carry one metal onto the other, and
//! the Mahalanobis distance of gold to copper with the per-band and the correlated
//! allowance. `cargo run --release -p polarid-core --example film_bands`.
#![allow(clippy::needless_range_loop, clippy::useless_vec)]

use polarid_core::dop::{dop, dop_grad};
use polarid_core::film::thin_film;
use polarid_core::systematic::{FILM_INDICES, Polarimetric, propagate, systematic_covariance};

const BANDS: [(f64, f64); 3] = [(450.0, 0.006), (550.0, 0.004), (650.0, 0.003)];
const GOLD: [(f64, f64); 3] = [
    (1.3583691243033487, 1.9035719845799093),
    (0.458220595924015, 2.4622677304841325),
    (0.16419903260653093, 3.5963204013331405),
];
const COPPER: [(f64, f64); 3] = [
    (1.2495336463140794, 2.3846575479531245),
    (0.9667875692138905, 2.6309649788092493),
    (0.250764626832477, 3.6109197426499264),
];

fn betas() -> Vec<f64> {
    (0..8)
        .map(|i| (0.5 * (30.0 + 7.0 * i as f64 + 60.0)).to_radians())
        .collect()
}

fn inv2(m: [f64; 3]) -> [f64; 3] {
    let d = m[0] * m[2] - m[1] * m[1];
    [m[2] / d, -m[1] / d, m[0] / d]
}

/// A (2×T) and noise cov (JᵀWJ)⁻¹
fn lin(n: f64, k: f64, sd: f64) -> (Vec<[f64; 2]>, [f64; 3]) {
    let b = betas();
    let w = 1.0 / (sd * sd);
    let g: Vec<_> = b.iter().map(|&x| dop_grad(n, k, x)).collect();
    let mut h = [0.0; 3];
    for q in &g {
        h[0] += w * q.dp_dn * q.dp_dn;
        h[1] += w * q.dp_dn * q.dp_dk;
        h[2] += w * q.dp_dk * q.dp_dk;
    }
    let i = inv2(h);
    let a = g
        .iter()
        .map(|q| {
            [
                w * (i[0] * q.dp_dn + i[1] * q.dp_dk),
                w * (i[1] * q.dp_dn + i[2] * q.dp_dk),
            ]
        })
        .collect();
    (a, i)
}

/// nonlinear GN fit of (n,k) to data y
fn fit(y: &[f64], n0: f64, k0: f64) -> (f64, f64) {
    let b = betas();
    let (mut n, mut k) = (n0, k0);
    for _ in 0..50 {
        let mut h = [0.0; 3];
        let mut r0 = 0.0;
        let mut r1 = 0.0;
        for (t, &x) in b.iter().enumerate() {
            let g = dop_grad(n, k, x);
            let r = y[t] - g.p;
            h[0] += g.dp_dn * g.dp_dn;
            h[1] += g.dp_dn * g.dp_dk;
            h[2] += g.dp_dk * g.dp_dk;
            r0 += g.dp_dn * r;
            r1 += g.dp_dk * r;
        }
        let i = inv2(h);
        n += i[0] * r0 + i[1] * r1;
        k += i[1] * r0 + i[2] * r1;
    }
    (n, k)
}

fn film_dolp(nk: (f64, f64), film: (f64, f64), d_nm: f64, wl: f64) -> Vec<f64> {
    betas()
        .iter()
        .map(|&b| {
            thin_film(film, d_nm / wl, nk, b, 1.0)
                .unwrap()
                .signed_dolp()
        })
        .collect()
}

fn main() {
    let b = betas();
    println!(
        "betas deg {:?}",
        b.iter().map(|x| x.to_degrees()).collect::<Vec<_>>()
    );
    for (name, m) in [("gold", GOLD), ("copper", COPPER)] {
        println!("== {name}");
        for (bi, &(wl, sd)) in BANDS.iter().enumerate() {
            let (n, k) = m[bi];
            let (a, nc) = lin(n, k, sd);
            let p: Vec<f64> = b.iter().map(|&x| dop(n, k, x)).collect();
            print!(
                "{wl} nm: (n,k)=({n:.3},{k:.3}) noise se=({:.4},{:.4}) cu-au=({:+.3},{:+.3})",
                nc[0].sqrt(),
                nc[2].sqrt(),
                COPPER[bi].0 - GOLD[bi].0,
                COPPER[bi].1 - GOLD[bi].1
            );
            println!();
            for &f in &FILM_INDICES {
                let y = film_dolp((n, k), f, 3.0, wl);
                let g: Vec<f64> = y.iter().zip(&p).map(|(a, b)| a - b).collect();
                let hn: f64 = a.iter().zip(&g).map(|(r, x)| r[0] * x).sum();
                let hk: f64 = a.iter().zip(&g).map(|(r, x)| r[1] * x).sum();
                let (fnn, fk) = fit(&y, n, k);
                println!(
                    "   film {:?}: lin dn,dk = ({hn:+.4},{hk:+.4})  nonlin ({:+.4},{:+.4})  max|g|={:.4}",
                    f,
                    fnn - n,
                    fk - k,
                    g.iter().fold(0.0f64, |m, x| m.max(x.abs()))
                );
            }
        }
    }
    // Nonlinear: gold + film (index j, thickness d, same in all bands) fitted per band vs copper.
    for (from, to, label) in [
        (GOLD, COPPER, "gold + one layer vs copper"),
        (COPPER, GOLD, "copper + one layer vs gold"),
    ] {
        println!("== {label}: chi2 over bands (2x noise cov, per band)");
        for &f in &FILM_INDICES {
            let mut best = (f64::INFINITY, 0.0, [0.0; 3]);
            let mut best_band = [(f64::INFINITY, 0.0); 3];
            for di in 0..=400 {
                let d = di as f64 * 0.05;
                let mut tot = 0.0;
                let mut per = [0.0; 3];
                for (bi, &(wl, sd)) in BANDS.iter().enumerate() {
                    let (n, k) = from[bi];
                    let y = film_dolp((n, k), f, d, wl);
                    let (fnn, fk) = fit(&y, n, k);
                    let (_, nc) = lin(to[bi].0, to[bi].1, sd);
                    // 2x noise cov (estimate + trained prototype)
                    let c = [2.0 * nc[0], 2.0 * nc[1], 2.0 * nc[2]];
                    let i = inv2(c);
                    let (dn, dk) = (fnn - to[bi].0, fk - to[bi].1);
                    let q = i[0] * dn * dn + 2.0 * i[1] * dn * dk + i[2] * dk * dk;
                    per[bi] = q;
                    tot += q;
                    if q < best_band[bi].0 {
                        best_band[bi] = (q, d);
                    }
                }
                if tot < best.0 {
                    best = (tot, d, per);
                }
            }
            println!(
                "  film {:?}: best common d = {:.2} nm chi2 = {:.1} (per band {:.1} {:.1} {:.1}); per-band best d: {:?}",
                f, best.1, best.0, best.2[0], best.2[1], best.2[2], best_band
            );
        }
    }
    // Covariance comparison with the default error model (angles 0.2 deg, floor .002, ER 100, film 3 nm).
    println!(
        "== d_M^2 gold estimate vs copper (library point, no proto cov): block-diag film vs correlated"
    );
    let mut q_block = 0.0;
    let mut q_none = 0.0;
    let mut stack_h = vec![[[0.0f64; 2]; 3]; 3]; // [band][film][n,k]
    let mut base = vec![[0.0f64; 3]; 3];
    for (bi, &(wl, sd)) in BANDS.iter().enumerate() {
        let (n, k) = GOLD[bi];
        let t = b.len();
        let ang = vec![0.2f64.to_radians(); t];
        let mk = |film: f64| {
            let pol = Polarimetric {
                dolp_floor: 0.002,
                extinction_ratio: 100.0,
                retardance: 0.0,
                film_sd_waves: film / wl,
            };
            let mut s = vec![0.0; t * t];
            systematic_covariance(n, k, &b, &ang, &pol, &mut s).unwrap();
            let r = vec![0.0; t];
            let se = vec![sd; t];
            let pr = propagate(n, k, &b, &r, Some(&se), &s, false).unwrap();
            pr.total
        };
        let tot3 = mk(3.0);
        let tot0 = mk(0.0);
        let cv = |c: polarid_core::systematic::NkCov| {
            [
                c.n_se * c.n_se,
                c.nk_corr * c.n_se * c.k_se,
                c.k_se * c.k_se,
            ]
        };
        let c3 = cv(tot3);
        let c0 = cv(tot0);
        let (dn, dk) = (COPPER[bi].0 - n, COPPER[bi].1 - k);
        let q = |c: [f64; 3]| {
            let i = inv2(c);
            i[0] * dn * dn + 2.0 * i[1] * dn * dk + i[2] * dk * dk
        };
        println!(
            "  {wl}: total se film3 ({:.4},{:.4}) film0 ({:.4},{:.4}); d2 film3 {:.1} film0 {:.1}",
            tot3.n_se,
            tot3.k_se,
            tot0.n_se,
            tot0.k_se,
            q(c3),
            q(c0)
        );
        q_block += q(c3);
        q_none += q(c0);
        base[bi] = c0;
        let (a, _) = lin(n, k, sd);
        let p: Vec<f64> = b.iter().map(|&x| dop(n, k, x)).collect();
        for (j, &f) in FILM_INDICES.iter().enumerate() {
            let y = film_dolp((n, k), f, 3.0, wl);
            let g: Vec<f64> = y.iter().zip(&p).map(|(a, b)| a - b).collect();
            stack_h[bi][j] = [
                a.iter().zip(&g).map(|(r, x)| r[0] * x).sum(),
                a.iter().zip(&g).map(|(r, x)| r[1] * x).sum(),
            ];
        }
    }
    // correlated: 6x6 = blockdiag(base) + H Hᵀ
    let mut m = [[0.0f64; 6]; 6];
    for bi in 0..3 {
        m[2 * bi][2 * bi] = base[bi][0];
        m[2 * bi][2 * bi + 1] = base[bi][1];
        m[2 * bi + 1][2 * bi] = base[bi][1];
        m[2 * bi + 1][2 * bi + 1] = base[bi][2];
    }
    for j in 0..3 {
        for r in 0..6 {
            for c in 0..6 {
                m[r][c] += stack_h[r / 2][j][r % 2] * stack_h[c / 2][j][c % 2];
            }
        }
    }
    let mut dvec = [0.0; 6];
    for bi in 0..3 {
        dvec[2 * bi] = COPPER[bi].0 - GOLD[bi].0;
        dvec[2 * bi + 1] = COPPER[bi].1 - GOLD[bi].1;
    }
    // solve m x = d by Gaussian elimination
    let mut a = m;
    let mut x = dvec;
    for i in 0..6 {
        let p = a[i][i];
        for r in (i + 1)..6 {
            let f = a[r][i] / p;
            for c in i..6 {
                a[r][c] -= f * a[i][c];
            }
            x[r] -= f * x[i];
        }
    }
    for i in (0..6).rev() {
        let mut s = x[i];
        for c in (i + 1)..6 {
            s -= a[i][c] * x[c];
        }
        x[i] = s / a[i][i];
    }
    let q_corr: f64 = x.iter().zip(&dvec).map(|(a, b)| a * b).sum();
    println!(
        "  sum d2: block-diag film3 {q_block:.1}, no film {q_none:.1}, correlated film3 {q_corr:.1}; chi2_6(0.95)=12.59"
    );
}
