//! Integrators (chosen by name: `path`; `photon` arrives with the photon-mapping work).

pub mod path;

use crate::accel::TraversalStats;
use crate::geometry::Ray;
use crate::math::Color;
use crate::sampler::Sampler;
use crate::world::World;

/// Estimates the radiance arriving along camera rays.
pub trait Integrator: Send + Sync {
    /// Configuration name.
    fn name(&self) -> &'static str;
    /// Work before the render pass (photon tracing, caches). Default: none.
    fn preprocess(&mut self, _world: &World) -> anyhow::Result<()> {
        Ok(())
    }
    /// Radiance along `ray`; the sampler has been started for this pixel sample and
    /// its dimensions 0–1 used for the pixel position.
    fn li(&self, world: &World, ray: &Ray, sampler: &mut dyn Sampler, stats: &mut TraversalStats) -> Color;
}
