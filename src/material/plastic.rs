//! Mitsuba 3's `plastic`: a smooth dielectric coating (delta reflection, Fresnel
//! weighted) over a diffuse base, one-sided. The base's light crosses the coating
//! twice and is reflected back inside with the hemispherical internal reflectance
//! F_dr,int, which the geometric series sums:
//! f_diffuse = ρ / (1 − F_dr,int·(ρ if `nonlinear` else 1)) · (1−F(wo))(1−F(wi)) / (η² π).
//! The coating is chosen with probability F(wo)·w / (F(wo)·w + (1−F(wo))(1−w)), w the
//! `specular_sampling_weight` = mean(ks) / (mean(kd) + mean(ks)) as Mitsuba derives it.

use super::fresnel::{fresnel_dielectric_eta, fresnel_diffuse_reflectance};
use super::{BsdfSample, ShadingPoint, front_pair};
use crate::math::{Color, cosine_hemisphere, mean, reflect};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

/// Smooth plastic.
#[derive(Clone, Debug, PartialEq)]
pub struct Plastic {
    /// Base reflectance ρ (Mitsuba default 0.5).
    pub diffuse_reflectance: Color,
    /// Multiplier on the coating's reflection (default 1).
    pub specular_reflectance: Color,
    /// Coating index (default 1.49, polypropylene).
    pub int_ior: f32,
    /// Exterior index (default 1.000277).
    pub ext_ior: f32,
    /// Mitsuba's `nonlinear`: internal scattering darkens and saturates the colour.
    pub nonlinear: bool,
    /// Probability weight of the coating lobe (derived; see the module docs).
    pub specular_sampling_weight: f32,
    /// F_dr of the coating seen from inside (derived).
    pub fdr_int: f32,
}

impl Plastic {
    /// Builds the material with its derived terms.
    pub fn new(diffuse_reflectance: Color, specular_reflectance: Color, int_ior: f32, ext_ior: f32, nonlinear: bool) -> Self {
        let eta = int_ior / ext_ior;
        Plastic {
            specular_sampling_weight: sampling_weight(diffuse_reflectance, specular_reflectance),
            fdr_int: fresnel_diffuse_reflectance(1.0 / eta),
            diffuse_reflectance,
            specular_reflectance,
            int_ior,
            ext_ior,
            nonlinear,
        }
    }

    #[inline]
    fn eta(&self) -> f32 {
        self.int_ior / self.ext_ior
    }

    /// ρ / (1 − F_dr,int·(ρ or 1)) / η²: the base's albedo as seen through the coating
    /// before the two Fresnel transmissions.
    #[inline]
    pub(super) fn base(&self, fdr_int: f32) -> Color {
        let d = self.diffuse_reflectance;
        let denom = if self.nonlinear { Color::ONE - d * fdr_int } else { Color::splat(1.0 - fdr_int) };
        d / denom / (self.eta() * self.eta())
    }

    #[inline]
    fn prob_specular(&self, f_o: f32) -> f32 {
        let w = self.specular_sampling_weight;
        let (ps, pd) = (f_o * w, (1.0 - f_o) * (1.0 - w));
        if ps + pd > 0.0 { ps / (ps + pd) } else { 0.0 }
    }

    pub(super) fn eval(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> Color {
        let Some((lo, li)) = front_pair(sp, wo, wi) else { return Color::ZERO };
        let (fo, fi) = (fresnel_dielectric_eta(lo.z, self.eta()), fresnel_dielectric_eta(li.z, self.eta()));
        self.base(self.fdr_int) * ((1.0 - fo) * (1.0 - fi) * FRAC_1_PI)
    }

    pub(super) fn pdf(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> f32 {
        let Some((lo, li)) = front_pair(sp, wo, wi) else { return 0.0 };
        (1.0 - self.prob_specular(fresnel_dielectric_eta(lo.z, self.eta()))) * li.z * FRAC_1_PI
    }

    /// The coating's delta lobe: mirror direction and F(wo)·specular_reflectance.
    pub(super) fn branch(&self, sp: &ShadingPoint, wo: Vec3) -> Option<(Vec3, Color)> {
        let cos_o = wo.dot(sp.ns());
        if wo.dot(sp.ng) <= 0.0 || cos_o <= 0.0 {
            return None;
        }
        let wi = reflect(wo, sp.ns()).normalize();
        if wi.dot(sp.ng) <= 0.0 {
            return None;
        }
        Some((wi, self.specular_reflectance * fresnel_dielectric_eta(cos_o, self.eta())))
    }

    /// The base alone, cosine-sampled: wi and f_diffuse·cos/pdf.
    pub(super) fn sample_base(&self, sp: &ShadingPoint, wo: Vec3, u: [f32; 2]) -> Option<(Vec3, Color)> {
        let lo = sp.frame.to_local(wo);
        if lo.z <= 0.0 || wo.dot(sp.ng) <= 0.0 {
            return None;
        }
        let li = cosine_hemisphere(u);
        let wi = sp.frame.to_world(li);
        if li.z <= 0.0 || wi.dot(sp.ng) <= 0.0 {
            return None;
        }
        let (fo, fi) = (fresnel_dielectric_eta(lo.z, self.eta()), fresnel_dielectric_eta(li.z, self.eta()));
        Some((wi, self.base(self.fdr_int) * ((1.0 - fo) * (1.0 - fi))))
    }

    pub(super) fn sample(&self, sp: &ShadingPoint, wo: Vec3, u_lobe: f32, u: [f32; 2]) -> Option<BsdfSample> {
        let cos_o = wo.dot(sp.ns());
        if wo.dot(sp.ng) <= 0.0 || cos_o <= 0.0 {
            return None;
        }
        let fo = fresnel_dielectric_eta(cos_o, self.eta());
        let ps = self.prob_specular(fo);
        if u_lobe < ps {
            let (wi, w) = self.branch(sp, wo)?;
            let cos = wi.dot(sp.ns()).max(1e-8);
            return Some(BsdfSample { wi, f: w / cos, pdf: ps, weight: w / ps, delta: true });
        }
        let (wi, w) = self.sample_base(sp, wo, u)?;
        let cos = wi.dot(sp.ns());
        let pdf = (1.0 - ps) * cos * FRAC_1_PI;
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        Some(BsdfSample { wi, f: w * FRAC_1_PI, pdf, weight: w / (1.0 - ps), delta: false })
    }

    /// Directional albedo of coating + base (for Russian roulette).
    pub(super) fn albedo(&self) -> Color {
        let fdr_ext = 1.0 - (1.0 - self.fdr_int) * self.eta() * self.eta();
        self.specular_reflectance * fdr_ext + self.base(self.fdr_int) * (1.0 - fdr_ext) * (1.0 - fdr_ext)
    }
}

/// Mitsuba's `specular_sampling_weight`: mean(ks) / (mean(kd) + mean(ks)).
pub(super) fn sampling_weight(kd: Color, ks: Color) -> f32 {
    let (d, s) = (mean(kd).max(0.0), mean(ks).max(0.0));
    if d + s > 0.0 { s / (d + s) } else { 0.5 }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{check_sampling, directional_albedo, sampled_albedo};
    use super::super::*;

    /// Energy: with a white base, coating + base albedo is ≤ 1 and close to 1 (the
    /// model's only loss is the hemispherical-average approximation of the internal
    /// reflections); the linear model is brighter than the nonlinear one for ρ < 1.
    #[test]
    fn furnace_and_consistency() {
        let sp = ShadingPoint::new(Vec3::Z, Vec3::Z);
        for ct in [0.95f32, 0.6, 0.2] {
            let wo = Vec3::new((1.0 - ct * ct).sqrt(), 0.0, ct);
            let white = Bsdf::Plastic(Plastic::new(Color::ONE, Color::ONE, 1.5, 1.0, false));
            let a = sampled_albedo(&white, &sp, wo, 300);
            assert!((a.x - 1.0).abs() < 3e-3, "cos {ct}: {a}");
            // Non-delta part: quadrature of eval·cos equals the sampled diffuse weights.
            let grey = Plastic::new(Color::splat(0.5), Color::ONE, 1.5, 1.0, false);
            let b = Bsdf::Plastic(grey.clone());
            let q = directional_albedo(&b, &sp, wo, 400);
            let n = 200;
            let mut s = Color::ZERO;
            for i in 0..n {
                for j in 0..n {
                    let u = [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32];
                    s += b.sample_glossy(&sp, wo, u).map_or(Color::ZERO, |x| x.1);
                }
            }
            s /= (n * n) as f32;
            assert!((q - s).abs().x < 2e-3, "{q} {s}");
            let nl = Bsdf::Plastic(Plastic { nonlinear: true, ..grey });
            assert!(directional_albedo(&nl, &sp, wo, 100).x < q.x);
        }
        check_sampling(&Bsdf::Plastic(Plastic::new(Color::new(0.7, 0.3, 0.1), Color::ONE, 1.5, 1.0, true)), &sp, 4000);
    }

    #[test]
    fn sampling_weight_as_mitsuba() {
        let p = Plastic::new(Color::splat(0.5), Color::ONE, 1.49, 1.000277, false);
        assert!((p.specular_sampling_weight - 1.0 / 1.5).abs() < 1e-6);
        let b = Bsdf::Plastic(p);
        let sp = ShadingPoint::new(Vec3::Z, Vec3::Z);
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let wi = Vec3::new(-0.5, 0.2, 0.7).normalize();
        assert!((b.eval(&sp, wo, wi) - b.eval(&sp, wi, wo)).abs().max_element() < 1e-7);
        assert_eq!(b.eval(&sp, -wo, -wi), Color::ZERO);
        assert!(b.has_delta() && !b.is_delta());
    }
}
