//! `final_gather`: `gather_samples` cosine-weighted rays over the hemisphere (points
//! from the configured sampler, so stratified for `halton`/`hammersley`), each shaded
//! with a photon-map estimate where it lands; `gather_bounces` levels.

use super::{Gather, PhotonContext, ShadeKey};
use crate::accel::TraversalStats;
use crate::material::Bsdf;
use crate::math::Color;
use crate::world::{Interaction, World};
use glam::Vec3;

/// Final gathering.
pub struct FinalGather;

impl Gather for FinalGather {
    fn name(&self) -> &'static str {
        "final_gather"
    }
    #[allow(clippy::too_many_arguments)]
    fn indirect(
        &self,
        ctx: &PhotonContext,
        world: &World,
        it: &Interaction,
        wo: Vec3,
        bsdf: &Bsdf,
        key: ShadeKey,
        stats: &mut TraversalStats,
    ) -> Color {
        ctx.gathered_indirect(world, it, wo, bsdf, 0, key, stats)
    }
}
