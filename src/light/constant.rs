//! Uniform environment (Mitsuba's `constant`): the same radiance from every
//! direction, sampled uniformly over the sphere.

use crate::math::{Color, UNIFORM_SPHERE_PDF, mean, uniform_sphere};
use glam::Vec3;
use std::f32::consts::PI;

/// Direction towards the environment, its radiance and solid-angle pdf.
#[inline]
pub(super) fn sample(radiance: Color, u: [f32; 2]) -> (Vec3, Color, f32) {
    (uniform_sphere(u), radiance, UNIFORM_SPHERE_PDF)
}

/// ∫ mean(L) dω over the sphere.
pub(super) fn integral(radiance: Color) -> f32 {
    4.0 * PI * mean(radiance)
}
