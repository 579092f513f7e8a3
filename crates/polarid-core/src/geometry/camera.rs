//! A calibrated pinhole camera with OpenCV conventions: intrinsics, optional lens
//! distortion, and pose in the scene frame.
//!
//! - **Pixels**: `u` is the column, `v` the row, in the pixels of the files as stored
//!   (the raw mosaic for a division-of-focal-plane sensor). Pixel centres are at integer
//!   coordinates: pixel `(0, 0)` covers `[-0.5, 0.5]²`. The principal point `(cx, cy)`
//!   is in the same coordinates.
//! - **Projection**: a point with camera coordinates `(X, Y, Z)`, `Z > 0`, has normalized
//!   coordinates `x = X/Z`, `y = Y/Z`, distorted by the OpenCV model (below) to
//!   `(x_d, y_d)`, and lands at `u = fx x_d + cx`, `v = fy y_d + cy`.
//! - **Distortion** (OpenCV `k1, k2, p1, p2, k3`): with `r² = x² + y²`,
//!   `x_d = x (1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2x²)`,
//!   `y_d = y (1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2y²) + 2 p2 x y`.
//! - **Pose**: `position` is the centre of projection in the scene frame, and the
//!   rotation `R` is world-to-camera: camera coordinates are `R (P − position)`. The
//!   rows of `R` are the camera axes in the scene frame: `x` along increasing columns,
//!   `y` along increasing rows, `z` forward (the optical axis).
//!
//! Undistortion (pixel → ray) inverts the distortion iteratively: a few fixed-point steps
//! `x ← (x_d − Δ(x)) / radial(x)` (OpenCV's `undistortPoints`) to get close, then
//! Newton's method on the 2×2 system `distort(x) = x_d` with the analytic Jacobian until
//! the residual is below 1e-13 in normalized coordinates (≈ 1e-10 pixel), at most 50
//! steps. If that fails (the pixel lies beyond the field where the polynomial is
//! monotonic), [`CoreError::UndistortFailed`] names the pixel.

use crate::error::{CoreError, Result};

use super::vec3::{self, V3};

/// Intrinsic parameters in pixels (OpenCV's camera matrix).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Focal length along columns, pixels.
    pub fx: f64,
    /// Focal length along rows, pixels.
    pub fy: f64,
    /// Principal point column (pixel centres at integers).
    pub cx: f64,
    /// Principal point row.
    pub cy: f64,
}

/// OpenCV's 5-coefficient lens distortion (`k1, k2, p1, p2, k3`); all zero: none.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Distortion {
    /// Radial coefficient of `r²`.
    pub k1: f64,
    /// Radial coefficient of `r⁴`.
    pub k2: f64,
    /// First tangential coefficient.
    pub p1: f64,
    /// Second tangential coefficient.
    pub p2: f64,
    /// Radial coefficient of `r⁶`.
    pub k3: f64,
}

impl Distortion {
    /// From OpenCV's order `[k1, k2, p1, p2, k3]`.
    pub fn from_array(c: [f64; 5]) -> Self {
        Self {
            k1: c[0],
            k2: c[1],
            p1: c[2],
            p2: c[3],
            k3: c[4],
        }
    }

    /// `true` when every coefficient is zero.
    pub fn is_none(&self) -> bool {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
            .iter()
            .all(|&c| c == 0.0)
    }

    /// Distorted normalized coordinates of undistorted `(x, y)`.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        (
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// Jacobian of [`Distortion::distort`] at `(x, y)`: `[[∂xd/∂x, ∂xd/∂y], [∂yd/∂x,
    /// ∂yd/∂y]]`.
    #[inline]
    pub fn jacobian(&self, x: f64, y: f64) -> [[f64; 2]; 2] {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        // d radial / d r²
        let dr = self.k1 + r2 * (2.0 * self.k2 + 3.0 * r2 * self.k3);
        let (p1, p2) = (self.p1, self.p2);
        [
            [
                radial + 2.0 * x * x * dr + 2.0 * p1 * y + 6.0 * p2 * x,
                2.0 * x * y * dr + 2.0 * p1 * x + 2.0 * p2 * y,
            ],
            [
                2.0 * x * y * dr + 2.0 * p1 * x + 2.0 * p2 * y,
                radial + 2.0 * y * y * dr + 6.0 * p1 * y + 2.0 * p2 * x,
            ],
        ]
    }

    /// Undistorted normalized coordinates of distorted `(xd, yd)` (see the module's
    /// documentation), or `None` when the iteration does not converge.
    pub fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        if self.is_none() {
            return Some((xd, yd));
        }
        const TOL: f64 = 1e-13;
        // Fixed-point steps (OpenCV): robust start for Newton.
        let (mut x, mut y) = self.fixed_point(xd, yd, 5);
        for _ in 0..50 {
            let (fx, fy) = self.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs().max(ey.abs()) <= TOL * (1.0 + xd.abs().max(yd.abs())) {
                return Some((x, y));
            }
            let j = self.jacobian(x, y);
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if !(det.is_finite() && det.abs() > 1e-300) {
                return None;
            }
            x -= (j[1][1] * ex - j[0][1] * ey) / det;
            y -= (j[0][0] * ey - j[1][0] * ex) / det;
            if !(x.is_finite() && y.is_finite()) {
                return None;
            }
        }
        let (fx, fy) = self.distort(x, y);
        let e = (fx - xd).abs().max((fy - yd).abs());
        (e <= 1e3 * TOL * (1.0 + xd.abs().max(yd.abs()))).then_some((x, y))
    }
}

/// A calibrated pinhole camera: intrinsics, distortion and pose (see the module's
/// documentation for the conventions).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeCamera {
    intrinsics: Intrinsics,
    distortion: Distortion,
    position: V3,
    rotation: [V3; 3],
}

fn check_intrinsics(k: &Intrinsics, d: &Distortion) -> Result<()> {
    if !(k.fx.is_finite() && k.fy.is_finite() && k.fx > 0.0 && k.fy > 0.0) {
        return Err(CoreError::InvalidFocalLength { fx: k.fx, fy: k.fy });
    }
    crate::error::ensure_finite("principal point cx", k.cx)?;
    crate::error::ensure_finite("principal point cy", k.cy)?;
    for (name, c) in [
        ("distortion k1", d.k1),
        ("distortion k2", d.k2),
        ("distortion p1", d.p1),
        ("distortion p2", d.p2),
        ("distortion k3", d.k3),
    ] {
        crate::error::ensure_finite(name, c)?;
    }
    Ok(())
}

impl PinholeCamera {
    /// A camera at `position` looking at `look_at`, oriented so that `up` points
    /// towards decreasing rows (up in the displayed image): camera `z` is the unit vector
    /// from `position` to `look_at`, camera `y` is `−up` made perpendicular to `z`, and
    /// camera `x = y × z`.
    ///
    /// Errors: [`CoreError::InvalidFocalLength`], [`CoreError::NonFinite`] (principal
    /// point, distortion), [`CoreError::InvalidVector`] (a non-finite vector, a zero
    /// `up`), [`CoreError::DegenerateLookAt`] (`look_at` equal to `position`, or `up`
    /// parallel to the viewing direction).
    pub fn look_at(
        intrinsics: Intrinsics,
        distortion: Distortion,
        position: V3,
        look_at: V3,
        up: V3,
    ) -> Result<Self> {
        check_intrinsics(&intrinsics, &distortion)?;
        vec3::finite("camera position", position)?;
        vec3::finite("camera look_at", look_at)?;
        let up_u = vec3::unit_named("camera up", up)?;
        let degenerate = |reason| CoreError::DegenerateLookAt {
            position,
            look_at,
            up,
            reason,
        };
        let z = vec3::unit(vec3::sub(look_at, position))
            .ok_or_else(|| degenerate("look_at coincides with the camera position"))?;
        let y_raw = vec3::sub(vec3::scale(z, vec3::dot(up_u, z)), up_u);
        if vec3::norm(y_raw) < 1e-9 {
            return Err(degenerate("up is parallel to the viewing direction"));
        }
        let y = vec3::unit(y_raw)
            .ok_or_else(|| degenerate("up is parallel to the viewing direction"))?;
        let x = vec3::cross(y, z);
        Ok(Self {
            intrinsics,
            distortion,
            position,
            rotation: [x, y, z],
        })
    }

    /// A camera at `position` with world-to-camera rotation `rotation` (row by row: the
    /// camera's x, y and z axes in the scene frame).
    ///
    /// Errors: as [`PinholeCamera::look_at`] for the intrinsics and position, and
    /// [`CoreError::NotARotation`] when `R Rᵀ` differs from the identity by more than
    /// 1e-6 in any entry, or `det R` from +1 by more than 1e-6 (a reflection).
    pub fn from_rotation(
        intrinsics: Intrinsics,
        distortion: Distortion,
        position: V3,
        rotation: [V3; 3],
    ) -> Result<Self> {
        check_intrinsics(&intrinsics, &distortion)?;
        vec3::finite("camera position", position)?;
        let bad = |reason: String| CoreError::NotARotation {
            rows: rotation,
            reason,
        };
        if rotation.iter().flatten().any(|x| !x.is_finite()) {
            return Err(bad("entries must be finite".into()));
        }
        let mut worst: f64 = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { 1.0 } else { 0.0 };
                worst = worst.max((vec3::dot(rotation[i], rotation[j]) - want).abs());
            }
        }
        if worst > 1e-6 {
            return Err(bad(format!(
                "rows are not orthonormal (R Rᵀ differs from the identity by {worst:.3e} > 1e-6)"
            )));
        }
        let det = vec3::dot(rotation[0], vec3::cross(rotation[1], rotation[2]));
        if (det - 1.0).abs() > 1e-6 {
            return Err(bad(format!("determinant is {det}, not +1")));
        }
        Ok(Self {
            intrinsics,
            distortion,
            position,
            rotation,
        })
    }

    /// The intrinsics.
    pub fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }

    /// The distortion coefficients.
    pub fn distortion(&self) -> Distortion {
        self.distortion
    }

    /// Centre of projection in the scene frame.
    pub fn position(&self) -> V3 {
        self.position
    }

    /// World-to-camera rotation, row by row (the camera's x, y, z axes in the scene
    /// frame).
    pub fn rotation(&self) -> [V3; 3] {
        self.rotation
    }

    /// Pixel `(u, v)` of the scene point `p`, or `None` when `p` is not in front of the
    /// camera (`Z <= 0`).
    pub fn project(&self, p: V3) -> Option<[f64; 2]> {
        let c = vec3::mul(&self.rotation, vec3::sub(p, self.position));
        if c[2].is_nan() || c[2] <= 0.0 {
            return None;
        }
        let (xd, yd) = self.distortion.distort(c[0] / c[2], c[1] / c[2]);
        Some([
            self.intrinsics.fx * xd + self.intrinsics.cx,
            self.intrinsics.fy * yd + self.intrinsics.cy,
        ])
    }

    /// Pixel of normalized undistorted coordinates `(x, y)`.
    pub fn pixel_of_normalized(&self, x: f64, y: f64) -> [f64; 2] {
        let (xd, yd) = self.distortion.distort(x, y);
        [
            self.intrinsics.fx * xd + self.intrinsics.cx,
            self.intrinsics.fy * yd + self.intrinsics.cy,
        ]
    }

    /// Undistorted normalized coordinates `(x, y)` of pixel `(u, v)`: the ray is
    /// `(x, y, 1)` in camera coordinates.
    ///
    /// Errors: [`CoreError::NonFinite`] for a non-finite pixel,
    /// [`CoreError::UndistortFailed`] when the distortion cannot be inverted there.
    pub fn normalized(&self, u: f64, v: f64) -> Result<(f64, f64)> {
        crate::error::ensure_finite("pixel column", u)?;
        crate::error::ensure_finite("pixel row", v)?;
        let k = &self.intrinsics;
        let (xd, yd) = ((u - k.cx) / k.fx, (v - k.cy) / k.fy);
        self.distortion.undistort(xd, yd).ok_or_else(|| {
            let (x, y) = self.distortion.fixed_point(xd, yd, 20);
            let [pu, pv] = self.pixel_of_normalized(x, y);
            CoreError::UndistortFailed {
                u,
                v,
                residual_px: (pu - u).hypot(pv - v),
            }
        })
    }

    /// Unit direction, in the scene frame, of the ray from the camera through pixel
    /// `(u, v)` (errors of [`PinholeCamera::normalized`]).
    pub fn ray(&self, u: f64, v: f64) -> Result<V3> {
        let (x, y) = self.normalized(u, v)?;
        let d = vec3::mul_t(&self.rotation, [x, y, 1.0]);
        vec3::unit(d).ok_or(CoreError::InvalidVector {
            name: "pixel ray",
            value: d,
        })
    }

    /// Camera-frame vector of a scene-frame vector.
    pub(crate) fn camera_vector(&self, w: V3) -> V3 {
        vec3::mul(&self.rotation, w)
    }
}

impl Distortion {
    /// The fixed-point estimate of the undistorted `(xd, yd)` after `steps` steps (or the
    /// last finite one): the start of [`Distortion::undistort`]'s Newton steps, and with
    /// 20 steps the estimate for error messages when it fails.
    fn fixed_point(&self, xd: f64, yd: f64, steps: usize) -> (f64, f64) {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..steps {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            let dx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
            let dy = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
            let (nx, ny) = ((xd - dx) / radial, (yd - dy) / radial);
            if !(nx.is_finite() && ny.is_finite()) {
                break;
            }
            (x, y) = (nx, ny);
        }
        (x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn intr() -> Intrinsics {
        Intrinsics {
            fx: 1350.0,
            fy: 1352.0,
            cx: 319.5,
            cy: 239.5,
        }
    }

    fn realistic() -> Distortion {
        // Typical of a C-mount machine-vision lens calibrated with OpenCV.
        Distortion::from_array([-0.21, 0.12, 8e-4, -5e-4, -0.03])
    }

    #[test]
    fn distort_undistort_round_trip_over_the_image() {
        let cam = PinholeCamera::look_at(
            intr(),
            realistic(),
            [0.0, 0.0, 1.0],
            [0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
        )
        .unwrap();
        let mut worst: f64 = 0.0;
        for v in (0..480).step_by(7).chain([479]) {
            for u in (0..640).step_by(7).chain([639]) {
                let (u, v) = (u as f64, v as f64);
                let (x, y) = cam.normalized(u, v).unwrap();
                let [pu, pv] = cam.pixel_of_normalized(x, y);
                worst = worst.max((pu - u).hypot(pv - v));
            }
        }
        assert!(worst < 1e-9, "worst round trip {worst} px");
    }

    #[test]
    fn strong_barrel_distortion_round_trip() {
        let d = Distortion::from_array([-0.4, 0.2, 1e-3, 1e-3, -0.05]);
        for &(x, y) in &[(0.2, 0.1), (-0.3, 0.25), (0.35, -0.3), (0.0, 0.0)] {
            let (xd, yd) = d.distort(x, y);
            let (ux, uy) = d.undistort(xd, yd).unwrap();
            assert!((ux - x).abs() < 1e-12 && (uy - y).abs() < 1e-12);
        }
    }

    #[test]
    fn look_at_axes() {
        // Looking north with up = +z: columns increase eastwards, rows downwards.
        let cam = PinholeCamera::look_at(
            intr(),
            Distortion::default(),
            [0.0, 0.0, 0.0],
            [0.0, 5.0, 0.0],
            [0.0, 0.0, 2.0],
        )
        .unwrap();
        let r = cam.rotation();
        let close = |a: V3, b: V3| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-15);
        assert!(close(r[0], [1.0, 0.0, 0.0]), "{r:?}");
        assert!(close(r[1], [0.0, 0.0, -1.0]), "{r:?}");
        assert!(close(r[2], [0.0, 1.0, 0.0]), "{r:?}");
        // The same rotation given as a matrix gives the same camera.
        let cam2 =
            PinholeCamera::from_rotation(intr(), Distortion::default(), [0.0; 3], r).unwrap();
        assert_eq!(cam, cam2);
        // Projection and ray agree.
        let p = [0.3, 4.0, 0.7];
        let [u, v] = cam.project(p).unwrap();
        assert!(v < intr().cy && u > intr().cx);
        let d = cam.ray(u, v).unwrap();
        let pu = vec3::unit(p).unwrap();
        assert!(close(d, pu) || (0..3).all(|i| (d[i] - pu[i]).abs() < 1e-12));
    }

    #[test]
    fn errors() {
        let d = Distortion::default();
        let bad_f = Intrinsics { fx: 0.0, ..intr() };
        assert!(matches!(
            PinholeCamera::look_at(bad_f, d, [0.0, 0.0, 1.0], [0.0; 3], [0.0, 1.0, 0.0]),
            Err(CoreError::InvalidFocalLength { .. })
        ));
        assert!(matches!(
            PinholeCamera::look_at(intr(), d, [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]),
            Err(CoreError::DegenerateLookAt { .. })
        ));
        assert!(matches!(
            PinholeCamera::look_at(intr(), d, [0.0, 0.0, 1.0], [0.0; 3], [0.0, 0.0, 3.0]),
            Err(CoreError::DegenerateLookAt { .. })
        ));
        assert!(matches!(
            PinholeCamera::look_at(intr(), d, [0.0, 0.0, 1.0], [0.0; 3], [0.0; 3]),
            Err(CoreError::InvalidVector {
                name: "camera up",
                ..
            })
        ));
        assert!(matches!(
            PinholeCamera::look_at(intr(), d, [f64::NAN, 0.0, 1.0], [0.0; 3], [0.0, 1.0, 0.0]),
            Err(CoreError::InvalidVector { .. })
        ));
        let scaled = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(matches!(
            PinholeCamera::from_rotation(intr(), d, [0.0; 3], scaled),
            Err(CoreError::NotARotation { .. })
        ));
        let reflection = [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let e = PinholeCamera::from_rotation(intr(), d, [0.0; 3], reflection).unwrap_err();
        assert!(e.to_string().contains("determinant"), "{e}");
        // Within 1e-6: accepted.
        let nearly = [[1.0, 1e-8, 0.0], [-1e-8, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(PinholeCamera::from_rotation(intr(), d, [0.0; 3], nearly).is_ok());
    }
}
