//! `polarid stokes` (not yet implemented).

use crate::Ctx;

/// Arguments of `polarid stokes`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `polarid stokes`.
pub fn run(_args: Args, _ctx: &Ctx) -> anyhow::Result<()> {
    anyhow::bail!("`polarid stokes` is not implemented yet")
}
