//! `bdpt`: bidirectional path tracing (Veach 1997; pbrt-v4's `BDPTIntegrator`), as
//! `vcm` with connections only: `spp` passes, each W·H light subpaths and one camera
//! subpath per pixel, every (s, t) technique under one MIS weight (`bdpt_mis`).

use super::mis::Heuristic;
use super::pass::run_pass;
use super::strategies::Strategies;
use super::{BidirParams, Ctx, Mode};
use crate::config::RenderConfig;
use crate::film::Film;
use crate::integrator::render::RenderStats;
use crate::rr::RussianRoulette;
use crate::world::World;
use anyhow::Result;
use glam::DVec3;
use std::collections::BTreeMap;
use std::time::Instant;

/// The bidirectional path tracer.
pub struct BdptIntegrator {
    cfg: RenderConfig,
    h: Heuristic,
    rr: Box<dyn RussianRoulette>,
    quiet: bool,
    counters: BTreeMap<String, f64>,
}

impl BdptIntegrator {
    /// Builds the integrator, reading `bdpt_mis`.
    pub fn new(cfg: &RenderConfig, r: &crate::param::Reader, rr: Box<dyn RussianRoulette>, quiet: bool) -> Result<Self> {
        let p = BidirParams::read(r)?;
        Ok(BdptIntegrator { cfg: cfg.clone(), h: Heuristic::parse(&p.bdpt_mis)?, rr, quiet, counters: BTreeMap::new() })
    }

    /// Renders `spp` passes; with `record`, also the per-technique sums.
    pub fn run(&mut self, world: &World, record: bool) -> Result<(Film, RenderStats, Strategies)> {
        let start = Instant::now();
        let cam = &world.scene.camera;
        let (w, h) = (cam.width, cam.height);
        let spp = self.cfg.spp;
        let ctx = Ctx::new(world, self.h, Mode::parse("bpt")?, self.cfg.depth_limit(), self.rr.as_ref(), 1.0, w * h, None);
        let cam_sampler = crate::sampler::make_any(&self.cfg.sampler, self.cfg.seed, Some(spp as u64))?;
        let light_sampler = cam_sampler.clone();
        let mut grid = super::grid::HashGrid::default();
        let mut sum = vec![DVec3::ZERO; (w * h) as usize];
        let mut stats = RenderStats::default();
        let mut strategies = Strategies::default();
        let (mut t_light, mut t_eye, mut vertices) = (0.0, 0.0, 0u64);
        let pb = crate::progress::progress_bar(spp as u64, self.quiet, "bdpt");
        for i in 0..spp {
            let out = run_pass(&ctx, &cam_sampler, &light_sampler, i as u64, record, false, &mut grid);
            for (s, p) in sum.iter_mut().zip(&out.pixels) {
                *s += *p;
            }
            stats.traversal.add(&out.traversal);
            stats.nonfinite_samples += out.nonfinite;
            (t_light, t_eye, vertices) = (t_light + out.t_light, t_eye + out.t_eye, vertices + out.light_vertices);
            strategies.add(&out.items, sum.len());
            pb.inc(1);
        }
        pb.finish_and_clear();
        let film = Film { width: w, height: h, pixels: sum.iter().map(|s| (*s / spp as f64).as_vec3()).collect() };
        stats.seconds = start.elapsed().as_secs_f64();
        let threads = rayon::current_num_threads() as f64;
        let paths = spp as f64 * (w * h) as f64;
        let c = &mut self.counters;
        c.insert("light_phase_s".into(), t_light);
        c.insert("camera_phase_s".into(), t_eye);
        c.insert("light_vertices".into(), vertices as f64);
        c.insert("light_subpaths_per_s_per_thread".into(), paths / t_light.max(1e-9) / threads);
        c.insert("camera_subpaths_per_s_per_thread".into(), paths / t_eye.max(1e-9) / threads);
        Ok((film, stats, strategies))
    }
}

impl crate::integrator::Integrator for BdptIntegrator {
    fn name(&self) -> &'static str {
        "bdpt"
    }
    /// Not used: the passes render the whole image ([`BdptIntegrator::run`]).
    fn li(
        &self,
        _: &World,
        _: &crate::geometry::Ray,
        _: &mut dyn crate::sampler::Sampler,
        _: &mut crate::accel::TraversalStats,
    ) -> crate::math::Color {
        crate::math::Color::ZERO
    }
    /// `strategies` is rendered by [`crate::integrator::Integrator::render_aov`]; accepted here so
    /// front ends can ask which integrators have it.
    fn set_output(&mut self, aov: &str) -> Result<()> {
        if aov == "strategies" {
            return Ok(());
        }
        anyhow::bail!("integrator `bdpt` has no extra image `{aov}` (known: strategies)")
    }
    fn render_progressive(
        &mut self,
        world: &World,
        _on_pass: crate::integrator::progressive::OnPass,
    ) -> Option<Result<(Film, RenderStats)>> {
        Some(self.run(world, false).map(|(f, s, _)| (f, s)))
    }
    fn render_aov(&mut self, world: &World, aov: &str) -> Option<Result<Vec<(String, Film)>>> {
        (aov == "strategies").then(|| {
            let (w, h) = (world.scene.camera.width, world.scene.camera.height);
            self.run(world, true).map(|(_, _, s)| s.images(w, h, self.cfg.spp))
        })
    }
    fn stats(&self) -> BTreeMap<String, f64> {
        self.counters.clone()
    }
}
