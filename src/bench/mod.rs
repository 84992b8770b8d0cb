//! Benchmarks run by `photonlab bench` (release builds; figures are ratios measured
//! side by side in one run).

pub mod accel;
pub mod embree;
pub mod knn;
pub mod photons;
pub mod progressive;
pub mod render;
pub mod scaling;

use anyhow::Result;
use clap::Subcommand;

/// `bench` subcommands.
#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Acceleration-structure build and ray throughput on the Embree harness's ray sets.
    Accel(accel::AccelArgs),
    /// Embree harness vs photonlab on the same OBJs and ray sets: ratio per row.
    EmbreeCompare(embree::EmbreeArgs),
    /// Photon kd-tree against kiddo: build and k-NN query times on the same points.
    Knn(knn::KnnArgs),
    /// Time and peak memory of the photon integrator per photon count (one process per count).
    Photons(photons::PhotonsArgs),
    /// Time per camera sample of `path` and the photon gathers, per sampler.
    Render(render::RenderArgs),
    /// Per-phase speed-up of a photon render from 1 to 2 threads.
    Scaling(scaling::ScalingArgs),
    /// Speed of an `sppm` pass: passes/s, photon paths/s per thread, 1 → 2 thread speed-up per phase.
    Progressive(progressive::ProgressiveArgs),
    /// Every benchmark that finishes within about ten minutes, one after another.
    All {
        /// One JSON object per line instead of tables.
        #[arg(long)]
        json: bool,
    },
}

/// Runs a benchmark.
pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Accel(a) => accel::run(&a),
        BenchCommand::EmbreeCompare(a) => embree::run(&a),
        BenchCommand::Knn(a) => knn::run(&a),
        BenchCommand::Photons(a) => photons::run(&a).map(|_| ()),
        BenchCommand::Render(a) => render::run(&a).map(|_| ()),
        BenchCommand::Scaling(a) => scaling::run(&a),
        BenchCommand::Progressive(a) => progressive::run(&a),
        BenchCommand::All { json } => run_all(json),
    }
}

/// `bench all`: each benchmark with its default (full-size) settings.
fn run_all(json: bool) -> Result<()> {
    for inside in [false, true] {
        accel::run(&accel::AccelArgs {
            obj: None,
            builtin: Some("displaced-sphere".into()),
            inside,
            rays: 2_000_000,
            threads: 1,
            accel: vec!["bvh".into(), "bvh4".into(), "bvh8".into(), "bvh8q".into()],
            builds: 1,
            name: None,
            json,
            stream: 8,
            sets: accel::all_sets(),
            no_counts: false,
        })?;
    }
    // The kd-tree-vs-kiddo comparison needs the optional `kiddo` feature; without it
    // `bench all` runs the rest (`bench knn` alone says how to enable it).
    if cfg!(feature = "kiddo") {
        knn::run(&knn::KnnArgs { n: 1_000_000, queries: 20_000, threads: None, reps: 3, json })?;
    } else {
        eprintln!("bench all: skipping `bench knn` (build with `--features kiddo` to include it)");
    }
    scaling::run(&scaling::ScalingArgs { json, ..Default::default() })?;
    render::run(&render::RenderArgs { json, ..Default::default() })?;
    Ok(())
}
