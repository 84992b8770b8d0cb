//! Command-line front end: `render`, `scene export`, `bench`.

use crate::config::{RenderConfig, parse_resolution};
use crate::scene::{Scene, builtin::builtin, export::export_scene, loader::load_scene};
use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

/// photonlab: a photon-mapping research testbed.
#[derive(Parser, Debug)]
#[command(name = "photonlab", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render a scene file or a built-in scene to OUT.exr and OUT.png.
    Render(Box<RenderArgs>),
    /// Scene utilities.
    #[command(subcommand)]
    Scene(SceneCommand),
    /// Compare two EXR images: mean per channel, RMSE, relative MSE.
    Diff {
        /// Image under test.
        test: PathBuf,
        /// Reference image.
        reference: PathBuf,
        /// Write the signed difference (test − reference), scaled ×4 around grey, to this PNG.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Also compare means over BLOCK×BLOCK-pixel blocks (blocks whose reference
        /// mean exceeds 0.005) and print the worst block's relative error.
        #[arg(long)]
        block: Option<u32>,
    },
    /// Benchmarks (release builds).
    #[command(subcommand)]
    Bench(crate::bench::BenchCommand),
    /// Statistical test suite: RR bias, discrepancy, chi-square, BRDF, convergence.
    Stats(crate::stats::StatsArgs),
    /// Run an experiment manifest: sweep configurations, measure them against a reference, write tables, images, plots and a summary.
    Run(crate::experiment::RunArgs),
    /// Combine the cells of a sharded experiment directory and write its tables, plots and summary.
    Merge(crate::experiment::MergeArgs),
    /// Combine sample-range parts (`render --sample-range`, `.psum`) into OUT.exr and OUT.png; bit-identical for any split.
    Accumulate {
        /// Output image (.exr; a .png is written beside it).
        out: PathBuf,
        /// Parts (`X.psum`, or `X.exr` for its `X.psum` sidecar) that together cover samples 0..spp once.
        #[arg(required = true)]
        parts: Vec<PathBuf>,
    },
    /// Maintenance: fuzz the scene TOML, OBJ, MTL and manifest readers (no panic, no hang).
    Fuzz(crate::fuzz::FuzzArgs),
}

/// `scene` subcommands.
#[derive(Subcommand, Debug)]
pub enum SceneCommand {
    /// Write a built-in scene as scene TOML + OBJ/MTL following the scene contract.
    Export {
        /// Built-in scene name.
        name: String,
        /// Output directory.
        dir: PathBuf,
    },
}

/// Flags of `render`.
#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    /// Scene TOML file.
    #[arg(long, conflicts_with = "builtin")]
    pub scene: Option<PathBuf>,
    /// Built-in scene (default: cornell).
    #[arg(long)]
    pub builtin: Option<String>,
    /// Integrator.
    #[arg(long)]
    pub integrator: Option<String>,
    /// Samples per pixel.
    #[arg(long)]
    pub spp: Option<u32>,
    /// Sampler: random | halton | hammersley | sobol.
    #[arg(long)]
    pub sampler: Option<String>,
    /// Accelerator: none | bvh | bvh4 | bvh8 | bvh8q (default bvh8).
    #[arg(long)]
    pub accel: Option<String>,
    /// Russian roulette: `off`, `fixed[:q]`, `albedo` or `throughput[:min_depth]`.
    #[arg(long)]
    pub rr: Option<String>,
    /// Maximum number of bounces (default unbounded).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Random seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (0 = all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Image size WIDTHxHEIGHT (overrides the scene camera's).
    #[arg(long)]
    pub resolution: Option<String>,
    /// Photon integrator: photons stored in the direct + indirect maps.
    #[arg(long)]
    pub photons: Option<u32>,
    /// Photon integrator: photons stored in the caustic map.
    #[arg(long)]
    pub caustic_photons: Option<u32>,
    /// Photon integrator: emit exactly N photon paths (needed by hammersley).
    #[arg(long)]
    pub emit_photons: Option<u64>,
    /// Photon integrator: cap on emitted photon paths.
    #[arg(long)]
    pub max_emitted: Option<u64>,
    /// Photon integrator: direct | final_gather | precomputed | irradiance_cache.
    #[arg(long)]
    pub gather: Option<String>,
    /// Photon integrator: final-gather rays per point.
    #[arg(long)]
    pub gather_samples: Option<u32>,
    /// Photon integrator: final-gather levels.
    #[arg(long)]
    pub gather_bounces: Option<u32>,
    /// Photon integrator: precomputed irradiance at gather hits (true/false).
    #[arg(long)]
    pub precomputed_irradiance: Option<bool>,
    /// Photon integrator: precompute irradiance at every n-th photon.
    #[arg(long)]
    pub precompute_stride: Option<u32>,
    /// Photon integrator: photons per global estimate.
    #[arg(long)]
    pub k: Option<u32>,
    /// Photon integrator: photons per caustic estimate.
    #[arg(long)]
    pub caustic_k: Option<u32>,
    /// Photon integrator: maximum global search radius (scene units).
    #[arg(long)]
    pub max_radius: Option<f32>,
    /// Photon integrator: maximum caustic search radius (scene units).
    #[arg(long)]
    pub caustic_max_radius: Option<f32>,
    /// Photon integrator: box | cone | gaussian.
    #[arg(long)]
    pub filter: Option<String>,
    /// Photon integrator: disc half-thickness as a fraction of the maximum radius.
    #[arg(long)]
    pub disc: Option<f32>,
    /// Photon integrator: shadow rays per shading point.
    #[arg(long)]
    pub direct_samples: Option<u32>,
    /// Photon integrator: sampler for direct-light samples.
    #[arg(long)]
    pub direct_sampler: Option<String>,
    /// Photon integrator: irradiance-cache tolerance a.
    #[arg(long)]
    pub ic_tolerance: Option<f32>,
    /// Photon integrator: smallest cache radius (fraction of the scene radius).
    #[arg(long)]
    pub ic_min_radius: Option<f32>,
    /// Photon integrator: largest cache radius (fraction of the scene radius).
    #[arg(long)]
    pub ic_max_radius: Option<f32>,
    /// Photon integrator: smallest cache radius in pixel footprints.
    #[arg(long)]
    pub ic_min_pixels: Option<f32>,
    /// Photon integrator: largest cache radius in pixel footprints.
    #[arg(long)]
    pub ic_max_pixels: Option<f32>,
    /// Photon integrator: irradiance gradients in the cache (true/false).
    #[arg(long)]
    pub ic_gradients: Option<bool>,
    /// Photon integrator: rays per irradiance-cache entry.
    #[arg(long)]
    pub ic_samples: Option<u32>,
    /// Photon integrator: neighbour clamping of cache radii (true/false).
    #[arg(long)]
    pub ic_neighbor_clamp: Option<bool>,
    /// Photon integrator: rays drawn from the glossy lobe at glossy points.
    #[arg(long)]
    pub glossy_samples: Option<u32>,
    /// sppm / ppm: maximum number of passes (default 16, unbounded with --time-limit).
    #[arg(long)]
    pub passes: Option<u32>,
    /// sppm / ppm: photon paths emitted per pass (sppm default 131072).
    #[arg(long)]
    pub photons_per_pass: Option<u64>,
    /// sppm / ppm: radius-reduction parameter alpha in (0, 1] (default 2/3).
    #[arg(long)]
    pub alpha: Option<f32>,
    /// sppm / ppm: stop after the pass that crosses this many seconds.
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// sppm: initial per-pixel radius in scene units (default 0.02 x scene radius).
    #[arg(long)]
    pub sppm_radius: Option<f32>,
    /// sppm: direct light by `trace` (shadow rays, default) or `photons`.
    #[arg(long)]
    pub sppm_direct: Option<String>,
    /// sppm / ppm: write the image and the state (OUT.checkpoint.json) every K passes.
    #[arg(long)]
    pub checkpoint_every: Option<u32>,
    /// sppm / ppm: continue from OUT.checkpoint.json (bit-identical to an uninterrupted run).
    #[arg(long)]
    pub resume: bool,
    /// Extra images (photon integrator): direct, caustic, indirect, photons-direct,
    /// photons-indirect, photons-caustic, cache. Repeat or comma-separate.
    #[arg(long, value_delimiter = ',')]
    pub aov: Vec<String>,
    /// Render only samples A..B-1 of every pixel (of the --spp N render) and write their
    /// exact sums to OUT.psum (plus a preview OUT.exr/png); combine with `accumulate`.
    #[arg(long, value_name = "A..B")]
    pub sample_range: Option<crate::accumulate::SampleRange>,
    /// Output path; .exr and .png are written next to each other.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl RenderArgs {
    /// The configuration these flags describe (defaults where a flag is absent).
    pub fn config(&self) -> Result<RenderConfig> {
        let mut c = RenderConfig::default();
        if let Some(v) = &self.integrator {
            c.integrator = v.clone();
        }
        if let Some(v) = self.spp {
            c.spp = v;
        }
        if let Some(v) = &self.sampler {
            c.sampler = v.clone();
        }
        if let Some(v) = &self.accel {
            c.accel = v.clone();
        }
        if let Some(v) = &self.rr {
            c.rr = v.clone();
        }
        c.max_depth = self.max_depth;
        if let Some(v) = self.seed {
            c.seed = v;
        }
        if let Some(v) = self.threads {
            c.threads = v;
        }
        macro_rules! set {
            ($($f:ident),*) => {$(if let Some(v) = &self.$f { c.$f = v.clone(); })*};
        }
        set!(photons, caustic_photons, max_emitted, gather, gather_samples, gather_bounces, precomputed_irradiance, precompute_stride, k);
        set!(caustic_k, filter, disc, direct_samples, direct_sampler, ic_tolerance, ic_min_radius, ic_max_radius);
        set!(ic_min_pixels, ic_max_pixels, ic_gradients, ic_neighbor_clamp, glossy_samples, ic_samples);
        set!(alpha, sppm_direct);
        c.passes = self.passes.or(c.passes);
        c.photons_per_pass = self.photons_per_pass.or(c.photons_per_pass);
        c.time_limit = self.time_limit.or(c.time_limit);
        c.sppm_radius = self.sppm_radius.or(c.sppm_radius);
        c.checkpoint_every = self.checkpoint_every.or(c.checkpoint_every);
        c.resume = self.resume;
        if let Some(o) = &self.output
            && (c.checkpoint_every.is_some() || c.resume)
        {
            c.checkpoint_file = Some(format!("{}.checkpoint.json", o.with_extension("").display()));
        }
        if self.emit_photons.is_some() {
            c.emit_photons = self.emit_photons;
        }
        if self.max_radius.is_some() {
            c.max_radius = self.max_radius;
        }
        if self.caustic_max_radius.is_some() {
            c.caustic_max_radius = self.caustic_max_radius;
        }
        if let Some(r) = &self.resolution {
            c.resolution = Some(parse_resolution(r).map_err(anyhow::Error::msg)?);
        }
        Ok(c)
    }

    /// Loads the scene the flags name.
    pub fn load(&self) -> Result<Scene> {
        match (&self.scene, &self.builtin) {
            (Some(p), _) => load_scene(p),
            (None, Some(b)) => builtin(b),
            (None, None) => builtin("cornell"),
        }
    }
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(a) => cmd_render(&a),
        Command::Scene(SceneCommand::Export { name, dir }) => {
            let scene = builtin(&name)?;
            let toml = export_scene(&scene, &dir)?;
            outln!("wrote {}", toml.display());
            Ok(())
        }
        Command::Bench(b) => crate::bench::run(b),
        Command::Stats(a) => crate::stats::run_cli(&a),
        Command::Run(a) => crate::experiment::run_cmd(&a),
        Command::Merge(a) => crate::experiment::merge_cmd(&a),
        Command::Accumulate { out, parts } => crate::accumulate::accumulate_cmd(&out, &parts),
        Command::Fuzz(a) => crate::fuzz::fuzz_cmd(&a),
        Command::Diff { test, reference, out, block } => {
            let a = crate::film::Film::read_exr(&test)?;
            let b = crate::film::Film::read_exr(&reference)?;
            if (a.width, a.height) != (b.width, b.height) {
                anyhow::bail!("{}: size {}x{} differs from the reference's {}x{}", test.display(), a.width, a.height, b.width, b.height);
            }
            let (mut se, mut rel) = (0.0f64, 0.0f64);
            for (p, q) in a.pixels.iter().zip(&b.pixels) {
                for c in 0..3 {
                    let d = (p[c] - q[c]) as f64;
                    se += d * d;
                    rel += d * d / ((q[c] as f64).powi(2) + 1e-2);
                }
            }
            let n = (a.pixels.len() * 3) as f64;
            outln!("mean test {:?} reference {:?}", a.mean().to_array(), b.mean().to_array());
            outln!("rmse {:.6} relmse {:.6}", (se / n).sqrt(), rel / n);
            if let Some(size) = block {
                let rep = crate::compare::compare_blocks(&a, &b, size, 0.005)?;
                outln!("image mean ratio {:.4}; {} blocks of {size} px judged", rep.mean_ratio, rep.blocks.len());
                if let Some(w) = rep.worst() {
                    outln!(
                        "worst block ({}, {}): test {:.5} reference {:.5} rel {:+.4} (std err {:.5})",
                        w.at.0,
                        w.at.1,
                        w.test,
                        w.reference,
                        w.rel(),
                        w.std_err
                    );
                }
            }
            if let Some(o) = out {
                let mut d = a.clone();
                for (p, q) in d.pixels.iter_mut().zip(&b.pixels) {
                    *p = (*p - *q) * 4.0 + glam::Vec3::splat(0.2);
                }
                d.write_png(&o)?;
            }
            Ok(())
        }
    }
}

fn cmd_render(a: &RenderArgs) -> Result<()> {
    let cfg = a.config()?;
    crate::registry::validate(&cfg)?;
    let t0 = std::time::Instant::now();
    let scene = a.load()?;
    let load_s = t0.elapsed().as_secs_f64();
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let out = a.output.clone().unwrap_or_else(|| PathBuf::from(format!("results/{}.exr", scene.name)));
    if let Some(range) = a.sample_range {
        return render_range_cmd(a, scene, &cfg, range, &out);
    }
    let ntris = scene.triangles.len();
    let name = scene.name.clone();
    // Progressive renders with checkpoints also write the image at every checkpoint.
    let mut on_pass = |p: u32, _: f64, f: &crate::film::Film| {
        if cfg.checkpoint_every.is_some_and(|k| p.is_multiple_of(k))
            && let Err(e) = f.write_pair(&out)
        {
            eprintln!("warning: cannot write the image of pass {p}: {e:#}");
        }
    };
    let o = crate::pipeline::render_scene_observed(scene, &cfg, a.quiet, &a.aov, &mut on_pass)?;
    let (exr, png) = o.film.write_pair(&out).context("writing the image")?;
    let rays = o.rays();
    outln!(
        "scene {name}: {ntris} triangles, {}x{} px, {} spp, integrator {}, sampler {}, accel {}, rr {}, {} threads",
        o.film.width,
        o.film.height,
        cfg.spp,
        cfg.integrator,
        cfg.sampler,
        cfg.accel,
        cfg.rr,
        o.threads
    );
    outln!(
        "time: load {:.3} s, accel build {:.3} s, preprocess {:.3} s, render {:.3} s",
        load_s,
        o.timings.accel_build_s,
        o.timings.preprocess_s,
        o.timings.render_s
    );
    outln!(
        "rays: {} ({} closest-hit, {} shadow), {:.2} Mrays/s",
        rays.total_rays(),
        rays.rays,
        rays.shadow_rays,
        rays.total_rays() as f64 / o.timings.render_s.max(1e-9) / 1e6
    );
    if !o.extra.is_empty() {
        let parts: Vec<String> = o.extra.iter().map(|(k, v)| format!("{k} {}", fmt_num(*v))).collect();
        outln!("{}: {}", cfg.integrator, parts.join(", "));
    }
    for (name, img) in &o.aovs {
        let stem = out.with_extension("");
        let p = PathBuf::from(format!("{}.{name}.exr", stem.display()));
        let (e, g) = img.write_pair(&p).with_context(|| format!("writing aov {name}"))?;
        outln!("wrote {} and {}", e.display(), g.display());
    }
    if o.stats.nonfinite_samples > 0 {
        eprintln!("warning: {} sample(s) were NaN or infinite and were dropped", o.stats.nonfinite_samples);
    }
    outln!("wrote {} and {}", exr.display(), png.display());
    Ok(())
}

/// `render --sample-range A..B`: the part's exact sums (OUT.psum) and its preview.
fn render_range_cmd(
    a: &RenderArgs,
    scene: Scene,
    cfg: &RenderConfig,
    range: crate::accumulate::SampleRange,
    out: &std::path::Path,
) -> Result<()> {
    if !a.aov.is_empty() {
        anyhow::bail!("--aov cannot be combined with --sample-range");
    }
    crate::accumulate::check_range(cfg, range)?;
    let key = crate::experiment::reference_key(&scene, cfg)?;
    let name = scene.name.clone();
    let o = crate::accumulate::render_part(scene, cfg, range, &key, a.quiet)?;
    let psum = crate::accumulate::part_path(out);
    o.part.write(&psum).context("writing the part")?;
    let (exr, png) = crate::accumulate::part_preview(&o.part).write_pair(out).context("writing the preview")?;
    let h = &o.part.header;
    outln!(
        "scene {name}: {}x{} px, samples {range} of {} spp, integrator {}, {} threads",
        h.width,
        h.height,
        cfg.spp,
        cfg.integrator,
        o.threads
    );
    outln!(
        "time: accel build {:.3} s, preprocess {:.3} s, render {:.3} s",
        o.timings.accel_build_s,
        o.timings.preprocess_s,
        o.timings.render_s
    );
    if h.nonfinite_samples > 0 {
        eprintln!("warning: {} sample(s) were NaN or infinite and were dropped", h.nonfinite_samples);
    }
    outln!("wrote {} (exact sums; combine with `photonlab accumulate`), preview {} and {}", psum.display(), exr.display(), png.display());
    Ok(())
}

fn fmt_num(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 { format!("{}", v as i64) } else { format!("{v:.3}") }
}
