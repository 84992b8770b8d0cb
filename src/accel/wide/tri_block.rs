//! The triangle block: up to four triangles of a leaf tested together, lane by lane,
//! with the operations of [`crate::geometry::intersect_triangle`] in the same order.

use crate::accel::PreTriangle;
use glam::Vec3;

/// Up to four triangles of one leaf as structure-of-arrays (v0, e1 = v1 − v0,
/// e2 = v2 − v0 per axis and lane) with their scene indices; unused lanes hold a
/// zero-area triangle, which the test rejects (det = 0).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(super) struct TriBlock {
    v0: [[f32; 4]; 3],
    e1: [[f32; 4]; 3],
    e2: [[f32; 4]; 3],
    pub(super) id: [u32; 4],
}

impl TriBlock {
    pub(super) fn new(tris: &[[Vec3; 3]], ids: &[u32]) -> Self {
        let mut b = TriBlock { v0: [[0.0; 4]; 3], e1: [[0.0; 4]; 3], e2: [[0.0; 4]; 3], id: [u32::MAX; 4] };
        for (lane, &i) in ids.iter().enumerate() {
            let t = PreTriangle::new(&tris[i as usize]);
            for a in 0..3 {
                b.v0[a][lane] = t.v0[a];
                b.e1[a][lane] = t.e1[a];
                b.e2[a][lane] = t.e2[a];
            }
            b.id[lane] = i;
        }
        b
    }

    /// [`intersect_triangle`] on the four lanes at once, with the same operations in
    /// the same order (so the same bits); returns the lanes hit with 0 < t < t_max
    /// and their (t, b1, b2).
    // The negated comparisons reproduce the scalar test's NaN behaviour exactly, and
    // plain `&` of comparisons keeps the lane loop branch-free for the vectoriser.
    #[allow(clippy::neg_cmp_op_on_partial_ord, clippy::manual_range_contains)]
    #[inline(always)]
    pub(super) fn intersect(&self, o: Vec3, d: Vec3, t_max: f32) -> (u32, [f32; 4], [f32; 4], [f32; 4]) {
        let [v0x, v0y, v0z] = &self.v0;
        let [e1x, e1y, e1z] = &self.e1;
        let [e2x, e2y, e2z] = &self.e2;
        let (mut det, mut un, mut vn, mut tn) = ([0.0f32; 4], [0.0f32; 4], [0.0f32; 4], [0.0f32; 4]);
        let mut maybe = [false; 4];
        for i in 0..4 {
            // pvec = d × e2, det = e1 · pvec
            let px = d.y * e2z[i] - e2y[i] * d.z;
            let py = d.z * e2x[i] - e2z[i] * d.x;
            let pz = d.x * e2y[i] - e2x[i] * d.y;
            det[i] = e1x[i] * px + e1y[i] * py + e1z[i] * pz;
            // tvec = o − v0; u·det = tvec · pvec
            let tx = o.x - v0x[i];
            let ty = o.y - v0y[i];
            let tz = o.z - v0z[i];
            un[i] = tx * px + ty * py + tz * pz;
            // qvec = tvec × e1; v·det = d · qvec, t·det = e2 · qvec
            let qx = ty * e1z[i] - e1y[i] * tz;
            let qy = tz * e1x[i] - e1z[i] * tx;
            let qz = tx * e1y[i] - e1x[i] * ty;
            vn[i] = d.x * qx + d.y * qy + d.z * qz;
            tn[i] = e2x[i] * qx + e2y[i] * qy + e2z[i] * qz;
            // Division-free reject (Möller–Trumbore with deferred division): with
            // U = u·|det| etc. (sign of det folded in), a lane is dropped only where
            // the exact test below must fail too. The margins (2^-20 relative) exceed
            // the few ulps by which the divided values can differ from U/|det|, and
            // keep u, v away from underflow, where the exact test would see ±0.
            let ad = det[i].abs();
            let s = if det[i] < 0.0 { -1.0 } else { 1.0 };
            let (uu, vv, tt) = (un[i] * s, vn[i] * s, tn[i] * s);
            let m = ad * (1.0 / 1048576.0);
            let out = (uu < -m) | (vv < -m) | (uu > ad + m) | (uu + vv > ad + 4.0 * m) | (tt <= 0.0) | (tt > ad * t_max + m * t_max);
            maybe[i] = !out;
        }
        let mut pre = 0u32;
        for (i, h) in maybe.iter().enumerate() {
            pre |= (*h as u32) << i;
        }
        if pre == 0 {
            return (0, [0.0; 4], [0.0; 4], [0.0; 4]);
        }
        // The exact test of `intersect_triangle` on the same intermediate values.
        // The scalar test's `det` check (non-zero, finite) is implied by the others:
        // det = ±0 makes u = ±∞ or NaN (fails 0 ≤ u ≤ 1), det = ±∞ makes t = ±0 or
        // NaN (fails t > 0), a NaN det fails everything.
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::*;
            // Explicit SSE (part of x86-64): written as a lane loop, LLVM scalarises
            // the range checks, which cost ~100 instructions per block that passes
            // the reject. Same IEEE operations, so the same bits.
            // SAFETY: SSE and SSE2 are part of x86-64; every array holds 4 floats.
            unsafe {
                let inv = _mm_div_ps(_mm_set1_ps(1.0), _mm_loadu_ps(det.as_ptr()));
                let u = _mm_mul_ps(_mm_loadu_ps(un.as_ptr()), inv);
                let v = _mm_mul_ps(_mm_loadu_ps(vn.as_ptr()), inv);
                let t = _mm_mul_ps(_mm_loadu_ps(tn.as_ptr()), inv);
                let (zero, one) = (_mm_setzero_ps(), _mm_set1_ps(1.0));
                let in_u = _mm_and_ps(_mm_cmpge_ps(u, zero), _mm_cmple_ps(u, one));
                let in_v = _mm_and_ps(_mm_cmpnlt_ps(v, zero), _mm_cmpngt_ps(_mm_add_ps(u, v), one));
                let in_t = _mm_and_ps(_mm_cmpgt_ps(t, zero), _mm_cmplt_ps(t, _mm_set1_ps(t_max)));
                let mask = _mm_movemask_ps(_mm_and_ps(_mm_and_ps(in_u, in_v), in_t)) as u32;
                let (mut tt, mut uu, mut vv) = ([0.0f32; 4], [0.0f32; 4], [0.0f32; 4]);
                _mm_storeu_ps(tt.as_mut_ptr(), t);
                _mm_storeu_ps(uu.as_mut_ptr(), u);
                _mm_storeu_ps(vv.as_mut_ptr(), v);
                (mask, tt, uu, vv)
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let (mut tt, mut uu, mut vv) = ([0.0f32; 4], [0.0f32; 4], [0.0f32; 4]);
            let mut mask = 0u32;
            for i in 0..4 {
                let inv = 1.0 / det[i];
                let (u, v, t) = (un[i] * inv, vn[i] * inv, tn[i] * inv);
                let ok = (u >= 0.0) & (u <= 1.0) & !(v < 0.0) & !(u + v > 1.0) & (t > 0.0) & (t < t_max);
                mask |= (ok as u32) << i;
                (tt[i], uu[i], vv[i]) = (t, u, v);
            }
            (mask, tt, uu, vv)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_block_matches_the_scalar_test_bit_for_bit() {
        use crate::geometry::intersect_triangle;
        use crate::math::{hash_words, uniform_sphere};
        let unit = |h: u64| (h >> 40) as f32 / (1u64 << 24) as f32;
        let p = |k: u64, s: u64| uniform_sphere([unit(hash_words(&[k, s])), unit(hash_words(&[k, s + 1]))]);
        let mut hits = 0;
        for k in 0..20_000u64 {
            let mut tris: Vec<[Vec3; 3]> = (0..4).map(|j| [p(k, 10 * j), p(k, 10 * j + 2) * 0.5, p(k, 10 * j + 4) * 2.0]).collect();
            let (mut o, mut d) = (p(k, 100) * 0.3, p(k, 102));
            // Degenerate cases, where det is 0 or infinite: a collinear triangle, a
            // huge one, and a ray in the plane of its triangle.
            match k % 8 {
                3 => tris[0][2] = tris[0][0] * 3.0 - tris[0][1] * 2.0,
                4 => tris[0] = tris[0].map(|v| v * 1e25),
                5 => {
                    let t = tris[0];
                    o = t[0] + (t[1] - t[0]) * 0.25 + (t[2] - t[0]) * 0.25 - (t[1] - t[0]);
                    d = (t[1] - t[0]).normalize();
                }
                _ => {}
            }
            let n = 1 + (k % 4) as usize;
            let ids: Vec<u32> = (0..n as u32).collect();
            let block = TriBlock::new(&tris, &ids);
            let t_max = if k % 5 == 0 { 0.7 } else { f32::INFINITY };
            let (mask, t, u, v) = block.intersect(o, d, t_max);
            for j in 0..4 {
                let want = if j < n {
                    let pt = PreTriangle::new(&tris[j]);
                    intersect_triangle(o, d, pt.v0, pt.e1, pt.e2, t_max)
                } else {
                    None
                };
                match want {
                    Some((wt, wu, wv)) => {
                        hits += 1;
                        assert!(mask & (1 << j) != 0, "case {k} lane {j}");
                        assert_eq!((t[j].to_bits(), u[j].to_bits(), v[j].to_bits()), (wt.to_bits(), wu.to_bits(), wv.to_bits()));
                    }
                    None => assert!(mask & (1 << j) == 0, "case {k} lane {j}"),
                }
            }
        }
        assert!(hits > 4_000, "{hits}");
    }

    /// The division-free reject must never drop a lane the exact test accepts: rays
    /// aimed at edges and vertices (u, v or u + v exactly at their limits, up to
    /// rounding) and t_max at, just above and just below the hit distance.
    #[test]
    fn triangle_block_agrees_on_edges_vertices_and_t_max() {
        use crate::geometry::intersect_triangle;
        use crate::math::{hash_words, uniform_sphere};
        let unit = |h: u64| (h >> 40) as f32 / (1u64 << 24) as f32;
        let p = |k: u64, s: u64| uniform_sphere([unit(hash_words(&[k, s])), unit(hash_words(&[k, s + 1]))]);
        let (mut hits, mut misses) = (0, 0);
        for k in 0..40_000u64 {
            let scale = [1e-3f32, 1.0, 1e3][(k % 3) as usize];
            let tri = [p(k, 0) * scale, p(k, 2) * scale, p(k, 4) * scale];
            let a = unit(hash_words(&[k, 7]));
            let (e1, e2) = (tri[1] - tri[0], tri[2] - tri[0]);
            // On an edge or at a vertex, chosen by k.
            let target = match k % 6 {
                0 => tri[0] + e1 * a,
                1 => tri[0] + e2 * a,
                2 => tri[0] + e1 * a + e2 * (1.0 - a),
                3 => tri[0],
                4 => tri[1],
                _ => tri[2],
            };
            let o = target + p(k, 9) * scale * 2.0;
            let d = (target - o).normalize();
            let block = TriBlock::new(&[tri; 4], &[0, 1, 2, 3]);
            let pt = PreTriangle::new(&tri);
            let t_hit = intersect_triangle(o, d, pt.v0, pt.e1, pt.e2, f32::INFINITY).map(|h| h.0);
            let limits = match t_hit {
                Some(t) => vec![f32::INFINITY, t, f32::from_bits(t.to_bits() + 1), f32::from_bits(t.to_bits() - 1)],
                None => vec![f32::INFINITY],
            };
            for t_max in limits {
                let want = intersect_triangle(o, d, pt.v0, pt.e1, pt.e2, t_max);
                let (mask, t, u, v) = block.intersect(o, d, t_max);
                match want {
                    Some((wt, wu, wv)) => {
                        hits += 1;
                        assert_eq!(mask, 0b1111, "case {k}, t_max {t_max}");
                        assert_eq!((t[0].to_bits(), u[0].to_bits(), v[0].to_bits()), (wt.to_bits(), wu.to_bits(), wv.to_bits()));
                    }
                    None => {
                        misses += 1;
                        assert_eq!(mask, 0, "case {k}, t_max {t_max}");
                    }
                }
            }
        }
        // Edge rays land on both sides of the boundary.
        assert!(hits > 10_000 && misses > 10_000, "{hits} hits, {misses} misses");
    }
}
