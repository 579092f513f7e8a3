//! `polarid model` (not yet implemented).

use crate::Ctx;

/// Arguments of `polarid model`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `polarid model`.
pub fn run(_args: Args, _ctx: &Ctx) -> anyhow::Result<()> {
    anyhow::bail!("`polarid model` is not implemented yet")
}
