//! `polarid demo` (not yet implemented).

use crate::Ctx;

/// Arguments of `polarid demo`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `polarid demo`.
pub fn run(_args: Args, _ctx: &Ctx) -> anyhow::Result<()> {
    anyhow::bail!("`polarid demo` is not implemented yet")
}
