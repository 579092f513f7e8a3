//! The noise model of a map made of blocks (`polarid.dask.material_map`).
//!
//! The noise model of `polarid map` ([`estimate_noise`]) is a global estimate: a sample
//! of every `m`-th usable pixel of the whole map (row-major order,
//! `m = ⌈usable / NOISE_SAMPLE⌉`) is fitted and its residuals regressed. A map made of
//! blocks reproduces it exactly in two passes over its blocks: [`usable_per_row`]
//! counts the usable pixels of every map row of a block; given the usable pixels of the
//! whole map before each row, [`noise_sample`] takes the block's pixels of the sample;
//! [`estimate_sample`] runs [`estimate_noise`] on the gathered sample, in the map's pixel
//! order, which gives the very numbers `polarid map` estimates.

use polarid_core::CoreError;
use polarid_core::fit::{FitOptions, FitPlan, PixelBetaPlan};
use polarid_core::map::noise::{NoiseEstimate, estimate_noise};
use polarid_core::map::{Betas, signal_reason};

use super::BandDolp;
use super::bands::slices;

/// The β of a block's fits, radians: one per capture, or one image per capture (f32, as
/// the map's geometry stage stores them).
#[derive(Debug, Clone, PartialEq)]
pub enum BlockBeta {
    /// One β per capture (far field).
    Shared(Vec<f64>),
    /// One β image per capture (calibrated geometry).
    PerPixel(Vec<Vec<f32>>),
}

impl BlockBeta {
    /// `beta_deg` (degrees) as the fits take it: one per capture, or when `per_pixel`
    /// one image of `npix` values per capture, captures first.
    pub fn from_degrees(beta_deg: &[f64], per_pixel: bool, npix: usize) -> Self {
        if per_pixel {
            BlockBeta::PerPixel(
                beta_deg
                    .chunks_exact(npix.max(1))
                    .map(|b| b.iter().map(|d| d.to_radians() as f32).collect())
                    .collect(),
            )
        } else {
            BlockBeta::Shared(beta_deg.iter().map(|d| d.to_radians()).collect())
        }
    }

    fn at(&self, t: usize, p: usize) -> f64 {
        match self {
            BlockBeta::Shared(v) => v[t],
            BlockBeta::PerPixel(m) => m[t][p] as f64,
        }
    }
}

/// Whether pixel `p` of `band` enters the noise sample, by the rule of
/// [`estimate_noise`]: no signal flag; DoLP, noise terms and β finite and a term
/// positive in every capture, or (a β per pixel, fewer than 64 captures) in at least 3.
fn usable(band: &BandDolp, beta: &BlockBeta, p: usize) -> bool {
    let (dolp, flags, read, shot) = band.images();
    if signal_reason(flags[p]) != 0 {
        return false;
    }
    let ok = |t: usize| {
        let (d, a, b) = (dolp[t][p], read[t][p], shot[t][p]);
        d.is_finite()
            && a.is_finite()
            && b.is_finite()
            && (a > 0.0 || b > 0.0)
            && beta.at(t, p).is_finite()
    };
    match beta {
        BlockBeta::PerPixel(_) if dolp.len() < 64 => {
            (0..dolp.len()).filter(|&t| ok(t)).count() >= 3
        }
        _ => (0..dolp.len()).all(ok),
    }
}

/// Noise pass 1: the number of usable pixels of every map row of a block's band
/// (`columns × rows` pixels, with its noise terms).
pub fn usable_per_row(
    band: &BandDolp,
    beta: &BlockBeta,
    columns: usize,
    rows: usize,
) -> Vec<usize> {
    (0..rows)
        .map(|y| {
            (y * columns..(y + 1) * columns)
                .filter(|&p| usable(band, beta, p))
                .count()
        })
        .collect()
}

/// Noise pass 2: the block's usable pixels whose rank in the map is a multiple of
/// `stride` (`row_offsets`: the usable pixels of the whole map before each row of the
/// block, row-major) and their images: the DoLP, read and shot terms and (a β per pixel)
/// β of every capture. Errors: not one offset per row.
pub fn noise_sample(
    band: &BandDolp,
    beta: &BlockBeta,
    columns: usize,
    row_offsets: &[usize],
    stride: usize,
) -> Result<(Vec<usize>, Vec<Vec<Vec<f32>>>), CoreError> {
    let (dolp, flags, read, shot) = band.images();
    let rows = flags.len() / columns.max(1);
    if row_offsets.len() != rows {
        return Err(CoreError::LengthMismatch {
            name: "row offsets (one per map row of the block)",
            expected: rows,
            got: row_offsets.len(),
        });
    }
    let mut index = Vec::new();
    for (y, &off) in row_offsets.iter().enumerate() {
        let usable = (y * columns..(y + 1) * columns).filter(|&p| usable(band, beta, p));
        let ranked = usable.zip(off..).filter(|(_, r)| r % stride.max(1) == 0);
        index.extend(ranked.map(|(p, _)| p));
    }
    let mut images = vec![dolp, read, shot];
    if let BlockBeta::PerPixel(m) = beta {
        images.push(m.as_slice());
    }
    let gather = |im: &Vec<f32>| -> Vec<f32> { index.iter().map(|&p| im[p]).collect() };
    let images = images
        .iter()
        .map(|imgs| imgs.iter().map(gather).collect())
        .collect();
    Ok((index, images))
}

/// The map's noise model from the gathered sample: per capture the DoLP, noise terms
/// and (`beta` per pixel) β of the sampled pixels, in the map's pixel order. `Ok(None)`
/// when the sample gives no estimate ([`estimate_noise`]). Errors: images of different
/// sizes.
pub fn estimate_sample(
    dolp: &[Vec<f32>],
    read: &[Vec<f32>],
    shot: &[Vec<f32>],
    beta: &BlockBeta,
) -> Result<Option<NoiseEstimate>, CoreError> {
    let flags = vec![0u8; dolp.first().map_or(0, Vec::len)];
    let (dv, rv, sv) = (slices(dolp), slices(read), slices(shot));
    match beta {
        BlockBeta::Shared(b) => {
            let plan = FitPlan::new(b, FitOptions::default())?;
            estimate_noise(Betas::Shared(&plan), &dv, &rv, &sv, &flags)
        }
        BlockBeta::PerPixel(m) => {
            if let Some(bad) = m.iter().find(|b| b.len() != flags.len()) {
                return Err(CoreError::LengthMismatch {
                    name: "beta (sampled pixels)",
                    expected: flags.len(),
                    got: bad.len(),
                });
            }
            let plan = PixelBetaPlan::new(FitOptions::default())?;
            let beta = slices(m);
            let betas = Betas::PerPixel {
                plan: &plan,
                beta: &beta,
            };
            estimate_noise(betas, &dv, &rv, &sv, &flags)
        }
    }
}
