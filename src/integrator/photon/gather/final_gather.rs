//! `final_gather`: `gather_samples` cosine-weighted rays over the hemisphere (points
//! from the configured sampler, so stratified for `halton`/`hammersley`), each shaded
//! with a photon-map estimate where it lands; `gather_bounces` levels. By default the
//! first level's rays (and the glossy lobe's) are a pixel's, shared out over its camera
//! samples ([`super::Gathering`], [`crate::integrator::photon::context::PixelSplit`]).
//!
//! The same gather serves `precomputed` (see [`super::precomputed`]): the one
//! difference is what a gather ray finds where it lands, a full photon estimate here or
//! Christensen's precomputed irradiance there. That choice is made when the photon
//! integrator builds its context (it precomputes irradiance when the plug-in asks for
//! it, [`super::GatherSpec::precompute_stride`]); this type only carries the name.

use super::Gather;
use crate::accel::TraversalStats;
use crate::integrator::photon::context::{GatherPoint, PhotonContext};
use crate::math::Color;

/// Final gathering (`final_gather`, or `precomputed` when `over_precomputed`).
pub struct FinalGather {
    /// Gather rays look up precomputed irradiance (the `precomputed` plug-in).
    pub over_precomputed: bool,
}

impl FinalGather {
    /// The `final_gather` plug-in.
    pub fn plain() -> Self {
        FinalGather { over_precomputed: false }
    }
}

impl Gather for FinalGather {
    fn name(&self) -> &'static str {
        if self.over_precomputed { "precomputed" } else { "final_gather" }
    }
    fn indirect(&self, ctx: &PhotonContext, at: &GatherPoint, stats: &mut TraversalStats) -> Color {
        ctx.gathered_indirect(at, 0, stats)
    }
}
