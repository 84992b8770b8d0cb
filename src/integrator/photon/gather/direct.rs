//! `direct`: direct visualisation of the photon map at the first diffuse hit (the
//! design report's noisy baseline). Direct light is ray traced and caustics come from
//! the caustic map, so the photon estimate here uses the indirect map only — adding
//! the direct map would count direct light twice.

use super::Gather;
use crate::accel::TraversalStats;
use crate::integrator::photon::context::{GatherPoint, PhotonContext};
use crate::math::Color;
use crate::photon::estimate::{self, with_heap};

/// Direct visualisation.
pub struct DirectVisualisation;

impl Gather for DirectVisualisation {
    fn name(&self) -> &'static str {
        "direct"
    }
    fn indirect(&self, ctx: &PhotonContext, at: &GatherPoint, stats: &mut TraversalStats) -> Color {
        // The integrator builds the indirect map's tree for this gather (`map_trees`).
        ctx.maps.indirect.as_ref().map_or(Color::ZERO, |m| {
            with_heap(|h| estimate::radiance_in(Some((at.world, stats)), m, at.it, at.wo, at.bsdf, &ctx.est_global, h))
        })
    }
}
