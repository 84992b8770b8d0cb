//! `photon`: the photon-mapping integrator of the design report.
//!
//! Pass 1 ([`crate::photon::build_maps`]) stores photons in the direct, indirect and
//! caustic maps. Pass 2 traces camera rays: emitters and the environment seen directly
//! or through mirrors and glass count fully; mirrors and glass are followed
//! Whitted-style (both glass branches for the first two specular bounces, one chosen
//! by weight after that); at the first non-specular surface the radiance is direct
//! light by distribution ray tracing (the light set samples the environment too) +
//! caustics by direct visualisation of the caustic map + indirect light by the
//! configured gather plug-in. Every vertex, in both passes, scatters with its textured
//! BSDF ([`World::bsdf_at`]); precomputed irradiance and the irradiance cache store
//! irradiance, which each lookup multiplies by the reflectance of its own point.
//!
//! The environment is counted once: light arriving straight from it at a
//! non-specular point comes from light sampling, so a final-gather ray that escapes
//! (directly, or through mirrors and glass, which the caustic map covers) carries
//! nothing; light it sends after a bounce comes from the photons it emits.

pub mod context;
pub mod gather;

use super::Integrator;
use crate::accel::TraversalStats;
use crate::config::RenderConfig;
use crate::geometry::Ray;
use crate::material::TransportMode;
use crate::math::Color;
use crate::photon::estimate::{self, EstimateParams, Filter, with_heap};
use crate::photon::irradiance;
use crate::photon::{self, MapTrees, PhotonPassSettings, build_maps};
use crate::rr::RussianRoulette;
use crate::sampler::Sampler;
use crate::world::World;
use anyhow::{Result, bail};
use context::{GatherPoint, MAX_SPECULAR, PhotonContext, PixelSample, PixelSplit, SPLIT_DEPTH, ShadeKey, pick_branch};
use gather::{Gather, GatherSpec};
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

crate::params! {
    /// Parameters of the `photon` integrator (also read by `ppm`, once per pass).
    pub struct PhotonParams {
        /// Photons stored in the direct + indirect (global) maps.
        photons: u32 = "200000",
        /// Photons stored in the caustic map (skipped with a warning when the scene has no mirror or glass).
        caustic_photons: u32 = "50000",
        /// Emit exactly this many photon paths (required by the `hammersley` sampler) instead of emitting until the maps hold the requested counts.
        emit_photons: Option<u64> = "auto",
        /// Cap on emitted photon paths; a map that cannot be filled is reported.
        max_emitted: u64 = "20000000",
        /// Indirect-light plug-in (`gather` family below).
        gather: String = "irradiance_cache",
        /// Photons per global radiance estimate.
        k: u32 = "100",
        /// Photons per caustic radiance estimate.
        caustic_k: u32 = "60",
        /// Largest search radius of global estimates (scene units); `auto` = 3 × the radius holding `k` photons at the mean density of the stored photons over the triangles they landed on.
        max_radius: Option<f32> = "auto",
        /// Largest search radius of caustic estimates; `auto` = 3 × the radius holding `caustic_k` caustic photons at their mean density.
        caustic_max_radius: Option<f32> = "auto",
        /// Density-estimation kernel (`filter` family below), normalised.
        filter: String = "cone",
        /// Photons (and precomputed points) must lie within ±disc × radius of the tangent plane and have arrived on the side the estimate looks from (corners, thin walls); ≥ 1 disables the plane test.
        disc: f32 = "0.25",
        /// Rays per global photon-map estimate (direct visualisation, final-gather hits, precomputed irradiance) that measure the surface area inside the estimate's disc (thin and curved geometry, edges: the boundary-bias correction), skipped when the photons found already fill the disc; 0 divides by π r² as plain photon mapping does.
        area_probes: u32 = "32",
    }
}

crate::params! {
    /// Direct light by distribution ray tracing (read by `photon`, `ppm` and `sppm`).
    pub struct DirectParams {
        /// Shadow rays per shading point.
        direct_samples: u32 = "4",
        /// Sampler of the direct-light samples at each shading point.
        direct_sampler: String = "hammersley",
    }
}

impl DirectParams {
    /// Reads and checks the parameters.
    pub fn read_checked(r: &crate::param::Reader) -> Result<Self> {
        let d = Self::read(r)?;
        if d.direct_samples == 0 {
            bail!("direct_samples must be at least 1");
        }
        crate::sampler::check(&d.direct_sampler)?;
        Ok(d)
    }
}

/// Everything the photon integrator reads, checked.
#[derive(Clone, Debug)]
pub struct PhotonSetup {
    /// Its own parameters.
    pub p: PhotonParams,
    /// Direct light.
    pub direct: DirectParams,
    /// The gather plug-in and its parameters.
    pub gather: GatherSpec,
    /// Estimates take every photon within the search radius instead of the k
    /// nearest ([`photon::within`]), and an `auto` radius holds k photons at the mean
    /// density instead of [`DENSITY_RADII`] times that (`ppm` sets it; not a key).
    pub radius_bounded: bool,
}

impl PhotonSetup {
    /// Reads and checks the photon integrator's parameters (`cfg` gives the sampler).
    pub fn read(cfg: &RenderConfig, r: &crate::param::Reader) -> Result<Self> {
        Self::read_with_gather_default(cfg, r, None)
    }

    /// [`PhotonSetup::read`] with another default for `gather` when the key is not set
    /// (`ppm`: `direct`).
    pub fn read_with_gather_default(cfg: &RenderConfig, r: &crate::param::Reader, gather: Option<&str>) -> Result<Self> {
        let mut p = PhotonParams::read(r)?;
        if let Some(g) = gather
            && !cfg.params.contains("gather")
        {
            p.gather = g.to_string();
        }
        let direct = DirectParams::read_checked(r)?;
        let gather = GatherSpec::read(&p.gather, r)?;
        Filter::parse(&p.filter)?;
        if cfg.sampler == "hammersley" && p.emit_photons.is_none() {
            bail!("sampler `hammersley` needs the number of emitted photons up front: set emit_photons (--emit-photons N) or use `halton`");
        }
        if p.photons == 0 && p.caustic_photons == 0 && p.emit_photons.is_none() {
            bail!("photons and caustic_photons are both 0: nothing to store");
        }
        if p.k == 0 || p.caustic_k == 0 {
            bail!("k and caustic_k must be at least 1");
        }
        if p.disc.is_nan() || p.disc <= 0.0 {
            bail!("disc must be positive, got {}", p.disc);
        }
        for (name, v) in [("max_radius", p.max_radius), ("caustic_max_radius", p.caustic_max_radius)] {
            if let Some(r) = v
                && (r.is_nan() || r <= 0.0 || r.is_infinite())
            {
                bail!("{name} must be positive and finite, got {r}");
            }
        }
        if p.emit_photons == Some(0) || p.max_emitted == 0 {
            bail!("emit_photons and max_emitted must be at least 1");
        }
        Ok(PhotonSetup { p, direct, gather, radius_bounded: false })
    }
}

/// The photon-mapping integrator.
pub struct PhotonIntegrator {
    cfg: RenderConfig,
    setup: PhotonSetup,
    rr: Box<dyn RussianRoulette>,
    gather: Box<dyn Gather>,
    ctx: Option<PhotonContext>,
    /// Image content.
    pub output: Output,
    quiet: bool,
    times: BTreeMap<String, f64>,
}

impl PhotonIntegrator {
    /// Builds the integrator from its parameters (the photon pass runs in `preprocess`).
    pub fn new(cfg: &RenderConfig, r: &crate::param::Reader, rr: Box<dyn RussianRoulette>, quiet: bool) -> Result<Self> {
        Ok(Self::from_setup(cfg, PhotonSetup::read(cfg, r)?, rr, quiet))
    }

    /// Builds the integrator from parameters read before.
    pub fn from_setup(cfg: &RenderConfig, setup: PhotonSetup, rr: Box<dyn RussianRoulette>, quiet: bool) -> Self {
        PhotonIntegrator {
            cfg: cfg.clone(),
            gather: setup.gather.build(),
            setup,
            rr,
            ctx: None,
            output: Output::All,
            quiet,
            times: BTreeMap::new(),
        }
    }

    /// The photon maps and shared state (after `preprocess`).
    pub fn context(&self) -> Option<&PhotonContext> {
        self.ctx.as_ref()
    }

    #[allow(clippy::too_many_arguments)]
    fn radiance(
        &self,
        ctx: &PhotonContext,
        world: &World,
        ray: &Ray,
        sdepth: u32,
        key: ShadeKey,
        pixel: PixelSample,
        stats: &mut TraversalStats,
    ) -> Color {
        let seen = matches!(self.output, Output::All | Output::Direct);
        // A camera ray or specular chain that leaves the scene sees the environment
        // (light reaching it from there after a diffuse or glossy bounce comes from
        // light sampling and the photon maps, never from a gather ray that escapes).
        let Some(it) = world.intersect(ray, stats) else {
            return if seen { world.escaped(ray.d.normalize()) } else { Color::ZERO };
        };
        let mat = world.material(&it);
        let mut l = Color::ZERO;
        if it.front && mat.is_emitter() && seen {
            l += mat.emission;
        }
        // Textured parameters filled in (borrowed, untouched, when untextured).
        let bsdf = &*world.bsdf_at(&it);
        let wo = -ray.d.normalize();
        // Delta lobes (all of a mirror's or glass's; a plastic coating's or a mask's
        // null lobe besides the other lobes shaded below) are followed as branches.
        if bsdf.has_delta() && (sdepth < MAX_SPECULAR || bsdf.is_delta()) {
            if sdepth >= MAX_SPECULAR {
                return l;
            }
            let (br, n) = bsdf.specular_branches(&it.sp, wo, TransportMode::Radiance);
            if sdepth < SPLIT_DEPTH {
                for (b, &(wi, w)) in br[..n].iter().enumerate() {
                    if w.max_element() > 0.0 {
                        let px = PixelSample { key: pixel.key.child(b as u64), ..pixel };
                        l += w * self.radiance(ctx, world, &world.spawn(&it, wi), sdepth + 1, key.child(b as u64), px, stats);
                    }
                }
            } else if let Some((wi, w)) = pick_branch(&br[..n], key.uniform(0x5BEC + sdepth as u64)) {
                l += w * self.radiance(ctx, world, &world.spawn(&it, wi), sdepth + 1, key, pixel, stats);
            }
            if bsdf.is_delta() {
                return l;
            }
        }
        // Rough glass is passed through by sampling its BSDF (one ray), as the delta
        // lobes above and as `sppm`'s camera paths do: a photon estimate of a narrow
        // transmission lobe, which gathers photons from both sides, is blotchy and
        // biased (+27 % in a block on an α = 0.1 glass sphere against Mitsuba).
        if bsdf.transmits_nondelta() && !bsdf.has_delta() && matches!(self.output, Output::All) {
            if sdepth >= MAX_SPECULAR {
                return l;
            }
            let u = [key.uniform(0x6C55 + 3 * sdepth as u64), key.uniform(0x6C56 + 3 * sdepth as u64)];
            if let Some(bs) = bsdf.sample(&it.sp, wo, key.uniform(0x6C57 + 3 * sdepth as u64), u, TransportMode::Radiance)
                && bs.weight.max_element() > 0.0
            {
                l += bs.weight * self.radiance(ctx, world, &world.spawn(&it, bs.wi), sdepth + 1, key, pixel, stats);
            }
            return l;
        }
        // The trees exist when the output asks for them (`map_trees`).
        let est = |map: &Option<_>, stats: &mut TraversalStats| {
            map.as_ref()
                .map_or(Color::ZERO, |m| with_heap(|h| estimate::radiance_in(Some((world, stats)), m, &it, wo, bsdf, &ctx.est_global, h)))
        };
        let at = GatherPoint { world, it: &it, wo, bsdf, key, pixel: Some(pixel) };
        match self.output {
            Output::All => {
                l += ctx.direct_light(&at, stats);
                l += ctx.caustic(world, &it, wo, bsdf, stats);
                l += self.gather.indirect(ctx, &at, stats);
            }
            Output::Direct => l += ctx.direct_light(&at, stats),
            Output::Caustic => l += ctx.caustic(world, &it, wo, bsdf, stats),
            Output::Indirect => l += self.gather.indirect(ctx, &at, stats),
            Output::PhotonsDirect => l += est(&ctx.maps.direct, stats),
            Output::PhotonsIndirect => l += est(&ctx.maps.indirect, stats),
            Output::PhotonsCaustic => {
                l += with_heap(|h| estimate::radiance_in(Some((world, stats)), &ctx.maps.caustic, &it, wo, bsdf, &ctx.est_caustic, h))
            }
        }
        l
    }

    /// The kd-trees of the direct and indirect maps this render searches: the
    /// `photons-direct` / `photons-indirect` outputs and direct visualisation
    /// (`gather = "direct"`, the indirect map); gathers search the global grid.
    fn map_trees(&self) -> MapTrees {
        MapTrees {
            direct: self.output == Output::PhotonsDirect,
            indirect: self.output == Output::PhotonsIndirect || self.setup.gather == GatherSpec::Direct,
        }
    }
}

impl Integrator for PhotonIntegrator {
    fn name(&self) -> &'static str {
        "photon"
    }

    fn preprocess(&mut self, world: &World) -> Result<()> {
        let cfg = &self.cfg;
        let (p, direct) = (&self.setup.p, &self.setup.direct);
        let gp = self.setup.gather.gather_params();
        let r_scene = world.lights.scene_radius;
        let filter = Filter::parse(&p.filter)?;
        let emit_sampler = crate::sampler::make(&cfg.sampler, cfg.seed, p.emit_photons)?;
        let t0 = Instant::now();
        let settings = PhotonPassSettings {
            global_photons: p.photons as usize,
            caustic_photons: p.caustic_photons as usize,
            fixed_emit: p.emit_photons,
            max_emitted: p.max_emitted,
            max_depth: cfg.depth_limit(),
            trees: self.map_trees(),
        };
        let mut maps = build_maps(world, emit_sampler.as_ref(), self.rr.as_ref(), &settings, self.quiet);
        for w in &maps.warnings {
            eprintln!("warning: {w}");
        }
        self.times.insert("photon_pass_s".into(), t0.elapsed().as_secs_f64());
        self.times.insert("photon_trace_s".into(), t0.elapsed().as_secs_f64() - maps.build_s);
        // Default search radii from the photons themselves: DENSITY_RADII × the radius
        // that would hold k photons at the mean density over the lit surfaces (so
        // they follow the photon count and the scene's scale; a region DENSITY_RADII²
        // times darker than average is the first to be estimated from fewer than k).
        let bounded = self.setup.radius_bounded;
        let radii = if bounded { 1.0 } else { DENSITY_RADII };
        let from_density = |k: u32, stored: usize, area: f64, fallback: f32| {
            photon::mean_density_radius(k as usize, stored, area).map_or(fallback, |r| (radii * r).min(r_scene))
        };
        let max_radius = p.max_radius.unwrap_or_else(|| from_density(p.k, maps.global_len(), maps.lit_area_global, 0.1 * r_scene));
        let caustic_radius =
            p.caustic_max_radius.unwrap_or_else(|| from_density(p.caustic_k, maps.caustic.len(), maps.lit_area_caustic, 0.025 * r_scene));
        self.times.insert("max_radius".into(), max_radius as f64);
        self.times.insert("caustic_max_radius".into(), caustic_radius as f64);
        let t1 = Instant::now();
        let t_global = Instant::now();
        let global = photon::global_grid(&mut maps, p.k as usize);
        self.times.insert("kdtree_build_s".into(), maps.build_s + t_global.elapsed().as_secs_f64());
        let k_of = |k: u32| if bounded { photon::within::ALL } else { k as usize };
        // Global estimates (direct visualisation, final-gather hits, precomputed
        // irradiance) divide by the surface inside their disc; caustic ones by π r².
        let est_global = EstimateParams::new(k_of(p.k), max_radius, filter, p.disc).with_area_probes(p.area_probes);
        let est_caustic = EstimateParams::new(k_of(p.caustic_k), caustic_radius, filter, p.disc);
        let pre = self.setup.gather.precompute_stride().map(|stride| irradiance::precompute(world, &global, stride, &est_global));
        self.times.insert("precompute_s".into(), t1.elapsed().as_secs_f64());
        let mut counts = vec![gp.gather_samples];
        for _ in 1..gp.gather_bounces {
            let last = *counts.last().unwrap_or(&1);
            counts.push((last / 8).max(4));
        }
        // Per pixel: the first level's and the glossy sampler's point sets are the
        // pixel's (spp × the rays of a sample).
        let pixel_split = gp.per_pixel.then(|| PixelSplit::new(gp.gather_samples, gp.glossy_samples, cfg.spp));
        let per_pixel = |n: u32, per_sample: Option<u32>| per_sample.map_or(n as u64, |m| m as u64 * cfg.spp.max(1) as u64);
        let gather_samplers = counts
            .iter()
            .enumerate()
            .map(|(i, &n)| {
                let n = if i == 0 { per_pixel(n, pixel_split.map(|p| p.gather)) } else { n as u64 };
                crate::sampler::make(&cfg.sampler, cfg.seed ^ (0x6A7E + i as u64), Some(n))
            })
            .collect::<Result<Vec<_>>>()?;
        let direct_sampler = crate::sampler::make(&direct.direct_sampler, cfg.seed ^ 0xD12EC7, Some(direct.direct_samples as u64))?;
        let ctx = PhotonContext {
            maps,
            global,
            est_global,
            est_caustic,
            precomputed: pre,
            precomputed_radius: max_radius,
            gather_samplers,
            gather_counts: counts,
            glossy_sampler: crate::sampler::make(
                &cfg.sampler,
                cfg.seed ^ 0x6105_5EED,
                Some(per_pixel(gp.glossy_samples, pixel_split.map(|p| p.glossy))),
            )?,
            glossy_samples: gp.glossy_samples,
            pixel_split,
            direct_sampler,
            direct_samples: direct.direct_samples,
        };
        let t2 = Instant::now();
        self.gather.prepare(&ctx, world, cfg.seed, self.quiet)?;
        self.times.insert("prefill_s".into(), t2.elapsed().as_secs_f64());
        self.ctx = Some(ctx);
        Ok(())
    }

    fn li(&self, world: &World, ray: &Ray, sampler: &mut dyn Sampler, stats: &mut TraversalStats) -> Color {
        let Some(ctx) = &self.ctx else { return Color::ZERO };
        let (stream, index) = sampler.current();
        // The pixel's key: its stream alone (every sample of the pixel shares it).
        let pixel = PixelSample { key: ShadeKey(crate::math::hash_words(&[stream, 0x9E1])), index };
        self.radiance(ctx, world, ray, 0, ShadeKey::from_sampler(sampler), pixel, stats)
    }

    fn set_output(&mut self, aov: &str) -> Result<()> {
        self.output = Output::parse(aov)?;
        let trees = self.map_trees();
        if let Some(ctx) = &mut self.ctx {
            ctx.maps.ensure_trees_with(trees, &ctx.global);
        }
        Ok(())
    }

    fn debug_points(&self) -> Vec<Vec3> {
        self.gather.debug_points()
    }

    fn stats(&self) -> BTreeMap<String, f64> {
        let mut m = self.times.clone();
        if let Some(c) = &self.ctx {
            m.insert("photons_emitted".into(), c.maps.emitted_total as f64);
            m.insert("photons_direct".into(), c.maps.direct_len() as f64);
            m.insert("photons_indirect".into(), c.maps.indirect_len() as f64);
            m.insert("photons_caustic".into(), c.maps.caustic.len() as f64);
            m.insert("photon_rays".into(), c.maps.rays.total_rays() as f64);
            let trees = [&c.maps.direct, &c.maps.indirect].iter().filter_map(|t| t.as_ref()).map(|t| t.memory_bytes()).sum::<usize>();
            let bytes = trees + c.maps.global.memory_bytes() + c.maps.caustic.memory_bytes();
            let stored = c.maps.global_len() + c.maps.caustic.len();
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
