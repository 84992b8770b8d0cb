//! Scene representation: camera, triangles with materials and optional vertex
//! normals, non-geometric lights. Loading follows `scene-format.md`
//! ([`loader`]); built-in scenes are generated in code ([`builtin`]).

pub mod builtin;
pub mod export;
pub mod loader;
pub mod mitsuba;
pub mod obj;
pub mod ply;
pub mod serialized;
pub mod textures;

use crate::camera::Camera;
use crate::geometry::Aabb;
use crate::material::Material;
use crate::math::Color;
use glam::{Vec2, Vec3};
use std::path::PathBuf;

/// Marker for "this triangle has no vertex normals".
pub const NO_NORMALS: u32 = u32::MAX;

/// One triangle face of a mesh before placement.
#[derive(Clone, Debug, PartialEq)]
pub struct Face {
    /// Position indices.
    pub v: [u32; 3],
    /// Normal indices, where the OBJ gave them.
    pub n: Option<[u32; 3]>,
    /// Index into the mesh's material list.
    pub material: u32,
    /// Source line (OBJ) for messages; 0 when generated.
    pub line: u32,
}

/// A mesh as read from an OBJ (or generated): indexed positions, normals, faces and
/// the materials its faces use.
#[derive(Clone, Debug, Default)]
pub struct MeshData {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Vertex normals.
    pub normals: Vec<Vec3>,
    /// Triangles (polygons already fan-triangulated).
    pub faces: Vec<Face>,
    /// Materials referenced by `faces`.
    pub materials: Vec<Material>,
}

/// Texture coordinates of a mesh, kept apart from [`MeshData`]: `faces[i]` gives the
/// `uvs` indices of `MeshData::faces[i]` (`None`: that face has none).
#[derive(Clone, Debug, Default)]
pub struct MeshUvs {
    /// Texture coordinates.
    pub uvs: Vec<Vec2>,
    /// Per face, its corners' indices into `uvs`.
    pub faces: Vec<Option<[u32; 3]>>,
}

/// Marker for "this triangle has no texture coordinates".
pub const NO_UVS: u32 = u32::MAX;

/// Affine placement of a mesh: scale, then rotation about +y, then translation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// Per-axis scale.
    pub scale: Vec3,
    /// Rotation about the y axis in degrees.
    pub rotate_y_deg: f32,
    /// Translation.
    pub translate: Vec3,
}

impl Default for Placement {
    fn default() -> Self {
        Placement { scale: Vec3::ONE, rotate_y_deg: 0.0, translate: Vec3::ZERO }
    }
}

impl Placement {
    /// Applies the placement to a point.
    pub fn point(&self, p: Vec3) -> Vec3 {
        let s = p * self.scale;
        let (sin, cos) = self.rotate_y_deg.to_radians().sin_cos();
        let r = Vec3::new(cos * s.x + sin * s.z, s.y, -sin * s.x + cos * s.z);
        r + self.translate
    }
    /// Applies the placement to a normal (inverse transpose), renormalised.
    pub fn normal(&self, n: Vec3) -> Vec3 {
        let s = n / self.scale;
        let (sin, cos) = self.rotate_y_deg.to_radians().sin_cos();
        unit_or_zero(Vec3::new(cos * s.x + sin * s.z, s.y, -sin * s.x + cos * s.z))
    }
}

/// Normalises `v` (zero stays zero), leaving vectors that are already unit length to
/// within rounding untouched, so that normalising twice gives the same bits: an
/// exported and re-loaded scene then has identical normals and light directions.
pub fn unit_or_zero(v: Vec3) -> Vec3 {
    if (v.length_squared() - 1.0).abs() <= 4.0 * f32::EPSILON { v } else { v.normalize_or_zero() }
}

/// A non-geometric light as described in the scene file.
#[derive(Clone, Debug, PartialEq)]
pub enum LightDesc {
    /// Isotropic point light; intensity in W/sr.
    Point {
        /// Position.
        position: Vec3,
        /// Radiant intensity.
        intensity: Color,
    },
    /// Spot light: full intensity inside `cone_deg`, falling linearly in angle to zero at
    /// `falloff_deg`.
    Spot {
        /// Position.
        position: Vec3,
        /// Unit axis.
        direction: Vec3,
        /// Radiant intensity on the axis.
        intensity: Color,
        /// Full-power half angle (degrees).
        cone_deg: f32,
        /// Outer half angle (degrees).
        falloff_deg: f32,
    },
    /// Distant light; `direction` is the direction light travels.
    Directional {
        /// Unit travel direction.
        direction: Vec3,
        /// Irradiance on a surface facing the light (W/m²).
        irradiance: Color,
    },
    /// Uniform environment light (Mitsuba's `constant`).
    Constant {
        /// Radiance arriving from every direction.
        radiance: Color,
    },
    /// Equirectangular environment map (Mitsuba's `envmap`).
    Envmap {
        /// Linear RGB image, Mitsuba's latitude–longitude layout.
        image: std::sync::Arc<crate::texture::Image>,
        /// Radiance scale.
        scale: f32,
        /// Environment-to-world rotation (`to_world`).
        to_world: glam::Mat4,
    },
}

/// A renderable scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Name (built-in name or file stem).
    pub name: String,
    /// File the scene came from, if any.
    pub source: Option<PathBuf>,
    /// The camera.
    pub camera: Camera,
    /// Placed triangle vertices.
    pub triangles: Vec<[Vec3; 3]>,
    /// Material index per triangle.
    pub tri_material: Vec<u32>,
    /// Index into `normals` per triangle, or [`NO_NORMALS`].
    pub tri_normals: Vec<u32>,
    /// Placed vertex normals, three per entry.
    pub normals: Vec<[Vec3; 3]>,
    /// Index into `uvs` per triangle, or [`NO_UVS`]; may be shorter than `triangles`
    /// (missing entries have none).
    pub tri_uvs: Vec<u32>,
    /// Texture coordinates, three per entry.
    pub uvs: Vec<[Vec2; 3]>,
    /// Image textures and their bindings to material parameters.
    pub textures: crate::texture::SceneTextures,
    /// Samples per pixel the scene file suggests (Mitsuba's `sample_count`); the
    /// command line's `--spp` wins.
    pub default_spp: Option<u32>,
    /// Materials.
    pub materials: Vec<Material>,
    /// Point, spot and directional lights.
    pub lights: Vec<LightDesc>,
    /// Bounds of all triangles.
    pub bounds: Aabb,
    /// Number of zero-area triangles dropped while loading.
    pub dropped_degenerate: usize,
    /// Non-fatal remarks made while loading (shown to the user).
    pub warnings: Vec<String>,
}

impl Scene {
    /// An empty scene with the given camera.
    pub fn new(name: &str, camera: Camera) -> Self {
        Scene {
            name: name.into(),
            source: None,
            camera,
            triangles: Vec::new(),
            tri_material: Vec::new(),
            tri_normals: Vec::new(),
            normals: Vec::new(),
            tri_uvs: Vec::new(),
            uvs: Vec::new(),
            textures: Default::default(),
            default_spp: None,
            materials: Vec::new(),
            lights: Vec::new(),
            bounds: Aabb::EMPTY,
            dropped_degenerate: 0,
            warnings: Vec::new(),
        }
    }

    /// Adds a mesh with a placement and an optional material override. Zero-area
    /// triangles are dropped and counted. Non-finite coordinates are an error
    /// (the message names the face's source line when known).
    pub fn add_mesh(&mut self, mesh: &MeshData, place: &Placement, override_material: Option<&Material>) -> anyhow::Result<()> {
        self.add_mesh_uv(mesh, None, place, override_material)
    }

    /// [`Scene::add_mesh`] with texture coordinates.
    pub fn add_mesh_uv(
        &mut self,
        mesh: &MeshData,
        uvs: Option<&MeshUvs>,
        place: &Placement,
        override_material: Option<&Material>,
    ) -> anyhow::Result<()> {
        if !place.scale.is_finite() || place.scale.cmpeq(Vec3::ZERO).any() {
            return Err(anyhow::anyhow!("scale must be finite and non-zero, got {:?}", place.scale.to_array()));
        }
        let mat_base = self.materials.len() as u32;
        match override_material {
            Some(m) => self.materials.push(m.clone()),
            None => self.materials.extend(mesh.materials.iter().cloned()),
        }
        if mesh.materials.is_empty() && override_material.is_none() {
            return Err(anyhow::anyhow!("mesh has no materials"));
        }
        for (i, p) in mesh.positions.iter().enumerate() {
            if !p.is_finite() {
                return Err(anyhow::anyhow!("vertex {} has a non-finite coordinate {:?}", i + 1, p.to_array()));
            }
        }
        for (i, n) in mesh.normals.iter().enumerate() {
            if !n.is_finite() {
                return Err(anyhow::anyhow!("vertex normal {} has a non-finite component {:?}", i + 1, n.to_array()));
            }
        }
        let placed: Vec<Vec3> = mesh.positions.iter().map(|&p| place.point(p)).collect();
        let placed_n: Vec<Vec3> = mesh.normals.iter().map(|&n| place.normal(n)).collect();
        for (fi, f) in mesh.faces.iter().enumerate() {
            let get = |i: u32| placed.get(i as usize).copied();
            let (Some(a), Some(b), Some(c)) = (get(f.v[0]), get(f.v[1]), get(f.v[2])) else {
                return Err(anyhow::anyhow!("face at line {} refers to a vertex that does not exist", f.line));
            };
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                return Err(anyhow::anyhow!("face at line {} has a non-finite placed coordinate", f.line));
            }
            let area2 = (b - a).cross(c - a).length();
            if area2.is_nan() || area2 <= 0.0 {
                self.dropped_degenerate += 1;
                continue;
            }
            let normals_idx = match f.n {
                Some(ni) => {
                    let g = |i: u32| placed_n.get(i as usize).copied();
                    let (Some(na), Some(nb), Some(nc)) = (g(ni[0]), g(ni[1]), g(ni[2])) else {
                        return Err(anyhow::anyhow!("face at line {} refers to a normal that does not exist", f.line));
                    };
                    if na == Vec3::ZERO || nb == Vec3::ZERO || nc == Vec3::ZERO {
                        NO_NORMALS
                    } else {
                        self.normals.push([na, nb, nc]);
                        (self.normals.len() - 1) as u32
                    }
                }
                None => NO_NORMALS,
            };
            let m = if override_material.is_some() { mat_base } else { mat_base + f.material };
            if let Some(t) = uvs.and_then(|u| u.faces.get(fi).copied().flatten()) {
                let u = &uvs.expect("checked").uvs;
                let g = |i: u32| u.get(i as usize).copied().filter(|v| v.is_finite());
                let (Some(ta), Some(tb), Some(tc)) = (g(t[0]), g(t[1]), g(t[2])) else {
                    return Err(anyhow::anyhow!(
                        "face at line {} refers to a texture coordinate that does not exist or is not finite",
                        f.line
                    ));
                };
                self.tri_uvs.resize(self.triangles.len(), NO_UVS);
                self.tri_uvs.push(self.uvs.len() as u32);
                self.uvs.push([ta, tb, tc]);
            }
            self.triangles.push([a, b, c]);
            self.tri_material.push(m);
            self.tri_normals.push(normals_idx);
            for p in [a, b, c] {
                self.bounds.grow(p);
            }
        }
        Ok(())
    }

    /// Geometric (winding) unit normal of triangle `i`.
    #[inline]
    pub fn geometric_normal(&self, i: u32) -> Vec3 {
        let t = &self.triangles[i as usize];
        (t[1] - t[0]).cross(t[2] - t[0]).normalize()
    }

    /// Area of triangle `i`.
    #[inline]
    pub fn triangle_area(&self, i: u32) -> f32 {
        let t = &self.triangles[i as usize];
        0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length()
    }

    /// Material of triangle `i`.
    #[inline]
    pub fn material(&self, i: u32) -> &Material {
        &self.materials[self.tri_material[i as usize] as usize]
    }

    /// Checks what rendering needs: at least one triangle and one light.
    pub fn validate(&self) -> anyhow::Result<()> {
        if self.triangles.is_empty() {
            return Err(anyhow::anyhow!("scene has no (non-degenerate) triangles"));
        }
        let has_emitter = self.tri_material.iter().any(|&m| self.materials[m as usize].is_emitter());
        if !has_emitter && self.lights.is_empty() {
            return Err(anyhow::anyhow!("scene has no light: no emissive (Ke) material is used and no [[light]] is given"));
        }
        Ok(())
    }
}

impl Scene {
    /// Hash of everything in a scene that affects an image: geometry, normals,
    /// materials, lights and camera.
    pub fn fingerprint(&self) -> u64 {
        let scene = self;
        let mut h = crate::math::Fnv::default();
        for t in &scene.triangles {
            for v in t {
                for c in v.to_array() {
                    h.write(&c.to_bits().to_le_bytes());
                }
            }
        }
        for m in &scene.tri_material {
            h.write(&m.to_le_bytes());
        }
        for n in &scene.tri_normals {
            h.write(&n.to_le_bytes());
        }
        for ns in &scene.normals {
            for v in ns {
                for c in v.to_array() {
                    h.write(&c.to_bits().to_le_bytes());
                }
            }
        }
        for t in &scene.tri_uvs {
            h.write(&t.to_le_bytes());
        }
        for t in &scene.uvs {
            for v in t {
                for c in v.to_array() {
                    h.write(&c.to_bits().to_le_bytes());
                }
            }
        }
        h.str(&format!("{:?}", scene.textures));
        // Debug output of floats is exact (shortest round-trip), so it is a faithful key.
        h.str(&format!("{:?}", scene.materials));
        h.str(&format!("{:?}", scene.lights));
        h.str(&format!("{:?}", scene.camera));
        h.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placement_order_scale_rotate_translate() {
        let p = Placement { scale: Vec3::new(2.0, 1.0, 1.0), rotate_y_deg: 90.0, translate: Vec3::new(0.0, 0.0, 1.0) };
        // (1,0,0) -> scale (2,0,0) -> rotate +90 about y: x->-z -> (0,0,-2) -> translate (0,0,-1)
        let q = p.point(Vec3::X);
        assert!((q - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-5, "{q}");
    }
}
