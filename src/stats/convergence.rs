//! Convergence rates on a smooth area-light configuration with an exact reference:
//! a 1 × 1 square light (radiance 5, facing down, black) one unit above a large
//! Lambertian floor (ρ = 0.5). The floor's radiance is ρ/π · E with E from Lambert's
//! closed form for a polygonal source, so every error is measured against the
//! exact value at the pixel centres of a 32 × 32 view of the floor.
//!
//! - `convergence/path/random`: MSE vs samples per pixel of the `path` integrator
//!   (next-event estimation + BSDF sampling with MIS) with independent random
//!   numbers: log–log slope must be −1 ± [`SLOPE_TOL`].
//! - `convergence/path/halton`, `/hammersley`: the same with low-discrepancy points
//!   (the integrand is smooth over the light, so randomised QMC converges faster):
//!   the slope must be steeper than random's by at least [`STEEPER_BY`].
//! - `convergence/photon`: MSE of the photon-map radiance estimate (direct map, cone
//!   filter) vs the number of photons, gathering k = √N photons: the error must fall
//!   (slope ≤ [`PHOTON_MAX_SLOPE`]; the variance term ∝ 1/k gives −0.5). The planted
//!   control gathers a fixed k = 16, whose variance never falls.

use super::{FamilyReport, Outcome, Settings, TestRow};
use crate::accel::TraversalStats;
use crate::camera::Camera;
use crate::integrator::Integrator;
use crate::integrator::path::PathIntegrator;
use crate::material::Material;
use crate::math::{Color, mean};
use crate::photon::estimate::with_heap;
use crate::photon::estimate::{self, EstimateParams, Filter};
use crate::photon::{MapTrees, PhotonPassSettings, build_maps};
use crate::plot::{LinePlot, Series, log_log_slope};
use crate::registry::{make_accel, make_rr, make_sampler};
use crate::scene::{Face, MeshData, Placement, Scene};
use crate::world::World;
use anyhow::Result;
use glam::Vec3;
use rayon::prelude::*;

/// Largest distance of the random path tracer's slope from −1.
pub const SLOPE_TOL: f64 = 0.15;
/// How much steeper the low-discrepancy slopes must be than random's.
pub const STEEPER_BY: f64 = 0.2;
/// The photon-map error must fall at least this fast.
pub const PHOTON_MAX_SLOPE: f64 = -0.3;
const RES: u32 = 32;
const LIGHT_RADIANCE: f32 = 5.0;
const FLOOR_ALBEDO: f32 = 0.5;
/// Light corners (y = 1), wound so that its front faces down.
const LIGHT: [[f32; 3]; 4] = [[-0.5, 1.0, -0.5], [0.5, 1.0, -0.5], [0.5, 1.0, 0.5], [-0.5, 1.0, 0.5]];

fn quad(corners: [[f32; 3]; 4], material: Material) -> MeshData {
    MeshData {
        positions: corners.iter().map(|c| Vec3::from_array(*c)).collect(),
        normals: Vec::new(),
        faces: vec![Face { v: [0, 1, 2], n: None, material: 0, line: 0 }, Face { v: [0, 2, 3], n: None, material: 0, line: 0 }],
        materials: vec![material],
    }
}

/// The test scene with its BVH.
pub fn world() -> Result<World> {
    let cam = Camera::new(Vec3::new(0.0, 1.6, 3.2), Vec3::new(0.0, 0.0, 0.2), Vec3::Y, 30.0, RES, RES)?;
    let mut s = Scene::new("area-light-floor", cam);
    let floor = quad(
        [[-10.0, 0.0, -10.0], [-10.0, 0.0, 10.0], [10.0, 0.0, 10.0], [10.0, 0.0, -10.0]],
        Material::diffuse("floor", Color::splat(FLOOR_ALBEDO)),
    );
    let light = quad(LIGHT, Material { emission: Color::splat(LIGHT_RADIANCE), ..Material::diffuse("light", Color::ZERO) });
    s.add_mesh(&floor, &Placement::default(), None)?;
    s.add_mesh(&light, &Placement::default(), None)?;
    let accel = make_accel("bvh", &s.triangles)?;
    World::new(s, accel)
}

/// Irradiance at floor point `x` (normal +y) from the light, by Lambert's formula
/// E = L/2 · Σ_i γ_i (n · (r_i × r_{i+1}) / |r_i × r_{i+1}|) for unit vectors r_i to
/// the polygon's corners (γ_i the angle between them).
pub fn irradiance(x: Vec3) -> f64 {
    let n = glam::DVec3::Y;
    let r: Vec<glam::DVec3> = LIGHT.iter().map(|c| (Vec3::from_array(*c) - x).as_dvec3().normalize()).collect();
    let mut sum = 0.0;
    for i in 0..4 {
        let (a, b) = (r[i], r[(i + 1) % 4]);
        let c = a.cross(b);
        let len = c.length();
        if len > 0.0 {
            sum += a.dot(b).clamp(-1.0, 1.0).acos() * n.dot(c / len);
        }
    }
    (0.5 * LIGHT_RADIANCE as f64 * sum).abs()
}

/// Exact radiance (channel mean) at each pixel centre, with the hit it shades.
fn reference(w: &World) -> Vec<(f64, Option<crate::world::Interaction>)> {
    let cam = &w.scene.camera;
    let mut st = TraversalStats::default();
    (0..RES * RES)
        .map(|p| {
            let ray = cam.generate_ray((p % RES) as f32 + 0.5, (p / RES) as f32 + 0.5);
            match w.intersect(&ray, &mut st) {
                Some(it) if w.material(&it).name == "floor" => (FLOOR_ALBEDO as f64 / std::f64::consts::PI * irradiance(it.p), Some(it)),
                other => (0.0, other),
            }
        })
        .collect()
}

/// MSE of the path integrator at each spp in `levels` (pixel centres), `sampler`.
fn path_mse(w: &World, refs: &[(f64, Option<crate::world::Interaction>)], sampler: &str, levels: &[u32]) -> Result<Vec<(f64, f64)>> {
    let integrator = PathIntegrator { max_depth: u32::MAX, rr: make_rr("throughput")?, output: Default::default() };
    let cam = &w.scene.camera;
    let nested = sampler != "hammersley";
    let max = *levels.iter().max().unwrap_or(&1);
    // Nested samplers: one pass, recording each pixel's running mean at every level.
    let runs: Vec<(u32, u32)> = if nested { vec![(max, 0)] } else { levels.iter().map(|&n| (n, n)).collect() };
    let mut se = vec![0.0f64; levels.len()];
    for (count, only) in runs {
        let proto = make_sampler(sampler, 0xC0, Some(count as u64))?;
        let per_pixel: Vec<Vec<f64>> = (0..RES * RES)
            .into_par_iter()
            .map_init(
                || proto.clone_box(),
                |s, p| {
                    let ray = cam.generate_ray((p % RES) as f32 + 0.5, (p / RES) as f32 + 0.5);
                    let mut st = TraversalStats::default();
                    let mut sum = 0.0f64;
                    let mut out = Vec::new();
                    for i in 0..count {
                        s.start(p as u64, i as u64);
                        sum += mean(integrator.li(w, &ray, s.as_mut(), &mut st)) as f64;
                        if levels.contains(&(i + 1)) && (only == 0 || only == i + 1) {
                            out.push(sum / (i + 1) as f64);
                        }
                    }
                    out
                },
            )
            .collect();
        for (p, est) in per_pixel.iter().enumerate() {
            for (k, e) in est.iter().enumerate() {
                let li = if nested { k } else { levels.iter().position(|&l| l == only).unwrap_or(0) };
                se[li] += (e - refs[p].0).powi(2);
            }
        }
    }
    Ok(levels.iter().zip(se).map(|(&l, s)| (l as f64, s / (RES * RES) as f64)).collect())
}

/// MSE of the photon-map estimate for each photon count, gathering `k(N)` photons.
fn photon_mse(
    w: &World,
    refs: &[(f64, Option<crate::world::Interaction>)],
    counts: &[u64],
    k: impl Fn(u64) -> usize,
) -> Result<Vec<(f64, f64)>> {
    let rr = make_rr("albedo")?;
    let mut out = Vec::new();
    for &n in counts {
        let sampler = make_sampler("random", 0xF07 ^ n, None)?;
        let settings = PhotonPassSettings {
            global_photons: n as usize,
            caustic_photons: 0,
            fixed_emit: Some(n),
            max_emitted: n,
            max_depth: 8,
            trees: MapTrees { direct: true, indirect: false },
        };
        let maps = build_maps(w, sampler.as_ref(), rr.as_ref(), &settings, true);
        let prm = EstimateParams::new(k(n), 1.0, Filter::Cone, 0.25);
        let se: f64 = refs
            .par_iter()
            .map(|(r, it)| {
                let Some(it) = it else { return 0.0 };
                let bsdf = &w.material(it).bsdf;
                let wo = (w.scene.camera.eye - it.p).normalize();
                let e = maps.direct.as_ref().map_or(Color::ZERO, |m| with_heap(|h| estimate::radiance(m, it, wo, bsdf, &prm, h)));
                (mean(e) as f64 - r).powi(2)
            })
            .collect::<Vec<f64>>()
            .iter()
            .sum();
        out.push((n as f64, se / refs.len() as f64));
    }
    Ok(out)
}

/// Runs the family.
pub fn run(s: &Settings) -> Result<FamilyReport> {
    let w = world()?;
    let refs = reference(&w);
    let levels: Vec<u32> = (0..=s.pick(8, 12)).map(|k| 1u32 << k).collect();
    let mut rows = Vec::new();
    let mut series = Vec::new();
    let mut random_slope = f64::NAN;
    for sampler in ["random", "halton", "hammersley"] {
        let c = path_mse(&w, &refs, sampler, &levels)?;
        let slope = log_log_slope(&c).unwrap_or(f64::NAN);
        let ok = if sampler == "random" {
            random_slope = slope;
            (slope + 1.0).abs() <= SLOPE_TOL
        } else {
            slope <= random_slope - STEEPER_BY
        };
        rows.push(TestRow::new(format!("convergence/path/{sampler}/slope"), slope, None, Outcome::Pass, ok));
        series.push(Series { name: format!("path, {sampler}"), points: c });
    }
    let counts: Vec<u64> = (10..=s.pick(17, 20)).map(|k| 1u64 << k).collect();
    let grows = photon_mse(&w, &refs, &counts, |n| ((n as f64).sqrt().round() as usize).max(8))?;
    let fixed = photon_mse(&w, &refs, &counts, |_| 16)?;
    let mut photon_series = Vec::new();
    for (name, c, expected) in [("photon/k_sqrt_n", grows, Outcome::Pass), ("planted/photon_fixed_k16", fixed, Outcome::Fail)] {
        let slope = log_log_slope(&c).unwrap_or(f64::NAN);
        rows.push(TestRow::new(format!("convergence/{name}/slope"), slope, None, expected, slope <= PHOTON_MAX_SLOPE));
        photon_series.push(Series { name: name.replace('/', ": "), points: c });
    }
    let plots = vec![
        (
            "convergence_path".to_string(),
            LinePlot {
                title: "Path tracing, area light over a floor: error vs samples".into(),
                x_label: "samples per pixel".into(),
                y_label: "MSE".into(),
                log_x: true,
                log_y: true,
                series,
            },
        ),
        (
            "convergence_photon".to_string(),
            LinePlot {
                title: "Photon-map radiance estimate: error vs photons".into(),
                x_label: "photons emitted".into(),
                y_label: "MSE".into(),
                log_x: true,
                log_y: true,
                series: photon_series,
            },
        ),
    ];
    Ok(FamilyReport { rows, plots })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lambert_formula_matches_numerical_integration() {
        // E(x) = L ∫_light cos θ cos θ' / d² dA, by a midpoint rule.
        let x = Vec3::new(0.3, 0.0, -0.2);
        let m = 400;
        let mut e = 0.0f64;
        for i in 0..m {
            for j in 0..m {
                let p = Vec3::new(-0.5 + (i as f32 + 0.5) / m as f32, 1.0, -0.5 + (j as f32 + 0.5) / m as f32);
                let d = (p - x).as_dvec3();
                let d2 = d.length_squared();
                let c = d.y / d2.sqrt();
                e += LIGHT_RADIANCE as f64 * c * c / d2 / (m * m) as f64;
            }
        }
        assert!((irradiance(x) - e).abs() < 1e-4 * e, "{} vs {e}", irradiance(x));
    }
}
