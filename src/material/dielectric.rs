//! Smooth dielectric: exact Fresnel reflection and refraction, total internal
//! reflection, transmission tint applied at every crossing (scene contract). As
//! Mitsuba 3's `dielectric`, the reflected part is multiplied by
//! `specular_reflectance` and the transmitted part by the tint
//! (`specular_transmittance`); the lobe probabilities stay Fresnel's.

use super::{BsdfSample, ShadingPoint, TransportMode};
use crate::math::{Color, reflect};
use glam::Vec3;

/// Smooth glass. The triangle's front side is outside (index 1), its back inside.
#[derive(Clone, Debug, PartialEq)]
pub struct Dielectric {
    /// Index of refraction of the inside.
    pub ior: f32,
    /// Transmission tint multiplied in at every transmission (Mitsuba's
    /// `specular_transmittance`).
    pub tint: Color,
    /// Multiplier on reflection (Mitsuba's `specular_reflectance`; 1 in the scene
    /// contract's glass).
    pub specular_reflectance: Color,
}

/// Unpolarised Fresnel reflectance for light arriving with cosine `cos_i` (> 0) on the
/// side of index `eta_i`, across to index `eta_t`. Returns 1 on total internal reflection.
pub fn fresnel_dielectric(cos_i: f32, eta_i: f32, eta_t: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
    let sin_t = eta_i / eta_t * sin_i;
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).max(0.0).sqrt();
    let r_par = (eta_t * cos_i - eta_i * cos_t) / (eta_t * cos_i + eta_i * cos_t);
    let r_perp = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t);
    0.5 * (r_par * r_par + r_perp * r_perp)
}

/// Fresnel reflectance at normal incidence from index 1 to `ior` (cosine 1).
pub fn fresnel(cos_i: f32, ior: f32) -> f32 {
    fresnel_dielectric(cos_i, 1.0, ior)
}

impl Dielectric {
    /// Glass of index `ior` with a transmission tint, reflecting unscaled.
    pub fn new(ior: f32, tint: Color) -> Self {
        Dielectric { ior, tint, specular_reflectance: Color::ONE }
    }

    pub(super) fn sample(&self, sp: &ShadingPoint, wo: Vec3, u_lobe: f32, mode: TransportMode) -> Option<BsdfSample> {
        // Outside = front = the side the geometric normal points to.
        let outside = wo.dot(sp.ng) > 0.0;
        let (eta_o, eta_t) = if outside { (1.0, self.ior) } else { (self.ior, 1.0) };
        let n = if outside { sp.ns() } else { -sp.ns() };
        let cos_o = wo.dot(n);
        if cos_o <= 0.0 {
            // Shading normal disagrees with the side: treat as a mirror about ng.
            let ng = if outside { sp.ng } else { -sp.ng };
            let wi = reflect(wo, ng).normalize();
            let w = self.specular_reflectance;
            return Some(BsdfSample { wi, f: w, pdf: 1.0, weight: w, delta: true });
        }
        let f = fresnel_dielectric(cos_o, eta_o, eta_t);
        if u_lobe < f {
            let wi = reflect(wo, n).normalize();
            let cos = wi.dot(n).abs().max(1e-8);
            let w = self.specular_reflectance;
            return Some(BsdfSample { wi, f: w * f / cos, pdf: f, weight: w, delta: true });
        }
        // Refraction (Snell) about n, from the wo side into the other side.
        let eta = eta_o / eta_t;
        let sin2_t = eta * eta * (1.0 - cos_o * cos_o).max(0.0);
        if sin2_t >= 1.0 {
            return None; // unreachable: f == 1 then
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        let wi = (-wo * eta + n * (eta * cos_o - cos_t)).normalize();
        // The refracted ray must actually cross the geometric surface.
        if wi.dot(sp.ng) * wo.dot(sp.ng) >= 0.0 {
            return None;
        }
        let mut weight = self.tint;
        if mode == TransportMode::Radiance {
            // Radiance is compressed by (η_t/η_i)² crossing into the denser medium; along
            // the camera path light travels wi -> wo, i.e. from index eta_t to eta_o.
            weight *= (eta_o / eta_t) * (eta_o / eta_t);
        }
        let cos = wi.dot(n).abs().max(1e-8);
        let pdf = 1.0 - f;
        Some(BsdfSample { wi, f: weight * pdf / cos, pdf, weight, delta: true })
    }
}

#[cfg(test)]
mod tests {
    use super::super::*;
    use super::*;

    #[test]
    fn fresnel_known_values() {
        // Normal incidence, n = 1.5: ((1.5-1)/(1.5+1))^2 = 0.04.
        assert!((fresnel_dielectric(1.0, 1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing: 1.
        assert!((fresnel_dielectric(0.0, 1.0, 1.5) - 1.0).abs() < 1e-6);
        // TIR beyond the critical angle from inside (sin > 1/1.5).
        assert_eq!(fresnel_dielectric(0.5, 1.5, 1.0), 1.0);
        // Symmetry of reflectance across the interface at matching angles.
        let cos_i: f32 = 0.8;
        let sin_t = (1.0 - cos_i * cos_i).sqrt() / 1.5;
        let cos_t = (1.0 - sin_t * sin_t).sqrt();
        assert!((fresnel_dielectric(cos_i, 1.0, 1.5) - fresnel_dielectric(cos_t, 1.5, 1.0)).abs() < 1e-5);
    }

    #[test]
    fn refraction_follows_snell_and_scales_radiance() {
        let g = Bsdf::Dielectric(Dielectric::new(1.5, Color::ONE));
        let sp = ShadingPoint::new(Vec3::Z, Vec3::Z);
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let s = g.sample(&sp, wo, 0.99, [0.0, 0.0], TransportMode::Radiance).unwrap();
        assert!(s.wi.z < 0.0);
        let sin_t = (s.wi.x * s.wi.x + s.wi.y * s.wi.y).sqrt();
        assert!((sin_t - 0.6 / 1.5).abs() < 1e-5);
        assert!((s.weight.x - 1.0 / 2.25).abs() < 1e-5);
        let s2 = g.sample(&sp, wo, 0.99, [0.0, 0.0], TransportMode::Importance).unwrap();
        assert!((s2.weight.x - 1.0).abs() < 1e-6);
        // From inside at a steep angle: total internal reflection.
        let wo_in = Vec3::new(0.9, 0.0, -(1.0f32 - 0.81).sqrt());
        let s3 = g.sample(&sp, wo_in, 0.99, [0.0, 0.0], TransportMode::Radiance).unwrap();
        assert!(s3.wi.z < 0.0 && (s3.wi.x + 0.9).abs() < 1e-5);
    }
}
