//! A synthetic calibrated bench for tests (used by the measure tests of polarid-io, the
//! calibrated fit tests of polarid-pipeline and the CLI's calibrated measure tests): a
//! perspective camera close to a bench plane, lamps at a finite distance (in and out of
//! the plane of incidence), plates whose pixels reflect s-polarized light with the DoLP of
//! eq. (9) at their own β, a brightness that varies across each plate like a specular
//! lobe, and rotating-polarizer noise.
//!
//! The clean Stokes images of a capture are computed once from core physics
//! (`ViewGeometry::pixel` → β, ψ; `dop::dop` → P; AoLP = ψ + 90°); each seed then adds
//! Gaussian noise to four polarizer frames (0°, 45°, 90°, 135°) with variance
//! `gain · I + read²` and recomputes the Stokes vectors.

use std::path::Path;

use polarid_core::dop::dop;
use polarid_core::geometry::{self, Source, ViewGeometry};
use polarid_core::region::{Rect, Sampling};
use polarid_core::stokes::PixelCounts;
use polarid_io::manifest::{self, Manifest};
use polarid_io::measure::StokesImages;

use crate::Rng;

/// Image width, pixels.
pub const W: usize = 80;
/// Image height, pixels.
pub const H: usize = 60;

/// The camera: 0.55 m from the bench's origin at 54.6° from its normal, 200 px focal
/// length (a ±11° field on an 80 × 60 image).
pub const CAMERA: &str = "[camera]
focal_px = [200.0, 200.0]
principal_point_px = [39.5, 29.5]
position = [0.45, 0.0, 0.32]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]
";

/// A plate: its rectangle and its complex index.
#[derive(Debug, Clone, Copy)]
pub struct Plate {
    /// Name of the region.
    pub name: &'static str,
    /// `[x, y, w, h]`.
    pub rect: [usize; 4],
    /// `n`.
    pub n: f64,
    /// `k`.
    pub k: f64,
}

/// Two plates side by side: gold at 450 nm and a dielectric.
pub const PLATES: [Plate; 2] = [
    Plate {
        name: "gold",
        rect: [14, 18, 24, 24],
        n: 1.38,
        k: 1.92,
    },
    Plate {
        name: "glass",
        rect: [44, 18, 22, 24],
        n: 1.52,
        k: 0.0,
    },
];

/// A lamp `distance` from the origin at zenith `zenith_deg`, its azimuth turned by
/// `azimuth_deg` from the camera's plane (0: in the plane of incidence, opposite the
/// camera).
pub fn lamp(distance: f64, zenith_deg: f64, azimuth_deg: f64) -> [f64; 3] {
    let (z, a) = (zenith_deg.to_radians(), azimuth_deg.to_radians());
    [
        -distance * z.sin() * a.cos(),
        distance * z.sin() * a.sin(),
        distance * z.cos(),
    ]
}

/// Lamps of a capture set at `distance` from the bench's origin: five in the plane of
/// incidence and two out of it.
pub fn lamps_at(distance: f64) -> Vec<[f64; 3]> {
    [
        (10.0, 0.0),
        (25.0, 0.0),
        (40.0, 0.0),
        (55.0, 0.0),
        (70.0, 0.0),
        (35.0, 40.0),
        (60.0, -35.0),
    ]
    .iter()
    .map(|&(z, a)| lamp(distance, z, a))
    .collect()
}

/// The lamps at 0.5 m.
pub fn lamps() -> Vec<[f64; 3]> {
    lamps_at(0.5)
}

/// The manifest text of a bench with `plates` and one Stokes capture per lamp (the
/// Stokes files are named `c{j}_s{0,1,2}.tif`).
pub fn manifest_text(plates: &[Plate], lamps: &[[f64; 3]]) -> String {
    let mut t = String::from(CAMERA);
    for p in plates {
        let [x, y, w, h] = p.rect;
        t += &format!(
            "\n[[region]]\nname = \"{}\"\nrect = [{x}, {y}, {w}, {h}]\nclass = \"{}\"\n",
            p.name, p.name
        );
    }
    for (j, l) in lamps.iter().enumerate() {
        t += &format!(
            "\n[[capture]]\nsource = {{ position = [{}, {}, {}] }}\n",
            l[0], l[1], l[2]
        );
        t += &format!(
            "stokes = {{ s0 = \"c{j}_s0.tif\", s1 = \"c{j}_s1.tif\", s2 = \"c{j}_s2.tif\" }}\n"
        );
    }
    t
}

/// Parse the bench's manifest in `dir` (placeholder Stokes files are created so that it
/// validates; [`write_stokes`] replaces them with images).
pub fn load(dir: &Path, plates: &[Plate], lamps: &[[f64; 3]]) -> Manifest {
    for j in 0..lamps.len() {
        for k in 0..3 {
            let p = dir.join(format!("c{j}_s{k}.tif"));
            if !p.exists() {
                std::fs::write(&p, b"placeholder").unwrap();
            }
        }
    }
    let text = manifest_text(plates, lamps);
    let path = dir.join("manifest.toml");
    std::fs::write(&path, &text).unwrap();
    manifest::parse(&path, &text).unwrap()
}

/// What a plate's row should report in one capture (angles in radians).
#[derive(Debug, Clone, Copy)]
pub struct Truth {
    /// `Σ S0 P(β) / Σ S0` over the plate's pixels (noise-free S0).
    pub dolp: f64,
    /// Noise-free S0-weighted mean of β.
    pub beta: f64,
    /// Noise-free S0-weighted SD of β.
    pub beta_sd: f64,
    /// β at the rectangle's centre.
    pub centre_beta: f64,
    /// DoLP of the unweighted image-frame mean (what far-field averaging would see).
    pub image_dolp: f64,
}

/// The noise-free Stokes images of one capture and the truth per plate.
#[derive(Debug, Clone)]
pub struct Clean {
    /// `(S0, S1, S2)` per pixel, row-major.
    pub s: Vec<[f64; 3]>,
    /// One per plate.
    pub truth: Vec<Truth>,
}

/// Peak brightness of the lobe, DN of S0.
pub const PEAK_S0: f64 = 3000.0;
/// RMS facet slope of the lobe, radians.
pub const LOBE_SIGMA: f64 = 0.2;

/// The clean capture lit by `lamp` with `plates` (lobe of RMS slope [`LOBE_SIGMA`]).
pub fn clean(m: &Manifest, plates: &[Plate], lamp: [f64; 3]) -> Clean {
    clean_with(m, plates, lamp, LOBE_SIGMA)
}

/// The clean capture lit by `lamp` with `plates`, a lobe of RMS facet slope `sigma`.
pub fn clean_with(m: &Manifest, plates: &[Plate], lamp: [f64; 3], sigma: f64) -> Clean {
    let cam = m.camera.as_ref().unwrap().to_camera();
    let vg = ViewGeometry::new(cam, m.planes[0].to_plane().unwrap()).unwrap();
    let src = Source::Position(lamp);
    let mut s = vec![[100.0, 0.0, 0.0]; W * H];
    let mut truth = Vec::new();
    for p in plates {
        let [x0, y0, w, h] = p.rect;
        let (mut sw, mut swb, mut swp) = (0.0, 0.0, 0.0);
        let mut img = [0.0f64; 3];
        let mut px = Vec::new();
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                let g = vg.pixel(x as f64, y as f64, &src).unwrap();
                let tilt = geometry::facet_tilt(g.theta_i, g.theta_r, g.phi);
                let d2 = (0..3).map(|i| (lamp[i] - g.point[i]).powi(2)).sum::<f64>();
                let lobe = 0.15 + (-(tilt.tan().powi(2)) / (2.0 * sigma * sigma)).exp();
                let s0 =
                    PEAK_S0 * lobe * (lamp[0].powi(2) + lamp[1].powi(2) + lamp[2].powi(2)) / d2;
                let pol = dop(p.n, p.k, g.beta);
                let a = 2.0 * (g.poi_angle + std::f64::consts::FRAC_PI_2);
                let v = [s0, s0 * pol * a.cos(), s0 * pol * a.sin()];
                s[y * W + x] = v;
                for c in 0..3 {
                    img[c] += v[c];
                }
                sw += s0;
                swb += s0 * g.beta;
                swp += s0 * pol;
                px.push((s0, g.beta));
            }
        }
        let beta = swb / sw;
        let var = px.iter().map(|(w, b)| w * (b - beta).powi(2)).sum::<f64>() / sw;
        let c = Rect {
            x: x0,
            y: y0,
            width: w,
            height: h,
        };
        let (cu, cv) = ViewGeometry::probe_points(c)[4];
        truth.push(Truth {
            dolp: swp / sw,
            beta,
            beta_sd: var.sqrt(),
            centre_beta: vg.pixel(cu, cv, &src).unwrap().beta,
            image_dolp: img[1].hypot(img[2]) / img[0],
        });
    }
    Clean { s, truth }
}

/// Read noise of each polarizer frame, DN.
pub const READ_NOISE: f64 = 3.0;

/// Stokes images of `clean` with the noise of four polarizer frames (variance
/// `gain · I + READ_NOISE²`); `gain = 0` gives the noise-free images.
pub fn noisy(clean: &Clean, gain: f64, seed: u64) -> StokesImages {
    noisy_with(clean, gain, READ_NOISE, seed)
}

/// [`noisy`] with read noise `read` (DN).
pub fn noisy_with(clean: &Clean, gain: f64, read: f64, seed: u64) -> StokesImages {
    let mut rng = Rng::new(seed);
    let mut out = StokesImages::alloc(W, H, Sampling::Independent);
    for (p, v) in clean.s.iter().enumerate() {
        let mut i = [0.0f64; 4];
        for (q, a) in [0.0f64, 45.0, 90.0, 135.0].iter().enumerate() {
            let a = 2.0 * a.to_radians();
            let ideal = 0.5 * (v[0] + v[1] * a.cos() + v[2] * a.sin());
            let sd = if gain > 0.0 {
                (gain * ideal.max(0.0) + read * read).sqrt()
            } else {
                0.0
            };
            i[q] = ideal + sd * rng.normal();
        }
        out.s0[p] = (0.5 * (i[0] + i[1] + i[2] + i[3])) as f32;
        out.s1[p] = (i[0] - i[2]) as f32;
        out.s2[p] = (i[1] - i[3]) as f32;
        out.mask[p] = if out.s0[p] > 0.0 { 0 } else { 2 };
    }
    out.counts = PixelCounts {
        valid: out.mask.iter().filter(|&&m| m == 0).count() as u64,
        ..PixelCounts::default()
    };
    out
}

/// Write `img` as the float TIFFs of capture `j` in `dir`.
pub fn write_stokes(dir: &Path, j: usize, img: &StokesImages) {
    for (k, data) in [&img.s0, &img.s1, &img.s2].into_iter().enumerate() {
        polarid_io::image::write_tiff_f32(
            &dir.join(format!("c{j}_s{k}.tif")),
            true,
            img.width,
            img.height,
            data,
        )
        .unwrap();
    }
}
