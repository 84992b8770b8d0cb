//! Directional (distant) light.

use super::LightSample;
use crate::math::Color;
use glam::Vec3;

pub(super) fn sample_li(direction: Vec3, irradiance: Color) -> Option<LightSample> {
    Some(LightSample { wi: -direction, dist: f32::INFINITY, li: irradiance, pdf: 1.0, delta: true, point: Vec3::ZERO, normal: Vec3::ZERO })
}
