//! refractiveindex.info YAML → a material library for one or several filter bands
//! (`polarid library`).
//!
//! With several bands (a colour camera: `--band 410:490 --band 510:590 --band
//! 610:690`), each material gets one row per band with `wavelength_nm`, the band's centre
//! `(LO + HI)/2`; with one band the library has no `wavelength_nm` column, as before.
//!
//! Each file gives one material: the arithmetic means of `n` and of `k` over the band,
//! sampled every `step` nm ([`RiiData::band_mean`], the method of the built-in 650 nm
//! library: band 610:690, step 1 reproduces it). Nothing is extrapolated: a file whose
//! data do not cover the whole band is an error naming the file, the band and the data's
//! range, or is skipped with a warning when the configuration says so.
//!
//! Names: by default the file stem, prefixed with the material folder in the database's
//! layout `shelf/BOOK/nk/PAGE.yml` (`main/Au/nk/Johnson.yml` → `Au_Johnson`), blanks
//! replaced by `_`. A names map (CSV, columns `file,name`, optional `category`,
//! `reference`) names files explicitly; `file` is matched against the end of each YAML
//! path, whole components only (`main/Au/nk/Johnson.yml` or `Au/nk/Johnson.yml`).
//!
//! Categories: the map's `category`, else the nearest folder named `metal`, `dielectric`,
//! `semiconductor` or `other` between a file and the directory input it was found in (that
//! directory included), else the configuration's category, else empty.
//!
//! Surfaces (materials as they are found, [`polarid_io::surfaces`]): the map's optional
//! `layer`, `layer_min_nm`, `layer_max_nm` (and `layer_n`, `layer_k`, a constant index
//! for a layer material without built-in data; `layer` = `none`: no layer), else the
//! built-in surface of a file behind a built-in material
//! ([`polarid_io::library::BUILTIN_SOURCES`], matched by its database path) or of a
//! material named like a built-in one, else none. The layer's index in each band is the
//! band mean of its data over the same band and step as the bulk; where its data do not
//! cover the band, the row keeps the layer without an index, with a warning.
//!
//! [`build_library`] returns the materials; writing the library CSV (with
//! [`LibraryConfig::comment`]) is the caller's.

mod sources;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use polarid_core::classify::check_class_name;
use polarid_io::IoError;
use polarid_io::library::{BUILTIN_SOURCES, Material, MaterialLayer, RiiData};
use polarid_io::surfaces::{builtin_surface, layer_index};

pub use sources::default_name;

use crate::error::{PipelineError, Result, ensure};
use crate::progress::{Progress, Warning};

/// Largest number of samples of one band mean (guards against `step = 1e-9`).
pub const MAX_SAMPLES: f64 = 1e6;

/// A wavelength band in nm, `lo <= hi` (`lo == hi`: one wavelength).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Band {
    /// Lower end, nm.
    pub lo: f64,
    /// Upper end, nm.
    pub hi: f64,
}

impl Band {
    /// The centre `(lo + hi)/2`, nm: the `wavelength_nm` of the band's rows.
    pub fn centre(&self) -> f64 {
        0.5 * (self.lo + self.hi)
    }
}

impl std::fmt::Display for Band {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.lo == self.hi {
            write!(f, "{} nm", self.lo)
        } else {
            write!(f, "{}–{} nm", self.lo, self.hi)
        }
    }
}

/// Parse `LO:HI` or `WL` (nm) into a [`Band`]; both ends finite and > 0, `LO <= HI`.
/// The error is a sentence for a command-line parser.
pub fn parse_band(s: &str) -> std::result::Result<Band, String> {
    let num = |t: &str, what: &str| -> std::result::Result<f64, String> {
        let v: f64 = t
            .trim()
            .parse()
            .map_err(|_| format!("{what} {t:?} is not a number (expected LO:HI or WL in nm)"))?;
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("{what} {t:?} must be a finite wavelength > 0 nm"));
        }
        Ok(v)
    };
    let band = match s.split_once(':') {
        Some((a, b)) => Band {
            lo: num(a, "LO")?,
            hi: num(b, "HI")?,
        },
        None => {
            let wl = num(s, "WL")?;
            Band { lo: wl, hi: wl }
        }
    };
    if band.hi < band.lo {
        return Err(format!(
            "empty band: HI {} nm is below LO {} nm",
            band.hi, band.lo
        ));
    }
    Ok(band)
}

/// Sample wavelengths (nm) of the band mean: first and last, and their count, exactly as
/// [`RiiData::band_mean`] takes them.
fn samples(band: Band, step: f64) -> (f64, f64, usize) {
    let count = ((band.hi - band.lo) / step + 1e-9).floor() as usize + 1;
    (band.lo, band.lo + (count - 1) as f64 * step, count)
}

/// The validated options of a library build.
#[derive(Debug, Clone, PartialEq)]
pub struct LibraryConfig {
    bands: Vec<Band>,
    step: f64,
    category: Option<String>,
    skip_missing: bool,
}

impl LibraryConfig {
    /// Check the options: one or more bands of finite wavelengths > 0 with `lo <= hi`,
    /// with distinct centres, a sampling step > 0 nm giving at most [`MAX_SAMPLES`]
    /// samples, a non-empty default `category`; `skip_missing` skips files that do not
    /// cover a band (with a warning) instead of failing. Errors name `--band`, `--step`,
    /// `--category`.
    pub fn new(
        bands: Vec<Band>,
        step: f64,
        category: Option<String>,
        skip_missing: bool,
    ) -> Result<Self> {
        let ok = |x: f64| x.is_finite() && x > 0.0;
        ensure(
            !bands.is_empty(),
            "--band",
            "none",
            "is needed at least once",
        )?;
        for (i, band) in bands.iter().enumerate() {
            ensure(
                ok(band.lo) && ok(band.hi) && band.lo <= band.hi,
                "--band",
                format!("{}:{}", band.lo, band.hi),
                "must be LO:HI with finite wavelengths 0 < LO <= HI nm",
            )?;
            let centre = Some(band.centre());
            let earlier = bands[..i]
                .iter()
                .any(|b| polarid_core::classify::same_band(Some(b.centre()), centre));
            ensure(
                !earlier,
                "--band",
                band,
                "has the same centre as an earlier --band",
            )?;
        }
        ensure(ok(step), "--step", step, "must be a step > 0 nm")?;
        for &band in &bands {
            let (_, _, count) = samples(band, step);
            ensure(
                count as f64 <= MAX_SAMPLES,
                "--step",
                step,
                format!("gives {count} samples over the band {band} (at most {MAX_SAMPLES})"),
            )?;
        }
        if let Some(c) = &category {
            let why = "must be a non-empty category name";
            ensure(!c.trim().is_empty(), "--category", format!("{c:?}"), why)?;
        }
        Ok(Self {
            bands,
            step,
            category,
            skip_missing,
        })
    }

    /// The first band.
    pub fn band(&self) -> Band {
        self.bands[0] // ok: `new` checks there is at least one
    }

    /// The bands.
    pub fn bands(&self) -> &[Band] {
        &self.bands
    }

    /// Number of samples of the first band's means.
    pub fn samples(&self) -> usize {
        samples(self.band(), self.step).2
    }

    /// The comment line of the library CSV: the data's origin and the sampling.
    pub fn comment(&self) -> String {
        let one = |band: Band| {
            let count = samples(band, self.step).2;
            if count == 1 {
                format!("n, k at {} nm", band.lo)
            } else {
                format!(
                    "n, k over {}: mean of {count} samples every {} nm",
                    band, self.step
                )
            }
        };
        let sampling = if self.bands.len() == 1 {
            one(self.band())
        } else {
            self.bands
                .iter()
                .map(|&b| format!("wavelength_nm {}: {}", b.centre(), one(b)))
                .collect::<Vec<_>>()
                .join("; ")
        };
        format!(
            "polarid library: refractiveindex.info data (CC0; cite M. N. Polyanskiy, Sci. \
             Data 11, 94 (2024) and each file's REFERENCES). {sampling}; tabulated data \
             linearly interpolated, k = 0 where only n is given"
        )
    }
}

/// The result of [`build_library`].
#[derive(Debug, Clone, Default)]
pub struct LibraryBuild {
    /// The materials, in input order.
    pub materials: Vec<Material>,
    /// Every YAML file read (folders expanded), in order.
    pub files: Vec<PathBuf>,
    /// The files skipped because their data do not cover the band, and the surface
    /// layers whose data do not cover a band.
    pub warnings: Vec<Warning>,
    /// How many files were skipped.
    pub skipped: usize,
}

fn nm(x_um: f64) -> String {
    format!("{:.1}", x_um * 1e3)
}

/// The mean `(n, k)` of file `s`'s `data` in every band of `cfg`. A band the data do not
/// cover is skipped with a warning under `--skip-missing` (counted in `out.skipped`),
/// else an error; so is a mean that is not a usable index.
fn band_means(
    cfg: &LibraryConfig,
    s: &sources::Source,
    data: &RiiData,
    out: &mut LibraryBuild,
) -> Result<Vec<(Band, f64, f64)>> {
    let (lo_um, hi_um) = data.range_um();
    let model_err = |reason| -> PipelineError {
        let path = s.path.clone();
        IoError::Model { path, reason }.into()
    };
    let mut rows: Vec<(Band, f64, f64)> = Vec::new();
    for &band in &cfg.bands {
        let (first, last, _) = samples(band, cfg.step);
        if !(first / 1e3 >= lo_um && last / 1e3 <= hi_um) {
            let what = format!(
                "band {band} is not covered by the data, whose range is {}–{} nm \
                 (no extrapolation)",
                nm(lo_um),
                nm(hi_um)
            );
            if cfg.skip_missing {
                out.warnings
                    .push(Warning(format!("{}: {what}; skipped", s.path.display())));
                out.skipped += 1;
                continue;
            }
            return Err(model_err(format!(
                "{what}; choose another band or pass --skip-missing"
            )));
        }
        let (n, k) = data.band_mean(band.lo, band.hi, cfg.step)?;
        if !(n > 0.0 && k >= 0.0) {
            return Err(model_err(format!(
                "band mean n = {n}, k = {k} over {band} is not a usable index \
                 (need n > 0, k >= 0)"
            )));
        }
        rows.push((band, n, k));
    }
    Ok(rows)
}

/// The surface layer of file `s` (material `name`): as the names map gives it
/// (`given`), else the built-in surface of its built-in source or of its name.
fn surface_layer(
    given: Option<Option<sources::LayerSpec>>,
    s: &sources::Source,
    name: &str,
) -> Option<sources::LayerSpec> {
    match given {
        Some(spec) => spec,
        None => BUILTIN_SOURCES
            .iter()
            .find(|b| s.path.ends_with(b.file))
            .map(|b| b.name)
            .and_then(builtin_surface)
            .or_else(|| builtin_surface(name))
            .map(|b| sources::LayerSpec {
                name: b.layer.to_string(),
                min_nm: b.min_nm,
                max_nm: b.max_nm,
                index: None,
            }),
    }
}

/// Surface layer `l` of file `s` in `band`: its index there (given, or the band mean of
/// its data; a warning when they do not cover the band).
fn layer_in_band(
    l: &sources::LayerSpec,
    band: Band,
    cfg: &LibraryConfig,
    s: &sources::Source,
    warnings: &mut Vec<Warning>,
) -> Result<MaterialLayer> {
    let index = match l.index {
        Some(x) => Some(x),
        None => layer_index(&l.name, band.lo, band.hi, cfg.step)?,
    };
    if index.is_none() {
        warnings.push(Warning(format!(
            "{}: the data of surface layer {} do not cover band {band}; \
             the layer has no index there",
            s.path.display(),
            l.name
        )));
    }
    Ok(MaterialLayer {
        name: l.name.clone(),
        index,
        min_nm: l.min_nm,
        max_nm: l.max_nm,
    })
}

/// Build a library from YAML files or folders of them (`inputs`) and an optional names
/// map (CSV). Progress stage `"files"`.
pub fn build_library(
    cfg: &LibraryConfig,
    inputs: &[PathBuf],
    names_map: Option<&Path>,
    progress: Progress<'_>,
) -> Result<LibraryBuild> {
    let srcs = sources::sources(inputs)?;
    let mapped = match names_map {
        Some(map) => sources::read_names(map, &srcs)?,
        None => BTreeMap::new(),
    };
    let multi = cfg.bands.len() > 1;
    let mut out = LibraryBuild::default();
    let mut names: BTreeMap<String, PathBuf> = BTreeMap::new();
    for (i, s) in srcs.iter().enumerate() {
        progress("files", i as u64, srcs.len() as u64);
        let data = RiiData::read(&s.path)?;
        let rows = band_means(cfg, s, &data, &mut out)?;
        if rows.is_empty() {
            continue;
        }
        let m = mapped.get(&i).cloned().unwrap_or_default();
        let name = m.name.unwrap_or_else(|| default_name(&s.path));
        let data_err = |reason: String| PipelineError::Data {
            path: s.path.display().to_string(),
            reason,
        };
        check_class_name(&name)
            .map_err(|e| data_err(format!("default name {name:?}: {e}; name it with --names")))?;
        if let Some(prev) = names.insert(name.clone(), s.path.clone()) {
            return Err(data_err(format!(
                "name {name:?} is also the name of {}; name them with --names MAP.csv",
                prev.display()
            )));
        }
        let category = m
            .category
            .or_else(|| sources::folder_category(s))
            .or_else(|| cfg.category.clone());
        let reference = m.reference.or_else(|| Some(s.rel.display().to_string()));
        let layer = surface_layer(m.layer, s, &name);
        for (band, n, k) in rows {
            let layer = layer
                .as_ref()
                .map(|l| layer_in_band(l, band, cfg, s, &mut out.warnings))
                .transpose()?;
            out.materials.push(Material {
                name: name.clone(),
                category: category.clone(),
                n,
                k,
                reference: reference.clone(),
                line: 0,
                wavelength_nm: multi.then(|| band.centre()),
                layer,
            });
        }
    }
    progress("files", srcs.len() as u64, srcs.len() as u64);
    let why = "is covered by no input file (every file was skipped)";
    ensure(!out.materials.is_empty(), "--band", cfg.band(), why)?;
    out.files = srcs.into_iter().map(|s| s.path).collect();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_syntax() {
        assert_eq!(
            parse_band("520:545"),
            Ok(Band {
                lo: 520.0,
                hi: 545.0
            })
        );
        assert_eq!(
            parse_band("532"),
            Ok(Band {
                lo: 532.0,
                hi: 532.0
            })
        );
        assert!(parse_band("545:520").unwrap_err().contains("empty band"));
        assert!(parse_band("5x0:545").unwrap_err().contains("\"5x0\""));
        assert!(parse_band("-5").unwrap_err().contains("> 0"));
        assert!(parse_band("nan").is_err());
    }

    #[test]
    fn samples_match_band_mean() {
        let b = Band {
            lo: 610.0,
            hi: 690.0,
        };
        assert_eq!(samples(b, 1.0), (610.0, 690.0, 81));
        assert_eq!(samples(b, 30.0), (610.0, 670.0, 3));
        assert_eq!(
            samples(
                Band {
                    lo: 532.0,
                    hi: 532.0
                },
                1.0
            ),
            (532.0, 532.0, 1)
        );
    }

    #[test]
    fn config_checks() {
        let b = Band {
            lo: 500.0,
            hi: 800.0,
        };
        assert!(LibraryConfig::new(vec![b], 1.0, None, false).is_ok());
        let e = LibraryConfig::new(vec![b], 1e-9, None, false).unwrap_err();
        assert!(e.to_string().contains("--step") && e.to_string().contains("samples"));
        assert!(LibraryConfig::new(vec![b], 1.0, Some(" ".into()), false).is_err());
        assert!(LibraryConfig::new(vec![b], -1.0, None, false).is_err());
        assert!(LibraryConfig::new(vec![], 1.0, None, false).is_err());
        let e = LibraryConfig::new(vec![b, b], 1.0, None, false).unwrap_err();
        assert!(e.to_string().contains("same centre"), "{e}");
    }
}
