//! Hash grid over a pass's light vertices for vertex merging (as SmallVCM's
//! `HashGrid`): cells of edge 2r hashed into as many buckets as there are points,
//! filled by a stable counting sort, so each bucket lists its points in index order
//! and every query visits them in the same order for any thread count.

use glam::Vec3;

/// Points bucketed by cell.
#[derive(Clone, Debug, Default)]
pub struct HashGrid {
    cell: f32,
    lo: Vec3,
    starts: Vec<u32>,
    indices: Vec<u32>,
}

impl HashGrid {
    /// Builds the grid over `points` for queries of radius `r`.
    pub fn build(points: impl ExactSizeIterator<Item = Vec3> + Clone, r: f32) -> Self {
        let n = points.len();
        let mut lo = Vec3::splat(f32::INFINITY);
        for p in points.clone() {
            lo = lo.min(p);
        }
        let mut g = HashGrid { cell: 2.0 * r, lo, starts: vec![0; n + 1], indices: vec![0; n] };
        if n == 0 || r.is_nan() || r <= 0.0 {
            return g;
        }
        let buckets: Vec<u32> = points.map(|p| g.bucket(g.cell_of(p))).collect();
        for &b in &buckets {
            g.starts[b as usize + 1] += 1;
        }
        for i in 0..n {
            g.starts[i + 1] += g.starts[i];
        }
        let mut fill = g.starts.clone();
        for (i, &b) in buckets.iter().enumerate() {
            g.indices[fill[b as usize] as usize] = i as u32;
            fill[b as usize] += 1;
        }
        g
    }

    #[inline]
    fn cell_of(&self, p: Vec3) -> [i32; 3] {
        let c = ((p - self.lo) / self.cell).floor();
        [c.x as i32, c.y as i32, c.z as i32]
    }

    #[inline]
    fn bucket(&self, c: [i32; 3]) -> u32 {
        let h = (c[0] as u32).wrapping_mul(73_856_093) ^ (c[1] as u32).wrapping_mul(19_349_663) ^ (c[2] as u32).wrapping_mul(83_492_791);
        h % (self.starts.len() as u32 - 1).max(1)
    }

    /// Calls `f` with the index of every point in the cells that the ball of radius
    /// r (the build radius) around `p` touches (a superset of the points within r;
    /// each once, buckets in increasing order).
    pub fn for_each_candidate(&self, p: Vec3, mut f: impl FnMut(u32)) {
        if self.indices.is_empty() {
            return;
        }
        let r = 0.5 * self.cell;
        let (a, b) = (self.cell_of(p - Vec3::splat(r)), self.cell_of(p + Vec3::splat(r)));
        let mut buckets = [0u32; 8];
        let mut n = 0;
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    if n < 8 {
                        buckets[n] = self.bucket([x, y, z]);
                        n += 1;
                    }
                }
            }
        }
        let buckets = &mut buckets[..n];
        buckets.sort_unstable();
        let mut last = u32::MAX;
        for &bk in buckets.iter() {
            if bk == last {
                continue;
            }
            last = bk;
            for &i in &self.indices[self.starts[bk as usize] as usize..self.starts[bk as usize + 1] as usize] {
                f(i);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_every_point_within_the_radius_once() {
        let mut s = 7u64;
        let mut rnd = || {
            s = crate::math::mix64(s);
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        let pts: Vec<Vec3> = (0..2000).map(|_| Vec3::new(rnd(), rnd(), rnd())).collect();
        let r = 0.05;
        let g = HashGrid::build(pts.iter().copied(), r);
        for _ in 0..200 {
            let q = Vec3::new(rnd(), rnd(), rnd());
            let mut got = Vec::new();
            g.for_each_candidate(q, |i| {
                if pts[i as usize].distance_squared(q) <= r * r {
                    got.push(i)
                }
            });
            let mut sorted = got.clone();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), got.len(), "a point reported twice");
            let want: Vec<u32> = (0..pts.len() as u32).filter(|&i| pts[i as usize].distance_squared(q) <= r * r).collect();
            assert_eq!(sorted, want);
        }
    }
}
