//! Balanced kd-tree (Bentley) stored implicitly: for a range [lo, hi) the median
//! element at lo + (hi − lo)/2 is the node, the halves its subtrees, so no pointers
//! are stored. Each node splits on the axis of largest extent of its range, kept in
//! two spare bits of the point record. Queries: k nearest neighbours within a maximum
//! radius (a max-heap of the k best) with a per-point filter, and a fixed-radius scan.

use glam::Vec3;

/// A point type the tree can hold.
pub trait KdPoint: Copy + Send + Sync {
    /// Position.
    fn pos(&self) -> Vec3;
    /// Split axis stored in the record.
    fn axis(&self) -> usize;
    /// Stores the split axis.
    fn set_axis(&mut self, axis: usize);
}

/// Implicit balanced kd-tree.
#[derive(Clone, Debug)]
pub struct KdTree<T> {
    /// Points in tree order.
    pub points: Vec<T>,
}

impl<T> Default for KdTree<T> {
    fn default() -> Self {
        KdTree { points: Vec::new() }
    }
}

/// Reusable buffer for k-NN queries: (squared distance, index) max-heap.
#[derive(Clone, Debug, Default)]
pub struct KnnHeap {
    /// Heap entries (distance², index into the tree's points).
    pub items: Vec<(f32, u32)>,
}

impl KnnHeap {
    #[inline]
    fn push(&mut self, k: usize, d2: f32, i: u32, max_r2: &mut f32) {
        let h = &mut self.items;
        if h.len() < k {
            h.push((d2, i));
            // Sift up.
            let mut c = h.len() - 1;
            while c > 0 {
                let p = (c - 1) / 2;
                if h[p].0 >= h[c].0 {
                    break;
                }
                h.swap(p, c);
                c = p;
            }
            if h.len() == k {
                *max_r2 = h[0].0;
            }
        } else if d2 < h[0].0 {
            h[0] = (d2, i);
            // Sift down.
            let n = h.len();
            let mut p = 0;
            loop {
                let l = 2 * p + 1;
                if l >= n {
                    break;
                }
                let r = l + 1;
                let c = if r < n && h[r].0 > h[l].0 { r } else { l };
                if h[p].0 >= h[c].0 {
                    break;
                }
                h.swap(p, c);
                p = c;
            }
            *max_r2 = h[0].0;
        }
    }
}

fn build_rec<T: KdPoint>(pts: &mut [T]) {
    let n = pts.len();
    if n <= 1 {
        if let Some(p) = pts.first_mut() {
            p.set_axis(0);
        }
        return;
    }
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for p in pts.iter() {
        lo = lo.min(p.pos());
        hi = hi.max(p.pos());
    }
    let ext = hi - lo;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let m = n / 2;
    pts.select_nth_unstable_by(m, |a, b| a.pos()[axis].total_cmp(&b.pos()[axis]));
    pts[m].set_axis(axis);
    let (left, rest) = pts.split_at_mut(m);
    let right = &mut rest[1..];
    if n > 50_000 {
        rayon::join(|| build_rec(left), || build_rec(right));
    } else {
        build_rec(left);
        build_rec(right);
    }
}

impl<T: KdPoint> KdTree<T> {
    /// Builds the tree (in parallel for large inputs; the result does not depend on
    /// the thread count).
    pub fn build(mut points: Vec<T>) -> Self {
        build_rec(&mut points);
        KdTree { points }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Position of the point at tree index `i`, as the searches see it.
    #[inline]
    pub fn position(&self, i: usize) -> Vec3 {
        self.points[i].pos()
    }

    /// Bytes held by the tree (its arrays; the struct itself aside).
    pub fn memory_bytes(&self) -> usize {
        self.points.len() * std::mem::size_of::<T>()
    }

    /// Finds up to `k` nearest points to `p` within distance² `max_r2` that pass
    /// `filter`. Results are in `heap.items` (unordered); returns the squared radius
    /// of the region searched: the k-th distance² if k were found, else `max_r2`.
    pub fn knn(&self, p: Vec3, k: usize, max_r2: f32, heap: &mut KnnHeap, filter: &impl Fn(&T) -> bool) -> f32 {
        heap.items.clear();
        if k == 0 || self.points.is_empty() {
            return max_r2;
        }
        let mut r2 = max_r2;
        self.knn_rec(0, self.points.len(), p, k, &mut r2, heap, filter);
        if heap.items.len() == k { r2 } else { max_r2 }
    }

    #[allow(clippy::too_many_arguments)]
    fn knn_rec(&self, lo: usize, hi: usize, p: Vec3, k: usize, r2: &mut f32, heap: &mut KnnHeap, filter: &impl Fn(&T) -> bool) {
        if lo >= hi {
            return;
        }
        let m = lo + (hi - lo) / 2;
        let node = &self.points[m];
        let q = node.pos();
        let axis = node.axis();
        let d = p[axis] - q[axis];
        if hi - lo > 1 {
            if d < 0.0 {
                self.knn_rec(lo, m, p, k, r2, heap, filter);
            } else {
                self.knn_rec(m + 1, hi, p, k, r2, heap, filter);
            }
        }
        let d2 = (q - p).length_squared();
        if d2 < *r2 && filter(node) {
            heap.push(k, d2, m as u32, r2);
        }
        if hi - lo > 1 && d * d < *r2 {
            if d < 0.0 {
                self.knn_rec(m + 1, hi, p, k, r2, heap, filter);
            } else {
                self.knn_rec(lo, m, p, k, r2, heap, filter);
            }
        }
    }

    /// Calls `f(index, distance²)` for every point within distance² `r2` of `p`.
    pub fn for_each_within(&self, p: Vec3, r2: f32, f: &mut impl FnMut(usize, f32)) {
        let mut stack: [(u32, u32); 64] = [(0, 0); 64];
        let mut sp = 0;
        stack[0] = (0, self.points.len() as u32);
        sp += 1;
        while sp > 0 {
            sp -= 1;
            let (lo, hi) = (stack[sp].0 as usize, stack[sp].1 as usize);
            if lo >= hi {
                continue;
            }
            let m = lo + (hi - lo) / 2;
            let node = &self.points[m];
            let q = node.pos();
            let d2 = (q - p).length_squared();
            if d2 <= r2 {
                f(m, d2);
            }
            let axis = node.axis();
            let d = p[axis] - q[axis];
            // The depth of a median-split tree is log2(n) < 64.
            if d <= 0.0 || d * d <= r2 {
                stack[sp] = (lo as u32, m as u32);
                sp += 1;
            }
            if d >= 0.0 || d * d <= r2 {
                stack[sp] = (m as u32 + 1, hi as u32);
                sp += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{hash_words, u32_to_unit};

    #[derive(Clone, Copy, Debug)]
    struct P(Vec3, usize, u32);
    impl KdPoint for P {
        fn pos(&self) -> Vec3 {
            self.0
        }
        fn axis(&self) -> usize {
            self.1
        }
        fn set_axis(&mut self, a: usize) {
            self.1 = a;
        }
    }

    fn rnd(k: u64, j: u64) -> f32 {
        u32_to_unit(hash_words(&[k, j]) as u32)
    }

    fn points(n: usize, on_faces: bool) -> Vec<P> {
        (0..n as u64)
            .map(|i| {
                let mut v = Vec3::new(rnd(i, 0), rnd(i, 1), rnd(i, 2));
                if on_faces {
                    // Snap one coordinate to a face of the unit box (photons on walls).
                    let a = (hash_words(&[i, 9]) % 3) as usize;
                    v[a] = if rnd(i, 4) < 0.5 { 0.0 } else { 1.0 };
                }
                P(v, 0, i as u32)
            })
            .collect()
    }

    #[test]
    fn knn_equals_brute_force() {
        for on_faces in [false, true] {
            let pts = points(5000, on_faces);
            let tree = KdTree::build(pts.clone());
            let mut heap = KnnHeap::default();
            for q in 0..300u64 {
                let p = Vec3::new(rnd(q, 5), rnd(q, 6), rnd(q, 7));
                for (k, max_r) in [(1, 10.0f32), (10, 10.0), (50, 0.08), (100, 0.2)] {
                    let filter = |x: &P| !x.2.is_multiple_of(7);
                    let r2 = tree.knn(p, k, max_r * max_r, &mut heap, &filter);
                    let mut got: Vec<u32> = heap.items.iter().map(|&(_, i)| tree.points[i as usize].2).collect();
                    got.sort_unstable();
                    let mut all: Vec<(f32, u32)> = pts
                        .iter()
                        .filter(|x| filter(x))
                        .map(|x| ((x.0 - p).length_squared(), x.2))
                        .filter(|&(d, _)| d < max_r * max_r)
                        .collect();
                    all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                    all.truncate(k);
                    let mut want: Vec<u32> = all.iter().map(|a| a.1).collect();
                    want.sort_unstable();
                    assert_eq!(got, want, "query {q} k {k}");
                    if want.len() == k {
                        assert_eq!(r2, all[k - 1].0);
                    } else {
                        assert_eq!(r2, max_r * max_r);
                    }
                }
                let mut within = Vec::new();
                tree.for_each_within(p, 0.01, &mut |i, _| within.push(tree.points[i].2));
                within.sort_unstable();
                let mut want: Vec<u32> = pts.iter().filter(|x| (x.0 - p).length_squared() <= 0.01).map(|x| x.2).collect();
                want.sort_unstable();
                assert_eq!(within, want);
            }
        }
    }

    #[test]
    fn empty_tree() {
        let t: KdTree<P> = KdTree::build(Vec::new());
        let mut h = KnnHeap::default();
        assert_eq!(t.knn(Vec3::ZERO, 5, 1.0, &mut h, &|_| true), 1.0);
        assert!(h.items.is_empty());
    }
}
