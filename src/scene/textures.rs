//! Texture maps of OBJ/MTL materials (`map_Kd`, `map_d`) for the TOML scene path.
//!
//! File names are resolved relative to the MTL file; when the exact name does not
//! exist, a file in the same folder whose name differs only in letter case is used,
//! with a warning (MTL files written on case-insensitive systems, e.g. Sponza's).
//! `map_Kd` becomes a bilinear, repeating `bitmap` on the diffuse reflectance (sRGB
//! decoded); `map_d` wraps the material in a `mask` BSDF whose opacity is the image's
//! alpha channel where it has one, else its mean (linear, not sRGB decoded), as
//! pbrt-v4's and Mitsuba's OBJ importers do.

use super::Scene;
use super::obj::MtlMaps;
use crate::material::{Bsdf, Mask};
use crate::texture::{Bitmap, Filter, Image, Slot, Texture, Wrap};
use anyhow::{Result, anyhow};
use glam::Mat3;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// `path` itself, or a file in its folder whose name matches it ignoring case
/// (second value true then).
pub fn resolve_case_insensitive(path: &Path) -> Option<(PathBuf, bool)> {
    if path.is_file() {
        return Some((path.to_path_buf(), false));
    }
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let want = path.file_name()?.to_string_lossy().to_lowercase();
    let mut hits: Vec<PathBuf> = std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().to_lowercase() == want)
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .collect();
    hits.sort();
    hits.into_iter().next().map(|p| (p, true))
}

/// Binds the texture maps of the materials `mat_base + k` (one [`MtlMaps`] per slot).
pub fn bind_mtl_maps(scene: &mut Scene, mat_base: u32, maps: &[MtlMaps], at: &str) -> Result<()> {
    let mut cache: HashMap<(PathBuf, bool), Arc<Image>> = HashMap::new();
    for (k, m) in maps.iter().enumerate() {
        let material = mat_base + k as u32;
        let name = scene.materials.get(material as usize).map_or("?", |m| m.name.as_str()).to_string();
        if let Some(d) = &m.d
            && let Some(t) = bitmap(scene, &mut cache, d, true, "map_d", &name, at)?
        {
            let mat = &mut scene.materials[material as usize];
            let nested = std::mem::replace(&mut mat.bsdf, Bsdf::Lambertian(crate::material::Lambertian { albedo: Default::default() }));
            mat.bsdf = Bsdf::Mask(Mask { opacity: 1.0, nested: Box::new(nested) });
            scene.textures.bind(material, Slot::Opacity { alpha: true }, t);
        }
        if let Some(kd) = &m.kd
            && let Some(t) = bitmap(scene, &mut cache, kd, false, "map_Kd", &name, at)?
        {
            scene.textures.bind(material, Slot::DiffuseReflectance, t);
        }
    }
    Ok(())
}

/// A bilinear, repeating bitmap from a map's file (`raw`: linear values, else sRGB
/// decoded); `None` with a warning when the file does not exist.
fn bitmap(
    scene: &mut Scene,
    cache: &mut HashMap<(PathBuf, bool), Arc<Image>>,
    file: &Path,
    raw: bool,
    kw: &str,
    material: &str,
    at: &str,
) -> Result<Option<Texture>> {
    let Some((path, changed)) = resolve_case_insensitive(file) else {
        let keeps = if kw == "map_d" { "stays opaque" } else { "keeps its Kd" };
        scene.warnings.push(format!("{at}: {kw}: texture {} not found; material `{material}` {keeps}", file.display()));
        return Ok(None);
    };
    if changed {
        scene.warnings.push(format!("{at}: {kw} {} resolved as {} (letter case differs)", file.display(), path.display()));
    }
    let key = (path.clone(), raw);
    let image = match cache.get(&key) {
        Some(i) => i.clone(),
        None => {
            let i = Arc::new(Image::load(&path, raw).map_err(|e| anyhow!("{at}: {kw}: {e}"))?);
            cache.insert(key, i.clone());
            i
        }
    };
    Ok(Some(Texture::Bitmap(Bitmap { image, filter: Filter::Bilinear, wrap: Wrap::Repeat, to_uv: Mat3::IDENTITY })))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn case_insensitive_lookup() {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(d.path().join("Wall.JPG"), b"x").unwrap();
        let (p, changed) = resolve_case_insensitive(&d.path().join("wall.jpg")).unwrap();
        assert!(changed && p.ends_with("Wall.JPG"));
        assert!(!resolve_case_insensitive(&d.path().join("Wall.JPG")).unwrap().1);
        assert!(resolve_case_insensitive(&d.path().join("none.jpg")).is_none());
    }
}
