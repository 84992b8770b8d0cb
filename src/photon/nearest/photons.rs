//! The photon search of radiance estimates at final-gather hits (tens of millions
//! per render): k nearest photons within a disc about the query's tangent plane, on
//! a [`DiscGrid`] of photons.
//!
//! A query scans the cells of a box about the query point and keeps the photons
//! that pass the estimate's filter (inside the search radius, within the disc's
//! half-thickness of the tangent plane, normal agreeing with the query's) and lie
//! closer than the box's inside radius, the distance from the query to the box's
//! outside: every photon that close was read. When k are found the k nearest of
//! them are the exact k nearest (as the kd-tree's search finds them, ties at the
//! k-th distance aside); otherwise the box doubles and is scanned afresh, until it
//! holds the whole search radius.
//!
//! Cells are about as wide as the typical k-th neighbour distance, so the first box
//! (three cells a side) usually answers: a few contiguous ranges read in order,
//! against the kd-tree's dependent loads down and back up a tree of a million
//! photons.

use super::disc::{BLOCK, DiscGrid};
use crate::photon::kdtree::KnnHeap;
use crate::photon::record::Photon;
use glam::Vec3;

/// Cell side, in median nearest-neighbour distances, for k-neighbour searches:
/// points on a surface at density σ have a median nearest-neighbour distance
/// √(ln 2 / (πσ)) and a k-th neighbour distance √(k / (πσ)).
fn cell_spacings(k: usize) -> f32 {
    (k.max(1) as f32 / std::f32::consts::LN_2).sqrt()
}

/// Photons in grid cells for k-nearest searches with the estimate's disc filter: per
/// photon its exact position (12 bytes), its record ([`Photon`], 8 bytes: power,
/// direction and normal, decoded when read), its normal's code again beside the
/// coordinates for the filter (2 bytes) and its input index (4 bytes, to rebuild
/// the maps' kd-trees in input order).
pub type PhotonGrid = DiscGrid<Photon>;

impl DiscGrid<Photon> {
    /// Indexes `photons` at `positions` (same length) for searches of `k` photons.
    pub fn build_photons(positions: &[Vec3], photons: &[Photon], k: usize) -> Self {
        let n = positions.len().min(photons.len());
        let coord = |a: usize| positions[..n].iter().map(|p| p[a]).collect();
        Self::build_photons_soa(coord(0), coord(1), coord(2), photons[..n].to_vec(), k)
    }

    /// [`DiscGrid::build_photons`] from coordinate arrays, which it consumes.
    pub fn build_photons_soa(x: Vec<f32>, y: Vec<f32>, z: Vec<f32>, photons: Vec<Photon>, k: usize) -> Self {
        let normals = photons.iter().map(|p| p.normal_code()).collect();
        DiscGrid::build_soa(x, y, z, normals, photons, cell_spacings(k), true)
    }

    /// The k nearest photons to `p` within distance² `max_r2` that lie within
    /// `thick` of the plane through `p` normal to `n` and whose normal has a cosine of
    /// at least `cos` with `n` — the kd-tree's search with the estimate's filter
    /// ([`crate::photon::estimate::PhotonSearch::gather`]). Results in `heap.items` (distance²,
    /// grid index; unordered); returns the k-th distance² when k were found, else
    /// `max_r2`.
    #[allow(clippy::too_many_arguments)]
    pub fn knn_disc(&self, p: Vec3, n: Vec3, thick: f32, cos: f32, k: usize, max_r2: f32, heap: &mut KnnHeap) -> f32 {
        heap.items.clear();
        if k == 0 || self.is_empty() || max_r2.is_nan() || max_r2 <= 0.0 || !p.is_finite() {
            return max_r2;
        }
        let max_r = max_r2.sqrt();
        let mut rho = self.first_rho(max_r);
        loop {
            heap.items.clear();
            if let Some((lo, hi)) = self.cells.cell_box(p, rho) {
                let inside = self.cells.inner_radius(p, lo, hi);
                // Only photons inside the box's inside radius can settle the query.
                let cap = max_r2.min(inside * inside);
                let mut r2 = cap;
                self.cells.scan_cells(lo, hi, None, &mut |rows| {
                    // Short scattered ranges: fetch them all before reading any, so
                    // their cache misses overlap.
                    for &(a, b) in rows {
                        self.prefetch_range(a as usize, b as usize);
                    }
                    for &(a, b) in rows {
                        self.scan_range(p, n, thick, cos, a as usize, b as usize, k, &mut r2, heap);
                    }
                });
                if heap.items.len() >= k {
                    return heap.keep_nearest(k).min(cap);
                }
                if cap >= max_r2 {
                    return max_r2;
                }
            }
            if rho >= max_r {
                return max_r2;
            }
            rho = (2.0 * rho).min(max_r);
        }
    }

    /// The first box's half-width of a search within `max_r`.
    #[inline]
    fn first_rho(&self, max_r: f32) -> f32 {
        self.cells.cell.min(max_r)
    }

    /// Offers the photons `a..b` that pass the filter and lie closer than `r2` to
    /// the heap: a block's tests computed for all its lanes (no branches), then the
    /// passing lanes from a bit mask. The arithmetic is the kd-tree filter's, in the
    /// same order, so the same photons pass.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn scan_range(&self, p: Vec3, n: Vec3, thick: f32, cos: f32, a: usize, b: usize, k: usize, r2: &mut f32, heap: &mut KnnHeap) {
        let mut i = a;
        while i < b {
            let (mut mask, d2) = self.block(i, p, n, thick, cos, *r2);
            if b - i < BLOCK {
                mask &= (1u32 << (b - i)) - 1;
            }
            while mask != 0 {
                let j = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                // r2 shrinks while the block is read.
                if d2[j] < *r2 {
                    heap.push(k, d2[j], (i + j) as u32, r2);
                }
            }
            i += BLOCK;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Color;
    use crate::photon::kdtree::KdTree;

    /// Photons on the faces of a box (normal: the face's inward one), a ten times
    /// denser patch, and some inside the box with random normals.
    fn photons(n: usize) -> (Vec<Vec3>, Vec<Photon>) {
        let (pos, items) = super::super::tests::points_with(n, 7, true);
        let ph = items.iter().map(|&(m, i)| Photon::new(Color::splat(1.0 + i as f32), m, m)).collect();
        (pos, ph)
    }

    #[test]
    fn knn_disc_equals_the_kd_tree_search() {
        let (pos, ph) = photons(20000);
        let tree = KdTree::build_with(&pos, ph);
        // The grid over the tree's stored positions, so distances agree bit for bit.
        let stored: Vec<Vec3> = (0..tree.len()).map(|i| tree.position(i)).collect();
        let (mut hg, mut ht) = (KnnHeap::default(), KnnHeap::default());
        for k in [1usize, 8, 50] {
            let g = PhotonGrid::build_photons(&stored, &tree.points, k);
            assert_eq!(g.len(), tree.len());
            let mut full = 0;
            for q in 0..1500u64 {
                let (p, n) = super::super::tests::query(q);
                for (max_r, thick, cos) in [(0.05f32, 0.01f32, 0.7f32), (0.3, 0.05, 0.7), (10.0, 10.0, -2.0), (10.0, 0.05, 0.0)] {
                    let filter = |ph: &Photon, at: Vec3| (at - p).dot(n).abs() <= thick && ph.normal().dot(n) >= cos;
                    let rg = g.knn_disc(p, n, thick, cos, k, max_r * max_r, &mut hg);
                    let rt = tree.knn(p, k, max_r * max_r, &mut ht, &filter);
                    assert_eq!(rg, rt, "query {q} k {k} r {max_r}");
                    let mut dg: Vec<f32> = hg.items.iter().map(|e| e.0).collect();
                    let mut dt: Vec<f32> = ht.items.iter().map(|e| e.0).collect();
                    dg.sort_by(f32::total_cmp);
                    dt.sort_by(f32::total_cmp);
                    assert_eq!(dg, dt, "query {q} k {k} r {max_r}");
                    for &(d2, i) in &hg.items {
                        let at = g.position(i as usize);
                        assert_eq!(d2, (at - p).length_squared());
                        assert!((at - p).dot(n).abs() <= thick && g.normal(i as usize).dot(n) >= cos);
                    }
                    full += (hg.items.len() == k) as usize;
                }
            }
            assert!(full > 1500, "k {k}: {full}");
        }
    }

    #[test]
    fn knn_disc_degenerate_inputs() {
        let mut h = KnnHeap::default();
        let none = PhotonGrid::build_photons(&[], &[], 10);
        assert_eq!(none.knn_disc(Vec3::ZERO, Vec3::Z, 1.0, 0.0, 10, 4.0, &mut h), 4.0);
        assert!(h.items.is_empty());
        let ph = Photon::new(Color::ONE, Vec3::Z, Vec3::Z);
        let g = PhotonGrid::build_photons(&[Vec3::splat(2.0); 30], &[ph; 30], 10);
        let n = Vec3::Z;
        assert_eq!(g.knn_disc(Vec3::new(2.0, 2.0, 3.0), n, 5.0, 0.5, 10, 100.0, &mut h), 1.0);
        assert_eq!(h.items.len(), 10);
        // The plane and normal tests.
        assert_eq!(g.knn_disc(Vec3::new(2.0, 2.0, 3.0), n, 0.5, 0.5, 10, 100.0, &mut h), 100.0);
        assert!(h.items.is_empty());
        assert_eq!(g.knn_disc(Vec3::new(2.0, 2.0, 3.0), -n, 5.0, 0.5, 10, 100.0, &mut h), 100.0);
        assert_eq!(g.knn_disc(Vec3::NAN, n, 5.0, 0.5, 10, 100.0, &mut h), 100.0);
        // Far from every photon, a radius that cannot reach them, then one that can.
        assert_eq!(g.knn_disc(Vec3::splat(-40.0), n, 1e3, 0.5, 3, 100.0, &mut h), 100.0);
        assert!(h.items.is_empty());
        assert_eq!(g.knn_disc(Vec3::splat(-40.0), n, 1e3, 0.5, 3, 1e5, &mut h), 3.0 * 42.0 * 42.0);
        assert_eq!(g.knn_disc(Vec3::ONE, n, 5.0, 0.5, 0, 100.0, &mut h), 100.0);
    }
}
