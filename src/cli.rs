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
    /// List every strategy family, plug-in and parameter with its default (from the plug-ins' own declarations).
    Plugins {
        /// Markdown tables (docs/plugins.md is this output).
        #[arg(long)]
        markdown: bool,
        /// One Markdown table row per family with its plug-ins (the README's table is this output).
        #[arg(long, conflicts_with = "markdown")]
        glance: bool,
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
    /// Russian roulette: `off`, `fixed[:q]`, `albedo` or `throughput[:min_depth]`; default `auto` (`throughput:5` for `path`, `throughput` from bounce 3 otherwise).
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
    /// Set a plug-in parameter, KEY=VALUE (repeatable; `photonlab plugins` lists them
    /// all). Every parameter is also accepted as `--KEY VALUE` (dashes or underscores),
    /// e.g. `--gather final_gather --ic-tolerance 0.2 --resume`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Extra images: direct, caustic, indirect (path, photon); photons-direct,
    /// photons-indirect, photons-caustic, cache (photon); strategies (bdpt, vcm: one
    /// image per technique, weighted and unweighted). Repeat or comma-separate.
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
        if let Some(r) = &self.resolution {
            c.resolution = Some(parse_resolution(r)?);
        }
        let cat = crate::registry::catalogue();
        for kv in &self.set {
            let (k, v) = kv.split_once('=').ok_or_else(|| anyhow::anyhow!("--set `{kv}`: expected KEY=VALUE"))?;
            c.set_text(k.trim(), v.trim(), &cat)?;
        }
        // Progressive renders keep their state beside the image.
        let wants_state = ["checkpoint_every", "resume"].iter().any(|k| c.params.contains(k));
        if let Some(o) = &self.output
            && wants_state
            && !c.params.contains("checkpoint_file")
        {
            c.params.set("checkpoint_file", format!("{}.checkpoint.json", o.with_extension("").display()));
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

/// Rewrites `render --KEY VALUE` / `--KEY=VALUE` for any declared plug-in parameter
/// (dashes or underscores) into `--set KEY=VALUE`, so every parameter has a flag
/// without a copy of it here; `--KEY` alone sets a boolean parameter to true.
/// Other arguments pass through unchanged.
pub fn expand_param_flags(args: Vec<String>) -> Vec<String> {
    if args.get(1).map(String::as_str) != Some("render") {
        return args;
    }
    let cat = crate::registry::catalogue();
    let mut out = Vec::with_capacity(args.len());
    let mut it = args.into_iter().peekable();
    while let Some(a) = it.next() {
        let Some(flag) = a.strip_prefix("--") else {
            out.push(a);
            continue;
        };
        let (name, inline) = match flag.split_once('=') {
            Some((n, v)) => (n.replace('-', "_"), Some(v.to_string())),
            None => (flag.replace('-', "_"), None),
        };
        let Some(def) = cat
            .families
            .iter()
            .flat_map(|f| f.plugins.iter().flat_map(|p| p.params.iter()))
            .chain(cat.groups.iter().flat_map(|g| g.params.iter()))
            .find(|d| d.name == name)
        else {
            out.push(a);
            continue;
        };
        let value = match inline {
            Some(v) => v,
            None if def.flag => match it.peek().map(String::as_str) {
                Some("true" | "false") => it.next().unwrap_or_default(),
                _ => "true".to_string(),
            },
            None => match it.next() {
                Some(v) => v,
                None => {
                    out.push(a);
                    continue;
                }
            },
        };
        out.push("--set".into());
        out.push(format!("{name}={value}"));
    }
    out
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
        Command::Plugins { markdown, glance } => {
            let cat = crate::registry::catalogue();
            let out = if glance {
                cat.glance()
            } else if markdown {
                cat.markdown()
            } else {
                cat.text()
            };
            outln!("{}", out.trim_end());
            Ok(())
        }
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
    let mut cfg = a.config()?;
    crate::registry::validate(&cfg)?;
    let t0 = std::time::Instant::now();
    let scene = a.load()?;
    let load_s = t0.elapsed().as_secs_f64();
    // A scene's suggested sample count (Mitsuba's `sample_count`) unless --spp is given.
    if a.spp.is_none()
        && let Some(n) = scene.default_spp
    {
        cfg.spp = n;
    }
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
    let checkpoint_every = cfg.params.raw("checkpoint_every").and_then(toml::Value::as_integer).and_then(|k| u32::try_from(k).ok());
    let mut on_pass = |p: u32, _: f64, f: &crate::film::Film| {
        if checkpoint_every.is_some_and(|k| p.is_multiple_of(k))
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
