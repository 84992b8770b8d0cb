//! `ppm`: probabilistic progressive photon mapping (Knaus & Zwicker 2011).
//!
//! Pass i is an independent render of the `photon` integrator — its own photon maps
//! and camera samples from the pass seed hash(seed, i), every gather method and filter
//! as configured — with the global and caustic search radii r_i shrinking by
//! r²_{i+1} = r²_i (i + α) / (i + 1); the image after p passes is the mean of the p
//! pass images. No per-pixel statistics.
//!
//! Every estimate of a pass takes all photons within r_i ([`crate::photon::within`]),
//! as Knaus & Zwicker's estimator does: its bias is the kernel's blur over r_i, so the
//! mean converges (variance O(p^−α), bias O(p^(α−1))) from the first pass. (A pass
//! that took the k nearest photons within r_i would keep the k-th neighbour's radius,
//! and its bias, until r_i fell below it — hundreds of passes; `ppm_knn` restores that
//! for comparisons.) The first radii, unless given (`max_radius`,
//! `caustic_max_radius`), are those that hold `k` (`caustic_k`) photons at the mean
//! density of the first pass's photons.
//!
//! The default gather is `direct` (direct visualisation of the indirect map at the
//! first diffuse hit: Knaus & Zwicker's estimator); `final_gather` and `precomputed`
//! are consistent too (their photon estimates and precomputed-point lookups use r_i).
//! With `irradiance_cache` the tolerance a shrinks with the radius, a_i = a · r_i / r_1,
//! so the entries' reach — and the interpolation error — shrink with the kernel's.
use super::{Budget, OnPass, ProgressiveParams, load_checkpoint, next_radius2, save_checkpoint};
use crate::config::RenderConfig;
use crate::film::Film;
use crate::integrator::Integrator;
use crate::integrator::photon::gather::GatherSpec;
use crate::integrator::photon::{Output, PhotonIntegrator, PhotonSetup};
use crate::integrator::render::{RenderStats, render};
use crate::math::hash_words;
use crate::world::World;
use anyhow::Result;
use glam::DVec3;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::time::Instant;

crate::params! {
    /// Parameters of the `ppm` integrator.
    pub struct PpmParams {
        /// Each pass estimates from the k nearest photons within its radius (`k`, `caustic_k`) instead of every photon within it: biased until the radius falls below the k-th neighbour's distance; for comparisons.
        ppm_knn: bool = "false",
    }
}

/// The radii of one pass: global and caustic (`None` = derived from the pass's
/// photons, the first pass's default), and their ratio to the first pass's radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassRadii {
    /// Global search radius.
    pub global: Option<f32>,
    /// Caustic search radius.
    pub caustic: Option<f32>,
    /// r_i / r_1 (1 in the first pass).
    pub shrink: f32,
}

/// The common keys and photon settings of pass `i` (from 1) with `radii`: an
/// independent `photon` render with its own seed.
pub fn pass_setup(
    cfg: &RenderConfig,
    base: &PhotonSetup,
    prog: &ProgressiveParams,
    i: u32,
    radii: PassRadii,
    has_specular: bool,
) -> (RenderConfig, PhotonSetup) {
    let mut c = cfg.clone();
    c.integrator = "photon".into();
    c.seed = hash_words(&[cfg.seed, i as u64, 0x9916]);
    c.record_passes = Vec::new();
    c.params = Default::default();
    let mut s = base.clone();
    s.p.max_radius = radii.global;
    s.p.caustic_max_radius = radii.caustic;
    if let GatherSpec::Cache(_, _, c) = &mut s.gather {
        c.ic_tolerance *= radii.shrink;
    }
    if prog.photons_per_pass.is_some() {
        s.p.emit_photons = prog.photons_per_pass;
    }
    if !has_specular {
        s.p.caustic_photons = 0;
    }
    (c, s)
}

/// `gather` when the key is not set: direct visualisation, Knaus & Zwicker's estimator.
pub const DEFAULT_GATHER: &str = "direct";

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
        let own = PpmParams::read(r)?;
        let mut photon = PhotonSetup::read_with_gather_default(cfg, r, Some(DEFAULT_GATHER))?;
        photon.radius_bounded = !own.ppm_knn;
        Ok(PpmIntegrator { output: Output::All, cfg: cfg.clone(), prog, photon, quiet, counters: BTreeMap::new() })
    }

    fn run(&mut self, world: &World, on_pass: OnPass) -> Result<(Film, RenderStats)> {
        let cam = &world.scene.camera;
        let budget = Budget::new(&self.prog);
        // Squared radii of the next pass; `None` until the first pass derived them.
        let sq = |r: Option<f32>| r.map(|r| (r as f64).powi(2));
        let (mut r2, mut rc2) = (sq(self.photon.p.max_radius), sq(self.photon.p.caustic_max_radius));
        let mut r2_first = r2;
        let has_specular = world.scene.tri_material.iter().any(|&m| world.scene.materials[m as usize].bsdf.has_delta());
        let alpha = self.prog.alpha as f64;
        let mut sum = vec![DVec3::ZERO; (cam.width * cam.height) as usize];
        let mut film = Film::new(cam.width, cam.height);
        let mut stats = RenderStats::default();
        let (mut t_pre, mut t_render) = (0.0, 0.0);
        let mut emitted = 0.0;
        let mut pass = 0u32;
        // Checkpoint state: pass sums, r², r_c², the first pass's r² (f64 bit patterns).
        type State = (Vec<[u64; 3]>, u64, u64, u64);
        if let Some((done, (saved, a, b, c))) = load_checkpoint::<State>(&self.cfg, &self.prog, world)? {
            if saved.len() != sum.len() {
                anyhow::bail!("checkpoint holds {} pixels, the image has {}", saved.len(), sum.len());
            }
            sum = saved.iter().map(|v| DVec3::from_array(v.map(f64::from_bits))).collect();
            (r2, rc2, r2_first, pass) = (Some(f64::from_bits(a)), Some(f64::from_bits(b)), Some(f64::from_bits(c)), done);
            let inv = 1.0 / pass.max(1) as f64;
            film.pixels.par_iter_mut().zip(sum.par_iter()).for_each(|(o, s)| *o = (*s * inv).as_vec3());
        }
        let pb = crate::progress::progress_bar(if budget.max_passes == u32::MAX { 0 } else { budget.max_passes as u64 }, self.quiet, "ppm");
        while budget.more(pass) {
            let i = pass + 1;
            let shrink = match (r2, r2_first) {
                (Some(a), Some(b)) if b > 0.0 => (a / b).sqrt() as f32,
                _ => 1.0,
            };
            let radii = PassRadii { global: r2.map(|v| v.sqrt() as f32), caustic: rc2.map(|v| v.sqrt() as f32), shrink };
            let (pcfg, setup) = pass_setup(&self.cfg, &self.photon, &self.prog, i, radii, has_specular);
            let mut integrator = PhotonIntegrator::from_setup(&pcfg, setup, crate::rr::make(&pcfg.rr)?, true);
            integrator.output = self.output;
            let t0 = Instant::now();
            integrator.preprocess(world)?;
            t_pre += t0.elapsed().as_secs_f64();
            let sampler = crate::sampler::make(&pcfg.sampler, pcfg.seed, Some(pcfg.spp as u64))?;
            let (img, st) = render(world, &integrator, sampler.as_ref(), pcfg.spp, true);
            // A cancelled pass is incomplete: never add it to the sums or a checkpoint.
            crate::progress::check_cancel()?;
            t_render += st.seconds;
            stats.traversal.add(&st.traversal);
            stats.nonfinite_samples += st.nonfinite_samples;
            let pstats = integrator.stats();
            emitted += pstats.get("photons_emitted").copied().unwrap_or(0.0);
            // The radii the pass used (derived from its photons when not given).
            let used = |key: &str, given: Option<f64>| given.or_else(|| pstats.get(key).map(|r| r * r));
            (r2, rc2) = (used("max_radius", r2), used("caustic_max_radius", rc2));
            r2_first = r2_first.or(r2);
            sum.par_iter_mut().zip(img.pixels.par_iter()).for_each(|(s, p)| *s += p.as_dvec3());
            let inv = 1.0 / i as f64;
            film.pixels.par_iter_mut().zip(sum.par_iter()).for_each(|(o, s)| *o = (*s * inv).as_vec3());
            pass = i;
            pb.inc(1);
            on_pass(pass, budget.elapsed(), &film);
            r2 = r2.map(|v| next_radius2(v, i, alpha));
            rc2 = rc2.map(|v| next_radius2(v, i, alpha));
            if self.prog.checkpoint_every.is_some_and(|k| pass.is_multiple_of(k)) {
                let bits = |v: Option<f64>| v.unwrap_or(0.0).to_bits();
                let state: State = (sum.iter().map(|v| v.to_array().map(f64::to_bits)).collect(), bits(r2), bits(rc2), bits(r2_first));
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
        c.insert("final_radius".into(), r2.unwrap_or(0.0).sqrt());
        c.insert("first_radius".into(), r2_first.unwrap_or(0.0).sqrt());
        Ok((film, stats))
    }
}

super::progressive_integrator!(PpmIntegrator, "ppm");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pass_configs_are_independent_photon_renders() {
        let cfg = RenderConfig { integrator: "ppm".into(), ..Default::default() }.with("photons_per_pass", 5000).with("passes", 8);
        let r = crate::param::Reader::new(&cfg.params);
        let ppm = PpmIntegrator::new(&cfg, &r, true).unwrap();
        // Defaults: radius-bounded estimates, direct visualisation.
        assert!(ppm.photon.radius_bounded && ppm.photon.gather == GatherSpec::Direct);
        let radii = |g: f32, c: f32, shrink: f32| PassRadii { global: Some(g), caustic: Some(c), shrink };
        let (a, sa) = pass_setup(&cfg, &ppm.photon, &ppm.prog, 1, radii(2.0, 0.5, 1.0), false);
        let (b, _) = pass_setup(&cfg, &ppm.photon, &ppm.prog, 2, radii(1.0, 0.25, 0.5), false);
        assert_eq!(a.integrator, "photon");
        assert_ne!(a.seed, b.seed);
        assert!(a.params.0.is_empty());
        assert_eq!(
            (sa.p.max_radius, sa.p.caustic_max_radius, sa.p.emit_photons, sa.p.caustic_photons),
            (Some(2.0), Some(0.5), Some(5000), 0)
        );
        let err = |c: RenderConfig| crate::registry::make_integrator(&c).err().unwrap().to_string();
        assert!(err(cfg.clone().with("sppm_radius", 1.0)).contains("sppm_radius"));
        assert!(err(cfg.clone().with("gather", "nope")).contains("nope"));
        // The cache's keys belong to a gather the default does not choose.
        assert!(err(cfg.clone().with("ic_tolerance", 0.1)).contains("ic_tolerance"));
        // The k-nearest control, and a chosen cache whose tolerance shrinks with the radius.
        let c = cfg.with("ppm_knn", true).with("gather", "irradiance_cache").with("ic_tolerance", 0.4);
        let r = crate::param::Reader::new(&c.params);
        let knn = PpmIntegrator::new(&c, &r, true).unwrap();
        assert!(!knn.photon.radius_bounded);
        let (_, s) = pass_setup(&c, &knn.photon, &knn.prog, 3, radii(1.0, 0.25, 0.5), false);
        let GatherSpec::Cache(_, _, cs) = s.gather else { panic!("{:?}", s.gather) };
        assert!((cs.ic_tolerance - 0.2).abs() < 1e-6);
    }
}
