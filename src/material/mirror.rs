//! Perfect mirror on both sides.

use super::{BsdfSample, ShadingPoint, same_side};
use crate::math::{Color, reflect};
use glam::Vec3;

/// Perfect specular reflector with per-channel reflectance.
#[derive(Clone, Debug, PartialEq)]
pub struct Mirror {
    /// Reflectance per channel.
    pub reflectance: Color,
}

impl Mirror {
    pub(super) fn sample(&self, sp: &ShadingPoint, wo: Vec3) -> Option<BsdfSample> {
        let n = if wo.dot(sp.ns()) < 0.0 { -sp.ns() } else { sp.ns() };
        let wi = reflect(wo, n).normalize();
        if !same_side(sp, wo, wi) {
            return None;
        }
        let cos = wi.dot(n).abs().max(1e-8);
        Some(BsdfSample { wi, f: self.reflectance / cos, pdf: 1.0, weight: self.reflectance, delta: true })
    }
}
