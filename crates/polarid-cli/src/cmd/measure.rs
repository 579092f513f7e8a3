//! `polarid measure` (not yet implemented).

use crate::Ctx;

/// Arguments of `polarid measure`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `polarid measure`.
pub fn run(_args: Args, _ctx: &Ctx) -> anyhow::Result<()> {
    anyhow::bail!("`polarid measure` is not implemented yet")
}
