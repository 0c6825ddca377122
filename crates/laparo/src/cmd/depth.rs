//! `laparo depth ...` (being written).
use clap::Subcommand;

#[derive(Subcommand)]
pub enum DepthCmd {
    /// Not yet available.
    Pending,
}

pub fn run(_c: DepthCmd) -> anyhow::Result<()> {
    anyhow::bail!("laparo depth is not available yet")
}
