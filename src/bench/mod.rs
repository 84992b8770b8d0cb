//! Benchmarks run by `photonlab bench` (release builds; figures are ratios measured
//! side by side in one run).

pub mod accel;

use anyhow::Result;
use clap::Subcommand;

/// `bench` subcommands.
#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Acceleration-structure build and ray throughput on the Embree harness's ray sets.
    Accel(accel::AccelArgs),
}

/// Runs a benchmark.
pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Accel(a) => accel::run(&a),
    }
}
