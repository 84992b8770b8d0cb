//! `albedo`: survive with the reflectance of the surface just hit (max channel, at
//! most 1), as Jensen traces photons: on a white surface nothing is lost, on a dark
//! one most paths end.

use super::{RrContext, RussianRoulette, clamp01};
use crate::math::max_component;

/// Surface-reflectance survival.
pub struct Albedo;

impl RussianRoulette for Albedo {
    fn name(&self) -> &'static str {
        "albedo"
    }
    fn survival_probability(&self, ctx: &RrContext) -> f32 {
        clamp01(max_component(ctx.albedo))
    }
}
