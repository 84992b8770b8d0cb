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
        if !reflects(sp, wo, wi) {
            return Color::ZERO;
        }
        self.albedo * FRAC_1_PI
    }

    pub(super) fn pdf(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> f32 {
        if !reflects(sp, wo, wi) {
            return 0.0;
        }
        let (_, li) = local_pair(sp, wo, wi);
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

/// Whether a Lambertian surface reflects light from `wi` towards `wo` (both on the
/// geometric normal's same side and above the shading frame's horizon). Scaling
/// either direction by a positive factor does not change the answer.
#[inline]
pub fn reflects(sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> bool {
    Reflects::towards(sp, wo).from(wi)
}

/// [`reflects`] for one `wo` and many `wi` (a radiance estimate's photons): what
/// depends on `wo` alone, computed once.
#[derive(Clone, Copy, Debug)]
pub struct Reflects {
    ng: Vec3,
    wo_ng: f32,
    /// The shading normal turned to `wo`'s side (zero when `wo` lies in its plane).
    n: Vec3,
}

impl Reflects {
    /// The test for light leaving towards `wo`.
    #[inline]
    pub fn towards(sp: &ShadingPoint, wo: Vec3) -> Self {
        // As `local_pair`: both directions flipped when wo is below the shading
        // frame, so the test is wi·n on wo's side of the shading normal.
        let lo_z = sp.frame.to_local(wo).z;
        let n = if lo_z > 0.0 {
            sp.frame.n
        } else if lo_z < 0.0 {
            -sp.frame.n
        } else {
            Vec3::ZERO
        };
        Reflects { ng: sp.ng, wo_ng: wo.dot(sp.ng), n }
    }

    /// Whether light from `wi` is reflected.
    #[inline(always)]
    pub fn from(&self, wi: Vec3) -> bool {
        self.wo_ng * wi.dot(self.ng) > 0.0 && wi.dot(self.n) > 0.0
    }
}
