//! Mitsuba's `checkerboard`: `color0` where the fractional parts of u and v are both
//! below or both above one half, `color1` elsewhere. Its scalar value (a mask's
//! opacity) has the opposite phase, as Mitsuba 3's `eval_1` does (`neq` where `eval`
//! tests `eq`), so that a scene's cut-outs fall where Mitsuba's do.

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

    /// Scalar value at `uv` (the mean of the colour), in Mitsuba 3's phase: `color0`
    /// where [`Checkerboard::eval`] gives `color1`.
    #[inline]
    pub fn eval_1(&self, uv: Vec2) -> f32 {
        let uv = super::apply_uv(&self.to_uv, uv);
        let f = uv - uv.floor();
        crate::math::mean(if (f.x > 0.5) != (f.y > 0.5) { self.color0 } else { self.color1 })
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
        // The scalar value has Mitsuba's opposite phase (checked against Mitsuba 3.9.1
        // with a mask over a constant environment).
        assert_eq!(c.eval_1(Vec2::new(0.25, 0.25)), 0.0);
        assert_eq!(c.eval_1(Vec2::new(0.75, 0.25)), 1.0);
    }
}
