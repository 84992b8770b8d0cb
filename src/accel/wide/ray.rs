//! Per-ray values every node test reuses, and the widening constants of the
//! conservative box tests.

use crate::geometry::Ray;

/// Relative widening of far distances in the integer-compare node test
/// ([`RayPre::fast_planes`]).
pub(super) const FAR_WIDEN: f32 = 1.0 + 8.0 * f32::EPSILON;
/// Far-distance widening of the robust slab test: 1 + 2γ₃ with γₙ = nε/(1 − nε).
pub(super) const ROBUST: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Whether the traversal may run on `ray`: finite origin and direction, and a
/// direction that is not zero. On any other ray every axis of a node test can give
/// NaN, which enters even the empty child slots; such a ray hits nothing (the
/// triangle test's determinant is 0 or NaN), so it is answered without traversal.
#[inline(always)]
pub(super) fn traceable(ray: &Ray) -> bool {
    ray.o.is_finite() && ray.d.is_finite() && ray.d != glam::Vec3::ZERO
}

/// Per-ray values every node test reuses.
pub(super) struct RayPre {
    pub(super) o: [f32; 3],
    pub(super) inv: [f32; 3],
    /// Per axis: the near plane is the box maximum (direction negative).
    pub(super) neg: [bool; 3],
    /// Byte offsets in a node of the near (x, y, z) then far (x, y, z) plane arrays,
    /// chosen once per ray so the node test does no per-node selection.
    pub(super) planes: [usize; 6],
    /// The same for quantised nodes (byte arrays qlo[3][N] then qhi[3][N]; set
    /// only for them).
    pub(super) qplanes: [usize; 6],
    /// o·inv per axis, for the fused-multiply-subtract form of the AVX2 node test.
    pub(super) oi: [f32; 3],
    /// Absolute error bound of that form's distances: rounding o·inv loses up to
    /// ulp(|o·inv|), which can exceed the relative slack of [`ROBUST`] for boxes close
    /// to an origin far from the world origin; 0 where o·inv is not finite (those
    /// lanes become NaN and are ignored, which only ever keeps a box).
    pub(super) slack: f32,
    /// Near-plane distance t = plane·`near_c` − `near_b` and far-plane distance
    /// plane·`far_c` − `far_b` per axis, for the integer-compare node test (see
    /// [`RayPre::fast_planes`]); set only for float nodes.
    pub(super) near_c: [f32; 3],
    pub(super) near_b: [f32; 3],
    pub(super) far_c: [f32; 3],
    pub(super) far_b: [f32; 3],
}

impl RayPre {
    #[inline(always)]
    pub(super) fn new<const N: usize>(ray: &Ray) -> Self {
        let inv = ray.d.recip().to_array();
        let o = ray.o.to_array();
        let oi = [o[0] * inv[0], o[1] * inv[1], o[2] * inv[2]];
        let big = oi.iter().filter(|v| v.is_finite()).fold(0.0f32, |m, v| m.max(v.abs()));
        let neg = [inv[0] < 0.0, inv[1] < 0.0, inv[2] < 0.0];
        // Node<N> holds lo[3][N] then hi[3][N] (repr(C)).
        let lo = |a: usize| a * N * 4;
        let hi = |a: usize| (3 + a) * N * 4;
        let pick = |a: usize, near: bool| if neg[a] == near { hi(a) } else { lo(a) };
        let planes = [pick(0, true), pick(1, true), pick(2, true), pick(0, false), pick(1, false), pick(2, false)];
        let z = [0.0; 3];
        RayPre { o, inv, neg, planes, qplanes: [0; 6], oi, slack: 4.0 * f32::EPSILON * big, near_c: z, near_b: z, far_c: z, far_b: z }
    }

    /// Plane-distance coefficients for the node test that compares distances as
    /// integers (`x86::node_test8`), given the largest coordinate magnitude of the
    /// scene per axis.
    ///
    /// An axis whose inverse direction is infinite, or so large that a product could
    /// overflow (|inv|·max(|o|, scene) ≥ 2^100), gets coefficient 0 and offsets ±∞:
    /// near distance −∞ and far +∞, so it never culls (as the NaN lanes of the float
    /// test). Otherwise the near offset is raised and the far one lowered by
    /// s = 16 ε·|o·inv| (plus the smallest normal, for underflow), and the far
    /// coefficient and offset are scaled by 1 + 8 ε. With u = ε/2 and T the exact
    /// distance: near ≤ T(1 + 2u + u²), because s exceeds the rounding of o·inv and
    /// of the offset; far ≥ T(1 + 13u) for T ≥ 0 (and > 0 at T = 0), because s
    /// exceeds the rounding of o·inv, of both scaled constants and of plane·coef
    /// (≤ 4u|o·inv| + u|T|). So a box the ray crosses on [0, t_max] is never culled,
    /// and the entry distance never exceeds T(1 + 2u + u²), within the traversal's
    /// culling margin [`ROBUST`]. Finite values keep NaN out of every non-empty
    /// lane, which the integer comparison needs.
    // `#[inline]`: called once per ray by the traversal in another file, where only an
    // inline function can be inlined (it was inlined when both shared one file).
    #[inline]
    pub(super) fn fast_planes(&mut self, cmax: [f32; 3]) {
        // 2^100, exactly, as a constant: `powi` is a library call, once per axis of
        // every ray.
        const TWO_POW_100: f32 = (1u128 << 100) as f32;
        for (a, c) in cmax.iter().enumerate() {
            let m = self.o[a].abs().max(*c);
            // Also true for NaN (∞·0).
            let parallel = (self.inv[a].abs() * m).partial_cmp(&TWO_POW_100) != Some(std::cmp::Ordering::Less);
            if parallel {
                (self.near_c[a], self.near_b[a], self.far_c[a], self.far_b[a]) = (0.0, f32::INFINITY, 0.0, f32::NEG_INFINITY);
                continue;
            }
            let s = 16.0 * f32::EPSILON * self.oi[a].abs() + f32::MIN_POSITIVE;
            self.near_c[a] = self.inv[a];
            self.near_b[a] = self.oi[a] + s;
            self.far_c[a] = self.inv[a] * FAR_WIDEN;
            self.far_b[a] = self.oi[a] * FAR_WIDEN - s;
        }
    }
}
