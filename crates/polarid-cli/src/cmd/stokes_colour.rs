//! `polarid stokes --dofp RAW --color RGGB [--bands R=650,G=550,B=450]`: per-band
//! Stokes, DoLP and AoLP of a colour polarization mosaic
//! ([`polarid_core::mosaic::colour_polar`], one fused pass for all bands), written as
//! `s0_<nm>.tif`, `s1_<nm>.tif`, `s2_<nm>.tif`, `dolp_<nm>.tif`, `aolp_<nm>.tif`,
//! `dolp_<nm>.png`, `aolp_<nm>.png` per band, plus the colour previews `s0_rgb.png`
//! (S0 of the R, G and B bands, gamma 1/2.2, scaled to the 99.5th percentile) and
//! `dolp_rgb.png` (DoLP of the R, G, B bands over the DoLP scale). The per-band views
//! are those of [`crate::render::views`] with each band's mask (saturated and dark
//! pixels in their colours); all files are written in parallel ([`super::write_files`]).

use polarid_io::manifest::colour::wavelength_label;
use polarid_pipeline::stokes::{StokesBand, StokesResult};

use super::{Args, OutFile, write_files};
use crate::Ctx;
use crate::render::views;

/// An RGB preview from the bands lettered R, G, B (a missing colour is black):
/// `f(value)` in `[0, 1]` per channel.
fn rgb_preview(
    bands: &[StokesBand],
    n: usize,
    pick: impl Fn(&StokesBand, usize) -> f32,
) -> Vec<u8> {
    let mut px = vec![0u8; 3 * n];
    for (ch, letter) in ['R', 'G', 'B'].into_iter().enumerate() {
        if let Some(b) = bands.iter().find(|b| b.letter == Some(letter)) {
            for i in 0..n {
                let v = pick(b, i);
                px[3 * i + ch] = if v.is_finite() {
                    (v.clamp(0.0, 1.0) * 255.0).round() as u8
                } else {
                    0
                };
            }
        }
    }
    px
}

/// Write the per-band images and previews of a colour mosaic's Stokes result.
pub fn write(args: &Args, r: &StokesResult, ctx: &Ctx) -> anyhow::Result<()> {
    let (w, h, bands) = (r.width, r.height, &r.bands);
    let n = w * h;
    let all_dolp: Vec<f32> = bands
        .iter()
        .flat_map(|b| b.dolp.iter().step_by(7).copied())
        .collect();
    let dolp_max = args.dolp_max.resolve(&all_dolp);
    // S0 scale: the 99.5th percentile of every band's finite S0
    let s0s: Vec<f32> = bands
        .iter()
        .flat_map(|b| b.images.s0.iter().step_by(7).copied())
        .collect();
    let scale = match views::sample_quantile(&s0s, 0.995) {
        Some(p) if p > 0.0 => p,
        _ => 1.0,
    };
    drop(s0s);
    let mode = args.aolp_view;
    let mut files: Vec<(String, OutFile)> = Vec::new();
    for b in bands {
        let l = wavelength_label(b.wavelength_nm.unwrap_or(f64::NAN));
        for (q, data) in [
            ("s0", &b.images.s0),
            ("s1", &b.images.s1),
            ("s2", &b.images.s2),
            ("dolp", &b.dolp),
            ("aolp", &b.aolp),
        ] {
            files.push((format!("{q}_{l}.tif"), OutFile::Tiff(data)));
        }
        let m = Some(&b.images.mask[..]);
        files.push((
            format!("dolp_{l}.png"),
            OutFile::png(move || views::dolp_view(w, h, &b.dolp, m, dolp_max)),
        ));
        files.push((
            format!("aolp_{l}.png"),
            OutFile::png(move || views::aolp_view(w, h, &b.aolp, &b.dolp, m, dolp_max, mode)),
        ));
    }
    let bands_ref = &bands[..];
    files.push((
        "s0_rgb.png".into(),
        OutFile::png(move || {
            let px = rgb_preview(bands_ref, n, |b, i| {
                (b.images.s0[i] / scale).max(0.0).powf(1.0 / 2.2)
            });
            (w, h, px)
        }),
    ));
    files.push((
        "dolp_rgb.png".into(),
        OutFile::png(move || (w, h, rgb_preview(bands_ref, n, |b, i| b.dolp[i] / dolp_max))),
    ));
    let n_files = write_files(&args.output, ctx, &r.inputs, (w, h), files)?;
    let per_band: Vec<String> = bands
        .iter()
        .map(|b| {
            let c = b.images.counts;
            format!(
                "{} {} nm: valid {}, saturated {}, dark {}, invalid {}",
                b.letter.unwrap_or('?'),
                wavelength_label(b.wavelength_nm.unwrap_or(f64::NAN)),
                c.valid,
                c.saturated,
                c.dark,
                c.invalid
            )
        })
        .collect();
    ctx.info(format!(
        "polarid stokes: wrote {} files ({w}x{h}, {} bands) to {}; {}",
        n_files,
        bands.len(),
        args.output.display(),
        per_band.join("; ")
    ));
    Ok(())
}
