//! `polarid train` (not yet implemented).

use crate::Ctx;

/// Arguments of `polarid train`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `polarid train`.
pub fn run(_args: Args, _ctx: &Ctx) -> anyhow::Result<()> {
    anyhow::bail!("`polarid train` is not implemented yet")
}
