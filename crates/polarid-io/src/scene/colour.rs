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
            return Err(self.err(&span, field, lib.unknown_material(m)));
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

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::scene::tests::parse_err as err;
    use crate::scene::{CaptureKind, parse};

    const COLOUR: &str = r#"
width = 32
height = 32
theta_r_deg = 60
theta_i_deg = [40, 50]
bands = { R = 650.0, G = 550.0, B = 450.0 }

[sensor]
band_response = { B = 0.5 }

[capture]
kind = "dofp"
color = "RGGB"

[[plate]]
name = "cu"
material = "copper"
sigma = 0.2
rect = [0, 0, 16, 32]

[[plate]]
name = "paint"
class = "paint"
n = { R = 1.39, G = 1.42, B = 1.45 }
k = { R = 0.34, G = 0.12, B = 0.30 }
rho_d = 0.1
sigma = 0.3
rect = [16, 0, 16, 32]
"#;

    #[test]
    fn colour_scene_has_bands_and_per_band_optics() {
        let s = parse(Path::new("s.toml"), COLOUR).unwrap();
        let CaptureKind::ColourDofp { pattern, bands } = &s.capture else {
            panic!("colour capture expected")
        };
        assert_eq!(pattern.color(), "RGGB");
        let wl: Vec<(char, f64, f64)> = bands
            .iter()
            .map(|b| (b.letter, b.wavelength_nm, b.response))
            .collect();
        assert_eq!(
            wl,
            vec![('R', 650.0, 1.0), ('G', 550.0, 1.0), ('B', 450.0, 0.5)]
        );
        // copper from builtin-rgb, band by band (R, G, B).
        let lib = crate::library::Library::builtin_rgb().unwrap();
        let cu = &s.plates[0];
        assert_eq!(cu.material.as_deref(), Some("copper"));
        assert_eq!(cu.class.as_deref(), Some("copper"));
        for (o, b) in cu.bands.iter().zip(bands) {
            let m = lib
                .materials
                .iter()
                .find(|m| m.name == "copper" && m.wavelength_nm == Some(b.wavelength_nm))
                .unwrap();
            assert_eq!((o.n, o.k, o.sigma), (m.n, m.k, 0.2));
        }
        assert_eq!(cu.optics, cu.bands[0]);
        let p = &s.plates[1];
        let nk: Vec<(f64, f64, f64)> = p.bands.iter().map(|o| (o.n, o.k, o.rho_d)).collect();
        assert_eq!(
            nk,
            vec![(1.39, 0.34, 0.1), (1.42, 0.12, 0.1), (1.45, 0.30, 0.1)]
        );
        // Without `bands`: R 650, G 550, B 450 nm.
        let s = parse(
            Path::new("s.toml"),
            &COLOUR.replace("bands = { R = 650.0, G = 550.0, B = 450.0 }", ""),
        )
        .unwrap();
        assert_eq!(s.capture.bands().unwrap()[2].wavelength_nm, 450.0);
    }

    #[test]
    fn material_in_a_single_band_scene_takes_the_scene_wavelength() {
        let mono = COLOUR
            .replace(
                "bands = { R = 650.0, G = 550.0, B = 450.0 }",
                "wavelength_nm = 550",
            )
            .replace("band_response = { B = 0.5 }", "")
            .replace("color = \"RGGB\"", "")
            .replace("n = { R = 1.39, G = 1.42, B = 1.45 }", "n = 1.4")
            .replace("k = { R = 0.34, G = 0.12, B = 0.30 }", "k = 0.1");
        let s = parse(Path::new("s.toml"), &mono).unwrap();
        assert!(s.plates[0].bands.is_empty());
        let lib = crate::library::Library::builtin_rgb().unwrap();
        let m = lib
            .materials
            .iter()
            .find(|m| m.name == "copper" && m.wavelength_nm == Some(550.0))
            .unwrap();
        assert_eq!((s.plates[0].optics.n, s.plates[0].optics.k), (m.n, m.k));
        assert!(matches!(s.capture, CaptureKind::Dofp { .. }));
    }

    #[test]
    fn colour_errors_name_the_field() {
        let e = err(&COLOUR.replace("color = \"RGGB\"", "color = \"RGB\""));
        assert!(e.contains("capture.color") && e.contains("four"), "{e}");
        let e = err(&COLOUR.replace("R = 650.0, ", ""));
        assert!(e.contains("bands") && e.contains("band missing"), "{e}");
        let e = err(&COLOUR.replace("material = \"copper\"", "material = \"unobtainium\""));
        assert!(
            e.contains("plate[1].material") && e.contains("unobtainium"),
            "{e}"
        );
        let e = err(&COLOUR.replace("material = \"copper\"", "material = \"PMMA\""));
        assert!(
            e.contains("plate[1].material") && e.contains("450 nm"),
            "{e}"
        );
        let e = err(&COLOUR.replace(
            "n = { R = 1.39, G = 1.42, B = 1.45 }",
            "n = { R = 1.39, G = 1.42 }",
        ));
        assert!(e.contains("plate[2].n.B") && e.contains("missing"), "{e}");
        let e = err(&COLOUR.replace(
            "k = { R = 0.34, G = 0.12, B = 0.30 }",
            "k = { R = 0.34, G = -1, B = 0.3 }",
        ));
        assert!(e.contains("plate[2].k.G"), "{e}");
        let e = err(&COLOUR.replace("sigma = 0.2\n", "sigma = 0.2\nn = 1.0\n"));
        assert!(e.contains("plate[1].n") && e.contains("not both"), "{e}");
        let e = err(&COLOUR.replace("[capture]\nkind = \"dofp\"\ncolor = \"RGGB\"", ""));
        assert!(e.contains("bands") && e.contains("colour captures"), "{e}");
        let e = err(&COLOUR.replace(
            "theta_i_deg = [40, 50]",
            "theta_i_deg = [40, 50]\nwavelength_nm = 600",
        ));
        assert!(e.contains("wavelength_nm") && e.contains("bands"), "{e}");
        let e = err(&COLOUR.replace("{ B = 0.5 }", "{ Y = 0.5 }"));
        assert!(e.contains("sensor.band_response.Y"), "{e}");
        let e = err(&COLOUR.replace(
            "theta_i_deg = [40, 50]",
            "theta_i_deg = [40, 50]\nlibrary = \"no/such.csv\"",
        ));
        assert!(e.contains("`library`") && e.contains("cannot read"), "{e}");
    }
}
