//! `polarid simulate` (not yet implemented).

use crate::Ctx;

/// Arguments of `polarid simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `polarid simulate`.
pub fn run(_args: Args, _ctx: &Ctx) -> anyhow::Result<()> {
    anyhow::bail!("`polarid simulate` is not implemented yet")
}
