//! Mitsuba's `checkerboard`: `color0` where the fractional parts of u and v are both
//! below or both above one half, `color1` elsewhere.

use crate::math::Color;
use glam::{Mat3, Vec2};

/// Checkerboard texture.
#[derive(Clone, Debug, PartialEq)]
pub struct Checkerboard {
    /// Colour of the (0,0) square (Mitsuba's default 0.4).
    pub color0: Color,
    /// The other colour (default 0.2).
    pub color1: Color,
    /// `to_uv`.
    pub to_uv: Mat3,
}

impl Checkerboard {
    /// Value at `uv`.
    #[inline]
    pub fn eval(&self, uv: Vec2) -> Color {
        let uv = super::apply_uv(&self.to_uv, uv);
        let f = uv - uv.floor();
        if (f.x > 0.5) == (f.y > 0.5) { self.color0 } else { self.color1 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn squares() {
        let c = Checkerboard { color0: Color::ONE, color1: Color::ZERO, to_uv: Mat3::IDENTITY };
        assert_eq!(c.eval(Vec2::new(0.25, 0.25)), Color::ONE);
        assert_eq!(c.eval(Vec2::new(0.75, 0.25)), Color::ZERO);
        assert_eq!(c.eval(Vec2::new(0.75, 0.75)), Color::ONE);
        assert_eq!(c.eval(Vec2::new(-0.25, 0.25)), Color::ZERO);
        let s = Checkerboard { to_uv: Mat3::from_scale(Vec2::splat(2.0)), ..c };
        assert_eq!(s.eval(Vec2::new(0.3, 0.1)), Color::ZERO);
    }
}
