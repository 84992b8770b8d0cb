//! Benchmarks run by `photonlab bench` (release builds; figures are ratios measured
//! side by side in one run).

pub mod accel;
pub mod embree;

use anyhow::Result;
use clap::Subcommand;

/// `bench` subcommands.
#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Acceleration-structure build and ray throughput on the Embree harness's ray sets.
    Accel(accel::AccelArgs),
    /// Embree harness vs photonlab on the same OBJs and ray sets: ratio per row.
    EmbreeCompare(embree::EmbreeArgs),
}

/// Runs a benchmark.
pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Accel(a) => accel::run(&a),
        BenchCommand::EmbreeCompare(a) => embree::run(&a),
    }
}
