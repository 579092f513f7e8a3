//! `polarid classify` (not yet implemented).

use crate::Ctx;

/// Arguments of `polarid classify`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `polarid classify`.
pub fn run(_args: Args, _ctx: &Ctx) -> anyhow::Result<()> {
    anyhow::bail!("`polarid classify` is not implemented yet")
}
