//! Energy-conserving modified Phong (Lafortune & Willems 1994) plus a Lambertian base:
//! f = Kd/π + Ks·(n+2)/(2π)·max(0, cos α)^n, α between wi and the mirror of wo.

use super::{BsdfSample, ShadingPoint, local_pair, same_side};
use crate::math::{Color, Frame, cosine_hemisphere, mean};
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, PI};

/// Modified Phong glossy material.
#[derive(Clone, Debug, PartialEq)]
pub struct Glossy {
    /// Diffuse reflectance.
    pub kd: Color,
    /// Specular reflectance.
    pub ks: Color,
    /// Phong exponent.
    pub exponent: f32,
}

impl Glossy {
    /// Probability of sampling the specular lobe.
    #[inline]
    fn spec_prob(&self) -> f32 {
        let d = mean(self.kd).max(0.0);
        let s = mean(self.ks).max(0.0);
        if d + s <= 0.0 { 0.0 } else { s / (d + s) }
    }

    #[inline]
    fn cos_alpha(lo: Vec3, li: Vec3) -> f32 {
        // Mirror of lo about +z in the local frame.
        let r = Vec3::new(-lo.x, -lo.y, lo.z);
        r.dot(li)
    }

    pub(super) fn eval(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> Color {
        let (lo, li) = local_pair(sp, wo, wi);
        if !same_side(sp, wo, wi) || li.z <= 0.0 || lo.z <= 0.0 {
            return Color::ZERO;
        }
        let ca = Self::cos_alpha(lo, li).max(0.0);
        let n = self.exponent;
        self.kd * FRAC_1_PI + self.ks * ((n + 2.0) / (2.0 * PI) * ca.powf(n))
    }

    fn pdf_local(&self, lo: Vec3, li: Vec3) -> f32 {
        let ps = self.spec_prob();
        let ca = Self::cos_alpha(lo, li).max(0.0);
        let n = self.exponent;
        (1.0 - ps) * li.z * FRAC_1_PI + ps * (n + 1.0) / (2.0 * PI) * ca.powf(n)
    }

    pub(super) fn pdf(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> f32 {
        let (lo, li) = local_pair(sp, wo, wi);
        if !same_side(sp, wo, wi) || li.z <= 0.0 || lo.z <= 0.0 {
            return 0.0;
        }
        self.pdf_local(lo, li)
    }

    pub(super) fn sample(&self, sp: &ShadingPoint, wo: Vec3, u_lobe: f32, u: [f32; 2]) -> Option<BsdfSample> {
        let mut lo = sp.frame.to_local(wo);
        let flip = lo.z < 0.0;
        if flip {
            lo.z = -lo.z;
        }
        if lo.z == 0.0 {
            return None;
        }
        let ps = self.spec_prob();
        let li = if u_lobe < ps {
            // Phong lobe around the mirror direction: cos α = u^(1/(n+1)).
            let r = Vec3::new(-lo.x, -lo.y, lo.z);
            let cos_a = u[0].powf(1.0 / (self.exponent + 1.0));
            let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
            let phi = 2.0 * PI * u[1];
            Frame::new(r).to_world(Vec3::new(sin_a * phi.cos(), sin_a * phi.sin(), cos_a))
        } else {
            cosine_hemisphere(u)
        };
        if li.z <= 0.0 {
            return None;
        }
        let world_li = Vec3::new(li.x, li.y, if flip { -li.z } else { li.z });
        let wi = sp.frame.to_world(world_li);
        if !same_side(sp, wo, wi) {
            return None;
        }
        let pdf = self.pdf_local(lo, li);
        if pdf <= 0.0 {
            return None;
        }
        let ca = Self::cos_alpha(lo, li).max(0.0);
        let n = self.exponent;
        let f = self.kd * FRAC_1_PI + self.ks * ((n + 2.0) / (2.0 * PI) * ca.powf(n));
        Some(BsdfSample { wi, f, pdf, weight: f * (li.z / pdf), delta: false })
    }

    /// The Phong lobe alone: Ks·(n+2)/(2π)·cos^n α (no Lambertian part).
    pub(super) fn eval_lobe(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> Color {
        let (lo, li) = local_pair(sp, wo, wi);
        if !same_side(sp, wo, wi) || li.z <= 0.0 || lo.z <= 0.0 {
            return Color::ZERO;
        }
        let n = self.exponent;
        self.ks * ((n + 2.0) / (2.0 * PI) * Self::cos_alpha(lo, li).max(0.0).powf(n))
    }

    /// Samples the Phong lobe alone (pdf (n+1)/(2π)·cos^n α about the mirror
    /// direction); returns wi and f_lobe·cos θi / pdf = Ks·(n+2)/(n+1)·cos θi, or
    /// `None` for a direction below the surface (it carries no light).
    pub(super) fn sample_lobe(&self, sp: &ShadingPoint, wo: Vec3, u: [f32; 2]) -> Option<(Vec3, Color)> {
        let mut lo = sp.frame.to_local(wo);
        let flip = lo.z < 0.0;
        if flip {
            lo.z = -lo.z;
        }
        if lo.z == 0.0 || self.ks.max_element() <= 0.0 {
            return None;
        }
        let r = Vec3::new(-lo.x, -lo.y, lo.z);
        let cos_a = u[0].powf(1.0 / (self.exponent + 1.0));
        let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
        let phi = 2.0 * PI * u[1];
        let li = Frame::new(r).to_world(Vec3::new(sin_a * phi.cos(), sin_a * phi.sin(), cos_a));
        if li.z <= 0.0 {
            return None;
        }
        let wi = sp.frame.to_world(Vec3::new(li.x, li.y, if flip { -li.z } else { li.z }));
        if !same_side(sp, wo, wi) {
            return None;
        }
        let n = self.exponent;
        Some((wi, self.ks * ((n + 2.0) / (n + 1.0) * li.z)))
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{directional_albedo, sampled_albedo};
    use super::super::*;

    /// Sampling the lobe alone: the mean weight equals ∫ f_lobe cos dω (quadrature),
    /// and the lobe plus Kd/π is the whole BSDF.
    #[test]
    fn lobe_sampling_matches_lobe_albedo() {
        let sp = ShadingPoint::new(Vec3::Z, Vec3::new(0.1, 0.0, 1.0).normalize());
        let g = Glossy { kd: Color::splat(0.2), ks: Color::splat(0.6), exponent: 20.0 };
        for ct in [0.95f32, 0.5] {
            let wo = Vec3::new((1.0 - ct * ct).sqrt(), 0.0, ct);
            let lobe_only = Bsdf::Glossy(Glossy { kd: Color::ZERO, ..g.clone() });
            let quad = directional_albedo(&lobe_only, &sp, wo, 600);
            let n = 300;
            let mut sum = Color::ZERO;
            for i in 0..n {
                for j in 0..n {
                    let u = [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32];
                    if let Some((_, w)) = g.sample_lobe(&sp, wo, u) {
                        sum += w;
                    }
                }
            }
            let est = sum / (n * n) as f32;
            assert!((est - quad).abs().max_element() < 0.01, "cos {ct}: sampled {est} vs quadrature {quad}");
            let wi = Vec3::new(-0.3, 0.1, 0.9).normalize();
            let whole = g.eval(&sp, wo, wi);
            let split = g.eval_lobe(&sp, wo, wi) + g.kd * std::f32::consts::FRAC_1_PI;
            assert!((whole - split).abs().max_element() < 1e-5);
        }
    }

    #[test]
    fn conserves_energy_and_is_reciprocal() {
        let sp = ShadingPoint::new(Vec3::Z, Vec3::Z);
        for n in [1.0, 10.0, 100.0] {
            let b = Bsdf::Glossy(Glossy { kd: Color::splat(0.3), ks: Color::splat(0.7), exponent: n });
            for ct in [1.0f32, 0.7, 0.3] {
                let wo = Vec3::new((1.0 - ct * ct).sqrt(), 0.0, ct);
                let a = directional_albedo(&b, &sp, wo, 400);
                assert!(a.max_element() <= 1.0 + 1e-2, "n={n} cos={ct} albedo={a}");
                let s = sampled_albedo(&b, &sp, wo, 200);
                assert!((a - s).abs().max_element() < 0.02, "n={n} cos={ct} quad={a} sampled={s}");
            }
            let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
            let wi = Vec3::new(-0.25, -0.05, 0.8).normalize();
            let (a, c) = (b.eval(&sp, wo, wi), b.eval(&sp, wi, wo));
            assert!((a - c).abs().max_element() < 1e-5 * a.max_element().max(1.0));
        }
    }
}
