//! `polarid stokes --dofp RAW --color RGGB [--bands R=650,G=550,B=450]`: per-band
//! Stokes, DoLP and AoLP of a colour polarization mosaic
//! ([`polarid_core::mosaic::colour_polar`], one fused pass for all bands), written as
//! `s0_<nm>.tif`, `s1_<nm>.tif`, `s2_<nm>.tif`, `dolp_<nm>.tif`, `aolp_<nm>.tif`,
//! `dolp_<nm>.png`, `aolp_<nm>.png` per band, plus the colour previews `s0_rgb.png`
//! (S0 of the R, G and B bands, gamma 1/2.2, scaled to the 99.5th percentile) and
//! `dolp_rgb.png` (DoLP of the R, G, B bands over the DoLP scale). The per-band views
//! are those of [`crate::render::views`] with each band's mask (saturated and dark
//! pixels in their colours); all files are written in parallel ([`super::write_files`]).

use std::path::Path;

use polarid_core::mosaic::{ColourMethod, ColourPattern, DofpOutputs, Pattern, colour_polar};
use polarid_core::stokes::PixelRules;
use polarid_io::IoError;
use polarid_io::atomic::{StagedDir, check_output};
use polarid_io::image::{self, Frame};
use polarid_io::manifest::colour::{band_table, pattern_wavelengths, wavelength_label};

use super::{Args, Demosaic, OutFile, write_files};
use crate::render::views::{self, DolpScale};
use crate::{BadInput, Ctx};

/// The wavelength of each band of `pattern` from `--bands` (`L=NM,...`; default R 650,
/// G 550, B 450).
fn band_wavelengths(pattern: &ColourPattern, spec: &[String]) -> anyhow::Result<Vec<f64>> {
    let mut entries: Vec<(&str, f64)> = Vec::new();
    for item in spec {
        let bad = || {
            BadInput(format!(
                "--bands: expected LETTER=NM (e.g. R=650), got {item:?}"
            ))
        };
        let (k, v) = item.split_once('=').ok_or_else(bad)?;
        entries.push((k, v.trim().parse().map_err(|_| bad())?));
    }
    let table = band_table(entries).map_err(|e| BadInput(format!("--bands: {e}")))?;
    pattern_wavelengths(pattern, &table)
        .map_err(|e| BadInput(format!("--color {}: {e} in --bands", pattern.color())).into())
}

/// The images of one band.
struct Band {
    nm: f64,
    letter: char,
    s: [Vec<f32>; 3],
    mask: Vec<u8>,
    dolp: Vec<f32>,
    aolp: Vec<f32>,
}

/// An RGB preview from the bands lettered R, G, B (a missing colour is black):
/// `f(value)` in `[0, 1]` per channel.
fn rgb_preview(bands: &[Band], n: usize, pick: impl Fn(&Band, usize) -> f32) -> Vec<u8> {
    let mut px = vec![0u8; 3 * n];
    for (ch, letter) in ['R', 'G', 'B'].into_iter().enumerate() {
        if let Some(b) = bands.iter().find(|b| b.letter == letter) {
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

/// Run `polarid stokes` for a colour mosaic (`--dofp` with `--color`).
pub fn run(
    args: &Args,
    raw_path: &Path,
    color: &str,
    rules_of: impl Fn(&Frame) -> PixelRules,
    ctx: &Ctx,
) -> anyhow::Result<()> {
    let pattern = ColourPattern::new(Pattern::new(&args.pattern)?, color)
        .map_err(|e| BadInput(format!("--color: {e}")))?;
    let wavelengths = band_wavelengths(&pattern, &args.bands)?;
    let raw = image::read_frame(raw_path)?;
    let rules = rules_of(&raw);
    let method = match args.demosaic {
        Demosaic::Bilinear => ColourMethod::Bilinear,
        Demosaic::Superpixel => ColourMethod::Superpixel,
    };
    let (w, h) = method.output_size(raw.width, raw.height);
    let n = w * h;
    let mut bands: Vec<Band> = pattern
        .bands()
        .iter()
        .zip(&wavelengths)
        .map(|(&letter, &nm)| Band {
            nm,
            letter,
            s: [vec![0f32; n], vec![0f32; n], vec![0f32; n]],
            mask: vec![0u8; n],
            dolp: vec![0f32; n],
            aolp: vec![0f32; n],
        })
        .collect();
    let outs = bands
        .iter_mut()
        .map(|b| {
            let [s0, s1, s2] = &mut b.s;
            DofpOutputs {
                s0: Some(s0),
                s1: Some(s1),
                s2: Some(s2),
                mask: Some(&mut b.mask),
                dolp: Some(&mut b.dolp),
                aolp: Some(&mut b.aolp),
            }
        })
        .collect();
    let counts =
        colour_polar(&raw.data, raw.width, &pattern, method, &rules, outs).map_err(|source| {
            IoError::Core {
                path: raw.path.clone(),
                source,
            }
        })?;
    drop(raw);
    let all_dolp: Vec<f32> = bands
        .iter()
        .flat_map(|b| b.dolp.iter().step_by(7).copied())
        .collect();
    let dolp_max = match args.dolp_max {
        DolpScale::Fixed(m) => m,
        DolpScale::Auto => views::auto_dolp_max(&all_dolp),
    };
    // S0 scale: the 99.5th percentile of every band's finite S0
    let s0s: Vec<f32> = bands
        .iter()
        .flat_map(|b| b.s[0].iter().step_by(7).copied())
        .collect();
    let scale = match views::sample_quantile(&s0s, 0.995) {
        Some(p) if p > 0.0 => p,
        _ => 1.0,
    };
    drop(s0s);
    let mode = args.aolp_view;
    let mut files: Vec<(String, OutFile)> = Vec::new();
    for b in &bands {
        let l = wavelength_label(b.nm);
        for (q, data) in [
            ("s0", &b.s[0]),
            ("s1", &b.s[1]),
            ("s2", &b.s[2]),
            ("dolp", &b.dolp),
            ("aolp", &b.aolp),
        ] {
            files.push((format!("{q}_{l}.tif"), OutFile::Tiff(data)));
        }
        let m = Some(&b.mask[..]);
        files.push((
            format!("dolp_{l}.png"),
            OutFile::png(move || views::dolp_view(w, h, &b.dolp, m, dolp_max)),
        ));
        files.push((
            format!("aolp_{l}.png"),
            OutFile::png(move || views::aolp_view(w, h, &b.aolp, &b.dolp, m, dolp_max, mode)),
        ));
    }
    let bands_ref = &bands;
    files.push((
        "s0_rgb.png".into(),
        OutFile::png(move || {
            let px = rgb_preview(bands_ref, n, |b, i| {
                (b.s[0][i] / scale).max(0.0).powf(1.0 / 2.2)
            });
            (w, h, px)
        }),
    ));
    files.push((
        "dolp_rgb.png".into(),
        OutFile::png(move || (w, h, rgb_preview(bands_ref, n, |b, i| b.dolp[i] / dolp_max))),
    ));
    let staged = StagedDir::new(&args.output, ctx.force)?;
    for (name, _) in &files {
        check_output(&staged.final_path(name), ctx.force, &[raw_path])?;
    }
    let n_files = files.len();
    write_files(&staged, w, h, files)?;
    staged.commit()?;
    let per_band: Vec<String> = bands
        .iter()
        .zip(&counts)
        .map(|(b, c)| {
            format!(
                "{} {} nm: valid {}, saturated {}, dark {}, invalid {}",
                b.letter,
                wavelength_label(b.nm),
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
