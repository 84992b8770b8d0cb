//! Mitsuba 3 XML scenes (`--scene FILE.xml`): the subset documented in
//! `docs/scene-formats.md`. Reading is strict: an element, plug-in type or parameter
//! photonlab does not support is an error naming file, line, element and name.
//!
//! Files: [`xml`] (document → typed plug-in tree: defaults, includes, refs,
//! transforms), [`transform`], [`sensor`] (camera, film, sampler), [`shapes`],
//! [`materials`], [`textures`], [`emitters`], [`presets`] (named IORs and conductor
//! presets).

pub mod emitters;
pub mod materials;
pub mod presets;
pub mod sensor;
pub mod shapes;
pub mod textures;
pub mod transform;
pub mod xml;

use super::{Placement, Scene};
use crate::camera::Camera;
use crate::material::Material;
use crate::scene::LightDesc;
use anyhow::{Result, bail};
use glam::Vec3;
use std::collections::HashMap;
use std::path::Path;
use std::rc::Rc;
use xml::{Plugin, SceneXml};

/// A mapped material and its textured slots.
type MappedMaterial = (Material, Vec<(crate::texture::Slot, crate::texture::Texture)>);

/// Loads a Mitsuba 3 XML scene.
pub fn load_mitsuba(path: &Path) -> Result<Scene> {
    let doc = xml::parse_file(path)?;
    build(&doc, path)
}

/// Builds a scene from parsed XML (`path` names the scene).
pub fn build(doc: &SceneXml, path: &Path) -> Result<Scene> {
    let name = path.file_stem().map_or_else(|| "scene".to_string(), |s| s.to_string_lossy().into_owned());
    let mut warnings = Vec::new();
    let mut cache = textures::TextureCache::default();
    let mut camera: Option<(Camera, Option<u32>)> = None;
    let mut shapes: Vec<&Rc<Plugin>> = Vec::new();
    let mut lights = Vec::new();
    let mut env_at: Option<String> = None;
    for item in &doc.items {
        match item.tag.as_str() {
            "sensor" => {
                if camera.is_some() {
                    bail!("{}: {}: only one sensor is supported", item.loc, item.what());
                }
                let s = sensor::sensor(item, &mut warnings)?;
                camera = Some((s.camera, s.spp));
            }
            "integrator" => {
                // Read for reference only: the command line chooses the integrator.
                warnings.push(format!(
                    "{}: <integrator type=\"{}\"> is not used: photonlab's integrator and its settings come from the command line",
                    item.loc, item.ty
                ));
            }
            "shape" => shapes.push(item),
            "emitter" => {
                let l = emitters::emitter(item, &mut cache)?;
                if matches!(l, LightDesc::Constant { .. } | LightDesc::Envmap { .. }) {
                    if let Some(prev) = &env_at {
                        bail!("{}: {}: a scene may have only one environment emitter (the first is at {prev})", item.loc, item.what());
                    }
                    env_at = Some(item.loc.to_string());
                }
                lights.push(l);
            }
            // Declarations used through <ref>; checked where they are used.
            "bsdf" | "texture" => {}
            other => bail!("{}: <{other}> is not supported at the top level", item.loc),
        }
    }
    let Some((camera, spp)) = camera else { bail!("{}: the scene has no <sensor>", path.display()) };
    let mut scene = Scene::new(&name, camera);
    scene.source = Some(path.to_path_buf());
    scene.default_spp = spp;
    scene.lights = lights;
    // Materials are mapped once per <bsdf> element (shared through <ref>).
    let mut mapped: HashMap<*const Plugin, MappedMaterial> = HashMap::new();
    let mut one_sided: Vec<String> = Vec::new();
    for s in shapes {
        let mesh = shapes::shape_mesh(s, &mut warnings)?;
        let emitter = s.child("emitter")?;
        let (mut material, texs) = match s.child("bsdf")? {
            Some(b) => match mapped.get(&Rc::as_ptr(&b)) {
                Some(m) => m.clone(),
                None => {
                    let m = materials::bsdf(&b, &mut cache)?;
                    if m.one_sided && !one_sided.contains(&m.material.name) {
                        one_sided.push(m.material.name.clone());
                    }
                    let v = (m.material, m.textures);
                    mapped.insert(Rc::as_ptr(&b), v.clone());
                    v
                }
            },
            // Mitsuba's default: diffuse, reflectance 0.5 (one-sided); black on an
            // emitter (Mitsuba's `Shape` gives an area light without a BSDF a diffuse
            // BSDF of reflectance 0, so it reflects nothing on either side).
            None if emitter.is_some() => (Material::diffuse("default", Vec3::ZERO), Vec::new()),
            None => {
                let d = "default (diffuse 0.5)".to_string();
                if !one_sided.contains(&d) {
                    one_sided.push(d);
                }
                (Material::diffuse("default", Vec3::splat(0.5)), Vec::new())
            }
        };
        if let Some(e) = emitter {
            material.emission = emitters::area(&e)?;
            material.name = format!("{}+area", material.name);
        }
        s.finish()?;
        if mesh.mesh.faces.is_empty() {
            warnings.push(format!("{}: {} has no faces; skipped", s.loc, s.what()));
            continue;
        }
        let index = scene.materials.len() as u32;
        let before = scene.triangles.len();
        scene
            .add_mesh_uv(&mesh.mesh, mesh.uvs.as_ref(), &Placement::default(), Some(&material))
            .map_err(|e| anyhow::anyhow!("{}: {}: {e}", s.loc, s.what()))?;
        if scene.triangles.len() > before {
            for (slot, t) in texs {
                scene.textures.bind(index, slot, t);
            }
        }
    }
    if !one_sided.is_empty() {
        warnings.push(format!(
            "{}: BSDF(s) {} are one-sided in Mitsuba (black from behind) but reflect on both sides in photonlab; wrap them in \
             <bsdf type=\"twosided\"> to make the two agree",
            path.display(),
            one_sided.join(", ")
        ));
    }
    if scene.dropped_degenerate > 0 {
        warnings.push(format!("{}: {} zero-area triangles dropped", path.display(), scene.dropped_degenerate));
    }
    scene.warnings = warnings;
    Ok(scene)
}

#[cfg(test)]
mod tests;
