//! `off`: no roulette; paths end only at the fixed maximum depth.

use super::{RrContext, RussianRoulette};

/// Never terminates.
pub struct Off;

impl RussianRoulette for Off {
    fn name(&self) -> &'static str {
        "off"
    }
    fn survival_probability(&self, _: &RrContext) -> f32 {
        1.0
    }
    fn never_terminates(&self) -> bool {
        true
    }
}
