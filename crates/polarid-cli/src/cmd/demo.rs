//! `polarid demo [-o DIR]`: the paper's experiment (section 7) in simulation, end to end
//! (the workflow is [`polarid_pipeline::demo`]).
//!
//! The analogues of Tables 1 and 2 go to standard output; `DIR` receives the captures,
//! the CSVs, `model.json`, the plots and `report.html` / `report.md`. Deterministic
//! (fixed seeds); a failure leaves nothing.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use polarid_io::atomic::{StagedDir, write_atomic};
use polarid_pipeline::demo::{self, PLATES, SIDE};

use super::common::{Bars, PipeResult, warn_all};
use crate::render::demo::{figures, report};
use crate::{BadInput, Ctx};

/// Arguments of `polarid demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory (captures, CSVs, model, plots, report).
    #[arg(short, long, value_name = "DIR", default_value = "polarid-demo")]
    pub output: PathBuf,
}

/// Run `polarid demo`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let start = std::time::Instant::now();
    let out = &args.output;
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
    let staged = StagedDir::new(out, ctx.force)?;
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
    let plot_dir = staged.path("plots/.keep")?;
    let plot_dir = plot_dir.parent().map(Path::to_path_buf).unwrap_or_default();
    let _ = std::fs::remove_file(plot_dir.join(".keep"));
    for (fig, stem) in figs.iter().zip(["dolp_training", "dolp_test", "nk_plane"]) {
        fig.write(&plot_dir, stem)?;
    }
    let stage_dir = plot_dir.parent().map(Path::to_path_buf).unwrap_or_default();
    report(&res, &figs).write(&stage_dir, "report")?;
    let tables = format!("{}\n{}\n{}\n", res.table1, res.table2, res.notes.join("\n"));
    let tables_path = staged.path("tables.txt")?;
    write_atomic(&tables_path, false, |w| {
        w.write_all(tables.as_bytes())
            .map_err(|e| polarid_io::IoError::io(&tables_path, e))
    })?;
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
    let mut stdout = std::io::stdout().lock();
    match stdout
        .write_all(so.as_bytes())
        .and_then(|()| stdout.flush())
    {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {}
        r => r?,
    }
    ctx.info(format!(
        "polarid demo: done in {:.1} s",
        start.elapsed().as_secs_f64()
    ));
    Ok(())
}
