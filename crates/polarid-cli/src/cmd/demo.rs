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
use polarid_pipeline::demo::{self, PLATES, SIDE, bench};

use super::common::{Bars, PipeResult, output_dir, warn_all};
use crate::Ctx;
use crate::render::bench as bench_render;
use crate::render::colour_demo as colour_render;
use crate::render::demo::{figures, report};

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
    if !ctx.force && out.join("report.html").exists() {
        return Err(polarid_io::IoError::OutputExists {
            path: out.join("report.html"),
        }
        .into());
    }
    output_dir(out, ctx)
}

/// The staged directory `sub` (created), for writers that take a directory.
fn staged_dir(staged: &StagedDir, sub: &str) -> anyhow::Result<PathBuf> {
    let keep = staged.path(&format!("{sub}/.keep"))?;
    let dir = keep.parent().map(Path::to_path_buf).unwrap_or_default();
    let _ = std::fs::remove_file(&keep);
    Ok(dir)
}

/// Write `text` to the staged `tables.txt`.
fn write_tables(staged: &StagedDir, text: &str) -> anyhow::Result<()> {
    let path = staged.path("tables.txt")?;
    Ok(write_atomic(&path, false, |w| {
        w.write_all(text.as_bytes())
            .map_err(|e| polarid_io::IoError::io(&path, e))
    })?)
}

/// Write `text` to standard output (a closed pipe is not an error), then say how long
/// the demo `what` took since `start`.
fn done(ctx: &Ctx, what: &str, start: std::time::Instant, text: &str) -> anyhow::Result<()> {
    crate::ctx::print_stdout(text.as_bytes())?;
    let secs = start.elapsed().as_secs_f64();
    ctx.info(format!("polarid {what}: done in {secs:.1} s"));
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
    let start = std::time::Instant::now();
    let out = args.output.unwrap_or_else(|| PathBuf::from("polarid-demo"));
    let out = &out;
    let staged = staging(out, ctx)?;
    ctx.info(format!(
        "polarid demo: simulating {} capture sets ({SIDE}x{SIDE} pixels, 12-bit) into {}",
        PLATES.len(),
        out.display()
    ));
    let res = {
        let bars = Bars::new(ctx);
        demo::run(&staged, &|s, d, t| bars.report(s, d, t)).cli()?
    };
    warn_all(ctx, &res.warnings);

    // Plots and report.
    let figs = figures(&res)?;
    let plot_dir = staged_dir(&staged, "plots")?;
    for (fig, stem) in figs.iter().zip(["dolp_training", "dolp_test", "nk_plane"]) {
        fig.write(&plot_dir, stem)?;
    }
    report(&res, &figs).write(&staged.path("")?, "report")?;
    let tables = format!("{}\n{}\n{}\n", res.table1, res.table2, res.notes.join("\n"));
    write_tables(&staged, &tables)?;
    staged.commit()?;

    // stdout: the tables and the decisions.
    let mut so = String::new();
    let _ = writeln!(so, "{}", res.table1);
    let _ = writeln!(so, "{}", res.table2);
    for n in &res.notes {
        let _ = writeln!(so, "{n}");
    }
    let _ = writeln!(
        so,
        "\nReport: {}  (also report.md; CSVs, model.json and the captures in {})",
        out.join("report.html").display(),
        out.display()
    );
    done(ctx, "demo", start, &so)
}

/// Run `polarid demo --bench`.
fn run_bench(output: Option<&Path>, ctx: &Ctx) -> anyhow::Result<()> {
    let start = std::time::Instant::now();
    let out = output.map_or_else(|| PathBuf::from("polarid-bench"), Path::to_path_buf);
    let staged = staging(&out, ctx)?;
    ctx.info(format!(
        "polarid demo --bench: a lamp-and-lens bench (2 renders of 9 captures, calibrated \
         geometry) into {}",
        out.display()
    ));
    let res = {
        let bars = Bars::new(ctx);
        bench::run_bench(&staged, &|s, d, t| bars.report(s, d, t)).cli()?
    };
    warn_all(ctx, &res.warnings);
    let figs = bench_render::figures(&res)?;
    let plot_dir = staged_dir(&staged, "plots")?;
    for f in &figs {
        f.plot.write(&plot_dir, &f.stem)?;
    }
    let map_dir = staged_dir(&staged, "map")?;
    bench_render::write_map(&map_dir, &res.map)?;
    if let Some(f) = figs.iter().find(|f| f.stem == "class_map") {
        f.plot.write(&map_dir, "class")?;
    }
    bench_render::report(&res, &figs).write(&staged.path("")?, "report")?;
    let text = format!(
        "{}
{}
",
        res.tables,
        res.notes.join("\n")
    );
    write_tables(&staged, &text)?;
    staged.commit()?;
    let report = format!(
        "{text}\nReport: {}  (also report.md; CSVs, model.json, map/ and the captures in {})\n",
        out.join("report.html").display(),
        out.display()
    );
    done(ctx, "demo --bench", start, &report)
}

/// Run `polarid demo --color`.
fn run_colour(output: Option<&Path>, seeds: u64, ctx: &Ctx) -> anyhow::Result<()> {
    let start = std::time::Instant::now();
    let out = output.map_or_else(|| PathBuf::from("polarid-colour"), Path::to_path_buf);
    let staged = staging(&out, ctx)?;
    ctx.info(format!(
        "polarid demo --color: six materials, colour polarization mosaics, {seeds} seeds \
         into {}",
        out.display()
    ));
    let res = {
        let bars = Bars::new(ctx);
        demo::colour::run_colour(&staged, seeds, &|s, d, t| bars.report(s, d, t)).cli()?
    };
    warn_all(ctx, &res.warnings);
    let figs = colour_render::figures(&res)?;
    let plot_dir = staged_dir(&staged, "plots")?;
    for f in &figs {
        f.plot.write(&plot_dir, &f.stem)?;
    }
    colour_render::report(&res, &figs).write(&staged.path("")?, "report")?;
    staged.commit()?;
    let report = format!(
        "{}\nReport: {}  (also report.md; CSVs, model.json, accuracy.md and seed 0's \
         captures in {})\n",
        res.table,
        out.join("report.html").display(),
        out.display()
    );
    done(ctx, "demo --color", start, &report)
}
