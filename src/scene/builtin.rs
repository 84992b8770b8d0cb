//! Scenes generated in code: `cornell` (Cornell University's published box),
//! `furnace` (a closed emitting diffuse sphere, for energy checks) and
//! `displaced-sphere` (≥ 1 M triangles, for acceleration benchmarks).

use super::{Face, MeshData, Placement, Scene};
use crate::camera::Camera;
use crate::material::{Bsdf, Dielectric, Material, Mirror};
use crate::math::Color;
use anyhow::{Result, bail};
use glam::Vec3;

/// Names of the built-in scenes.
pub const BUILTINS: &[&str] = &["cornell", "cornell-glass", "furnace", "displaced-sphere"];

/// Builds a built-in scene by name.
pub fn builtin(name: &str) -> Result<Scene> {
    match name {
        "cornell" => Ok(cornell()),
        "cornell-glass" => Ok(cornell_glass()),
        "furnace" => Ok(furnace(0.5, 1.0, 24)),
        "displaced-sphere" => Ok(displaced_sphere(710)),
        _ => bail!("unknown built-in scene `{name}` (known: {})", BUILTINS.join(", ")),
    }
}

/// Adds quads (fan-triangulated as (0,1,2), (0,2,3)) of one material to a mesh.
fn add_quads(mesh: &mut MeshData, quads: &[[[f32; 3]; 4]], material: u32) {
    for q in quads {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(q.iter().map(|p| Vec3::from_array(*p)));
        mesh.faces.push(Face { v: [base, base + 1, base + 2], n: None, material, line: 0 });
        mesh.faces.push(Face { v: [base, base + 2, base + 3], n: None, material, line: 0 });
    }
}

/// The Cornell box as published by the Cornell University Program of Computer
/// Graphics (geometry in millimetres and camera from
/// graphics.cornell.edu/online/box/data.html). The light is lowered 0.1 mm below
/// the ceiling so the two do not coincide. RGB reflectances are the usual RGB
/// reductions of the measured spectra (white 0.725/0.71/0.68, red 0.63/0.065/0.05,
/// green 0.14/0.45/0.091); the light's radiance is (17, 12, 4) with albedo 0.78,
/// the values of the widely used OBJ version of the box.
pub fn cornell() -> Scene {
    cornell_with(true)
}

/// Jensen's box: the Cornell box without its blocks, with a mirror sphere at the
/// back left and a glass sphere (index 1.5) at the front right, both smooth-shaded
/// (vertex normals) UV spheres of radius 100 mm. Caustics appear under the glass
/// sphere and where the mirror focuses light.
pub fn cornell_glass() -> Scene {
    let mut s = cornell_with(false);
    s.name = "cornell-glass".into();
    let mut sphere = uv_sphere(48, true, |_, _| 1.0);
    sphere.normals = sphere.positions.iter().map(|p| p.normalize()).collect();
    for f in &mut sphere.faces {
        f.n = Some(f.v);
    }
    let mut mirror = sphere.clone();
    mirror.materials.push(Material {
        name: "mirror".into(),
        bsdf: Bsdf::Mirror(Mirror { reflectance: Color::splat(0.95) }),
        emission: Color::ZERO,
    });
    let mut glass = sphere;
    glass.materials.push(Material {
        name: "glass".into(),
        bsdf: Bsdf::Dielectric(Dielectric { ior: 1.5, tint: Color::ONE }),
        emission: Color::ZERO,
    });
    let place = |x: f32, z: f32| Placement { scale: Vec3::splat(100.0), rotate_y_deg: 0.0, translate: Vec3::new(x, 100.0, z) };
    s.add_mesh(&mirror, &place(390.0, 360.0), None).expect("sphere geometry is valid");
    s.add_mesh(&glass, &place(175.0, 170.0), None).expect("sphere geometry is valid");
    s
}

fn cornell_with(blocks: bool) -> Scene {
    let mut m = MeshData {
        materials: vec![
            Material::diffuse("white", Color::new(0.725, 0.71, 0.68)),
            Material::diffuse("red", Color::new(0.63, 0.065, 0.05)),
            Material::diffuse("green", Color::new(0.14, 0.45, 0.091)),
            Material { emission: Color::new(17.0, 12.0, 4.0), ..Material::diffuse("light", Color::splat(0.78)) },
        ],
        ..Default::default()
    };
    let (white, red, green, light) = (0, 1, 2, 3);
    add_quads(
        &mut m,
        &[
            // floor
            [[552.8, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 559.2], [549.6, 0.0, 559.2]],
            // ceiling
            [[556.0, 548.8, 0.0], [556.0, 548.8, 559.2], [0.0, 548.8, 559.2], [0.0, 548.8, 0.0]],
            // back wall
            [[549.6, 0.0, 559.2], [0.0, 0.0, 559.2], [0.0, 548.8, 559.2], [556.0, 548.8, 559.2]],
        ],
        white,
    );
    add_quads(&mut m, &[[[0.0, 0.0, 559.2], [0.0, 0.0, 0.0], [0.0, 548.8, 0.0], [0.0, 548.8, 559.2]]], green);
    add_quads(&mut m, &[[[552.8, 0.0, 0.0], [549.6, 0.0, 559.2], [556.0, 548.8, 559.2], [556.0, 548.8, 0.0]]], red);
    add_quads(&mut m, &[[[343.0, 548.7, 227.0], [343.0, 548.7, 332.0], [213.0, 548.7, 332.0], [213.0, 548.7, 227.0]]], light);
    if blocks {
        add_blocks(&mut m, white);
    }
    // 35 mm focal length on a 25 mm film: fov = 2·atan(12.5/35).
    let fov = 2.0 * (12.5f32 / 35.0).atan().to_degrees();
    let cam = Camera::new(Vec3::new(278.0, 273.0, -800.0), Vec3::new(278.0, 273.0, 0.0), Vec3::Y, fov, 256, 256)
        .expect("cornell camera is valid");
    let mut s = Scene::new("cornell", cam);
    s.add_mesh(&m, &Placement::default(), None).expect("cornell geometry is valid");
    s
}

fn add_blocks(m: &mut MeshData, white: u32) {
    // Short block.
    add_quads(
        m,
        &[
            [[130.0, 165.0, 65.0], [82.0, 165.0, 225.0], [240.0, 165.0, 272.0], [290.0, 165.0, 114.0]],
            [[290.0, 0.0, 114.0], [290.0, 165.0, 114.0], [240.0, 165.0, 272.0], [240.0, 0.0, 272.0]],
            [[130.0, 0.0, 65.0], [130.0, 165.0, 65.0], [290.0, 165.0, 114.0], [290.0, 0.0, 114.0]],
            [[82.0, 0.0, 225.0], [82.0, 165.0, 225.0], [130.0, 165.0, 65.0], [130.0, 0.0, 65.0]],
            [[240.0, 0.0, 272.0], [240.0, 165.0, 272.0], [82.0, 165.0, 225.0], [82.0, 0.0, 225.0]],
        ],
        white,
    );
    // Tall block.
    add_quads(
        m,
        &[
            [[423.0, 330.0, 247.0], [265.0, 330.0, 296.0], [314.0, 330.0, 456.0], [472.0, 330.0, 406.0]],
            [[423.0, 0.0, 247.0], [423.0, 330.0, 247.0], [472.0, 330.0, 406.0], [472.0, 0.0, 406.0]],
            [[472.0, 0.0, 406.0], [472.0, 330.0, 406.0], [314.0, 330.0, 456.0], [314.0, 0.0, 456.0]],
            [[314.0, 0.0, 456.0], [314.0, 330.0, 456.0], [265.0, 330.0, 296.0], [265.0, 0.0, 296.0]],
            [[265.0, 0.0, 296.0], [265.0, 330.0, 296.0], [423.0, 330.0, 247.0], [423.0, 0.0, 247.0]],
        ],
        white,
    );
}

/// Sphere triangle mesh: an n × n UV grid (n rings of n segments; the pole triangles
/// collapse and are dropped on loading), winding facing outward when `outward`,
/// otherwise inward. `radius(θ, φ)` displaces it.
pub fn uv_sphere(n: u32, outward: bool, radius: impl Fn(f32, f32) -> f32) -> MeshData {
    let mut m = MeshData::default();
    let (nu, nv) = (n, n);
    for j in 0..=nv {
        for i in 0..nu {
            let th = std::f32::consts::PI * j as f32 / nv as f32;
            let ph = 2.0 * std::f32::consts::PI * i as f32 / nu as f32;
            // Exact poles, so the pole triangles collapse to zero area.
            let (st, ct) = if j == 0 {
                (0.0, 1.0)
            } else if j == nv {
                (0.0, -1.0)
            } else {
                th.sin_cos()
            };
            let r = if j == 0 || j == nv { radius(th, 0.0) } else { radius(th, ph) };
            m.positions.push(Vec3::new(r * st * ph.cos(), r * ct, r * st * ph.sin()));
        }
    }
    let idx = |i: u32, j: u32| j * nu + (i % nu);
    for j in 0..nv {
        for i in 0..nu {
            let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
            // With y up, θ from the north pole and φ towards +z, (a, b, c) winds
            // counter-clockwise seen from outside; swapped for inward.
            let tris = if outward { [[a, b, c], [a, c, d]] } else { [[a, c, b], [a, d, c]] };
            for v in tris {
                m.faces.push(Face { v, n: None, material: 0, line: 0 });
            }
        }
    }
    m
}

/// White furnace: the camera inside a closed sphere whose inner surface is diffuse
/// with albedo `albedo` and emits `le`; every pixel's radiance is le / (1 − albedo).
pub fn furnace(albedo: f32, le: f32, rings: u32) -> Scene {
    let mut m = uv_sphere(rings, false, |_, _| 1.0);
    m.materials.push(Material { emission: Color::splat(le), ..Material::diffuse("furnace", Color::splat(albedo)) });
    let cam = Camera::new(Vec3::new(0.1, 0.05, 0.0), Vec3::new(0.1, 0.05, 1.0), Vec3::Y, 90.0, 16, 16).expect("valid camera");
    let mut s = Scene::new("furnace", cam);
    s.add_mesh(&m, &Placement::default(), None).expect("furnace geometry is valid");
    s
}

/// A displaced UV sphere on an n × n grid (710 gives 1,006,780 triangles, the size
/// of the Embree harness's sphere) lit by a point light, for benchmarks.
pub fn displaced_sphere(n: u32) -> Scene {
    let mut m = uv_sphere(n, true, |th, ph| 1.0 + (0.05 * (8.0 * ph).sin() * (6.0 * th).sin() + 0.02 * (29.0 * ph + 17.0 * th).sin()));
    m.materials.push(Material::diffuse("grey", Color::splat(0.5)));
    let cam = Camera::new(Vec3::new(0.0, 0.6, 3.2), Vec3::ZERO, Vec3::Y, 45.0, 256, 256).expect("valid camera");
    let mut s = Scene::new("displaced-sphere", cam);
    s.add_mesh(&m, &Placement::default(), None).expect("sphere geometry is valid");
    s.lights.push(crate::light::LightDesc::Point { position: Vec3::new(2.0, 4.0, 3.0), intensity: Color::splat(30.0) });
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cornell_light_faces_down_and_counts() {
        let s = cornell();
        assert_eq!(s.triangles.len(), 2 * (5 + 1 + 5 + 5));
        let lights: Vec<u32> = (0..s.triangles.len() as u32).filter(|&i| s.material(i).is_emitter()).collect();
        assert_eq!(lights.len(), 2);
        for i in lights {
            assert!(s.geometric_normal(i).y < -0.99);
        }
        assert!(s.validate().is_ok());
    }

    #[test]
    fn furnace_faces_inward() {
        let s = furnace(0.5, 1.0, 8);
        for i in 0..s.triangles.len() as u32 {
            let c = (s.triangles[i as usize][0] + s.triangles[i as usize][1] + s.triangles[i as usize][2]) / 3.0;
            assert!(s.geometric_normal(i).dot(c) < 0.0, "triangle {i} faces outward");
        }
        assert_eq!(s.dropped_degenerate, 2 * 8); // pole triangles collapse
    }

    #[test]
    fn displaced_sphere_has_a_million_triangles() {
        let s = displaced_sphere(710);
        assert_eq!(s.triangles.len(), 1_006_780);
    }
}
