//! `polarid map` (not yet implemented).

use crate::Ctx;

/// Arguments of `polarid map`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `polarid map`.
pub fn run(_args: Args, _ctx: &Ctx) -> anyhow::Result<()> {
    anyhow::bail!("`polarid map` is not implemented yet")
}
