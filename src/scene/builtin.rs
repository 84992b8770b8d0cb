//! Scenes generated in code: `cornell` (Cornell University's published box),
//! `cornell-glass` (Jensen's box), `cornell-glossy` (glossy floor, sphere and box),
//! `cornell-contact` (a cube on the floor and a sphere touching a corner),
//! `leaky-box` (a closed box of zero-thickness walls lit only from outside),
//! `furnace` (a closed emitting diffuse sphere, for energy checks),
//! `displaced-sphere` (≥ 1 M triangles, for acceleration benchmarks),
//! `smooth-sphere` / `faceted-sphere` (a coarse 10 × 5-facet sphere with and without
//! vertex normals, for shading normals and creases in photon estimates),
//! `lamp-panel` (a thin panel hanging 1 cm under a ceiling lit from above) and
//! `door-ajar` (Veach's room lit through a door left ajar).

use super::{Face, MeshData, Placement, Scene};
use crate::camera::Camera;
use crate::material::{Bsdf, Dielectric, Glossy, Material, Mirror};
use crate::math::Color;
use anyhow::{Result, bail};
use glam::Vec3;

/// Names of the built-in scenes.
pub const BUILTINS: &[&str] = &[
    "cornell",
    "cornell-glass",
    "cornell-glossy",
    "cornell-contact",
    "leaky-box",
    "sun-slats",
    "furnace",
    "displaced-sphere",
    "smooth-sphere",
    "faceted-sphere",
    "lamp-panel",
    "door-ajar",
];

/// Builds a built-in scene by name.
pub fn builtin(name: &str) -> Result<Scene> {
    match name {
        "cornell" => Ok(cornell()),
        "cornell-glass" => Ok(cornell_glass()),
        "cornell-glossy" => Ok(cornell_glossy()),
        "cornell-contact" => Ok(cornell_contact()),
        "leaky-box" => Ok(leaky_box()),
        "sun-slats" => Ok(sun_slats()),
        "furnace" => Ok(furnace(0.5, 1.0, 24)),
        "displaced-sphere" => Ok(displaced_sphere(710)),
        "smooth-sphere" => Ok(coarse_sphere_box(true)),
        "faceted-sphere" => Ok(coarse_sphere_box(false)),
        "lamp-panel" => Ok(lamp_panel()),
        "door-ajar" => Ok(door_ajar()),
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
        bsdf: Bsdf::Dielectric(Dielectric::new(1.5, Color::ONE)),
        emission: Color::ZERO,
    });
    let place = |x: f32, z: f32| Placement { scale: Vec3::splat(100.0), rotate_y_deg: 0.0, translate: Vec3::new(x, 100.0, z) };
    s.add_mesh(&mirror, &place(390.0, 360.0), None).expect("sphere geometry is valid");
    s.add_mesh(&glass, &place(175.0, 170.0), None).expect("sphere geometry is valid");
    s
}

fn cornell_with(blocks: bool) -> Scene {
    cornell_room(blocks, Material::diffuse("white", CORNELL_WHITE))
}

const CORNELL_WHITE: Color = Color::new(0.725, 0.71, 0.68);

fn cornell_room(blocks: bool, floor: Material) -> Scene {
    let mut m = MeshData {
        materials: vec![
            Material::diffuse("white", CORNELL_WHITE),
            Material::diffuse("red", Color::new(0.63, 0.065, 0.05)),
            Material::diffuse("green", Color::new(0.14, 0.45, 0.091)),
            Material { emission: Color::new(17.0, 12.0, 4.0), ..Material::diffuse("light", Color::splat(0.78)) },
            floor,
        ],
        ..Default::default()
    };
    let (white, red, green, light, floor) = (0, 1, 2, 3, 4);
    add_quads(&mut m, &[[[552.8, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 559.2], [549.6, 0.0, 559.2]]], floor);
    add_quads(
        &mut m,
        &[
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
    add_short_block(m, white);
    add_tall_block(m, white);
}

fn add_short_block(m: &mut MeshData, material: u32) {
    add_quads(
        m,
        &[
            [[130.0, 165.0, 65.0], [82.0, 165.0, 225.0], [240.0, 165.0, 272.0], [290.0, 165.0, 114.0]],
            [[290.0, 0.0, 114.0], [290.0, 165.0, 114.0], [240.0, 165.0, 272.0], [240.0, 0.0, 272.0]],
            [[130.0, 0.0, 65.0], [130.0, 165.0, 65.0], [290.0, 165.0, 114.0], [290.0, 0.0, 114.0]],
            [[82.0, 0.0, 225.0], [82.0, 165.0, 225.0], [130.0, 165.0, 65.0], [130.0, 0.0, 65.0]],
            [[240.0, 0.0, 272.0], [240.0, 165.0, 272.0], [82.0, 165.0, 225.0], [82.0, 0.0, 225.0]],
        ],
        material,
    );
}

fn add_tall_block(m: &mut MeshData, white: u32) {
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

/// A glossy Cornell box: the published room with a glossy floor (Kd 0.35, Ks 0.35,
/// Phong exponent 40), the short block glossy (Kd 0.45, Ks 0.25, exponent 20) and a
/// glossy sphere of radius 100 mm at the back left (Kd 0.2/0.4/0.5, Ks 0.45,
/// exponent 60), all energy-conserving. Exercises the glossy lobes at camera hits
/// and at final-gather hits.
pub fn cornell_glossy() -> Scene {
    let glossy = |name: &str, kd: Color, ks: f32, exponent: f32| Material {
        name: name.into(),
        bsdf: Bsdf::Glossy(Glossy { kd, ks: Color::splat(ks), exponent }),
        emission: Color::ZERO,
    };
    let mut s = cornell_room(false, glossy("glossy-floor", Color::new(0.36, 0.35, 0.34), 0.35, 40.0));
    s.name = "cornell-glossy".into();
    let mut block = MeshData { materials: vec![glossy("glossy-box", Color::new(0.45, 0.44, 0.42), 0.25, 20.0)], ..Default::default() };
    add_short_block(&mut block, 0);
    s.add_mesh(&block, &Placement::default(), None).expect("block geometry is valid");
    let mut sphere = smooth_sphere(48);
    sphere.materials.push(glossy("glossy-sphere", Color::new(0.2, 0.4, 0.5), 0.45, 60.0));
    let place = Placement { scale: Vec3::splat(100.0), rotate_y_deg: 0.0, translate: Vec3::new(390.0, 100.0, 360.0) };
    s.add_mesh(&sphere, &place, None).expect("sphere geometry is valid");
    s
}

/// Contacts and corners: the published room with a white cube of edge 150 mm resting
/// on the floor (rotated 30°, faces meeting the floor along its whole edge) and a
/// white sphere of radius 90 mm touching the floor, the back wall and the green
/// wall. Contact shadows are where an irradiance cache interpolates across a
/// discontinuity.
pub fn cornell_contact() -> Scene {
    let mut s = cornell_with(false);
    s.name = "cornell-contact".into();
    let mut cube = MeshData { materials: vec![Material::diffuse("white", CORNELL_WHITE)], ..Default::default() };
    add_quads(&mut cube, &unit_cube_quads(), 0);
    let place = Placement { scale: Vec3::splat(75.0), rotate_y_deg: 30.0, translate: Vec3::new(370.0, 75.0, 200.0) };
    s.add_mesh(&cube, &place, None).expect("cube geometry is valid");
    let mut sphere = smooth_sphere(48);
    sphere.materials.push(Material::diffuse("white", CORNELL_WHITE));
    let r = 90.0;
    let place = Placement { scale: Vec3::splat(r), rotate_y_deg: 0.0, translate: Vec3::new(r, r, 559.2 - r) };
    s.add_mesh(&sphere, &place, None).expect("sphere geometry is valid");
    s
}

/// A closed box of zero-thickness walls (one quad each, both sides reflect, as the
/// scene contract says) lit only from outside: an area light above the roof facing
/// down, under a white canopy that sends light back onto the roof. Nothing reaches
/// the inside, so the correct image is black apart from the walls' faint edges where
/// floating point lets a path through (`path` gives about 1e-7). The camera sits on
/// the box's axis, so pixel centres fall exactly on the edges between walls.
pub fn leaky_box() -> Scene {
    let mut m = MeshData {
        materials: vec![
            Material::diffuse("wall", Color::splat(0.7)),
            Material { emission: Color::splat(20.0), ..Material::diffuse("lamp", Color::splat(0.5)) },
            Material::diffuse("canopy", Color::splat(0.8)),
        ],
        ..Default::default()
    };
    add_quads(&mut m, &unit_cube_quads().map(|q| q.map(|p| [0.5 * (p[0] + 1.0), 0.5 * (p[1] + 1.0), 0.5 * (p[2] + 1.0)])), 0);
    // Lamp facing down (clockwise seen from above) and a canopy facing down above it.
    add_quads(&mut m, &[[[0.3, 1.2, 0.3], [0.7, 1.2, 0.3], [0.7, 1.2, 0.7], [0.3, 1.2, 0.7]]], 1);
    add_quads(&mut m, &[[[-1.0, 1.6, -1.0], [2.0, 1.6, -1.0], [2.0, 1.6, 2.0], [-1.0, 1.6, 2.0]]], 2);
    let cam = Camera::new(Vec3::new(0.5, 0.5, 0.95), Vec3::new(0.5, 0.5, 0.0), Vec3::Y, 80.0, 64, 64).expect("valid camera");
    let mut s = Scene::new("leaky-box", cam);
    s.add_mesh(&m, &Placement::default(), None).expect("box geometry is valid");
    s
}

/// Thin geometry lit by a sun (boundary bias of photon estimates): a white wall
/// (z = 0, facing +z) and five narrow white slats (8 cm deep, staggered so none
/// shades another) in front of it, in an otherwise empty scene, under a directional
/// light shining straight down. The wall gets no direct light (the sun grazes it); all
/// of its light is reflected from the slats' sunlit tops, whose photon estimates use
/// discs wider than the slats.
pub fn sun_slats() -> Scene {
    let mut m = MeshData { materials: vec![Material::diffuse("white", Color::splat(0.8))], ..Default::default() };
    add_quads(&mut m, &[[[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 2.0, 0.0], [-1.0, 2.0, 0.0]]], 0);
    for i in 0..5 {
        let (y, z0) = (0.2 + 0.35 * i as f32, 0.05 + 0.1 * i as f32);
        let z1 = z0 + 0.08;
        add_quads(&mut m, &[[[-1.0, y, z0], [-1.0, y, z1], [1.0, y, z1], [1.0, y, z0]]], 0);
    }
    let cam = Camera::new(Vec3::new(0.0, 1.0, 3.0), Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 45.0, 64, 64).expect("valid camera");
    let mut s = Scene::new("sun-slats", cam);
    s.add_mesh(&m, &Placement::default(), None).expect("slat geometry is valid");
    s.lights.push(crate::scene::LightDesc::Directional { direction: Vec3::new(0.0, -1.0, 0.0), irradiance: Color::splat(3.0) });
    s
}

/// The six faces of the cube [-1, 1]³, wound outward.
fn unit_cube_quads() -> [[[f32; 3]; 4]; 6] {
    [
        [[-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]],
        [[1.0, -1.0, -1.0], [-1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [1.0, 1.0, -1.0]],
        [[1.0, -1.0, 1.0], [1.0, -1.0, -1.0], [1.0, 1.0, -1.0], [1.0, 1.0, 1.0]],
        [[-1.0, -1.0, -1.0], [-1.0, -1.0, 1.0], [-1.0, 1.0, 1.0], [-1.0, 1.0, -1.0]],
        [[-1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, 1.0, -1.0], [-1.0, 1.0, -1.0]],
        [[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [1.0, -1.0, 1.0], [-1.0, -1.0, 1.0]],
    ]
}

/// A unit UV sphere with vertex normals (smooth shading).
fn smooth_sphere(n: u32) -> MeshData {
    let mut sphere = uv_sphere(n, true, |_, _| 1.0);
    sphere.normals = sphere.positions.iter().map(|p| p.normalize()).collect();
    for f in &mut sphere.faces {
        f.n = Some(f.v);
    }
    sphere
}

/// Sphere triangle mesh: an n × n UV grid (n rings of n segments; the pole triangles
/// collapse and are dropped on loading), winding facing outward when `outward`,
/// otherwise inward. `radius(θ, φ)` displaces it.
pub fn uv_sphere(n: u32, outward: bool, radius: impl Fn(f32, f32) -> f32) -> MeshData {
    uv_sphere_grid(n, n, outward, radius)
}

/// [`uv_sphere`] with `nu` segments around and `nv` rings from pole to pole.
pub fn uv_sphere_grid(nu: u32, nv: u32, outward: bool, radius: impl Fn(f32, f32) -> f32) -> MeshData {
    let mut m = MeshData::default();
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
    s.lights.push(super::LightDesc::Point { position: Vec3::new(2.0, 4.0, 3.0), intensity: Color::splat(30.0) });
    s
}

/// A coarse diffuse sphere in a closed box (shading normals and creases in photon
/// estimates): a 10 × 5-facet UV sphere (10 segments, 5 rings: 36° creases) of
/// radius 0.5 and albedo 0.7, with radial vertex normals (`smooth-sphere`, smooth
/// shading) or without (`faceted-sphere`), in a closed 2 × 2 × 2 box (white floor,
/// ceiling and back wall, red left and green right wall, one-sided walls facing in)
/// lit by a 0.6 × 0.6 area light under the ceiling. With vertex normals `path`
/// shades the facets with the interpolated normal while photons land per geometric
/// area, so a photon estimator agrees with `path` only when it corrects for the
/// difference (Veach 1997, §5.3).
pub fn coarse_sphere_box(vertex_normals: bool) -> Scene {
    let mut m = MeshData {
        materials: vec![
            Material::diffuse("white", Color::splat(0.7)),
            Material::diffuse("red", Color::new(0.63, 0.1, 0.08)),
            Material::diffuse("green", Color::new(0.14, 0.45, 0.1)),
            Material { emission: Color::splat(12.0), ..Material::diffuse("light", Color::splat(0.7)) },
        ],
        ..Default::default()
    };
    let (white, red, green, light) = (0, 1, 2, 3);
    // The unit cube's faces wound inward (reversed), scaled to x, z ∈ [-1, 1], y ∈ [0, 2].
    let inward = unit_cube_quads().map(|q| [q[3], q[2], q[1], q[0]].map(|p| [p[0], p[1] + 1.0, p[2]]));
    // Faces: +z (front), −z (back), +x (right), −x (left), +y (ceiling), −y (floor).
    add_quads(&mut m, &[inward[0], inward[1], inward[4], inward[5]], white);
    add_quads(&mut m, &[inward[3]], red);
    add_quads(&mut m, &[inward[2]], green);
    add_quads(&mut m, &[[[-0.3, 1.99, -0.3], [0.3, 1.99, -0.3], [0.3, 1.99, 0.3], [-0.3, 1.99, 0.3]]], light);
    let cam = Camera::new(Vec3::new(0.0, 1.0, 0.97), Vec3::new(0.0, 0.75, -0.3), Vec3::Y, 66.0, 128, 128).expect("valid camera");
    let name = if vertex_normals { "smooth-sphere" } else { "faceted-sphere" };
    let mut s = Scene::new(name, cam);
    s.add_mesh(&m, &Placement::default(), None).expect("box geometry is valid");
    let mut sphere = uv_sphere_grid(10, 5, true, |_, _| 1.0);
    if vertex_normals {
        sphere.normals = sphere.positions.iter().map(|p| p.normalize()).collect();
        for f in &mut sphere.faces {
            f.n = Some(f.v);
        }
    }
    sphere.materials.push(Material::diffuse("sphere", Color::splat(0.7)));
    let place = Placement { scale: Vec3::splat(0.5), rotate_y_deg: 0.0, translate: Vec3::new(0.0, 0.7, -0.3) };
    s.add_mesh(&sphere, &place, None).expect("sphere geometry is valid");
    s
}

/// A thin panel under a lit ceiling: a closed room (4 × 2.5 × 4 m) of zero-thickness
/// walls, lit only from outside by an area light above its roof (under a canopy that
/// sends light back down), with a zero-thickness panel (1.2 × 1.2 m, both sides
/// reflect) hanging 1 cm under the ceiling, seen from below. Nothing reaches the
/// inside, so the correct image is black (`path` ~1e-8): an estimate that borrows
/// the roof's photons or precomputed irradiance across the 1 cm gap (the panel's
/// upper side faces the same way as the roof, within any disc's thickness) lights
/// the room.
pub fn lamp_panel() -> Scene {
    let mut m = MeshData {
        materials: vec![
            Material::diffuse("wall", Color::splat(0.7)),
            Material { emission: Color::splat(20.0), ..Material::diffuse("lamp", Color::splat(0.5)) },
            Material::diffuse("canopy", Color::splat(0.8)),
            Material::diffuse("panel", Color::splat(0.8)),
        ],
        ..Default::default()
    };
    let (wall, lamp, canopy, panel) = (0, 1, 2, 3);
    // The room: the unit cube's faces scaled to x, z ∈ [0, 4], y ∈ [0, 2.5].
    let room = unit_cube_quads().map(|q| q.map(|p| [2.0 * (p[0] + 1.0), 1.25 * (p[1] + 1.0), 2.0 * (p[2] + 1.0)]));
    add_quads(&mut m, &room, wall);
    // Lamp facing down over the roof, and a canopy facing down above it.
    add_quads(&mut m, &[[[1.2, 3.0, 1.2], [2.8, 3.0, 1.2], [2.8, 3.0, 2.8], [1.2, 3.0, 2.8]]], lamp);
    add_quads(&mut m, &[[[-2.0, 3.6, -2.0], [6.0, 3.6, -2.0], [6.0, 3.6, 6.0], [-2.0, 3.6, 6.0]]], canopy);
    // The panel, 1 cm under the ceiling (y = 2.5), facing down.
    add_quads(&mut m, &[[[1.4, 2.49, 1.4], [2.6, 2.49, 1.4], [2.6, 2.49, 2.6], [1.4, 2.49, 2.6]]], panel);
    let cam = Camera::new(Vec3::new(2.0, 0.9, 3.8), Vec3::new(2.0, 2.2, 2.0), Vec3::Y, 70.0, 128, 128).expect("valid camera");
    let mut s = Scene::new("lamp-panel", cam);
    s.add_mesh(&m, &Placement::default(), None).expect("room geometry is valid");
    s
}

/// Veach's difficult case for path tracing (Veach 1997, fig. 10.4): a room (x < 4 m)
/// lit only through a door left ajar from a neighbouring room (4 m < x < 6 m), whose
/// lamp faces away from the door, onto the far wall. No point of the camera's room
/// sees the lamp: all its light arrives after at least one bounce in the lit room,
/// through a gap of about 14 cm between the door's free edge and its frame (door 0.8 m
/// wide, open 10°). Walls are zero-thickness quads (both sides reflect), the door too.
pub fn door_ajar() -> Scene {
    let mut m = MeshData {
        materials: vec![
            Material::diffuse("wall", Color::new(0.75, 0.72, 0.68)),
            Material::diffuse("floor", Color::new(0.55, 0.45, 0.35)),
            Material::diffuse("door", Color::new(0.6, 0.6, 0.65)),
            Material { emission: Color::new(900.0, 780.0, 600.0), ..Material::diffuse("lamp", Color::splat(0.5)) },
            Material {
                name: "table".into(),
                bsdf: Bsdf::Glossy(Glossy { kd: Color::new(0.3, 0.2, 0.12), ks: Color::splat(0.3), exponent: 40.0 }),
                emission: Color::ZERO,
            },
        ],
        ..Default::default()
    };
    let (w, h, d) = (6.0f32, 2.5f32, 4.0f32);
    // Floor, ceiling and outer walls of both rooms.
    add_quads(&mut m, &[[[0.0, 0.0, 0.0], [w, 0.0, 0.0], [w, 0.0, d], [0.0, 0.0, d]]], 1);
    add_quads(
        &mut m,
        &[
            [[0.0, h, 0.0], [0.0, h, d], [w, h, d], [w, h, 0.0]],
            [[0.0, 0.0, 0.0], [0.0, 0.0, d], [0.0, h, d], [0.0, h, 0.0]],
            [[w, 0.0, 0.0], [w, h, 0.0], [w, h, d], [w, 0.0, d]],
            [[0.0, 0.0, 0.0], [0.0, h, 0.0], [w, h, 0.0], [w, 0.0, 0.0]],
            [[0.0, 0.0, d], [w, 0.0, d], [w, h, d], [0.0, h, d]],
        ],
        0,
    );
    // The dividing wall at x = 4 with a doorway z ∈ [1.6, 2.4], y < 2.
    let (x, z0, z1, top) = (4.0f32, 1.6f32, 2.4f32, 2.0f32);
    add_quads(
        &mut m,
        &[
            [[x, 0.0, 0.0], [x, 0.0, z0], [x, h, z0], [x, h, 0.0]],
            [[x, 0.0, z1], [x, 0.0, d], [x, h, d], [x, h, z1]],
            [[x, top, z0], [x, top, z1], [x, h, z1], [x, h, z0]],
        ],
        0,
    );
    // The door: hinged at z = 2.4, opened 10° into the lit room.
    let a = 10f32.to_radians();
    let (fx, fz) = (x + 0.8 * a.sin(), z1 - 0.8 * a.cos());
    add_quads(&mut m, &[[[x, 0.0, z1], [fx, 0.0, fz], [fx, top, fz], [x, top, z1]]], 2);
    // The lamp: a 0.4 m square facing +x, onto the lit room's far wall.
    add_quads(&mut m, &[[[5.4, 1.0, 1.8], [5.4, 1.4, 1.8], [5.4, 1.4, 2.2], [5.4, 1.0, 2.2]]], 3);
    // A glossy table top in the dark room, near the door.
    add_quads(&mut m, &[[[2.6, 0.7, 1.2], [2.6, 0.7, 2.4], [3.4, 0.7, 2.4], [3.4, 0.7, 1.2]]], 4);
    let cam = Camera::new(Vec3::new(0.4, 1.5, 3.7), Vec3::new(4.0, 0.5, 1.6), Vec3::Y, 62.0, 160, 120).expect("valid camera");
    let mut s = Scene::new("door-ajar", cam);
    s.add_mesh(&m, &Placement::default(), None).expect("room geometry is valid");
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
    fn new_scenes_are_valid() {
        for name in ["cornell-glossy", "cornell-contact", "leaky-box", "sun-slats", "door-ajar"] {
            let s = builtin(name).unwrap();
            assert!(s.validate().is_ok(), "{name}");
        }
        // The cube faces outward.
        let q = unit_cube_quads();
        for quad in q {
            let (a, b, c) = (Vec3::from(quad[0]), Vec3::from(quad[1]), Vec3::from(quad[2]));
            let centre = (a + c) * 0.5;
            assert!((b - a).cross(c - a).dot(centre) > 0.0);
        }
        // The leaky box's lamp faces down.
        let s = leaky_box();
        let lamp: Vec<u32> = (0..s.triangles.len() as u32).filter(|&i| s.material(i).is_emitter()).collect();
        assert!(lamp.iter().all(|&i| s.geometric_normal(i).y < -0.99));
    }

    #[test]
    fn coarse_sphere_boxes_face_inward_and_differ_only_in_normals() {
        let (smooth, faceted) = (coarse_sphere_box(true), coarse_sphere_box(false));
        for s in [&smooth, &faceted] {
            assert!(s.validate().is_ok());
            // 6 walls + light = 14 triangles; 10 × 5 grid = 100, less 20 at the poles.
            assert_eq!(s.triangles.len(), 14 + 80, "{}", s.name);
            for i in 0..14u32 {
                let t = &s.triangles[i as usize];
                let c = (t[0] + t[1] + t[2]) / 3.0;
                assert!(s.geometric_normal(i).dot(Vec3::new(0.0, 1.0, 0.0) - c) > 0.0, "{}: wall {i} faces out", s.name);
            }
        }
        assert_eq!(smooth.triangles, faceted.triangles);
        assert_ne!(smooth.normals.len(), faceted.normals.len());
        assert_eq!(builtin("smooth-sphere").unwrap().name, "smooth-sphere");
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
