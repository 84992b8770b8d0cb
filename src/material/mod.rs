//! Surface materials and their BSDFs: the scene contract's five types and Mitsuba 3's
//! BSDFs (`conductor`, `roughconductor`, `plastic`, `roughplastic`, `roughdielectric`,
//! `thindielectric`, `twosided`, `mask`, one file each, with Mitsuba's definitions of
//! evaluation, sampling and pdf; `microfacet.rs` and `fresnel.rs` are their shared
//! terms).
//!
//! Materials are a closed set fixed by the scene contract, so they are an enum with
//! static dispatch rather than a plug-in trait. Every BSDF works in world space on a
//! [`ShadingPoint`]: directions `wo` (towards the viewer / where light goes) and `wi`
//! (towards the light / where light comes from) both point away from the surface.
//! The geometric normal decides sidedness; the shading normal (interpolated `vn`)
//! decides the lobe shape, as in pbrt.

mod conductor;
mod dielectric;
pub mod fresnel;
mod glossy;
mod lambertian;
mod mask;
pub mod microfacet;
mod mirror;
mod plastic;
#[cfg(test)]
mod reflectance_tests;
mod roughconductor;
mod roughdielectric;
mod roughplastic;
mod split;
mod thindielectric;
mod twosided;

pub use conductor::Conductor;
pub use dielectric::Dielectric;
pub use glossy::Glossy;
pub use lambertian::{Lambertian, Reflects as LambertianReflects};
pub use mask::Mask;
pub use microfacet::MicrofacetType;
pub use mirror::Mirror;
pub use plastic::Plastic;
pub use roughconductor::RoughConductor;
pub use roughdielectric::RoughDielectric;
pub use roughplastic::RoughPlastic;
pub use thindielectric::ThinDielectric;
pub use twosided::TwoSided;

use crate::math::{Color, Frame};
use glam::Vec3;

/// Whether the carried quantity is radiance (camera paths) or flux/importance
/// (photons). Only refraction differs: radiance is scaled by (η_o/η_i)² there.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportMode {
    /// Paths traced from the camera.
    Radiance,
    /// Paths traced from the lights (photons).
    Importance,
}

/// Local geometry for BSDF evaluation.
#[derive(Clone, Copy, Debug)]
pub struct ShadingPoint {
    /// Frame around the shading normal; the normal is on the same side as `ng`.
    pub frame: Frame,
    /// Geometric (winding) normal, unit length: its side is the triangle's front.
    pub ng: Vec3,
}

impl ShadingPoint {
    /// Builds a shading point; `ns` is flipped onto `ng`'s side (vertex normals never
    /// change which side is the front).
    pub fn new(ng: Vec3, ns: Vec3) -> Self {
        let ns = if ns.dot(ng) < 0.0 { -ns } else { ns };
        ShadingPoint { frame: Frame::new(ns), ng }
    }
    /// Shading normal.
    #[inline]
    pub fn ns(&self) -> Vec3 {
        self.frame.n
    }

    /// |w·n_s| / |w·n_g|: light crossing the surface along `w` per unit geometric area
    /// (what photons carry) times this is the cosine-weighted measure that radiance
    /// transport with shading normals uses (`path`: L_o = ∫ f L_i |ω_i·n_s| dω_i).
    /// Exactly 1 without vertex normals; 0 for `w` in the geometric plane.
    #[inline]
    pub fn shading_to_geometric(&self, w: Vec3) -> f32 {
        if self.ns() == self.ng {
            return 1.0;
        }
        let g = w.dot(self.ng).abs();
        if g == 0.0 { 0.0 } else { w.dot(self.ns()).abs() / g }
    }

    /// The adjoint correction for shading normals when importance (photons) scatters
    /// from `wo` (towards where the photon came from) into `wi`: |wo·n_s| |wi·n_g| /
    /// (|wo·n_g| |wi·n_s|) (Veach 1997, §5.3; pbrt's `CorrectShadingNormal`). The
    /// sampling weight f |wi·n_s| / pdf times it is the flux carried on per unit of
    /// the arriving flux. Exactly 1 without vertex normals.
    #[inline]
    pub fn importance_correction(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.ns() == self.ng {
            return 1.0;
        }
        let den = wo.dot(self.ng).abs() * wi.dot(self.ns()).abs();
        if den == 0.0 { 0.0 } else { wo.dot(self.ns()).abs() * wi.dot(self.ng).abs() / den }
    }
}

/// One sampled scattering direction.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Sampled incident direction (unit, away from the surface).
    pub wi: Vec3,
    /// BSDF value f(wo, wi) (for delta lobes: the weight times pdf / cos, unused).
    pub f: Color,
    /// Solid-angle pdf of `wi` (for delta lobes: the discrete lobe probability).
    pub pdf: f32,
    /// f·|cos θi| / pdf: the throughput multiplier.
    pub weight: Color,
    /// True when `wi` came from a delta (specular) lobe.
    pub delta: bool,
}

/// The scattering part of a material.
#[derive(Clone, Debug, PartialEq)]
pub enum Bsdf {
    /// Lambertian diffuse.
    Lambertian(Lambertian),
    /// Perfect mirror.
    Mirror(Mirror),
    /// Smooth dielectric.
    Dielectric(Dielectric),
    /// Modified Phong + Lambertian.
    Glossy(Glossy),
    /// Smooth conductor (Mitsuba `conductor`).
    Conductor(Conductor),
    /// Microfacet conductor (Mitsuba `roughconductor`).
    RoughConductor(RoughConductor),
    /// Smooth coating over a diffuse base (Mitsuba `plastic`).
    Plastic(Plastic),
    /// Rough coating over a diffuse base (Mitsuba `roughplastic`).
    RoughPlastic(RoughPlastic),
    /// Microfacet dielectric (Mitsuba `roughdielectric`).
    RoughDielectric(RoughDielectric),
    /// Thin dielectric sheet (Mitsuba `thindielectric`).
    ThinDielectric(ThinDielectric),
    /// Nested BSDF(s) seen from both sides (Mitsuba `twosided`).
    TwoSided(TwoSided),
    /// Opacity cut-out (Mitsuba `mask`).
    Mask(Mask),
}

/// Most delta lobes any BSDF has (a mask's null lobe over a nested mask over a
/// thin sheet's two).
pub const MAX_BRANCHES: usize = 4;

/// A surface material: a BSDF plus optional front-side emission.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name (from the MTL or the override), for messages and export.
    pub name: String,
    /// Scattering.
    pub bsdf: Bsdf,
    /// Emitted radiance from the front side (zero for non-emitters).
    pub emission: Color,
}

impl Material {
    /// Lambertian material.
    pub fn diffuse(name: &str, albedo: Color) -> Self {
        Material { name: name.into(), bsdf: Bsdf::Lambertian(Lambertian { albedo }), emission: Color::ZERO }
    }
    /// True when the material emits.
    pub fn is_emitter(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

/// Geometric side test for reflection: both directions on the same side of `ng`.
#[inline]
pub(crate) fn same_side(sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> bool {
    wo.dot(sp.ng) * wi.dot(sp.ng) > 0.0
}

/// Local directions of a one-sided (front only) reflective lobe: `None` unless both
/// directions are on the geometric front and above the shading horizon.
#[inline]
pub(crate) fn front_pair(sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> Option<(Vec3, Vec3)> {
    if wo.dot(sp.ng) <= 0.0 || wi.dot(sp.ng) <= 0.0 {
        return None;
    }
    let (lo, li) = (sp.frame.to_local(wo), sp.frame.to_local(wi));
    if lo.z <= 0.0 || li.z <= 0.0 { None } else { Some((lo, li)) }
}

/// Local directions for a two-sided reflective lobe: flips both so that wo is on the
/// +z side of the shading frame.
#[inline]
pub(crate) fn local_pair(sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> (Vec3, Vec3) {
    let mut lo = sp.frame.to_local(wo);
    let mut li = sp.frame.to_local(wi);
    if lo.z < 0.0 {
        lo.z = -lo.z;
        li.z = -li.z;
    }
    (lo, li)
}

impl Bsdf {
    /// f(wo, wi); zero for delta lobes.
    #[inline]
    pub fn eval(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> Color {
        match self {
            Bsdf::Lambertian(m) => m.eval(sp, wo, wi),
            Bsdf::Glossy(m) => m.eval(sp, wo, wi),
            Bsdf::Mirror(_) | Bsdf::Dielectric(_) | Bsdf::Conductor(_) | Bsdf::ThinDielectric(_) => Color::ZERO,
            Bsdf::RoughConductor(m) => m.eval(sp, wo, wi),
            Bsdf::Plastic(m) => m.eval(sp, wo, wi),
            Bsdf::RoughPlastic(m) => m.eval(sp, wo, wi),
            Bsdf::RoughDielectric(m) => m.eval(sp, wo, wi),
            Bsdf::TwoSided(t) => {
                let (b, s) = t.side(sp, wo);
                if TwoSided::same_side(sp, wo, wi) { b.eval(&s, wo, wi) } else { Color::ZERO }
            }
            Bsdf::Mask(m) => m.nested.eval(sp, wo, wi) * m.opacity,
        }
    }

    /// Solid-angle pdf with which [`Bsdf::sample`] would produce `wi`; zero for delta lobes.
    #[inline]
    pub fn pdf(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            Bsdf::Lambertian(m) => m.pdf(sp, wo, wi),
            Bsdf::Glossy(m) => m.pdf(sp, wo, wi),
            Bsdf::Mirror(_) | Bsdf::Dielectric(_) | Bsdf::Conductor(_) | Bsdf::ThinDielectric(_) => 0.0,
            Bsdf::RoughConductor(m) => m.pdf(sp, wo, wi),
            Bsdf::Plastic(m) => m.pdf(sp, wo, wi),
            Bsdf::RoughPlastic(m) => m.pdf(sp, wo, wi),
            Bsdf::RoughDielectric(m) => m.pdf(sp, wo, wi),
            Bsdf::TwoSided(t) => {
                let (b, s) = t.side(sp, wo);
                if TwoSided::same_side(sp, wo, wi) { b.pdf(&s, wo, wi) } else { 0.0 }
            }
            Bsdf::Mask(m) => m.nested.pdf(sp, wo, wi) * m.opacity,
        }
    }

    /// Samples wi given wo. `u_lobe` chooses among lobes, `u` the direction within one.
    #[inline]
    pub fn sample(&self, sp: &ShadingPoint, wo: Vec3, u_lobe: f32, u: [f32; 2], mode: TransportMode) -> Option<BsdfSample> {
        match self {
            Bsdf::Lambertian(m) => m.sample(sp, wo, u),
            Bsdf::Glossy(m) => m.sample(sp, wo, u_lobe, u),
            Bsdf::Mirror(m) => m.sample(sp, wo),
            Bsdf::Dielectric(m) => m.sample(sp, wo, u_lobe, mode),
            Bsdf::Conductor(m) => m.sample(sp, wo),
            Bsdf::RoughConductor(m) => m.sample(sp, wo, u),
            Bsdf::Plastic(m) => m.sample(sp, wo, u_lobe, u),
            Bsdf::RoughPlastic(m) => m.sample(sp, wo, u_lobe, u),
            Bsdf::RoughDielectric(m) => m.sample(sp, wo, u_lobe, u, mode),
            Bsdf::ThinDielectric(m) => m.sample(sp, wo, u_lobe),
            Bsdf::TwoSided(t) => {
                let (b, s) = t.side(sp, wo);
                b.sample(&s, wo, u_lobe, u, mode).filter(|r| TwoSided::same_side(sp, wo, r.wi))
            }
            Bsdf::Mask(m) => {
                let pn = m.null_prob();
                if u_lobe < pn {
                    let wi = Mask::pass(sp, wo);
                    let cos = wi.dot(sp.ns()).abs().max(1e-8);
                    return Some(BsdfSample { wi, f: Color::splat(pn / cos), pdf: pn, weight: Color::ONE, delta: true });
                }
                let u2 = ((u_lobe - pn) / m.opacity).min(crate::math::ONE_MINUS_EPSILON);
                let mut r = m.nested.sample(sp, wo, u2, u, mode)?;
                r.f *= m.opacity;
                r.pdf *= m.opacity;
                Some(r)
            }
        }
    }

    /// Every delta lobe with its weight (f·|cos|/pdf times the lobe probability):
    /// the branches a Whitted-style tracer follows. Empty for non-delta BSDFs.
    /// Mixed BSDFs (plastic's coating, a mask's null lobe) give their delta lobes alone.
    pub fn specular_branches(&self, sp: &ShadingPoint, wo: Vec3, mode: TransportMode) -> ([(Vec3, Color); MAX_BRANCHES], usize) {
        let mut out = [(Vec3::ZERO, Color::ZERO); MAX_BRANCHES];
        let mut n = 0;
        if !matches!(self, Bsdf::Mirror(_) | Bsdf::Dielectric(_)) {
            self.push_delta_branches(sp, wo, mode, Color::ONE, &mut out, &mut n);
            return (out, n);
        }
        if let Some(r) = self.sample(sp, wo, 0.0, [0.0; 2], mode) {
            out[n] = (r.wi, r.weight * r.pdf);
            n += 1;
            if r.pdf < 1.0
                && let Some(t) = self.sample(sp, wo, crate::math::ONE_MINUS_EPSILON, [0.0; 2], mode)
                && t.wi != r.wi
            {
                out[n] = (t.wi, t.weight * t.pdf);
                n += 1;
            }
        }
        (out, n)
    }

    /// True when every lobe is a delta (no light sampling possible).
    #[inline]
    pub fn is_delta(&self) -> bool {
        match self {
            Bsdf::Mirror(_) | Bsdf::Dielectric(_) | Bsdf::Conductor(_) | Bsdf::ThinDielectric(_) => true,
            Bsdf::TwoSided(t) => t.front.is_delta() && t.back.is_delta(),
            Bsdf::Mask(m) => m.nested.is_delta(),
            _ => false,
        }
    }

    /// Hemispherical reflectance estimate used by the `albedo` Russian-roulette
    /// policy (Jensen's photon survival probability).
    pub fn albedo(&self) -> Color {
        match self {
            Bsdf::Lambertian(m) => m.albedo,
            Bsdf::Glossy(m) => m.kd + m.ks,
            Bsdf::Mirror(m) => m.reflectance,
            Bsdf::Dielectric(m) => m.tint.max(m.specular_reflectance * dielectric::fresnel(1.0, m.ior)),
            Bsdf::Conductor(m) => m.specular_reflectance * conductor::fresnel_rgb(1.0, m.eta, m.k),
            Bsdf::RoughConductor(m) => m.specular_reflectance * conductor::fresnel_rgb(1.0, m.eta, m.k),
            Bsdf::Plastic(m) => m.albedo(),
            Bsdf::RoughPlastic(m) => m.albedo(),
            Bsdf::RoughDielectric(m) => m.specular_reflectance.max(m.specular_transmittance),
            Bsdf::ThinDielectric(m) => m.specular_reflectance.max(m.specular_transmittance),
            Bsdf::TwoSided(t) => t.front.albedo().max(t.back.albedo()),
            Bsdf::Mask(m) => m.nested.albedo() * m.opacity + Color::splat(m.null_prob()),
        }
    }

    /// The non-diffuse, non-delta part of f (the glossy lobe); zero for Lambertian
    /// and specular materials. `eval = diffuse_albedo/π + eval_glossy` off delta lobes.
    #[inline]
    pub fn eval_glossy(&self, sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> Color {
        match self {
            Bsdf::Glossy(m) => m.eval_lobe(sp, wo, wi),
            Bsdf::Lambertian(_) | Bsdf::Mirror(_) | Bsdf::Dielectric(_) => Color::ZERO,
            _ => self.eval_glossy_ext(sp, wo, wi),
        }
    }

    /// True when the BSDF has a glossy part: Phong with Ks > 0, and every non-delta
    /// part of Mitsuba's BSDFs that is not exactly Lambertian (see [`Bsdf::diffuse_albedo`]).
    #[inline]
    pub fn has_glossy(&self) -> bool {
        match self {
            Bsdf::Glossy(m) => m.ks.max_element() > 0.0,
            Bsdf::Lambertian(_) | Bsdf::Mirror(_) | Bsdf::Dielectric(_) => false,
            _ => self.has_glossy_ext(),
        }
    }

    /// Samples the glossy lobe alone: wi and f_glossy·cos/pdf. `None` when there is
    /// no glossy lobe or the sample falls below the surface.
    #[inline]
    pub fn sample_glossy(&self, sp: &ShadingPoint, wo: Vec3, u: [f32; 2]) -> Option<(Vec3, Color)> {
        match self {
            Bsdf::Glossy(m) => m.sample_lobe(sp, wo, u),
            Bsdf::Lambertian(_) | Bsdf::Mirror(_) | Bsdf::Dielectric(_) => None,
            _ => self.sample_glossy_ext(sp, wo, u),
        }
    }

    /// Diffuse part's albedo (what a photon map can represent): Kd for Lambertian
    /// and glossy, zero for specular materials. Only exactly Lambertian parts count:
    /// a plastic's base is seen through Fresnel terms that depend on wi, so it belongs
    /// to the glossy part (gathered with rays drawn from it), as Mitsuba 0.6's photon
    /// mapper treats every BSDF that is not purely diffuse. A mask scales its nested
    /// BSDF's diffuse part by the opacity; `twosided` keeps it when both sides agree.
    pub fn diffuse_albedo(&self) -> Color {
        match self {
            Bsdf::Lambertian(m) => m.albedo,
            Bsdf::Glossy(m) => m.kd,
            Bsdf::TwoSided(t) if t.front == t.back => t.front.diffuse_albedo(),
            Bsdf::Mask(m) => m.nested.diffuse_albedo() * m.opacity,
            _ => Color::ZERO,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::math::uniform_sphere;

    /// Directional albedo ∫ f |cos| dωi estimated by stratified sphere sampling.
    pub fn directional_albedo(b: &Bsdf, sp: &ShadingPoint, wo: Vec3, n: usize) -> Color {
        let mut sum = Color::ZERO;
        for i in 0..n {
            for j in 0..n {
                let u = [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32];
                let wi = uniform_sphere(u);
                sum += b.eval(sp, wo, wi) * wi.dot(sp.ns()).abs() * (4.0 * std::f32::consts::PI);
            }
        }
        sum / (n * n) as f32
    }

    /// Sampled directions agree with eval and pdf: for non-delta samples, `f` and `pdf`
    /// equal `eval`/`pdf` at the sampled direction and `weight` = f·|cos|/pdf; delta
    /// samples have zero eval. Directions wo from both sides.
    pub fn check_sampling(b: &Bsdf, sp: &ShadingPoint, n: usize) {
        let close = |a: f32, c: f32| (a - c).abs() <= 2e-3 * a.abs().max(c.abs()) + 1e-6;
        let mut nondelta = 0;
        for k in 0..n {
            let h = |i: u64| crate::math::u32_to_unit((crate::math::hash_words(&[k as u64, i]) >> 32) as u32);
            let wo = uniform_sphere([h(1), h(2)]);
            let Some(s) = b.sample(sp, wo, h(3), [h(4), h(5)], TransportMode::Radiance) else { continue };
            assert!(s.wi.is_finite() && (s.wi.length() - 1.0).abs() < 1e-3 && s.weight.is_finite(), "{b:?}: {s:?}");
            if s.delta {
                continue;
            }
            nondelta += 1;
            let (e, p) = (b.eval(sp, wo, s.wi), b.pdf(sp, wo, s.wi));
            assert!(close(s.pdf, p), "{b:?} wo {wo}: sample pdf {} vs pdf {p}", s.pdf);
            for c in 0..3 {
                assert!(close(s.f[c], e[c]), "{b:?} wo {wo}: sample f {} vs eval {e}", s.f);
                let w = s.f[c] * s.wi.dot(sp.ns()).abs() / s.pdf;
                assert!(close(s.weight[c], w), "{b:?} wo {wo}: weight {} vs f·cos/pdf {w}", s.weight);
            }
        }
        assert!(nondelta > 0 || b.is_delta(), "{b:?}: no non-delta sample");
    }

    /// [`sampled_albedo`] in either transport mode.
    pub fn sampled_albedo_mode(b: &Bsdf, sp: &ShadingPoint, wo: Vec3, n: usize, mode: TransportMode) -> Color {
        let mut sum = Color::ZERO;
        for i in 0..n {
            for j in 0..n {
                let u = [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32];
                let ul = ((i * 7919 + j * 104729) % (n * n)) as f32 / (n * n) as f32;
                if let Some(s) = b.sample(sp, wo, ul, u, mode) {
                    sum += s.weight;
                }
            }
        }
        sum / (n * n) as f32
    }

    /// Mean of the sampling weight over many samples: must equal the directional albedo.
    pub fn sampled_albedo(b: &Bsdf, sp: &ShadingPoint, wo: Vec3, n: usize) -> Color {
        let mut sum = Color::ZERO;
        for i in 0..n {
            for j in 0..n {
                let u = [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32];
                let ul = ((i * 7919 + j * 104729) % (n * n)) as f32 / (n * n) as f32;
                if let Some(s) = b.sample(sp, wo, ul, u, TransportMode::Radiance) {
                    sum += s.weight;
                }
            }
        }
        sum / (n * n) as f32
    }

    /// The adjoint correction makes photon scattering carry the flux `path`'s radiance
    /// implies: a photon of unit flux (per geometric area) from `wl`, scattered by a
    /// Lambertian surface whose shading normal is tilted 22° off the geometric one,
    /// must send into a cone about `wc` the flux ∫ f(ω, wl) |wl·n_s|/|wl·n_g| |ω·n_g| dω
    /// (radiance f |wl·n_s| L per unit of L |wl·n_g| arriving, leaving per geometric
    /// area). Without the correction the sampled flux is about 3 times that here.
    #[test]
    fn importance_correction_carries_the_flux_of_radiance_transport() {
        let sp = ShadingPoint::new(Vec3::Z, Vec3::new(0.4, 0.0, 1.0).normalize());
        let b = Bsdf::Lambertian(Lambertian { albedo: Color::splat(0.8) });
        let wl = Vec3::new(-0.6, 0.2, 0.5).normalize();
        let wc = Vec3::new(0.7, -0.1, 0.45).normalize();
        let cos_max = 0.95f32;
        let (mut with, mut without) = (0.0f64, 0.0f64);
        let n = 1024;
        for i in 0..n {
            for j in 0..n {
                let u = [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32];
                if let Some(s) = b.sample(&sp, wl, 0.5, u, TransportMode::Importance)
                    && s.wi.dot(wc) >= cos_max
                {
                    with += (s.weight.x * sp.importance_correction(wl, s.wi)) as f64;
                    without += s.weight.x as f64;
                }
            }
        }
        let (with, without) = (with / (n * n) as f64, without / (n * n) as f64);
        // The expected flux by quadrature over the cone.
        let frame = Frame::new(wc);
        let (nt, np) = (200, 400);
        let t_max = cos_max.acos();
        let mut want = 0.0f64;
        for a in 0..nt {
            let t = (a as f32 + 0.5) / nt as f32 * t_max;
            for c in 0..np {
                let ph = (c as f32 + 0.5) / np as f32 * std::f32::consts::TAU;
                let w = frame.to_world(Vec3::new(t.sin() * ph.cos(), t.sin() * ph.sin(), t.cos()));
                let f = b.eval(&sp, w, wl).x * sp.shading_to_geometric(wl) * w.dot(sp.ng).abs();
                want += (f * t.sin()) as f64 * (t_max / nt as f32 * std::f32::consts::TAU / np as f32) as f64;
            }
        }
        assert!((with / want - 1.0).abs() < 0.02, "corrected flux {with} vs {want}");
        assert!((without / want - 1.0).abs() > 0.5, "uncorrected {without} vs {want}: the test can fail");
        // No vertex normals: exactly 1.
        let flat = ShadingPoint::new(Vec3::Z, Vec3::Z);
        assert_eq!((flat.importance_correction(wl, wc), flat.shading_to_geometric(wl)), (1.0, 1.0));
    }

    #[test]
    fn shading_normal_flipped_to_geometric_side() {
        let sp = ShadingPoint::new(Vec3::Z, -Vec3::Z);
        assert!(sp.ns().dot(Vec3::Z) > 0.0);
    }
}
