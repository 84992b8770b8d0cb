//! The photon integrator's indirect-light plug-ins (`gather` = `direct`,
//! `final_gather`, `precomputed`, `irradiance_cache`): the [`Gather`] trait, what every
//! gather reads ([`GatherParams`]) and the by-name constructor ([`GatherSpec`]).
//! The shading they build on (final gather, direct light, caustics, map lookups at
//! gather hits) is the integrator's, in [`super::context`].

pub mod direct;
pub mod final_gather;
pub mod hemisphere;
pub mod irradiance_cache;
pub mod precomputed;

use super::context::{GatherPoint, PhotonContext};
use crate::accel::TraversalStats;
use crate::math::Color;
use crate::world::World;
use glam::Vec3;

/// Values of `gather_per`.
pub const GATHER_PER: &[&str] = &["sample", "pixel"];

/// Plug-in names.
pub const GATHERS: &[&str] = &["direct", "final_gather", "precomputed", "irradiance_cache"];

crate::params! {
    /// What every gathering plug-in (`final_gather`, `precomputed`, `irradiance_cache`) reads.
    pub struct GatherParams {
        /// Final-gather rays at the first level (cosine-weighted, points from the configured sampler), counted as `gather_per` says; `auto` = 256 a `pixel`, 64 a `sample` (for `irradiance_cache`, whose entries have `ic_samples` rays, the rays at a point no entry covers).
        gather_samples: Option<u32> = "auto",
        /// Final-gather levels (≥ 1); each deeper level traces, from every hit of the level above, 1/8 of that level's `gather_samples` (at least 4).
        gather_bounces: u32 = "1",
        /// Rays drawn from the glossy lobe at glossy gathering points (the diffuse part uses the gather or the cache), counted as `gather_per` says; `auto` = 64 a `pixel`, 16 a `sample`.
        glossy_samples: Option<u32> = "auto",
        /// What `gather_samples` and `glossy_samples` count at camera-sample hits: the rays of a `pixel` (each of its spp samples traces ⌈count / spp⌉ of one point set stratified over the pixel, so the cost per pixel does not depend on spp) or of each camera `sample`; `auto` = `pixel` for `final_gather` and `precomputed`, `sample` for `irradiance_cache`.
        gather_per: Option<String> = "auto",
    }
}

/// Default first-level gather rays per pixel (`gather_per = "pixel"`).
pub const PIXEL_GATHER_SAMPLES: u32 = 256;
/// Default glossy-lobe rays per pixel.
pub const PIXEL_GLOSSY_SAMPLES: u32 = 64;
/// Default first-level gather rays per camera sample (`gather_per = "sample"`).
pub const SAMPLE_GATHER_SAMPLES: u32 = 64;
/// Default glossy-lobe rays per camera sample.
pub const SAMPLE_GLOSSY_SAMPLES: u32 = 16;

/// The final-gather settings a plug-in uses: [`GatherParams`] with every `auto`
/// resolved for that plug-in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Gathering {
    /// First-level gather rays (per pixel when `per_pixel`, else per camera sample).
    pub gather_samples: u32,
    /// Final-gather levels.
    pub gather_bounces: u32,
    /// Glossy-lobe rays (counted as `gather_samples`).
    pub glossy_samples: u32,
    /// `gather_per = "pixel"`.
    pub per_pixel: bool,
}

impl Gathering {
    /// Resolves `p` for plug-in `name`: `final_gather` and `precomputed` count their
    /// rays per pixel, the irradiance cache per camera sample (its entries, which hold
    /// most of its gathering, have their own count; a point no entry covers is gathered
    /// alone, with the full count); counts left `auto` follow what they count.
    pub fn resolve(name: &str, p: &GatherParams) -> anyhow::Result<Self> {
        let cache = name == "irradiance_cache";
        let per = p.gather_per.as_deref().unwrap_or(if cache { "sample" } else { "pixel" });
        if !GATHER_PER.contains(&per) {
            anyhow::bail!("gather_per must be one of {}, got `{per}`", GATHER_PER.join(", "));
        }
        let (g, s) =
            if per == "pixel" { (PIXEL_GATHER_SAMPLES, PIXEL_GLOSSY_SAMPLES) } else { (SAMPLE_GATHER_SAMPLES, SAMPLE_GLOSSY_SAMPLES) };
        let g = Gathering {
            gather_samples: p.gather_samples.unwrap_or(g),
            gather_bounces: p.gather_bounces,
            glossy_samples: p.glossy_samples.unwrap_or(s),
            per_pixel: per == "pixel",
        };
        if g.gather_bounces == 0 || g.gather_samples == 0 || g.glossy_samples == 0 {
            anyhow::bail!("gather_bounces, gather_samples and glossy_samples must be at least 1");
        }
        Ok(g)
    }
}

/// A gather plug-in chosen by name, with the parameters it read; `build` makes a fresh
/// instance (the progressive `ppm` builds one per pass).
#[derive(Clone, Debug, PartialEq)]
pub enum GatherSpec {
    /// `direct`.
    Direct,
    /// `final_gather`.
    FinalGather(Gathering),
    /// `precomputed`.
    Precomputed(Gathering, precomputed::PrecomputedParams),
    /// `irradiance_cache`.
    Cache(Gathering, precomputed::PrecomputedParams, irradiance_cache::CacheSettings),
}

impl GatherSpec {
    /// Reads the parameters of gather `name`.
    pub fn read(name: &str, r: &crate::param::Reader) -> anyhow::Result<Self> {
        r.chose(format!("gather `{name}`"));
        let g = |r| -> anyhow::Result<Gathering> { Gathering::resolve(name, &GatherParams::read(r)?) };
        Ok(match name {
            "direct" => GatherSpec::Direct,
            "final_gather" => GatherSpec::FinalGather(g(r)?),
            "precomputed" => GatherSpec::Precomputed(g(r)?, precomputed::PrecomputedParams::read_checked(r)?),
            "irradiance_cache" => {
                let c = irradiance_cache::CacheSettings::read(r)?;
                c.validate()?;
                GatherSpec::Cache(g(r)?, precomputed::PrecomputedParams::read_checked(r)?, c)
            }
            other => anyhow::bail!("unknown gather `{other}` (known: {})", GATHERS.join(", ")),
        })
    }

    /// A fresh plug-in.
    pub fn build(&self) -> Box<dyn Gather> {
        match self {
            GatherSpec::Direct => Box::new(direct::DirectVisualisation),
            GatherSpec::FinalGather(_) => Box::new(final_gather::FinalGather::plain()),
            GatherSpec::Precomputed(..) => Box::new(precomputed::gather()),
            GatherSpec::Cache(_, _, c) => Box::new(irradiance_cache::IrradianceCache::new(c.clone())),
        }
    }

    /// The final-gather settings (for `direct`, which does not gather, the per-sample
    /// counts its samplers have always been built with).
    pub fn gather_params(&self) -> Gathering {
        match self {
            GatherSpec::Direct => Gathering {
                gather_samples: SAMPLE_GATHER_SAMPLES,
                gather_bounces: 1,
                glossy_samples: SAMPLE_GLOSSY_SAMPLES,
                per_pixel: false,
            },
            GatherSpec::FinalGather(g) | GatherSpec::Precomputed(g, _) | GatherSpec::Cache(g, _, _) => *g,
        }
    }

    /// Stride of Christensen's precomputed irradiance, when the plug-in gathers over it.
    pub fn precompute_stride(&self) -> Option<usize> {
        match self {
            GatherSpec::Precomputed(_, p) => Some(p.precompute_stride as usize),
            GatherSpec::Cache(_, p, c) if c.precomputed_irradiance => Some(p.precompute_stride as usize),
            _ => None,
        }
    }
}

/// An indirect-light strategy.
pub trait Gather: Send + Sync {
    /// Configuration name.
    fn name(&self) -> &'static str;
    /// Work after the photon pass and before rendering (e.g. cache prefill); `seed` is
    /// the render's seed (renders with different seeds must be independent).
    fn prepare(&mut self, _ctx: &PhotonContext, _world: &World, _seed: u64, _quiet: bool) -> anyhow::Result<()> {
        Ok(())
    }
    /// Indirect radiance reflected towards `at.wo` at the first diffuse surface `at.it`.
    fn indirect(&self, ctx: &PhotonContext, at: &GatherPoint, stats: &mut TraversalStats) -> Color;
    /// Counters for reports (e.g. cache hits).
    fn counters(&self) -> Vec<(String, f64)> {
        Vec::new()
    }
    /// Points worth showing in a debug image (e.g. cache entries).
    fn debug_points(&self) -> Vec<Vec3> {
        Vec::new()
    }
}
