//! `laparo cpc ...` (being written).
use clap::Subcommand;

#[derive(Subcommand)]
pub enum CpcCmd {
    /// Not yet available.
    Pending,
}

pub fn run(_c: CpcCmd) -> anyhow::Result<()> {
    anyhow::bail!("laparo cpc is not available yet")
}
