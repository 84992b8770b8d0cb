//! Isotropic point light.

use super::LightSample;
use crate::math::Color;
use glam::Vec3;

pub(super) fn sample_li(position: Vec3, intensity: Color, p: Vec3) -> Option<LightSample> {
    let d = position - p;
    let d2 = d.length_squared();
    if d2 <= 0.0 {
        return None;
    }
    let dist = d2.sqrt();
    Some(LightSample { wi: d / dist, dist, li: intensity / d2, pdf: 1.0, delta: true, point: position, normal: Vec3::ZERO })
}
