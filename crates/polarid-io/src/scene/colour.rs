//! Colour polarization scenes (docs/SCENE.md, "Colour cameras"): `[capture] color`,
//! the top-level `bands`, `[sensor] band_response`, and per-band plate values
//! (`n`, `k`, `rho_d` as a number or a table by colour letter) or a library `material`.
//!
//! ```toml
//! bands = { R = 650.0, G = 550.0, B = 450.0 }   # as in a manifest (default: these)
//! library = "builtin-rgb"                       # for `material` (default builtin-rgb)
//! [sensor]
//! band_response = { B = 0.5 }                   # relative response per band (default 1)
//! [capture]
//! kind = "dofp"
//! pattern = [90, 45, 135, 0]
//! color = "RGGB"
//! [[plate]]
//! material = "copper"                           # (n, k) of each band from the library
//! # n = { R = 0.25, G = 0.97, B = 1.25 }        # or given per band
//! # k = { R = 3.61, G = 2.64, B = 2.39 }
//! ```

use std::ops::Range;

use polarid_core::mosaic::{ColourPattern, Pattern};
use toml::Spanned;

use super::SceneBand;
use super::context::Ctx;
use crate::error::Result;
use crate::library::Library;
use crate::manifest::DEFAULT_BANDS;

/// A number of a TOML value (integers too), if it is a finite one.
pub(super) fn as_num(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Integer(i) => Some(*i as f64),
        toml::Value::Float(f) if f.is_finite() => Some(*f),
        _ => None,
    }
}

/// Where a plate's index comes from: its own numbers or a library.
pub(super) struct MaterialSource<'a> {
    /// The scene's `library` (spec as written and its span), default `builtin-rgb`.
    pub(super) spec: Option<&'a Spanned<String>>,
    /// The loaded library (loaded on first use).
    pub(super) loaded: std::cell::OnceCell<Library>,
}

impl Ctx<'_> {
    /// A table `{ LETTER = number, ... }` with single-letter keys (upper-cased), each
    /// value passing `ok`; at least one entry.
    pub(super) fn letter_table(
        &self,
        v: &Spanned<toml::Value>,
        field: &str,
        ok: impl Fn(f64) -> bool,
        expected: &str,
    ) -> Result<Vec<(char, f64)>> {
        let span = v.span();
        let toml::Value::Table(t) = v.get_ref() else {
            return Err(self.err(
                &span,
                field,
                "expected a table by colour letter, e.g. { R = 650.0, G = 550.0, B = 450.0 }",
            ));
        };
        let mut out: Vec<(char, f64)> = Vec::new();
        for (k, x) in t {
            let f = format!("{field}.{k}");
            let mut cs = k.chars();
            let c = match (cs.next(), cs.next()) {
                (Some(c), None) if c.is_ascii_alphabetic() => c.to_ascii_uppercase(),
                _ => {
                    return Err(self.err(
                        &span,
                        &f,
                        "keys are single colour letters (R, G, B, ...)",
                    ));
                }
            };
            if out.iter().any(|(d, _)| *d == c) {
                return Err(self.err(&span, &f, "colour given twice"));
            }
            match as_num(x).filter(|&x| ok(x)) {
                Some(x) => out.push((c, x)),
                None => return Err(self.err(&span, &f, format!("must be {expected}"))),
            }
        }
        if out.is_empty() {
            return Err(self.err(&span, field, "no colour given"));
        }
        Ok(out)
    }

    /// A colour capture (`[capture] kind = "dofp"` with `color`): the pattern and its
    /// bands, with wavelengths from `bands` (default R 650, G 550, B 450 nm) and
    /// responses from `band_response` (default 1).
    pub(super) fn colour_capture(
        &self,
        polar: Pattern,
        color: &Spanned<String>,
        bands: Option<&Spanned<toml::Value>>,
        response: Option<&Spanned<toml::Value>>,
    ) -> Result<(ColourPattern, Vec<SceneBand>)> {
        let pattern = ColourPattern::new(polar, color.get_ref())
            .map_err(|e| self.err(&color.span(), "capture.color", e.to_string()))?;
        let given = match bands {
            Some(v) => self.letter_table(v, "bands", |x| x > 0.0, "a wavelength > 0 nm")?,
            None => DEFAULT_BANDS.to_vec(),
        };
        let resp = match response {
            Some(v) => self.letter_table(
                v,
                "sensor.band_response",
                |x| x > 0.0 && x <= 1e6,
                "a relative response > 0",
            )?,
            None => Vec::new(),
        };
        let letters = pattern.bands();
        for (table, field, span) in [
            (&given, "bands", bands.map(|v| v.span())),
            (&resp, "sensor.band_response", response.map(|v| v.span())),
        ] {
            if let (Some((c, _)), Some(span)) =
                (table.iter().find(|(c, _)| !letters.contains(c)), span)
            {
                return Err(self.err(
                    &span,
                    &format!("{field}.{c}"),
                    format!(
                        "colour `{c}` is not in the capture's color {:?}",
                        pattern.color()
                    ),
                ));
            }
        }
        let mut out = Vec::with_capacity(letters.len());
        for &c in letters {
            let Some(&(_, wavelength_nm)) = given.iter().find(|(d, _)| *d == c) else {
                return Err(self.err(
                    &bands.map_or(color.span(), |v| v.span()),
                    "bands",
                    format!(
                        "band missing: colour `{c}` of color {:?} has no wavelength; add it, \
                         e.g. bands = {{ {c} = 600.0 }}",
                        pattern.color()
                    ),
                ));
            };
            let response = resp.iter().find(|(d, _)| *d == c).map_or(1.0, |&(_, r)| r);
            out.push(SceneBand {
                letter: c,
                wavelength_nm,
                response,
            });
        }
        Ok((pattern, out))
    }

    /// A plate value given as a number (every band) or, in a colour scene, a table by
    /// colour letter (every band of the capture): one value per band (one for a
    /// single-band scene).
    pub(super) fn per_band(
        &self,
        v: &Spanned<toml::Value>,
        field: &str,
        bands: Option<&[SceneBand]>,
        ok: impl Fn(f64) -> bool,
        expected: &str,
    ) -> Result<Vec<f64>> {
        let span = v.span();
        let nb = bands.map_or(1, <[SceneBand]>::len);
        if let Some(x) = as_num(v.get_ref()) {
            if !ok(x) {
                return Err(self.err(&span, field, format!("must be {expected}")));
            }
            return Ok(vec![x; nb]);
        }
        let Some(bands) = bands else {
            return Err(self.err(
                &span,
                field,
                "expected a finite number (a table by colour letter is for colour captures, \
                 [capture] color)",
            ));
        };
        if !matches!(v.get_ref(), toml::Value::Table(_)) {
            return Err(self.err(
                &span,
                field,
                "expected a finite number, or a table by colour letter (e.g. { R = 0.25, \
                 G = 0.97, B = 1.25 })",
            ));
        }
        let t = self.letter_table(v, field, ok, expected)?;
        let mut out = Vec::with_capacity(nb);
        for b in bands {
            match t.iter().find(|(c, _)| *c == b.letter) {
                Some(&(_, x)) => out.push(x),
                None => {
                    return Err(self.err(
                        &span,
                        &format!("{field}.{}", b.letter),
                        format!("missing: every band of the capture needs a value ({})", {
                            let l: String = bands.iter().map(|b| b.letter).collect();
                            l
                        }),
                    ));
                }
            }
        }
        if let Some((c, _)) = t
            .iter()
            .find(|(c, _)| !bands.iter().any(|b| b.letter == *c))
        {
            return Err(self.err(
                &span,
                &format!("{field}.{c}"),
                "colour not in the capture's color",
            ));
        }
        Ok(out)
    }

    /// The `(n, k)` of library material `name` in each band (a single-band scene: at
    /// `wavelength_nm`, default 650 nm), from the scene's `library`.
    pub(super) fn material_nk(
        &self,
        src: &MaterialSource<'_>,
        name: &Spanned<String>,
        field: &str,
        bands: Option<&[SceneBand]>,
        wavelength_nm: Option<f64>,
    ) -> Result<Vec<(f64, f64)>> {
        let lib = self.library(src)?;
        let span: Range<usize> = name.span();
        let m = name.get_ref();
        let entries: Vec<&crate::library::Material> =
            lib.materials.iter().filter(|x| &x.name == m).collect();
        if entries.is_empty() {
            return Err(self.err(
                &span,
                field,
                format!(
                    "no material {m:?} in library {}; see `polarid library` for the names",
                    lib.source
                ),
            ));
        }
        let wls: Vec<f64> = match bands {
            Some(b) => b.iter().map(|b| b.wavelength_nm).collect(),
            None => vec![wavelength_nm.unwrap_or(650.0)],
        };
        let mut out = Vec::with_capacity(wls.len());
        for wl in wls {
            let hit = entries
                .iter()
                .find(|e| e.wavelength_nm.is_some_and(|w| (w - wl).abs() <= 0.5))
                .or_else(|| {
                    // A single-band library (no wavelength) serves single-band scenes.
                    (bands.is_none() && entries.len() == 1 && entries[0].wavelength_nm.is_none())
                        .then_some(&entries[0])
                });
            match hit {
                Some(e) => out.push((e.n, e.k)),
                None => {
                    let have: Vec<String> = entries
                        .iter()
                        .map(|e| {
                            e.wavelength_nm
                                .map_or("no wavelength".into(), |w| format!("{w} nm"))
                        })
                        .collect();
                    return Err(self.err(
                        &span,
                        field,
                        format!(
                            "library {} has {m:?} at {} only, not at {wl} nm (within 0.5 nm)",
                            lib.source,
                            have.join(", ")
                        ),
                    ));
                }
            }
        }
        Ok(out)
    }

    /// The scene's library (loaded once): `builtin-rgb` by default, a built-in name, or
    /// a CSV file relative to the scene file.
    fn library<'s>(&self, src: &'s MaterialSource<'_>) -> Result<&'s Library> {
        if let Some(l) = src.loaded.get() {
            return Ok(l);
        }
        let lib = match src.spec {
            None => Library::builtin_rgb(),
            Some(v) => {
                let spec = v.get_ref();
                let spec = match spec.as_str() {
                    "builtin" | "builtin-rgb" | "paper2007" => spec.clone(),
                    _ => {
                        let p = std::path::Path::new(spec);
                        let p = if p.is_relative() {
                            self.path.parent().map_or(p.to_path_buf(), |d| d.join(p))
                        } else {
                            p.to_path_buf()
                        };
                        p.display().to_string()
                    }
                };
                Library::load(&spec).map_err(|e| {
                    self.err(
                        &v.span(),
                        "library",
                        format!(
                            "cannot read the library: {}",
                            crate::error::chain_message(&e)
                        ),
                    )
                })
            }
        };
        let lib = lib.map_err(|e| {
            self.err(
                &(0..0),
                "library",
                format!(
                    "cannot read the built-in library: {}",
                    crate::error::chain_message(&e)
                ),
            )
        })?;
        Ok(src.loaded.get_or_init(|| lib))
    }
}
