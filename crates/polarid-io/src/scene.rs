//! The scene file (TOML) of `polarid simulate`: plates of known optics in one frame, a
//! fixed camera, the source at several zenith angles, a sensor and how it is exposed.
//! `docs/SCENE.md` documents every key; `examples/scenes/` holds commented examples.
//!
//! ```toml
//! name = "training_60"          # optional label
//! width = 256                   # frame size, pixels
//! height = 128
//! theta_r_deg = 60.0            # camera zenith
//! phi_deg = 180.0               # phi_r - phi_i (default 180: in the plane of incidence)
//! theta_i_deg = [35, 40, 45]    # source zeniths, one capture each
//!                               # (or { start = 35, stop = 80, step = 5 })
//! wavelength_nm = 650.0         # optional, informational
//! background = 0.0              # unpolarized background radiance (default 0)
//! seed = 1                      # noise seed (default 0)
//! format = "png"                # png | tiff (16-bit, or 8-bit when bit_depth <= 8)
//!
//! [sensor]                      # every key optional
//! bit_depth = 12
//! full_well_e = 10000.0         # electrons at the top of the ADC range (sets the gain)
//! read_noise_e = 2.5
//! dark_level_dn = 64.0
//! shot_noise = true
//!
//! [exposure]                    # default: mode = "auto", fraction = 0.7
//! mode = "auto"                 # brightest plate pixel at `fraction` of full scale
//! fraction = 0.7
//! # mode = "fixed", value = 0.5 # radiance I behind the polarizer -> value * I * full well
//!
//! [capture]                     # default: kind = "frames", angles_deg = [0, 45, 90, 135]
//! kind = "frames"
//! angles_deg = [0, 45, 90, 135]
//! # kind = "dofp", pattern = [90, 45, 135, 0]
//!
//! [[plate]]
//! name = "aluminum"
//! class = "aluminum"            # optional (written to the manifest's region)
//! n = 1.24
//! k = 6.60
//! sigma = 0.2                   # Priest–Meier roughness (slope standard deviation)
//! rho_d = 0.0                   # optional Lambertian depolarized albedo
//! rect = [8, 8, 112, 112]       # x, y, width, height in the frame
//! region = [16, 16, 96, 96]     # optional measured region (default: an inset of rect)
//! ```
//!
//! Errors are [`IoError::Manifest`] naming the file, the 1-based line, the dotted field
//! (`plate[2].sigma`; indices 1-based) and the value. Unknown keys are errors (a scene is
//! an input the simulator acts on, so a typo must not silently change the physics).

use std::collections::HashSet;
use std::ops::Range;
use std::path::{Path, PathBuf};

use polarid_core::mosaic::Pattern;
use polarid_core::region::Rect;
use polarid_core::simulate::{Exposure, PlateOptics, Sensor};
use polarid_core::stokes::StokesSolver;
use serde::Deserialize;
use toml::Spanned;

use crate::error::{IoError, Result};
use crate::toml_span::TomlText;

/// Largest frame side accepted, pixels.
pub const MAX_SIDE: usize = 16384;

/// Image file format of the simulated frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// PNG (`.png`).
    Png,
    /// TIFF (`.tif`).
    Tiff,
}

impl ImageFormat {
    /// File extension without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            ImageFormat::Png => "png",
            ImageFormat::Tiff => "tif",
        }
    }
}

/// What each capture records.
#[derive(Debug, Clone, PartialEq)]
pub enum CaptureKind {
    /// A rotating polarizer: one frame per angle (degrees), at least 3 distinct angles.
    Frames {
        /// Polarizer angles, degrees.
        angles_deg: Vec<f64>,
    },
    /// A division-of-focal-plane raw mosaic with a 2×2 pattern.
    Dofp {
        /// The pattern, row by row from the top-left.
        pattern: Pattern,
    },
}

impl CaptureKind {
    /// Every polarizer angle a capture uses, degrees.
    pub fn angles_deg(&self) -> Vec<f64> {
        match self {
            CaptureKind::Frames { angles_deg } => angles_deg.clone(),
            CaptureKind::Dofp { pattern } => pattern.angles_deg().to_vec(),
        }
    }
}

/// One plate of a scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Plate {
    /// Unique name (the manifest's region and the target of the measurements).
    pub name: String,
    /// Material class, if given.
    pub class: Option<String>,
    /// Index, roughness and diffuse albedo.
    pub optics: PlateOptics,
    /// The plate's rectangle in the frame.
    pub rect: Rect,
    /// The measured region (inside `rect`).
    pub region: Rect,
    /// Line of the plate's `name` in the scene file.
    pub line: usize,
}

/// A validated scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The scene file.
    pub path: PathBuf,
    /// The scene's text as read (copied next to the outputs).
    pub text: String,
    /// Optional label.
    pub name: Option<String>,
    /// Frame width, pixels.
    pub width: usize,
    /// Frame height, pixels.
    pub height: usize,
    /// Camera zenith, degrees.
    pub theta_r_deg: f64,
    /// `phi_r − phi_i`, degrees.
    pub phi_deg: f64,
    /// Source zeniths, degrees, one capture each (in order).
    pub theta_i_deg: Vec<f64>,
    /// Informational wavelength, nm.
    pub wavelength_nm: Option<f64>,
    /// Unpolarized background radiance (same units as the plates' radiance).
    pub background: f64,
    /// Noise seed.
    pub seed: u64,
    /// Output image format.
    pub format: ImageFormat,
    /// The sensor.
    pub sensor: Sensor,
    /// How each capture is exposed.
    pub exposure: Exposure,
    /// What each capture records.
    pub capture: CaptureKind,
    /// The plates, in file order.
    pub plates: Vec<Plate>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    name: Option<Spanned<String>>,
    width: Option<Spanned<i64>>,
    height: Option<Spanned<i64>>,
    theta_r_deg: Option<Spanned<f64>>,
    phi_deg: Option<Spanned<f64>>,
    theta_i_deg: Option<Spanned<toml::Value>>,
    wavelength_nm: Option<Spanned<f64>>,
    background: Option<Spanned<f64>>,
    seed: Option<Spanned<i64>>,
    format: Option<Spanned<String>>,
    sensor: Option<RawSensor>,
    exposure: Option<RawExposure>,
    capture: Option<RawCapture>,
    #[serde(default)]
    plate: Vec<RawPlate>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSensor {
    bit_depth: Option<Spanned<i64>>,
    full_well_e: Option<Spanned<f64>>,
    read_noise_e: Option<Spanned<f64>>,
    dark_level_dn: Option<Spanned<f64>>,
    shot_noise: Option<Spanned<bool>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawExposure {
    mode: Option<Spanned<String>>,
    value: Option<Spanned<f64>>,
    fraction: Option<Spanned<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCapture {
    kind: Option<Spanned<String>>,
    angles_deg: Option<Spanned<Vec<f64>>>,
    pattern: Option<Spanned<Vec<f64>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlate {
    name: Option<Spanned<String>>,
    class: Option<Spanned<String>>,
    n: Option<Spanned<f64>>,
    k: Option<Spanned<f64>>,
    sigma: Option<Spanned<f64>>,
    rho_d: Option<Spanned<f64>>,
    rect: Option<Spanned<Vec<i64>>>,
    region: Option<Spanned<Vec<i64>>>,
}

/// Read and validate a scene file.
pub fn load(path: &Path) -> Result<Scene> {
    let text = std::fs::read_to_string(path).map_err(|e| IoError::io(path, e))?;
    parse(path, &text)
}

/// Validate scene `text`; `path` labels errors.
pub fn parse(path: &Path, text: &str) -> Result<Scene> {
    Ctx { path, text }.scene()
}

/// The default measured region of a plate: the plate inset by an eighth of its smaller
/// side (at least 2 pixels), with an even corner and even size so that it holds whole
/// 2×2 DoFP super-pixels.
pub fn default_region(rect: Rect) -> Option<Rect> {
    let inset = (rect.width.min(rect.height) / 8).max(2);
    let x = (rect.x + inset).next_multiple_of(2);
    let y = (rect.y + inset).next_multiple_of(2);
    let x1 = (rect.x + rect.width).checked_sub(inset)?;
    let y1 = (rect.y + rect.height).checked_sub(inset)?;
    let w = x1.checked_sub(x)? / 2 * 2;
    let h = y1.checked_sub(y)? / 2 * 2;
    (w >= 2 && h >= 2).then_some(Rect {
        x,
        y,
        width: w,
        height: h,
    })
}

struct Ctx<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Ctx<'_> {
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

    /// An error about a missing key (no span: line 0 unless `near` is given).
    fn missing(&self, near: Option<&Range<usize>>, field: &str, what: &str) -> IoError {
        IoError::Manifest {
            path: self.path.to_path_buf(),
            line: near.map_or(0, |s| self.line(s.start)),
            field: field.to_string(),
            value: "(missing)".into(),
            reason: format!("missing {what}"),
        }
    }

    /// The key written on the line holding `pos` (for TOML syntax and type errors).
    fn key_at(&self, pos: usize, message: &str) -> String {
        // serde names the key in "unknown field `x`" and "missing field `x`".
        for pat in ["unknown field `", "missing field `"] {
            if let Some(i) = message.find(pat) {
                let rest = &message[i + pat.len()..];
                if let Some(j) = rest.find('`') {
                    return rest[..j].to_string();
                }
            }
        }
        let end = pos.min(self.text.len());
        let start = self.text[..end].rfind('\n').map_or(0, |i| i + 1);
        let line = self.text[start..].lines().next().unwrap_or("");
        let key = line.split('=').next().unwrap_or("").trim();
        if key.is_empty() || line.trim_start().starts_with('[') && !line.contains('=') {
            line.trim().trim_matches(['[', ']']).to_string()
        } else {
            key.to_string()
        }
    }

    fn num(&self, v: &Spanned<f64>, field: &str) -> Result<f64> {
        let x = *v.get_ref();
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err(&v.span(), field, "expected a finite number"))
        }
    }

    fn num_in(
        &self,
        v: &Spanned<f64>,
        field: &str,
        ok: impl Fn(f64) -> bool,
        expected: &str,
    ) -> Result<f64> {
        let x = self.num(v, field)?;
        if ok(x) {
            Ok(x)
        } else {
            Err(self.err(&v.span(), field, format!("must be {expected}")))
        }
    }

    fn zenith(&self, v: &Spanned<f64>, field: &str) -> Result<f64> {
        self.num_in(
            v,
            field,
            |x| (0.0..90.0).contains(&x),
            "a zenith angle in [0, 90) degrees",
        )
    }

    fn rect(&self, v: &Spanned<Vec<i64>>, field: &str) -> Result<Rect> {
        let r = v.get_ref();
        if r.len() != 4 || r.iter().any(|&x| x < 0) || r[2] == 0 || r[3] == 0 {
            return Err(self.err(
                &v.span(),
                field,
                "rect must be [x, y, width, height]: four non-negative integers, width and \
                 height > 0",
            ));
        }
        Ok(Rect {
            x: r[0] as usize,
            y: r[1] as usize,
            width: r[2] as usize,
            height: r[3] as usize,
        })
    }

    fn name(&self, v: &Spanned<String>, field: &str) -> Result<String> {
        let s = v.get_ref();
        if s.trim().is_empty() || s.contains([',', '"', '/', '\\', '\n']) {
            return Err(self.err(
                &v.span(),
                field,
                "names must be non-empty and contain no comma, quote, slash or newline",
            ));
        }
        Ok(s.clone())
    }

    fn theta_i(&self, v: &Spanned<toml::Value>) -> Result<Vec<f64>> {
        let field = "theta_i_deg";
        let span = v.span();
        let as_num = |x: &toml::Value| match x {
            toml::Value::Integer(i) => Some(*i as f64),
            toml::Value::Float(f) if f.is_finite() => Some(*f),
            _ => None,
        };
        let list: Vec<f64> = match v.get_ref() {
            toml::Value::Array(a) => {
                let mut out = Vec::with_capacity(a.len());
                for x in a {
                    out.push(as_num(x).ok_or_else(|| {
                        self.err(&span, field, "expected an array of finite numbers")
                    })?);
                }
                out
            }
            toml::Value::Table(t) => {
                for k in t.keys() {
                    if !["start", "stop", "step"].contains(&k.as_str()) {
                        return Err(self.err(
                            &span,
                            field,
                            format!("unknown key `{k}` (expected start, stop, step)"),
                        ));
                    }
                }
                let get = |k: &str| {
                    t.get(k).and_then(as_num).ok_or_else(|| {
                        self.err(&span, &format!("{field}.{k}"), "expected a finite number")
                    })
                };
                let (a, b, s) = (get("start")?, get("stop")?, get("step")?);
                if s.is_nan() || s <= 0.0 || b < a {
                    return Err(self.err(&span, field, "need step > 0 and stop >= start"));
                }
                // Count in f64 and bound it before converting: a tiny step gives a count
                // beyond usize (the conversion saturates, and `+ 1` would overflow).
                let count = ((b - a) / s + 1e-9).floor() + 1.0;
                if !(count <= 10_000.0) {
                    return Err(self.err(&span, field, "more than 10000 source positions"));
                }
                (0..count as usize).map(|i| a + s * i as f64).collect()
            }
            other => {
                return Err(self.err(
                    &span,
                    field,
                    format!(
                        "expected an array of angles or {{ start, stop, step }}, found a {}",
                        other.type_str()
                    ),
                ));
            }
        };
        if list.is_empty() {
            return Err(self.err(&span, field, "at least one source position is needed"));
        }
        if let Some(bad) = list.iter().find(|x| !(0.0..90.0).contains(*x)) {
            return Err(self.err(
                &span,
                field,
                format!("source zenith {bad} is outside [0, 90) degrees"),
            ));
        }
        Ok(list)
    }

    fn scene(&self) -> Result<Scene> {
        let raw: RawScene = toml::from_str(self.text).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            let msg = e.message().trim().to_string();
            IoError::Manifest {
                path: self.path.to_path_buf(),
                line: self.line(span.start),
                field: self.key_at(span.start, &msg),
                value: self.snippet(&span),
                reason: format!("invalid scene: {msg}"),
            }
        })?;
        let name = match &raw.name {
            Some(v) => Some(self.name(v, "name")?),
            None => None,
        };
        let side = |v: &Option<Spanned<i64>>, field: &str| -> Result<usize> {
            let v = v
                .as_ref()
                .ok_or_else(|| self.missing(None, field, "frame size (pixels)"))?;
            let x = *v.get_ref();
            if !(2..=MAX_SIDE as i64).contains(&x) {
                return Err(self.err(
                    &v.span(),
                    field,
                    format!("must be an integer from 2 to {MAX_SIDE}"),
                ));
            }
            Ok(x as usize)
        };
        let width = side(&raw.width, "width")?;
        let height = side(&raw.height, "height")?;
        let theta_r_deg = match &raw.theta_r_deg {
            Some(v) => self.zenith(v, "theta_r_deg")?,
            None => return Err(self.missing(None, "theta_r_deg", "camera zenith angle")),
        };
        let phi_deg = match &raw.phi_deg {
            Some(v) => self.num(v, "phi_deg")?,
            None => 180.0,
        };
        let theta_i_deg = match &raw.theta_i_deg {
            Some(v) => self.theta_i(v)?,
            None => {
                return Err(self.missing(None, "theta_i_deg", "source zenith angles"));
            }
        };
        let wavelength_nm = match &raw.wavelength_nm {
            Some(v) => Some(self.num_in(v, "wavelength_nm", |x| x > 0.0, "> 0")?),
            None => None,
        };
        let background = match &raw.background {
            Some(v) => self.num_in(v, "background", |x| x >= 0.0, ">= 0")?,
            None => 0.0,
        };
        let seed = match &raw.seed {
            Some(v) if *v.get_ref() < 0 => {
                return Err(self.err(&v.span(), "seed", "must be a non-negative integer"));
            }
            Some(v) => *v.get_ref() as u64,
            None => 0,
        };
        let format = match &raw.format {
            None => ImageFormat::Png,
            Some(v) => match v.get_ref().to_ascii_lowercase().as_str() {
                "png" => ImageFormat::Png,
                "tif" | "tiff" => ImageFormat::Tiff,
                _ => return Err(self.err(&v.span(), "format", "must be \"png\" or \"tiff\"")),
            },
        };
        let sensor = self.sensor(raw.sensor.as_ref())?;
        let exposure = self.exposure(raw.exposure.as_ref())?;
        let capture = self.capture(raw.capture.as_ref())?;
        let plates = self.plates(&raw.plate, width, height)?;
        Ok(Scene {
            path: self.path.to_path_buf(),
            text: self.text.to_string(),
            name,
            width,
            height,
            theta_r_deg,
            phi_deg,
            theta_i_deg,
            wavelength_nm,
            background,
            seed,
            format,
            sensor,
            exposure,
            capture,
            plates,
        })
    }

    fn sensor(&self, raw: Option<&RawSensor>) -> Result<Sensor> {
        let mut s = Sensor::default();
        let Some(r) = raw else { return Ok(s) };
        if let Some(v) = &r.bit_depth {
            let b = *v.get_ref();
            if !(1..=16).contains(&b) {
                return Err(self.err(
                    &v.span(),
                    "sensor.bit_depth",
                    "must be an integer from 1 to 16",
                ));
            }
            s.bit_depth = b as u32;
        }
        if let Some(v) = &r.full_well_e {
            s.full_well_e = self.num_in(
                v,
                "sensor.full_well_e",
                |x| (1.0..=1e9).contains(&x),
                "from 1 to 1e9 electrons",
            )?;
        }
        if let Some(v) = &r.read_noise_e {
            s.read_noise_e = self.num_in(
                v,
                "sensor.read_noise_e",
                |x| (0.0..=1e6).contains(&x),
                ">= 0 electrons",
            )?;
        }
        if let Some(v) = &r.dark_level_dn {
            let max = s.max_dn();
            s.dark_level_dn = self.num_in(
                v,
                "sensor.dark_level_dn",
                |x| x >= 0.0 && x < max,
                &format!("in [0, {max}) DN (below the ADC maximum)"),
            )?;
        }
        if let Some(v) = &r.shot_noise {
            s.shot_noise = *v.get_ref();
        }
        Ok(s)
    }

    fn exposure(&self, raw: Option<&RawExposure>) -> Result<Exposure> {
        let Some(r) = raw else {
            return Ok(Exposure::Auto { fraction: 0.7 });
        };
        // Without `mode`, a `value` means a fixed exposure.
        let (mode, mode_span) = match &r.mode {
            Some(m) => (m.get_ref().as_str(), Some(m.span())),
            None if r.value.is_some() => ("fixed", None),
            None => ("auto", None),
        };
        match mode {
            "auto" => {
                if let Some(v) = &r.value {
                    return Err(self.err(
                        &v.span(),
                        "exposure.value",
                        "`value` is for mode = \"fixed\"; auto exposure takes `fraction`",
                    ));
                }
                let fraction = match &r.fraction {
                    Some(v) => {
                        self.num_in(v, "exposure.fraction", |x| x > 0.0 && x <= 1.0, "in (0, 1]")?
                    }
                    None => 0.7,
                };
                Ok(Exposure::Auto { fraction })
            }
            "fixed" => {
                if let Some(v) = &r.fraction {
                    return Err(self.err(
                        &v.span(),
                        "exposure.fraction",
                        "`fraction` is for mode = \"auto\"; a fixed exposure takes `value`",
                    ));
                }
                let v = r.value.as_ref().ok_or_else(|| {
                    self.missing(mode_span.as_ref(), "exposure.value", "fixed exposure value")
                })?;
                Ok(Exposure::Fixed(self.num_in(
                    v,
                    "exposure.value",
                    |x| x > 0.0 && x <= 1e12,
                    "> 0",
                )?))
            }
            _ => Err(self.err(
                &mode_span.unwrap_or(0..0),
                "exposure.mode",
                "must be \"auto\" or \"fixed\"",
            )),
        }
    }

    fn capture(&self, raw: Option<&RawCapture>) -> Result<CaptureKind> {
        let default_angles = vec![0.0, 45.0, 90.0, 135.0];
        let Some(r) = raw else {
            return Ok(CaptureKind::Frames {
                angles_deg: default_angles,
            });
        };
        let kind = r.kind.as_ref().map(|k| (k.get_ref().as_str(), k.span()));
        match kind {
            None | Some(("frames", _)) => {
                if let Some(p) = &r.pattern {
                    return Err(self.err(
                        &p.span(),
                        "capture.pattern",
                        "`pattern` is for kind = \"dofp\"",
                    ));
                }
                let angles_deg = match &r.angles_deg {
                    None => default_angles,
                    Some(v) => {
                        let a = v.get_ref().clone();
                        if let Err(e) = StokesSolver::from_degrees(&a) {
                            return Err(self.err(&v.span(), "capture.angles_deg", e.to_string()));
                        }
                        a
                    }
                };
                Ok(CaptureKind::Frames { angles_deg })
            }
            Some(("dofp", _)) => {
                if let Some(a) = &r.angles_deg {
                    return Err(self.err(
                        &a.span(),
                        "capture.angles_deg",
                        "`angles_deg` is for kind = \"frames\"; a DoFP capture takes `pattern`",
                    ));
                }
                let pattern = match &r.pattern {
                    None => Pattern::default(),
                    Some(v) => Pattern::new(v.get_ref())
                        .map_err(|e| self.err(&v.span(), "capture.pattern", e.to_string()))?,
                };
                Ok(CaptureKind::Dofp { pattern })
            }
            Some((_, span)) => {
                Err(self.err(&span, "capture.kind", "must be \"frames\" or \"dofp\""))
            }
        }
    }

    fn plates(&self, raw: &[RawPlate], width: usize, height: usize) -> Result<Vec<Plate>> {
        if raw.is_empty() {
            return Err(self.missing(None, "plate", "[[plate]]: at least one plate is needed"));
        }
        let mut plates: Vec<Plate> = Vec::with_capacity(raw.len());
        let mut names = HashSet::new();
        for (i, p) in raw.iter().enumerate() {
            let pre = format!("plate[{}].", i + 1);
            let f = |k: &str| format!("{pre}{k}");
            let name_v = p
                .name
                .as_ref()
                .ok_or_else(|| self.missing(None, &f("name"), "plate name"))?;
            let near = Some(name_v.span());
            let near = near.as_ref();
            let name = self.name(name_v, &f("name"))?;
            if !names.insert(name.clone()) {
                return Err(self.err(&name_v.span(), &f("name"), "duplicate plate name"));
            }
            let class = match &p.class {
                Some(v) if v.get_ref().trim().is_empty() => None,
                Some(v) => Some(self.name(v, &f("class"))?),
                None => None,
            };
            let req = |v: &Option<Spanned<f64>>, key: &str, what: &str| {
                v.as_ref()
                    .ok_or_else(|| self.missing(near, &f(key), what))
                    .cloned()
            };
            let n = self.num_in(
                &req(&p.n, "n", "real part of the index `n`")?,
                &f("n"),
                |x| x > 0.0 && x <= 100.0,
                "in (0, 100]",
            )?;
            let k = self.num_in(
                &req(&p.k, "k", "imaginary part of the index `k`")?,
                &f("k"),
                |x| (0.0..=100.0).contains(&x),
                "in [0, 100]",
            )?;
            let sigma = self.num_in(
                &req(&p.sigma, "sigma", "roughness `sigma`")?,
                &f("sigma"),
                |x| (1e-3..=10.0).contains(&x),
                "in [0.001, 10] (slope standard deviation)",
            )?;
            let rho_d = match &p.rho_d {
                Some(v) => {
                    self.num_in(v, &f("rho_d"), |x| (0.0..=1.0).contains(&x), "in [0, 1]")?
                }
                None => 0.0,
            };
            let rect_v = p
                .rect
                .as_ref()
                .ok_or_else(|| self.missing(near, &f("rect"), "plate rectangle `rect`"))?;
            let rect = self.rect(rect_v, &f("rect"))?;
            if let Err(e) = rect.check(width, height) {
                return Err(self.err(&rect_v.span(), &f("rect"), e.to_string()));
            }
            for q in &plates {
                let overlap = rect.x < q.rect.x + q.rect.width
                    && q.rect.x < rect.x + rect.width
                    && rect.y < q.rect.y + q.rect.height
                    && q.rect.y < rect.y + rect.height;
                if overlap {
                    return Err(self.err(
                        &rect_v.span(),
                        &f("rect"),
                        format!("overlaps plate {:?}", q.name),
                    ));
                }
            }
            let region = match &p.region {
                Some(v) => {
                    let r = self.rect(v, &f("region"))?;
                    let inside = r.x >= rect.x
                        && r.y >= rect.y
                        && r.x + r.width <= rect.x + rect.width
                        && r.y + r.height <= rect.y + rect.height;
                    if !inside {
                        return Err(self.err(
                            &v.span(),
                            &f("region"),
                            format!(
                                "the region must lie inside the plate's rect [{}, {}, {}, {}]",
                                rect.x, rect.y, rect.width, rect.height
                            ),
                        ));
                    }
                    r
                }
                None => default_region(rect).ok_or_else(|| {
                    self.err(
                        &rect_v.span(),
                        &f("rect"),
                        "plate too small for a default region; give `region`",
                    )
                })?,
            };
            plates.push(Plate {
                name,
                class,
                optics: PlateOptics { n, k, sigma, rho_d },
                rect,
                region,
                line: self.line(name_v.span().start),
            });
        }
        Ok(plates)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
name = "t"
width = 64
height = 32
theta_r_deg = 60
theta_i_deg = { start = 35, stop = 80, step = 5 }
seed = 3

[sensor]
dark_level_dn = 64

[capture]
kind = "dofp"

[[plate]]
name = "al"
class = "aluminum"
n = 1.24
k = 6.6
sigma = 0.2
rect = [0, 0, 32, 32]

[[plate]]
name = "cu"
n = 0.4
k = 2.95
sigma = 0.15
rect = [32, 0, 32, 32]
region = [36, 4, 20, 20]
"#;

    fn parse_err(text: &str) -> String {
        parse(Path::new("s.toml"), text).unwrap_err().to_string()
    }

    #[test]
    fn parses_a_scene_with_defaults() {
        let s = parse(Path::new("s.toml"), GOOD).unwrap();
        assert_eq!((s.width, s.height), (64, 32));
        assert_eq!(s.theta_i_deg.len(), 10);
        assert_eq!(s.theta_i_deg[9], 80.0);
        assert_eq!(s.phi_deg, 180.0);
        assert_eq!(s.exposure, Exposure::Auto { fraction: 0.7 });
        assert_eq!(s.sensor.dark_level_dn, 64.0);
        assert_eq!(s.sensor.bit_depth, 12);
        assert!(matches!(s.capture, CaptureKind::Dofp { .. }));
        // default region: inset 4, even
        assert_eq!(
            s.plates[0].region,
            Rect {
                x: 4,
                y: 4,
                width: 24,
                height: 24
            }
        );
        assert_eq!(s.plates[1].region.x, 36);
        assert_eq!(s.plates[0].class.as_deref(), Some("aluminum"));
        assert_eq!(s.plates[1].line, 24);
    }

    #[test]
    fn errors_name_line_and_field() {
        let e = parse_err(&GOOD.replace("sigma = 0.15", "sigma = -1"));
        assert!(e.contains("line 27") && e.contains("plate[2].sigma"), "{e}");
        let e = parse_err(&GOOD.replace("rect = [32, 0, 32, 32]", "rect = [40, 0, 32, 32]"));
        assert!(e.contains("plate[2].rect") && e.contains("64x32"), "{e}");
        let e = parse_err(&GOOD.replace("rect = [32, 0, 32, 32]", "rect = [16, 0, 16, 16]"));
        assert!(e.contains("overlaps plate \"al\""), "{e}");
        let e = parse_err(&GOOD.replace("seed = 3", "sede = 3"));
        assert!(e.contains("line 7") && e.contains("sede"), "{e}");
        let e = parse_err(&GOOD.replace("kind = \"dofp\"", "kind = \"video\""));
        assert!(e.contains("capture.kind") && e.contains("line 13"), "{e}");
        let e = parse_err(&GOOD.replace("region = [36, 4, 20, 20]", "region = [30, 4, 20, 20]"));
        assert!(e.contains("plate[2].region") && e.contains("inside"), "{e}");
        let e = parse_err(&GOOD.replace("theta_r_deg = 60", "theta_r_deg = 95"));
        assert!(e.contains("line 5") && e.contains("theta_r_deg"), "{e}");
        let e = parse_err(&GOOD.replace("k = 6.6", "k = \"big\""));
        assert!(e.contains("line 19") && e.contains("`k`"), "{e}");
        let e = parse_err(&GOOD.replace("dark_level_dn = 64", "dark_level_dn = 5000"));
        assert!(e.contains("sensor.dark_level_dn"), "{e}");
    }

    /// Fuzz finding (fuzz/fuzz_targets/scene.rs): a tiny `step` made the number of source
    /// positions overflow usize (a panic with overflow checks; without them the count
    /// wrapped to 0 and the error wrongly said no position was given).
    #[test]
    fn theta_i_range_with_a_tiny_step_is_refused() {
        for step in ["1e-300", "5e-324", "1e-15", "0.0001"] {
            let e = parse_err(&GOOD.replace("step = 5 }", &format!("step = {step} }}")));
            assert!(
                e.contains("line 6")
                    && e.contains("theta_i_deg")
                    && e.contains("more than 10000 source positions"),
                "{step}: {e}"
            );
        }
        // 10000 positions are accepted, 10001 are not (step 2^-7: exact arithmetic).
        let range = |stop: &str| {
            GOOD.replace(
                "{ start = 35, stop = 80, step = 5 }",
                &format!("{{ start = 0, stop = {stop}, step = 0.0078125 }}"),
            )
        };
        let s = parse(Path::new("s.toml"), &range("78.1171875")).unwrap();
        assert_eq!(s.theta_i_deg.len(), 10_000);
        assert_eq!(s.theta_i_deg[9_999], 78.1171875);
        let e = parse_err(&range("78.125"));
        assert!(e.contains("more than 10000 source positions"), "{e}");
    }
}
