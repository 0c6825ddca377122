//! `laparo stereo ...` (being written).
use clap::Subcommand;

#[derive(Subcommand)]
pub enum StereoCmd {
    /// Not yet available.
    Pending,
}

pub fn run(_c: StereoCmd) -> anyhow::Result<()> {
    anyhow::bail!("laparo stereo is not available yet")
}
