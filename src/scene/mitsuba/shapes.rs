//! Mitsuba shapes as triangle meshes: `obj`, `ply`, `rectangle`, `cube`, `disk`,
//! `sphere`, each with `to_world` and `flip_normals` (meshes also `face_normals`).
//!
//! photonlab is triangle-only: `disk` is a fan of [`DISK_SEGMENTS`] triangles and
//! `sphere` a latitude–longitude mesh of [`SPHERE_PHI`]×[`SPHERE_THETA`] cells with
//! exact (radial) vertex normals; their areas are within 1e-4 (disk) and 1.3e-4
//! (sphere) of the analytic ones. Texture coordinates follow Mitsuba's
//! parameterisations.

use super::transform::normal_matrix;
use super::xml::Plugin;
use crate::scene::obj::load_obj_geometry;
use crate::scene::ply::load_ply;
use crate::scene::{Face, MeshData, MeshUvs};
use anyhow::{Result, anyhow};
use glam::{Mat4, Vec2, Vec3};
use std::f32::consts::PI;

/// Triangles of a disk.
pub const DISK_SEGMENTS: u32 = 256;
/// Longitude cells of a sphere.
pub const SPHERE_PHI: u32 = 256;
/// Latitude cells of a sphere.
pub const SPHERE_THETA: u32 = 128;

/// A shape's placed geometry.
pub struct ShapeMesh {
    /// Placed positions, normals and faces (material 0; no materials).
    pub mesh: MeshData,
    /// Texture coordinates.
    pub uvs: Option<MeshUvs>,
}

/// Reads the geometry parameters of `<shape>` `p` and builds its mesh.
pub fn shape_mesh(p: &Plugin, warnings: &mut Vec<String>) -> Result<ShapeMesh> {
    let mut to_world = p.transform("to_world")?.unwrap_or(Mat4::IDENTITY);
    let flip = p.bool_or("flip_normals", false)?;
    let mut smooth_missing_normals = false;
    let (mut mesh, uvs) = match p.ty.as_str() {
        "obj" | "ply" | "serialized" => {
            let (name, loc) = p.string("filename")?.ok_or_else(|| p.err("needs a `filename`"))?;
            let path = loc.resolve(&name);
            let face_normals = p.bool_or("face_normals", false)?;
            let (mut mesh, uvs) = if p.ty == "obj" {
                // Mitsuba flips v by default; photonlab's texture space is Mitsuba's.
                if !p.bool_or("flip_tex_coords", true)? {
                    return Err(p.err("flip_tex_coords=false is not supported"));
                }
                let o = load_obj_geometry(&path).map_err(|e| anyhow!("{loc}: {e}"))?;
                warnings.extend(o.warnings);
                let has_uv = o.uvs.faces.iter().any(Option::is_some);
                (o.mesh, has_uv.then_some(o.uvs))
            } else {
                let m = if p.ty == "ply" {
                    load_ply(&path)
                } else {
                    let index = p.int("shape_index")?.unwrap_or(0);
                    let index = u32::try_from(index).map_err(|_| p.err(format!("shape_index must not be negative, got {index}")))?;
                    crate::scene::serialized::load_serialized(&path, index)
                }
                .map_err(|e| anyhow!("{loc}: {e:#}"))?;
                warnings.extend(m.warnings);
                (m.mesh, m.uvs)
            };
            if face_normals {
                mesh.normals.clear();
                for f in mesh.faces.iter_mut() {
                    f.n = None;
                }
            } else {
                smooth_missing_normals = mesh.faces.iter().any(|f| f.n.is_none());
            }
            mesh.materials.clear();
            for f in mesh.faces.iter_mut() {
                f.material = 0;
            }
            (mesh, uvs)
        }
        "rectangle" => rectangle(),
        "cube" => cube(),
        "disk" => disk(),
        "sphere" => {
            let c = p.point("center")?.unwrap_or(Vec3::ZERO);
            let r = p.float_or("radius", 1.0)?;
            if r <= 0.0 {
                return Err(p.err(format!("radius must be positive, got {r}")));
            }
            to_world = to_world * Mat4::from_translation(c) * Mat4::from_scale(Vec3::splat(r));
            sphere()
        }
        other => return Err(p.err(format!("shape type `{other}` is not supported (obj, ply, serialized, rectangle, cube, disk, sphere)"))),
    };
    if to_world.determinant() == 0.0 {
        return Err(p.err("`to_world` is singular"));
    }
    let nm = normal_matrix(&to_world);
    for v in mesh.positions.iter_mut() {
        *v = to_world.transform_point3(*v);
    }
    for n in mesh.normals.iter_mut() {
        *n = nm.transform_vector3(*n).normalize_or_zero();
    }
    if flip {
        // Reversed winding flips the geometric normal (the emitting and front side);
        // vertex normals follow.
        for f in mesh.faces.iter_mut() {
            f.v.swap(1, 2);
            if let Some(n) = f.n.as_mut() {
                n.swap(1, 2);
            }
        }
        for n in mesh.normals.iter_mut() {
            *n = -*n;
        }
    }
    if smooth_missing_normals {
        smooth_normals(&mut mesh, uvs.as_ref());
    }
    let mut uvs = uvs;
    if flip && let Some(u) = uvs.as_mut() {
        for t in u.faces.iter_mut().flatten() {
            t.swap(1, 2);
        }
    }
    Ok(ShapeMesh { mesh, uvs })
}

/// Mitsuba's `recompute_vertex_normals` for faces without normals: each vertex gets
/// the sum of its faces' normals weighted by the corner angle (Thürmer and Wüthrich
/// 1998), normalised. Vertices are Mitsuba's: a position with a different texture
/// coordinate is another vertex (its OBJ reader merges corners by (v, vt, vn)).
fn smooth_normals(mesh: &mut MeshData, uvs: Option<&MeshUvs>) {
    let mut slot: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
    let mut sums: Vec<Vec3> = Vec::new();
    let base = mesh.normals.len() as u32;
    let mut corner_slots: Vec<Option<[u32; 3]>> = Vec::with_capacity(mesh.faces.len());
    for (fi, f) in mesh.faces.iter().enumerate() {
        if f.n.is_some() {
            corner_slots.push(None);
            continue;
        }
        let t = uvs.and_then(|u| u.faces.get(fi).copied().flatten());
        let p = f.v.map(|k| mesh.positions.get(k as usize).copied().unwrap_or(Vec3::ZERO));
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        let mut ids = [0u32; 3];
        for c in 0..3 {
            let key = (f.v[c], t.map_or(u32::MAX, |t| t[c]));
            let id = *slot.entry(key).or_insert_with(|| {
                sums.push(Vec3::ZERO);
                (sums.len() - 1) as u32
            });
            let d0 = (p[(c + 1) % 3] - p[c]).normalize_or_zero();
            let d1 = (p[(c + 2) % 3] - p[c]).normalize_or_zero();
            let angle = d0.dot(d1).clamp(-1.0, 1.0).acos();
            sums[id as usize] += n * angle;
            ids[c] = base + id;
        }
        corner_slots.push(Some(ids));
    }
    mesh.normals.extend(sums.into_iter().map(|n| n.normalize_or_zero()));
    for (f, ids) in mesh.faces.iter_mut().zip(corner_slots) {
        if ids.is_some() {
            f.n = ids;
        }
    }
}

fn face(v: [u32; 3], with_normals: bool) -> Face {
    Face { v, n: with_normals.then_some(v), material: 0, line: 0 }
}

fn rectangle() -> (MeshData, Option<MeshUvs>) {
    let positions = vec![Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(-1.0, 1.0, 0.0)];
    let faces = vec![face([0, 1, 2], false), face([0, 2, 3], false)];
    let uvs = positions.iter().map(|p| Vec2::new(0.5 * (p.x + 1.0), 0.5 * (p.y + 1.0))).collect();
    (MeshData { positions, faces, ..Default::default() }, Some(MeshUvs { uvs, faces: vec![Some([0, 1, 2]), Some([0, 2, 3])] }))
}

fn cube() -> (MeshData, Option<MeshUvs>) {
    let mut m = MeshData::default();
    let mut uv = MeshUvs::default();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let n = Vec3::from_array(std::array::from_fn(|k| if k == axis { sign } else { 0.0 }));
            // Two tangents with t1 × t2 = n.
            let t1 = Vec3::from_array(std::array::from_fn(|k| if k == (axis + 1) % 3 { 1.0 } else { 0.0 }));
            let t2 = n.cross(t1);
            let base = m.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                m.positions.push(n + t1 * a + t2 * b);
                uv.uvs.push(Vec2::new(0.5 * (a + 1.0), 0.5 * (b + 1.0)));
            }
            for t in [[base, base + 1, base + 2], [base, base + 2, base + 3]] {
                m.faces.push(face(t, false));
                uv.faces.push(Some(t));
            }
        }
    }
    (m, Some(uv))
}

fn disk() -> (MeshData, Option<MeshUvs>) {
    let mut m = MeshData { positions: vec![Vec3::ZERO], ..Default::default() };
    let mut uv = MeshUvs::default();
    let n = DISK_SEGMENTS;
    for i in 0..n {
        let phi = 2.0 * PI * i as f32 / n as f32;
        m.positions.push(Vec3::new(phi.cos(), phi.sin(), 0.0));
    }
    for i in 0..n {
        let (a, b) = (1 + i, 1 + (i + 1) % n);
        m.faces.push(face([0, a, b], false));
        // Mitsuba's polar parameterisation (r, φ/2π), per face so φ does not wrap.
        let k = uv.uvs.len() as u32;
        let (u0, u1) = (i as f32 / n as f32, (i + 1) as f32 / n as f32);
        uv.uvs.extend([Vec2::new(0.0, 0.5 * (u0 + u1)), Vec2::new(1.0, u0), Vec2::new(1.0, u1)]);
        uv.faces.push(Some([k, k + 1, k + 2]));
    }
    (m, Some(uv))
}

/// Unit sphere about the origin, z the polar axis, outward winding.
fn sphere() -> (MeshData, Option<MeshUvs>) {
    let (np, nt) = (SPHERE_PHI, SPHERE_THETA);
    let mut m = MeshData::default();
    let mut uv = MeshUvs::default();
    for j in 0..=nt {
        let theta = PI * j as f32 / nt as f32;
        // Exact poles.
        let (st, ct) = match j {
            0 => (0.0, 1.0),
            j if j == nt => (0.0, -1.0),
            _ => theta.sin_cos(),
        };
        for i in 0..=np {
            let phi = 2.0 * PI * (i % np) as f32 / np as f32;
            let p = Vec3::new(st * phi.cos(), st * phi.sin(), ct);
            m.positions.push(p);
            m.normals.push(p);
            uv.uvs.push(Vec2::new(i as f32 / np as f32, j as f32 / nt as f32));
        }
    }
    let id = |i: u32, j: u32| j * (np + 1) + i;
    for j in 0..nt {
        for i in 0..np {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            // theta grows downwards from +z and phi anticlockwise about z: (a, d, c)
            // winds outwards.
            for (k, t) in [[a, d, c], [a, c, b]].into_iter().enumerate() {
                // The degenerate half of a pole cell.
                if (j == 0 && k == 1) || (j == nt - 1 && k == 0) {
                    continue;
                }
                m.faces.push(face(t, true));
                uv.faces.push(Some(t));
            }
        }
    }
    (m, Some(uv))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area_and_orientation(m: &MeshData) -> (f32, bool) {
        let mut area = 0.0f64;
        let mut outward = true;
        for f in &m.faces {
            let p = f.v.map(|k| m.positions[k as usize]);
            let c = (p[1] - p[0]).cross(p[2] - p[0]);
            area += 0.5 * c.length() as f64;
            let centre = (p[0] + p[1] + p[2]) / 3.0;
            outward &= c.dot(centre) > 0.0 || centre.z.abs() < 1e-6 && c.z > 0.0;
        }
        (area as f32, outward)
    }

    #[test]
    fn primitives_have_mitsuba_areas_and_orientation() {
        let (a, out) = area_and_orientation(&sphere().0);
        assert!(out);
        assert!((a / (4.0 * PI) - 1.0).abs() < 2e-4, "{a}");
        let (a, _) = area_and_orientation(&disk().0);
        assert!((a / PI - 1.0).abs() < 2e-4, "{a}");
        let (a, out) = area_and_orientation(&cube().0);
        assert!(out && (a - 24.0).abs() < 1e-5);
        let r = rectangle().0;
        let p = r.faces[0].v.map(|k| r.positions[k as usize]);
        assert!((p[1] - p[0]).cross(p[2] - p[0]).z > 0.0, "rectangle faces +z");
    }
}
