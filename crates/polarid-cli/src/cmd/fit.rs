//! `polarid fit MEASUREMENTS.csv [-o fits.csv] [--reflectance auto|specular|mixed]`:
//! the complex index `(n, k)` of every target from its DoLP measurements (paper
//! section 5, eq. 16), written as the fits CSV of `docs/FORMATS.md`.
//!
//! The work (grouping by target, the specular fit with the `depolarized` rule, the mixed
//! radiometric fit with model selection) is `polarid_pipeline::fit`; see its
//! documentation. `--models FILE` writes both radiometric fits of every target with their
//! information criteria (`--reflectance mixed`). Rows with `beta_sd_deg` (regions of
//! calibrated captures) are fitted with the model `P(β̄) + ½ P''(β̄) s_β²` of the
//! region's spread of β (docs/GEOMETRY.md). The standard errors include the systematic
//! errors of the geometry and the polarimeter (`--angle-sd-deg`, `--dolp-floor`,
//! `--extinction-ratio`, `--retardance-deg`), and `--mismatch-p` sets the level of the
//! model checks (docs/ERRORS.md). Measurement rows whose `status` is not `ok` are
//! skipped, and a target that cannot be fitted gets a row with status `invalid_input`
//! and the reason; `--strict` makes either an error (docs/FORMATS.md, "Partial failure").

use std::path::PathBuf;

use polarid_core::mixed::{DEPOLARIZED_MAX_DOLP, Shadowing};
use polarid_io::table::fits;
use polarid_io::table::write_rows;
use polarid_pipeline::fit::{
    self as pipe, DEFAULT_ANGLE_SD_DEG, DEFAULT_DOLP_FLOOR, DEFAULT_EXTINCTION_RATIO,
    DEFAULT_FILM_SD_NM, DEFAULT_MISMATCH_P, DEFAULT_RETARDANCE_DEG, DEFAULT_WAVELENGTH_NM,
    FitConfig, MODEL_COLUMNS, Reflectance, model_rows, range_problem, read_measurements,
};

use super::common::{Bars, PipeResult};
use crate::render::table_report;
use crate::{BadInput, Ctx};

/// Reflectance model of the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ReflectanceArg {
    /// Specular, then the brightness check when the rows carry s0 and exposure: Lambert
    /// brightness makes a target `depolarized`, and the mixed model replaces the
    /// specular fit when BIC selects it (docs/MIXED.md).
    Auto,
    /// Specular Fresnel reflection only (the paper's eq. 9), with no brightness check.
    Specular,
    /// Specular plus a Lambertian depolarized diffuse term; uses `s0` too.
    Mixed,
}

/// Shadowing factor of the mixed model's specular term.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ShadowingArg {
    /// None: the paper's eq. (3).
    None,
    /// Smith G1(θi)·G1(θr) of a Beckmann surface (α = √2 σ).
    Smith,
}

/// Arguments of `polarid fit`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Measurements CSV (written by `polarid measure`); `-`: standard input.
    pub measurements: PathBuf,
    /// Output fits CSV (standard output when absent or `-`).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Reflectance model.
    #[arg(long, value_enum, default_value = "auto")]
    pub reflectance: ReflectanceArg,
    /// Search box for n, as MIN,MAX.
    #[arg(long, value_name = "MIN,MAX", default_value = "0.01,10", value_parser = parse_range)]
    pub n_range: (f64, f64),
    /// Search box for k, as MIN,MAX (MIN >= 0).
    #[arg(long, value_name = "MIN,MAX", default_value = "0,15", value_parser = parse_range)]
    pub k_range: (f64, f64),
    /// Specular fit: status `depolarized` when the DoLP stays below this at every
    /// source position.
    #[arg(long, value_name = "DOLP", default_value_t = DEPOLARIZED_MAX_DOLP, value_parser = parse_unit)]
    pub depolarized_dolp: f64,
    /// Mixed fit: estimate the camera zenith θr (known: each capture's beta, i.e. the
    /// source-camera angle; in-plane captures only).
    #[arg(long)]
    pub estimate_theta_r: bool,
    /// Mixed fit: shadowing factor of the specular term.
    #[arg(long, value_enum, default_value = "none")]
    pub shadowing: ShadowingArg,
    /// Mixed fit: relative standard deviation of s0 (weight of the intensity residuals).
    #[arg(long, value_name = "FRACTION", default_value_t = 0.02, value_parser = parse_unit)]
    pub s0_rel_sd: f64,
    /// Mixed fit: search range of the roughness sigma, as MIN,MAX.
    #[arg(long, value_name = "MIN,MAX", default_value = "0.02,1", value_parser = parse_range)]
    pub sigma_range: (f64, f64),
    /// Mixed fit: also write both models' fits of every target (CSV) to this file.
    #[arg(long, value_name = "CSV")]
    pub models: Option<PathBuf>,
    /// Standard uncertainty of the source and camera directions, degrees, for rows
    /// without an angle_sd_deg (docs/ERRORS.md).
    #[arg(long, value_name = "DEG", default_value_t = DEFAULT_ANGLE_SD_DEG)]
    pub angle_sd_deg: f64,
    /// Additive DoLP error of the polarimeter (standard deviation, per measurement).
    #[arg(long, value_name = "DOLP", default_value_t = DEFAULT_DOLP_FLOOR)]
    pub dolp_floor: f64,
    /// The lowest extinction ratio the polarizer may have (DoLP scale uncertainty
    /// 2/(ER+1), common to a target's measurements; inf: ideal).
    #[arg(long, value_name = "ER", default_value_t = DEFAULT_EXTINCTION_RATIO)]
    pub extinction_ratio: f64,
    /// The largest retardance ahead of the polarizer, degrees.
    #[arg(long, value_name = "DEG", default_value_t = DEFAULT_RETARDANCE_DEG)]
    pub retardance_deg: f64,
    /// Status model_mismatch when the goodness-of-fit or AoLP test has a p-value below
    /// this (0: never).
    #[arg(long, value_name = "P", default_value_t = DEFAULT_MISMATCH_P)]
    pub mismatch_p: f64,
    /// Stop with exit status 2 at the first problem (a skipped measurement row, a target
    /// that cannot be fitted) instead of writing its row with a status and a reason.
    #[arg(long)]
    pub strict: bool,
    /// Standard thickness of an unmodelled surface layer (native oxide), nm.
    #[arg(long, value_name = "NM", default_value_t = DEFAULT_FILM_SD_NM)]
    pub film_sd_nm: f64,
    /// The wavelength that layer's thickness is compared with, nm, for rows without a
    /// `wavelength_nm` (rows with one use their own).
    #[arg(long, value_name = "NM", default_value_t = DEFAULT_WAVELENGTH_NM)]
    pub wavelength_nm: f64,
    /// `--reflectance auto`: do not decide from the brightness (s0 with exposures)
    /// whether a target reflects specularly at all (docs/MIXED.md); the same as
    /// `--reflectance specular`.
    #[arg(long)]
    pub no_brightness_check: bool,
    /// `--report DIR`: per-band figures (docs/BANDS.md).
    #[command(flatten)]
    pub plots: table_report::FitReportArgs,
}

/// Parse a number in (0, 1].
fn parse_unit(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number"))?;
    if v > 0.0 && v <= 1.0 {
        Ok(v)
    } else {
        Err(format!("need a value in (0, 1], got {v}"))
    }
}

/// Parse `MIN,MAX` (finite, MIN >= 0, MIN < MAX: [`range_problem`]).
fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("expected MIN,MAX, got {s:?}"))?;
    let parse = |t: &str| -> Result<f64, String> {
        let v: f64 = t
            .trim()
            .parse()
            .map_err(|_| format!("{t:?} is not a number"))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(format!("{t:?} is not finite"))
        }
    };
    let range = (parse(a)?, parse(b)?);
    match range_problem(range) {
        Some(why) => Err(why),
        None => Ok(range),
    }
}

impl Args {
    /// The pipeline's configuration.
    fn config(&self) -> FitConfig {
        FitConfig {
            reflectance: match self.reflectance {
                ReflectanceArg::Auto => Reflectance::Auto,
                ReflectanceArg::Specular => Reflectance::Specular,
                ReflectanceArg::Mixed => Reflectance::Mixed,
            },
            n_range: self.n_range,
            k_range: self.k_range,
            depolarized_dolp: self.depolarized_dolp,
            estimate_theta_r: self.estimate_theta_r,
            shadowing: match self.shadowing {
                ShadowingArg::None => Shadowing::None,
                ShadowingArg::Smith => Shadowing::SmithBeckmann,
            },
            s0_rel_sd: self.s0_rel_sd,
            sigma_range: self.sigma_range,
            angle_sd_deg: self.angle_sd_deg,
            dolp_floor: self.dolp_floor,
            extinction_ratio: self.extinction_ratio,
            retardance_deg: self.retardance_deg,
            mismatch_p: self.mismatch_p,
            strict: self.strict,
            film_sd_nm: self.film_sd_nm,
            wavelength_nm: self.wavelength_nm,
            brightness_check: !self.no_brightness_check,
        }
    }
}

/// Run `polarid fit`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    if args.reflectance != ReflectanceArg::Mixed
        && (args.estimate_theta_r || args.models.is_some() || args.shadowing != ShadowingArg::None)
    {
        return Err(BadInput(
            "--estimate-theta-r, --shadowing and --models need --reflectance mixed".into(),
        )
        .into());
    }
    let path = &args.measurements;
    args.plots.check(ctx)?;
    let meas = read_measurements(path).cli()?;
    let cfg = args.config();
    // Name the option as it was written: `--angle-sd-deg must be ..., got -1`.
    if let Err(polarid_pipeline::PipelineError::Config {
        option,
        value,
        reason,
    }) = cfg.validate()
    {
        let option = option.replace('_', "-");
        return Err(BadInput(format!("--{option} {reason}, got {value}")).into());
    }
    let out = {
        let bars = Bars::new(ctx);
        pipe::fit(path, &meas, &cfg, &|s, d, t| bars.report(s, d, t)).cli()?
    };
    if let Some(mp) = &args.models {
        if args.output.as_deref() == Some(mp.as_path()) {
            return Err(
                BadInput(format!("--models {} is the same file as -o", mp.display())).into(),
            );
        }
        polarid_io::atomic::check_output(mp, ctx.force, &[path.as_path()])?;
    }
    for t in &out.targets {
        if let Some(rep) = &t.report {
            ctx.info(format!(
                "{}: selected {} (BIC specular - mixed = {:.2}; rho_d = {:.4})",
                t.row.target,
                rep.selected.as_str(),
                rep.delta_bic,
                rep.mixed.rho_d
            ));
        }
    }
    for w in &out.warnings {
        ctx.info(w.to_string());
    }
    let rows = out.rows();
    ctx.write_output(args.output.as_deref(), &[path.as_path()], |w, p| {
        fits::write(w, p, &rows)
    })?;
    if let Some(mp) = &args.models {
        polarid_io::atomic::write_atomic(mp, ctx.force, |w| {
            write_rows(w, mp, &MODEL_COLUMNS, model_rows(&out.targets))
        })?;
    }
    table_report::write_fit_report(&args.plots, ctx, path, &meas, &rows)
}
