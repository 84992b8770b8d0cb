//! Lambertian diffuse reflection on both sides.

use super::{BsdfSample, ShadingPoint, local_pair, same_side};
use crate::math::{Color, cosine_hemisphere};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

/// Lambertian BRDF f = albedo / π.
#[derive(Clone, Debug, PartialEq)]
pub struct Lambertian {
    /// Reflectance per channel.
    pub albedo: Color,
}

impl Lambertian {
    pub(super) fn eval(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> Color {
        let (lo, li) = local_pair(sp, wo, wi);
        if !same_side(sp, wo, wi) || li.z <= 0.0 || lo.z <= 0.0 {
            return Color::ZERO;
        }
        self.albedo * FRAC_1_PI
    }

    pub(super) fn pdf(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> f32 {
        let (lo, li) = local_pair(sp, wo, wi);
        if !same_side(sp, wo, wi) || li.z <= 0.0 || lo.z <= 0.0 {
            return 0.0;
        }
        li.z * FRAC_1_PI
    }

    pub(super) fn sample(&self, sp: &ShadingPoint, wo: Vec3, u: [f32; 2]) -> Option<BsdfSample> {
        let lo = sp.frame.to_local(wo);
        if lo.z == 0.0 {
            return None;
        }
        let mut li = cosine_hemisphere(u);
        if lo.z < 0.0 {
            li.z = -li.z;
        }
        let wi = sp.frame.to_world(li);
        if !same_side(sp, wo, wi) || li.z == 0.0 {
            return None;
        }
        let pdf = li.z.abs() * FRAC_1_PI;
        Some(BsdfSample { wi, f: self.albedo * FRAC_1_PI, pdf, weight: self.albedo, delta: false })
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{directional_albedo, sampled_albedo};
    use super::super::*;

    #[test]
    fn albedo_and_reciprocity() {
        let b = Bsdf::Lambertian(Lambertian { albedo: Color::new(0.8, 0.5, 0.2) });
        let sp = ShadingPoint::new(Vec3::Z, Vec3::Z);
        for wo in [Vec3::Z, Vec3::new(0.6, 0.0, 0.8), Vec3::new(0.0, 0.6, -0.8)] {
            let a = directional_albedo(&b, &sp, wo, 200);
            assert!((a - Color::new(0.8, 0.5, 0.2)).abs().max_element() < 0.01, "{a}");
            let s = sampled_albedo(&b, &sp, wo, 64);
            assert!((s - Color::new(0.8, 0.5, 0.2)).abs().max_element() < 1e-4, "{s}");
        }
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let wi = Vec3::new(-0.5, 0.2, 0.7).normalize();
        assert_eq!(b.eval(&sp, wo, wi), b.eval(&sp, wi, wo));
        assert_eq!(b.eval(&sp, wo, -wi), Color::ZERO);
    }
}
