//! The chi-square cases of light sampling and photon emission: directions towards an
//! area light, emission directions and positions of area, spot and point lights, each
//! in a small scene built here.

use super::{CHUNK, DirCase, PdfFn, SEED};
use crate::light::LightSet;
use crate::material::Material;
use crate::math::{Color, Frame};
use crate::photon::emit::emit_photon;
use crate::sampler::Sampler;
use crate::sampler::random::RandomSampler;
use crate::scene::{Face, LightDesc, MeshData, Placement, Scene};
use crate::stats::Outcome;
use anyhow::Result;
use glam::Vec3;
use rayon::prelude::*;
use std::f64::consts::PI;

fn quad_mesh(corners: [Vec3; 4], material: Material) -> MeshData {
    MeshData {
        positions: corners.to_vec(),
        normals: Vec::new(),
        faces: vec![Face { v: [0, 1, 2], n: None, material: 0, line: 0 }, Face { v: [0, 2, 3], n: None, material: 0, line: 0 }],
        materials: vec![material],
    }
}

fn emitter(name: &str, radiance: f32) -> Material {
    Material { emission: Color::splat(radiance), ..Material::diffuse(name, Color::ZERO) }
}

fn scene_with(meshes: &[MeshData], lights: Vec<LightDesc>) -> Result<Scene> {
    let cam = crate::camera::Camera::new(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 40.0, 8, 8)?;
    let mut s = Scene::new("chi2", cam);
    for m in meshes {
        s.add_mesh(m, &Placement::default(), None)?;
    }
    s.lights = lights;
    Ok(s)
}

/// Area-light sampling as seen from the origin: a skewed quad light about z = 1 and a
/// brighter triangle light at z = 0.6 (selection by power matters), both facing down.
/// The edges are deliberately not aligned with the histogram's bin edges.
pub(super) fn area_light_case() -> Result<DirCase> {
    area_light_case_with(true, true)
}

fn area_light_case_with(use_quad: bool, use_tri: bool) -> Result<DirCase> {
    let quad = quad_mesh(
        [Vec3::new(-0.9, -0.55, 1.0), Vec3::new(-1.1, 1.0, 1.1), Vec3::new(1.05, 0.95, 1.1), Vec3::new(1.25, -0.6, 1.0)],
        emitter("quad", 1.0),
    );
    let tri = MeshData {
        positions: vec![Vec3::new(0.2, -0.6, 0.6), Vec3::new(0.3, 0.1, 0.6), Vec3::new(0.9, -0.4, 0.6)],
        normals: Vec::new(),
        faces: vec![Face { v: [0, 1, 2], n: None, material: 0, line: 0 }],
        materials: vec![emitter("tri", 4.0)],
    };
    let mut meshes = Vec::new();
    if use_quad {
        meshes.push(quad);
    }
    if use_tri {
        meshes.push(tri);
    }
    let scene = scene_with(&meshes, Vec::new())?;
    let lights = LightSet::build(&scene)?;
    let p = Vec3::ZERO;
    let tris: Vec<(u32, [Vec3; 3], Vec3)> =
        (0..scene.triangles.len() as u32).map(|i| (i, scene.triangles[i as usize], scene.geometric_normal(i))).collect();
    let pdf_lights = lights.clone();
    Ok(DirCase {
        name: "chi2/light/area".into(),
        expected: Outcome::Pass,
        frame: Frame::new(Vec3::Z),
        theta_max: 0.5 * PI,
        can_fail: false,
        sample: Box::new(move |ul, u| lights.sample_li(&scene, p, ul, u).map(|s| s.wi)),
        pdf: Box::new(move |w| {
            let mut pdf = 0.0;
            for (i, t, n) in &tris {
                if w.dot(*n) >= 0.0 {
                    continue; // back side: emits nothing, never sampled
                }
                if let Some((d, _, _)) = crate::geometry::intersect_triangle(p, w, t[0], t[1] - t[0], t[2] - t[0], f32::INFINITY) {
                    pdf += pdf_lights.pdf_area(*i, p, p + w * d, *n) as f64;
                }
            }
            pdf
        }),
    })
}

/// Photon emission directions of a tilted quad light: cosine about its normal.
pub(super) fn area_emission_case() -> Result<(DirCase, Scene, LightSet, [Vec3; 3])> {
    let (c0, a, b) = (Vec3::new(-0.5, 0.2, 1.0), Vec3::new(1.2, 0.1, 0.3), Vec3::new(-0.2, 0.9, -0.1));
    let quad = quad_mesh([c0, c0 + b, c0 + a + b, c0 + a], emitter("quad", 2.0));
    let scene = scene_with(&[quad], Vec::new())?;
    let lights = LightSet::build(&scene)?;
    let n = scene.geometric_normal(0);
    let (sc, sl) = (scene.clone(), lights.clone());
    let case = DirCase {
        name: "chi2/emit/area/direction".into(),
        expected: Outcome::Pass,
        frame: Frame::new(n),
        theta_max: 0.5 * PI,
        can_fail: false,
        sample: Box::new(move |ul, u| emit_photon(&sl, &sc, ul, [0.5, 0.5], u).map(|e| e.dir)),
        pdf: Box::new(move |w| (w.dot(n).max(0.0) / std::f32::consts::PI) as f64),
    };
    Ok((case, scene, lights, [c0, a, b]))
}

/// Photon emission positions of the same quad: uniform over its area (8 × 8 cells
/// of its parallelogram parameters).
pub(super) fn area_emission_positions(scene: &Scene, lights: &LightSet, q: [Vec3; 3], n: usize) -> (Vec<u64>, Vec<f64>) {
    let [c0, a, b] = q;
    let cells = 8usize;
    let partial: Vec<Vec<u64>> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut h = vec![0u64; cells * cells + 1];
            let mut s = RandomSampler::new(SEED ^ 0xE);
            for i in c * CHUNK..((c + 1) * CHUNK).min(n) {
                s.start(77, i as u64);
                let (ul, up, ud) = (s.next_1d(), s.next_2d(), s.next_2d());
                let Some(e) = emit_photon(lights, scene, ul, up, ud) else {
                    h[cells * cells] += 1;
                    continue;
                };
                // Parallelogram coordinates (a and b are not orthogonal: solve 2×2).
                let d = e.origin - c0;
                let (aa, ab, bb, da, db) = (a.dot(a), a.dot(b), b.dot(b), d.dot(a), d.dot(b));
                let det = aa * bb - ab * ab;
                let (s1, s2) = ((da * bb - db * ab) / det, (db * aa - da * ab) / det);
                if !(-1e-3..=1.001).contains(&s1) || !(-1e-3..=1.001).contains(&s2) {
                    h[cells * cells] += 1;
                    continue;
                }
                let i1 = ((s1.clamp(0.0, 0.999_999) * cells as f32) as usize).min(cells - 1);
                let i2 = ((s2.clamp(0.0, 0.999_999) * cells as f32) as usize).min(cells - 1);
                h[i1 * cells + i2] += 1;
            }
            h
        })
        .collect();
    let mut obs = vec![0u64; cells * cells + 1];
    for h in partial {
        for (o, v) in obs.iter_mut().zip(h) {
            *o += v;
        }
    }
    let mut exp = vec![n as f64 / (cells * cells) as f64; cells * cells];
    exp.push(0.0);
    (obs, exp)
}

/// Point or spot light emission directions.
pub(super) fn delta_emission_case(light: LightDesc) -> Result<DirCase> {
    let floor = quad_mesh(
        [Vec3::new(-5.0, -5.0, -3.0), Vec3::new(5.0, -5.0, -3.0), Vec3::new(5.0, 5.0, -3.0), Vec3::new(-5.0, 5.0, -3.0)],
        Material::diffuse("floor", Color::splat(0.5)),
    );
    let scene = scene_with(&[floor], vec![light.clone()])?;
    let lights = LightSet::build(&scene)?;
    let (name, frame, theta_max, pdf): (&str, Frame, f64, PdfFn) = match light {
        LightDesc::Spot { direction, cone_deg, falloff_deg, .. } => {
            let outer = (falloff_deg.max(cone_deg).min(180.0) as f64).to_radians();
            let cos_max = outer.cos();
            let frame = Frame::new(direction);
            (
                "chi2/emit/spot/direction",
                frame,
                (outer * 1.15).min(PI),
                Box::new(move |w| if (w.dot(direction) as f64) >= cos_max { 1.0 / (2.0 * PI * (1.0 - cos_max)) } else { 0.0 }),
            )
        }
        _ => ("chi2/emit/point/direction", Frame::new(Vec3::Z), PI, Box::new(|_| 1.0 / (4.0 * PI))),
    };
    Ok(DirCase {
        name: name.into(),
        expected: Outcome::Pass,
        frame,
        theta_max,
        can_fail: false,
        sample: Box::new(move |ul, u| emit_photon(&lights, &scene, ul, [0.5, 0.5], u).map(|e| e.dir)),
        pdf,
    })
}
