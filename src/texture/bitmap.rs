//! Mitsuba's `bitmap` texture: lookups at `uv·res − ½` with bilinear (or nearest)
//! filtering and Mitsuba's wrap modes applied to texel indices.

use super::Image;
use glam::{Mat3, Vec2, Vec4};
use std::sync::Arc;

/// Filter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    /// Bilinear interpolation of the four nearest texels.
    Bilinear,
    /// The nearest texel.
    Nearest,
}

/// Wrap mode outside [0, 1].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    /// Periodic.
    Repeat,
    /// Periodic with every other copy mirrored.
    Mirror,
    /// Edge texels extend.
    Clamp,
}

/// Image texture.
#[derive(Clone, Debug, PartialEq)]
pub struct Bitmap {
    /// The image (shared between materials using the same file).
    pub image: Arc<Image>,
    /// Filter.
    pub filter: Filter,
    /// Wrap mode (both axes).
    pub wrap: Wrap,
    /// `to_uv`.
    pub to_uv: Mat3,
}

#[inline]
fn wrap(i: i64, n: u32, mode: Wrap) -> u32 {
    let n = n as i64;
    let j = match mode {
        Wrap::Clamp => i.clamp(0, n - 1),
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::Mirror => {
            let m = i.rem_euclid(2 * n);
            if m < n { m } else { 2 * n - 1 - m }
        }
    };
    j as u32
}

impl Bitmap {
    /// RGBA at `uv`.
    #[inline]
    pub fn eval(&self, uv: Vec2) -> Vec4 {
        let uv = super::apply_uv(&self.to_uv, uv);
        let img = &*self.image;
        let (w, h) = (img.width, img.height);
        // Large or non-finite coordinates: fold into one period first (exact for
        // repeat and mirror, irrelevant for clamp's far outside).
        let fold = |x: f32| if x.is_finite() { if x.abs() > 1e6 { x.rem_euclid(2.0) } else { x } } else { 0.0 };
        let (x, y) = (fold(uv.x) * w as f32 - 0.5, fold(uv.y) * h as f32 - 0.5);
        let t = |i: i64, j: i64| Vec4::from_array(img.texel(wrap(i, w, self.wrap), wrap(j, h, self.wrap)));
        match self.filter {
            Filter::Nearest => t((x + 0.5).floor() as i64, (y + 0.5).floor() as i64),
            Filter::Bilinear => {
                let (fx, fy) = (x.floor(), y.floor());
                let (i, j) = (fx as i64, fy as i64);
                let (ax, ay) = (x - fx, y - fy);
                let top = t(i, j) * (1.0 - ax) + t(i + 1, j) * ax;
                let bottom = t(i, j + 1) * (1.0 - ax) + t(i + 1, j + 1) * ax;
                top * (1.0 - ay) + bottom * ay
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> Bitmap {
        // 2x1 image: black, white.
        let img = Image::new(2, 1, vec![[0.0, 0.0, 0.0, 1.0], [1.0, 1.0, 1.0, 1.0]], false).unwrap();
        Bitmap { image: Arc::new(img), filter: Filter::Bilinear, wrap: Wrap::Clamp, to_uv: Mat3::IDENTITY }
    }

    #[test]
    fn bilinear_between_texel_centres() {
        let b = ramp();
        assert_eq!(b.eval(Vec2::new(0.25, 0.5)).x, 0.0);
        assert_eq!(b.eval(Vec2::new(0.75, 0.5)).x, 1.0);
        assert!((b.eval(Vec2::new(0.5, 0.5)).x - 0.5).abs() < 1e-6);
        // Clamp holds the edge, repeat blends with the opposite edge.
        assert_eq!(b.eval(Vec2::new(0.0, 0.5)).x, 0.0);
        let r = Bitmap { wrap: Wrap::Repeat, ..ramp() };
        assert!((r.eval(Vec2::new(0.0, 0.5)).x - 0.5).abs() < 1e-6);
        assert!((r.eval(Vec2::new(1.25, 0.5)).x - 0.0).abs() < 1e-6);
        let m = Bitmap { wrap: Wrap::Mirror, ..ramp() };
        assert!((m.eval(Vec2::new(1.25, 0.5)).x - 1.0).abs() < 1e-6);
        let n = Bitmap { filter: Filter::Nearest, ..ramp() };
        assert_eq!(n.eval(Vec2::new(0.45, 0.5)).x, 0.0);
        assert_eq!(n.eval(Vec2::new(0.55, 0.5)).x, 1.0);
        assert!(b.eval(Vec2::new(f32::NAN, 1e30)).is_finite());
    }
}
