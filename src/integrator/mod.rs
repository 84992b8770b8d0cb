//! Integrators (chosen by name: `path`, `photon`, `sppm`, `ppm`, `bdpt`, `vcm`).

pub mod bidir;
pub mod path;
pub mod photon;
pub mod progressive;
pub mod render;

use crate::accel::TraversalStats;
use crate::film::Film;
use crate::geometry::Ray;
use crate::integrator::render::RenderStats;
use crate::math::Color;
use crate::sampler::{AnySampler, Sampler};
use crate::world::World;
use std::collections::BTreeMap;

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
    /// [`Integrator::li`] with the sampler by value, which an integrator may match once
    /// ([`crate::sampler::with_sampler!`]) to draw without a virtual call per
    /// dimension; the same values either way. Default: `li` with a trait object.
    fn li_any(&self, world: &World, ray: &Ray, sampler: &mut AnySampler, stats: &mut TraversalStats) -> Color {
        crate::sampler::with_sampler!(sampler, s => self.li(world, ray, s, stats))
    }
    /// Switches what `li` returns to an extra image (AOV) by name.
    fn set_output(&mut self, aov: &str) -> anyhow::Result<()> {
        anyhow::bail!("integrator `{}` has no extra image `{aov}`", self.name())
    }
    /// Named counters and phase times of the last preprocess/render (for reports).
    fn stats(&self) -> BTreeMap<String, f64> {
        BTreeMap::new()
    }
    /// World-space points to mark in a debug image (e.g. irradiance-cache entries).
    fn debug_points(&self) -> Vec<glam::Vec3> {
        Vec::new()
    }
    /// Whether this is a progressive integrator (renders in passes; `record_passes`).
    fn is_progressive(&self) -> bool {
        false
    }
    /// Progressive integrators (`sppm`, `ppm`) render the whole image themselves, pass
    /// by pass, calling `on_pass` with each pass's image; `None` = use the render pass.
    fn render_progressive(&mut self, _world: &World, _on_pass: progressive::OnPass) -> Option<anyhow::Result<(Film, RenderStats)>> {
        None
    }
    /// Extra images the integrator renders itself in one run, by AOV name (e.g.
    /// `strategies`: one image per technique); `None` = render the AOV with `li`.
    fn render_aov(&mut self, _world: &World, _aov: &str) -> Option<anyhow::Result<Vec<(String, Film)>>> {
        None
    }
}
