//! Emissive triangle: area-uniform point sampling, one-sided (front) emission.

use super::LightSample;
use crate::math::{Color, uniform_triangle};
use crate::scene::Scene;
use glam::Vec3;

pub(super) fn sample_li(scene: &Scene, tri: u32, radiance: Color, area: f32, normal: Vec3, p: Vec3, u: [f32; 2]) -> Option<LightSample> {
    let t = &scene.triangles[tri as usize];
    let b = uniform_triangle(u);
    let y = t[0] * (1.0 - b[0] - b[1]) + t[1] * b[0] + t[2] * b[1];
    let d = y - p;
    let d2 = d.length_squared();
    if d2 <= 0.0 {
        return None;
    }
    let dist = d2.sqrt();
    let wi = d / dist;
    // Only the front side emits.
    let cos_l = -wi.dot(normal);
    if cos_l <= 0.0 {
        return None;
    }
    Some(LightSample { wi, dist, li: radiance, pdf: d2 / (cos_l * area), delta: false, point: y, normal })
}
