//! Command-line front end: `render`, `scene export`, `bench`.

use crate::config::{RenderConfig, parse_resolution};
use crate::pipeline::render_scene;
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
    Render(RenderArgs),
    /// Scene utilities.
    #[command(subcommand)]
    Scene(SceneCommand),
    /// Benchmarks (release builds).
    #[command(subcommand)]
    Bench(crate::bench::BenchCommand),
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
    /// Sampler: random | halton | hammersley.
    #[arg(long)]
    pub sampler: Option<String>,
    /// Accelerator: none | bvh.
    #[arg(long)]
    pub accel: Option<String>,
    /// Russian roulette: off | fixed[:q] | albedo | throughput[:min_depth].
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
            println!("wrote {}", toml.display());
            Ok(())
        }
        Command::Bench(b) => crate::bench::run(b),
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
    if scene.dropped_degenerate > 0 {
        eprintln!("note: dropped {} zero-area triangle(s)", scene.dropped_degenerate);
    }
    let out = a.output.clone().unwrap_or_else(|| PathBuf::from(format!("results/{}.exr", scene.name)));
    let ntris = scene.triangles.len();
    let name = scene.name.clone();
    let o = render_scene(scene, &cfg, a.quiet)?;
    let (exr, png) = o.film.write_pair(&out).context("writing the image")?;
    let rays = o.rays();
    println!(
        "scene {name}: {ntris} triangles, {}x{} px, {} spp, integrator {}, sampler {}, accel {}, rr {}, {} threads",
        o.film.width, o.film.height, cfg.spp, cfg.integrator, cfg.sampler, cfg.accel, cfg.rr, o.threads
    );
    println!(
        "time: load {:.3} s, accel build {:.3} s, preprocess {:.3} s, render {:.3} s",
        load_s, o.timings.accel_build_s, o.timings.preprocess_s, o.timings.render_s
    );
    println!(
        "rays: {} ({} closest-hit, {} shadow), {:.2} Mrays/s",
        rays.total_rays(),
        rays.rays,
        rays.shadow_rays,
        rays.total_rays() as f64 / o.timings.render_s.max(1e-9) / 1e6
    );
    if o.stats.nonfinite_samples > 0 {
        eprintln!("warning: {} sample(s) were NaN or infinite and were dropped", o.stats.nonfinite_samples);
    }
    println!("wrote {} and {}", exr.display(), png.display());
    Ok(())
}
