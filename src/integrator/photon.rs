//! `photon`: the photon-mapping integrator of the design report.
//!
//! Pass 1 ([`crate::photon::build_maps`]) stores photons in the direct, indirect and
//! caustic maps. Pass 2 traces camera rays: emitters seen directly or through mirrors
//! and glass count fully; mirrors and glass are followed Whitted-style (both glass
//! branches for the first two specular bounces, one chosen by weight after that);
//! at the first non-specular surface the radiance is direct light by distribution ray
//! tracing + caustics by direct visualisation of the caustic map + indirect light by
//! the configured gather plug-in.

use super::Integrator;
use crate::accel::TraversalStats;
use crate::config::RenderConfig;
use crate::gather::{
    Gather, MAX_SPECULAR, PhotonContext, SPLIT_DEPTH, ShadeKey,
    direct::DirectVisualisation,
    final_gather::FinalGather,
    irradiance_cache::{CacheSettings, IrradianceCache},
    pick_branch, precomputed,
    precomputed::PrecomputedGather,
    with_heap,
};
use crate::geometry::Ray;
use crate::material::TransportMode;
use crate::math::Color;
use crate::photon::estimate::{self, EstimateParams, Filter};
use crate::photon::kdtree::KdTree;
use crate::photon::{self, PhotonPassSettings, build_maps};
use crate::registry;
use crate::rr::RussianRoulette;
use crate::sampler::Sampler;
use crate::world::World;
use anyhow::{Result, bail};
use glam::Vec3;
use std::collections::BTreeMap;
use std::time::Instant;

/// Default maximum search radius, in units of the radius that holds k photons at the
/// mean photon density over the lit surfaces.
pub const DENSITY_RADII: f32 = 3.0;

/// What the integrator writes into the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    /// Everything.
    All,
    /// Emitted + direct light.
    Direct,
    /// Caustics only.
    Caustic,
    /// Indirect (gathered) light only.
    Indirect,
    /// Direct visualisation of the direct map alone.
    PhotonsDirect,
    /// Direct visualisation of the indirect map alone.
    PhotonsIndirect,
    /// Direct visualisation of the caustic map alone.
    PhotonsCaustic,
}

impl Output {
    /// AOV names accepted by `--aov`.
    pub const NAMES: &'static [&'static str] =
        &["direct", "caustic", "indirect", "photons-direct", "photons-indirect", "photons-caustic", "cache"];

    /// Parses an AOV name (`cache` is drawn by the caller from the cache entries).
    pub fn parse(s: &str) -> Result<Self> {
        Ok(match s {
            "all" => Output::All,
            "direct" => Output::Direct,
            "caustic" => Output::Caustic,
            "indirect" => Output::Indirect,
            "photons-direct" => Output::PhotonsDirect,
            "photons-indirect" => Output::PhotonsIndirect,
            "photons-caustic" => Output::PhotonsCaustic,
            _ => bail!("unknown aov `{s}` (known: {})", Self::NAMES.join(", ")),
        })
    }
}

/// The photon-mapping integrator.
pub struct PhotonIntegrator {
    cfg: RenderConfig,
    rr: Box<dyn RussianRoulette>,
    gather: Box<dyn Gather>,
    ctx: Option<PhotonContext>,
    /// Image content.
    pub output: Output,
    quiet: bool,
    times: BTreeMap<String, f64>,
}

/// Checks the photon settings of a configuration.
pub fn validate(cfg: &RenderConfig) -> Result<()> {
    make_gather(cfg)?;
    Filter::parse(&cfg.filter).map_err(anyhow::Error::msg)?;
    registry::check_sampler(&cfg.direct_sampler)?;
    if cfg.sampler == "hammersley" && cfg.emit_photons.is_none() {
        bail!("sampler `hammersley` needs the number of emitted photons up front: set emit_photons (--emit-photons N) or use `halton`");
    }
    if cfg.photons == 0 && cfg.caustic_photons == 0 && cfg.emit_photons.is_none() {
        bail!("photons and caustic_photons are both 0: nothing to store");
    }
    if cfg.gather_bounces == 0 || cfg.gather_samples == 0 || cfg.glossy_samples == 0 || cfg.ic_samples == 0 {
        bail!("gather_bounces, gather_samples, glossy_samples and ic_samples must be at least 1");
    }
    let bad_px = |v: f32| v.is_nan() || v < 0.0 || v.is_infinite();
    if bad_px(cfg.ic_min_pixels) || bad_px(cfg.ic_max_pixels) || cfg.ic_max_pixels < cfg.ic_min_pixels {
        bail!("irradiance cache: need 0 <= ic_min_pixels <= ic_max_pixels (finite), got {} and {}", cfg.ic_min_pixels, cfg.ic_max_pixels);
    }
    if cfg.k == 0 || cfg.caustic_k == 0 {
        bail!("k and caustic_k must be at least 1");
    }
    if cfg.direct_samples == 0 {
        bail!("direct_samples must be at least 1");
    }
    if cfg.precompute_stride == 0 {
        bail!("precompute_stride must be at least 1");
    }
    if cfg.disc.is_nan() || cfg.disc <= 0.0 {
        bail!("disc must be positive, got {}", cfg.disc);
    }
    for (name, v) in [("max_radius", cfg.max_radius), ("caustic_max_radius", cfg.caustic_max_radius)] {
        if let Some(r) = v
            && (r.is_nan() || r <= 0.0 || r.is_infinite())
        {
            bail!("{name} must be positive and finite, got {r}");
        }
    }
    let bad = |v: f32| v.is_nan() || v <= 0.0;
    if bad(cfg.ic_tolerance) || bad(cfg.ic_min_radius) || bad(cfg.ic_max_radius) || cfg.ic_max_radius < cfg.ic_min_radius {
        bail!("irradiance cache: need ic_tolerance > 0 and 0 < ic_min_radius <= ic_max_radius");
    }
    if cfg.emit_photons == Some(0) || cfg.max_emitted == 0 {
        bail!("emit_photons and max_emitted must be at least 1");
    }
    Ok(())
}

fn make_gather(cfg: &RenderConfig) -> Result<Box<dyn Gather>> {
    Ok(match cfg.gather.as_str() {
        "direct" => Box::new(DirectVisualisation),
        "final_gather" => Box::new(FinalGather),
        "precomputed" => Box::new(PrecomputedGather),
        "irradiance_cache" => Box::new(IrradianceCache::new(CacheSettings::from_config(cfg))),
        other => bail!("unknown gather `{other}` (known: {})", crate::gather::GATHERS.join(", ")),
    })
}

impl PhotonIntegrator {
    /// Builds the integrator (the photon pass runs in `preprocess`).
    pub fn new(cfg: &RenderConfig, rr: Box<dyn RussianRoulette>, quiet: bool) -> Result<Self> {
        validate(cfg)?;
        Ok(PhotonIntegrator {
            cfg: cfg.clone(),
            rr,
            gather: make_gather(cfg)?,
            ctx: None,
            output: Output::All,
            quiet,
            times: BTreeMap::new(),
        })
    }

    /// The photon maps and shared state (after `preprocess`).
    pub fn context(&self) -> Option<&PhotonContext> {
        self.ctx.as_ref()
    }

    fn radiance(&self, ctx: &PhotonContext, world: &World, ray: &Ray, sdepth: u32, key: ShadeKey, stats: &mut TraversalStats) -> Color {
        let Some(it) = world.intersect(ray, stats) else { return Color::ZERO };
        let mat = world.material(&it);
        let mut l = Color::ZERO;
        if it.front && mat.is_emitter() && matches!(self.output, Output::All | Output::Direct) {
            l += mat.emission;
        }
        let bsdf = &mat.bsdf;
        let wo = -ray.d.normalize();
        if bsdf.is_delta() {
            if sdepth >= MAX_SPECULAR {
                return l;
            }
            let (br, n) = bsdf.specular_branches(&it.sp, wo, TransportMode::Radiance);
            if sdepth < SPLIT_DEPTH {
                for (b, &(wi, w)) in br[..n].iter().enumerate() {
                    if w.max_element() > 0.0 {
                        l += w * self.radiance(ctx, world, &world.spawn(&it, wi), sdepth + 1, key.child(b as u64), stats);
                    }
                }
            } else if let Some((wi, w)) = pick_branch(&br[..n], key.uniform(0x5BEC + sdepth as u64)) {
                l += w * self.radiance(ctx, world, &world.spawn(&it, wi), sdepth + 1, key, stats);
            }
            return l;
        }
        let est = |map| with_heap(|h| estimate::radiance(map, &it, wo, bsdf, &ctx.est_global, h));
        match self.output {
            Output::All => {
                l += ctx.direct_light(world, &it, wo, bsdf, key.child(0xD1), stats);
                l += ctx.caustic(&it, wo, bsdf);
                l += self.gather.indirect(ctx, world, &it, wo, bsdf, key, stats);
            }
            Output::Direct => l += ctx.direct_light(world, &it, wo, bsdf, key.child(0xD1), stats),
            Output::Caustic => l += ctx.caustic(&it, wo, bsdf),
            Output::Indirect => l += self.gather.indirect(ctx, world, &it, wo, bsdf, key, stats),
            Output::PhotonsDirect => l += est(&ctx.maps.direct),
            Output::PhotonsIndirect => l += est(&ctx.maps.indirect),
            Output::PhotonsCaustic => l += with_heap(|h| estimate::radiance(&ctx.maps.caustic, &it, wo, bsdf, &ctx.est_caustic, h)),
        }
        l
    }
}

impl Integrator for PhotonIntegrator {
    fn name(&self) -> &'static str {
        "photon"
    }

    fn preprocess(&mut self, world: &World) -> Result<()> {
        let cfg = &self.cfg;
        let r_scene = world.lights.scene_radius;
        let filter = Filter::parse(&cfg.filter).map_err(anyhow::Error::msg)?;
        let emit_sampler = registry::make_sampler(&cfg.sampler, cfg.seed, cfg.emit_photons)?;
        let t0 = Instant::now();
        let settings = PhotonPassSettings {
            global_photons: cfg.photons as usize,
            caustic_photons: cfg.caustic_photons as usize,
            fixed_emit: cfg.emit_photons,
            max_emitted: cfg.max_emitted,
            max_depth: cfg.depth_limit(),
        };
        let maps = build_maps(world, emit_sampler.as_ref(), self.rr.as_ref(), &settings, self.quiet);
        for w in &maps.warnings {
            eprintln!("warning: {w}");
        }
        self.times.insert("photon_pass_s".into(), t0.elapsed().as_secs_f64());
        self.times.insert("photon_trace_s".into(), t0.elapsed().as_secs_f64() - maps.build_s);
        // Default search radii from the photons themselves: DENSITY_RADII × the radius
        // that would hold k photons at the mean density over the lit surfaces (so
        // they follow the photon count and the scene's scale; a region DENSITY_RADII²
        // times darker than average is the first to be estimated from fewer than k).
        let from_density = |k: u32, stored: usize, area: f64, fallback: f32| {
            photon::mean_density_radius(k as usize, stored, area).map_or(fallback, |r| (DENSITY_RADII * r).min(r_scene))
        };
        let max_radius = cfg.max_radius.unwrap_or_else(|| from_density(cfg.k, maps.global_len(), maps.lit_area_global, 0.1 * r_scene));
        let caustic_radius = cfg
            .caustic_max_radius
            .unwrap_or_else(|| from_density(cfg.caustic_k, maps.caustic.len(), maps.lit_area_caustic, 0.025 * r_scene));
        self.times.insert("max_radius".into(), max_radius as f64);
        self.times.insert("caustic_max_radius".into(), caustic_radius as f64);
        let t1 = Instant::now();
        let t_global = Instant::now();
        let global = KdTree::merged(&[&maps.direct, &maps.indirect, &maps.caustic]);
        self.times.insert("kdtree_build_s".into(), maps.build_s + t_global.elapsed().as_secs_f64());
        let est_global = EstimateParams::new(cfg.k as usize, max_radius, filter, cfg.disc);
        let est_caustic = EstimateParams::new(cfg.caustic_k as usize, caustic_radius, filter, cfg.disc);
        let use_pre = cfg.gather == "precomputed" || (cfg.precomputed_irradiance && cfg.gather == "irradiance_cache");
        let pre = use_pre.then(|| precomputed::precompute(&global, cfg.precompute_stride as usize, &est_global));
        self.times.insert("precompute_s".into(), t1.elapsed().as_secs_f64());
        let mut counts = vec![cfg.gather_samples];
        for _ in 1..cfg.gather_bounces {
            let last = *counts.last().unwrap_or(&1);
            counts.push((last / 8).max(4));
        }
        let gather_samplers = counts
            .iter()
            .enumerate()
            .map(|(i, &n)| registry::make_sampler(&cfg.sampler, cfg.seed ^ (0x6A7E + i as u64), Some(n as u64)))
            .collect::<Result<Vec<_>>>()?;
        let direct_sampler = registry::make_sampler(&cfg.direct_sampler, cfg.seed ^ 0xD12EC7, Some(cfg.direct_samples as u64))?;
        let ctx = PhotonContext {
            maps,
            global,
            est_global,
            est_caustic,
            precomputed: pre,
            precomputed_radius: max_radius,
            gather_samplers,
            gather_counts: counts,
            glossy_sampler: registry::make_sampler(&cfg.sampler, cfg.seed ^ 0x6105_5EED, Some(cfg.glossy_samples as u64))?,
            glossy_samples: cfg.glossy_samples,
            direct_sampler,
            direct_samples: cfg.direct_samples,
        };
        let t2 = Instant::now();
        self.gather.prepare(&ctx, world, self.quiet)?;
        self.times.insert("prefill_s".into(), t2.elapsed().as_secs_f64());
        self.ctx = Some(ctx);
        Ok(())
    }

    fn li(&self, world: &World, ray: &Ray, sampler: &mut dyn Sampler, stats: &mut TraversalStats) -> Color {
        let Some(ctx) = &self.ctx else { return Color::ZERO };
        self.radiance(ctx, world, ray, 0, ShadeKey::from_sampler(sampler), stats)
    }

    fn set_output(&mut self, aov: &str) -> Result<()> {
        self.output = Output::parse(aov)?;
        Ok(())
    }

    fn debug_points(&self) -> Vec<Vec3> {
        self.gather.debug_points()
    }

    fn stats(&self) -> BTreeMap<String, f64> {
        let mut m = self.times.clone();
        if let Some(c) = &self.ctx {
            m.insert("photons_emitted".into(), c.maps.emitted_total as f64);
            m.insert("photons_direct".into(), c.maps.direct.len() as f64);
            m.insert("photons_indirect".into(), c.maps.indirect.len() as f64);
            m.insert("photons_caustic".into(), c.maps.caustic.len() as f64);
            m.insert("photon_rays".into(), c.maps.rays.total_rays() as f64);
            let bytes = c.maps.direct.memory_bytes() + c.maps.indirect.memory_bytes() + c.maps.caustic.memory_bytes();
            let stored = c.maps.direct.len() + c.maps.indirect.len() + c.maps.caustic.len();
            m.insert("photon_bytes".into(), bytes as f64 / stored.max(1) as f64);
            m.insert("photon_map_bytes".into(), (bytes + c.global.memory_bytes()) as f64);
            if let Some(p) = &c.precomputed {
                m.insert("precomputed_points".into(), p.len() as f64);
            }
        }
        for (k, v) in self.gather.counters() {
            m.insert(k, v);
        }
        m
    }
}
