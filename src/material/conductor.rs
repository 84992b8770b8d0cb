//! Mitsuba 3's `conductor`: a smooth metal, one-sided (black from the back), perfect
//! specular reflection weighted by the complex Fresnel term of `eta` + i·`k` (per RGB
//! channel) times `specular_reflectance`.

use super::fresnel::fresnel_conductor;
use super::{BsdfSample, ShadingPoint};
use crate::math::{Color, reflect};
use glam::Vec3;

/// Smooth conductor.
#[derive(Clone, Debug, PartialEq)]
pub struct Conductor {
    /// Real part of the relative index, per channel.
    pub eta: Color,
    /// Imaginary part (absorption), per channel.
    pub k: Color,
    /// Multiplier on the reflectance (Mitsuba: `specular_reflectance`, default 1).
    pub specular_reflectance: Color,
}

/// Per-channel conductor Fresnel reflectance.
#[inline]
pub(super) fn fresnel_rgb(cos_i: f32, eta: Color, k: Color) -> Color {
    Color::new(fresnel_conductor(cos_i, eta.x, k.x), fresnel_conductor(cos_i, eta.y, k.y), fresnel_conductor(cos_i, eta.z, k.z))
}

impl Conductor {
    /// The one delta lobe: mirror direction about the shading normal and its weight
    /// (`None` from the back or when the mirror direction leaves through the surface).
    pub(super) fn branch(&self, sp: &ShadingPoint, wo: Vec3) -> Option<(Vec3, Color)> {
        let cos_o = wo.dot(sp.ns());
        if wo.dot(sp.ng) <= 0.0 || cos_o <= 0.0 {
            return None;
        }
        let wi = reflect(wo, sp.ns()).normalize();
        if wi.dot(sp.ng) <= 0.0 {
            return None;
        }
        Some((wi, self.specular_reflectance * fresnel_rgb(cos_o, self.eta, self.k)))
    }

    pub(super) fn sample(&self, sp: &ShadingPoint, wo: Vec3) -> Option<BsdfSample> {
        let (wi, w) = self.branch(sp, wo)?;
        let cos = wi.dot(sp.ns()).abs().max(1e-8);
        Some(BsdfSample { wi, f: w / cos, pdf: 1.0, weight: w, delta: true })
    }
}

#[cfg(test)]
mod tests {
    use super::super::*;

    #[test]
    fn one_sided_mirror_with_conductor_fresnel() {
        let c =
            Bsdf::Conductor(Conductor { eta: Color::new(0.2, 0.9, 1.1), k: Color::new(3.9, 2.4, 1.9), specular_reflectance: Color::ONE });
        let sp = ShadingPoint::new(Vec3::Z, Vec3::Z);
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let s = c.sample(&sp, wo, 0.3, [0.1, 0.2], TransportMode::Radiance).unwrap();
        assert!(s.delta && (s.wi - Vec3::new(-0.6, 0.0, 0.8)).length() < 1e-6);
        assert!(s.weight.max_element() <= 1.0 && s.weight.min_element() > 0.4);
        assert!(c.sample(&sp, -wo, 0.3, [0.1, 0.2], TransportMode::Radiance).is_none());
        assert_eq!(c.eval(&sp, wo, s.wi), Color::ZERO);
        assert!(c.is_delta());
    }
}
