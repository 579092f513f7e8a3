//! Colour polarization cameras in the manifest (docs/FORMATS.md, "Colour polarization
//! cameras"):
//!
//! ```toml
//! bands = { R = 650.0, G = 550.0, B = 450.0 }   # colour letter -> wavelength, nm
//! [[capture]]
//! dofp = { file = "raw.tif", pattern = [90, 45, 135, 0], color = "RGGB" }
//! ```
//!
//! `color` makes the capture a [`CaptureSource::ColourDofp`]: four colour letters, the
//! colour of each 2×2 polarizer block of the 4×4 period, block-row by block-row. Every
//! letter needs a wavelength: from `bands`, or, when the manifest has no `bands`, the
//! nominal bands of colour sensors [`DEFAULT_BANDS`] (R 650, G 550, B 450 nm). A
//! single-band capture (frames, mono DoFP, Stokes) may carry its own `wavelength_nm`
//! (default: the top-level `wavelength_nm`); a colour capture may not (its bands come
//! from `bands`).
//!
//! Errors name the field and value: `bands.R` (not a positive number), `bands.RG` (a
//! name that is not one colour letter), `capture[2].dofp.color` (not four letters — the
//! pattern does not fill the 4×4 period —, a character that is not a letter, a letter
//! with no band).

use std::ops::Range;

use polarid_core::mosaic::{ColourPattern, Pattern};

use super::{CaptureSource, Parser, Result, Table};

/// The nominal bands of colour polarization sensors used when a manifest has no
/// `bands`: `(letter, wavelength nm)`.
pub const DEFAULT_BANDS: [(char, f64); 3] = [('R', 650.0), ('G', 550.0), ('B', 450.0)];

/// The top-level `bands` of a manifest: `(letter, wavelength nm)` by letter.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Bands {
    /// The bands given, sorted by letter (empty when the manifest has no `bands`).
    pub given: Vec<(char, f64)>,
}

impl Bands {
    /// The wavelength of colour `letter` (upper case): from the given bands, or when
    /// none were given from [`DEFAULT_BANDS`].
    pub fn wavelength(&self, letter: char) -> Option<f64> {
        let table: &[(char, f64)] = if self.given.is_empty() {
            &DEFAULT_BANDS
        } else {
            &self.given
        };
        table.iter().find(|(c, _)| *c == letter).map(|&(_, w)| w)
    }
}

impl Parser<'_> {
    /// The top-level `bands` table (module docs).
    pub(super) fn bands(&self, root: &Table<'_>) -> Result<Bands> {
        let Some(v) = self.get(root, "bands") else {
            return Ok(Bands::default());
        };
        let t = self.table(v, "bands")?;
        let mut given: Vec<(char, f64)> = Vec::new();
        for (k, val) in t.iter() {
            let name = k.get_ref().as_ref();
            let field = format!("bands.{name}");
            let mut chars = name.chars();
            let letter = match (chars.next(), chars.next()) {
                (Some(c), None) if c.is_ascii_alphabetic() => c.to_ascii_uppercase(),
                _ => {
                    return Err(self.err(
                        &k.span(),
                        &field,
                        "band names are single colour letters (R, G, B, ...)",
                    ));
                }
            };
            let w = self.num(val, &field)?;
            if w <= 0.0 {
                return Err(self.err(&val.span(), &field, "wavelength must be > 0 nm"));
            }
            if given.iter().any(|(c, _)| *c == letter) {
                return Err(self.err(&k.span(), &field, "band given twice"));
            }
            given.push((letter, w));
        }
        if given.is_empty() {
            return Err(self.err(&v.span(), "bands", "no band: give e.g. { R = 650.0 }"));
        }
        given.sort_by_key(|&(c, _)| c);
        Ok(Bands { given })
    }

    /// A DoFP capture's `color` (module docs): the colour DoFP source, with the
    /// wavelength of each band of the pattern.
    pub(super) fn colour_dofp(
        &self,
        dt: &Table<'_>,
        field: &str,
        file: std::path::PathBuf,
        pattern: Pattern,
        bands: &Bands,
    ) -> Result<Option<CaptureSource>> {
        let Some(cv) = self.get(dt, "color") else {
            return Ok(None);
        };
        let cf = format!("{field}.color");
        let color = self.string(cv, &cf)?;
        let span: Range<usize> = cv.span();
        if let Some(bad) = color.chars().find(|c| !c.is_ascii_alphabetic()) {
            return Err(self.err(
                &span,
                &cf,
                format!("unknown colour letter `{bad}`: colours are letters (R, G, B, ...)"),
            ));
        }
        if color.chars().count() != 4 {
            return Err(self.err(
                &span,
                &cf,
                format!(
                    "{} colour letter(s) do not match the 4x4 period: give four, the colour \
                     of each 2x2 polarizer block, block-row by block-row (e.g. RGGB)",
                    color.chars().count()
                ),
            ));
        }
        let pattern =
            ColourPattern::new(pattern, &color).map_err(|e| self.err(&span, &cf, e.to_string()))?;
        let mut wavelengths = Vec::new();
        for &c in pattern.bands() {
            match bands.wavelength(c) {
                Some(w) => wavelengths.push(w),
                None => {
                    let known: Vec<String> = if bands.given.is_empty() {
                        DEFAULT_BANDS.iter().map(|(c, _)| c.to_string()).collect()
                    } else {
                        bands.given.iter().map(|(c, _)| c.to_string()).collect()
                    };
                    return Err(self.err(
                        &span,
                        &cf,
                        format!(
                            "band missing: colour `{c}` has no wavelength (bands: {}); add it \
                             to the top-level `bands`, e.g. bands = {{ {c} = 600.0 }}",
                            known.join(", ")
                        ),
                    ));
                }
            }
        }
        Ok(Some(CaptureSource::ColourDofp {
            file,
            pattern,
            wavelengths_nm: wavelengths,
        }))
    }

    /// A single-band capture's own `wavelength_nm`, else `top`; `None` for a colour
    /// capture (which may not have one).
    pub(super) fn capture_wavelength(
        &self,
        t: &Table<'_>,
        pre: &str,
        top: Option<f64>,
        source: &CaptureSource,
    ) -> Result<Option<f64>> {
        let colour = matches!(source, CaptureSource::ColourDofp { .. });
        match self.opt_num(t, "wavelength_nm", pre)? {
            None if colour => Ok(None),
            None => Ok(top),
            Some((_, span)) if matches!(source, CaptureSource::ColourDofp { .. }) => Err(self.err(
                &span,
                &format!("{pre}wavelength_nm"),
                "a colour capture's wavelengths come from the top-level `bands`",
            )),
            Some((v, span)) if v <= 0.0 => Err(self.err(
                &span,
                &format!("{pre}wavelength_nm"),
                "wavelength must be > 0 nm",
            )),
            Some((v, _)) => Ok(Some(v)),
        }
    }
}
