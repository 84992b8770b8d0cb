//! Mitsuba 3's `thindielectric`: a thin pane (two parallel interfaces) with every
//! internal reflection summed: R' = R + T²R/(1−R²) = 2R/(1+R), T' = 1 − R'.
//! Both lobes are delta; transmission leaves undeflected (−wo), so there is no
//! radiance scaling. Two-sided.

use super::fresnel::fresnel_dielectric_eta;
use super::{BsdfSample, ShadingPoint};
use crate::math::{Color, reflect};
use glam::Vec3;

/// Thin dielectric sheet.
#[derive(Clone, Debug, PartialEq)]
pub struct ThinDielectric {
    /// Interior index.
    pub int_ior: f32,
    /// Exterior index.
    pub ext_ior: f32,
    /// Multiplier on reflection.
    pub specular_reflectance: Color,
    /// Multiplier on transmission.
    pub specular_transmittance: Color,
}

impl ThinDielectric {
    /// Total reflectance of the sheet for a direction with |cos| `cos_o`.
    pub fn reflectance(&self, cos_o: f32) -> f32 {
        let r = fresnel_dielectric_eta(cos_o.abs(), self.int_ior / self.ext_ior);
        if r < 1.0 { 2.0 * r / (1.0 + r) } else { 1.0 }
    }

    /// The two delta lobes: (mirror direction, R'·specular_reflectance) and
    /// (−wo, T'·specular_transmittance).
    pub(super) fn branches(&self, sp: &ShadingPoint, wo: Vec3) -> [(Vec3, Color); 2] {
        let n = if wo.dot(sp.ns()) < 0.0 { -sp.ns() } else { sp.ns() };
        let r = self.reflectance(wo.dot(n));
        let wr = reflect(wo, n).normalize();
        let rw = if wr.dot(sp.ng) * wo.dot(sp.ng) > 0.0 { self.specular_reflectance * r } else { Color::ZERO };
        [(wr, rw), (-wo, self.specular_transmittance * (1.0 - r))]
    }

    pub(super) fn sample(&self, sp: &ShadingPoint, wo: Vec3, u_lobe: f32) -> Option<BsdfSample> {
        let n = if wo.dot(sp.ns()) < 0.0 { -sp.ns() } else { sp.ns() };
        let cos_o = wo.dot(n);
        if cos_o <= 0.0 && wo.dot(sp.ng) == 0.0 {
            return None;
        }
        let r = self.reflectance(cos_o);
        let [(wr, _), (wt, _)] = self.branches(sp, wo);
        let (wi, pdf, w) = if u_lobe < r { (wr, r, self.specular_reflectance) } else { (wt, 1.0 - r, self.specular_transmittance) };
        if u_lobe < r && wi.dot(sp.ng) * wo.dot(sp.ng) <= 0.0 {
            return None;
        }
        let cos = wi.dot(n).abs().max(1e-8);
        Some(BsdfSample { wi, f: w * pdf / cos, pdf, weight: w, delta: true })
    }
}

#[cfg(test)]
mod tests {
    use super::super::*;

    #[test]
    fn lobes_sum_to_one_and_match_the_series() {
        let t = ThinDielectric { int_ior: 1.5, ext_ior: 1.0, specular_reflectance: Color::ONE, specular_transmittance: Color::ONE };
        for ct in [1.0f32, 0.6, 0.1] {
            let r = fresnel::fresnel_dielectric_eta(ct, 1.5);
            // Σ over bounces: R + T²R Σ (R²)^k.
            let mut series = r;
            let mut term = (1.0 - r) * (1.0 - r) * r;
            for _ in 0..200 {
                series += term;
                term *= r * r;
            }
            assert!((t.reflectance(ct) - series).abs() < 1e-5);
        }
        let b = Bsdf::ThinDielectric(t);
        let sp = ShadingPoint::new(Vec3::Z, Vec3::Z);
        let wo = Vec3::new(0.6, 0.0, -0.8);
        let (br, n) = b.specular_branches(&sp, wo, TransportMode::Radiance);
        assert_eq!(n, 2);
        assert!((br[0].1.x + br[1].1.x - 1.0).abs() < 1e-6);
        assert!(br[0].0.z < 0.0 && br[1].0 == -wo);
        let s = b.sample(&sp, wo, 0.999, [0.5; 2], TransportMode::Radiance).unwrap();
        assert!(s.delta && s.wi == -wo && s.weight == Color::ONE);
    }
}
