//! `direct`: direct visualisation of the photon map at the first diffuse hit (the
//! design report's noisy baseline). Direct light is ray traced and caustics come from
//! the caustic map, so the photon estimate here uses the indirect map only — adding
//! the direct map would count direct light twice.

use super::{Gather, PhotonContext, ShadeKey, with_heap};
use crate::accel::TraversalStats;
use crate::material::Bsdf;
use crate::math::Color;
use crate::photon::estimate;
use crate::world::{Interaction, World};
use glam::Vec3;

/// Direct visualisation.
pub struct DirectVisualisation;

impl Gather for DirectVisualisation {
    fn name(&self) -> &'static str {
        "direct"
    }
    #[allow(clippy::too_many_arguments)]
    fn indirect(
        &self,
        ctx: &PhotonContext,
        _world: &World,
        it: &Interaction,
        wo: Vec3,
        bsdf: &Bsdf,
        _key: ShadeKey,
        _stats: &mut TraversalStats,
    ) -> Color {
        with_heap(|h| estimate::radiance(&ctx.maps.indirect, it, wo, bsdf, &ctx.est_global, h))
    }
}
