//! `photonlab bench scaling`: per-phase speed-up of a photon render from 1 to 2 threads.

use anyhow::Result;
use clap::Args;

/// Flags of `bench scaling`.
#[derive(Args, Debug, Clone, Default)]
pub struct ScalingArgs {
    /// Built-in scene.
    #[arg(long, default_value = "cornell-glass")]
    pub scene: String,
    /// One JSON object per line instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Runs `bench scaling`.
pub fn run(_args: &ScalingArgs) -> Result<()> {
    anyhow::bail!("bench scaling: not built yet")
}
