//! `fixed:q`: every bounce survives with the same probability q (default 0.8).

use super::{RrContext, RussianRoulette};

/// Constant survival probability.
pub struct Fixed {
    q: f32,
}

impl Fixed {
    /// Default survival probability.
    pub const DEFAULT_Q: f32 = 0.8;
    /// New policy; q must be in (0, 1].
    pub fn new(q: f32) -> anyhow::Result<Self> {
        if !(q > 0.0 && q <= 1.0) {
            return Err(anyhow::anyhow!("rr fixed: survival probability must be in (0, 1], got {q}"));
        }
        Ok(Fixed { q })
    }
}

impl RussianRoulette for Fixed {
    fn name(&self) -> &'static str {
        "fixed"
    }
    fn survival_probability(&self, _: &RrContext) -> f32 {
        self.q
    }
}
