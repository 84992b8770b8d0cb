//! Image files for textures and environment maps: PNG, JPEG (8- or 16-bit, sRGB
//! decoded to linear unless `raw`) and OpenEXR (linear), held as linear RGBA f32.

use anyhow::{Result, anyhow, bail};
use std::fmt;
use std::io::Cursor;
use std::path::Path;

/// Largest image accepted (pixels), so a corrupt header cannot ask for terabytes.
pub const MAX_PIXELS: u64 = 1 << 28;

/// A linear RGBA image, row 0 at the top.
#[derive(Clone, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major linear RGBA.
    pub pixels: Vec<[f32; 4]>,
    /// True when the file had an alpha channel.
    pub has_alpha: bool,
    /// Content hash (scene fingerprints).
    pub hash: u64,
}

impl fmt::Debug for Image {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Image({}x{}, alpha {}, hash {:016x})", self.width, self.height, self.has_alpha, self.hash)
    }
}

/// sRGB transfer function, decoding direction.
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

impl Image {
    /// Builds an image from pixels (computes the hash).
    pub fn new(width: u32, height: u32, pixels: Vec<[f32; 4]>, has_alpha: bool) -> Result<Self> {
        if width == 0 || height == 0 || pixels.len() as u64 != width as u64 * height as u64 {
            bail!("image has an empty or inconsistent size {width}x{height}");
        }
        let mut h = crate::math::Fnv::default();
        for p in &pixels {
            for c in p {
                h.write(&c.to_bits().to_le_bytes());
            }
        }
        let hash = h.0;
        Ok(Image { width, height, pixels, has_alpha, hash })
    }

    /// Pixel (x, y), both in range.
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> [f32; 4] {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Reads an image file (kind by extension, case-insensitive).
    pub fn load(path: &Path, raw: bool) -> Result<Image> {
        let bytes = std::fs::read(path).map_err(|e| anyhow!("{}: cannot read image: {e}", path.display()))?;
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
        Self::decode(&bytes, &ext, raw).map_err(|e| anyhow!("{}: {e}", path.display()))
    }

    /// Decodes image bytes of the kind `ext` (`png`, `jpg`/`jpeg`, `exr`).
    pub fn decode(bytes: &[u8], ext: &str, raw: bool) -> Result<Image> {
        match ext {
            "exr" => decode_exr(bytes),
            "png" | "jpg" | "jpeg" => decode_ldr(bytes, ext, raw),
            other => bail!("unsupported image format `.{other}` (png, jpg, jpeg, exr)"),
        }
    }
}

fn decode_ldr(bytes: &[u8], ext: &str, raw: bool) -> Result<Image> {
    let (w, h, px) = if ext == "png" { decode_png(bytes)? } else { decode_jpeg(bytes)? };
    let has_alpha = px.alpha;
    let pixels: Vec<[f32; 4]> = if px.bits == 8 {
        let mut lut = [0.0f32; 256];
        for (i, v) in lut.iter_mut().enumerate() {
            let x = i as f32 / 255.0;
            *v = if raw { x } else { srgb_to_linear(x) };
        }
        px.rgba().map(|[r, g, b, a]| [lut[r], lut[g], lut[b], a as f32 / 255.0]).collect()
    } else {
        let dec = |v: usize| {
            let x = v as f32 / 65535.0;
            if raw { x } else { srgb_to_linear(x) }
        };
        px.rgba().map(|[r, g, b, a]| [dec(r), dec(g), dec(b), a as f32 / 65535.0]).collect()
    };
    Image::new(w, h, pixels, has_alpha)
}

/// Decoded 8- or 16-bit samples, 1–4 channels (grey, grey + alpha, RGB, RGBA).
struct Samples {
    /// One value per channel and pixel (16-bit values already combined).
    values: Vec<u16>,
    channels: usize,
    bits: u8,
    alpha: bool,
}

impl Samples {
    /// Every pixel as RGBA (grey repeated; opaque without alpha).
    fn rgba(&self) -> impl Iterator<Item = [usize; 4]> + '_ {
        let opaque = if self.bits == 8 { 255 } else { 65535 };
        self.values.chunks_exact(self.channels).map(move |p| {
            let (r, g, b, a) = match p.len() {
                1 => (p[0], p[0], p[0], opaque),
                2 => (p[0], p[0], p[0], p[1]),
                3 => (p[0], p[1], p[2], opaque),
                _ => (p[0], p[1], p[2], p[3]),
            };
            [r as usize, g as usize, b as usize, a as usize]
        })
    }
}

fn check_size(w: u64, h: u64) -> Result<()> {
    if w == 0 || h == 0 || w * h > MAX_PIXELS {
        bail!("image is too large or empty ({w}x{h})");
    }
    Ok(())
}

/// PNG with the `png` crate: palettes, low bit depths and tRNS expanded; 16-bit kept.
fn decode_png(bytes: &[u8]) -> Result<(u32, u32, Samples)> {
    let err = |e: png::DecodingError| anyhow!("cannot decode png image: {e}");
    let mut dec = png::Decoder::new_with_limits(Cursor::new(bytes), png::Limits { bytes: 2 << 30 });
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec.read_info().map_err(err)?;
    let (w, h) = (reader.info().width, reader.info().height);
    check_size(w as u64, h as u64)?;
    let size = reader.output_buffer_size().ok_or_else(|| anyhow!("cannot decode png image: too large"))?;
    let mut buf = vec![0u8; size];
    let frame = reader.next_frame(&mut buf).map_err(err)?;
    let channels = frame.color_type.samples();
    let bits = match frame.bit_depth {
        png::BitDepth::Sixteen => 16,
        png::BitDepth::Eight => 8,
        d => bail!("cannot decode png image: unexpected bit depth {d:?} after expansion"),
    };
    let alpha = matches!(frame.color_type, png::ColorType::GrayscaleAlpha | png::ColorType::Rgba);
    let (line, row) = (frame.line_size, w as usize * channels * (bits as usize / 8));
    let mut values = Vec::with_capacity(w as usize * h as usize * channels);
    for y in 0..h as usize {
        let r = &buf[y * line..y * line + row];
        if bits == 8 {
            values.extend(r.iter().map(|&v| v as u16));
        } else {
            values.extend(r.chunks_exact(2).map(|c| u16::from_be_bytes([c[0], c[1]])));
        }
    }
    Ok((w, h, Samples { values, channels, bits, alpha }))
}

/// Baseline and progressive JPEG with `zune-jpeg`, decoded to 8-bit RGB.
fn decode_jpeg(bytes: &[u8]) -> Result<(u32, u32, Samples)> {
    use zune_core::bytestream::ZCursor;
    use zune_core::colorspace::ColorSpace;
    use zune_core::options::DecoderOptions;
    let options = DecoderOptions::default().jpeg_set_out_colorspace(ColorSpace::RGB).set_max_width(1 << 16).set_max_height(1 << 16);
    let mut dec = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    let data = dec.decode().map_err(|e| anyhow!("cannot decode jpg image: {e:?}"))?;
    let info = dec.info().ok_or_else(|| anyhow!("cannot decode jpg image: no header"))?;
    let (w, h) = (info.width as u32, info.height as u32);
    check_size(w as u64, h as u64)?;
    if data.len() != w as usize * h as usize * 3 {
        bail!("cannot decode jpg image: {} bytes for {w}x{h} RGB", data.len());
    }
    Ok((w, h, Samples { values: data.into_iter().map(u16::from).collect(), channels: 3, bits: 8, alpha: false }))
}

fn decode_exr(bytes: &[u8]) -> Result<Image> {
    use exr::prelude::*;
    struct Buf {
        w: usize,
        px: Vec<[f32; 4]>,
    }
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |res, _| {
                let n = res.width() as u64 * res.height() as u64;
                let n = if n > MAX_PIXELS { 0 } else { n as usize };
                Buf { w: res.width(), px: vec![[0.0; 4]; n] }
            },
            |b: &mut Buf, pos, (r, g, bl, a): (f32, f32, f32, f32)| {
                if let Some(p) = b.px.get_mut(pos.y() * b.w + pos.x()) {
                    *p = [r, g, bl, a];
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| anyhow!("cannot read EXR: {e}"))?;
    let size = img.layer_data.size;
    if size.width() as u64 * size.height() as u64 > MAX_PIXELS {
        bail!("EXR image is too large ({}x{})", size.width(), size.height());
    }
    let has_alpha = img.layer_data.channel_data.channels.3.is_some();
    let mut px = img.layer_data.channel_data.pixels.px;
    for p in px.iter_mut() {
        for c in p.iter_mut() {
            if !c.is_finite() {
                *c = 0.0;
            }
        }
    }
    crate::texture::Image::new(size.width() as u32, size.height() as u32, px, has_alpha)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// PNG kinds the `png` crate hands back differently (16-bit, grey + alpha, a
    /// palette with transparency, 1-bit grey) decode to the same raw RGBA as the
    /// `image` crate reads them.
    #[test]
    fn png_kinds_decode_as_the_image_crate_reads_them() {
        fn encode(w: u32, h: u32, color: png::ColorType, depth: png::BitDepth, data: &[u8], palette: Option<(&[u8], &[u8])>) -> Vec<u8> {
            let mut buf = Vec::new();
            let mut e = png::Encoder::new(&mut buf, w, h);
            e.set_color(color);
            e.set_depth(depth);
            if let Some((plte, trns)) = palette {
                e.set_palette(plte.to_vec());
                e.set_trns(trns.to_vec());
            }
            let mut wr = e.write_header().unwrap();
            wr.write_image_data(data).unwrap();
            wr.finish().unwrap();
            buf
        }
        let rgb16: Vec<u8> = [0u16, 65535, 32768, 1, 300, 65000].iter().flat_map(|v| v.to_be_bytes()).collect();
        let cases = [
            encode(2, 1, png::ColorType::Rgb, png::BitDepth::Sixteen, &rgb16, None),
            encode(2, 1, png::ColorType::GrayscaleAlpha, png::BitDepth::Eight, &[10, 255, 200, 7], None),
            encode(3, 1, png::ColorType::Indexed, png::BitDepth::Eight, &[0, 1, 1], Some((&[255, 0, 0, 0, 0, 255], &[128]))),
            encode(8, 1, png::ColorType::Grayscale, png::BitDepth::One, &[0b1010_0000], None),
        ];
        for (n, bytes) in cases.iter().enumerate() {
            let ours = Image::decode(bytes, "png", true).unwrap();
            let theirs = image::load_from_memory(bytes).unwrap().to_rgba16();
            assert_eq!((ours.width, ours.height), theirs.dimensions(), "case {n}");
            for (x, y, p) in theirs.enumerate_pixels() {
                let want = p.0.map(|v| v as f32 / 65535.0);
                let got = ours.texel(x, y);
                for c in 0..4 {
                    assert!((got[c] - want[c]).abs() < 1e-6, "case {n} pixel ({x}, {y}) channel {c}: {got:?} vs {want:?}");
                }
            }
        }
    }

    #[test]
    fn png_is_srgb_decoded_unless_raw() {
        let mut buf = Vec::new();
        let img = image::RgbImage::from_pixel(2, 1, image::Rgb([128, 255, 0]));
        img.write_to(&mut Cursor::new(&mut buf), image::ImageFormat::Png).unwrap();
        let a = Image::decode(&buf, "png", false).unwrap();
        // sRGB 128/255 = 0.2158605 linear.
        assert!((a.texel(0, 0)[0] - 0.215_860_5).abs() < 1e-5, "{:?}", a.texel(0, 0));
        assert_eq!(a.texel(1, 0)[1], 1.0);
        assert!(!a.has_alpha);
        let r = Image::decode(&buf, "png", true).unwrap();
        assert!((r.texel(0, 0)[0] - 128.0 / 255.0).abs() < 1e-6);
        assert!(Image::decode(b"not an image", "png", false).is_err());
        assert!(Image::decode(b"x", "gif", false).is_err());
    }

    /// A flat JPEG is sRGB-decoded like a PNG (within the codec's rounding of a flat
    /// colour, ±1 of 255); `raw` keeps the stored values.
    #[test]
    fn jpeg_is_srgb_decoded_unless_raw() {
        let mut buf = Vec::new();
        let img = image::RgbImage::from_pixel(16, 8, image::Rgb([128, 128, 128]));
        img.write_to(&mut Cursor::new(&mut buf), image::ImageFormat::Jpeg).unwrap();
        let a = Image::decode(&buf, "jpg", false).unwrap();
        assert_eq!((a.width, a.height, a.has_alpha), (16, 8, false));
        let (lo, hi) = (srgb_to_linear(127.0 / 255.0), srgb_to_linear(129.0 / 255.0));
        assert!(a.pixels.iter().all(|p| (lo..=hi).contains(&p[0]) && (lo..=hi).contains(&p[2])), "{:?}", a.texel(3, 3));
        let r = Image::decode(&buf, "jpg", true).unwrap();
        assert!((r.texel(3, 3)[1] - 128.0 / 255.0).abs() <= 1.0 / 255.0 + 1e-6, "{:?}", r.texel(3, 3));
    }

    /// EXR values are linear (never sRGB-decoded), HDR values kept, row 0 at the top.
    #[test]
    fn exr_is_linear_and_keeps_hdr_values() {
        let path = std::env::temp_dir().join(format!("photonlab-image-test-{}.exr", std::process::id()));
        exr::prelude::write_rgb_file(&path, 2, 2, |x, y| if y == 0 { (0.5f32, 4.0f32, 0.0f32) } else { (x as f32, 0.25, 1.0) }).unwrap();
        let buf = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).ok();
        let a = Image::decode(&buf, "exr", false).unwrap();
        assert_eq!(a.texel(0, 0)[..3], [0.5, 4.0, 0.0]);
        assert_eq!(a.texel(1, 1)[..3], [1.0, 0.25, 1.0]);
        assert_eq!(Image::decode(&buf, "exr", true).unwrap().texel(0, 0), a.texel(0, 0));
    }
}
