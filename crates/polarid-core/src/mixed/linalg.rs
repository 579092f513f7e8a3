//! Small dense symmetric positive definite systems (at most `NPAR` unknowns): Cholesky
//! solve for the Levenberg–Marquardt step and a Jacobi-scaled inverse for the covariance
//! `s² (JᵀJ)⁻¹`, refusing near-singular matrices.

use super::NPAR;

/// Solve the symmetric positive definite `a x = b` (size `d`) by Cholesky; `None` when
/// a pivot is not positive relative to the diagonal.
pub(super) fn cholesky_solve(
    a: &[[f64; NPAR]; NPAR],
    b: &[f64; NPAR],
    d: usize,
) -> Option<[f64; NPAR]> {
    let mut l = [[0.0; NPAR]; NPAR];
    for i in 0..d {
        for jj in 0..=i {
            let mut s = a[i][jj];
            for kk in 0..jj {
                s -= l[i][kk] * l[jj][kk];
            }
            if i == jj {
                if !(s > 1e-14 * a[i][i].abs()) || !(s > 0.0) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][jj] = s / l[jj][jj];
            }
        }
    }
    let mut y = [0.0; NPAR];
    for i in 0..d {
        let mut s = b[i];
        for kk in 0..i {
            s -= l[i][kk] * y[kk];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0; NPAR];
    for i in (0..d).rev() {
        let mut s = y[i];
        for kk in i + 1..d {
            s -= l[kk][i] * x[kk];
        }
        x[i] = s / l[i][i];
    }
    Some(x)
}

/// Inverse of the symmetric positive definite `a` (size `d`), with Jacobi scaling.
pub(super) fn spd_inverse(a: &[[f64; NPAR]; NPAR], d: usize) -> Option<[[f64; NPAR]; NPAR]> {
    let mut sc = [0.0; NPAR];
    for i in 0..d {
        if !(a[i][i] > 0.0 && a[i][i].is_finite()) {
            return None;
        }
        sc[i] = 1.0 / a[i][i].sqrt();
    }
    let mut s = [[0.0; NPAR]; NPAR];
    for i in 0..d {
        for jj in 0..d {
            s[i][jj] = a[i][jj] * sc[i] * sc[jj];
        }
    }
    let mut inv = [[0.0; NPAR]; NPAR];
    for col in 0..d {
        let mut e = [0.0; NPAR];
        e[col] = 1.0;
        let x = cholesky_solve(&s, &e, d)?;
        for i in 0..d {
            inv[i][col] = x[i] * sc[i] * sc[col];
        }
    }
    // Reject near-singular: condition of the scaled matrix.
    let mut max_diag: f64 = 0.0;
    for (i, row) in inv.iter().enumerate().take(d) {
        max_diag = max_diag.max(row[i] / (sc[i] * sc[i]));
    }
    if !(max_diag < 1e12) {
        return None;
    }
    Some(inv)
}
