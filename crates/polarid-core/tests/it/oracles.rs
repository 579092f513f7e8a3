//! Every row of `data/oracles/dop_reference.csv` and `data/oracles/pbrdf_reference.csv`
//! (values from mpmath and NIST SCATMECH, see the oracle README), at the tolerances of
//! the issue: DoP 1e-12 absolute; pBRDF each element 1e-9·m00 in both frames, `dolp`
//! 1e-12 absolute.

use std::collections::HashMap;

use polarid_core::{dop, fresnel, geometry, pbrdf};

const ORACLES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../data/oracles");

/// A plain numeric CSV with `#` comments: header names and rows of numbers.
struct Table {
    cols: HashMap<String, usize>,
    rows: Vec<(usize, Vec<f64>)>,
}

impl Table {
    fn read(name: &str) -> Table {
        let path = format!("{ORACLES}/{name}");
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim_start().starts_with('#') && !l.trim().is_empty());
        let (_, header) = lines.next().expect("header line");
        let cols = header
            .split(',')
            .enumerate()
            .map(|(i, h)| (h.trim().to_string(), i))
            .collect();
        let rows = lines
            .map(|(i, l)| {
                let v = l
                    .split(',')
                    .map(|c| {
                        c.trim()
                            .parse::<f64>()
                            .unwrap_or_else(|e| panic!("{path}:{}: {c:?}: {e}", i + 1))
                    })
                    .collect();
                (i + 1, v)
            })
            .collect();
        Table { cols, rows }
    }

    fn get(&self, row: &[f64], name: &str) -> f64 {
        row[self.cols[name]]
    }
}

#[test]
fn dop_reference_every_row() {
    let t = Table::read("dop_reference.csv");
    assert!(t.rows.len() >= 400, "{} rows", t.rows.len());
    let mut worst = (0.0f64, 0usize);
    let mut worst_grad = (0.0f64, 0usize);
    for (line, r) in &t.rows {
        let (n, k, b) = (t.get(r, "n"), t.get(r, "k"), t.get(r, "beta_deg"));
        let want = t.get(r, "dop");
        let beta = b.to_radians();
        let p = dop::dop(n, k, beta);
        let g = dop::dop_grad(n, k, beta);
        let e = (p - want).abs();
        let eg = (g.p - want).abs();
        assert!(
            e <= 1e-12,
            "line {line}: n={n} k={k} beta={b}: {p} vs {want}"
        );
        assert!(eg <= 1e-12, "line {line}: grad p {} vs {want}", g.p);
        assert!(g.dp_dn.is_finite() && g.dp_dk.is_finite(), "line {line}");
        if e > worst.0 {
            worst = (e, *line);
        }
        if eg > worst_grad.0 {
            worst_grad = (eg, *line);
        }
    }
    println!(
        "dop_reference: {} rows, max |dop - oracle| = {:.3e} (line {}), dop_grad.p: {:.3e} (line {})",
        t.rows.len(),
        worst.0,
        worst.1,
        worst_grad.0,
        worst_grad.1
    );
}

/// The complex Fresnel amplitudes, (Rs − Rp)/(Rs + Rp), against the same oracle away
/// from index matching (where that form loses digits, as the oracle README says).
#[test]
fn fresnel_dop_reference() {
    let t = Table::read("dop_reference.csv");
    let mut worst = 0.0f64;
    for (line, r) in &t.rows {
        let (n, k, b) = (t.get(r, "n"), t.get(r, "k"), t.get(r, "beta_deg"));
        let want = t.get(r, "dop");
        let (rs, rp) = fresnel::reflectances(n, k, b.to_radians());
        let p = (rs - rp) / (rs + rp);
        let tol = if ((n - 1.0).powi(2) + k * k).sqrt() < 1e-2 {
            1e-9
        } else {
            1e-12
        };
        let e = (p - want).abs();
        assert!(e <= tol, "line {line}: n={n} k={k} beta={b}: {p} vs {want}");
        worst = worst.max(e);
    }
    println!("dop_reference via complex Fresnel: max error {worst:.3e}");
}

const LOCAL: [&str; 9] = [
    "m00", "m01", "m02", "m10", "m11", "m12", "m20", "m21", "m22",
];

#[test]
fn pbrdf_reference_every_row() {
    let t = Table::read("pbrdf_reference.csv");
    assert!(t.rows.len() >= 300, "{} rows", t.rows.len());
    let (mut w_loc, mut w_glob, mut w_dolp, mut w_beta, mut w_tilt) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (line, r) in &t.rows {
        let n = t.get(r, "n");
        let k = t.get(r, "k");
        let sigma = t.get(r, "sigma");
        let ti = t.get(r, "theta_i_deg").to_radians();
        let tr = t.get(r, "theta_r_deg").to_radians();
        let phi = t.get(r, "phi_deg").to_radians();
        let p = pbrdf::pbrdf(n, k, sigma, ti, tr, phi).expect("valid row");
        let m00 = t.get(r, "m00");
        for (idx, name) in LOCAL.iter().enumerate() {
            let (i, j) = (idx / 3, idx % 3);
            let want = t.get(r, name);
            let e = (p.local[i][j] - want).abs() / m00;
            assert!(
                e <= 1e-9,
                "line {line}: local {name}: {} vs {want} (rel {e:.2e})",
                p.local[i][j]
            );
            w_loc = w_loc.max(e);
            let gname = if *name == "m00" {
                "m00".to_string()
            } else {
                format!("{name}_psps")
            };
            let want = t.get(r, &gname);
            let e = (p.global[i][j] - want).abs() / m00;
            assert!(
                e <= 1e-9,
                "line {line}: global {gname}: {} vs {want} (rel {e:.2e})",
                p.global[i][j]
            );
            w_glob = w_glob.max(e);
        }
        let e = (p.dolp - t.get(r, "dolp")).abs();
        assert!(
            e <= 1e-12,
            "line {line}: dolp {} vs {}",
            p.dolp,
            t.get(r, "dolp")
        );
        w_dolp = w_dolp.max(e);
        // DoLP from the global matrix is the same (frame invariance).
        let dg = p.global[1][0].hypot(p.global[2][0]) / p.global[0][0];
        assert!((dg - p.dolp).abs() <= 1e-9, "line {line}: global dolp {dg}");
        let e = (p.beta.to_degrees() - t.get(r, "beta_deg")).abs();
        assert!(
            e <= 1e-9,
            "line {line}: beta {} vs {}",
            p.beta.to_degrees(),
            t.get(r, "beta_deg")
        );
        w_beta = w_beta.max(e);
        assert!((geometry::beta(ti, tr, phi) - p.beta).abs() < 1e-15);
        let e = (p.facet_tilt.to_degrees() - t.get(r, "facet_tilt_deg")).abs();
        assert!(
            e <= 1e-9,
            "line {line}: facet tilt {} vs {}",
            p.facet_tilt.to_degrees(),
            t.get(r, "facet_tilt_deg")
        );
        w_tilt = w_tilt.max(e);
    }
    println!(
        "pbrdf_reference: {} rows; max |err|/m00 local {w_loc:.3e}, global {w_glob:.3e}; dolp {w_dolp:.3e}; beta_deg {w_beta:.3e}; facet_tilt_deg {w_tilt:.3e}",
        t.rows.len()
    );
}
