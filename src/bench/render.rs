//! `photonlab bench render`: time per camera sample of `path` and of the photon
//! integrator's gathers on the built-in scenes, for each sampler, with rays per second
//! and samples per second (also per worker thread).
//!
//! Every case (scene × integrator/gather × sampler) is prepared once (accelerator,
//! photon pass, caches: not timed) and its render pass runs `--reps` times; the
//! repetitions are interleaved case by case so that all cases see the same machine
//! load, and the fastest pass counts (a shared machine only ever slows a run down).
//! `ratio` is a case's time over the time of the first sampler listed on the same
//! scene and integrator (so `--samplers random,halton,...` prints halton/random).

use crate::config::RenderConfig;
use crate::integrator::render::render;
use crate::pipeline::{configured_scene, prepare, thread_pool};
use crate::scene::builtin::builtin;
use anyhow::{Result, bail};
use clap::Args;

/// Flags of `bench render`.
#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// Built-in scenes, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "cornell")]
    pub scenes: Vec<String>,
    /// Integrators, comma-separated: `path` and/or `photon` (one case per `--gather`).
    #[arg(long, value_delimiter = ',', default_value = "path")]
    pub integrator: Vec<String>,
    /// Photon integrator's gathers, comma-separated: direct | final_gather | precomputed | irradiance_cache.
    #[arg(long, value_delimiter = ',', default_value = "direct")]
    pub gather: Vec<String>,
    /// Samplers, comma-separated; the first is the reference of `ratio`.
    #[arg(long, value_delimiter = ',', default_value = "random,halton,hammersley,sobol")]
    pub samplers: Vec<String>,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Photon integrator: photons in the direct + indirect maps.
    #[arg(long, default_value_t = 200_000)]
    pub photons: u32,
    /// Photon integrator: photons in the caustic map (0: none; `cornell` has no glass).
    #[arg(long, default_value_t = 0)]
    pub caustic_photons: u32,
    /// Photon integrator: `gather_samples` (default: the gather plug-in's own, e.g. 256 rays a pixel for `precomputed`).
    #[arg(long)]
    pub gather_samples: Option<u32>,
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Timed render passes per case (the fastest counts).
    #[arg(long, default_value_t = 3)]
    pub reps: usize,
    /// Render seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// One JSON object per line instead of a table.
    #[arg(long)]
    pub json: bool,
}

impl Default for RenderArgs {
    fn default() -> Self {
        RenderArgs {
            scenes: vec!["cornell".into()],
            integrator: vec!["path".into()],
            gather: vec!["direct".into()],
            samplers: crate::registry::SAMPLERS.iter().map(|s| s.to_string()).collect(),
            size: 256,
            spp: 64,
            photons: 200_000,
            caustic_photons: 0,
            gather_samples: None,
            threads: 0,
            reps: 3,
            seed: 0,
            json: false,
        }
    }
}

/// One result row (one JSON line).
#[derive(serde::Serialize, Clone, Debug)]
pub struct Row {
    bench: &'static str,
    scene: String,
    integrator: String,
    gather: Option<String>,
    sampler: String,
    size: u32,
    spp: u32,
    threads: usize,
    /// Fastest render pass, seconds.
    seconds: f64,
    /// Median render pass, seconds.
    median_seconds: f64,
    /// Time over the first sampler's on the same scene and integrator.
    ratio: f64,
    samples: u64,
    ns_per_sample: f64,
    samples_per_s: f64,
    /// `samples_per_s` over the worker threads.
    samples_per_s_per_thread: f64,
    /// Closest-hit plus shadow rays of one pass.
    rays: u64,
    shadow_rays: u64,
    rays_per_s: f64,
    /// Untimed set-up: accelerator build and pre-pass.
    setup_seconds: f64,
    load_average: Option<f64>,
}

struct Case {
    scene: String,
    integrator: String,
    gather: Option<String>,
    cfg: RenderConfig,
}

fn cases(args: &RenderArgs) -> Result<Vec<Case>> {
    let mut out = Vec::new();
    for scene in &args.scenes {
        for integ in &args.integrator {
            let gathers: Vec<Option<String>> = match integ.as_str() {
                "path" => vec![None],
                "photon" => args.gather.iter().cloned().map(Some).collect(),
                other => bail!("bench render: integrator `{other}` is not timed here (use path or photon)"),
            };
            for gather in gathers {
                for sampler in &args.samplers {
                    let mut cfg = RenderConfig {
                        integrator: integ.clone(),
                        sampler: sampler.clone(),
                        spp: args.spp,
                        seed: args.seed,
                        threads: args.threads,
                        resolution: Some([args.size, args.size]),
                        ..RenderConfig::default()
                    };
                    if let Some(g) = &gather {
                        cfg = cfg.with("gather", g.as_str()).with("photons", args.photons).with("caustic_photons", args.caustic_photons);
                        if let Some(n) = args.gather_samples.filter(|_| g != "direct") {
                            cfg = cfg.with("gather_samples", n);
                        }
                        // Hammersley needs its photon count up front.
                        if sampler == "hammersley" {
                            cfg = cfg.with("emit_photons", (args.photons + args.caustic_photons) as i64 * 2);
                        }
                    }
                    out.push(Case { scene: scene.clone(), integrator: integ.clone(), gather: gather.clone(), cfg });
                }
            }
        }
    }
    Ok(out)
}

/// Runs `bench render` and returns its rows (also printed).
pub fn run(args: &RenderArgs) -> Result<Vec<Row>> {
    if args.size == 0 || args.spp == 0 || args.samplers.is_empty() {
        bail!("bench render: --size and --spp must be at least 1 and --samplers not empty");
    }
    let cases = cases(args)?;
    let pool = thread_pool(args.threads)?;
    let threads = pool.current_num_threads();
    let prepared = pool.install(|| -> Result<Vec<_>> {
        cases
            .iter()
            .map(|c| {
                let t = std::time::Instant::now();
                let scene = configured_scene(builtin(&c.scene)?, &c.cfg)?;
                let p = prepare(scene, &c.cfg, true)?;
                Ok((p, t.elapsed().as_secs_f64()))
            })
            .collect()
    })?;
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); cases.len()];
    let mut rays = vec![(0u64, 0u64); cases.len()];
    for _ in 0..args.reps.max(1) {
        for (k, (p, _)) in prepared.iter().enumerate() {
            let (_, st) = pool.install(|| render(&p.world, p.integrator.as_ref(), p.sampler.as_ref(), args.spp, true));
            times[k].push(st.seconds);
            rays[k] = (st.traversal.rays, st.traversal.shadow_rays);
        }
    }
    let load = super::scaling::load_average();
    let mut rows: Vec<Row> = Vec::new();
    for (k, c) in cases.iter().enumerate() {
        let mut t = times[k].clone();
        t.sort_by(f64::total_cmp);
        let (best, median) = (t[0], t[t.len() / 2]);
        let reference =
            rows.iter().find(|r| r.scene == c.scene && r.integrator == c.integrator && r.gather == c.gather).map_or(best, |r| r.seconds);
        let samples = args.size as u64 * args.size as u64 * args.spp as u64;
        let (r, s) = rays[k];
        rows.push(Row {
            bench: "render",
            scene: c.scene.clone(),
            integrator: c.integrator.clone(),
            gather: c.gather.clone(),
            sampler: c.cfg.sampler.clone(),
            size: args.size,
            spp: args.spp,
            threads,
            seconds: best,
            median_seconds: median,
            ratio: best / reference,
            samples,
            ns_per_sample: best * 1e9 / samples as f64,
            samples_per_s: samples as f64 / best,
            samples_per_s_per_thread: samples as f64 / best / threads.max(1) as f64,
            rays: r + s,
            shadow_rays: s,
            rays_per_s: (r + s) as f64 / best,
            setup_seconds: prepared[k].1,
            load_average: load,
        });
    }
    if args.json {
        for r in &rows {
            outln!("{}", serde_json::to_string(r)?);
        }
    } else {
        outln!(
            "bench render: {}x{} px, {} spp, {} threads, best of {} interleaved passes; load average {}",
            args.size,
            args.size,
            args.spp,
            threads,
            args.reps.max(1),
            load.map_or("unknown".into(), |l| format!("{l:.1}"))
        );
        outln!("| scene | integrator | sampler | seconds | ratio | ns/sample | Msamples/s | ksamples/s/thread | Mrays/s | rays |");
        outln!("|---|---|---|---|---|---|---|---|---|---|");
        for r in &rows {
            let integ = match &r.gather {
                Some(g) => format!("{} ({g})", r.integrator),
                None => r.integrator.clone(),
            };
            outln!(
                "| {} | {} | {} | {:.3} | {:.2} | {:.0} | {:.2} | {:.1} | {:.1} | {} |",
                r.scene,
                integ,
                r.sampler,
                r.seconds,
                r.ratio,
                r.ns_per_sample,
                r.samples_per_s / 1e6,
                r.samples_per_s_per_thread / 1e3,
                r.rays_per_s / 1e6,
                r.rays
            );
        }
    }
    Ok(rows)
}
