//! `photonlab bench progressive`: speed of an `sppm` pass on 1 and 2 threads —
//! passes per second, photon paths per second per thread, and the 1 → 2 thread
//! speed-up of a whole pass and of each phase (camera pass, photon pass, gather).
//!
//! Each repetition renders the same `sppm` run once with 1 thread and once with 2,
//! alternated; the fastest run of each thread count counts (a shared machine's load
//! only ever slows a run down). Beside the wall times the process's CPU time of each
//! run is printed: when it is well below threads × wall time, the threads did not get
//! their cores and the speed-up says more about the load than about the code. The
//! images of both thread counts must be bit-identical, which the command checks.

use super::scaling::load_average;
use crate::config::RenderConfig;
use crate::pipeline::render_scene;
use crate::scene::builtin::builtin;
use anyhow::{Result, bail};
use clap::Args;

/// Flags of `bench progressive`.
#[derive(Args, Debug, Clone)]
pub struct ProgressiveArgs {
    /// Built-in scene.
    #[arg(long, default_value = "cornell")]
    pub scene: String,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Passes per run.
    #[arg(long, default_value_t = 32)]
    pub passes: u32,
    /// Runs per thread count, alternated (the fastest counts).
    #[arg(long, default_value_t = 3)]
    pub reps: usize,
    /// One JSON object per line instead of a table.
    #[arg(long)]
    pub json: bool,
}

impl Default for ProgressiveArgs {
    fn default() -> Self {
        ProgressiveArgs { scene: "cornell".into(), size: 256, passes: 32, reps: 3, json: false }
    }
}

/// CPU seconds used by this process so far (all threads).
fn process_cpu_s() -> f64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    if rc != 0 { f64::NAN } else { ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9 }
}

/// Phases timed (wall seconds over the run), with the counter each comes from.
const PHASES: [(&str, &str); 4] =
    [("whole pass", "render_s"), ("camera pass", "camera_pass_s"), ("photon pass", "photon_pass_s"), ("gather", "gather_s")];

/// The best run of one thread count.
#[derive(Clone, Copy)]
struct Best {
    phase_s: [f64; 4],
    cpu_s: f64,
    photons: f64,
}

#[derive(serde::Serialize)]
struct Row {
    bench: &'static str,
    scene: String,
    size: u32,
    passes: u32,
    phase: &'static str,
    t1_ms_per_pass: f64,
    t2_ms_per_pass: f64,
    speedup: f64,
    cores: usize,
    load_average: Option<f64>,
}

/// Runs `bench progressive`.
pub fn run(args: &ProgressiveArgs) -> Result<()> {
    if args.size == 0 || args.passes == 0 {
        bail!("bench progressive: --size and --passes must be at least 1");
    }
    let load_before = load_average();
    let mut best = [Best { phase_s: [f64::INFINITY; 4], cpu_s: f64::NAN, photons: 0.0 }; 2];
    let mut images: [Option<Vec<crate::math::Color>>; 2] = [None, None];
    for rep in 0..args.reps.max(1) {
        for (slot, threads) in [1usize, 2].into_iter().enumerate() {
            let scene = builtin(&args.scene)?;
            let cfg =
                RenderConfig { integrator: "sppm".into(), threads, resolution: Some([args.size, args.size]), ..RenderConfig::default() }
                    .with("passes", args.passes);
            let cpu0 = process_cpu_s();
            let out = render_scene(scene, &cfg, true)?;
            let cpu = process_cpu_s() - cpu0;
            let t: Vec<f64> = PHASES
                .iter()
                .map(|(_, key)| if *key == "render_s" { out.timings.render_s } else { out.extra.get(*key).copied().unwrap_or(f64::NAN) })
                .collect();
            let b = &mut best[slot];
            if t[0] < b.phase_s[0] {
                b.cpu_s = cpu;
            }
            for (j, v) in t.iter().enumerate() {
                b.phase_s[j] = b.phase_s[j].min(*v);
            }
            b.photons = out.extra.get("photons_emitted").copied().unwrap_or(0.0);
            if rep == 0 {
                images[slot] = Some(out.film.pixels.clone());
            }
        }
    }
    if images[0] != images[1] {
        bail!("bench progressive: the images of 1 and 2 threads differ (sppm must be deterministic)");
    }
    let per_pass = 1e3 / args.passes as f64;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let load = load_average();
    let rows: Vec<Row> = PHASES
        .iter()
        .enumerate()
        .map(|(j, (name, _))| Row {
            bench: "progressive",
            scene: args.scene.clone(),
            size: args.size,
            passes: args.passes,
            phase: name,
            t1_ms_per_pass: best[0].phase_s[j] * per_pass,
            t2_ms_per_pass: best[1].phase_s[j] * per_pass,
            speedup: best[0].phase_s[j] / best[1].phase_s[j],
            cores,
            load_average: load,
        })
        .collect();
    // Photon paths per second and thread, over the photon pass.
    let photon_rate = |b: &Best, threads: f64| b.photons / b.phase_s[2] / threads;
    if args.json {
        for r in &rows {
            outln!("{}", serde_json::to_string(r)?);
        }
        outln!(
            "{}",
            serde_json::json!({
                "bench": "progressive", "scene": args.scene, "summary": true,
                "passes_per_s_1": args.passes as f64 / best[0].phase_s[0], "passes_per_s_2": args.passes as f64 / best[1].phase_s[0],
                "photons_per_s_per_thread_1": photon_rate(&best[0], 1.0), "photons_per_s_per_thread_2": photon_rate(&best[1], 2.0),
                "cpu_s_1": best[0].cpu_s, "cpu_s_2": best[1].cpu_s, "wall_s_1": best[0].phase_s[0], "wall_s_2": best[1].phase_s[0],
                "load_average_before": load_before, "load_average_after": load,
            })
        );
        return Ok(());
    }
    let fmt_load = |l: Option<f64>| l.map_or("unknown".into(), |l| format!("{l:.1}"));
    outln!(
        "bench progressive: sppm on {}, {}x{} px, {} passes ({} photon paths per pass), best of {} alternated runs; {} cores, load average {} before, {} after",
        args.scene,
        args.size,
        args.size,
        args.passes,
        (best[0].photons / args.passes as f64).round(),
        args.reps.max(1),
        cores,
        fmt_load(load_before),
        fmt_load(load)
    );
    outln!("| phase | 1 thread (ms/pass) | 2 threads (ms/pass) | speed-up |");
    outln!("|---|---|---|---|");
    for r in &rows {
        outln!("| {} | {:.2} | {:.2} | {:.2}x |", r.phase, r.t1_ms_per_pass, r.t2_ms_per_pass, r.speedup);
    }
    for (b, threads) in [(&best[0], 1.0), (&best[1], 2.0)] {
        outln!(
            "{threads} thread(s): {:.2} passes/s, {:.3} M photon paths/s per thread; CPU {:.2} s in {:.2} s wall ({:.2} cores busy)",
            args.passes as f64 / b.phase_s[0],
            photon_rate(b, threads) * 1e-6,
            b.cpu_s,
            b.phase_s[0],
            b.cpu_s / b.phase_s[0]
        );
    }
    Ok(())
}
