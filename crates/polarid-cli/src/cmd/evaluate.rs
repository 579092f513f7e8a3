//! `polarid evaluate` (not yet implemented).

use crate::Ctx;

/// Arguments of `polarid evaluate`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `polarid evaluate`.
pub fn run(_args: Args, _ctx: &Ctx) -> anyhow::Result<()> {
    anyhow::bail!("`polarid evaluate` is not implemented yet")
}
