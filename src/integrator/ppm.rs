//! `ppm`: probabilistic progressive photon mapping (Knaus & Zwicker 2011).
//!
//! Pass i is an independent render of the `photon` integrator — its own photon maps
//! and camera samples from the pass seed hash(seed, i), every gather method and filter
//! as configured — with the global and caustic search radii r_i shrinking by
//! r²_{i+1} = r²_i (i + α) / (i + 1) from `max_radius` / `caustic_max_radius`; the
//! image after p passes is the mean of the p pass images. No per-pixel statistics.
//!
//! With a fixed radius the estimate of each pass is biased by the kernel's blur; the
//! shrinking radius makes the mean converge (variance O(p^−α), bias O(p^(α−1))). The
//! photon integrator gathers the k nearest photons within r_i, so a pass is a
//! fixed-radius estimate once r_i is below the k-th neighbour's distance (raise `k`
//! for that to hold from the first pass). The irradiance cache's interpolation error
//! (`ic_tolerance`) does not shrink with the passes: use `gather = "direct"` or
//! `"final_gather"` for an estimate that converges to the exact image.

use super::Integrator;
use super::photon::{Output, PhotonIntegrator, PhotonSetup};
use super::progressive::{Budget, OnPass, ProgressiveParams, load_checkpoint, next_radius2, save_checkpoint};
use crate::config::RenderConfig;
use crate::film::Film;
use crate::integrator::render::{RenderStats, render};
use crate::math::hash_words;
use crate::world::World;
use anyhow::Result;
use glam::DVec3;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::time::Instant;

/// The common keys and photon settings of pass `i` (from 1) with radii `r` (global)
/// and `rc` (caustic): an independent `photon` render with its own seed.
pub fn pass_setup(
    cfg: &RenderConfig,
    base: &PhotonSetup,
    prog: &ProgressiveParams,
    i: u32,
    r: f32,
    rc: f32,
    has_specular: bool,
) -> (RenderConfig, PhotonSetup) {
    let mut c = cfg.clone();
    c.integrator = "photon".into();
    c.seed = hash_words(&[cfg.seed, i as u64, 0x9916]);
    c.record_passes = Vec::new();
    c.params = Default::default();
    let mut s = base.clone();
    s.p.max_radius = Some(r);
    s.p.caustic_max_radius = Some(rc);
    if prog.photons_per_pass.is_some() {
        s.p.emit_photons = prog.photons_per_pass;
    }
    if !has_specular {
        s.p.caustic_photons = 0;
    }
    (c, s)
}

/// The probabilistic progressive photon-mapping integrator.
pub struct PpmIntegrator {
    /// What every pass's photon integrator writes (e.g. `PhotonsDirect`, the direct
    /// visualisation of the direct map, used by the statistical tests).
    pub output: Output,
    cfg: RenderConfig,
    prog: ProgressiveParams,
    photon: PhotonSetup,
    quiet: bool,
    counters: BTreeMap<String, f64>,
}

impl PpmIntegrator {
    /// Builds the integrator (checking its settings).
    pub fn new(cfg: &RenderConfig, r: &crate::param::Reader, quiet: bool) -> Result<Self> {
        let prog = ProgressiveParams::read_checked(cfg, r)?;
        let photon = PhotonSetup::read(cfg, r)?;
        Ok(PpmIntegrator { output: Output::All, cfg: cfg.clone(), prog, photon, quiet, counters: BTreeMap::new() })
    }

    fn run(&mut self, world: &World, on_pass: OnPass) -> Result<(Film, RenderStats)> {
        let cam = &world.scene.camera;
        let budget = Budget::new(&self.prog);
        let r_scene = world.lights.scene_radius;
        let mut r2 = self.photon.p.max_radius.unwrap_or(0.1 * r_scene) as f64;
        r2 *= r2;
        let mut rc2 = self.photon.p.caustic_max_radius.unwrap_or(0.025 * r_scene) as f64;
        rc2 *= rc2;
        let has_specular = world.scene.tri_material.iter().any(|&m| world.scene.materials[m as usize].bsdf.has_delta());
        let alpha = self.prog.alpha as f64;
        let mut sum = vec![DVec3::ZERO; (cam.width * cam.height) as usize];
        let mut film = Film::new(cam.width, cam.height);
        let mut stats = RenderStats::default();
        let (mut t_pre, mut t_render) = (0.0, 0.0);
        let mut emitted = 0.0;
        let mut pass = 0u32;
        // Checkpoint state: pass sums, r², r_c² (f64 bit patterns).
        type State = (Vec<[u64; 3]>, u64, u64);
        if let Some((done, (saved, a, b))) = load_checkpoint::<State>(&self.cfg, &self.prog, world)? {
            if saved.len() != sum.len() {
                anyhow::bail!("checkpoint holds {} pixels, the image has {}", saved.len(), sum.len());
            }
            sum = saved.iter().map(|v| DVec3::from_array(v.map(f64::from_bits))).collect();
            (r2, rc2, pass) = (f64::from_bits(a), f64::from_bits(b), done);
            let inv = 1.0 / pass.max(1) as f64;
            film.pixels.par_iter_mut().zip(sum.par_iter()).for_each(|(o, s)| *o = (*s * inv).as_vec3());
        }
        let pb = crate::progress::progress_bar(if budget.max_passes == u32::MAX { 0 } else { budget.max_passes as u64 }, self.quiet, "ppm");
        while budget.more(pass) {
            let i = pass + 1;
            let (pcfg, setup) = pass_setup(&self.cfg, &self.photon, &self.prog, i, r2.sqrt() as f32, rc2.sqrt() as f32, has_specular);
            let mut integrator = PhotonIntegrator::from_setup(&pcfg, setup, crate::rr::make(&pcfg.rr)?, true);
            integrator.output = self.output;
            let t0 = Instant::now();
            integrator.preprocess(world)?;
            t_pre += t0.elapsed().as_secs_f64();
            let sampler = crate::sampler::make(&pcfg.sampler, pcfg.seed, Some(pcfg.spp as u64))?;
            let (img, st) = render(world, &integrator, sampler.as_ref(), pcfg.spp, true);
            t_render += st.seconds;
            stats.traversal.add(&st.traversal);
            stats.nonfinite_samples += st.nonfinite_samples;
            emitted += integrator.stats().get("photons_emitted").copied().unwrap_or(0.0);
            sum.par_iter_mut().zip(img.pixels.par_iter()).for_each(|(s, p)| *s += p.as_dvec3());
            let inv = 1.0 / i as f64;
            film.pixels.par_iter_mut().zip(sum.par_iter()).for_each(|(o, s)| *o = (*s * inv).as_vec3());
            pass = i;
            pb.inc(1);
            on_pass(pass, budget.elapsed(), &film);
            r2 = next_radius2(r2, i, alpha);
            rc2 = next_radius2(rc2, i, alpha);
            if self.prog.checkpoint_every.is_some_and(|k| pass.is_multiple_of(k)) {
                let state: State = (sum.iter().map(|v| v.to_array().map(f64::to_bits)).collect(), r2.to_bits(), rc2.to_bits());
                save_checkpoint(&self.cfg, &self.prog, world, pass, &state)?;
            }
        }
        pb.finish_and_clear();
        stats.seconds = budget.elapsed();
        let c = &mut self.counters;
        c.insert("passes".into(), pass as f64);
        c.insert("photons_emitted".into(), emitted);
        c.insert("photon_and_cache_s".into(), t_pre);
        c.insert("pass_render_s".into(), t_render);
        c.insert("passes_per_s".into(), pass as f64 / stats.seconds.max(1e-9));
        c.insert("final_radius".into(), r2.sqrt());
        Ok((film, stats))
    }
}

super::progressive::progressive_integrator!(PpmIntegrator, "ppm");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pass_configs_are_independent_photon_renders() {
        let cfg = RenderConfig { integrator: "ppm".into(), ..Default::default() }.with("photons_per_pass", 5000).with("passes", 8);
        let r = crate::param::Reader::new(&cfg.params);
        let ppm = PpmIntegrator::new(&cfg, &r, true).unwrap();
        let (a, sa) = pass_setup(&cfg, &ppm.photon, &ppm.prog, 1, 2.0, 0.5, false);
        let (b, _) = pass_setup(&cfg, &ppm.photon, &ppm.prog, 2, 1.0, 0.25, false);
        assert_eq!(a.integrator, "photon");
        assert_ne!(a.seed, b.seed);
        assert!(a.params.0.is_empty());
        assert_eq!(
            (sa.p.max_radius, sa.p.caustic_max_radius, sa.p.emit_photons, sa.p.caustic_photons),
            (Some(2.0), Some(0.5), Some(5000), 0)
        );
        let err = |c: RenderConfig| crate::registry::make_integrator(&c).err().unwrap().to_string();
        assert!(err(cfg.clone().with("sppm_radius", 1.0)).contains("sppm_radius"));
        assert!(err(cfg.with("gather", "nope")).contains("nope"));
    }
}
