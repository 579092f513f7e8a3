//! The capture-set manifest (TOML) of `docs/FORMATS.md`: one scene, one fixed camera,
//! the source moved between captures; several targets (regions) may share the frame.
//!
//! ```toml
//! theta_r_deg = 60.0        # camera zenith; may be overridden per capture
//! phi_deg = 180.0           # phi_r - phi_i (default 180)
//! dark_level = 0.0          # DN subtracted from every raw frame (default 0)
//! saturation = 4095.0       # DN; raw pixels at or above it are rejected (default: type max)
//! wavelength_nm = 650.0     # optional, informational
//! angle_sd_deg = 0.1        # optional: standard uncertainty of the source and camera directions
//!
//! [[region]]
//! name = "A"
//! rect = [12, 44, 40, 40]   # x (column), y (row), width, height; origin top-left
//! class = "aluminum"        # optional
//! reference = "N-BK7"       # optional: an in-scene reference of known material
//!                           #   (or reference_n, reference_k; docs/FORMATS.md)
//!
//! [[capture]]
//! theta_i_deg = 35.0
//! exposure = 1.0            # optional; S0 is divided by it
//! frames = [ { angle_deg = 0.0, file = "i35/pol000.tif" }, ... ]   # >= 3 distinct angles
//! # or: dofp = { file = "raw.tif", pattern = [90, 45, 135, 0] }   (pattern optional)
//! # or: stokes = { s0 = "s0.tif", s1 = "s1.tif", s2 = "s2.tif" }
//! # or, colour: dofp = { file = "raw.tif", color = "RGGB" } with top-level
//! #   bands = { R = 650.0, G = 550.0, B = 450.0 }   (see [`colour`])
//! ```
//!
//! Per capture, `theta_r_deg`, `phi_deg`, `dark_level`, `saturation` and `angle_sd_deg` may override the
//! top-level values, and `name` may label the capture. Paths are relative to the manifest
//! file. Validation errors are [`IoError::Manifest`] with the manifest's 1-based line
//! number and a dotted field path; array indices in field paths are 1-based
//! (`capture[2].frames[1].file` is the first frame of the second `[[capture]]`).
//! Unknown keys are not errors (FORMATS.md lets users extend files) but are listed in
//! [`Manifest::warnings`] so that a typo does not pass unnoticed.
//!
//! Calibrated geometry (optional, [`calibration`]): a `[camera]` table, `[[plane]]`
//! tables, a `[site]` table, a `plane` per region and a `source` per capture instead of
//! the capture's angles. See [`calibration`] for the tables and their rules.

pub mod calibration;
pub mod colour;
pub mod opencv;
mod reference;
pub mod shared;

pub use calibration::{CameraOrientation, CameraSpec, PlaneSpec, SiteSpec, SourceSpec};
pub use colour::{Bands, DEFAULT_BANDS};

use std::collections::HashSet;
use std::ops::Range;
use std::path::{Path, PathBuf};

use polarid_core::mosaic::{ColourPattern, Pattern};
use polarid_core::region::Rect;
use polarid_core::stokes::StokesSolver;
use toml::Spanned;
use toml::de::{DeTable, DeValue};

use crate::error::{IoError, Result};
use crate::toml_span::TomlText;

/// A validated capture-set manifest.
#[derive(Debug, Clone, PartialEq)]
pub struct Manifest {
    /// The manifest file.
    pub path: PathBuf,
    /// Top-level camera zenith, degrees (if given).
    pub theta_r_deg: Option<f64>,
    /// Top-level `phi_r − phi_i`, degrees (default 180).
    pub phi_deg: f64,
    /// Top-level dark level, DN (default 0).
    pub dark_level: f64,
    /// Top-level saturation level, DN (default: the frames' type maximum).
    pub saturation: Option<f64>,
    /// Informational wavelength, nm (the default of single-band captures'
    /// [`Capture::wavelength_nm`]).
    pub wavelength_nm: Option<f64>,
    /// The colour bands (`bands`) of colour polarization captures ([`colour`]).
    pub bands: Bands,
    /// Top-level standard uncertainty of the geometry's directions, degrees (if given;
    /// docs/ERRORS.md).
    pub angle_sd_deg: Option<f64>,
    /// Top-level dark threshold, DN of dark-subtracted S0 (if given; default
    /// `polarid_io::measure::dark_threshold_dn`).
    pub dark_signal_dn: Option<f64>,
    /// The calibrated camera (`[camera]`), if any: then every capture has a
    /// [`Capture::illumination`] and no angles of its own.
    pub camera: Option<CameraSpec>,
    /// The target planes (`[[plane]]`), never empty: without `[[plane]]` tables, one
    /// plane named `default` through the origin with normal `+z`.
    pub planes: Vec<PlaneSpec>,
    /// The observing site (`[site]`), if any (needed by `sun` sources).
    pub site: Option<SiteSpec>,
    /// The targets.
    pub regions: Vec<Region>,
    /// The captures, in file order.
    pub captures: Vec<Capture>,
    /// Unknown keys that were ignored, one message each (with the line).
    pub warnings: Vec<String>,
}

/// One target region.
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// Unique target name.
    pub name: String,
    /// Pixel rectangle in the coordinates of the files as stored.
    pub rect: Rect,
    /// Known material, if any.
    pub class: Option<String>,
    /// Line of the region's `rect` in the manifest (for later errors, e.g. a rectangle
    /// that leaves the frame).
    pub line: usize,
    /// 1-based index among the `[[region]]` tables.
    pub index: usize,
    /// Index into [`Manifest::planes`] of the plane the region lies on (its `plane`
    /// name; default the first plane).
    pub plane: usize,
    /// The region's known material when it is an in-scene reference (its `reference`, or
    /// `reference_n` and `reference_k`; docs/FORMATS.md "In-scene reference").
    pub reference: Option<crate::table::measurements::Reference>,
}

/// One capture (source position).
#[derive(Debug, Clone, PartialEq)]
pub struct Capture {
    /// 1-based index among the `[[capture]]` tables.
    pub index: usize,
    /// Line of the capture's first key in the manifest.
    pub line: usize,
    /// Optional label.
    pub name: Option<String>,
    /// Source zenith angle, degrees (NaN for a capture with calibrated geometry: see
    /// [`Capture::illumination`]).
    pub theta_i_deg: f64,
    /// Camera zenith angle, degrees (the capture's own or the top-level one; NaN with
    /// calibrated geometry).
    pub theta_r_deg: f64,
    /// `phi_r − phi_i`, degrees (NaN with calibrated geometry).
    pub phi_deg: f64,
    /// The light source of a capture with calibrated geometry (its `source` key, given
    /// when the manifest has a `[camera]`); `None` for far-field captures.
    pub illumination: Option<SourceSpec>,
    /// Relative exposure (S0 is divided by it), default 1.
    pub exposure: f64,
    /// Dark level, DN.
    pub dark_level: f64,
    /// Saturation level, DN (`None`: the frames' type maximum).
    pub saturation: Option<f64>,
    /// Standard uncertainty of the source and camera directions, degrees (the capture's
    /// own `angle_sd_deg` or the top-level one; `None` when neither is given).
    pub angle_sd_deg: Option<f64>,
    /// Dark threshold, DN of dark-subtracted S0: a region whose mean S0 is below it is
    /// `dark` (the capture's own `dark_signal_dn` or the top-level one; `None`: the
    /// default of `polarid_io::measure::dark_threshold_dn`).
    pub dark_signal_dn: Option<f64>,
    /// What was recorded (for an HDR capture: the longest exposure's data, the first of
    /// [`Capture::brackets`]).
    pub source: CaptureSource,
    /// HDR brackets (the `brackets` key): every exposure of the capture, longest first,
    /// merged per pixel by `measure` (docs/FORMATS.md, "HDR brackets"); empty for a
    /// capture with one exposure. [`Capture::exposure`] is then the longest one's.
    pub brackets: Vec<Bracket>,
    /// The wavelength of a single-band capture, nm (its own `wavelength_nm` or the
    /// top-level one); `None` for colour captures (see
    /// [`CaptureSource::ColourDofp::wavelengths_nm`]).
    pub wavelength_nm: Option<f64>,
}

/// One exposure of an HDR capture.
#[derive(Debug, Clone, PartialEq)]
pub struct Bracket {
    /// Relative exposure (time × gain), > 0.
    pub exposure: f64,
    /// Its data: rotating-polarizer frames or a DoFP mosaic (not Stokes images).
    pub source: CaptureSource,
}

impl Region {
    /// An [`IoError::Manifest`] of the manifest at `path` naming this region's `rect`
    /// (its line and value).
    pub fn rect_error(&self, path: &Path, reason: String) -> IoError {
        let r = self.rect;
        IoError::Manifest {
            path: path.to_path_buf(),
            line: self.line,
            field: format!("region[{}].rect", self.index),
            value: format!("[{}, {}, {}, {}]", r.x, r.y, r.width, r.height),
            reason,
        }
    }
}

impl Capture {
    /// An [`IoError::Manifest`] of the manifest at `path` naming this capture's field
    /// `key` (`capture[i].KEY`, at the capture's line) and the value at fault.
    pub fn field_error(
        &self,
        path: &Path,
        key: &str,
        value: impl Into<String>,
        reason: impl Into<String>,
    ) -> IoError {
        IoError::Manifest {
            path: path.to_path_buf(),
            line: self.line,
            field: format!("capture[{}].{key}", self.index),
            value: value.into(),
            reason: reason.into(),
        }
    }

    /// Every file the capture reads (all brackets of an HDR capture).
    pub fn files(&self) -> Vec<&Path> {
        if self.brackets.is_empty() {
            self.source.files()
        } else {
            self.brackets
                .iter()
                .flat_map(|b| b.source.files())
                .collect()
        }
    }
}

/// Why bracket `b` cannot be merged with the first bracket `first`: the key at fault
/// and the reason; `None` when they match (same kind; frames with the same angles in
/// the same order, or DoFP with the same pattern).
fn bracket_mismatch(first: &CaptureSource, b: &CaptureSource) -> Option<(&'static str, String)> {
    match (first, b) {
        (CaptureSource::Frames(a), CaptureSource::Frames(b)) => {
            let a: Vec<f64> = a.iter().map(|f| f.angle_deg).collect();
            let b: Vec<f64> = b.iter().map(|f| f.angle_deg).collect();
            (a != b).then(|| {
                (
                    "frames",
                    format!("the polarizer angles {b:?} differ from those of brackets[1], {a:?}"),
                )
            })
        }
        (CaptureSource::Dofp { pattern: a, .. }, CaptureSource::Dofp { pattern: b, .. }) => {
            (a != b).then(|| {
                (
                    "dofp",
                    "the pattern differs from that of brackets[1]".to_string(),
                )
            })
        }
        (
            CaptureSource::ColourDofp { pattern: a, .. },
            CaptureSource::ColourDofp { pattern: b, .. },
        ) => (a != b).then(|| {
            (
                "dofp",
                "the polarizer or colour pattern differs from that of brackets[1]".to_string(),
            )
        }),
        (CaptureSource::ColourDofp { .. }, _) => Some((
            "dofp",
            "every bracket must hold the same kind of data as brackets[1] (a colour dofp)".into(),
        )),
        (CaptureSource::Dofp { .. }, _) => Some((
            "frames",
            "every bracket must hold the same kind of data as brackets[1] (dofp)".into(),
        )),
        _ => Some((
            "dofp",
            "every bracket must hold the same kind of data as brackets[1] (frames)".into(),
        )),
    }
}

/// One frame of a rotating-polarizer capture.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRef {
    /// Polarizer angle, degrees.
    pub angle_deg: f64,
    /// Image file (resolved against the manifest's directory).
    pub file: PathBuf,
}

/// The data of a capture.
#[derive(Debug, Clone, PartialEq)]
pub enum CaptureSource {
    /// Rotating polarizer: at least 3 frames with distinct angles (mod 180°).
    Frames(Vec<FrameRef>),
    /// Division-of-focal-plane raw mosaic.
    Dofp {
        /// The raw frame.
        file: PathBuf,
        /// The 2×2 pattern (default `90,45,135,0`).
        pattern: Pattern,
    },
    /// Colour polarization raw mosaic (a `dofp` with `color`, [`colour`]).
    ColourDofp {
        /// The raw frame.
        file: PathBuf,
        /// The polarizer and colour pattern.
        pattern: ColourPattern,
        /// The wavelength of each band of the pattern (in the order of
        /// [`ColourPattern::bands`]), nm.
        wavelengths_nm: Vec<f64>,
    },
    /// Stokes images computed elsewhere (float TIFF).
    Stokes {
        /// S0 image.
        s0: PathBuf,
        /// S1 image.
        s1: PathBuf,
        /// S2 image.
        s2: PathBuf,
    },
}

impl CaptureSource {
    /// Every file the capture reads.
    pub fn files(&self) -> Vec<&Path> {
        match self {
            CaptureSource::Frames(f) => f.iter().map(|f| f.file.as_path()).collect(),
            CaptureSource::Dofp { file, .. } => vec![file.as_path()],
            CaptureSource::ColourDofp { file, .. } => vec![file.as_path()],
            CaptureSource::Stokes { s0, s1, s2 } => vec![s0, s1, s2],
        }
    }
}

/// Largest dark or saturation level (DN): levels are compared in float32.
const MAX_LEVEL: f64 = f32::MAX as f64;
/// Smallest and largest relative exposure: S0 is divided by it, and beyond these the
/// float32 results overflow or lose all precision (`exposure = 1e-308` gave S0 = inf).
const MIN_EXPOSURE: f64 = 1e-9;
/// See [`MIN_EXPOSURE`].
const MAX_EXPOSURE: f64 = 1e9;

/// Read and validate a manifest file.
pub fn load(path: &Path) -> Result<Manifest> {
    let text = crate::limits::read_text(path)?;
    parse(path, &text)
}

/// Validate manifest `text`; `path` labels errors and anchors relative file paths.
pub fn parse(path: &Path, text: &str) -> Result<Manifest> {
    parse_with(path, text, true)
}

/// [`parse`] without looking for the files it names: a manifest of captures whose
/// frames are in memory (`polarid demo --color` measures its simulated mosaics so).
pub fn parse_in_memory(path: &Path, text: &str) -> Result<Manifest> {
    parse_with(path, text, false)
}

fn parse_with(path: &Path, text: &str, files: bool) -> Result<Manifest> {
    Parser::new(path, text, files).manifest()
}

/// True when `text` is a capture-set manifest: TOML with `[[capture]]` or
/// `[[region]]` tables (so that a manifest given where a table is expected gets a
/// message saying what it is, not a CSV error).
pub fn looks_like_manifest(text: &str) -> bool {
    DeTable::parse(text).is_ok_and(|root| {
        let root = root.get_ref();
        root.contains_key("capture") || root.contains_key("region")
    })
}

type Table<'i> = DeTable<'i>;
type Val<'i> = Spanned<DeValue<'i>>;

/// The top-level values a capture takes when it does not give its own, and what it
/// needs of the rest of the manifest.
struct CaptureDefaults<'m> {
    theta_r_deg: Option<f64>,
    phi_deg: f64,
    dark_level: f64,
    saturation: Option<f64>,
    wavelength_nm: Option<f64>,
    angle_sd_deg: Option<f64>,
    dark_signal_dn: Option<f64>,
    /// Whether the manifest has a `[camera]`.
    calibrated: bool,
    site: Option<&'m SiteSpec>,
    bands: &'m Bands,
}

/// Whether a name holds a comma, a quote or a control character (refused in region
/// and class names, which CSV tables repeat).
fn has_separator(name: &str) -> bool {
    name.contains(',') || name.contains('"') || name.chars().any(char::is_control)
}

struct Parser<'a> {
    /// Whether the files named must exist.
    files: bool,
    path: &'a Path,
    text: &'a str,
    dir: PathBuf,
    warnings: std::cell::RefCell<Vec<String>>,
}

impl<'a> Parser<'a> {
    /// A parser of `text`: `path` labels errors and anchors relative file paths, which
    /// must exist when `files`.
    fn new(path: &'a Path, text: &'a str, files: bool) -> Self {
        Parser {
            files,
            path,
            text,
            dir: path
                .parent()
                .filter(|d| !d.as_os_str().is_empty())
                .map(Path::to_path_buf)
                .unwrap_or_else(|| PathBuf::from(".")),
            warnings: std::cell::RefCell::new(Vec::new()),
        }
    }

    fn toml(&self) -> TomlText<'_> {
        TomlText {
            path: self.path,
            text: self.text,
        }
    }

    fn line(&self, pos: usize) -> usize {
        self.toml().line(pos)
    }

    fn snippet(&self, span: &Range<usize>) -> String {
        self.toml().snippet(span)
    }

    fn err(&self, span: &Range<usize>, field: &str, reason: impl Into<String>) -> IoError {
        self.toml().err(span, field, reason)
    }

    fn warn_unknown(&self, table: &Table<'_>, known: &[&str], prefix: &str) {
        for (k, _) in table.iter() {
            if !known.contains(&k.get_ref().as_ref()) {
                self.warnings.borrow_mut().push(format!(
                    "{}: line {}: unknown field `{}{}` ignored",
                    self.path.display(),
                    self.line(k.span().start),
                    prefix,
                    k.get_ref()
                ));
            }
        }
    }

    fn get<'t, 'i>(&self, t: &'t Table<'i>, key: &str) -> Option<&'t Val<'i>> {
        t.iter()
            .find(|(k, _)| k.get_ref().as_ref() == key)
            .map(|(_, v)| v)
    }

    fn num(&self, v: &Val<'_>, field: &str) -> Result<f64> {
        let x = match v.get_ref() {
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
                .ok()
                .map(|x| x as f64),
            DeValue::Float(f) => f.as_str().replace('_', "").parse::<f64>().ok(),
            other => {
                return Err(self.err(
                    &v.span(),
                    field,
                    format!("expected a number, found a {}", other.type_str()),
                ));
            }
        };
        match x {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(self.err(&v.span(), field, "expected a finite number")),
        }
    }

    fn opt_num(
        &self,
        t: &Table<'_>,
        key: &str,
        prefix: &str,
    ) -> Result<Option<(f64, Range<usize>)>> {
        match self.get(t, key) {
            None => Ok(None),
            Some(v) => Ok(Some((self.num(v, &format!("{prefix}{key}"))?, v.span()))),
        }
    }

    fn string(&self, v: &Val<'_>, field: &str) -> Result<String> {
        match v.get_ref() {
            DeValue::String(s) => Ok(s.to_string()),
            other => Err(self.err(
                &v.span(),
                field,
                format!("expected a string, found a {}", other.type_str()),
            )),
        }
    }

    fn file(&self, v: &Val<'_>, field: &str) -> Result<PathBuf> {
        let s = self.string(v, field)?;
        if s.trim().is_empty() {
            return Err(self.err(&v.span(), field, "empty file name"));
        }
        let p = self.dir.join(&s);
        if self.files && !p.is_file() {
            let why = if p.exists() {
                format!("{} is not a regular file", p.display())
            } else {
                format!("file {} not found", p.display())
            };
            return Err(self.err(&v.span(), field, why));
        }
        Ok(p)
    }

    fn table<'t, 'i>(&self, v: &'t Val<'i>, field: &str) -> Result<&'t Table<'i>> {
        v.get_ref().as_table().ok_or_else(|| {
            self.err(
                &v.span(),
                field,
                format!("expected a table, found a {}", v.get_ref().type_str()),
            )
        })
    }

    fn array<'t, 'i>(&self, v: &'t Val<'i>, field: &str) -> Result<&'t [Val<'i>]> {
        v.get_ref().as_array().map(|a| &a[..]).ok_or_else(|| {
            self.err(
                &v.span(),
                field,
                format!("expected an array, found a {}", v.get_ref().type_str()),
            )
        })
    }

    fn angle(&self, t: &Table<'_>, key: &str, prefix: &str) -> Result<Option<f64>> {
        match self.opt_num(t, key, prefix)? {
            Some((v, span)) if !(0.0..90.0).contains(&v) => Err(self.err(
                &span,
                &format!("{prefix}{key}"),
                "zenith angle must be in [0, 90) degrees",
            )),
            other => Ok(other.map(|x| x.0)),
        }
    }

    fn manifest(&self) -> Result<Manifest> {
        let root = self.parse_root()?;
        let root = root.get_ref();
        self.warn_unknown(
            root,
            &[
                "theta_r_deg",
                "phi_deg",
                "dark_level",
                "saturation",
                "wavelength_nm",
                "bands",
                "angle_sd_deg",
                "dark_signal_dn",
                "region",
                "capture",
                "camera",
                "plane",
                "site",
            ],
            "",
        );
        let theta_r_deg = self.angle(root, "theta_r_deg", "")?;
        let phi_deg = self.opt_num(root, "phi_deg", "")?.map_or(180.0, |x| x.0);
        let dark_level = self.dark_level(root, "", 0.0)?;
        let saturation = self.saturation(root, "", dark_level, None)?;
        let wavelength_nm = match self.opt_num(root, "wavelength_nm", "")? {
            Some((v, span)) if v <= 0.0 => {
                return Err(self.err(&span, "wavelength_nm", "wavelength must be > 0"));
            }
            other => other.map(|x| x.0),
        };

        let angle_sd_deg = self.angle_sd(root, "")?;
        let dark_signal_dn = self.dark_signal(root, "")?;
        let bands = self.bands(root)?;

        // Calibrated geometry.
        let camera = self.camera(root)?;
        let planes = self.planes(root, camera.as_ref())?;
        let site = self.site(root)?;
        if camera.is_some() {
            self.refuse_top_angles(root)?;
        }
        let regions = self.regions(root, &planes)?;

        // Captures.
        let cap_vals = match self.get(root, "capture") {
            Some(v) => self.array(v, "capture")?,
            None => &[],
        };
        let defaults = CaptureDefaults {
            theta_r_deg,
            phi_deg,
            dark_level,
            saturation,
            wavelength_nm,
            angle_sd_deg,
            dark_signal_dn,
            calibrated: camera.is_some(),
            site: site.as_ref(),
            bands: &bands,
        };
        let captures = (cap_vals.iter().enumerate())
            .map(|(i, cv)| self.capture(i + 1, cv, &defaults))
            .collect::<Result<Vec<_>>>()?;
        if captures.is_empty() {
            return Err(self.err(&(0..0), "capture", "no [[capture]]: at least one is needed"));
        }
        if let Some(cam) = &camera {
            self.check_geometry(cam, &planes, &regions, &captures, cap_vals)?;
        }
        Ok(Manifest {
            path: self.path.to_path_buf(),
            theta_r_deg,
            phi_deg,
            dark_level,
            saturation,
            wavelength_nm,
            bands,
            angle_sd_deg,
            dark_signal_dn,
            camera,
            planes,
            site,
            regions,
            captures,
            warnings: self.warnings.take(),
        })
    }

    /// The TOML document, or an error naming the line and the key where it is invalid.
    fn parse_root(&self) -> Result<Spanned<Table<'a>>> {
        DeTable::parse(self.text).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            IoError::Manifest {
                path: self.path.to_path_buf(),
                line: self.line(span.start),
                field: self
                    .text
                    .get(self.line_start(span.start)..)
                    .and_then(|l| l.split('=').next())
                    .map(|k| k.trim().to_string())
                    .filter(|k| !k.is_empty() && !k.contains('\n'))
                    .unwrap_or_else(|| "-".into()),
                value: self.snippet(&span),
                reason: format!("invalid TOML: {}", e.message()),
            }
        })
    }

    /// With `[camera]`, the top level gives no angles.
    fn refuse_top_angles(&self, root: &Table<'_>) -> Result<()> {
        let Some((key, v)) = ["theta_r_deg", "phi_deg"]
            .into_iter()
            .find_map(|k| self.get(root, k).map(|v| (k, v)))
        else {
            return Ok(());
        };
        Err(self.err(
            &v.span(),
            key,
            "with [camera], the angles come from the calibrated geometry: \
             remove the angle or the [camera] table",
        ))
    }

    /// The optional `dark_level` of a table (`default` when absent).
    fn dark_level(&self, t: &Table<'_>, pre: &str, default: f64) -> Result<f64> {
        match self.opt_num(t, "dark_level", pre)? {
            Some((v, s)) if !(0.0..=MAX_LEVEL).contains(&v) => Err(self.err(
                &s,
                &format!("{pre}dark_level"),
                "dark level must be >= 0 and at most 3.4e38 (the float32 range)",
            )),
            Some((v, _)) => Ok(v),
            None => Ok(default),
        }
    }

    /// The optional `saturation` of a table, above `dark_level` (`default` when absent).
    fn saturation(
        &self,
        t: &Table<'_>,
        pre: &str,
        dark_level: f64,
        default: Option<f64>,
    ) -> Result<Option<f64>> {
        match self.opt_num(t, "saturation", pre)? {
            Some((v, s)) if v <= dark_level || v > MAX_LEVEL => Err(self.err(
                &s,
                &format!("{pre}saturation"),
                format!("saturation must be above the dark level {dark_level}"),
            )),
            Some((v, _)) => Ok(Some(v)),
            None => Ok(default),
        }
    }

    /// The `[[region]]` tables: at least one, with distinct names.
    fn regions(&self, root: &Table<'_>, planes: &[PlaneSpec]) -> Result<Vec<Region>> {
        let region_vals = match self.get(root, "region") {
            Some(v) => self.array(v, "region")?,
            None => &[],
        };
        let mut names = HashSet::new();
        let regions = (region_vals.iter().enumerate())
            .map(|(i, rv)| self.region(i + 1, rv, planes, &mut names))
            .collect::<Result<Vec<_>>>()?;
        if regions.is_empty() {
            return Err(self.err(
                &(0..0),
                "region",
                "no [[region]]: at least one target is needed",
            ));
        }
        Ok(regions)
    }

    /// The `[[region]]` table number `index` (1-based); `names` holds the names seen.
    fn region(
        &self,
        index: usize,
        rv: &Val<'_>,
        planes: &[PlaneSpec],
        names: &mut HashSet<String>,
    ) -> Result<Region> {
        let pre = format!("region[{index}].");
        let t = self.table(rv, &format!("region[{index}]"))?;
        self.warn_unknown(
            t,
            &[
                "name",
                "rect",
                "class",
                "plane",
                "reference",
                "reference_n",
                "reference_k",
            ],
            &pre,
        );
        let name = self.region_name(t, rv, &pre, names)?;
        let (rect, line) = self.region_rect(t, rv, &pre)?;
        let class = match self.get(t, "class") {
            Some(v) => {
                let c = self.string(v, &format!("{pre}class"))?;
                if has_separator(&c) {
                    return Err(self.err(
                        &v.span(),
                        &format!("{pre}class"),
                        "class names must contain no comma, quote or control character",
                    ));
                }
                let c = crate::table::clean_name(&c)
                    .map_err(|why| self.err(&v.span(), &format!("{pre}class"), why))?;
                Some(c).filter(|c| !c.is_empty())
            }
            None => None,
        };
        Ok(Region {
            name,
            rect,
            class,
            line,
            index,
            plane: self.region_plane(t, &pre, planes)?,
            reference: self.region_reference(t, &pre)?,
        })
    }

    /// A region's `name`, checked, normalised and added to `names` (it must not be there).
    fn region_name(
        &self,
        t: &Table<'_>,
        rv: &Val<'_>,
        pre: &str,
        names: &mut HashSet<String>,
    ) -> Result<String> {
        let field = format!("{pre}name");
        let name_v = self
            .get(t, "name")
            .ok_or_else(|| self.err(&rv.span(), &field, "missing region name"))?;
        let name = self.string(name_v, &field)?;
        if name.trim().is_empty() || has_separator(&name) || name.trim() != name {
            return Err(self.err(
                &name_v.span(),
                &field,
                "region names must be non-empty, without leading or trailing spaces, \
                 and contain no comma, quote or control character",
            ));
        }
        // NFC, no zero-width or bidirectional-formatting character (as CSV names),
        // so that look-alike names are one target or refused.
        let name =
            crate::table::clean_name(&name).map_err(|why| self.err(&name_v.span(), &field, why))?;
        if !names.insert(name.clone()) {
            return Err(self.err(&name_v.span(), &field, "duplicate region name"));
        }
        Ok(name)
    }

    /// A region's `rect` and the line where it is given.
    fn region_rect(&self, t: &Table<'_>, rv: &Val<'_>, pre: &str) -> Result<(Rect, usize)> {
        let field = format!("{pre}rect");
        let rect_v = self
            .get(t, "rect")
            .ok_or_else(|| self.err(&rv.span(), &field, "missing rect"))?;
        let items = self.array(rect_v, &field)?;
        let bad_rect = || {
            self.err(
                &rect_v.span(),
                &field,
                "rect must be [x, y, width, height]: four non-negative integers, width and height > 0",
            )
        };
        if items.len() != 4 {
            return Err(bad_rect());
        }
        let mut r = [0usize; 4];
        for (k, it) in items.iter().enumerate() {
            let v = match it.get_ref() {
                DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix()).ok(),
                _ => None,
            };
            r[k] = match v {
                // ok: k < 4 (items.len() == 4 was checked)
                Some(v) if v >= 0 => v as usize,
                _ => return Err(bad_rect()),
            };
        }
        if r[2] == 0 || r[3] == 0 {
            return Err(bad_rect());
        }
        let rect = Rect {
            x: r[0],
            y: r[1],
            width: r[2],
            height: r[3],
        };
        Ok((rect, self.line(rect_v.span().start)))
    }

    fn line_start(&self, pos: usize) -> usize {
        let end = pos.min(self.text.len());
        // Bytes, not `str` slicing: a span need not fall on a character boundary.
        self.text.as_bytes()[..end] // ok: end <= len
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |i| i + 1)
    }

    /// The `[[capture]]` table number `index` (1-based).
    fn capture(&self, index: usize, cv: &Val<'_>, top: &CaptureDefaults<'_>) -> Result<Capture> {
        let pre = format!("capture[{index}].");
        let t = self.table(cv, &format!("capture[{index}]"))?;
        self.warn_unknown(
            t,
            &[
                "name",
                "theta_i_deg",
                "theta_r_deg",
                "phi_deg",
                "exposure",
                "dark_level",
                "saturation",
                "angle_sd_deg",
                "dark_signal_dn",
                "frames",
                "dofp",
                "stokes",
                "brackets",
                "source",
                "wavelength_nm",
            ],
            &pre,
        );
        let first_line = t
            .iter()
            .map(|(k, _)| k.span().start)
            .min()
            .unwrap_or(cv.span().start);
        let span = first_line..cv.span().end;
        let name = match self.get(t, "name") {
            Some(v) => Some(self.string(v, &format!("{pre}name"))?),
            None => None,
        };
        let illumination = self.capture_source(t, &pre, &span, top.calibrated, top.site)?;
        let (theta_i_deg, theta_r_deg, phi_deg) = if illumination.is_some() {
            (f64::NAN, f64::NAN, f64::NAN)
        } else {
            self.capture_angles(t, &pre, &span, top)?
        };
        let exposure = match self.opt_num(t, "exposure", &pre)? {
            Some((v, s)) if !(MIN_EXPOSURE..=MAX_EXPOSURE).contains(&v) => {
                return Err(self.err(
                    &s,
                    &format!("{pre}exposure"),
                    "exposure must be > 0, within [1e-9, 1e9] (S0 is divided by it)",
                ));
            }
            Some((v, _)) => v,
            None => 1.0,
        };
        let dark_level = self.dark_level(t, &pre, top.dark_level)?;
        let saturation = self.saturation(t, &pre, dark_level, top.saturation)?;
        if let (Some(s), None) = (saturation, self.get(t, "saturation"))
            && s <= dark_level
        {
            return Err(self.err(
                &span,
                &format!("{pre}dark_level"),
                format!("dark level must be below the saturation level {s}"),
            ));
        }
        let angle_sd_deg = self.angle_sd(t, &pre)?.or(top.angle_sd_deg);
        let dark_signal_dn = self.dark_signal(t, &pre)?.or(top.dark_signal_dn);
        let (source, exposure, brackets) = match self.get(t, "brackets") {
            Some(bv) => self.hdr_capture(t, bv, &pre, top.bands)?,
            None => (
                self.data_source(t, &pre, &span, true, top.bands)?,
                exposure,
                Vec::new(),
            ),
        };
        let wavelength_nm = self.capture_wavelength(t, &pre, top.wavelength_nm, &source)?;
        Ok(Capture {
            index,
            line: self.line(first_line),
            name,
            theta_i_deg,
            theta_r_deg,
            phi_deg,
            illumination,
            exposure,
            dark_level,
            saturation,
            angle_sd_deg,
            dark_signal_dn,
            source,
            brackets,
            wavelength_nm,
        })
    }

    /// A far-field capture's `theta_i_deg`, `theta_r_deg` and `phi_deg` (the last two
    /// default to the top level's).
    fn capture_angles(
        &self,
        t: &Table<'_>,
        pre: &str,
        span: &Range<usize>,
        top: &CaptureDefaults<'_>,
    ) -> Result<(f64, f64, f64)> {
        let theta_i_deg = self.angle(t, "theta_i_deg", pre)?.ok_or_else(|| {
            self.err(
                span,
                &format!("{pre}theta_i_deg"),
                "missing source zenith angle",
            )
        })?;
        let theta_r_deg = self
            .angle(t, "theta_r_deg", pre)?
            .or(top.theta_r_deg)
            .ok_or_else(|| {
                self.err(
                    span,
                    &format!("{pre}theta_r_deg"),
                    "no camera zenith angle: set theta_r_deg at the top or in the capture",
                )
            })?;
        let phi_deg = self
            .opt_num(t, "phi_deg", pre)?
            .map_or(top.phi_deg, |x| x.0);
        Ok((theta_i_deg, theta_r_deg, phi_deg))
    }

    /// An HDR capture's data (its `brackets` `bv`): the longest exposure's data, its
    /// exposure, and every bracket.
    fn hdr_capture(
        &self,
        t: &Table<'_>,
        bv: &Val<'_>,
        pre: &str,
        bands: &Bands,
    ) -> Result<(CaptureSource, f64, Vec<Bracket>)> {
        for k in ["frames", "dofp", "stokes", "exposure"] {
            if let Some(v) = self.get(t, k) {
                return Err(self.err(
                    &v.span(),
                    &format!("{pre}{k}"),
                    format!(
                        "a capture with `brackets` gives its data and exposures in \
                         each bracket, not `{k}`"
                    ),
                ));
            }
        }
        let brackets = self.brackets(bv, pre, bands)?;
        match brackets.first() {
            Some(b) => Ok((b.source.clone(), b.exposure, brackets)),
            None => Err(self.err(&bv.span(), &format!("{pre}brackets"), "empty")),
        }
    }

    /// The data of a capture or of a bracket (table `t`, fields under `pre`): exactly
    /// one of `frames`, `dofp` or (`allow_stokes`) `stokes`.
    fn data_source(
        &self,
        t: &Table<'_>,
        pre: &str,
        span: &Range<usize>,
        allow_stokes: bool,
        bands: &Bands,
    ) -> Result<CaptureSource> {
        if !allow_stokes && let Some(v) = self.get(t, "stokes") {
            return Err(self.err(
                &v.span(),
                &format!("{pre}stokes"),
                "HDR brackets need raw data (`frames` or `dofp`), not Stokes images",
            ));
        }
        let kinds: Vec<&str> = ["frames", "dofp", "stokes"]
            .into_iter()
            .filter(|k| self.get(t, k).is_some())
            .collect();
        let [kind] = kinds[..] else {
            return Err(self.err(
                span,
                &format!("{pre}frames"),
                if kinds.is_empty() {
                    "a capture needs one of `frames`, `dofp` or `stokes`".to_string()
                } else {
                    format!(
                        "a capture needs exactly one of `frames`, `dofp` or `stokes`, found {}",
                        kinds.join(" and ")
                    )
                },
            ));
        };
        let v = self
            .get(t, kind)
            .ok_or_else(|| self.err(span, kind, "missing"))?;
        let field = format!("{pre}{kind}");
        match kind {
            "frames" => self.frames(v, &field),
            "dofp" => self.dofp(v, &field, bands),
            _ => self.stokes(v, &field),
        }
    }

    /// A `frames` array `fv` (field `field`): polarizer angles and files.
    fn frames(&self, fv: &Val<'_>, field: &str) -> Result<CaptureSource> {
        let items = self.array(fv, field)?;
        let mut frames = Vec::new();
        for (j, it) in items.iter().enumerate() {
            let fpre = format!("{field}[{}].", j + 1);
            let ft = self.table(it, &format!("{field}[{}]", j + 1))?;
            self.warn_unknown(ft, &["angle_deg", "file"], &fpre);
            let (angle_deg, aspan) = self.opt_num(ft, "angle_deg", &fpre)?.ok_or_else(|| {
                self.err(
                    &it.span(),
                    &format!("{fpre}angle_deg"),
                    "missing polarizer angle",
                )
            })?;
            if !(angle_deg.abs() <= 3600.0) {
                return Err(self.err(
                    &aspan,
                    &format!("{fpre}angle_deg"),
                    "polarizer angle must be in [-3600, 3600] degrees",
                ));
            }
            let file_v = self
                .get(ft, "file")
                .ok_or_else(|| self.err(&it.span(), &format!("{fpre}file"), "missing file"))?;
            let file = self.file(file_v, &format!("{fpre}file"))?;
            frames.push(FrameRef { angle_deg, file });
        }
        let angles: Vec<f64> = frames.iter().map(|f| f.angle_deg).collect();
        if let Err(e) = StokesSolver::from_degrees(&angles) {
            return Err(self.err(&fv.span(), field, e.to_string()));
        }
        Ok(CaptureSource::Frames(frames))
    }

    /// A `dofp` table `dv` (field `field`): the mosaic's file and pattern.
    fn dofp(&self, dv: &Val<'_>, field: &str, bands: &Bands) -> Result<CaptureSource> {
        let dt = self.table(dv, field)?;
        self.warn_unknown(dt, &["file", "pattern", "color"], &format!("{field}."));
        let file_v = self
            .get(dt, "file")
            .ok_or_else(|| self.err(&dv.span(), &format!("{field}.file"), "missing file"))?;
        let file = self.file(file_v, &format!("{field}.file"))?;
        let pattern = match self.get(dt, "pattern") {
            None => Pattern::default(),
            Some(pv) => {
                let pf = format!("{field}.pattern");
                let items = self.array(pv, &pf)?;
                let mut a = Vec::new();
                for it in items {
                    a.push(self.num(it, &pf)?);
                }
                Pattern::new(&a).map_err(|e| self.err(&pv.span(), &pf, e.to_string()))?
            }
        };
        Ok(
            match self.colour_dofp(dt, field, file.clone(), pattern, bands)? {
                Some(colour) => colour,
                None => CaptureSource::Dofp { file, pattern },
            },
        )
    }

    /// A `stokes` table `sv` (field `field`): the files of S0, S1 and S2.
    fn stokes(&self, sv: &Val<'_>, field: &str) -> Result<CaptureSource> {
        let st = self.table(sv, field)?;
        self.warn_unknown(st, &["s0", "s1", "s2"], &format!("{field}."));
        let mut files = Vec::new();
        for k in ["s0", "s1", "s2"] {
            let v = self
                .get(st, k)
                .ok_or_else(|| self.err(&sv.span(), &format!("{field}.{k}"), "missing file"))?;
            files.push(self.file(v, &format!("{field}.{k}"))?);
        }
        let mut it = files.into_iter();
        match (it.next(), it.next(), it.next()) {
            (Some(s0), Some(s1), Some(s2)) => Ok(CaptureSource::Stokes { s0, s1, s2 }),
            _ => Err(self.err(&sv.span(), field, "needs s0, s1 and s2")),
        }
    }

    /// The `brackets` of a capture (HDR): at least 2 tables, each with an `exposure`
    /// (> 0, distinct) and the same kind of data (`frames` with the same angles, or
    /// `dofp` with the same pattern); returned longest exposure first.
    fn brackets(&self, bv: &Val<'_>, pre: &str, bands: &Bands) -> Result<Vec<Bracket>> {
        let field = format!("{pre}brackets");
        let items = self.array(bv, &field)?;
        if items.len() < 2 {
            return Err(self.err(
                &bv.span(),
                &field,
                "HDR brackets need at least 2 exposures (one exposure: use `frames` or `dofp`)",
            ));
        }
        let mut out: Vec<Bracket> = Vec::with_capacity(items.len());
        for (j, it) in items.iter().enumerate() {
            let bpre = format!("{field}[{}].", j + 1);
            let bt = self.table(it, &format!("{field}[{}]", j + 1))?;
            self.warn_unknown(bt, &["exposure", "frames", "dofp", "stokes"], &bpre);
            let exposure = match self.opt_num(bt, "exposure", &bpre)? {
                Some((v, s)) if v <= 0.0 => {
                    return Err(self.err(&s, &format!("{bpre}exposure"), "exposure must be > 0"));
                }
                Some((v, s)) if out.iter().any(|b| b.exposure == v) => {
                    return Err(self.err(
                        &s,
                        &format!("{bpre}exposure"),
                        "two brackets have the same exposure",
                    ));
                }
                Some((v, _)) => v,
                None => {
                    return Err(self.err(
                        &it.span(),
                        &format!("{bpre}exposure"),
                        "missing exposure (each bracket needs its relative exposure)",
                    ));
                }
            };
            let source = self.data_source(bt, &bpre, &it.span(), false, bands)?;
            if let Some(first) = out.first()
                && let Some((key, reason)) = bracket_mismatch(&first.source, &source)
            {
                let v = self.get(bt, key).map_or(it.span(), |v| v.span());
                return Err(self.err(&v, &format!("{bpre}{key}"), reason));
            }
            out.push(Bracket { exposure, source });
        }
        out.sort_by(|a, b| b.exposure.total_cmp(&a.exposure));
        Ok(out)
    }

    /// The optional `dark_signal_dn` of a table: finite (checked by `num`) and `>= 0`.
    fn dark_signal(&self, t: &Table<'_>, prefix: &str) -> Result<Option<f64>> {
        match self.opt_num(t, "dark_signal_dn", prefix)? {
            Some((v, span)) if v < 0.0 => Err(self.err(
                &span,
                &format!("{prefix}dark_signal_dn"),
                "dark threshold must be >= 0 DN",
            )),
            other => Ok(other.map(|x| x.0)),
        }
    }

    /// The optional `angle_sd_deg` of a table: finite (checked by `num`) and in
    /// `[0, 90)` degrees.
    fn angle_sd(&self, t: &Table<'_>, prefix: &str) -> Result<Option<f64>> {
        match self.opt_num(t, "angle_sd_deg", prefix)? {
            Some((v, span)) if !(0.0..90.0).contains(&v) => Err(self.err(
                &span,
                &format!("{prefix}angle_sd_deg"),
                "angle uncertainty must be in [0, 90) degrees",
            )),
            other => Ok(other.map(|x| x.0)),
        }
    }
}
