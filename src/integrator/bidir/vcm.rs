//! `vcm`: vertex connection and merging (Georgiev et al. 2012; Hachisuka et al.'s
//! unified path sampling), progressive as SmallVCM's `VertexCM`: pass i (from 1)
//! merges within r_i = r₀ · i^((α−1)/2), α = 0.75 unless `alpha` is set, r₀ =
//! `vcm_radius` or a fraction of the scene's bounding radius; the image after p passes
//! is the mean of the passes' estimates. A pass traces `vcm_light_paths` × W·H light
//! subpaths (½ by default) and joins each camera vertex to `vcm_connect_draws` vertices
//! drawn from all of the pass's light vertices (1 by default; 0: every vertex of its own
//! light subpath), and merges at the first non-delta camera vertex only (`vcm_merge =
//! "first"`, the MIS weights counting merging only there; `"all"`: at every non-delta
//! one — with `vcm_light_paths = 1`, `vcm_connect_draws = 0` SmallVCM's pass). `vcm_mode` restricts
//! the techniques for ablations (SmallVCM's algorithms): `bpt` connections only, `ppm`
//! merging at the first non-delta camera vertex only (no MIS), `lt` light tracing only.

use super::mis::Heuristic;
use super::pass::run_pass;
use super::strategies::Strategies;
use super::{BidirParams, Ctx, Mode};
use crate::config::RenderConfig;
use crate::film::Film;
use crate::integrator::progressive::{Budget, OnPass, ProgressiveParams, load_checkpoint, save_checkpoint};
use crate::integrator::render::RenderStats;
use crate::rr::RussianRoulette;
use crate::world::World;
use anyhow::{Result, bail};
use glam::DVec3;
use std::collections::BTreeMap;

/// α when `alpha` is not set (SmallVCM's default).
pub const DEFAULT_ALPHA: f32 = 0.75;
/// r₀ as a fraction of the scene's bounding-sphere radius when `vcm_radius` is unset.
pub const DEFAULT_RADIUS_FRACTION: f32 = 0.01;

crate::params! {
    /// Parameters of the `vcm` integrator.
    pub struct VcmParams {
        /// Techniques: `vcm` (connections and merging), `bpt` (connections), `ppm` (merging at the first diffuse vertex), `lt` (light tracing).
        vcm_mode: String = "vcm",
        /// Initial merging radius r₀ (scene units); `auto` = 0.01 × the scene's bounding radius.
        vcm_radius: Option<f32> = "auto",
        /// Light subpaths per pass as a fraction of the pixel count (1 = one per pixel, as SmallVCM); pixel p's camera subpath is joined to light subpath p mod their number.
        vcm_light_paths: f32 = "0.5",
        /// Light vertices each camera vertex is joined to, drawn (stratified) from all light vertices of the pass (Davidovič et al. 2014's light vertex cache); 0 = every vertex of its own light subpath (SmallVCM).
        vcm_connect_draws: u32 = "1",
        /// Camera vertices merged with the pass's light vertices: the `first` non-delta one only (the MIS weights count merging only there) or `all` non-delta ones (SmallVCM).
        vcm_merge: String = "first",
    }
}

/// Light subpaths of the pilot that measures light vertices per subpath.
const PILOT_PATHS: u64 = 4096;
/// First light stream of the pilot (above any pass's light subpaths).
const PILOT_STREAMS: u64 = 1 << 40;

/// The vertex connection and merging integrator.
pub struct VcmIntegrator {
    cfg: RenderConfig,
    h: Heuristic,
    mode: Mode,
    radius: Option<f32>,
    light_fraction: f32,
    draws: u32,
    alpha: f32,
    prog: ProgressiveParams,
    rr: Box<dyn RussianRoulette>,
    quiet: bool,
    counters: BTreeMap<String, f64>,
}

impl VcmIntegrator {
    /// Builds the integrator (checking its settings).
    pub fn new(cfg: &RenderConfig, r: &crate::param::Reader, rr: Box<dyn RussianRoulette>, quiet: bool) -> Result<Self> {
        let prog = ProgressiveParams::read_checked(cfg, r)?;
        let p = VcmParams::read(r)?;
        let b = BidirParams::read(r)?;
        if prog.photons_per_pass.is_some() {
            bail!("vcm sets its light subpaths per pass with vcm_light_paths; photons_per_pass does not apply");
        }
        if let Some(r) = p.vcm_radius
            && !(r > 0.0 && r.is_finite())
        {
            bail!("vcm_radius must be positive and finite, got {r}");
        }
        if p.vcm_connect_draws > 64 {
            bail!("vcm_connect_draws must be at most 64, got {}", p.vcm_connect_draws);
        }
        if !(p.vcm_light_paths > 0.0 && p.vcm_light_paths <= 64.0) {
            bail!("vcm_light_paths must be in (0, 64] (a fraction of the pixel count), got {}", p.vcm_light_paths);
        }
        let alpha = if cfg.params.contains("alpha") { prog.alpha } else { DEFAULT_ALPHA };
        Ok(VcmIntegrator {
            cfg: cfg.clone(),
            h: Heuristic::parse(&b.bdpt_mis)?,
            mode: Mode::parse(&p.vcm_mode)?.with_merge(&p.vcm_merge)?,
            radius: p.vcm_radius,
            light_fraction: p.vcm_light_paths,
            draws: p.vcm_connect_draws,
            alpha,
            prog,
            rr,
            quiet,
            counters: BTreeMap::new(),
        })
    }

    /// Merging radius of pass `i` (from 1).
    pub fn radius(r0: f32, alpha: f32, i: u32) -> f32 {
        (r0 as f64 * (i as f64).powf(0.5 * (alpha as f64 - 1.0))).max(1e-7) as f32
    }

    /// Light vertices stored per light subpath, from a pilot of [`PILOT_PATHS`] light
    /// subpaths on streams no pass uses: the same for every run of a scene and
    /// configuration (resumed or not, any thread count), and independent of the
    /// passes' own samples, so the MIS weights that use it stay exact.
    fn light_vertices_per_path(&self, world: &World, sampler: &crate::sampler::AnySampler, r0: f32) -> f32 {
        let ctx = Ctx::new(world, self.h, self.mode, self.cfg.depth_limit(), self.rr.as_ref(), r0, 1, None);
        let (mut vertices, mut splats, mut stats) = (Vec::new(), Vec::new(), crate::accel::TraversalStats::default());
        let mut s = sampler.clone();
        let mut count = 0usize;
        crate::sampler::with_sampler!(&mut s, s => {
            for j in 0..PILOT_PATHS {
                super::subpath::trace_light(&ctx, s, super::pass::light_stream(PILOT_STREAMS + j), 0, &mut vertices, &mut splats, &mut stats);
                count += vertices.len();
                vertices.clear();
                splats.clear();
            }
        });
        (count as f32 / PILOT_PATHS as f32).max(1.0 / PILOT_PATHS as f32)
    }

    fn run_passes(&mut self, world: &World, on_pass: OnPass, record: bool) -> Result<(Film, RenderStats, Strategies, u32)> {
        let cam = &world.scene.camera;
        let (w, h) = (cam.width, cam.height);
        let npix = (w * h) as usize;
        let budget = Budget::new(&self.prog);
        let counts = (budget.max_passes != u32::MAX).then_some(budget.max_passes as u64);
        let cam_sampler = crate::sampler::make_any(&self.cfg.sampler, self.cfg.seed, counts)?;
        let light_paths = ((npix as f64 * self.light_fraction as f64).round() as u64).clamp(1, u32::MAX as u64 / 2) as u32;
        let light_sampler = cam_sampler.clone();
        let mut grid = super::grid::HashGrid::default();
        let r0 = self.radius.unwrap_or(DEFAULT_RADIUS_FRACTION * world.lights.scene_radius);
        let joins = (self.draws > 0 && self.mode.connect).then(|| (self.draws, self.light_vertices_per_path(world, &light_sampler, r0)));
        let mut sum = vec![DVec3::ZERO; npix];
        let mut pass = 0u32;
        let mut film = Film::new(w, h);
        if !record && let Some((done, saved)) = load_checkpoint::<Vec<[u64; 3]>>(&self.cfg, &self.prog, world)? {
            if saved.len() != npix {
                bail!("checkpoint holds {} pixels, the image has {npix}", saved.len());
            }
            sum = saved.iter().map(|b| DVec3::new(f64::from_bits(b[0]), f64::from_bits(b[1]), f64::from_bits(b[2]))).collect();
            pass = done;
            film.pixels = sum.iter().map(|s| (*s / pass.max(1) as f64).as_vec3()).collect();
        }
        let mut stats = RenderStats::default();
        let mut strategies = Strategies::default();
        let (mut t_light, mut t_grid, mut t_eye, mut vertices, mut run) = (0.0, 0.0, 0.0, 0u64, 0u32);
        let pb = crate::progress::progress_bar(counts.unwrap_or(0), self.quiet, "vcm");
        while budget.more(pass) {
            let r = Self::radius(r0, self.alpha, pass + 1);
            let ctx = Ctx::new(world, self.h, self.mode, self.cfg.depth_limit(), self.rr.as_ref(), r, light_paths, joins);
            let out = run_pass(&ctx, &cam_sampler, &light_sampler, pass as u64, record, &mut grid);
            for (s, p) in sum.iter_mut().zip(&out.pixels) {
                *s += *p;
            }
            stats.traversal.add(&out.traversal);
            stats.nonfinite_samples += out.nonfinite;
            (t_light, t_grid, t_eye, vertices) =
                (t_light + out.t_light, t_grid + out.t_grid, t_eye + out.t_eye, vertices + out.light_vertices);
            strategies.add(&out.items, npix);
            pass += 1;
            run += 1;
            pb.inc(1);
            film.pixels = sum.iter().map(|s| (*s / pass as f64).as_vec3()).collect();
            on_pass(pass, budget.elapsed(), &film);
            if !record {
                save_checkpoint(
                    &self.cfg,
                    &self.prog,
                    world,
                    pass,
                    &sum.iter().map(|s| [s.x.to_bits(), s.y.to_bits(), s.z.to_bits()]).collect::<Vec<_>>(),
                )?;
            }
        }
        pb.finish_and_clear();
        stats.seconds = budget.elapsed();
        let threads = rayon::current_num_threads() as f64;
        let paths = run as f64 * npix as f64;
        let lpaths = run as f64 * light_paths as f64;
        let c = &mut self.counters;
        c.insert("passes".into(), pass as f64);
        c.insert("light_phase_s".into(), t_light);
        c.insert("grid_s".into(), t_grid);
        c.insert("camera_phase_s".into(), t_eye);
        c.insert("light_vertices".into(), vertices as f64);
        c.insert("final_radius".into(), Self::radius(r0, self.alpha, pass.max(1)) as f64);
        c.insert("light_subpaths_per_pass".into(), light_paths as f64);
        if let Some((_, lbar)) = joins {
            c.insert("pilot_light_vertices_per_subpath".into(), lbar as f64);
        }
        c.insert("light_subpaths_per_s_per_thread".into(), lpaths / t_light.max(1e-9) / threads);
        c.insert("camera_subpaths_per_s_per_thread".into(), paths / t_eye.max(1e-9) / threads);
        c.insert("passes_per_s".into(), run as f64 / stats.seconds.max(1e-9));
        Ok((film, stats, strategies, pass))
    }
}

impl crate::integrator::Integrator for VcmIntegrator {
    fn name(&self) -> &'static str {
        "vcm"
    }
    /// Not used: the passes render the whole image.
    fn li(
        &self,
        _: &World,
        _: &crate::geometry::Ray,
        _: &mut dyn crate::sampler::Sampler,
        _: &mut crate::accel::TraversalStats,
    ) -> crate::math::Color {
        crate::math::Color::ZERO
    }
    fn is_progressive(&self) -> bool {
        true
    }
    /// `strategies` is rendered by [`crate::integrator::Integrator::render_aov`]; accepted here so
    /// front ends can ask which integrators have it.
    fn set_output(&mut self, aov: &str) -> Result<()> {
        if aov == "strategies" {
            return Ok(());
        }
        anyhow::bail!("integrator `vcm` has no extra image `{aov}` (known: strategies)")
    }
    fn render_progressive(&mut self, world: &World, on_pass: OnPass) -> Option<Result<(Film, RenderStats)>> {
        Some(self.run_passes(world, on_pass, false).map(|(f, s, _, _)| (f, s)))
    }
    fn render_aov(&mut self, world: &World, aov: &str) -> Option<Result<Vec<(String, Film)>>> {
        (aov == "strategies").then(|| {
            let (w, h) = (world.scene.camera.width, world.scene.camera.height);
            self.run_passes(world, &mut |_, _, _| {}, true).map(|(_, _, s, passes)| s.images(w, h, passes))
        })
    }
    fn stats(&self) -> BTreeMap<String, f64> {
        self.counters.clone()
    }
}
