//! Scene TOML reading per `scene-format.md`.
//!
//! Choices where the contract is silent:
//! * `[camera]`: `eye`, `look_at`, `fov_y_deg` and `resolution` are required; `up`
//!   defaults to `[0, 1, 0]`.
//! * `[[light]]`: every key of its type is required (no defaults), so that a scene
//!   means the same thing to every tool that reads it. Spot lights need
//!   `0 <= cone_deg <= falloff_deg <= 180` and `falloff_deg > 0`; directions are
//!   normalised and must not be zero.
//! * Colours are `[r, g, b]` arrays of finite, non-negative numbers; `scale` may be a
//!   number or `[sx, sy, sz]`, finite and non-zero.
//! * Unknown keys and unknown material or light types are errors.
//! * A mesh whose OBJ has no faces is skipped with a warning.
//!
//! Every error is one line naming the scene file, with `line:column` where the TOML
//! parser or the value's position tells it, and the OBJ/MTL `file:line` for errors
//! inside a mesh.

use super::obj::{ObjFile, load_obj};
use super::{Placement, Scene, unit_or_zero};
use crate::camera::Camera;
use crate::material::{Bsdf, Dielectric, Glossy, Lambertian, Material, Mirror};
use crate::math::Color;
use crate::scene::LightDesc;
use anyhow::{Result, anyhow};
use glam::Vec3;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// The whole scene file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneToml {
    camera: Spanned<CameraToml>,
    #[serde(default)]
    mesh: Vec<Spanned<MeshToml>>,
    #[serde(default)]
    light: Vec<Spanned<LightToml>>,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraToml {
    eye: [f32; 3],
    look_at: [f32; 3],
    #[serde(default = "default_up")]
    up: [f32; 3],
    fov_y_deg: f32,
    resolution: [u32; 2],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshToml {
    obj: String,
    #[serde(default)]
    scale: Option<Scale>,
    #[serde(default)]
    rotate_y_deg: Option<f32>,
    #[serde(default)]
    translate: Option<[f32; 3]>,
    #[serde(default)]
    material: Option<OverrideToml>,
}

/// `scale = s` or `scale = [sx, sy, sz]`.
struct Scale(Vec3);

impl<'de> Deserialize<'de> for Scale {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Scale;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number or an array of 3 numbers")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> std::result::Result<Scale, E> {
                Ok(Scale(Vec3::splat(v as f32)))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> std::result::Result<Scale, E> {
                Ok(Scale(Vec3::splat(v as f32)))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> std::result::Result<Scale, E> {
                Ok(Scale(Vec3::splat(v as f32)))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<Scale, A::Error> {
                let mut c = [0.0f32; 3];
                for (i, slot) in c.iter_mut().enumerate() {
                    *slot = seq.next_element()?.ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<f32>()?.is_some() {
                    return Err(serde::de::Error::invalid_length(4, &self));
                }
                Ok(Scale(Vec3::from_array(c)))
            }
        }
        d.deserialize_any(V)
    }
}

/// The contract's material override table (aliases and defaults).
#[derive(Deserialize)]
#[serde(tag = "type", deny_unknown_fields)]
enum OverrideToml {
    #[serde(rename = "diffuse", alias = "lambertian")]
    Diffuse {
        #[serde(alias = "kd")]
        albedo: Option<[f32; 3]>,
    },
    #[serde(rename = "mirror")]
    Mirror {
        #[serde(alias = "ks")]
        reflectance: Option<[f32; 3]>,
    },
    #[serde(rename = "glass", alias = "dielectric")]
    Glass {
        ior: Option<f32>,
        #[serde(alias = "tf")]
        tint: Option<[f32; 3]>,
    },
    #[serde(rename = "glossy")]
    Glossy {
        #[serde(alias = "albedo")]
        kd: Option<[f32; 3]>,
        ks: Option<[f32; 3]>,
        #[serde(alias = "exponent")]
        ns: Option<f32>,
    },
    #[serde(rename = "emitter")]
    Emitter {
        #[serde(alias = "ke")]
        radiance: Option<[f32; 3]>,
        #[serde(alias = "kd")]
        albedo: Option<[f32; 3]>,
    },
}

#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
enum LightToml {
    Point { position: [f32; 3], intensity: [f32; 3] },
    Spot { position: [f32; 3], direction: [f32; 3], intensity: [f32; 3], cone_deg: f32, falloff_deg: f32 },
    Directional { direction: [f32; 3], irradiance: [f32; 3] },
}

/// 1-based line and column of a byte offset (also used for manifest errors).
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// Where a value sits in the scene file, for messages: `file:line`.
struct Locator<'a> {
    file: &'a Path,
    text: &'a str,
}

impl Locator<'_> {
    fn at<T>(&self, s: &Spanned<T>) -> String {
        let (l, _) = line_col(self.text, s.span().start);
        format!("{}:{l}", self.file.display())
    }
}

/// Checks a colour: finite, non-negative.
fn colour(c: [f32; 3], what: &str) -> std::result::Result<Color, String> {
    let v = Vec3::from_array(c);
    if !v.is_finite() || v.min_element() < 0.0 {
        return Err(format!("{what} must be finite and non-negative, got {c:?}"));
    }
    Ok(v)
}

/// Checks a finite vector.
fn finite(c: [f32; 3], what: &str) -> std::result::Result<Vec3, String> {
    let v = Vec3::from_array(c);
    if v.is_finite() { Ok(v) } else { Err(format!("{what} must be finite, got {c:?}")) }
}

/// Checks and normalises a direction.
fn direction(c: [f32; 3], what: &str) -> std::result::Result<Vec3, String> {
    let v = unit_or_zero(finite(c, what)?);
    if v == Vec3::ZERO { Err(format!("{what} must not be zero")) } else { Ok(v) }
}

/// Builds the override material with the contract's defaults.
fn override_material(m: &OverrideToml, name: &str) -> std::result::Result<Material, String> {
    let grey = [0.5f32; 3];
    let mut mat = Material::diffuse(name, Color::splat(0.5));
    match m {
        OverrideToml::Diffuse { albedo } => mat.bsdf = Bsdf::Lambertian(Lambertian { albedo: colour(albedo.unwrap_or(grey), "albedo")? }),
        OverrideToml::Mirror { reflectance } => {
            mat.bsdf = Bsdf::Mirror(Mirror { reflectance: colour(reflectance.unwrap_or([1.0; 3]), "reflectance")? })
        }
        OverrideToml::Glass { ior, tint } => {
            let ior = ior.unwrap_or(1.5);
            if !(ior.is_finite() && ior > 0.0) {
                return Err(format!("ior must be finite and positive, got {ior}"));
            }
            mat.bsdf = Bsdf::Dielectric(Dielectric { ior, tint: colour(tint.unwrap_or([1.0; 3]), "tint")? });
        }
        OverrideToml::Glossy { kd, ks, ns } => {
            let exponent = ns.unwrap_or(1.0);
            if !(exponent.is_finite() && exponent >= 0.0) {
                return Err(format!("ns must be finite and non-negative, got {exponent}"));
            }
            mat.bsdf = Bsdf::Glossy(Glossy { kd: colour(kd.unwrap_or(grey), "kd")?, ks: colour(ks.unwrap_or([0.0; 3]), "ks")?, exponent });
        }
        OverrideToml::Emitter { radiance, albedo } => {
            mat.bsdf = Bsdf::Lambertian(Lambertian { albedo: colour(albedo.unwrap_or(grey), "albedo")? });
            mat.emission = colour(radiance.unwrap_or([0.0; 3]), "radiance")?;
        }
    }
    Ok(mat)
}

/// Converts a `[[light]]` entry.
fn light_desc(l: &LightToml) -> std::result::Result<LightDesc, String> {
    Ok(match *l {
        LightToml::Point { position, intensity } => {
            LightDesc::Point { position: finite(position, "position")?, intensity: colour(intensity, "intensity")? }
        }
        LightToml::Spot { position, direction: dir, intensity, cone_deg, falloff_deg } => {
            if !(cone_deg >= 0.0 && cone_deg <= falloff_deg && falloff_deg <= 180.0 && falloff_deg > 0.0) {
                return Err(format!(
                    "spot light needs 0 <= cone_deg <= falloff_deg <= 180 and falloff_deg > 0, got cone_deg {cone_deg}, falloff_deg {falloff_deg}"
                ));
            }
            LightDesc::Spot {
                position: finite(position, "position")?,
                direction: direction(dir, "direction")?,
                intensity: colour(intensity, "intensity")?,
                cone_deg,
                falloff_deg,
            }
        }
        LightToml::Directional { direction: dir, irradiance } => {
            LightDesc::Directional { direction: direction(dir, "direction")?, irradiance: colour(irradiance, "irradiance")? }
        }
    })
}

/// Loads a scene file (TOML with OBJ/MTL meshes) following `scene-format.md`.
///
/// Non-fatal remarks (undefined materials, negative scales, dropped zero-area
/// triangles, ignored MTL statements) end up in `scene.warnings`.
pub fn load_scene(path: &Path) -> Result<Scene> {
    let file = path.display();
    let text = std::fs::read_to_string(path).map_err(|e| anyhow!("{file}: cannot read scene file: {e}"))?;
    let doc: SceneToml = toml::from_str(&text).map_err(|e| {
        let msg = e.message().replace('\n', " ");
        match e.span() {
            Some(s) => {
                let (l, c) = line_col(&text, s.start);
                anyhow!("{file}:{l}:{c}: {msg}")
            }
            None => anyhow!("{file}: {msg}"),
        }
    })?;
    let loc = Locator { file: path, text: &text };
    let dir = path.parent().unwrap_or(Path::new(""));

    let c = doc.camera.get_ref();
    let camera = Camera::new(
        Vec3::from_array(c.eye),
        Vec3::from_array(c.look_at),
        Vec3::from_array(c.up),
        c.fov_y_deg,
        c.resolution[0],
        c.resolution[1],
    )
    .map_err(|e| anyhow!("{}: [camera]: {e}", loc.at(&doc.camera)))?;
    let name = path.file_stem().map_or_else(|| "scene".to_string(), |s| s.to_string_lossy().into_owned());
    let mut scene = Scene::new(&name, camera);
    scene.source = Some(path.to_path_buf());

    for (i, m) in doc.mesh.iter().enumerate() {
        let at = || format!("{}: [[mesh]] {}", loc.at(m), i + 1);
        let mt = m.get_ref();
        let place = Placement {
            scale: mt.scale.as_ref().map_or(Vec3::ONE, |s| s.0),
            rotate_y_deg: mt.rotate_y_deg.unwrap_or(0.0),
            translate: Vec3::from_array(mt.translate.unwrap_or([0.0; 3])),
        };
        if !place.scale.is_finite() || place.scale.cmpeq(Vec3::ZERO).any() {
            return Err(anyhow!("{}: scale must be finite and non-zero, got {:?}", at(), place.scale.to_array()));
        }
        if !place.rotate_y_deg.is_finite() || !place.translate.is_finite() {
            return Err(anyhow!("{}: rotate_y_deg and translate must be finite", at()));
        }
        let obj_path: PathBuf = dir.join(&mt.obj);
        let override_mat = match &mt.material {
            Some(o) => Some(override_material(o, &format!("{} (override)", mt.obj)).map_err(|e| anyhow!("{}: material: {e}", at()))?),
            None => None,
        };
        let ObjFile { mesh, warnings } = load_obj(&obj_path).map_err(|e| anyhow!("{}: {e}", at()))?;
        scene.warnings.extend(warnings);
        if place.scale.min_element() < 0.0 {
            let mirrored = place.scale.x * place.scale.y * place.scale.z < 0.0;
            scene.warnings.push(if mirrored {
                format!("{}: negative scale mirrors the mesh; its triangles' front sides flip with it (not corrected)", at())
            } else {
                format!("{}: negative scale components (an even number: a rotation, not a mirror)", at())
            });
        }
        if mesh.faces.is_empty() {
            scene.warnings.push(format!("{}: {} has no faces", at(), obj_path.display()));
            continue;
        }
        let before = scene.dropped_degenerate;
        scene.add_mesh(&mesh, &place, override_mat.as_ref()).map_err(|e| anyhow!("{}: {}: {e}", at(), obj_path.display()))?;
        let dropped = scene.dropped_degenerate - before;
        if dropped > 0 {
            scene.warnings.push(format!("{}: dropped {dropped} zero-area triangle(s) of {}", at(), obj_path.display()));
        }
    }
    for (i, l) in doc.light.iter().enumerate() {
        let d = light_desc(l.get_ref()).map_err(|e| anyhow!("{}: [[light]] {}: {e}", loc.at(l), i + 1))?;
        scene.lights.push(d);
    }
    scene.validate().map_err(|e| anyhow!("{file}: {e}"))?;
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_counts_from_one() {
        assert_eq!(line_col("ab\ncd", 0), (1, 1));
        assert_eq!(line_col("ab\ncd", 4), (2, 2));
    }

    #[test]
    fn override_defaults() {
        let m: OverrideToml = toml::from_str("type = \"glossy\"").unwrap();
        let g = override_material(&m, "x").unwrap();
        assert_eq!(g.bsdf, Bsdf::Glossy(Glossy { kd: Color::splat(0.5), ks: Color::ZERO, exponent: 1.0 }));
        assert!(toml::from_str::<OverrideToml>("type = \"glass\"\nshiny = 1").is_err());
        assert!(toml::from_str::<OverrideToml>("type = \"plastic\"").is_err());
    }
}
