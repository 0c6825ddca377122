//! `laparo cats ...` (being written).
use clap::Subcommand;

#[derive(Subcommand)]
pub enum CatsCmd {
    /// Not yet available.
    Pending,
}

pub fn run(_c: CatsCmd) -> anyhow::Result<()> {
    anyhow::bail!("laparo cats is not available yet")
}
