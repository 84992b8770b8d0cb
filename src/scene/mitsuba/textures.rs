//! Mitsuba `<texture>` plug-ins: `bitmap` and `checkerboard`. Images are read once
//! per file (and `raw` flag) and shared.

use super::xml::{Plugin, SpectrumValue};
use crate::texture::{Bitmap, Checkerboard, Filter, Image, Texture, Wrap};
use anyhow::{Result, anyhow};
use glam::{Mat3, Mat4, Vec3};
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

/// Images already read.
#[derive(Default)]
pub struct TextureCache {
    images: HashMap<(PathBuf, bool), Arc<Image>>,
}

impl TextureCache {
    /// An image file, read once.
    pub fn image(&mut self, path: PathBuf, raw: bool) -> Result<Arc<Image>> {
        if let Some(i) = self.images.get(&(path.clone(), raw)) {
            return Ok(i.clone());
        }
        let img = Arc::new(Image::load(&path, raw)?);
        self.images.insert((path, raw), img.clone());
        Ok(img)
    }
}

/// Mitsuba's `to_uv`: the 2-D affine part of a 4×4 (rows x, y; columns x, y, w).
pub fn uv_matrix(m: &Mat4) -> Mat3 {
    let c = m.to_cols_array_2d();
    Mat3::from_cols(Vec3::new(c[0][0], c[0][1], 0.0), Vec3::new(c[1][0], c[1][1], 0.0), Vec3::new(c[3][0], c[3][1], 1.0))
}

/// Builds a `<texture>` (and checks its parameters).
pub fn texture(p: &Plugin, cache: &mut TextureCache) -> Result<Texture> {
    let to_uv = uv_matrix(&p.transform("to_uv")?.unwrap_or(Mat4::IDENTITY));
    let t = match p.ty.as_str() {
        "bitmap" => {
            let (name, loc) = p.string("filename")?.ok_or_else(|| p.err("needs a `filename`"))?;
            let raw = p.bool_or("raw", false)?;
            let filter = match p.string("filter_type")?.map(|s| s.0).as_deref() {
                None | Some("bilinear") => Filter::Bilinear,
                Some("nearest") => Filter::Nearest,
                Some(o) => return Err(p.err(format!("filter_type must be `bilinear` or `nearest`, got `{o}`"))),
            };
            let wrap = match p.string("wrap_mode")?.map(|s| s.0).as_deref() {
                None | Some("repeat") => Wrap::Repeat,
                Some("mirror") => Wrap::Mirror,
                Some("clamp") => Wrap::Clamp,
                Some(o) => return Err(p.err(format!("wrap_mode must be `repeat`, `mirror` or `clamp`, got `{o}`"))),
            };
            let image = cache.image(loc.resolve(&name), raw).map_err(|e| anyhow!("{loc}: {e}"))?;
            Texture::Bitmap(Bitmap { image, filter, wrap, to_uv })
        }
        "checkerboard" => {
            let c = |name: &str, d: f32| -> Result<Vec3> {
                match p.spectrum(name)? {
                    None => Ok(Vec3::splat(d)),
                    Some(SpectrumValue::Rgb(c)) => Ok(c),
                    Some(SpectrumValue::Texture(t)) => Err(t.err("nested textures are not supported")),
                }
            };
            Texture::Checkerboard(Checkerboard { color0: c("color0", 0.4)?, color1: c("color1", 0.2)?, to_uv })
        }
        other => return Err(p.err(format!("texture type `{other}` is not supported (bitmap, checkerboard)"))),
    };
    p.finish()?;
    Ok(t)
}
