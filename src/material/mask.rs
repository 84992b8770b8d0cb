//! Mitsuba 3's `mask`: an opacity cut-out. With probability 1 − opacity light passes
//! straight through (a delta "null" lobe, wi = −wo, weight 1); otherwise the nested
//! BSDF scatters, so f = opacity·f_nested off the null lobe.
//!
//! Every integrator treats the null lobe as a delta lobe: shadow rays stop at masked
//! surfaces (as Mitsuba 3's `path`, whose shadow rays do not pass through `mask`), so
//! light through a cut-out reaches the shading point along BSDF-sampled (camera) or
//! specular (photon) chains: `path` counts emitters reached through the null lobe
//! fully, photons that passed a cut-out are caustic photons, and `sppm` and `photon`
//! follow the null lobe like a mirror's.

use super::{Bsdf, ShadingPoint};
use glam::Vec3;

/// Opacity cut-out.
#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    /// Opacity in [0, 1] (Mitsuba default 0.5); textured by `set_color_param`.
    pub opacity: f32,
    /// The BSDF of the opaque part.
    pub nested: Box<Bsdf>,
}

impl Mask {
    /// Probability of the null lobe.
    #[inline]
    pub fn null_prob(&self) -> f32 {
        (1.0 - self.opacity).clamp(0.0, 1.0)
    }

    /// The null lobe's direction for `wo` (never degenerate).
    #[inline]
    pub(super) fn pass(_sp: &ShadingPoint, wo: Vec3) -> Vec3 {
        -wo
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{check_sampling, sampled_albedo};
    use super::super::*;

    #[test]
    fn null_lobe_and_scaled_nested() {
        let lam = Bsdf::Lambertian(Lambertian { albedo: Color::splat(0.8) });
        let m = Bsdf::Mask(Mask { opacity: 0.25, nested: Box::new(lam.clone()) });
        let sp = ShadingPoint::new(Vec3::Z, Vec3::Z);
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let wi = Vec3::new(-0.5, 0.2, 0.7).normalize();
        assert!((m.eval(&sp, wo, wi) - lam.eval(&sp, wo, wi) * 0.25).abs().max_element() < 1e-7);
        assert!((m.pdf(&sp, wo, wi) - lam.pdf(&sp, wo, wi) * 0.25).abs() < 1e-7);
        let s = m.sample(&sp, wo, 0.5, [0.3, 0.3], TransportMode::Radiance).unwrap();
        assert!(s.delta && s.wi == -wo && s.weight == Color::ONE && (s.pdf - 0.75).abs() < 1e-6);
        // Passed-through share + reflected share: 0.75 + 0.25·0.8.
        let a = sampled_albedo(&m, &sp, wo, 100);
        assert!((a.x - (0.75 + 0.25 * 0.8)).abs() < 2e-3, "{a}");
        let (br, n) = m.specular_branches(&sp, wo, TransportMode::Radiance);
        assert!(n == 1 && br[0].0 == -wo && (br[0].1.x - 0.75).abs() < 1e-6);
        assert!(m.has_delta() && !m.is_delta());
        assert!((m.diffuse_albedo().x - 0.2).abs() < 1e-6);
        check_sampling(&m, &sp, 2000);
        let mut t = m.clone();
        assert!(t.set_color_param("opacity", Color::splat(0.6)));
        assert!(matches!(t, Bsdf::Mask(ref k) if (k.opacity - 0.6).abs() < 1e-6));
        assert!(t.set_color_param("reflectance", Color::splat(0.1)));
        assert!(!t.set_color_param("nonsense", Color::ONE));
    }
}
