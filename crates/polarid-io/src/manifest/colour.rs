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

/// A wavelength as polarid writes it in file names, column tags and messages: whole
/// nanometres without a decimal point (`450`), others as given (`632.8`).
pub fn wavelength_label(nm: f64) -> String {
    if nm.fract() == 0.0 && nm.abs() < 1e9 {
        format!("{nm:.0}")
    } else {
        format!("{nm}")
    }
}

/// Why a band table (colour letter → wavelength) is refused: the one rule of the
/// manifest's `bands`, `polarid stokes --bands` and the Python functions' `bands`.
/// Front ends prefix the message with their own field or option.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BandTableError {
    /// A key that is not one colour letter.
    #[error("band names are single colour letters (R, G, B, ...), got {0:?}")]
    NotALetter(String),
    /// A wavelength that is not a finite number > 0 nm.
    #[error("wavelength must be > 0 nm, got {nm} for band {letter}")]
    Wavelength {
        /// The band's letter.
        letter: char,
        /// The value given.
        nm: f64,
    },
    /// A letter given twice.
    #[error("band {0} given twice")]
    Twice(char),
    /// A colour of the pattern with no wavelength in the table.
    #[error("band missing: colour {letter} has no wavelength (bands: {known})")]
    Missing {
        /// The pattern's colour letter.
        letter: char,
        /// The table's letters, comma-separated.
        known: String,
    },
}

/// The band table of `entries` (`key`, wavelength nm): each key one colour letter
/// (upper-cased), each wavelength finite and > 0, no letter twice. The table given
/// replaces the defaults; no entry at all gives [`DEFAULT_BANDS`].
pub fn band_table<'a>(
    entries: impl IntoIterator<Item = (&'a str, f64)>,
) -> std::result::Result<Vec<(char, f64)>, BandTableError> {
    let mut table: Vec<(char, f64)> = Vec::new();
    for (key, nm) in entries {
        let mut ch = key.trim().chars();
        let letter = match (ch.next(), ch.next()) {
            (Some(c), None) if c.is_ascii_alphabetic() => c.to_ascii_uppercase(),
            _ => return Err(BandTableError::NotALetter(key.to_string())),
        };
        if !(nm.is_finite() && nm > 0.0) {
            return Err(BandTableError::Wavelength { letter, nm });
        }
        if table.iter().any(|(l, _)| *l == letter) {
            return Err(BandTableError::Twice(letter));
        }
        table.push((letter, nm));
    }
    if table.is_empty() {
        table = DEFAULT_BANDS.to_vec();
    }
    Ok(table)
}

/// The wavelength of each band of `pattern` (in the pattern's band order) from `table`
/// ([`band_table`]).
pub fn pattern_wavelengths(
    pattern: &ColourPattern,
    table: &[(char, f64)],
) -> std::result::Result<Vec<f64>, BandTableError> {
    pattern
        .bands()
        .iter()
        .map(|&c| {
            table
                .iter()
                .find(|(l, _)| *l == c)
                .map(|&(_, w)| w)
                .ok_or_else(|| BandTableError::Missing {
                    letter: c,
                    known: table
                        .iter()
                        .map(|(l, _)| l.to_string())
                        .collect::<Vec<_>>()
                        .join(", "),
                })
        })
        .collect()
}

impl Parser<'_> {
    /// The top-level `bands` table (module docs).
    pub(super) fn bands(&self, root: &Table<'_>) -> Result<Bands> {
        let Some(v) = self.get(root, "bands") else {
            return Ok(Bands::default());
        };
        let t = self.table(v, "bands")?;
        if t.is_empty() {
            return Err(self.err(&v.span(), "bands", "no band: give e.g. { R = 650.0 }"));
        }
        let mut given: Vec<(&str, f64, Range<usize>, Range<usize>)> = Vec::new();
        for (k, val) in t.iter() {
            let name = k.get_ref().as_ref();
            let field = format!("bands.{name}");
            let w = self.num(val, &field)?;
            given.push((name, w, k.span(), val.span()));
        }
        let given = band_table(given.iter().map(|(n, w, ..)| (*n, *w))).map_err(|e| {
            let at = |n: &str| given.iter().find(|g| g.0.trim().eq_ignore_ascii_case(n));
            let (name, span) = match &e {
                BandTableError::NotALetter(n) => (n.clone(), at(n).map(|g| g.2.clone())),
                BandTableError::Wavelength { letter, .. } => {
                    let l = letter.to_string();
                    (l.clone(), at(&l).map(|g| g.3.clone()))
                }
                BandTableError::Twice(letter) => {
                    let l = letter.to_string();
                    (
                        l.clone(),
                        given
                            .iter()
                            .rev()
                            .find(|g| g.0.trim().eq_ignore_ascii_case(&l))
                            .map(|g| g.2.clone()),
                    )
                }
                BandTableError::Missing { letter, .. } => (letter.to_string(), None),
            };
            self.err(
                &span.unwrap_or_else(|| v.span()),
                &format!("bands.{name}"),
                e.to_string(),
            )
        })?;
        let mut given = given;
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

#[cfg(test)]
mod band_table_tests {
    use super::*;

    #[test]
    fn one_rule_for_every_band_table() {
        assert_eq!(band_table([]).expect("empty"), DEFAULT_BANDS.to_vec());
        assert_eq!(
            band_table([("r", 700.0)]).expect("replaces"),
            vec![('R', 700.0)]
        );
        assert_eq!(
            band_table([("RG", 1.0)]),
            Err(BandTableError::NotALetter("RG".into()))
        );
        assert!(matches!(
            band_table([("G", 0.0)]),
            Err(BandTableError::Wavelength { letter: 'G', .. })
        ));
        assert_eq!(
            band_table([("R", 650.0), ("r", 640.0)]),
            Err(BandTableError::Twice('R'))
        );
        let p = ColourPattern::new(
            Pattern::new(&Pattern::IMX250MZR).expect("polarizers"),
            "RGGB",
        )
        .expect("pattern");
        let t = band_table([("R", 700.0), ("G", 532.0)]).expect("table");
        let e = pattern_wavelengths(&p, &t).expect_err("B missing");
        assert!(
            e.to_string()
                .contains("colour B has no wavelength (bands: R, G)"),
            "{e}"
        );
        assert_eq!(wavelength_label(450.0), "450");
        assert_eq!(wavelength_label(632.8), "632.8");
    }
}
