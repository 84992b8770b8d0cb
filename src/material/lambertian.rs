//! Lambertian diffuse reflection on both sides.

use super::{BsdfSample, ShadingPoint, local_pair, same_side};
use crate::math::{Color, sin_cos_quarter};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;
use std::f32::consts::FRAC_PI_4;

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
        let mut li = cosine_hemisphere_selects(u);
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

/// [`crate::math::cosine_hemisphere`] without branches: the concentric map's two
/// cases (and the centre) chosen by selects after one division and one polynomial
/// sine and cosine, the same operations on the same values, so the same bits. Its
/// 50/50 branch was mispredicted half the time.
#[inline]
pub fn cosine_hemisphere_selects(u: [f32; 2]) -> Vec3 {
    let ox = 2.0 * u[0] - 1.0;
    let oy = 2.0 * u[1] - 1.0;
    let x_major = ox.abs() > oy.abs();
    let (num, r) = select2(x_major, (oy, ox), (ox, oy));
    let (s, c) = sin_cos_quarter(FRAC_PI_4 * (num / r));
    // x = r·cos, y = r·sin when |ox| > |oy|; x = r·sin, y = r·cos otherwise.
    let (a, b) = select2(x_major, (c, s), (s, c));
    let centre = ox == 0.0 && oy == 0.0;
    let (dx, dy) = select2(centre, (0.0, 0.0), (r * a, r * b));
    let z = (1.0 - dx * dx - dy * dy).max(0.0).sqrt();
    Vec3::new(dx, dy, z)
}

/// `if c { a } else { b }` on pairs, written so the compiler emits selects.
#[inline(always)]
fn select2(c: bool, a: (f32, f32), b: (f32, f32)) -> (f32, f32) {
    let m = (c as u32).wrapping_neg();
    let pick = |x: f32, y: f32| f32::from_bits((x.to_bits() & m) | (y.to_bits() & !m));
    (pick(a.0, b.0), pick(a.1, b.1))
}

#[cfg(test)]
mod tests {
    use super::super::tests::{directional_albedo, sampled_albedo};
    use super::super::*;
    use super::cosine_hemisphere_selects;
    use crate::math::cosine_hemisphere;

    /// The select version gives the bits of the branching one: on a grid (with the
    /// centre, the diagonals |ox| = |oy| and the axes), and on hashed points.
    #[test]
    fn selects_equal_the_branches_bit_for_bit() {
        let mut us: Vec<[f32; 2]> = Vec::new();
        for i in 0..=256 {
            for j in 0..=256 {
                us.push([i as f32 / 256.0, j as f32 / 256.0]);
            }
        }
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..200_000 {
            x = crate::math::mix64(x);
            us.push([crate::math::u32_to_unit(x as u32), crate::math::u32_to_unit((x >> 32) as u32)]);
        }
        us.push([0.5, 0.5]);
        us.push([crate::math::ONE_MINUS_EPSILON, 0.0]);
        for u in us {
            let (a, b) = (cosine_hemisphere_selects(u), cosine_hemisphere(u));
            assert_eq!(a.to_array().map(f32::to_bits), b.to_array().map(f32::to_bits), "u = {u:?}");
        }
    }

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
