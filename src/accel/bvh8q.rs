//! `bvh8q`: the 8-wide BVH of [`super::wide`] with quantised child boxes.
//!
//! Each node stores its children's boxes as 8-bit offsets on a per-node grid
//! (origin + q·scale per axis, the scale a power of two; Ylitie, Karras & Laine
//! 2017), rounded outwards, so a node takes two cache lines instead of four and the
//! node array half the memory: more of the tree stays in the L2 cache. The ray's
//! plane distances are (origin − o)/d + q·(scale/d), one fused multiply-add per
//! plane after the byte-to-float conversion; the extra rounding of (origin − o) is
//! covered by a per-ray absolute slack (see `wide::qnode`), so no box a ray
//! crosses is ever culled. Leaves and the triangle test are those of `bvh8`, so
//! hits are bit-identical.

/// 8-wide BVH with quantised nodes (`bvh8q`), built by `Bvh8q::build_quantized`.
pub type Bvh8q = super::wide::WideBvh<8>;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Accel;
    use crate::accel::TraversalStats;
    use crate::geometry::Ray;
    use glam::Vec3;

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
