//! Mitsuba 3's `twosided`: a one-sided BSDF made visible from both sides. Seen from
//! the front (geometric normal side) the `front` BSDF applies; from the back, `back`
//! (the same one unless two are given) with the surface turned over (both normals
//! negated). Light never crosses: front and back only reflect.

use super::{Bsdf, ShadingPoint};
use crate::math::Frame;
use glam::Vec3;

/// Two-sided adapter.
#[derive(Clone, Debug, PartialEq)]
pub struct TwoSided {
    /// BSDF of the front side.
    pub front: Box<Bsdf>,
    /// BSDF of the back side.
    pub back: Box<Bsdf>,
}

impl TwoSided {
    /// The same BSDF on both sides.
    pub fn new(b: Bsdf) -> Self {
        TwoSided { front: Box::new(b.clone()), back: Box::new(b) }
    }

    /// The side `wo` sees and the shading point as that side's BSDF sees it.
    #[inline]
    pub(super) fn side(&self, sp: &ShadingPoint, wo: Vec3) -> (&Bsdf, ShadingPoint) {
        if wo.dot(sp.ng) >= 0.0 { (&self.front, *sp) } else { (&self.back, ShadingPoint { frame: Frame::new(-sp.ns()), ng: -sp.ng }) }
    }

    /// Whether `wi` lies on `wo`'s side (no transmission through a two-sided sheet).
    #[inline]
    pub(super) fn same_side(sp: &ShadingPoint, wo: Vec3, wi: Vec3) -> bool {
        wo.dot(sp.ng) * wi.dot(sp.ng) > 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{check_sampling, sampled_albedo};
    use super::super::*;

    #[test]
    fn back_side_mirrors_front() {
        let rc = Bsdf::RoughConductor(RoughConductor {
            distribution: MicrofacetType::Ggx,
            alpha: 0.3,
            eta: Color::new(0.2, 0.9, 1.1),
            k: Color::new(3.9, 2.4, 1.9),
            specular_reflectance: Color::ONE,
        });
        let b = Bsdf::TwoSided(TwoSided::new(rc.clone()));
        let sp = ShadingPoint::new(Vec3::Z, Vec3::new(0.1, 0.0, 1.0).normalize());
        let spf = ShadingPoint::new(-Vec3::Z, -Vec3::new(0.1, 0.0, 1.0).normalize());
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let wi = Vec3::new(-0.5, 0.2, 0.7).normalize();
        assert_eq!(b.eval(&sp, wo, wi), rc.eval(&sp, wo, wi));
        let back = b.eval(&sp, -wo, -wi);
        assert!(back.max_element() > 0.0);
        assert!((back - rc.eval(&spf, -wo, -wi)).abs().max_element() < 1e-6);
        assert_eq!(b.eval(&sp, wo, -wi), Color::ZERO);
        let a1 = sampled_albedo(&b, &sp, wo, 64);
        let a2 = sampled_albedo(&b, &spf, wo, 64);
        assert!((a1 - sampled_albedo(&rc, &sp, wo, 64)).abs().max_element() < 1e-6);
        assert!((a2 - sampled_albedo(&rc, &sp, wo, 64)).abs().max_element() < 2e-2, "{a1} {a2}");
        check_sampling(&b, &sp, 3000);
        let p = Bsdf::TwoSided(TwoSided::new(Bsdf::Plastic(Plastic::new(Color::splat(0.5), Color::ONE, 1.5, 1.0, false))));
        check_sampling(&p, &sp, 3000);
        let (br, n) = p.specular_branches(&sp, -wo, TransportMode::Radiance);
        assert!(n == 1 && br[0].0.z < 0.0 && br[0].1.x > 0.0);
    }
}
