//! Per-ray values every node test reuses, and the widening constants of the
//! conservative box tests.

use crate::geometry::Ray;
use glam::Vec3A;

/// Units in the last place added to the exit distance of the integer-compare node
/// test (`x86::node_test8`), as one integer addition: a relative widening of at
/// least 8·ε/2 (see [`RayPre::fast_planes`]).
pub(super) const FAR_ULPS: i32 = 8;
/// Far-distance widening of the robust slab test: 1 + 2γ₃ with γₙ = nε/(1 − nε).
pub(super) const ROBUST: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Whether the traversal may run on `ray`: finite origin and direction, and a
/// direction that is not zero. On any other ray every axis of a node test can give
/// NaN, which enters even the empty child slots; such a ray hits nothing (the
/// triangle test's determinant is 0 or NaN), so it is answered without traversal.
#[inline(always)]
pub(super) fn traceable(ray: &Ray) -> bool {
    let (o, d) = (Vec3A::from(ray.o), Vec3A::from(ray.d));
    (o.is_finite_mask() & d.is_finite_mask()).all() && d.cmpne(Vec3A::ZERO).any()
}

/// The byte offsets of a node's near (x, y, z) then far (x, y, z) plane arrays for
/// each of the 8 direction octants (bit a set: the direction is negative on axis a),
/// for N-wide nodes of E-byte coordinates: [`RayPre::planes`] (float nodes, E = 4)
/// and [`RayPre::qplanes`] (quantised nodes, E = 1).
struct Planes<const N: usize, const E: usize>;

impl<const N: usize, const E: usize> Planes<N, E> {
    /// Nodes hold lo[3][N] then hi[3][N] (repr(C)): per axis, the near plane is the
    /// maximum where the direction is negative, the far plane the other one.
    const BY_OCTANT: [[usize; 6]; 8] = {
        let mut t = [[0usize; 6]; 8];
        let mut oct = 0;
        while oct < 8 {
            let mut a = 0;
            while a < 3 {
                let hi = oct >> a & 1;
                t[oct][a] = (a + 3 * hi) * N * E;
                t[oct][3 + a] = (a + 3 * (1 - hi)) * N * E;
                a += 1;
            }
            oct += 1;
        }
        t
    };
}

/// Per-ray values every node test reuses.
pub(super) struct RayPre {
    pub(super) o: Vec3A,
    pub(super) inv: Vec3A,
    /// The direction octant: bit a set where the direction is negative on axis a
    /// (there the near plane is the box maximum).
    pub(super) octant: usize,
    /// Byte offsets in a node of the near (x, y, z) then far (x, y, z) plane arrays,
    /// chosen once per ray so the node test does no per-node selection.
    pub(super) planes: [usize; 6],
    /// The same for quantised nodes (byte arrays qlo[3][N] then qhi[3][N]; set
    /// only for them).
    pub(super) qplanes: [usize; 6],
    /// o·inv per axis, for the fused-multiply-subtract form of the AVX2 node test.
    pub(super) oi: Vec3A,
    /// Absolute error bound of that form's distances: rounding o·inv loses up to
    /// ulp(|o·inv|), which can exceed the relative slack of [`ROBUST`] for boxes close
    /// to an origin far from the world origin; 0 where o·inv is not finite (those
    /// lanes become NaN and are ignored, which only ever keeps a box).
    pub(super) slack: f32,
    /// Near-plane distance t = plane·`c` − `near_b` and far-plane distance
    /// plane·`c` − `far_b` per axis, for the integer-compare node test (see
    /// [`RayPre::fast_planes`]); set only for float nodes.
    pub(super) c: Vec3A,
    pub(super) near_b: Vec3A,
    pub(super) far_b: Vec3A,
}

impl RayPre {
    #[inline(always)]
    pub(super) fn new<const N: usize>(ray: &Ray) -> Self {
        // The three axes at once in one SSE register (glam's `Vec3A`), without
        // branches: the same IEEE operations as one axis at a time, so the same bits
        // (unit test), in fewer instructions (cachegrind: docs/benchmarks.md).
        let (o, d) = (Vec3A::from(ray.o), Vec3A::from(ray.d));
        let inv = d.recip();
        let oi = o * inv;
        let aoi = oi.abs();
        let big = Vec3A::select(aoi.cmplt(Vec3A::INFINITY), aoi, Vec3A::ZERO).max_element();
        let octant = inv.cmplt(Vec3A::ZERO).bitmask() as usize & 7;
        let z = Vec3A::ZERO;
        RayPre {
            o,
            inv,
            octant,
            planes: Planes::<N, 4>::BY_OCTANT[octant],
            qplanes: [0; 6],
            oi,
            slack: 4.0 * f32::EPSILON * big,
            c: z,
            near_b: z,
            far_b: z,
        }
    }

    /// Sets [`RayPre::qplanes`], the plane offsets in quantised N-wide nodes.
    #[inline(always)]
    pub(super) fn quantised_planes<const N: usize>(&mut self) {
        self.qplanes = Planes::<N, 1>::BY_OCTANT[self.octant];
    }

    /// Plane-distance coefficients for the node test that compares distances as
    /// integers (`x86::node_test8`), given the largest coordinate magnitude of the
    /// scene per axis.
    ///
    /// An axis whose inverse direction is infinite, or so large that a product could
    /// overflow (|inv|·max(|o|, scene) ≥ 2^100), gets coefficient 0 and offsets ±∞:
    /// near distance −∞ and far +∞, so it never culls (as the NaN lanes of the float
    /// test). Otherwise the coefficient is inv (near and far planes share it, so
    /// that only three per-ray vectors need registers beside the inlined triangle
    /// test), the near offset is o·inv raised and the far one lowered by
    /// s = 16 ε·|o·inv| (plus the smallest normal, for underflow). With u = ε/2 and T
    /// the exact distance: near ≤ T(1 + u)², because s exceeds the rounding of o·inv
    /// and of the offset; far ≥ T(1 − u)² for T ≥ 0 (and ≥ 2^-127 at T = 0), for the
    /// same reason. The node test widens the folded exit by [`FAR_ULPS`] units in the
    /// last place, at least a factor 1 + 8u on a non-negative float, and
    /// (1 − u)²(1 + 8u) > (1 + u)²: so a box the ray crosses on [0, t_max] is never
    /// culled, and the entry distance never exceeds T(1 + u)², within the
    /// traversal's culling margin [`ROBUST`]. Finite values keep NaN out of every
    /// non-empty lane, which the integer comparison needs.
    // `#[inline]`: called once per ray by the traversal in another file, where only an
    // inline function can be inlined (it was inlined when both shared one file).
    #[inline]
    pub(super) fn fast_planes(&mut self, cmax: [f32; 3]) {
        // 2^100, exactly, as a constant: `powi` is a library call.
        const TWO_POW_100: f32 = (1u128 << 100) as f32;
        // All three axes at once, branch-free, with the operations of the formulas
        // above in the same order (same bits as one axis at a time: unit test).
        let (o, inv, oi) = (self.o, self.inv, self.oi);
        let m = o.abs().max(Vec3A::from_array(cmax));
        // Not below 2^100 (NaN included, from ∞·0): the axis never culls.
        let culls = (inv.abs() * m).cmplt(Vec3A::splat(TWO_POW_100));
        let s = Vec3A::splat(16.0 * f32::EPSILON) * oi.abs() + Vec3A::splat(f32::MIN_POSITIVE);
        let pick = |v: Vec3A, parallel: f32| Vec3A::select(culls, v, Vec3A::splat(parallel));
        self.c = pick(inv, 0.0);
        self.near_b = pick(oi + s, f32::INFINITY);
        self.far_b = pick(oi - s, f32::NEG_INFINITY);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// The per-ray values, one axis at a time (the form the vector code replaced).
    fn scalar(ray: &Ray, cmax: [f32; 3]) -> ([f32; 3], [usize; 6], f32, [[f32; 3]; 3]) {
        let inv = ray.d.recip().to_array();
        let o = ray.o.to_array();
        let oi = [o[0] * inv[0], o[1] * inv[1], o[2] * inv[2]];
        let big = oi.iter().filter(|v| v.is_finite()).fold(0.0f32, |m, v| m.max(v.abs()));
        let neg = [inv[0] < 0.0, inv[1] < 0.0, inv[2] < 0.0];
        let pick = |a: usize, near: bool| if neg[a] == near { (3 + a) * 32 } else { a * 32 };
        let planes = [pick(0, true), pick(1, true), pick(2, true), pick(0, false), pick(1, false), pick(2, false)];
        let mut c = [[0.0f32; 3]; 3];
        for a in 0..3 {
            let m = o[a].abs().max(cmax[a]);
            if (inv[a].abs() * m).partial_cmp(&((1u128 << 100) as f32)) != Some(std::cmp::Ordering::Less) {
                (c[0][a], c[1][a], c[2][a]) = (0.0, f32::INFINITY, f32::NEG_INFINITY);
                continue;
            }
            let s = 16.0 * f32::EPSILON * oi[a].abs() + f32::MIN_POSITIVE;
            (c[0][a], c[1][a], c[2][a]) = (inv[a], oi[a] + s, oi[a] - s);
        }
        (inv, planes, 4.0 * f32::EPSILON * big, c)
    }

    /// The vector setup gives the scalar formulas' values bit for bit, on rays with
    /// zero (±0) and tiny direction components and origins far from the scene.
    #[test]
    fn vector_setup_equals_the_scalar_formulas() {
        let mut seed = 5u64;
        let mut v = |scale: f32| {
            let mut c = [0.0f32; 3];
            for x in &mut c {
                seed = crate::math::hash_words(&[seed]);
                let u = (seed >> 40) as f32 / (1u64 << 24) as f32;
                *x = match seed % 9 {
                    0 => 0.0,
                    1 => -0.0,
                    2 => (u - 0.5) * 1e-30,
                    3 => (u - 0.5) * 1e30,
                    _ => (u - 0.5) * scale,
                };
            }
            Vec3::from(c)
        };
        let bits = |a: [f32; 3]| a.map(f32::to_bits);
        for k in 0..20_000 {
            let ray = Ray::new(v(if k % 2 == 0 { 10.0 } else { 1e6 }), v(2.0));
            let cmax = [4.0, 0.0, 1e7];
            let mut r = RayPre::new::<8>(&ray);
            r.fast_planes(cmax);
            let (inv, planes, slack, c) = scalar(&ray, cmax);
            assert_eq!(bits(r.inv.to_array()), bits(inv), "{ray:?}");
            assert_eq!(r.planes, planes, "{ray:?}");
            assert_eq!(r.slack.to_bits(), slack.to_bits(), "{ray:?}");
            assert_eq!([r.c, r.near_b, r.far_b].map(|v| bits(v.to_array())), c.map(bits), "{ray:?}");
        }
    }
}
