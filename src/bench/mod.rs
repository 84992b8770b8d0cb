//! Benchmarks run by `photonlab bench` (release builds; figures are ratios measured
//! side by side in one run).

use anyhow::Result;
use clap::Subcommand;

/// `bench` subcommands.
#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Acceleration-structure build and ray throughput.
    Accel,
}

/// Runs a benchmark.
pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Accel => anyhow::bail!("bench accel: not built yet"),
    }
}
