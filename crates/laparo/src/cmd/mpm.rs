//! `laparo mpm ...` (being written).
use clap::Subcommand;

#[derive(Subcommand)]
pub enum MpmCmd {
    /// Not yet available.
    Pending,
}

pub fn run(_c: MpmCmd) -> anyhow::Result<()> {
    anyhow::bail!("laparo mpm is not available yet")
}
