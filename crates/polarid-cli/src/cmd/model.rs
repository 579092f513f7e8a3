//! `polarid model --input ROWS.csv [-o OUT.csv]`: evaluate the forward model for rows
//! of a CSV file.
//!
//! Rows `n,k,beta_deg` give `dop`, the degree of linear polarization of eq. (9).
//! Rows `n,k,sigma,theta_i_deg,theta_r_deg,phi_deg` give `beta_deg`, `facet_tilt_deg`,
//! the pBRDF of eq. (3) in the local facet frame (`m00 … m22`) and in the global s/p
//! frame (`m01_psps … m22_psps`; `m00` is the same in both), in sr⁻¹, and `dolp`.
//! Conventions and validation: `polarid_io::table::model_rows`.

use std::path::PathBuf;

use anyhow::Context;
use polarid_core::{dop, pbrdf};
use polarid_io::IoError;
use polarid_io::table::model_rows::{self, ModelRows, PbrdfOut};
use rayon::prelude::*;

use crate::Ctx;

/// Arguments of `polarid model`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// CSV with columns `n,k,beta_deg` (DoLP of eq. 9) or
    /// `n,k,sigma,theta_i_deg,theta_r_deg,phi_deg` (pBRDF of eq. 3); angles in degrees.
    #[arg(long, short = 'i', value_name = "ROWS.csv")]
    pub input: PathBuf,
    /// Output CSV (default: standard output).
    #[arg(long, short = 'o', value_name = "OUT.csv")]
    pub output: Option<PathBuf>,
}

/// Run `polarid model`.
pub fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()> {
    let input = model_rows::read(&args.input)?;
    let out_path = args.output.as_deref();
    match &input.rows {
        ModelRows::Dop(rows) => {
            let p: Vec<f64> = rows
                .par_iter()
                .map(|r| dop::dop(r.n, r.k, r.beta_deg.to_radians()))
                .collect();
            ctx.write_output(out_path, &[&args.input], |w, path| {
                model_rows::write_dop(w, path, &input, rows, &p)
            })?;
            info(ctx, out_path, rows.len(), "DoP");
        }
        ModelRows::Pbrdf(rows) => {
            let results: Vec<PbrdfOut> = rows
                .par_iter()
                .map(|r| {
                    let p = pbrdf::pbrdf(
                        r.n,
                        r.k,
                        r.sigma,
                        r.theta_i_deg.to_radians(),
                        r.theta_r_deg.to_radians(),
                        r.phi_deg.to_radians(),
                    )
                    .map_err(|source| IoError::core(&args.input, source))
                    .with_context(|| format!("line {}", r.line))?;
                    Ok(PbrdfOut {
                        beta_deg: p.beta.to_degrees(),
                        facet_tilt_deg: p.facet_tilt.to_degrees(),
                        local: p.local,
                        global: p.global,
                        dolp: p.dolp,
                    })
                })
                .collect::<anyhow::Result<_>>()?;
            ctx.write_output(out_path, &[&args.input], |w, path| {
                model_rows::write_pbrdf(w, path, &input, rows, &results)
            })?;
            info(ctx, out_path, rows.len(), "pBRDF");
        }
    }
    Ok(())
}

/// Say what was written when the output is a file (standard output stays clean).
fn info(ctx: &Ctx, out: Option<&std::path::Path>, rows: usize, kind: &str) {
    if let Some(p) = out {
        ctx.info(format!(
            "model: wrote {rows} {kind} rows to {}",
            p.display()
        ));
    }
}
