//! `polarid plan SCENE.toml`: which materials the bench's source positions can tell apart,
//! and where to put the lamp (docs/PLAN.md).
//!
//! The workflow is [`polarid_pipeline::plan`]. Standard output: the current plan (the
//! scene's own sources) and the recommended one, per plate its hardest alternatives with
//! `λ`, degrees of freedom and rejection power, and the verdict. `-o DIR` also writes
//! `pairs.csv` (every pair of both plans), `positions.csv` (each position's β, DoLP
//! standard error and electrons per plate), `plan.png`/`plan.svg` (DoLP against β: each
//! plate's material and its hardest alternative, the recommended and current rows) and
//! `scene.toml` (the scene with the recommended sources, ready for `polarid simulate`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use polarid_io::atomic::write_atomic;
use polarid_io::manifest::SourceSpec;
use polarid_io::table::{fmt_f64, write_rows};
use polarid_pipeline::fit::FitConfig;
use polarid_pipeline::plan::{
    Evaluation, PlanConfig, PlanOutput, Position, Region, dolp_curve, plan_file,
};

use super::common::{PipeResult, output_dir, warn_all};
use crate::Ctx;
use crate::render::join;
use crate::render::plots::{DolpPoint, PlanAxes, PlanPlate, PlotSize, plan_dolp};

/// Arguments of `polarid plan`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The bench: a scene (TOML, docs/SCENE.md) with the camera, plane, plates (their
    /// `class` is their material) and the current `[[source]]` positions.
    pub scene: PathBuf,
    /// Number of source positions to recommend.
    #[arg(short = 'n', long, default_value_t = 6)]
    pub positions: usize,
    /// Candidate materials: `builtin`, `builtin-rgb` or a library CSV.
    #[arg(long, default_value = "builtin")]
    pub library: String,
    /// Only these materials of the library (comma-separated; default: all).
    #[arg(long, value_delimiter = ',')]
    pub materials: Vec<String>,
    /// Confidence of `classify`'s test.
    #[arg(long, default_value_t = 0.95)]
    pub confidence: f64,
    /// Rejection power that makes two materials separable.
    #[arg(long, default_value_t = 0.95)]
    pub power: f64,
    /// Lamp distance from the plates' centre (default: the median of the scene's lamps).
    #[arg(long, value_name = "D")]
    pub distance: Option<f64>,
    /// Lamp zeniths to consider, degrees.
    #[arg(long, value_name = "LO:HI", default_value = "10:85", value_parser = parse_range)]
    pub zenith_deg: (f64, f64),
    /// Lamp azimuths to consider, degrees from the direction opposite the camera.
    #[arg(long, value_name = "LO:HI", default_value = "-40:40", value_parser = parse_range)]
    pub azimuth_deg: (f64, f64),
    /// Grid step of the region, degrees.
    #[arg(long, default_value_t = 5.0)]
    pub step_deg: f64,
    /// A row's DoLP standard error (default: from the scene's sensor, exposure and regions).
    #[arg(long)]
    pub dolp_se: Option<f64>,
    /// Standard uncertainty of the source and camera directions, degrees (as `fit`).
    #[arg(long, default_value_t = polarid_pipeline::fit::DEFAULT_ANGLE_SD_DEG)]
    pub angle_sd_deg: f64,
    /// DoLP floor (as `fit`).
    #[arg(long, default_value_t = polarid_pipeline::fit::DEFAULT_DOLP_FLOOR)]
    pub dolp_floor: f64,
    /// Lowest extinction ratio of the polarimeter (as `fit`).
    #[arg(long, default_value_t = polarid_pipeline::fit::DEFAULT_EXTINCTION_RATIO)]
    pub extinction_ratio: f64,
    /// Output directory (pairs.csv, positions.csv, plan.png/svg, scene.toml).
    #[arg(short, long, value_name = "DIR")]
    pub output: Option<PathBuf>,
}

fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s
        .split_once(':')
        .ok_or_else(|| format!("{s:?}: expected LO:HI, e.g. 10:85"))?;
    let p = |x: &str| {
        x.trim()
            .parse::<f64>()
            .map_err(|_| format!("{s:?}: {x:?} is not a number"))
    };
    Ok((p(a)?, p(b)?))
}

/// The verdict lines and pair tables of one design.
fn design_text(out: &PlanOutput, ev: &Evaluation, title: &str) -> String {
    let p = out.config.power;
    let mut s = String::new();
    let _ = writeln!(s, "{title}: {} positions", ev.positions.len());
    let betas: Vec<String> = (0..out.targets.len())
        .map(|t| {
            let b: Vec<f64> = ev.positions.iter().map(|q| q.rows[t].beta_deg).collect();
            let lo = b.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = b.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            format!("{} {lo:.1}-{hi:.1}", out.targets[t].name)
        })
        .collect();
    let _ = writeln!(s, "  beta span (deg): {}", betas.join(", "));
    for q in &ev.positions {
        let b = join(q.rows.iter().map(|r| format!("{:.1}", r.beta_deg)), " / ");
        let _ = writeln!(s, "  {:<24} beta {b}", q.label);
    }
    // A colour scene: the power of each band's rows alone after the overall one.
    let band_heads: String = band_names(out)
        .iter()
        .map(|b| format!(" {:>7}", format!("p_{b}")))
        .collect();
    let _ = writeln!(
        s,
        "  {:<14} {:<14} {:<20} {:>9} {:>6} {:>7} {:>7}{band_heads}",
        "plate", "material", "hardest alternative", "lambda", "dof", "power", "margin"
    );
    for (t, tg) in out.targets.iter().enumerate() {
        for (shown, pr) in ev.pairs.iter().filter(|x| x.target == t).enumerate() {
            if shown >= 3 && pr.sep.power >= p {
                break;
            }
            let bands: String = pr
                .by_band
                .iter()
                .map(|b| format!(" {:>7.3}", b.power))
                .collect();
            let _ = writeln!(
                s,
                "  {:<14} {:<14} {:<20} {:>9.2} {:>6.2} {:>7.3} {:>7.2}{bands}",
                tg.name,
                tg.material,
                pr.alternative,
                pr.sep.lambda,
                pr.sep.dof,
                pr.sep.power,
                pr.sep.margin
            );
        }
    }
    for (t, tg) in out.targets.iter().enumerate() {
        if let Some(f) = ev.fits.get(t) {
            let band = if out.wavelengths_nm.len() > 1 {
                format!(" at {} nm", f.wavelength_nm)
            } else {
                String::new()
            };
            let _ = writeln!(
                s,
                "  {}: fit of the noise-free rows{band} {}, n_se {:.3}, k_se {:.3} (total)",
                tg.name, f.status, f.n_se, f.k_se
            );
        }
    }
    for (t, tg) in out.targets.iter().enumerate() {
        let confused = ev.confused(t, p);
        if let Some(f) = ev.fits.get(t)
            && f.status != polarid_core::FitStatus::Ok
        {
            let _ = writeln!(
                s,
                "  {}: {} NOT identifiable: its fit would be {} ({}), and classify tests only fits that are ok",
                tg.name, tg.material, f.status, f.reason
            );
        } else if let Some(f) = ev.fits.get(t)
            && !f.locates()
        {
            let _ = writeln!(
                s,
                "  {}: {} NOT identifiable: the fit cannot locate it (n {:.3} +- 2 x {:.2}, k {:.3} +- 2 x {:.2} \
                 reaches the search box's edge n {} / k {}): a noisy fit strays along the (n, k) valley \
                 to ill_conditioned, and classify then tests nothing",
                tg.name, tg.material, f.n, f.n_se, f.k, f.k_se, f.box_max.0, f.box_max.1
            );
        } else if confused.is_empty() {
            let w = ev.worst(t).map_or(f64::NAN, |w| w.sep.power);
            let _ = writeln!(
                s,
                "  {}: {} identifiable (every other material rejected with power >= {:.3})",
                tg.name, tg.material, w
            );
        } else {
            let names = join(
                confused
                    .iter()
                    .map(|c| format!("{} ({:.2})", c.alternative, c.sep.power)),
                ", ",
            );
            let _ = writeln!(
                s,
                "  {}: {} NOT identifiable: not rejected with power {p}: {}",
                tg.name, tg.material, names
            );
        }
    }
    s
}

/// The bands' names: a colour scene's letters (`R`, `G`, `B`), nothing for one band.
fn band_names(out: &PlanOutput) -> Vec<String> {
    if out.wavelengths_nm.len() < 2 {
        return Vec::new();
    }
    out.wavelengths_nm
        .iter()
        .enumerate()
        .map(|(b, w)| {
            out.band_letters
                .get(b)
                .map_or_else(|| format!("{w}"), |c| c.to_string())
        })
        .collect()
}

/// The evaluated designs, named as in the CSV files: the scene's own positions, then the
/// recommended ones.
fn designs(out: &PlanOutput) -> impl Iterator<Item = (&'static str, &Evaluation)> {
    out.current
        .iter()
        .map(|e| ("current", e))
        .chain(std::iter::once(("recommended", &out.recommended)))
}

/// `pairs.csv`: one row per design, plate and alternative (the project's CSV writer:
/// quoted names, formula-like names neutralised).
fn write_pairs_csv(path: &Path, out: &PlanOutput) -> anyhow::Result<()> {
    const HEADERS: [&str; 13] = [
        "design",
        "plate",
        "material",
        "alternative",
        "band",
        "lambda",
        "dof",
        "critical",
        "power",
        "margin",
        "worst_thickness_nm",
        "worst_scale",
        "worst_offset_deg",
    ];
    let bands = band_names(out);
    let rows = designs(out).flat_map(|(name, ev)| {
        let bands = &bands;
        ev.pairs.iter().flat_map(move |pr| {
            let t = &out.targets[pr.target];
            std::iter::once(("all".to_string(), &pr.sep))
                .chain(bands.iter().cloned().zip(&pr.by_band))
                .map(move |(band, sep)| {
                    vec![
                        name.to_string(),
                        t.name.clone(),
                        t.material.clone(),
                        pr.alternative.clone(),
                        band,
                        fmt_f64(sep.lambda),
                        fmt_f64(sep.dof),
                        fmt_f64(sep.critical),
                        fmt_f64(sep.power),
                        fmt_f64(sep.margin),
                        fmt_f64(sep.worst.thickness_nm),
                        fmt_f64(sep.worst.scale),
                        fmt_f64(sep.worst.offset.to_degrees()),
                    ]
                })
        })
    });
    Ok(write_atomic(path, true, |w| {
        write_rows(w, path, &HEADERS, rows)
    })?)
}

/// `positions.csv`: one row per design, position and plate.
fn write_positions_csv(path: &Path, out: &PlanOutput) -> anyhow::Result<()> {
    const HEADERS: [&str; 11] = [
        "design",
        "position",
        "x",
        "y",
        "z",
        "plate",
        "band",
        "beta_deg",
        "theta_i_deg",
        "dolp_se",
        "electrons",
    ];
    let bands: Vec<String> = out.wavelengths_nm.iter().map(|w| fmt_f64(*w)).collect();
    let rows = designs(out).flat_map(|(name, ev)| {
        let bands = &bands;
        ev.positions.iter().flat_map(move |q| {
            let v = match &q.spec {
                SourceSpec::Position(v) | SourceSpec::Direction(v) => *v,
                SourceSpec::Sun { direction, .. } => *direction,
            };
            q.rows.iter().enumerate().flat_map(move |(t, r)| {
                r.bands.iter().zip(bands).map(move |(n, band)| {
                    vec![
                        name.to_string(),
                        q.label.replace(',', ""),
                        fmt_f64(v[0]),
                        fmt_f64(v[1]),
                        fmt_f64(v[2]),
                        out.targets[t].name.clone(),
                        band.clone(),
                        fmt_f64(r.beta_deg),
                        fmt_f64(r.theta_i_deg),
                        fmt_f64(n.dolp_se),
                        fmt_f64(n.electrons),
                    ]
                })
            })
        })
    });
    Ok(write_atomic(path, true, |w| {
        write_rows(w, path, &HEADERS, rows)
    })?)
}

/// Plate `t`'s heading: its name and the recommended design's verdict.
fn heading(out: &PlanOutput, t: usize) -> String {
    let verdict = if out.recommended.identifiable(t, out.config.power) {
        "identifiable"
    } else {
        "NOT identifiable"
    };
    format!("{}: {verdict}", out.targets[t].name)
}

/// A plate's points of the recommended and the current designs: `point` of each position.
fn design_points(
    out: &PlanOutput,
    point: impl Fn(&Position) -> Option<DolpPoint>,
) -> (Vec<DolpPoint>, Vec<DolpPoint>) {
    let points = |ev: &Evaluation| ev.positions.iter().filter_map(&point).collect();
    let current = out.current.as_ref().map(points).unwrap_or_default();
    (points(&out.recommended), current)
}

/// DoLP against β, one colour per plate: its material's curve with the recommended rows
/// (±1 σ of the row) and the current ones, its hardest alternative's curve dashed; the
/// legend gives each plate's verdict and the hardest alternative's power.
fn plot(out: &PlanOutput) -> anyhow::Result<crate::render::Rendered> {
    let floor = out.config.fit.dolp_floor;
    let ev = &out.recommended;
    let mut plates = Vec::new();
    for (t, tg) in out.targets.iter().enumerate() {
        let curve = dolp_curve(out, &tg.material).cli()?;
        let at = |b: f64| {
            curve
                .iter()
                .min_by(|x, y| (x.0 - b).abs().total_cmp(&(y.0 - b).abs()))
                .map_or(0.0, |c| c.1)
        };
        let (recommended, current) = design_points(out, |q| {
            let r = &q.rows[t];
            let se = r.bands[0].dolp_se;
            Some(DolpPoint {
                beta_deg: r.beta_deg,
                dolp: at(r.beta_deg),
                dolp_se: Some((se * se + floor * floor).sqrt()),
            })
        });
        let (alt_curve, alt_label) = match ev.worst(t) {
            Some(w) => (
                dolp_curve(out, &w.alternative).cli()?,
                format!("{}: power {:.2}", w.alternative, w.sep.power),
            ),
            None => (Vec::new(), String::new()),
        };
        plates.push(PlanPlate {
            heading: heading(out, t),
            curve: curve.clone(),
            curve_label: tg.material.clone(),
            alt_curve,
            alt_label,
            recommended,
            current,
        });
    }
    let mut notes = vec![format!(
        "dashed: the hardest alternative; worst margin {:.2}{}",
        ev.worst_margin(),
        out.current
            .as_ref()
            .map(|c| format!(" (current {:.2})", c.worst_margin()))
            .unwrap_or_default()
    )];
    if out.wavelengths_nm.len() > 1 {
        notes.push(format!(
            "curves and bars at {} nm; the powers use every band",
            out.wavelengths_nm[0]
        ));
    }
    plan_dolp(
        &format!(
            "Planned captures: DoLP against β ({} positions)",
            ev.positions.len()
        ),
        &plates,
        &notes,
        PlanAxes::DOLP,
        PlotSize::REPORT,
    )
}

/// The sun window's figure: each plate's β over the window's times (hours of the day at
/// the window's offset), the recommended times (filled) and the current ones.
fn times_plot(out: &PlanOutput, all: &[Position]) -> anyhow::Result<crate::render::Rendered> {
    let Some(w) = &out.sun else {
        anyhow::bail!("no sun window");
    };
    let day0 = ((w.start_unix_s + 60.0 * f64::from(w.offset_minutes)) / 86400.0).floor() * 86400.0
        - 60.0 * f64::from(w.offset_minutes);
    let hour = |q: &Position| match &q.spec {
        SourceSpec::Sun { unix_seconds, .. } => Some((unix_seconds - day0) / 3600.0),
        _ => None,
    };
    let mut plates = Vec::new();
    for (t, tg) in out.targets.iter().enumerate() {
        let curve: Vec<(f64, f64)> = all
            .iter()
            .filter_map(|q| hour(q).map(|h| (h, q.rows[t].beta_deg)))
            .collect();
        let (recommended, current) = design_points(out, |q| {
            hour(q).map(|h| DolpPoint {
                beta_deg: h,
                dolp: q.rows[t].beta_deg,
                dolp_se: None,
            })
        });
        plates.push(PlanPlate {
            heading: heading(out, t),
            curve,
            curve_label: format!("β of {}", tg.name),
            alt_curve: Vec::new(),
            alt_label: String::new(),
            recommended,
            current,
        });
    }
    let mut chosen: Vec<&Position> = out.recommended.positions.iter().collect();
    chosen.sort_by(|a, b| hour(a).unwrap_or(0.0).total_cmp(&hour(b).unwrap_or(0.0)));
    let times: Vec<String> = chosen
        .into_iter()
        .filter_map(|q| {
            hour(q).map(|h| {
                let m = (h * 60.0).round() as i64;
                format!("{:02}:{:02}", m.div_euclid(60), m.rem_euclid(60))
            })
        })
        .collect();
    plan_dolp(
        &format!(
            "The sun's times: β over {}",
            &w.start[..w.start.len().min(10)]
        ),
        &plates,
        &[format!("capture at {}", times.join(", "))],
        PlanAxes {
            x_label: "time of day (hours)",
            y_label: "β (degrees)",
            x_limits: (-48.0, 24.0 * 400.0),
            y_cap: 90.0,
        },
        PlotSize::REPORT,
    )
}

/// Run `polarid plan`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let fit = FitConfig {
        angle_sd_deg: args.angle_sd_deg,
        dolp_floor: args.dolp_floor,
        extinction_ratio: args.extinction_ratio,
        ..FitConfig::default()
    };
    let cfg = PlanConfig {
        positions: args.positions,
        library: args.library.clone(),
        materials: args.materials.clone(),
        confidence: args.confidence,
        power: args.power,
        region: Region {
            distance: args.distance,
            zenith_deg: args.zenith_deg,
            azimuth_deg: args.azimuth_deg,
            step_deg: args.step_deg,
        },
        dolp_se: args.dolp_se,
        fit,
    };
    let staged = args
        .output
        .as_deref()
        .map(|d| output_dir(d, ctx))
        .transpose()?;
    let out = plan_file(&args.scene, &cfg).cli()?;
    warn_all(ctx, &out.warnings);
    let mut text = format!(
        "polarid plan: {} plate(s) of {} against {} material(s) of {} at {} nm; \
         classify's test at {}%, separable when rejected with power >= {}; {} candidate \
         positions\n",
        out.targets.len(),
        args.scene.display(),
        out.materials.len(),
        out.library,
        join(&out.wavelengths_nm, ", "),
        out.config.confidence * 100.0,
        out.config.power,
        out.candidates
    );
    if let Some(cur) = &out.current {
        text.push('\n');
        text.push_str(&design_text(
            &out,
            cur,
            "Current plan (the scene's sources)",
        ));
    }
    text.push('\n');
    text.push_str(&design_text(
        &out,
        &out.recommended,
        &format!(
            "Recommended (worst pair's margin {:.2}; search {:?})",
            out.recommended.worst_margin(),
            out.progress
                .iter()
                .map(|p| (p * 100.0).round() / 100.0)
                .collect::<Vec<_>>()
        ),
    ));
    let m = out.recommended.worst_margin();
    if m < 1.0 && m > 0.0 {
        let _ = writeln!(
            text,
            "\nThe worst pair's margin is {m:.2} < 1: lambda grows in proportion to the rows, so \
             about {} positions (or each position captured {} times) would reach power {}: \
             polarid plan {} --positions {}",
            (args.positions as f64 / m).ceil(),
            (1.0 / m).ceil(),
            out.config.power,
            args.scene.display(),
            (args.positions as f64 / m).ceil()
        );
    }
    print!("{text}");
    if let (Some(staged), Some(dir)) = (staged, &args.output) {
        write_pairs_csv(&staged.path("pairs.csv")?, &out)?;
        write_positions_csv(&staged.path("positions.csv")?, &out)?;
        let scene_text = std::fs::read_to_string(&args.scene)?;
        std::fs::write(
            staged.path("scene.toml")?,
            out.recommended_scene(&scene_text),
        )?;
        plot(&out)?.write(&staged.path("")?, "plan")?;
        if out.sun.is_some() {
            times_plot(&out, &out.sun_positions)?.write(&staged.path("")?, "times")?;
        }
        staged.commit()?;
        ctx.info(format!(
            "polarid plan: pairs.csv, positions.csv, plan.png, plan.svg, {}scene.toml -> {}",
            if out.sun.is_some() {
                "times.png, times.svg, "
            } else {
                ""
            },
            dir.display()
        ));
    }
    Ok(())
}
