//! Energy conservation and reciprocity of the BSDFs.
//!
//! - `brdf/albedo/*`: the directional albedo ρ(wo) = ∫ f(wo, wi) |cos θi| dωi at
//!   incident angles 0°–89°, by deterministic numerical integration: an M × M midpoint
//!   grid of the unit square mapped through a half-cosine, half-Phong-lobe mixture
//!   (so even an exponent-1000 lobe is resolved), each node weighted by f·|cos| / q.
//!   The statistic is the largest albedo over the angles; it must not exceed
//!   1 + [`ALBEDO_TOL`]. Planted: a glossy material with kd + ks = 1.2.
//! - `brdf/energy/*`: mirror and glass are delta BSDFs: the flux they scatter is the
//!   sum of their branch weights (importance transport), at most 1.
//! - `brdf/reciprocity/*`: the largest relative |f(wo, wi) − f(wi, wo)| over random
//!   direction pairs and pairs near the specular lobe, with flat and tilted shading
//!   normals; at most [`RECIPROCITY_TOL`] (single-precision evaluation). Planted: the
//!   original Phong model, which divides by cos θi and is not reciprocal.

use super::{FamilyReport, Outcome, Settings, TestRow};
use crate::material::{Bsdf, Dielectric, Glossy, Lambertian, Mirror, ShadingPoint, TransportMode};
use crate::math::{Color, Frame, cosine_hemisphere, mean, uniform_sphere};
use crate::sampler::Sampler;
use crate::sampler::random::RandomSampler;
use anyhow::Result;
use glam::Vec3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Allowed excess of the directional albedo over 1 (quadrature error).
pub const ALBEDO_TOL: f64 = 1e-3;
/// Allowed relative asymmetry of f (single-precision rounding).
pub const RECIPROCITY_TOL: f64 = 1e-3;
/// Incident angles (degrees from the normal) of the albedo test.
pub const ANGLES: [f32; 10] = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 89.0];

fn glossy(kd: f32, ks: f32, exponent: f32) -> Bsdf {
    Bsdf::Glossy(Glossy { kd: Color::splat(kd), ks: Color::splat(ks), exponent })
}

/// The reflective BSDFs tested, with their expected verdicts (planted last).
pub fn materials() -> Vec<(String, Bsdf, Outcome)> {
    let mut v = vec![("lambertian".to_string(), Bsdf::Lambertian(Lambertian { albedo: Color::ONE }), Outcome::Pass)];
    for n in [1.0, 10.0, 100.0, 1000.0] {
        v.push((format!("phong/n{n}"), glossy(0.0, 1.0, n), Outcome::Pass));
    }
    v.push(("phong/kd0.5_ks0.5_n50".into(), glossy(0.5, 0.5, 50.0), Outcome::Pass));
    v.push(("planted/phong_kd0.6_ks0.6_n20".into(), glossy(0.6, 0.6, 20.0), Outcome::Fail));
    v
}

/// Directional albedo (channel mean) for outgoing `wo` at a flat shading point, by
/// an m × m grid through the cosine/lobe mixture around the mirror direction with
/// exponent `lobe` (the grid is deterministic: this is quadrature, not Monte Carlo).
pub fn directional_albedo(f: &(dyn Fn(Vec3, Vec3) -> f64 + Sync), wo: Vec3, lobe: f64, m: usize) -> f64 {
    let r = Vec3::new(-wo.x, -wo.y, wo.z);
    let fr = Frame::new(r);
    let q = |wi: Vec3| {
        let c = 0.5 * (wi.z as f64).max(0.0) / PI;
        let l = 0.5 * (lobe + 1.0) / (2.0 * PI) * (r.dot(wi) as f64).max(0.0).powf(lobe);
        c + l
    };
    let rows: Vec<f64> = (0..m)
        .into_par_iter()
        .map(|i| {
            let u0 = (i as f64 + 0.5) / m as f64;
            let mut s = 0.0;
            for j in 0..m {
                let u1 = (j as f64 + 0.5) / m as f64;
                let wi = if u0 < 0.5 {
                    cosine_hemisphere([(2.0 * u0) as f32, u1 as f32])
                } else {
                    let cos_a = (2.0 * u0 - 1.0).powf(1.0 / (lobe + 1.0));
                    let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
                    let phi = 2.0 * PI * u1;
                    fr.to_world(Vec3::new((sin_a * phi.cos()) as f32, (sin_a * phi.sin()) as f32, cos_a as f32)).normalize()
                };
                let pdf = q(wi);
                if pdf > 0.0 {
                    s += f(wo, wi) * (wi.z as f64).abs() / pdf;
                }
            }
            s
        })
        .collect();
    rows.iter().sum::<f64>() / (m * m) as f64
}

fn lobe_of(b: &Bsdf) -> f64 {
    match b {
        Bsdf::Glossy(g) => g.exponent as f64,
        _ => 1.0,
    }
}

/// The original (non-reciprocal) Phong BRDF: ks·(n+2)/(2π)·cos^n α / cos θi.
fn original_phong(n: f64) -> impl Fn(Vec3, Vec3) -> f64 + Sync {
    move |wo: Vec3, wi: Vec3| {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let r = Vec3::new(-wo.x, -wo.y, wo.z);
        (n + 2.0) / (2.0 * PI) * (r.dot(wi) as f64).max(0.0).powf(n) / wi.z as f64
    }
}

/// Largest relative asymmetry of `f` over `n` direction pairs (half uniform on the
/// sphere, half near the specular configuration).
pub fn max_asymmetry(f: &(dyn Fn(Vec3, Vec3) -> f64 + Sync), n: usize, seed: u64) -> f64 {
    (0..n)
        .into_par_iter()
        .with_min_len(1024)
        .map_init(
            || RandomSampler::new(seed),
            |s, i| {
                s.start(0, i as u64);
                let a = uniform_sphere(s.next_2d());
                let b = if i % 2 == 0 {
                    uniform_sphere(s.next_2d())
                } else {
                    // Near the mirror of a: perturb by up to ~0.1 rad.
                    let m = Vec3::new(-a.x, -a.y, a.z);
                    let d = uniform_sphere(s.next_2d()) * 0.1;
                    (m + d).normalize()
                };
                let (x, y) = (f(a, b), f(b, a));
                let big = x.abs().max(y.abs());
                if big <= 1e-6 { 0.0 } else { (x - y).abs() / big }
            },
        )
        .reduce(|| 0.0, f64::max)
}

/// Runs the family.
pub fn run(s: &Settings) -> Result<FamilyReport> {
    let m = s.pick(512, 2048);
    let pairs = s.pick(200_000, 2_000_000);
    let flat = ShadingPoint::new(Vec3::Z, Vec3::Z);
    let tilt = 15f32.to_radians();
    let tilted = ShadingPoint::new(Vec3::Z, Vec3::new(tilt.sin(), 0.0, tilt.cos()));
    let mut rows = Vec::new();
    for (name, b, expected) in materials() {
        let f = |wo: Vec3, wi: Vec3| mean(b.eval(&flat, wo, wi)) as f64;
        let max = ANGLES
            .iter()
            .map(|&deg| {
                let t = deg.to_radians();
                directional_albedo(&f, Vec3::new(t.sin(), 0.0, t.cos()), lobe_of(&b), m)
            })
            .fold(0.0f64, f64::max);
        rows.push(TestRow::new(format!("brdf/albedo/{name}"), max, None, expected, max <= 1.0 + ALBEDO_TOL));
        if expected == Outcome::Pass {
            for (sp_name, sp) in [("flat", flat), ("shading_normal", tilted)] {
                let f = |wo: Vec3, wi: Vec3| mean(b.eval(&sp, wo, wi)) as f64;
                let a = max_asymmetry(&f, pairs, 11);
                rows.push(TestRow::new(format!("brdf/reciprocity/{name}/{sp_name}"), a, None, Outcome::Pass, a <= RECIPROCITY_TOL));
            }
        }
    }
    let a = max_asymmetry(&original_phong(10.0), pairs, 11);
    rows.push(TestRow::new("brdf/reciprocity/planted/original_phong_n10", a, None, Outcome::Fail, a <= RECIPROCITY_TOL));
    // Delta BSDFs: scattered flux = sum of the branch weights, from both sides.
    let deltas =
        [("mirror", Bsdf::Mirror(Mirror { reflectance: Color::ONE })), ("glass", Bsdf::Dielectric(Dielectric::new(1.5, Color::ONE)))];
    for (name, b) in deltas {
        let mut max = 0.0f64;
        for &deg in &ANGLES {
            let t = deg.to_radians();
            for z in [t.cos(), -t.cos()] {
                let wo = Vec3::new(t.sin(), 0.0, z);
                let (br, n) = b.specular_branches(&flat, wo, TransportMode::Importance);
                let sum: f64 = br[..n].iter().map(|(_, w)| mean(*w) as f64).sum();
                max = max.max(sum);
            }
        }
        rows.push(TestRow::new(format!("brdf/energy/{name}"), max, None, Outcome::Pass, max <= 1.0 + 1e-5));
    }
    Ok(FamilyReport { rows, plots: Vec::new() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn albedo_quadrature_is_exact_for_lambert_and_phong() {
        // Lambertian albedo 1 at every angle; the normalised Phong lobe has albedo
        // exactly 1 at normal incidence.
        let lam = |wo: Vec3, wi: Vec3| if wo.z > 0.0 && wi.z > 0.0 { 1.0 / PI } else { 0.0 };
        let a = directional_albedo(&lam, Vec3::new(0.6, 0.0, 0.8), 1.0, 256);
        assert!((a - 1.0).abs() < 1e-3, "{a}");
        let b = glossy(0.0, 1.0, 100.0);
        let sp = ShadingPoint::new(Vec3::Z, Vec3::Z);
        let f = |wo: Vec3, wi: Vec3| mean(b.eval(&sp, wo, wi)) as f64;
        let a = directional_albedo(&f, Vec3::Z, 100.0, 256);
        assert!((a - 1.0).abs() < 1e-3, "{a}");
    }
}
