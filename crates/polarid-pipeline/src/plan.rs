//! Planning the captures (`polarid plan`): which materials a bench's source positions can
//! tell apart under the hypothesis test of `polarid classify MEASUREMENTS.csv`, and which
//! `N` positions of a region of possible lamp positions tell them apart best
//! (docs/PLAN.md).
//!
//! Input: a scene (docs/SCENE.md): its camera, plane and plates (each plate's `class` is
//! the material it is, its region and optics set the noise), its sensor and exposure, and
//! its `[[source]]`s (the current plan, evaluated too). Candidates: a library (and
//! optionally a list of its materials). Per plate `A` and candidate `B ≠ A` the worst-case
//! non-centrality `λ_AB` and rejection power of `B`
//! (`polarid_core::classify::separability`); a plate is **identifiable** when every other
//! candidate is rejected with at least the target power.
//!
//! The recommended positions maximise the smallest margin `λ_AB / λ*` over the plates and
//! their hardest alternatives: Fedorov's exchange algorithm (start from positions spread
//! evenly in β, replace one position at a time by the candidate that raises the worst
//! margin most, until no exchange helps; a trial stops at the first active pair below
//! the current worst margin, and the trials run in parallel).
//!
//! The candidates are a region of lamp positions, or, with the scene's `[plan.sun]`
//! table ([`sun_window`]), the sun over a time window. A colour scene is planned in all
//! its bands: one test per pair over the rows of every band (one layer for all), and
//! each band's alone ([`PairResult::by_band`]).

use std::path::{Path, PathBuf};

use polarid_core::FitStatus;
use polarid_core::classify::separability::{
    PlanRow, Separation, TruthPoint, margin_of, separation, truth_grid, worst_case,
};
use polarid_core::classify::{CandidateModel, HypothesisConfig, MultiPrototype};
use polarid_core::pbrdf::pbrdf;
use polarid_core::simulate::{Exposure, Sensor};
use polarid_io::manifest::SourceSpec;
use polarid_io::scene::{CaptureKind, Geometry, Scene};
use polarid_io::table::measurements::Measurement;
use rayon::prelude::*;

use crate::classify::PrototypeSource;
use crate::error::ensure;
use crate::fit::FitConfig;
use crate::{PipelineError, Result, Warning};

/// Lowest expected electrons per pixel (S0, the plate's centre) for a position to count
/// as lighting a plate; darker positions are left out of the candidates.
pub const MIN_ELECTRONS: f64 = 100.0;

/// How many of each plate's hardest alternatives the exchange search optimises (all
/// alternatives are evaluated at the end; a pair found harder is added and the search
/// repeated).
pub const ACTIVE_PER_TARGET: usize = 4;

/// The region of possible lamp positions: a grid on a sphere about the plates' centre,
/// zenith from the plane's normal, azimuth from the direction opposite the camera (0: in
/// the camera's plane of incidence). Far-field scenes use the zeniths only (their `phi`).
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// Lamp distance from the plates' centre (scene units); `None`: the median distance
    /// of the scene's lamps (a distant source when the scene has none).
    pub distance: Option<f64>,
    /// Zenith range, degrees.
    pub zenith_deg: (f64, f64),
    /// Azimuth range, degrees.
    pub azimuth_deg: (f64, f64),
    /// Grid step in zenith, degrees (in azimuth twice as coarse).
    pub step_deg: f64,
}

impl Default for Region {
    fn default() -> Self {
        Self {
            distance: None,
            zenith_deg: (10.0, 85.0),
            azimuth_deg: (-40.0, 40.0),
            step_deg: 5.0,
        }
    }
}

/// The validated settings of a plan.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanConfig {
    /// Number of positions to recommend (2 … 64).
    pub positions: usize,
    /// The library of candidate materials (`builtin`, `builtin-rgb`, a CSV).
    pub library: String,
    /// Only these materials of the library (empty: all).
    pub materials: Vec<String>,
    /// Confidence of the test, as `classify --confidence`.
    pub confidence: f64,
    /// The rejection power that makes a pair separable.
    pub power: f64,
    /// The region of possible positions.
    pub region: Region,
    /// A row's DoLP standard error, instead of the one from the sensor and exposure.
    pub dolp_se: Option<f64>,
    /// The error model (as `fit`/`classify`: angle, DoLP floor, extinction, retardance).
    pub fit: FitConfig,
}

impl Default for PlanConfig {
    fn default() -> Self {
        Self {
            positions: 6,
            library: "builtin".into(),
            materials: Vec::new(),
            confidence: polarid_core::classify::DEFAULT_CONFIDENCE,
            power: 0.95,
            region: Region::default(),
            dolp_se: None,
            fit: FitConfig::default(),
        }
    }
}

impl PlanConfig {
    /// Check every value (errors name the option and the value).
    pub fn validate(&self) -> Result<()> {
        let n = self.positions;
        ensure((2..=64).contains(&n), "positions", n, "must be 2 to 64")?;
        let c = self.confidence;
        ensure(c > 0.0 && c < 1.0, "confidence", c, "must be in (0, 1)")?;
        let p = self.power;
        ensure(p > 0.0 && p < 1.0, "power", p, "must be in (0, 1)")?;
        let r = &self.region;
        if let Some(d) = r.distance {
            ensure(d > 0.0 && d.is_finite(), "distance", d, "must be > 0")?;
        }
        let (z0, z1) = r.zenith_deg;
        ensure(
            z0 >= 0.0 && z1 < 90.0 && z0 <= z1,
            "zenith-deg",
            format!("{z0}:{z1}"),
            "must be LO:HI with 0 <= LO <= HI < 90",
        )?;
        let (a0, a1) = r.azimuth_deg;
        ensure(
            a0 >= -180.0 && a1 <= 180.0 && a0 <= a1,
            "azimuth-deg",
            format!("{a0}:{a1}"),
            "must be LO:HI with -180 <= LO <= HI <= 180",
        )?;
        let step = r.step_deg;
        ensure(
            (0.5..=45.0).contains(&step),
            "step-deg",
            step,
            "must be 0.5 to 45",
        )?;
        if let Some(s) = self.dolp_se {
            ensure((0.0..1.0).contains(&s), "dolp-se", s, "must be in [0, 1)")?;
        }
        self.fit.validate()?;
        Ok(())
    }
}

/// The sun over a time window as the bench's possible source positions (the scene's
/// `[plan.sun]` table, docs/PLAN.md), instead of the lamp region.
#[derive(Debug, Clone, PartialEq)]
pub struct SunWindow {
    /// First time, as written (RFC 3339 with its offset).
    pub start: String,
    /// First time, Unix seconds (UTC).
    pub start_unix_s: f64,
    /// Last time, Unix seconds (UTC).
    pub end_unix_s: f64,
    /// Step, minutes.
    pub step_minutes: f64,
    /// The start's UTC offset, minutes (the times are written with it).
    pub offset_minutes: i32,
    /// The sun's irradiance (`intensity`; default: the mean of the scene's sources').
    pub intensity: Option<f64>,
}

/// `[plan.sun]` as written.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSunWindow {
    start: SunValue,
    end: SunValue,
    step_minutes: SunValue,
    intensity: SunValue,
}

/// `[plan]` as written.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlanTable {
    sun: Option<toml::Spanned<RawSunWindow>>,
}

/// The scene file's top level, `[plan]` only.
#[derive(Debug, serde::Deserialize)]
struct RawPlanKeys {
    plan: Option<toml::Spanned<RawPlanTable>>,
}

/// Most times a sun window may give.
pub const MAX_SUN_TIMES: f64 = 2000.0;

/// A `toml` value of `[plan.sun]` with its place in the file.
type SunValue = Option<toml::Spanned<toml::Value>>;

/// The scene file being read for `[plan.sun]`: its name and text, for errors naming the
/// line.
struct SunFile<'a> {
    file: String,
    text: &'a str,
}

impl SunFile<'_> {
    /// The line of the byte offset `span.start`.
    fn line_of(&self, span: &std::ops::Range<usize>) -> usize {
        self.text[..span.start.min(self.text.len())]
            .bytes()
            .filter(|&b| b == b'\n')
            .count()
            + 1
    }

    /// The configuration error of key `plan.sun.{key}` at `span`.
    fn err(
        &self,
        span: &std::ops::Range<usize>,
        key: &str,
        value: &dyn std::fmt::Display,
        why: &str,
    ) -> PipelineError {
        PipelineError::config(
            format!("{}, line {}: plan.sun.{key}", self.file, self.line_of(span)),
            value,
            why,
        )
    }

    /// The time `v` of key `key` (needed: `sun_span` is the table's place): as written,
    /// Unix seconds and its UTC offset in minutes.
    fn time(
        &self,
        v: &SunValue,
        key: &str,
        sun_span: &std::ops::Range<usize>,
    ) -> Result<(String, f64, i32)> {
        let Some(v) = v else {
            return Err(self.err(
                sun_span,
                key,
                &"(missing)",
                "is needed: an RFC 3339 time with its offset, e.g. \"2026-06-21T09:00:00-06:00\"",
            ));
        };
        let Some(text) = v.get_ref().as_str() else {
            return Err(self.err(
                &v.span(),
                key,
                v.get_ref(),
                "must be a quoted RFC 3339 time with its offset",
            ));
        };
        let ts = polarid_io::time::parse_rfc3339_timestamp(text).map_err(|e| {
            self.err(
                &v.span(),
                key,
                &format!("{text:?}"),
                &format!("is not a time: {e}"),
            )
        })?;
        Ok((text.to_string(), ts.unix_seconds_f64(), ts.offset_minutes))
    }

    /// The number `v` of key `key` and its place (`None` when not given).
    fn number(&self, v: &SunValue, key: &str) -> Result<Option<(f64, std::ops::Range<usize>)>> {
        let Some(v) = v else { return Ok(None) };
        let x = match v.get_ref() {
            toml::Value::Float(f) => *f,
            toml::Value::Integer(i) => *i as f64,
            other => return Err(self.err(&v.span(), key, other, "must be a number")),
        };
        Ok(Some((x, v.span())))
    }
}

/// Read the scene's `[plan.sun]` table (`None` without one). Errors name the file, the
/// line, the key and the value (a configuration error: exit status 2).
pub fn sun_window(scene: &Scene) -> Result<Option<SunWindow>> {
    let f = SunFile {
        file: scene.path.display().to_string(),
        text: &scene.text,
    };
    let file = &f.file;
    let keys: RawPlanKeys = toml::from_str(&scene.text).map_err(|e| {
        PipelineError::config(
            format!("{file}: [plan]"),
            e.message(),
            format!(
                "is not a valid [plan] table (line {}; keys: [plan.sun] start, end, step_minutes, intensity)",
                e.span().map_or(0, |s| f.line_of(&s))
            ),
        )
    })?;
    let Some(plan) = keys.plan else {
        return Ok(None);
    };
    let plan_span = plan.span();
    let Some(sun) = plan.into_inner().sun else {
        return Err(PipelineError::config(
            format!("{file}, line {}: [plan]", f.line_of(&plan_span)),
            "(no sun)",
            "must hold a [plan.sun] table (start, end, step_minutes)",
        ));
    };
    let sun_span = sun.span();
    let sun = sun.into_inner();
    let geometry_ok = matches!(&scene.geometry, Geometry::Calibrated(c) if c.site.is_some());
    if !geometry_ok {
        return Err(PipelineError::config(
            format!("{file}, line {}: [plan.sun]", f.line_of(&sun_span)),
            "(no [site])",
            "needs a calibrated scene ([camera]) with a [site] (latitude_deg, longitude_deg)",
        ));
    }
    let (start, start_unix_s, offset_minutes) = f.time(&sun.start, "start", &sun_span)?;
    let (_, end_unix_s, _) = f.time(&sun.end, "end", &sun_span)?;
    let end_span = sun.end.as_ref().map_or(sun_span.clone(), |v| v.span());
    if !(end_unix_s > start_unix_s) {
        return Err(f.err(
            &end_span,
            "end",
            &format!("{end_unix_s}"),
            "must be after plan.sun.start",
        ));
    }
    if end_unix_s - start_unix_s > 366.0 * 86400.0 {
        return Err(f.err(
            &end_span,
            "end",
            &format!("{end_unix_s}"),
            "must be within a year of plan.sun.start",
        ));
    }
    let (step_minutes, step_span) = f
        .number(&sun.step_minutes, "step_minutes")?
        .unwrap_or((15.0, sun_span.clone()));
    if !(step_minutes >= 1.0 && step_minutes <= 1440.0) {
        return Err(f.err(
            &step_span,
            "step_minutes",
            &step_minutes,
            "must be 1 to 1440 minutes",
        ));
    }
    let times = (end_unix_s - start_unix_s) / (60.0 * step_minutes);
    if times > MAX_SUN_TIMES {
        return Err(f.err(
            &step_span,
            "step_minutes",
            &step_minutes,
            &format!(
                "gives {} times over the window: at most {MAX_SUN_TIMES} (a longer step or a shorter window)",
                times.floor() + 1.0
            ),
        ));
    }
    let intensity = match f.number(&sun.intensity, "intensity")? {
        Some((x, span)) if !(x > 0.0 && x.is_finite()) => {
            return Err(f.err(&span, "intensity", &x, "must be > 0"));
        }
        Some((x, _)) => Some(x),
        None => None,
    };
    Ok(Some(SunWindow {
        start,
        start_unix_s,
        end_unix_s,
        step_minutes,
        offset_minutes,
        intensity,
    }))
}

/// A Unix time written in RFC 3339 with the offset `offset_minutes`.
fn local_time(unix_s: f64, offset_minutes: i32) -> String {
    let shifted = unix_s.round() as i64 + i64::from(offset_minutes) * 60;
    let utc = polarid_io::time::format_rfc3339_utc(shifted).unwrap_or_else(|| format!("{unix_s}"));
    let off = if offset_minutes == 0 {
        "Z".to_string()
    } else {
        let a = offset_minutes.abs();
        format!(
            "{}{:02}:{:02}",
            if offset_minutes < 0 { '-' } else { '+' },
            a / 60,
            a % 60
        )
    };
    match utc.strip_suffix('Z') {
        Some(t) => format!("{t}{off}"),
        None => utc,
    }
}

/// One source position: where it is and what each target plate sees from it.
#[derive(Debug, Clone, PartialEq)]
pub struct Position {
    /// Label: `d 0.70, t 35, a -20` (lamp), `t 35` (far field), the source's name or
    /// `source N` for the scene's own.
    pub label: String,
    /// The source as a scene writes it.
    pub spec: SourceSpec,
    /// Per target: `β` (degrees), the row's DoLP standard error, expected S0 electrons
    /// per pixel.
    pub rows: Vec<RowGeometry>,
    /// Whether the source lies in the camera's plane of incidence (azimuth 0; far-field
    /// and the scene's own sources: true).
    pub in_plane: bool,
}

/// What one target sees from one position.
#[derive(Debug, Clone, PartialEq)]
pub struct RowGeometry {
    /// Local incidence angle, degrees (the same in every band).
    pub beta_deg: f64,
    /// Source zenith at the plate, degrees.
    pub theta_i_deg: f64,
    /// Per band (in the order of [`PlanOutput::wavelengths_nm`]): the row's noise.
    pub bands: Vec<BandNoise>,
}

/// One band of a row: its DoLP standard error and brightness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BandNoise {
    /// The row's DoLP standard error (noise only).
    pub dolp_se: f64,
    /// Expected S0 electrons per pixel of the band at the plate's centre.
    pub electrons: f64,
}

/// A target plate: its material as a hypothesis test's truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// The plate's name.
    pub name: String,
    /// Its material (the plate's class).
    pub material: String,
}

/// One (target, alternative) pair.
#[derive(Debug, Clone, PartialEq)]
pub struct PairResult {
    /// Index into [`PlanOutput::targets`].
    pub target: usize,
    /// The alternative material.
    pub alternative: String,
    /// The separation (worst case over the target's nuisances), every band together:
    /// one test over the rows of all bands, one layer thickness for all, as `classify`.
    pub sep: Separation,
    /// A colour scene's separation by each band's rows alone (in the order of
    /// [`PlanOutput::wavelengths_nm`]); empty for one band.
    pub by_band: Vec<Separation>,
}

/// A design evaluated: its positions and every pair.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// The positions.
    pub positions: Vec<Position>,
    /// Every (target, alternative) pair, per target hardest (smallest margin) first.
    pub pairs: Vec<PairResult>,
    /// Per target: the fit of its noise-free rows (`fit`'s status gate: `classify` tests
    /// only targets whose fit is `ok`).
    pub fits: Vec<FitCheck>,
}

/// `fit` on a target's noise-free rows (its material at mid-layer, full scale, no
/// offset), with the plan's noise: whether `classify` would test the target at all.
#[derive(Debug, Clone, PartialEq)]
pub struct FitCheck {
    /// The band it is (a colour scene: the band whose fit fails, else the least
    /// precise one), nm.
    pub wavelength_nm: f64,
    /// The fit's status.
    pub status: FitStatus,
    /// The fit's reason when not `ok`.
    pub reason: String,
    /// The material's `n` (its bulk index at the band).
    pub n: f64,
    /// The material's `k`.
    pub k: f64,
    /// The fit's search box's upper ends `(n_max, k_max)`.
    pub box_max: (f64, f64),
    /// Standard errors of `n` and `k` (total).
    pub n_se: f64,
    /// See `n_se`.
    pub k_se: f64,
}

impl FitCheck {
    /// Whether the fit locates the material: status `ok`, and its two-sigma interval at
    /// the truth stays inside the fit's search box on the far side (`n + 2 n_se ≤ n_max`,
    /// `k + 2 k_se ≤ k_max`). Otherwise a noisy estimate can wander along the valley of
    /// the fit's χ² to where its standard error exceeds `fit`'s ill-conditioning bound
    /// (3 box widths), and `classify` then tests nothing (docs/PLAN.md).
    pub fn locates(&self) -> bool {
        self.status == FitStatus::Ok
            && self.n + 2.0 * self.n_se <= self.box_max.0
            && self.k + 2.0 * self.k_se <= self.box_max.1
    }
}

impl Evaluation {
    /// The hardest pair of target `t` (smallest margin).
    pub fn worst(&self, t: usize) -> Option<&PairResult> {
        self.pairs.iter().filter(|p| p.target == t).min_by(|a, b| {
            a.sep
                .margin
                .total_cmp(&b.sep.margin)
                .then(a.sep.power.total_cmp(&b.sep.power))
        })
    }

    /// Whether target `t` is identifiable: its fit is `ok` and every alternative is
    /// rejected with at least `power`.
    pub fn identifiable(&self, t: usize, power: f64) -> bool {
        self.fits.get(t).is_some_and(|f| f.locates())
            && self
                .pairs
                .iter()
                .filter(|p| p.target == t)
                .all(|p| p.sep.power >= power)
    }

    /// The alternatives of target `t` rejected with less than `power`.
    pub fn confused(&self, t: usize, power: f64) -> Vec<&PairResult> {
        self.pairs
            .iter()
            .filter(|p| p.target == t && p.sep.power < power)
            .collect()
    }

    /// The smallest margin over every pair.
    pub fn worst_margin(&self) -> f64 {
        self.pairs
            .iter()
            .map(|p| p.sep.margin)
            .fold(f64::INFINITY, f64::min)
    }
}

/// What `plan` found.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOutput {
    /// The scene file.
    pub scene: PathBuf,
    /// The plates planned for.
    pub targets: Vec<Target>,
    /// The candidate materials (library order).
    pub materials: Vec<String>,
    /// The library's label.
    pub library: String,
    /// The library as loaded (`builtin`, `builtin-rgb`, a CSV path: a colour scene's
    /// `builtin` is read as `builtin-rgb`).
    pub library_source: String,
    /// The bands' wavelengths, nm (one for a monochrome scene).
    pub wavelengths_nm: Vec<f64>,
    /// The bands' colour letters (colour scenes; empty for one band).
    pub band_letters: Vec<char>,
    /// The scene's own sources, evaluated (`None` when it has fewer than 2).
    pub current: Option<Evaluation>,
    /// The recommended positions, evaluated.
    pub recommended: Evaluation,
    /// The worst margin after each exchange pass (the search's progress).
    pub progress: Vec<f64>,
    /// How many candidate positions the region gave (lit, above the horizon).
    pub candidates: usize,
    /// The sun window the candidates came from (`[plan.sun]`), if any.
    pub sun: Option<SunWindow>,
    /// With a sun window: every candidate time (the sun's path over the window).
    pub sun_positions: Vec<Position>,
    /// The settings.
    pub config: PlanConfig,
    /// Warnings.
    pub warnings: Vec<Warning>,
}

impl PlanOutput {
    /// The recommended scene: the input scene's text with its `[[source]]` tables
    /// replaced by the recommended positions.
    pub fn recommended_scene(&self, scene_text: &str) -> String {
        let mut out = String::new();
        let mut skipping = false;
        for line in scene_text.lines() {
            let t = line.trim_start();
            if t.starts_with("[[source]]") {
                skipping = true;
                continue;
            }
            if skipping && t.starts_with('[') {
                skipping = false;
            }
            if !skipping {
                out.push_str(line);
                out.push('\n');
            }
        }
        out.push_str("\n# The positions recommended by `polarid plan` (docs/PLAN.md).\n");
        for p in &self.recommended.positions {
            out.push_str("[[source]]\n");
            match &p.spec {
                SourceSpec::Position(v) => out.push_str(&format!(
                    "position = [{:.4}, {:.4}, {:.4}]   # {}\n",
                    v[0], v[1], v[2], p.label
                )),
                SourceSpec::Direction(v) => out.push_str(&format!(
                    "direction = [{:.6}, {:.6}, {:.6}]   # {}\n",
                    v[0], v[1], v[2], p.label
                )),
                SourceSpec::Sun { time, .. } => out.push_str(&format!("sun = \"{time}\"\n")),
            }
        }
        out
    }
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}
fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = norm(v);
    [v[0] / n, v[1] / n, v[2] / n]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// A plate as the planner sees it.
struct PlateView {
    center: [f64; 3],
    normal: [f64; 3],
    /// Per band: `(n, k, response, sets)`, `sets` the independent DoLP estimates of the
    /// band in the region: super-pixels (DoFP; a colour DoFP: the band's blocks) or
    /// pixels.
    bands: Vec<(f64, f64, f64, f64)>,
    sigma: f64,
}

/// The scene's geometry for the planner.
enum Bench {
    Calibrated { camera: [f64; 3] },
    FarField { theta_r: f64, phi: f64 },
}

/// The angles `(θi, θr, φ)` (radians) and the irradiance factor at a plate for a source.
fn angles(bench: &Bench, p: &PlateView, src: &SourceSpec) -> Option<(f64, f64, f64, f64)> {
    match bench {
        Bench::Calibrated { camera } => {
            let v = unit(sub(*camera, p.center));
            let (l, e) = match src {
                SourceSpec::Position(s) => {
                    let d = sub(*s, p.center);
                    let r2 = dot(d, d);
                    (unit(d), 1.0 / r2)
                }
                SourceSpec::Direction(d) | SourceSpec::Sun { direction: d, .. } => (unit(*d), 1.0),
            };
            let ci = dot(l, p.normal);
            let cr = dot(v, p.normal);
            if ci <= 1e-6 || cr <= 1e-6 {
                return None;
            }
            let lp = sub(l, [ci * p.normal[0], ci * p.normal[1], ci * p.normal[2]]);
            let vp = sub(v, [cr * p.normal[0], cr * p.normal[1], cr * p.normal[2]]);
            let phi = if norm(lp) < 1e-9 || norm(vp) < 1e-9 {
                std::f64::consts::PI
            } else {
                (dot(lp, vp) / (norm(lp) * norm(vp)))
                    .clamp(-1.0, 1.0)
                    .acos()
            };
            Some((ci.acos(), cr.acos(), phi, e))
        }
        Bench::FarField { theta_r, phi } => match src {
            SourceSpec::Direction(d) => {
                let ti = d[2].clamp(-1.0, 1.0).acos();
                (ti < std::f64::consts::FRAC_PI_2).then_some((ti, *theta_r, *phi, 1.0))
            }
            _ => None,
        },
    }
}

impl Bench {
    fn of(geometry: &Geometry) -> Bench {
        match geometry {
            Geometry::Calibrated(c) => Bench::Calibrated {
                camera: c.camera.position,
            },
            Geometry::FarField {
                theta_r_deg,
                phi_deg,
                ..
            } => Bench::FarField {
                theta_r: theta_r_deg.to_radians(),
                phi: phi_deg.to_radians(),
            },
        }
    }
}

/// How the scene's plates are lit and seen: what a source position gives.
struct Lighting<'a> {
    bench: Bench,
    plates: Vec<PlateView>,
    sensor: &'a Sensor,
    exposure: &'a Exposure,
    /// The sources' intensity (the mean of the scene's own).
    intensity: f64,
    /// A fixed DoLP standard error per row (`None`: from the shot and read noise).
    dolp_se: Option<f64>,
}

impl Lighting<'_> {
    /// The position of the source `spec` at the scene's intensity ([`Self::rows`]).
    fn position(&self, label: String, spec: SourceSpec) -> Option<Position> {
        self.position_with(label, spec, self.intensity)
    }

    /// The position of the source `spec` at `intensity` ([`Self::rows`]).
    fn position_with(&self, label: String, spec: SourceSpec, intensity: f64) -> Option<Position> {
        self.rows(&spec, intensity).map(|rows| Position {
            label,
            spec,
            rows,
            in_plane: true,
        })
    }

    /// What every plate sees from a source: `None` when a plate is unlit (below its
    /// horizon) or too dark ([`MIN_ELECTRONS`]), or `β` is under 2°.
    fn rows(&self, src: &SourceSpec, intensity: f64) -> Option<Vec<RowGeometry>> {
        let plates = &self.plates;
        let mut s0 = Vec::with_capacity(plates.len());
        let mut peak: f64 = 0.0;
        let mut geo = Vec::with_capacity(plates.len());
        for p in plates {
            let (ti, tr, phi, e) = angles(&self.bench, p, src)?;
            let mut per_band = Vec::with_capacity(p.bands.len());
            let mut beta = 0.0;
            for &(n, k, response, _) in &p.bands {
                let f = pbrdf(n, k, p.sigma, ti, tr, phi).ok()?;
                // L = E cos θi (f00, …) times the band's response: S0 and the brightest
                // polarizer angle S0 (1 + P) / 2.
                let l0 = intensity * e * ti.cos() * f.local[0][0] * response;
                peak = peak.max(0.5 * l0 * (1.0 + f.dolp));
                per_band.push(l0);
                beta = f.beta;
            }
            s0.push(per_band);
            geo.push((beta, ti));
        }
        let x = self.exposure.resolve(peak).ok()?;
        let mut rows = Vec::with_capacity(plates.len());
        for ((p, l0s), (beta, ti)) in plates.iter().zip(s0).zip(geo) {
            if beta.to_degrees() < 2.0 {
                return None;
            }
            let mut bands = Vec::with_capacity(l0s.len());
            for (l0, &(_, _, _, sets)) in l0s.iter().zip(&p.bands) {
                // Expected S0 electrons of one pixel (the sum of two orthogonal polarizer
                // frames: x · S0 · full well).
                let el = self.sensor.electrons_per_unit(x) * l0;
                if !(el >= MIN_ELECTRONS) {
                    return None;
                }
                // Shot and read noise of a small DoLP from K independent sets of four
                // samples (S1 = I0 − I90 has variance S0 + 2 r² electrons²):
                // var P ≈ (S0 + 2 r²) / (K S0²).
                let r2 = self.sensor.read_noise_e * self.sensor.read_noise_e;
                let se = self
                    .dolp_se
                    .unwrap_or_else(|| ((el + 2.0 * r2) / (sets * el * el)).sqrt());
                bands.push(BandNoise {
                    dolp_se: se,
                    electrons: el,
                });
            }
            rows.push(RowGeometry {
                beta_deg: beta.to_degrees(),
                theta_i_deg: ti.to_degrees(),
                bands,
            });
        }
        Some(rows)
    }
}

/// The hypotheses of the plan and its error model.
struct Models {
    names: Vec<String>,
    models: Vec<CandidateModel>,
    /// Per target: index of its material in `names`.
    truth: Vec<usize>,
    cfg: HypothesisConfig,
    wavelengths: Vec<f64>,
    angle_sd: f64,
    floor: f64,
    power: f64,
    fit: FitConfig,
}

impl Models {
    fn new(
        cfg: &PlanConfig,
        names: Vec<String>,
        models: Vec<CandidateModel>,
        truth: Vec<usize>,
        wavelengths: &[f64],
    ) -> Models {
        let fit = cfg.fit;
        let angle_sd = fit.angle_sd_deg.to_radians();
        Models {
            names,
            models,
            truth,
            cfg: HypothesisConfig {
                confidence: cfg.confidence,
                nuisances: fit.nuisances(angle_sd),
                open_world: true,
            },
            wavelengths: wavelengths.to_vec(),
            angle_sd,
            floor: fit.dolp_floor,
            power: cfg.power,
            fit,
        }
    }

    /// Each target's truth grid.
    fn grids(&self) -> Vec<Vec<TruthPoint>> {
        self.truth
            .iter()
            .map(|&m| truth_grid(&self.models[m], &self.cfg))
            .collect()
    }

    /// Target `t`'s rows at `positions`: one per position and band (only band `band`
    /// when given).
    fn rows_of(&self, positions: &[&Position], t: usize, band: Option<usize>) -> Vec<PlanRow> {
        positions
            .iter()
            .flat_map(|p| {
                let r = &p.rows[t];
                r.bands
                    .iter()
                    .enumerate()
                    .filter(move |(b, _)| band.is_none_or(|x| x == *b))
                    .map(move |(b, n)| PlanRow {
                        beta: r.beta_deg.to_radians(),
                        dolp_sd: (n.dolp_se * n.dolp_se + self.floor * self.floor).sqrt(),
                        angle_sd: self.angle_sd,
                        band: b,
                    })
            })
            .collect()
    }

    fn pair(
        &self,
        positions: &[&Position],
        t: usize,
        alt: usize,
        grid: &[TruthPoint],
        band: Option<usize>,
    ) -> Result<Separation> {
        let rows = self.rows_of(positions, t, band);
        let truth = &self.models[self.truth[t]];
        Ok(separation(
            &rows,
            &self.wavelengths,
            truth,
            &self.models[alt],
            &self.cfg,
            grid,
            self.power,
        )?)
    }

    /// The margin of pair `(t, alt)` at `positions`, the worst case over `grid` (the
    /// margin of [`separation`] without its power and its full test), and the truth point
    /// of the worst case.
    fn margin(
        &self,
        positions: &[&Position],
        t: usize,
        alt: usize,
        grid: &[TruthPoint],
    ) -> Result<(f64, TruthPoint)> {
        let rows = self.rows_of(positions, t, None);
        let (lambda, dof, at) = worst_case(
            &rows,
            &self.wavelengths,
            &self.models[self.truth[t]],
            &self.models[alt],
            &self.cfg,
            grid,
        )?;
        Ok((margin_of(lambda, dof, self.cfg.confidence, self.power), at))
    }

    /// Every `(target, alternative)` pair.
    fn all_pairs(&self) -> Vec<(usize, usize)> {
        (0..self.truth.len())
            .flat_map(|t| {
                (0..self.models.len())
                    .filter(move |&alt| alt != self.truth[t])
                    .map(move |alt| (t, alt))
            })
            .collect()
    }

    /// Every pair of every target, the full grid.
    fn evaluate(&self, positions: Vec<Position>) -> Result<Evaluation> {
        let refs: Vec<&Position> = positions.iter().collect();
        let grids = self.grids();
        let mut pairs = self
            .all_pairs()
            .into_par_iter()
            .map(|(t, alt)| {
                let by_band = if self.wavelengths.len() > 1 {
                    (0..self.wavelengths.len())
                        .map(|b| self.pair(&refs, t, alt, &grids[t], Some(b)))
                        .collect::<Result<Vec<_>>>()?
                } else {
                    Vec::new()
                };
                Ok(PairResult {
                    target: t,
                    alternative: self.names[alt].clone(),
                    sep: self.pair(&refs, t, alt, &grids[t], None)?,
                    by_band,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        // Per target (in order), hardest first.
        pairs.sort_by(|a, b| {
            a.target
                .cmp(&b.target)
                .then(a.sep.margin.total_cmp(&b.sep.margin))
        });
        let fits = (0..self.truth.len())
            .into_par_iter()
            .map(|t| self.fit_check(&refs, t))
            .collect::<Result<Vec<_>>>()?;
        Ok(Evaluation {
            positions,
            pairs,
            fits,
        })
    }

    /// `fit` on target `t`'s noise-free rows ([`FitCheck`]).
    fn fit_check(&self, positions: &[&Position], t: usize) -> Result<FitCheck> {
        let mut worst: Option<FitCheck> = None;
        for b in 0..self.wavelengths.len() {
            let f = self.fit_check_band(positions, t, b)?;
            let bad = |f: &FitCheck| !f.locates();
            let spread = |f: &FitCheck| f.n_se + f.k_se;
            let replace = match &worst {
                None => true,
                Some(w) if bad(w) => false,
                Some(w) => bad(&f) || spread(&f) > spread(w),
            };
            if replace {
                worst = Some(f);
            }
        }
        worst.ok_or_else(|| PipelineError::config("scene", "plan", "no band to fit"))
    }

    /// `fit` on band `b` of target `t`'s noise-free rows.
    fn fit_check_band(&self, positions: &[&Position], t: usize, b: usize) -> Result<FitCheck> {
        let truth = &self.models[self.truth[t]];
        let mid = TruthPoint {
            thickness_nm: truth
                .layer
                .as_ref()
                .map_or(0.0, |l| 0.5 * (l.min_nm + l.max_nm)),
            scale: 1.0,
            offset: 0.0,
        };
        let (n, k) = truth.bulk[b];
        let check = |status, reason, n_se, k_se| FitCheck {
            wavelength_nm: self.wavelengths[b],
            status,
            reason,
            n,
            k,
            box_max: (self.fit.n_range.1, self.fit.k_range.1),
            n_se,
            k_se,
        };
        if positions.len() < 3 {
            // `fit` needs three rows of a target and band.
            let why = format!("{} rows: fit needs at least 3", positions.len());
            return Ok(check(FitStatus::IllConditioned, why, f64::NAN, f64::NAN));
        }
        let plan_rows = self.rows_of(positions, t, Some(b));
        let clean = polarid_core::classify::separability::truth_rows(
            &plan_rows,
            &self.wavelengths,
            truth,
            mid,
        );
        let rows: Vec<(u64, Measurement)> = positions
            .iter()
            .zip(&clean)
            .enumerate()
            .map(|(i, (p, h))| {
                (
                    i as u64 + 2,
                    Measurement {
                        target: "T".into(),
                        beta_deg: p.rows[t].beta_deg,
                        phi_deg: 180.0,
                        dolp: h.dolp,
                        dolp_se: Some(p.rows[t].bands[b].dolp_se),
                        wavelength_nm: Some(self.wavelengths[b]),
                        ..Default::default()
                    },
                )
            })
            .collect();
        let out = crate::fit::fit(Path::new("plan"), &rows, &self.fit, &|_, _, _| {})?;
        Ok(match out.targets.into_iter().next() {
            Some(f) => check(f.row.status, f.row.reason, f.row.n_se, f.row.k_se),
            None => check(
                FitStatus::IllConditioned,
                "no fit".into(),
                f64::NAN,
                f64::NAN,
            ),
        })
    }
}

/// An active pair of the search: target, alternative, and the truth points to try.
#[derive(Debug, Clone)]
struct Active {
    target: usize,
    alt: usize,
    grid: Vec<TruthPoint>,
}

/// The smallest margin over the active pairs for the positions `idx` of `cands`, or, as
/// soon as one pair's margin falls below `beat`, that pair's margin (a value below `beat`:
/// such a design cannot win the exchange, and the pairs are taken hardest first so that
/// most losing trials stop at the first). A design whose value is at least `beat` is
/// always evaluated in full.
fn objective(
    models: &Models,
    cands: &[Position],
    idx: &[usize],
    active: &[Active],
    beat: f64,
) -> f64 {
    let pos: Vec<&Position> = idx.iter().map(|&i| &cands[i]).collect();
    let mut worst = f64::INFINITY;
    for a in active {
        let m = models
            .margin(&pos, a.target, a.alt, &a.grid)
            .map_or(f64::NEG_INFINITY, |s| s.0);
        worst = worst.min(m);
        if worst < beat {
            break;
        }
    }
    worst
}

/// Sort the active pairs hardest first at the positions `idx` (stable); the smallest
/// margin.
fn order_active(
    models: &Models,
    cands: &[Position],
    idx: &[usize],
    active: &mut Vec<Active>,
) -> f64 {
    let pos: Vec<&Position> = idx.iter().map(|&i| &cands[i]).collect();
    let mut keyed: Vec<(f64, Active)> = std::mem::take(active)
        .into_par_iter()
        .map(|a| {
            let m = models
                .margin(&pos, a.target, a.alt, &a.grid)
                .map_or(f64::NEG_INFINITY, |s| s.0);
            (m, a)
        })
        .collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
    let worst = keyed.first().map_or(f64::INFINITY, |k| k.0);
    *active = keyed.into_iter().map(|k| k.1).collect();
    worst
}

/// Fedorov's exchange from the positions `idx`: for each slot in turn, the candidate
/// that raises the smallest margin over the `active` pairs most replaces it (candidates
/// tried in parallel); up to 3 passes, until no exchange helps. Appends the smallest
/// margin before and after each pass to `progress`; returns it.
fn exchange(
    models: &Models,
    cands: &[Position],
    idx: &mut [usize],
    active: &mut Vec<Active>,
    progress: &mut Vec<f64>,
) -> f64 {
    let mut best = order_active(models, cands, idx, active);
    progress.push(best);
    for _pass in 0..3 {
        let mut improved = false;
        for slot in 0..idx.len() {
            let beat = best * (1.0 + 1e-9) + 1e-12;
            let current: &[usize] = idx;
            let trials: Vec<(usize, f64)> = (0..cands.len())
                .into_par_iter()
                .filter(|c| !current.contains(c))
                .map(|c| {
                    let mut trial = current.to_vec();
                    trial[slot] = c;
                    (c, objective(models, cands, &trial, active, beat))
                })
                .collect();
            // The best trial (the first of equal ones) when it beats the current design.
            let pick = trials.iter().filter(|t| t.1 > beat).fold(
                None::<(usize, f64)>,
                |acc, &t| match acc {
                    Some(a) if a.1 >= t.1 => Some(a),
                    _ => Some(t),
                },
            );
            if let Some((c, _)) = pick {
                idx[slot] = c;
                improved = true;
                best = order_active(models, cands, idx, active);
            }
        }
        progress.push(best);
        if !improved {
            break;
        }
    }
    best
}

/// The bands a scene is planned in and the library holding its candidates.
struct PlanBands {
    wavelengths: Vec<f64>,
    letters: Vec<char>,
    library: String,
}

/// A colour scene's bands (every band together, as `classify`; the one-band library
/// `builtin` becomes `builtin-rgb`), else one band: the scene's wavelength or the
/// built-in library's.
fn plan_bands(scene: &Scene, cfg: &PlanConfig, warnings: &mut Vec<Warning>) -> PlanBands {
    let scene_path = scene.path.display();
    match scene.capture.bands() {
        Some(bands) => {
            let library = if cfg.library == "builtin" {
                warnings.push(Warning(format!(
                    "{scene_path} is a colour scene and the library `builtin` has one band: \
                         planned with `builtin-rgb`, its materials in the three bands"
                )));
                "builtin-rgb".to_string()
            } else {
                cfg.library.clone()
            };
            PlanBands {
                wavelengths: bands.iter().map(|b| b.wavelength_nm).collect(),
                letters: bands.iter().map(|b| b.letter).collect(),
                library,
            }
        }
        None => {
            let wl = match scene.wavelength_nm {
                Some(w) => w,
                None => {
                    warnings.push(Warning(format!(
                            "{scene_path} gives no wavelength_nm: planned at {} nm, the built-in library's band",
                            polarid_io::library::BUILTIN_WAVELENGTH_NM
                        )));
                    polarid_io::library::BUILTIN_WAVELENGTH_NM
                }
            };
            PlanBands {
                wavelengths: vec![wl],
                letters: Vec::new(),
                library: cfg.library.clone(),
            }
        }
    }
}

/// The candidate materials of the library `bands.library` (only `cfg.materials` when
/// given): their names (each once), their models and the library's label.
fn candidate_models(
    cfg: &PlanConfig,
    bands: &PlanBands,
    warnings: &mut Vec<Warning>,
) -> Result<(Vec<String>, Vec<CandidateModel>, String)> {
    let source = PrototypeSource::Library(bands.library.clone());
    let (protos, label, w) = source.load_multi_for(&bands.wavelengths, 0)?;
    warnings.extend(w);
    let protos: Vec<MultiPrototype> = if cfg.materials.is_empty() {
        protos
    } else {
        for m in &cfg.materials {
            let why = format!("no material of that name in {label} (see `polarid library --list`)");
            ensure(protos.iter().any(|p| &p.class == m), "materials", m, why)?;
        }
        protos
            .into_iter()
            .filter(|p| cfg.materials.contains(&p.class))
            .collect()
    };
    let mut names = Vec::new();
    let mut models = Vec::new();
    for p in &protos {
        if names.contains(&p.class) {
            continue;
        }
        if let Some(m) = CandidateModel::from_prototype(p, &bands.wavelengths) {
            names.push(p.class.clone());
            models.push(m);
        }
    }
    Ok((names, models, label))
}

/// The plates planned for (those whose class is a candidate), as the report names them,
/// as indices into the candidates, and as the planner sees them.
#[derive(Default)]
struct TargetPlates {
    targets: Vec<Target>,
    truth: Vec<usize>,
    plates: Vec<PlateView>,
}

/// Pixels per independent DoLP estimate of each band: a super-pixel of four (DoFP), one
/// pixel (rotating polarizer); a colour DoFP's band has `blocks` of the four 2×2 blocks
/// of each 4×4 period.
fn pixels_per_set(capture: &CaptureKind) -> Vec<f64> {
    match capture {
        CaptureKind::Dofp { .. } => vec![4.0],
        CaptureKind::ColourDofp { pattern, bands } => (0..bands.len())
            .map(|b| {
                let blocks = (0..4).filter(|&k| pattern.block_band(k) == b).count();
                16.0 / blocks.max(1) as f64
            })
            .collect(),
        CaptureKind::Frames { .. } => vec![1.0],
    }
}

/// The scene's plates whose class is one of `names` (the library `label`'s materials);
/// a warning for each other plate. Errors when none is.
fn target_plates(
    scene: &Scene,
    names: &[String],
    label: &str,
    warnings: &mut Vec<Warning>,
) -> Result<TargetPlates> {
    let per_set = pixels_per_set(&scene.capture);
    let responses: Vec<f64> = match scene.capture.bands() {
        Some(bands) => bands.iter().map(|b| b.response).collect(),
        None => vec![1.0],
    };
    let mut out = TargetPlates::default();
    for p in &scene.plates {
        let Some(class) = &p.class else {
            warnings.push(Warning(format!(
                "plate {:?} has no class: not planned for",
                p.name
            )));
            continue;
        };
        let Some(i) = names.iter().position(|n| n == class) else {
            warnings.push(Warning(format!(
                "plate {:?} is {class:?}, not a material of {label}: not planned for",
                p.name
            )));
            continue;
        };
        let (center, normal) = match (&scene.geometry, &p.placement) {
            (Geometry::Calibrated(c), Some(pl)) => {
                let plane = &c.planes[pl.plane];
                (pl.center, unit(plane.normal))
            }
            _ => ([0.0; 3], [0.0, 0.0, 1.0]),
        };
        out.targets.push(Target {
            name: p.name.clone(),
            material: class.clone(),
        });
        out.truth.push(i);
        let pixels = (p.region.width * p.region.height) as f64;
        let optics: Vec<(f64, f64)> = if p.bands.is_empty() {
            vec![(p.optics.n, p.optics.k)]
        } else {
            p.bands.iter().map(|o| (o.n, o.k)).collect()
        };
        out.plates.push(PlateView {
            center,
            normal,
            bands: optics
                .iter()
                .zip(&responses)
                .zip(&per_set)
                .map(|((&(n, k), &r), &per)| (n, k, r, pixels / per))
                .collect(),
            sigma: p.optics.sigma,
        });
    }
    ensure(
        !out.targets.is_empty(),
        "scene",
        scene.path.display(),
        format!(
            "no plate has a class that is a material of {label}: give each plate the \
             `class` of its material"
        ),
    )?;
    Ok(out)
}

/// The scene's own sources (label and spec) and their mean intensity.
fn own_sources(geometry: &Geometry) -> (Vec<(String, SourceSpec)>, f64) {
    match geometry {
        Geometry::Calibrated(c) => (
            c.sources
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    (
                        s.name.clone().unwrap_or(format!("source {}", i + 1)),
                        s.spec.clone(),
                    )
                })
                .collect(),
            if c.sources.is_empty() {
                1.0
            } else {
                c.sources.iter().map(|s| s.intensity).sum::<f64>() / c.sources.len() as f64
            },
        ),
        Geometry::FarField { theta_i_deg, .. } => {
            (theta_i_deg.iter().map(|&t| far_source(t)).collect(), 1.0)
        }
    }
}

/// A distant source at zenith `t` degrees in the camera's plane of incidence: `t 35`.
fn far_source(t: f64) -> (String, SourceSpec) {
    let r = t.to_radians();
    (
        format!("t {t}"),
        SourceSpec::Direction([r.sin(), 0.0, r.cos()]),
    )
}

/// The sun over the window `w`: one candidate per time the sun is up and lights every
/// plate. Errors: a scene without a `[site]`, a window with fewer such times than
/// `cfg.positions`.
fn sun_candidates(
    light: &Lighting,
    scene: &Scene,
    w: &SunWindow,
    cfg: &PlanConfig,
) -> Result<Vec<Position>> {
    let scene_path = scene.path.display().to_string();
    let site = match &scene.geometry {
        Geometry::Calibrated(c) => c.site.as_ref(),
        Geometry::FarField { .. } => None,
    };
    let Some(site) = site else {
        return Err(PipelineError::config(
            "[plan.sun]",
            &scene_path,
            "needs a [site]",
        ));
    };
    let core_site = polarid_core::sun::Site {
        latitude_deg: site.latitude_deg,
        longitude_deg: site.longitude_deg,
        elevation_m: site.elevation_m,
        pressure_mbar: site.pressure_mbar,
        temperature_c: site.temperature_c,
    };
    let path = polarid_core::sun::sun_path(
        &core_site,
        w.start_unix_s,
        w.end_unix_s,
        60.0 * w.step_minutes,
    )?;
    let mut cands = Vec::new();
    for (t, pos) in path {
        let time = local_time(t, w.offset_minutes);
        let spec = SourceSpec::Sun {
            time: time.clone(),
            unix_seconds: t,
            zenith_deg: pos.zenith_deg,
            azimuth_deg: pos.azimuth_deg,
            direction: polarid_core::sun::sun_direction(&pos),
        };
        if let Some(mut p) = light.position_with(time, spec, w.intensity.unwrap_or(light.intensity))
        {
            p.in_plane = false;
            cands.push(p);
        }
    }
    if cands.len() < cfg.positions {
        return Err(PipelineError::config(
            format!("{scene_path}: [plan.sun]"),
            format!(
                "{} to {} every {} min",
                w.start,
                local_time(w.end_unix_s, w.offset_minutes),
                w.step_minutes
            ),
            format!(
                "gives only {} times when the sun is up and lights every plate, for {} \
                 positions: widen the window, shorten the step or ask for fewer",
                cands.len(),
                cfg.positions
            ),
        ));
    }
    Ok(cands)
}

/// `lo, lo + step, …` up to `hi`.
fn steps_of((lo, hi): (f64, f64), step: f64) -> Vec<f64> {
    let n = ((hi - lo) / step + 1e-9).floor() as usize;
    (0..=n).map(|i| lo + i as f64 * step).collect()
}

/// The region's lit candidates: lamps on a grid of zenith and azimuth about the plates'
/// centre (calibrated bench; at the distance `r.distance`, else the median of the
/// scene's lamps `own`, else distant), or far-field directions of the zeniths.
fn region_candidates(light: &Lighting, own: &[(String, SourceSpec)], r: &Region) -> Vec<Position> {
    let zeniths = steps_of(r.zenith_deg, r.step_deg);
    let mut cands = Vec::new();
    let Bench::Calibrated { camera } = &light.bench else {
        let far = zeniths.iter().map(|&t| far_source(t));
        return far
            .filter_map(|(label, spec)| light.position(label, spec))
            .collect();
    };
    let plates = &light.plates;
    let n_p = plates.len() as f64;
    let o = plates.iter().fold([0.0; 3], |a, p| {
        [
            a[0] + p.center[0] / n_p,
            a[1] + p.center[1] / n_p,
            a[2] + p.center[2] / n_p,
        ]
    });
    let nrm = plates[0].normal;
    let away = sub(o, *camera);
    let e1 = unit(sub(away, {
        let c = dot(away, nrm);
        [c * nrm[0], c * nrm[1], c * nrm[2]]
    }));
    let e2 = cross(nrm, e1);
    let mut lamps: Vec<f64> = own
        .iter()
        .filter_map(|(_, s)| match s {
            SourceSpec::Position(p) => Some(norm(sub(*p, o))),
            _ => None,
        })
        .collect();
    lamps.sort_by(f64::total_cmp);
    let distance = r.distance.or(lamps.get(lamps.len() / 2).copied());
    for &t in &zeniths {
        let azis = if t == 0.0 {
            vec![0.0]
        } else {
            let mut a = steps_of(r.azimuth_deg, 2.0 * r.step_deg);
            if r.azimuth_deg.0 <= 0.0 && r.azimuth_deg.1 >= 0.0 && !a.contains(&0.0) {
                a.push(0.0);
            }
            a
        };
        for &a in &azis {
            let (tr, ar) = (t.to_radians(), a.to_radians());
            let dir: [f64; 3] = std::array::from_fn(|i| {
                tr.sin() * ar.cos() * e1[i] + tr.sin() * ar.sin() * e2[i] + tr.cos() * nrm[i]
            });
            let (label, spec) = match distance {
                Some(d) => (
                    format!("d {d:.2}, t {t}, a {a}"),
                    SourceSpec::Position(std::array::from_fn(|i| o[i] + d * dir[i])),
                ),
                None => (format!("t {t}, a {a}"), SourceSpec::Direction(dir)),
            };
            if let Some(mut p) = light.position(label, spec) {
                p.in_plane = a == 0.0;
                cands.push(p);
            }
        }
    }
    cands
}

/// Active pairs: each target's hardest alternatives, screened on the candidates in the
/// camera's plane of incidence (all of them when none is), each with the three points of
/// its truth grid that were hardest there.
fn active_pairs(
    models: &Models,
    cands: &[Position],
    grids: &[Vec<TruthPoint>],
) -> Result<Vec<Active>> {
    let in_plane: Vec<&Position> = cands.iter().filter(|p| p.in_plane).collect();
    let screen: Vec<&Position> = if in_plane.len() >= 3 {
        in_plane
    } else {
        cands.iter().collect()
    };
    let mut active: Vec<Active> = Vec::new();
    for (t, grid) in grids.iter().enumerate() {
        let alts: Vec<usize> = (0..models.models.len())
            .filter(|&alt| alt != models.truth[t])
            .collect();
        let mut m = alts
            .into_par_iter()
            .map(|alt| {
                let mut pts: Vec<(f64, TruthPoint)> = Vec::with_capacity(grid.len());
                for &at in grid {
                    pts.push((models.margin(&screen, t, alt, &[at])?.0, at));
                }
                pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                Ok((pts[0].0, alt, pts.iter().take(3).map(|p| p.1).collect()))
            })
            .collect::<Result<Vec<(f64, usize, Vec<TruthPoint>)>>>()?;
        m.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for (_, alt, pts) in m.into_iter().take(ACTIVE_PER_TARGET) {
            active.push(Active {
                target: t,
                alt,
                grid: pts,
            });
        }
    }
    Ok(active)
}

/// Sort candidate indices by the first target's β.
fn sort_by_beta(idx: &mut [usize], cands: &[Position]) {
    idx.sort_by(|&a, &b| {
        cands[a].rows[0]
            .beta_deg
            .total_cmp(&cands[b].rows[0].beta_deg)
    });
}

/// The starting design: `n` positions spread evenly in the first target's β.
fn start_design(cands: &[Position], n: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..cands.len()).collect();
    sort_by_beta(&mut order, cands);
    let mut idx: Vec<usize> = (0..n)
        .map(|i| order[(i * (order.len() - 1)) / (n - 1)])
        .collect();
    idx.dedup();
    while idx.len() < n {
        if let Some(&c) = order.iter().find(|c| !idx.contains(c)) {
            idx.push(c);
        }
    }
    idx
}

/// Up to three rounds of [`exchange`] from the positions `idx`: after each, every pair is
/// checked at the chosen positions, and a pair found harder than the active ones (or a
/// harder truth point of an active pair) is added before searching again. Returns the
/// smallest margin before and after each pass.
fn search(
    models: &Models,
    cands: &[Position],
    grids: &[Vec<TruthPoint>],
    idx: &mut [usize],
    active: &mut Vec<Active>,
) -> Result<Vec<f64>> {
    let all_pairs = models.all_pairs();
    let mut progress = Vec::new();
    for _round in 0..3 {
        let best = exchange(models, cands, idx, active, &mut progress);
        let chosen: Vec<&Position> = idx.iter().map(|&i| &cands[i]).collect();
        let checked = all_pairs
            .par_iter()
            .map(|&(t, alt)| Ok((t, alt, models.margin(&chosen, t, alt, &grids[t])?)))
            .collect::<Result<Vec<_>>>()?;
        let mut added = false;
        for (t, alt, (margin, worst)) in checked {
            match active.iter_mut().find(|a| a.target == t && a.alt == alt) {
                Some(a) if !a.grid.contains(&worst) => {
                    a.grid.push(worst);
                    added = true;
                }
                Some(_) => {}
                None if margin < best => {
                    active.push(Active {
                        target: t,
                        alt,
                        grid: vec![worst],
                    });
                    added = true;
                }
                None => {}
            }
        }
        if !added {
            break;
        }
    }
    Ok(progress)
}

/// Plan the captures of `scene` (module documentation).
///
/// Errors: a configuration error naming the option, a scene without plates of a
/// candidate material (naming the plates and the library), an unusable library, a region
/// with fewer lit positions than asked for.
pub fn plan(scene: &Scene, cfg: &PlanConfig) -> Result<PlanOutput> {
    cfg.validate()?;
    let mut warnings = Vec::new();
    let bands = plan_bands(scene, cfg, &mut warnings);
    let (names, models, label) = candidate_models(cfg, &bands, &mut warnings)?;
    let TargetPlates {
        targets,
        truth,
        plates,
    } = target_plates(scene, &names, &label, &mut warnings)?;
    let models = Models::new(cfg, names, models, truth, &bands.wavelengths);
    let (own, intensity) = own_sources(&scene.geometry);
    let light = Lighting {
        bench: Bench::of(&scene.geometry),
        plates,
        sensor: &scene.sensor,
        exposure: &scene.exposure,
        intensity,
        dolp_se: cfg.dolp_se,
    };
    let mut current_positions = Vec::new();
    for (label, spec) in &own {
        match light.position(label.clone(), spec.clone()) {
            Some(p) => current_positions.push(p),
            None => warnings.push(Warning(format!(
                "the scene's {label} leaves a plate dark or unlit: left out of the current plan"
            ))),
        }
    }
    let sun = sun_window(scene)?;
    let cands = match &sun {
        Some(w) if matches!(scene.geometry, Geometry::Calibrated(_)) => {
            sun_candidates(&light, scene, w, cfg)?
        }
        _ => region_candidates(&light, &own, &cfg.region),
    };
    let r = &cfg.region;
    ensure(
        cands.len() >= cfg.positions,
        "positions",
        cfg.positions,
        format!(
            "the region gives only {} lit positions (zenith {:?}, azimuth {:?}, step {}): \
             widen it or ask for fewer",
            cands.len(),
            r.zenith_deg,
            r.azimuth_deg,
            r.step_deg
        ),
    )?;
    let grids = models.grids();
    let mut active = active_pairs(&models, &cands, &grids)?;
    let mut idx = start_design(&cands, cfg.positions);
    let progress = search(&models, &cands, &grids, &mut idx, &mut active)?;
    sort_by_beta(&mut idx, &cands);
    let recommended = models.evaluate(idx.iter().map(|&i| cands[i].clone()).collect())?;
    let current = (current_positions.len() >= 2)
        .then(|| models.evaluate(current_positions))
        .transpose()?;
    Ok(PlanOutput {
        scene: scene.path.clone(),
        targets,
        materials: models.names,
        library: label,
        library_source: bands.library,
        wavelengths_nm: bands.wavelengths,
        band_letters: bands.letters,
        current,
        recommended,
        progress,
        candidates: cands.len(),
        sun_positions: sun.as_ref().map_or_else(Vec::new, |_| cands.clone()),
        sun,
        config: cfg.clone(),
        warnings,
    })
}

/// Load the scene at `path` and plan it ([`plan`]).
///
/// Errors: the scene's (naming the file, line and field), then [`plan`]'s.
pub fn plan_file(path: &Path, cfg: &PlanConfig) -> Result<PlanOutput> {
    cfg.validate()?;
    let scene = polarid_io::scene::load(path)?;
    plan(&scene, cfg)
}

/// The DoLP curve of material `name` (its layer at the range's middle) in the first band
/// for plots: `(β degrees, DoLP)` from 0 to 89°.
pub fn dolp_curve(out: &PlanOutput, name: &str) -> Result<Vec<(f64, f64)>> {
    let source = PrototypeSource::Library(out.library_source.clone());
    let (protos, _, _) = source.load_multi_for(&out.wavelengths_nm, 0)?;
    let Some(p) = protos.iter().find(|p| p.class == name) else {
        return Ok(Vec::new());
    };
    let Some(m) = CandidateModel::from_prototype(p, &out.wavelengths_nm) else {
        return Ok(Vec::new());
    };
    let wl = out.wavelengths_nm[0];
    let (layer, d) = match &m.layer {
        Some(l) => (l.index[0], 0.5 * (l.min_nm + l.max_nm) / wl),
        None => ((1.0, 0.0), 0.0),
    };
    Ok((0..=178)
        .map(|i| {
            let b = i as f64 * 0.5;
            (
                b,
                polarid_core::classify::layered_dolp(m.bulk[0], layer, d, b.to_radians()),
            )
        })
        .collect())
}
