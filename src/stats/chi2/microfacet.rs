//! Chi-square cases of Mitsuba's BSDFs: visible-normal sampling of both microfacet
//! distributions, `roughconductor`, `roughdielectric` (reflection and transmission on
//! the whole sphere, from both sides), `roughplastic`, the non-delta lobes of
//! `plastic` and `mask` and a `twosided` back face. Delta samples (a plastic's
//! coating, a mask's null lobe) go to the failure bin, which then expects
//! N·(1 − ∫pdf) — the delta lobes' probability. Planted controls: GGX samples
//! against the pdf of an α 10 % larger, reflections about normals sampled for the
//! mirrored view direction (a sign error in the half vector), and rough-plastic
//! samples against a pdf with another lobe weight.

use super::{DirCase, bsdf_case_filtered, from_theta};
use crate::material::microfacet::{Microfacet, reflect_about};
use crate::material::{
    Bsdf, Lambertian, Mask, MicrofacetType, Plastic, RoughConductor, RoughDielectric, RoughPlastic, ShadingPoint, TwoSided,
};
use crate::math::{Color, Frame};
use crate::stats::{Outcome, Settings};
use glam::Vec3;
use std::f64::consts::PI;

fn gold(kind: MicrofacetType, alpha: f32) -> Bsdf {
    Bsdf::RoughConductor(RoughConductor {
        distribution: kind,
        alpha,
        eta: Color::new(0.143, 0.374, 1.442),
        k: Color::new(3.983, 2.385, 1.603),
        specular_reflectance: Color::ONE,
    })
}

fn glass(kind: MicrofacetType, alpha: f32) -> Bsdf {
    Bsdf::RoughDielectric(RoughDielectric {
        distribution: kind,
        alpha,
        int_ior: 1.5,
        ext_ior: 1.0,
        specular_reflectance: Color::ONE,
        specular_transmittance: Color::ONE,
    })
}

fn rough_plastic(kind: MicrofacetType, alpha: f32, kd: f32) -> Bsdf {
    Bsdf::RoughPlastic(RoughPlastic::new(kind, alpha, Color::splat(kd), Color::ONE, 1.49, 1.0, false))
}

fn flat() -> ShadingPoint {
    ShadingPoint::new(Vec3::Z, Vec3::Z)
}

/// A microfacet distribution's visible normals against their pdf.
fn normals_case(name: &str, mf: Microfacet, pdf_of: Microfacet, wo: Vec3, expected: Outcome) -> DirCase {
    DirCase {
        name: name.into(),
        expected,
        frame: Frame::new(Vec3::Z),
        theta_max: PI / 2.0,
        can_fail: false,
        sample: Box::new(move |_, u| Some(mf.sample_visible(wo, u))),
        pdf: Box::new(move |m| pdf_of.pdf_visible(wo, m) as f64),
    }
}

/// The cases (planted controls last).
pub fn cases(s: &Settings) -> Vec<DirCase> {
    use MicrofacetType::{Beckmann, Ggx};
    let z = Frame::new(Vec3::Z);
    let mut v = Vec::new();
    let mut normals = vec![(Ggx, 0.1f32, 30.0f32), (Ggx, 0.5, 70.0), (Beckmann, 0.1, 30.0), (Beckmann, 0.5, 70.0)];
    if s.thorough {
        normals.extend([(Ggx, 1.0, 85.0), (Beckmann, 1.0, 85.0), (Beckmann, 0.02, 0.0)]);
    }
    for (k, a, t) in normals {
        let mf = Microfacet::new(k, a);
        v.push(normals_case(&format!("chi2/microfacet/{k:?}_a{a}_theta{t}").to_lowercase(), mf, mf, from_theta(t), Outcome::Pass));
    }
    let pass = |name: &str, b: Bsdf, sp: ShadingPoint, wo: Vec3| bsdf_case_filtered(name, b.clone(), b, sp, wo, z, PI, Outcome::Pass);
    v.push(pass("chi2/roughconductor/ggx_a0.3_theta30", gold(Ggx, 0.3), flat(), from_theta(30.0)));
    v.push(pass("chi2/roughconductor/beckmann_a0.1_theta60", gold(Beckmann, 0.1), flat(), from_theta(60.0)));
    v.push(pass("chi2/roughconductor/ggx_a0.6_grazing80", gold(Ggx, 0.6), flat(), from_theta(80.0)));
    let tilted = ShadingPoint::new(Vec3::Z, Vec3::new(15f32.to_radians().sin(), 0.0, 15f32.to_radians().cos()));
    v.push(pass("chi2/roughconductor/ggx_a0.4_shading_normal", gold(Ggx, 0.4), tilted, from_theta(40.0)));
    v.push(pass("chi2/roughdielectric/ggx_a0.3_outside", glass(Ggx, 0.3), flat(), from_theta(30.0)));
    v.push(pass("chi2/roughdielectric/beckmann_a0.2_outside_grazing", glass(Beckmann, 0.2), flat(), from_theta(75.0)));
    v.push(pass("chi2/roughdielectric/ggx_a0.3_inside", glass(Ggx, 0.3), flat(), -from_theta(20.0)));
    v.push(pass("chi2/roughdielectric/beckmann_a0.3_inside_near_tir", glass(Beckmann, 0.3), flat(), -from_theta(45.0)));
    v.push(pass("chi2/roughplastic/beckmann_a0.2_theta45", rough_plastic(Beckmann, 0.2, 0.5), flat(), from_theta(45.0)));
    v.push(pass("chi2/roughplastic/ggx_a0.5_theta70", rough_plastic(Ggx, 0.5, 0.3), flat(), from_theta(70.0)));
    let plastic = Bsdf::Plastic(Plastic::new(Color::new(0.6, 0.4, 0.2), Color::ONE, 1.5, 1.0, false));
    v.push(pass("chi2/plastic/base_theta50", plastic, flat(), from_theta(50.0)));
    let mask = Bsdf::Mask(Mask { opacity: 0.6, nested: Box::new(gold(Ggx, 0.3)) });
    v.push(pass("chi2/mask/roughconductor_opacity0.6", mask, flat(), from_theta(30.0)));
    let two = Bsdf::TwoSided(TwoSided::new(rough_plastic(Ggx, 0.3, 0.5)));
    v.push(pass("chi2/twosided/roughplastic_back", two, flat(), -from_theta(35.0)));
    let lam_mask = Bsdf::Mask(Mask { opacity: 0.3, nested: Box::new(Bsdf::Lambertian(Lambertian { albedo: Color::ONE })) });
    v.push(pass("chi2/mask/lambertian_back", lam_mask, flat(), -from_theta(60.0)));
    // Planted controls.
    let wo = from_theta(30.0);
    v.push(bsdf_case_filtered(
        "chi2/planted/roughconductor_ggx_a0.3_vs_pdf_a0.33",
        gold(Ggx, 0.3),
        gold(Ggx, 0.33),
        flat(),
        wo,
        z,
        PI,
        Outcome::Fail,
    ));
    let (mf, b) = (Microfacet::new(Ggx, 0.3), gold(Ggx, 0.3));
    let wo_m = Vec3::new(-wo.x, -wo.y, wo.z);
    v.push(DirCase {
        name: "chi2/planted/roughconductor_flipped_half_vector".into(),
        expected: Outcome::Fail,
        frame: z,
        theta_max: PI,
        can_fail: true,
        sample: Box::new(move |_, u| Some(reflect_about(wo, mf.sample_visible(wo_m, u))).filter(|w| w.z > 0.0)),
        pdf: Box::new(move |w| b.pdf(&flat(), wo, w) as f64),
    });
    v.push(bsdf_case_filtered(
        "chi2/planted/roughplastic_lobe_weight",
        rough_plastic(Beckmann, 0.2, 0.5),
        rough_plastic(Beckmann, 0.2, 0.8),
        flat(),
        from_theta(45.0),
        z,
        PI,
        Outcome::Fail,
    ));
    v
}
