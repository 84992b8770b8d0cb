//! `photonlab bench scaling`: the speed-up of each phase of a photon render from 1 to
//! 2 threads (photon tracing, kd-tree builds, irradiance-cache prefill, rendering).
//!
//! The render runs through the normal pipeline with the photon integrator and the
//! irradiance cache; phase times come from the integrator's counters
//! (`photon_trace_s`, `kdtree_build_s`, `prefill_s`) and the render pass. Each thread
//! count runs `--reps` times and the fastest time of each phase counts (a shared
//! machine's load only ever slows a run down). The images of both thread counts
//! must be bit-identical, which the command checks.

use crate::config::RenderConfig;
use crate::pipeline::render_scene;
use crate::scene::builtin::builtin;
use anyhow::{Result, bail};
use clap::Args;

/// Flags of `bench scaling`.
#[derive(Args, Debug, Clone)]
pub struct ScalingArgs {
    /// Built-in scene.
    #[arg(long, default_value = "cornell-glass")]
    pub scene: String,
    /// Photons in the direct + indirect maps (the caustic map gets a tenth).
    #[arg(long, default_value_t = 1_000_000)]
    pub photons: u32,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 192)]
    pub size: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 4)]
    pub spp: u32,
    /// Runs per thread count (the fastest time of each phase counts).
    #[arg(long, default_value_t = 2)]
    pub reps: usize,
    /// One JSON object per line instead of a table.
    #[arg(long)]
    pub json: bool,
}

impl Default for ScalingArgs {
    fn default() -> Self {
        ScalingArgs { scene: "cornell-glass".into(), photons: 1_000_000, size: 192, spp: 4, reps: 2, json: false }
    }
}

/// The 1-minute load average (Linux), printed beside timings: on a shared machine a
/// load above the core count means the threads did not get their cores.
pub fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg").ok()?.split_whitespace().next()?.parse().ok()
}

/// Phases timed, with the counter each comes from.
const PHASES: [(&str, &str); 4] =
    [("photon tracing", "photon_trace_s"), ("kd-tree build", "kdtree_build_s"), ("cache prefill", "prefill_s"), ("rendering", "render_s")];

#[derive(serde::Serialize)]
struct Row {
    bench: &'static str,
    scene: String,
    phase: &'static str,
    t1_s: f64,
    t2_s: f64,
    speedup: f64,
    cores: usize,
    load_average: Option<f64>,
}

/// Runs `bench scaling`.
pub fn run(args: &ScalingArgs) -> Result<()> {
    if args.size == 0 || args.spp == 0 || args.photons == 0 {
        bail!("bench scaling: --size, --spp and --photons must be at least 1");
    }
    let mut best = [[f64::INFINITY; 4]; 2];
    let mut images: [Option<Vec<crate::math::Color>>; 2] = [None, None];
    for rep in 0..args.reps.max(1) {
        for (slot, threads) in [1usize, 2].into_iter().enumerate() {
            let scene = builtin(&args.scene)?;
            let cfg = RenderConfig {
                integrator: "photon".into(),
                spp: args.spp,
                threads,
                resolution: Some([args.size, args.size]),
                ..RenderConfig::default()
            }
            .with("gather", "irradiance_cache")
            .with("photons", args.photons)
            .with("caustic_photons", args.photons / 10);
            let out = render_scene(scene, &cfg, true)?;
            for (j, (_, key)) in PHASES.iter().enumerate() {
                let t = if *key == "render_s" { out.timings.render_s } else { out.extra.get(*key).copied().unwrap_or(f64::NAN) };
                best[slot][j] = best[slot][j].min(t);
            }
            if rep == 0 {
                images[slot] = Some(out.film.pixels.clone());
            }
        }
    }
    if images[0] != images[1] {
        bail!("bench scaling: the images of 1 and 2 threads differ (the pipeline must be deterministic)");
    }
    let rows: Vec<Row> = PHASES
        .iter()
        .enumerate()
        .map(|(j, (name, _))| Row {
            bench: "scaling",
            scene: args.scene.clone(),
            phase: name,
            t1_s: best[0][j],
            t2_s: best[1][j],
            speedup: best[0][j] / best[1][j],
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            load_average: load_average(),
        })
        .collect();
    if args.json {
        for r in &rows {
            outln!("{}", serde_json::to_string(r)?);
        }
    } else {
        outln!(
            "bench scaling: {}, {} global + {} caustic photons, irradiance cache, {}x{} px, {} spp; best of {} runs; {} cores, load average {}",
            args.scene,
            args.photons,
            args.photons / 10,
            args.size,
            args.size,
            args.spp,
            args.reps.max(1),
            rows[0].cores,
            rows[0].load_average.map_or("unknown".into(), |l| format!("{l:.1}"))
        );
        outln!("| phase | 1 thread | 2 threads | speed-up |");
        outln!("|---|---|---|---|");
        for r in &rows {
            outln!("| {} | {:.3} s | {:.3} s | {:.2}x |", r.phase, r.t1_s, r.t2_s, r.speedup);
        }
    }
    Ok(())
}
