//! `throughput:d`: after `d` bounces (default 3) survive with
//! min(1, max channel of the path throughput), as pbrt does. The `auto` default of
//! `path` is `throughput:5` (Mitsuba 3's `rr_depth`).

use super::{RrContext, RussianRoulette, clamp01};
use crate::math::max_component;

/// Throughput-based survival after a minimum depth.
pub struct Throughput {
    min_depth: u32,
}

impl Throughput {
    /// Default minimum depth.
    pub const DEFAULT_MIN_DEPTH: u32 = 3;
    /// Minimum depth of `path`'s default (`rr = "auto"`).
    pub const PATH_MIN_DEPTH: u32 = 5;
    /// New policy.
    pub fn new(min_depth: u32) -> Self {
        Throughput { min_depth }
    }
}

impl RussianRoulette for Throughput {
    fn name(&self) -> &'static str {
        "throughput"
    }
    fn survival_probability(&self, ctx: &RrContext) -> f32 {
        if ctx.depth < self.min_depth { 1.0 } else { clamp01(max_component(ctx.throughput)) }
    }
}
