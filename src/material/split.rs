//! How Mitsuba's BSDFs split into the parts the integrators handle apart: delta lobes
//! (followed as specular branches), the exactly Lambertian part (gathered irradiance)
//! and the rest, the glossy part (`eval − diffuse_albedo/π`, sampled on its own);
//! plus which surfaces a progressive camera path passes through, and textured
//! parameters by Mitsuba's names.

use super::{Bsdf, Mask, ShadingPoint, TransportMode, TwoSided};
use crate::math::{Color, hash_words, u32_to_unit};
use glam::Vec3;

impl Bsdf {
    /// The BSDF's name (Mitsuba's plug-in name for Mitsuba's BSDFs).
    pub fn kind_name(&self) -> &'static str {
        match self {
            Bsdf::Lambertian(_) => "diffuse",
            Bsdf::Mirror(_) => "mirror",
            Bsdf::Dielectric(_) => "dielectric",
            Bsdf::Glossy(_) => "glossy",
            Bsdf::Conductor(_) => "conductor",
            Bsdf::RoughConductor(_) => "roughconductor",
            Bsdf::Plastic(_) => "plastic",
            Bsdf::RoughPlastic(_) => "roughplastic",
            Bsdf::RoughDielectric(_) => "roughdielectric",
            Bsdf::ThinDielectric(_) => "thindielectric",
            Bsdf::TwoSided(_) => "twosided",
            Bsdf::Mask(_) => "mask",
        }
    }

    /// True when some lobe is a delta (a mixed BSDF has others as well).
    pub fn has_delta(&self) -> bool {
        match self {
            Bsdf::Plastic(_) | Bsdf::Mask(_) => true,
            Bsdf::TwoSided(t) => t.front.has_delta() || t.back.has_delta(),
            b => b.is_delta(),
        }
    }

    /// True for BSDFs with only glossy (rough, non-diffuse) non-delta lobes — rough
    /// conductors and dielectrics. As pbrt-v4's SPPM, progressive camera paths pass
    /// through them by sampling the BSDF instead of stopping there.
    pub fn is_glossy_only(&self) -> bool {
        match self {
            Bsdf::RoughConductor(_) | Bsdf::RoughDielectric(_) => true,
            Bsdf::TwoSided(t) => t.front.is_glossy_only() && t.back.is_glossy_only(),
            Bsdf::Mask(m) => m.nested.is_glossy_only(),
            _ => false,
        }
    }

    /// True when light crosses the surface through a non-delta lobe (rough glass, also
    /// under a mask): photon estimates there count photons from both sides.
    pub fn transmits_nondelta(&self) -> bool {
        match self {
            Bsdf::RoughDielectric(_) => true,
            Bsdf::Mask(m) => m.nested.transmits_nondelta(),
            _ => false,
        }
    }

    /// Probability that [`Bsdf::sample`] picks a delta lobe for `wo` (the delta lobes
    /// are always the lowest `u_lobe` values, so `u_lobe` < this ⇔ a delta sample).
    /// 0 for BSDFs without delta lobes, 1 for purely delta ones.
    pub fn delta_probability(&self, sp: &ShadingPoint, wo: Vec3) -> f32 {
        match self {
            Bsdf::Plastic(p) => {
                if p.branch(sp, wo).is_none() {
                    return 0.0;
                }
                let fo = super::fresnel::fresnel_dielectric_eta(wo.dot(sp.ns()), p.int_ior / p.ext_ior);
                let w = p.specular_sampling_weight;
                let (ps, pd) = (fo * w, (1.0 - fo) * (1.0 - w));
                if ps + pd > 0.0 { ps / (ps + pd) } else { 0.0 }
            }
            Bsdf::Mask(m) => m.null_prob() + m.opacity * m.nested.delta_probability(sp, wo),
            Bsdf::TwoSided(t) => {
                let (b, s) = t.side(sp, wo);
                b.delta_probability(&s, wo)
            }
            b if b.is_delta() => 1.0,
            _ => 0.0,
        }
    }

    /// Appends this BSDF's delta lobes, scaled by `scale`.
    pub(super) fn push_delta_branches(
        &self,
        sp: &ShadingPoint,
        wo: Vec3,
        mode: TransportMode,
        scale: Color,
        out: &mut [(Vec3, Color); super::MAX_BRANCHES],
        n: &mut usize,
    ) {
        let mut push = |wi: Vec3, w: Color| {
            if *n < out.len() {
                out[*n] = (wi, w * scale);
                *n += 1;
            }
        };
        match self {
            Bsdf::Mirror(_) | Bsdf::Dielectric(_) => {
                let (br, k) = self.specular_branches(sp, wo, mode);
                for &(wi, w) in &br[..k] {
                    push(wi, w);
                }
            }
            Bsdf::Conductor(c) => {
                if let Some((wi, w)) = c.branch(sp, wo) {
                    push(wi, w);
                }
            }
            Bsdf::Plastic(p) => {
                if let Some((wi, w)) = p.branch(sp, wo) {
                    push(wi, w);
                }
            }
            Bsdf::ThinDielectric(t) => {
                for (wi, w) in t.branches(sp, wo) {
                    push(wi, w);
                }
            }
            Bsdf::TwoSided(t) => {
                let (b, s) = t.side(sp, wo);
                b.push_delta_branches(&s, wo, mode, scale, out, n);
            }
            Bsdf::Mask(m) => {
                push(Mask::pass(sp, wo), Color::splat(m.null_prob()));
                m.nested.push_delta_branches(sp, wo, mode, scale * m.opacity, out, n);
            }
            _ => {}
        }
    }

    /// Samples the non-delta lobes alone: wi and f·|cos θi|/pdf.
    pub fn sample_nondelta(&self, sp: &ShadingPoint, wo: Vec3, u_lobe: f32, u: [f32; 2]) -> Option<(Vec3, Color)> {
        match self {
            Bsdf::Plastic(p) => p.sample_base(sp, wo, u),
            Bsdf::Mask(m) => m.nested.sample_nondelta(sp, wo, u_lobe, u).map(|(wi, w)| (wi, w * m.opacity)),
            Bsdf::TwoSided(t) => {
                let (b, s) = t.side(sp, wo);
                b.sample_nondelta(&s, wo, u_lobe, u).filter(|r| TwoSided::same_side(sp, wo, r.0))
            }
            b if b.is_delta() => None,
            b => b.sample(sp, wo, u_lobe, u, TransportMode::Radiance).filter(|s| !s.delta).map(|s| (s.wi, s.weight)),
        }
    }

    /// [`Bsdf::eval_glossy`] for Mitsuba's BSDFs.
    pub(super) fn eval_glossy_ext(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> Color {
        match self {
            Bsdf::TwoSided(t) if t.front == t.back => {
                let (b, s) = t.side(sp, wo);
                if TwoSided::same_side(sp, wo, wi) { b.eval_glossy(&s, wo, wi) } else { Color::ZERO }
            }
            Bsdf::Mask(m) => m.nested.eval_glossy(sp, wo, wi) * m.opacity,
            b => b.eval(sp, wo, wi),
        }
    }

    /// [`Bsdf::has_glossy`] for Mitsuba's BSDFs.
    pub(super) fn has_glossy_ext(&self) -> bool {
        match self {
            Bsdf::Conductor(_) | Bsdf::ThinDielectric(_) => false,
            Bsdf::TwoSided(t) if t.front == t.back => t.front.has_glossy(),
            Bsdf::Mask(m) => m.nested.has_glossy(),
            b => !b.is_delta(),
        }
    }

    /// [`Bsdf::sample_glossy`] for Mitsuba's BSDFs. The lobe choice of BSDFs with
    /// several non-delta lobes takes a number hashed from `u` (the glossy gather
    /// provides two dimensions).
    pub(super) fn sample_glossy_ext(&self, sp: &ShadingPoint, wo: Vec3, u: [f32; 2]) -> Option<(Vec3, Color)> {
        match self {
            Bsdf::TwoSided(t) if t.front == t.back => {
                let (b, s) = t.side(sp, wo);
                b.sample_glossy(&s, wo, u).filter(|r| TwoSided::same_side(sp, wo, r.0))
            }
            Bsdf::Mask(m) => m.nested.sample_glossy(sp, wo, u).map(|(wi, w)| (wi, w * m.opacity)),
            b => {
                let u_lobe = u32_to_unit((hash_words(&[u[0].to_bits() as u64, u[1].to_bits() as u64, 0x10BE]) >> 32) as u32);
                b.sample_nondelta(sp, wo, u_lobe, u)
            }
        }
    }

    /// Sets a colour parameter by its Mitsuba name (a texture's value at a hit):
    /// `reflectance` (diffuse; also the `diffuse_reflectance` of plastics),
    /// `diffuse_reflectance`, `specular_reflectance`, `specular_transmittance`, `eta`,
    /// `k` and a mask's `opacity` (its luminance). `twosided` sets both sides, `mask`
    /// its nested BSDF for other names. False when this BSDF has no such parameter.
    pub fn set_color_param(&mut self, name: &str, c: Color) -> bool {
        match (self, name) {
            (Bsdf::Lambertian(m), "reflectance" | "diffuse_reflectance") => m.albedo = c,
            (Bsdf::Mirror(m), "specular_reflectance") => m.reflectance = c,
            (Bsdf::Dielectric(m), "specular_reflectance") => m.specular_reflectance = c,
            (Bsdf::Dielectric(m), "specular_transmittance") => m.tint = c,
            (Bsdf::Glossy(m), "diffuse_reflectance" | "reflectance") => m.kd = c,
            (Bsdf::Glossy(m), "specular_reflectance") => m.ks = c,
            (Bsdf::Conductor(m), "specular_reflectance") => m.specular_reflectance = c,
            (Bsdf::Conductor(m), "eta") => m.eta = c,
            (Bsdf::Conductor(m), "k") => m.k = c,
            (Bsdf::RoughConductor(m), "specular_reflectance") => m.specular_reflectance = c,
            (Bsdf::RoughConductor(m), "eta") => m.eta = c,
            (Bsdf::RoughConductor(m), "k") => m.k = c,
            (Bsdf::Plastic(m), "diffuse_reflectance" | "reflectance") => m.diffuse_reflectance = c,
            (Bsdf::Plastic(m), "specular_reflectance") => m.specular_reflectance = c,
            (Bsdf::RoughPlastic(m), "diffuse_reflectance" | "reflectance") => m.diffuse_reflectance = c,
            (Bsdf::RoughPlastic(m), "specular_reflectance") => m.specular_reflectance = c,
            (Bsdf::RoughDielectric(m), "specular_reflectance") => m.specular_reflectance = c,
            (Bsdf::RoughDielectric(m), "specular_transmittance") => m.specular_transmittance = c,
            (Bsdf::ThinDielectric(m), "specular_reflectance") => m.specular_reflectance = c,
            (Bsdf::ThinDielectric(m), "specular_transmittance") => m.specular_transmittance = c,
            (Bsdf::Mask(m), "opacity") => m.opacity = (0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z).clamp(0.0, 1.0),
            (Bsdf::Mask(m), n) => return m.nested.set_color_param(n, c),
            (Bsdf::TwoSided(t), n) => {
                let a = t.front.set_color_param(n, c);
                let b = t.back.set_color_param(n, c);
                return a || b;
            }
            _ => return false,
        }
        true
    }
}
