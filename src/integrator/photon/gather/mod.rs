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
        /// Final-gather rays at the first level (cosine-weighted, points from the configured sampler).
        gather_samples: u32 = "64",
        /// Final-gather levels (≥ 1); each deeper level uses 1/8 of the rays of the one above (at least 4).
        gather_bounces: u32 = "1",
        /// Rays drawn from the glossy lobe at glossy gathering points (the diffuse part uses the gather or the cache).
        glossy_samples: u32 = "16",
        /// What `gather_samples` and `glossy_samples` count at camera-sample hits: rays per camera `sample`, or per `pixel` (each of the pixel's spp samples traces ⌈count / spp⌉ of one point set stratified over the pixel).
        gather_per: String = "sample",
    }
}

/// A gather plug-in chosen by name, with the parameters it read; `build` makes a fresh
/// instance (the progressive `ppm` builds one per pass).
#[derive(Clone, Debug, PartialEq)]
pub enum GatherSpec {
    /// `direct`.
    Direct,
    /// `final_gather`.
    FinalGather(GatherParams),
    /// `precomputed`.
    Precomputed(GatherParams, precomputed::PrecomputedParams),
    /// `irradiance_cache`.
    Cache(GatherParams, precomputed::PrecomputedParams, irradiance_cache::CacheSettings),
}

impl GatherSpec {
    /// Reads the parameters of gather `name`.
    pub fn read(name: &str, r: &crate::param::Reader) -> anyhow::Result<Self> {
        r.chose(format!("gather `{name}`"));
        let g = |r| -> anyhow::Result<GatherParams> {
            let g = GatherParams::read(r)?;
            if g.gather_bounces == 0 || g.gather_samples == 0 || g.glossy_samples == 0 {
                anyhow::bail!("gather_bounces, gather_samples and glossy_samples must be at least 1");
            }
            if !GATHER_PER.contains(&g.gather_per.as_str()) {
                anyhow::bail!("gather_per must be one of {}, got `{}`", GATHER_PER.join(", "), g.gather_per);
            }
            Ok(g)
        };
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

    /// The final-gather settings (defaults for `direct`, which does not gather).
    pub fn gather_params(&self) -> GatherParams {
        match self {
            GatherSpec::Direct => GatherParams::default(),
            GatherSpec::FinalGather(g) | GatherSpec::Precomputed(g, _) | GatherSpec::Cache(g, _, _) => g.clone(),
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
