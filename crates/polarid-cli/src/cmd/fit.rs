//! `polarid fit` (not yet implemented).

use crate::Ctx;

/// Arguments of `polarid fit`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `polarid fit`.
pub fn run(_args: Args, _ctx: &Ctx) -> anyhow::Result<()> {
    anyhow::bail!("`polarid fit` is not implemented yet")
}
