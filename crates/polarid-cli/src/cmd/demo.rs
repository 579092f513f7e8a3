//! `polarid demo [-o DIR]`: the paper's experiment (section 7) in simulation, end to end
//! (the workflow is [`polarid_pipeline::demo`]); `polarid demo --bench [-o DIR]`: a
//! lamp-and-lens bench with calibrated geometry, from renders to a material map
//! ([`polarid_pipeline::demo::bench`]); `polarid demo --color [--seeds N]`: a colour
//! polarization camera telling copper from gold ([`polarid_pipeline::demo::colour`]).
//!
//! The tables go to standard output; `DIR` receives the captures, the CSVs,
//! `model.json`, the plots and `report.html` / `report.md` (and `map/` for the bench).
//! Deterministic (fixed seeds); a failure leaves nothing.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use polarid_io::atomic::{StagedDir, write_atomic};
use polarid_pipeline::Progress;
use polarid_pipeline::demo::{self, PLATES, SIDE, bench};

use super::common::{Bars, PipeResult, warn_all};
use crate::render::Rendered;
use crate::render::bench as bench_render;
use crate::render::colour_demo as colour_render;
use crate::render::demo::{figures, report};
use crate::render::report::Report;
use crate::{BadInput, Ctx};

/// Arguments of `polarid demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory (captures, CSVs, model, plots, report) [default: polarid-demo,
    /// or polarid-bench with --bench].
    #[arg(short, long, value_name = "DIR")]
    pub output: Option<PathBuf>,
    /// The lamp-and-lens bench (calibrated geometry: a 40° lens, a lamp at 0.55-0.9 m,
    /// five plates) instead of the paper's experiment; ends with a material map.
    #[arg(long)]
    pub bench: bool,
    /// A colour polarization camera (450, 550, 650 nm) telling aluminum, copper, gold,
    /// brass, a paint and a clear plastic apart, against the 650 nm band alone.
    #[arg(long, visible_alias = "colour", conflicts_with = "bench")]
    pub color: bool,
    /// Seeds of the --color accuracy table (each: 18 plates, 8 captures).
    #[arg(long, value_name = "N", default_value_t = demo::colour::COLOUR_SEEDS)]
    pub seeds: u64,
}

/// The staging directory of a demo writing `DIR/report.html`.
fn staging(out: &Path, ctx: &Ctx) -> anyhow::Result<StagedDir> {
    if out.is_file() {
        return Err(BadInput(format!(
            "{}: the output must be a directory, and this is a file",
            out.display()
        ))
        .into());
    }
    if !ctx.force && out.join("report.html").exists() {
        return Err(polarid_io::IoError::OutputExists {
            path: out.join("report.html"),
        }
        .into());
    }
    Ok(StagedDir::new(out, ctx.force)?)
}

/// The staged directory `sub` (created), for writers that take a directory.
fn staged_dir(staged: &StagedDir, sub: &str) -> anyhow::Result<PathBuf> {
    let keep = staged.path(&format!("{sub}/.keep"))?;
    let dir = keep.parent().map(Path::to_path_buf).unwrap_or_default();
    let _ = std::fs::remove_file(&keep);
    Ok(dir)
}

/// A demo as [`run_demo`] reports it: its command, output directory, what it runs and
/// what else the directory holds besides the report.
type Demo<'a> = (&'a str, &'a Path, String, &'a str);

/// The steps every demo shares: stage `out`, say what runs (`intro`), `run` it with
/// progress bars, `write` its files into the staging directory (it prints the run's
/// warnings and returns the text for standard output), commit, then print that text, where
/// the report is (`contents`: what else `out` holds) and the time taken.
fn run_demo<R>(
    ctx: &Ctx,
    (command, out, intro, contents): Demo<'_>,
    run: impl FnOnce(&StagedDir, Progress) -> polarid_pipeline::Result<R>,
    write: impl FnOnce(&StagedDir, R) -> anyhow::Result<String>,
) -> anyhow::Result<()> {
    let start = std::time::Instant::now();
    let staged = staging(out, ctx)?;
    ctx.info(format!("{command}: {intro} into {}", out.display()));
    let res = {
        let bars = Bars::new(ctx);
        run(&staged, &|s, d, t| bars.report(s, d, t)).cli()?
    };
    let text = write(&staged, res)?;
    staged.commit()?;
    // A closed pipe is not an error.
    crate::ctx::print_stdout(
        format!(
            "{text}\nReport: {}  (also report.md; {contents} in {})\n",
            out.join("report.html").display(),
            out.display()
        )
        .as_bytes(),
    )?;
    let seconds = start.elapsed().as_secs_f64();
    ctx.info(format!("{command}: done in {seconds:.1} s"));
    Ok(())
}

/// Write `figs` (drawing, stem) under `plots/` and `report` (`report.html`, `report.md`)
/// into the staging directory.
fn write_report<'a>(
    staged: &StagedDir,
    figs: impl IntoIterator<Item = (&'a Rendered, &'a str)>,
    report: &Report,
) -> anyhow::Result<()> {
    let plot_dir = staged_dir(staged, "plots")?;
    for (fig, stem) in figs {
        fig.write(&plot_dir, stem)?;
    }
    let stage_dir = plot_dir.parent().map(Path::to_path_buf).unwrap_or_default();
    report.write(&stage_dir, "report")?;
    Ok(())
}

/// Write `text` as `tables.txt` into the staging directory.
fn write_tables(staged: &StagedDir, text: &str) -> anyhow::Result<()> {
    let path = staged.path("tables.txt")?;
    write_atomic(&path, false, |w| {
        w.write_all(text.as_bytes())
            .map_err(|e| polarid_io::IoError::io(&path, e))
    })?;
    Ok(())
}

/// Run `polarid demo`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    if args.bench {
        return run_bench(args.output.as_deref(), ctx);
    }
    if args.color {
        return run_colour(args.output.as_deref(), args.seeds, ctx);
    }
    let out = args.output.unwrap_or_else(|| PathBuf::from("polarid-demo"));
    let intro = format!(
        "simulating {} capture sets ({SIDE}x{SIDE} pixels, 12-bit)",
        PLATES.len()
    );
    let contents = "CSVs, model.json and the captures";
    let what = ("polarid demo", out.as_path(), intro, contents);
    run_demo(ctx, what, demo::run, |staged, res| {
        warn_all(ctx, &res.warnings);
        let figs = figures(&res)?;
        let stems = ["dolp_training", "dolp_test", "nk_plane"];
        write_report(staged, figs.iter().zip(stems), &report(&res, &figs))?;
        let tables = format!("{}\n{}\n{}\n", res.table1, res.table2, res.notes.join("\n"));
        write_tables(staged, &tables)?;
        // stdout: the tables and the decisions.
        let mut so = String::new();
        let _ = writeln!(so, "{}", res.table1);
        let _ = writeln!(so, "{}", res.table2);
        for n in &res.notes {
            let _ = writeln!(so, "{n}");
        }
        Ok(so)
    })
}

/// Run `polarid demo --bench`.
fn run_bench(output: Option<&Path>, ctx: &Ctx) -> anyhow::Result<()> {
    let out = output.map_or_else(|| PathBuf::from("polarid-bench"), Path::to_path_buf);
    let intro = "a lamp-and-lens bench (2 renders of 9 captures, calibrated geometry)".into();
    let contents = "CSVs, model.json, map/ and the captures";
    let what = ("polarid demo --bench", out.as_path(), intro, contents);
    run_demo(ctx, what, bench::run_bench, |staged, res| {
        warn_all(ctx, &res.warnings);
        let figs = bench_render::figures(&res)?;
        let stems = figs.iter().map(|f| (&f.plot, f.stem.as_str()));
        write_report(staged, stems, &bench_render::report(&res, &figs))?;
        let map_dir = staged_dir(staged, "map")?;
        bench_render::write_map(&map_dir, &res.map)?;
        if let Some(f) = figs.iter().find(|f| f.stem == "class_map") {
            f.plot.write(&map_dir, "class")?;
        }
        let text = format!("{}\n{}\n", res.tables, res.notes.join("\n"));
        write_tables(staged, &text)?;
        Ok(text)
    })
}

/// Run `polarid demo --color`.
fn run_colour(output: Option<&Path>, seeds: u64, ctx: &Ctx) -> anyhow::Result<()> {
    let out = output.map_or_else(|| PathBuf::from("polarid-colour"), Path::to_path_buf);
    let intro = format!("six materials, colour polarization mosaics, {seeds} seeds");
    let contents = "CSVs, model.json, accuracy.md and seed 0's captures";
    let what = ("polarid demo --color", out.as_path(), intro, contents);
    let run = |staged: &StagedDir, p: Progress| demo::colour::run_colour(staged, seeds, p);
    run_demo(ctx, what, run, |staged, res| {
        warn_all(ctx, &res.warnings);
        let figs = colour_render::figures(&res)?;
        let stems = figs.iter().map(|f| (&f.plot, f.stem.as_str()));
        write_report(staged, stems, &colour_render::report(&res, &figs))?;
        Ok(res.table)
    })
}
