//! Scene → accelerator → (pre-pass) → render pass → film, with the time of each
//! phase. Used by `photonlab render` and the experiment runner.

use crate::accel::TraversalStats;
use crate::config::RenderConfig;
use crate::film::Film;
use crate::integrator::Integrator;
use crate::integrator::render::{RenderStats, render};
use crate::registry;
use crate::sampler::Sampler;
use crate::scene::Scene;
use crate::world::World;
use anyhow::{Context, Result};
use std::time::Instant;

/// Wall time of each phase in seconds.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Timings {
    /// Acceleration-structure build.
    pub accel_build_s: f64,
    /// Integrator pre-pass (photon tracing etc.).
    pub preprocess_s: f64,
    /// Render pass.
    pub render_s: f64,
}

/// Result of a full render.
pub struct RenderOutcome {
    /// The image.
    pub film: Film,
    /// Phase timings.
    pub timings: Timings,
    /// Render-pass counters.
    pub stats: RenderStats,
    /// Memory of the accelerator in bytes.
    pub accel_bytes: usize,
    /// Threads used.
    pub threads: usize,
    /// Integrator counters and phase times (photons, cache entries, …).
    pub extra: std::collections::BTreeMap<String, f64>,
    /// Extra images requested by name.
    pub aovs: Vec<(String, Film)>,
}

impl RenderOutcome {
    /// All rays traced (closest-hit and shadow).
    pub fn rays(&self) -> TraversalStats {
        self.stats.traversal
    }
}

/// Builds a rayon pool with `threads` workers (0 = all cores).
pub fn thread_pool(threads: usize) -> Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("cannot start worker threads")
}

/// Renders `scene` with `cfg` (validated first). The scene's camera resolution is
/// replaced by `cfg.resolution` when given.
pub fn render_scene(scene: Scene, cfg: &RenderConfig, quiet: bool) -> Result<RenderOutcome> {
    render_scene_with_aovs(scene, cfg, quiet, &[])
}

/// As [`render_scene`], also rendering the named extra images (AOVs) with the same
/// pre-pass. `cache` marks the integrator's debug points (irradiance-cache entries)
/// over a dimmed copy of the image.
pub fn render_scene_with_aovs(scene: Scene, cfg: &RenderConfig, quiet: bool, aovs: &[String]) -> Result<RenderOutcome> {
    render_scene_observed(scene, cfg, quiet, aovs, &mut |_, _, _| {})
}

/// As [`render_scene_with_aovs`]; progressive integrators (`sppm`, `ppm`) call
/// `on_pass` with the image after every pass (others never call it).
pub fn render_scene_observed(
    scene: Scene,
    cfg: &RenderConfig,
    quiet: bool,
    aovs: &[String],
    on_pass: crate::integrator::progressive::OnPass,
) -> Result<RenderOutcome> {
    let scene = configured_scene(scene, cfg)?;
    let pool = thread_pool(cfg.threads)?;
    let threads = pool.current_num_threads();
    pool.install(|| {
        let Prepared { world, mut integrator, sampler, accel_build_s, accel_bytes, preprocess_s } = prepare(scene, cfg, quiet)?;
        crate::progress::check_cancel()?;
        let (film, stats) = match integrator.render_progressive(&world, on_pass) {
            Some(done) => done?,
            None => render(&world, integrator.as_ref(), sampler.as_ref(), cfg.spp, quiet),
        };
        // A cancelled render's image is incomplete: never hand it out.
        crate::progress::check_cancel()?;
        let mut extra_images = Vec::new();
        for name in aovs {
            if name == "cache" {
                extra_images.push((name.clone(), mark_points(&world, &film, &integrator.debug_points())));
                continue;
            }
            if let Some(images) = integrator.render_aov(&world, name) {
                extra_images.extend(images?.into_iter().map(|(n, f)| (format!("{name}-{n}"), f)));
                continue;
            }
            integrator.set_output(name)?;
            let (img, _) = render(&world, integrator.as_ref(), sampler.as_ref(), cfg.spp, quiet);
            crate::progress::check_cancel()?;
            extra_images.push((name.clone(), img));
        }
        Ok(RenderOutcome {
            film,
            timings: Timings { accel_build_s, preprocess_s, render_s: stats.seconds },
            stats,
            accel_bytes,
            threads,
            extra: integrator.stats(),
            aovs: extra_images,
        })
    })
}

/// A world ready to render: accelerator built, integrator pre-pass done.
pub struct Prepared {
    /// Scene, accelerator and lights.
    pub world: World,
    /// The integrator after its pre-pass.
    pub integrator: Box<dyn Integrator>,
    /// The camera-sample prototype (seed `cfg.seed`, `cfg.spp` samples).
    pub sampler: Box<dyn Sampler>,
    /// Accelerator build time.
    pub accel_build_s: f64,
    /// Accelerator memory.
    pub accel_bytes: usize,
    /// Pre-pass time.
    pub preprocess_s: f64,
}

/// Validates `cfg` and applies its resolution override to the scene's camera.
pub fn configured_scene(mut scene: Scene, cfg: &RenderConfig) -> Result<Scene> {
    registry::validate(cfg)?;
    if let Some([w, h]) = cfg.resolution {
        scene.camera = scene.camera.with_resolution(w, h)?;
    }
    Ok(scene)
}

/// Builds the accelerator, the world, the integrator and the camera sampler and runs
/// the integrator's pre-pass (call inside the worker pool).
pub fn prepare(scene: Scene, cfg: &RenderConfig, quiet: bool) -> Result<Prepared> {
    let t0 = Instant::now();
    let accel = registry::make_accel(&cfg.accel, &scene.triangles)?;
    let accel_build_s = t0.elapsed().as_secs_f64();
    let accel_bytes = accel.memory_bytes();
    let world = World::new(scene, accel)?;
    let mut integrator = registry::make_integrator_with(cfg, quiet)?;
    let sampler = registry::make_sampler(&cfg.sampler, cfg.seed, Some(cfg.spp as u64))?;
    let t1 = Instant::now();
    integrator.preprocess(&world)?;
    Ok(Prepared { world, integrator, sampler, accel_build_s, accel_bytes, preprocess_s: t1.elapsed().as_secs_f64() })
}

/// A dimmed copy of `film` with a red dot at every visible point of `points`
/// (like the design report's figure 3 of irradiance-cache entries).
fn mark_points(world: &World, film: &Film, points: &[glam::Vec3]) -> Film {
    let mut out = film.clone();
    for p in out.pixels.iter_mut() {
        *p *= 0.35;
    }
    let cam = &world.scene.camera;
    let mut stats = TraversalStats::default();
    for &p in points {
        let Some((x, y)) = cam.project(p) else { continue };
        if x < 0.0 || y < 0.0 || x >= film.width as f32 || y >= film.height as f32 {
            continue;
        }
        let d = p - cam.eye;
        let ray = crate::geometry::Ray::new(cam.eye, d);
        if world.accel.occluded(&ray, 1.0 - 1e-3, &mut stats) {
            continue;
        }
        out.pixels[(y as u32 * film.width + x as u32) as usize] = crate::math::Color::new(1.0, 0.05, 0.05);
    }
    out
}
