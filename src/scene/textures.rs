//! Texture maps of OBJ/MTL materials (`map_Kd`, `map_d`) for the TOML scene path.
//!
//! File names are resolved relative to the MTL file; when the exact name does not
//! exist, a file in the same folder whose name differs only in letter case is used,
//! with a warning (MTL files written on case-insensitive systems, e.g. Sponza's).
//! `map_Kd` becomes a bilinear, repeating `bitmap` on the diffuse reflectance (sRGB
//! decoded); `map_d` needs the `mask` BSDF, which this build does not have: it is
//! reported and not applied.

use super::Scene;
use super::obj::MtlMaps;
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
    let mut cache: HashMap<PathBuf, Arc<Image>> = HashMap::new();
    for (k, m) in maps.iter().enumerate() {
        let material = mat_base + k as u32;
        if let Some(d) = &m.d {
            scene.warnings.push(format!(
                "{at}: map_d {} of material `{}` is not applied (opacity needs the mask BSDF)",
                d.display(),
                scene.materials.get(material as usize).map_or("?", |m| m.name.as_str())
            ));
        }
        let Some(kd) = &m.kd else { continue };
        let Some((path, changed)) = resolve_case_insensitive(kd) else {
            scene.warnings.push(format!("{at}: map_Kd: texture {} not found; the material keeps its Kd", kd.display()));
            continue;
        };
        if changed {
            scene.warnings.push(format!("{at}: map_Kd {} resolved as {} (letter case differs)", kd.display(), path.display()));
        }
        let image = match cache.get(&path) {
            Some(i) => i.clone(),
            None => {
                let i = Arc::new(Image::load(&path, false).map_err(|e| anyhow!("{at}: map_Kd: {e}"))?);
                cache.insert(path.clone(), i.clone());
                i
            }
        };
        let t = Texture::Bitmap(Bitmap { image, filter: Filter::Bilinear, wrap: Wrap::Repeat, to_uv: Mat3::IDENTITY });
        scene.textures.bind(material, Slot::DiffuseReflectance, t);
    }
    Ok(())
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
