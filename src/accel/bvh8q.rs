//! `bvh8q`: the 8-wide BVH of [`super::bvh4`] with quantised child boxes.
//!
//! Each node stores its children's boxes as 8-bit offsets on a per-node grid
//! (origin + q·scale per axis, the scale a power of two; Ylitie, Karras & Laine
//! 2017), rounded outwards, so a node takes two cache lines instead of four and the
//! node array half the memory: more of the tree stays in the L2 cache. The ray's
//! plane distances are (origin − o)/d + q·(scale/d), one fused multiply-add per
//! plane after the byte-to-float conversion; the extra rounding of (origin − o) is
//! covered by a per-ray absolute slack (see `QNode::slack`), so no box a ray
//! crosses is ever culled. Leaves and the triangle test are those of `bvh8`, so
//! hits are bit-identical.

use super::bvh4::Node;

/// 8-wide BVH with quantised nodes (`bvh8q`).
pub type Bvh8q = super::bvh4::WideBvh<8>;

/// A quantised wide node: 8-bit child boxes on the node's grid, the grid, and the
/// child references (two cache lines for N = 8).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct QNode<const N: usize> {
    /// Lower grid coordinates per axis and lane (255 in empty slots).
    pub(crate) qlo: [[u8; N]; 3],
    /// Upper grid coordinates per axis and lane (0 in empty slots).
    pub(crate) qhi: [[u8; N]; 3],
    /// Grid origin (the lower corner of the union of the children's boxes).
    pub(crate) origin: [f32; 3],
    /// Grid step per axis (a power of two).
    pub(crate) scale: [f32; 3],
    /// Child references, as in [`Node`].
    pub(crate) child: [u32; N],
    /// Bit i set when slot i holds a child.
    pub(crate) valid: u32,
}

impl<const N: usize> QNode<N> {
    /// Quantises a node's child boxes outwards (exactly, in f64: every decoded lower
    /// plane origin + q·scale is ≤ the box's, every upper one ≥).
    pub(crate) fn from_node(n: &Node<N>, empty: u32) -> Self {
        let mut q = QNode { qlo: [[255; N]; 3], qhi: [[0; N]; 3], origin: [0.0; 3], scale: [1.0; 3], child: n.child, valid: 0 };
        for i in 0..N {
            if n.child[i] != empty {
                q.valid |= 1 << i;
            }
        }
        for a in 0..3 {
            let lanes = (0..N).filter(|&i| q.valid & (1 << i) != 0);
            let lo = lanes.clone().map(|i| n.lo[a][i]).fold(f32::INFINITY, f32::min);
            let hi = lanes.map(|i| n.hi[a][i]).fold(f32::NEG_INFINITY, f32::max);
            if lo > hi {
                continue; // no child
            }
            let ext = hi as f64 - lo as f64;
            // Smallest power of two with ext / scale ≤ 255 (at least 2^-100, so that
            // scale / d stays a normal number).
            let mut e = if ext > 0.0 { (ext / 255.0).log2().ceil() as i32 } else { -100 };
            e = e.max(-100);
            while ext / 2f64.powi(e) > 255.0 {
                e += 1;
            }
            let scale = 2f64.powi(e);
            q.origin[a] = lo;
            q.scale[a] = scale as f32;
            for i in 0..N {
                if q.valid & (1 << i) == 0 {
                    continue;
                }
                let l = ((n.lo[a][i] as f64 - lo as f64) / scale).floor();
                let h = ((n.hi[a][i] as f64 - lo as f64) / scale).ceil();
                q.qlo[a][i] = l.clamp(0.0, 255.0) as u8;
                q.qhi[a][i] = h.clamp(0.0, 255.0) as u8;
                debug_assert!(lo as f64 + q.qlo[a][i] as f64 * scale <= n.lo[a][i] as f64);
                debug_assert!(lo as f64 + q.qhi[a][i] as f64 * scale >= n.hi[a][i] as f64);
            }
        }
        q
    }

    /// Per-ray absolute slack for the far distances of quantised boxes in a scene
    /// whose coordinates are at most `cmax` in magnitude: rounding (origin − o) and
    /// its product with 1/d errs by up to 2ε·(|origin| + |o|)/|d| on each of the near
    /// and far distances. Axes with a non-finite 1/d are skipped (their distances
    /// are ±∞ or NaN, which the test ignores).
    pub(crate) fn slack(o: [f32; 3], inv: [f32; 3], cmax: [f32; 3]) -> f32 {
        let mut s = 0.0f32;
        for a in 0..3 {
            if inv[a].is_finite() {
                s = s.max((cmax[a] + o[a].abs()) * inv[a].abs());
            }
        }
        6.0 * f32::EPSILON * s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Accel;
    use crate::accel::TraversalStats;
    use crate::geometry::Ray;
    use glam::Vec3;

    #[test]
    fn quantised_node_is_two_cache_lines() {
        assert_eq!(std::mem::size_of::<QNode<8>>(), 128);
    }

    /// Far from the origin and with tiny triangles, the quantised tree still finds
    /// exactly the hits of the float tree (boxes only ever grow).
    #[test]
    fn far_from_origin_tiny_triangles_agree_with_bvh8() {
        use crate::math::hash_words;
        let unit = |h: u64| (h >> 40) as f32 / (1u64 << 24) as f32;
        let base = Vec3::new(1000.0, -2000.0, 500.0);
        let tris: Vec<[Vec3; 3]> = (0..5000u64)
            .map(|k| {
                let c = base + Vec3::new(unit(hash_words(&[k, 0])), unit(hash_words(&[k, 1])), unit(hash_words(&[k, 2]))) * 2.0;
                [c, c + Vec3::new(1e-3, 0.0, 0.0), c + Vec3::new(0.0, 1e-3, 1e-4)]
            })
            .collect();
        let q = Bvh8q::build_quantized(&tris);
        let f = super::super::bvh8::Bvh8::build(&tris);
        let (mut s1, mut s2) = (TraversalStats::default(), TraversalStats::default());
        let mut hits = 0;
        for k in 0..20_000u64 {
            // Aim at a triangle's interior from nearby, or at a vertex (often on a
            // grid plane of its node) from up to 3000 units away, where rounding
            // (origin − o)/d is largest.
            let t = &tris[(k % 5000) as usize];
            let (target, dist) = match k % 4 {
                0 => (t[0] + (t[1] - t[0]) * 0.3 + (t[2] - t[0]) * 0.3, 3.0),
                v => (t[(v - 1) as usize], 3000.0),
            };
            let o = target + (Vec3::new(unit(hash_words(&[k, 5])), unit(hash_words(&[k, 6])), unit(hash_words(&[k, 7]))) - 0.5) * dist;
            let ray = Ray::new(o, (target - o).normalize());
            let a = q.intersect(&ray, f32::INFINITY, &mut s1);
            let b = f.intersect(&ray, f32::INFINITY, &mut s2);
            assert_eq!(a.map(|h| (h.tri, h.t.to_bits())), b.map(|h| (h.tri, h.t.to_bits())), "ray {k}");
            hits += a.is_some() as u32;
            assert_eq!(q.occluded(&ray, f32::INFINITY, &mut s1), b.is_some());
        }
        assert!(hits > 10_000, "{hits}");
    }
}
