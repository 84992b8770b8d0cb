//! The image: linear RGB radiance per pixel, written as OpenEXR (float32, for
//! measurement) and PNG (sRGB transfer, clamped, for looking). Files are written to a
//! temporary name and renamed, so a killed run never leaves a torn image behind.

use crate::math::Color;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// A width × height RGB image, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels.
    pub pixels: Vec<Color>,
}

/// sRGB opto-electronic transfer function for a linear value in [0, 1].
#[inline]
pub fn srgb_encode(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x >= 1.0 {
        1.0
    } else if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// Temporary sibling path used for atomic writes.
pub fn temp_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    name.push(format!(".tmp{}", std::process::id()));
    path.with_file_name(name)
}

/// Writes `bytes` atomically (temporary file + rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create directory", dir.display()))?;
    }
    let tmp = temp_path(path);
    std::fs::write(&tmp, bytes).with_context(|| format!("{}: cannot write", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("{}: cannot rename into place", path.display()))?;
    Ok(())
}

impl Film {
    /// A black image.
    pub fn new(width: u32, height: u32) -> Self {
        Film { width, height, pixels: vec![Color::ZERO; width as usize * height as usize] }
    }

    /// Pixel at (x, y).
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Color {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Mean of all pixels.
    pub fn mean(&self) -> Color {
        let s: glam::DVec3 = self.pixels.iter().map(|c| c.as_dvec3()).sum();
        (s / self.pixels.len().max(1) as f64).as_vec3()
    }

    /// 8-bit sRGB bytes (RGB, row-major).
    pub fn to_srgb8(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.pixels.len() * 3);
        for c in &self.pixels {
            for v in c.to_array() {
                let v = if v.is_nan() { 0.0 } else { v };
                out.push((srgb_encode(v) * 255.0 + 0.5) as u8);
            }
        }
        out
    }

    /// Writes a PNG (sRGB, clamped).
    pub fn write_png(&self, path: &Path) -> Result<()> {
        let buf =
            encode_png_rgb8(self.width, self.height, &self.to_srgb8()).with_context(|| format!("{}: cannot encode PNG", path.display()))?;
        write_atomic(path, &buf)
    }

    /// Writes an OpenEXR file (float32 linear RGB), byte-identical for identical pixels.
    pub fn write_exr(&self, path: &Path) -> Result<()> {
        use exr::prelude::*;
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create directory", dir.display()))?;
        }
        let w = self.width as usize;
        let tmp = temp_path(path);
        // Increasing line order, compressed sequentially: the default (unspecified
        // order, parallel compression) writes tiles in the order threads finish them,
        // so two files of the same image could differ in bytes.
        let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
            let c = self.pixels[y * w + x];
            (c.x, c.y, c.z)
        });
        let encoding = Encoding { line_order: LineOrder::Increasing, ..Encoding::FAST_LOSSLESS };
        Image::from_encoded_channels((w, self.height as usize), encoding, channels)
            .write()
            .non_parallel()
            .to_file(&tmp)
            .with_context(|| format!("{}: cannot write EXR", tmp.display()))?;
        std::fs::rename(&tmp, path).with_context(|| format!("{}: cannot rename into place", path.display()))?;
        Ok(())
    }

    /// Reads an OpenEXR file's RGB channels.
    pub fn read_exr(path: &Path) -> Result<Film> {
        use exr::prelude::*;
        let img = read_first_rgba_layer_from_file(
            path,
            |res, _| Film::new(res.width() as u32, res.height() as u32),
            |f: &mut Film, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let i = pos.y() * f.width as usize + pos.x();
                f.pixels[i] = Color::new(r, g, b);
            },
        )
        .with_context(|| format!("{}: cannot read EXR", path.display()))?;
        Ok(img.layer_data.channel_data.pixels)
    }

    /// Writes `stem.exr` and `stem.png` for an output path given with or without
    /// an extension.
    pub fn write_pair(&self, out: &Path) -> Result<(PathBuf, PathBuf)> {
        let exr = out.with_extension("exr");
        let png = out.with_extension("png");
        self.write_exr(&exr)?;
        self.write_png(&png)?;
        Ok((exr, png))
    }
}

/// PNG bytes of an 8-bit RGB buffer (`width * height * 3` bytes, rows top to bottom),
/// written with the `png` crate: the same input gives the same bytes.
pub fn encode_png_rgb8(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>> {
    anyhow::ensure!(rgb.len() as u64 == width as u64 * height as u64 * 3, "PNG buffer of {} bytes for {width}x{height} RGB", rgb.len());
    let mut buf = Vec::new();
    let mut enc = png::Encoder::new(&mut buf, width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().map_err(|e| anyhow::anyhow!("cannot encode PNG: {e}"))?;
    w.write_image_data(rgb).map_err(|e| anyhow::anyhow!("cannot encode PNG: {e}"))?;
    w.finish().map_err(|e| anyhow::anyhow!("cannot encode PNG: {e}"))?;
    Ok(buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curve() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_encode(0.5) - 0.7354).abs() < 1e-3);
        assert_eq!(srgb_encode(7.0), 1.0);
    }

    #[test]
    fn exr_round_trip() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let mut f = Film::new(3, 2);
        f.pixels[4] = Color::new(1.5, 0.25, 100.0);
        let (exr, png) = f.write_pair(&dir.join("t.exr")).unwrap();
        let g = Film::read_exr(&exr).unwrap();
        assert_eq!(f, g);
        assert!(png.exists());
    }

    /// The chunk offset table of a single-part scan-line or tiled EXR written by
    /// `write_exr`: offsets must increase (chunks in file order = index order).
    fn chunk_offsets(bytes: &[u8], chunks: usize) -> Vec<u64> {
        // Header: magic + version (8 bytes), attributes until an empty name (a 0 byte
        // where a name would start).
        let mut i = 8;
        while bytes[i] != 0 {
            let name_end = i + bytes[i..].iter().position(|&b| b == 0).unwrap();
            let type_end = name_end + 1 + bytes[name_end + 1..].iter().position(|&b| b == 0).unwrap();
            let size = u32::from_le_bytes(bytes[type_end + 1..type_end + 5].try_into().unwrap()) as usize;
            i = type_end + 5 + size;
        }
        i += 1;
        (0..chunks).map(|k| u64::from_le_bytes(bytes[i + 8 * k..i + 8 * k + 8].try_into().unwrap())).collect()
    }

    #[test]
    fn exr_bytes_are_reproducible_and_chunks_in_order() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        // 5 × 4 tiles of 64 px, noisy so compression time varies between tiles.
        let mut f = Film::new(300, 200);
        let mut s = 1u32;
        for p in f.pixels.iter_mut() {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            *p = Color::splat((s >> 8) as f32 / (1u32 << 24) as f32);
        }
        let mut prev: Option<Vec<u8>> = None;
        for k in 0..8 {
            let path = dir.join(format!("t{k}.exr"));
            f.write_exr(&path).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            let offs = chunk_offsets(&bytes, 20);
            assert!(offs.windows(2).all(|w| w[0] < w[1]), "chunks out of order: {offs:?}");
            assert!(*offs.last().unwrap() < bytes.len() as u64);
            if let Some(p) = &prev {
                assert!(p == &bytes, "two writes of one image differ");
            }
            prev = Some(bytes);
        }
        assert_eq!(Film::read_exr(&dir.join("t0.exr")).unwrap(), f);
    }
}
