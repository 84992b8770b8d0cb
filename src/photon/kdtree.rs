//! Balanced kd-tree (Bentley) stored implicitly, with leaf buckets and compact
//! quantised positions.
//!
//! Layout: for a range [lo, hi) of more than [`LEAF`] points the median element at
//! lo + (hi − lo)/2 is the node and the halves on either side its subtrees, so no
//! pointers or split values are stored; ranges of at most [`LEAF`] points are leaves
//! scanned linearly. Each node splits on the axis of largest extent of its range.
//!
//! Positions live apart from the payload, in tree order, as one `u64` per point:
//! three 20-bit coordinates quantised over the bounding box of the whole tree (a
//! step of 1/1 048 575 of the box on each axis) and the node's split axis in two
//! spare bits. A search reads only this array until a point is inside the search
//! radius, so the payload (`points`) is touched only for candidates. Every search
//! answers on the quantised positions, which [`KdTree::position`] returns: the tree
//! is exact for the points as stored.
//!
//! Queries: k nearest neighbours within a maximum radius (a reusable max-heap of the
//! k best, no allocation per query) with a per-point filter, and a fixed-radius scan.
//! Subtrees are pruned by the incremental squared distance of Arya and Mount (the
//! sum over axes of the squared offsets to the splitting planes crossed), which is
//! tighter than the distance to the last plane alone.
//!
//! The build sorts by median selection, recursing in parallel on large ranges; the
//! tree is the same whatever the thread count.

use glam::Vec3;
use rayon::prelude::*;

/// A point type the tree can build from directly.
pub trait KdPoint: Copy + Send + Sync {
    /// Position.
    fn pos(&self) -> Vec3;
}

/// Largest range stored as a leaf bucket.
pub const LEAF: usize = 16;
const BITS: u32 = 20;
const MASK: u64 = (1 << BITS) - 1;
const AXIS_SHIFT: u32 = 60;
/// Ranges at least this large build their two subtrees in parallel.
const PAR_BUILD: usize = 1 << 14;
/// Ranges at least this large are also split in parallel.
const PAR_PARTITION: usize = 1 << 17;

/// Implicit balanced kd-tree over quantised positions.
#[derive(Clone, Debug)]
pub struct KdTree<T> {
    /// Payload in tree order (index `i` belongs to [`KdTree::position`]`(i)`).
    pub points: Vec<T>,
    /// Quantised positions and split axes in tree order.
    keys: Vec<u64>,
    /// Lower corner of the bounding box.
    origin: Vec3,
    /// Quantisation step per axis (0 on an axis where every point is equal).
    step: Vec3,
}

impl<T> Default for KdTree<T> {
    fn default() -> Self {
        KdTree { points: Vec::new(), keys: Vec::new(), origin: Vec3::ZERO, step: Vec3::ZERO }
    }
}

/// Reusable buffers for k-NN queries: the candidates (squared distance, index) and
/// the traversal stack.
#[derive(Clone, Debug, Default)]
pub struct KnnHeap {
    /// Candidates (distance², index into the tree's points), unordered.
    pub items: Vec<(f32, u32)>,
    /// Traversal stack, kept to avoid an allocation per query.
    stack: Vec<Pending>,
}

/// A subtree still to visit: its range, its incremental squared distance and the
/// per-axis offsets that make it up.
#[derive(Clone, Copy, Debug, Default)]
struct Pending {
    lo: u32,
    hi: u32,
    rd: f32,
    off: [f32; 3],
}

impl KnnHeap {
    /// Offers a candidate closer than `max_r2`. Candidates are appended; when k are
    /// held `max_r2` becomes the largest of them, and whenever 2k are held the k
    /// nearest are selected (in linear time) and `max_r2` shrinks to the k-th
    /// distance: amortised O(1) per candidate, with no per-candidate sifting.
    #[inline(always)]
    pub(crate) fn push(&mut self, k: usize, d2: f32, i: u32, max_r2: &mut f32) {
        self.items.push((d2, i));
        let n = self.items.len();
        if n == k {
            *max_r2 = self.items.iter().fold(0.0f32, |m, e| m.max(e.0));
        } else if n == 2 * k {
            *max_r2 = self.keep_nearest(k);
        }
    }

    /// Keeps the k nearest candidates; returns the k-th distance².
    #[cold]
    pub(crate) fn keep_nearest(&mut self, k: usize) -> f32 {
        // Distances are never negative, so their bits order them: an integer compare.
        self.items.select_nth_unstable_by_key(k - 1, |e| e.0.to_bits());
        self.items.truncate(k);
        self.items[k - 1].0
    }
}

/// Hints the cache to fetch the key and payload of the node covering [lo, hi), or
/// every key and payload of the leaf: the descent's loads depend on each other, so
/// fetching both children while the parent is compared hides much of the memory
/// latency (the payload is read for every point inside the search radius, which in a
/// k-NN search of 100 photons is most of the points of the leaves visited).
#[inline(always)]
fn prefetch<T>(keys: &[u64], points: &[T], lo: usize, hi: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        #[inline(always)]
        fn line<U>(x: &U) {
            // SAFETY: a prefetch never faults and `x` is a valid reference anyway.
            unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>((x as *const U).cast()) };
        }
        if hi - lo <= LEAF {
            for at in [lo, (lo + hi) / 2, hi.saturating_sub(1)] {
                if let (Some(k), Some(p)) = (keys.get(at), points.get(at)) {
                    line(k);
                    line(p);
                }
            }
        } else {
            let at = lo + (hi - lo) / 2;
            if let (Some(k), Some(p)) = (keys.get(at), points.get(at)) {
                line(k);
                line(p);
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (keys, points, lo, hi);
}

#[inline(always)]
fn coord(key: u64, axis: usize) -> u32 {
    ((key >> (BITS * axis as u32)) & MASK) as u32
}

#[inline(always)]
fn key_axis(key: u64) -> usize {
    ((key >> AXIS_SHIFT) & 3) as usize
}

/// Bounds of the quantised coordinates of a range, per axis.
fn coord_bounds(e: &[(u64, u32)]) -> ([u32; 3], [u32; 3]) {
    let mut b = ([u32::MAX; 3], [0u32; 3]);
    for &(k, _) in e {
        for a in 0..3 {
            b.0[a] = b.0[a].min(coord(k, a));
            b.1[a] = b.1[a].max(coord(k, a));
        }
    }
    b
}

/// Median split of `e` on `axis` by the key (coordinate, original index), which is
/// unique, so the median and both halves as sets are fully determined. Small ranges
/// use an in-place selection; large ones a parallel radix selection of the median
/// and a stable parallel partition, whose result does not depend on the thread count
/// either.
fn split_at_median(e: &mut [(u64, u32)], scratch: &mut [(u64, u32)], axis: usize, m: usize) {
    // One u64 compare: coordinate above, original index below.
    let key = |x: &(u64, u32)| ((coord(x.0, axis) as u64) << 32) | x.1 as u64;
    if e.len() < PAR_PARTITION {
        e.select_nth_unstable_by_key(m, key);
        return;
    }
    const R: usize = 1 << (BITS / 2);
    // The coordinate holding rank m: a histogram on the high half of its bits, then
    // on the low half within the chosen bucket.
    let hist = |sel: &(dyn Fn(u32) -> Option<usize> + Sync)| {
        e.par_chunks(1 << 14)
            .map(|ch| {
                let mut h = vec![0usize; R];
                for x in ch {
                    if let Some(b) = sel(coord(x.0, axis)) {
                        h[b] += 1;
                    }
                }
                h
            })
            .reduce(
                || vec![0usize; R],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                    a
                },
            )
    };
    let pick = |h: &[usize], rank: usize| {
        let mut below = 0;
        for (b, &c) in h.iter().enumerate() {
            if below + c > rank {
                return (b as u32, below);
            }
            below += c;
        }
        (R as u32 - 1, below)
    };
    let half = BITS / 2;
    let (hi, below_hi) = pick(&hist(&|c| Some((c >> half) as usize)), m);
    let (lo, below_lo) = pick(&hist(&|c| ((c >> half) == hi).then_some((c & (R as u32 - 1)) as usize)), m - below_hi);
    let v = (hi << half) | lo;
    // Among points at coordinate v, the median is the one of rank m − below by index.
    let mut at_v: Vec<u32> = e.par_iter().filter(|x| coord(x.0, axis) == v).map(|x| x.1).collect();
    let r = m - below_hi - below_lo;
    let (_, &mut pivot_index, _) = at_v.select_nth_unstable(r);
    let pivot = ((v as u64) << 32) | pivot_index as u64;
    // Order-preserving parallel partition; the pivot (the largest on the left) then
    // moves to m.
    if par_partition(e, scratch, |x| key(x) <= pivot) == m + 1
        && let Some(at) = e[..=m].par_iter().position_first(|x| key(x) == pivot)
    {
        e.swap(at, m);
    } else {
        // Unreachable (the ranks add up); fall back to the serial selection.
        e.select_nth_unstable_by_key(m, key);
    }
}

/// Moves the entries satisfying `pred` to the front, keeping the order on both sides
/// (so the result is unique), with every pass parallel: per-chunk counts, a scatter
/// of each chunk into its precomputed slots of `scratch` (as long as `e`), a copy
/// back. Returns the front's size.
fn par_partition(e: &mut [(u64, u32)], scratch: &mut [(u64, u32)], pred: impl Fn(&(u64, u32)) -> bool + Sync) -> usize {
    const CH: usize = 1 << 14;
    let counts: Vec<usize> = e.par_chunks(CH).map(|c| c.iter().filter(|x| pred(x)).count()).collect();
    let front: usize = counts.iter().sum();
    let out = &mut scratch[..e.len()];
    let (mut l, mut r) = out.split_at_mut(front);
    let mut slots = Vec::with_capacity(counts.len());
    for (ci, &c) in counts.iter().enumerate() {
        let len = CH.min(e.len() - ci * CH);
        let (a, rest_l) = std::mem::take(&mut l).split_at_mut(c);
        let (b, rest_r) = std::mem::take(&mut r).split_at_mut(len - c);
        (l, r) = (rest_l, rest_r);
        slots.push((a, b));
    }
    e.par_chunks(CH).zip(slots.into_par_iter()).for_each(|(src, (a, b))| {
        let (mut i, mut j) = (0, 0);
        for x in src {
            if pred(x) {
                a[i] = *x;
                i += 1;
            } else {
                b[j] = *x;
                j += 1;
            }
        }
    });
    e.par_chunks_mut(CH).zip(out.par_chunks(CH)).for_each(|(d, s)| d.copy_from_slice(s));
    front
}

/// `scratch` is a buffer as long as `e` for the parallel partitions: one allocation
/// for the whole build, because a fresh buffer per split costs page faults and, when
/// freed, TLB shootdowns on every core, which kept the build below 1.9× on 2 threads.
fn build_rec(e: &mut [(u64, u32)], scratch: &mut [(u64, u32)]) {
    let n = e.len();
    if n <= LEAF {
        return;
    }
    let (lo, hi) = if n >= PAR_PARTITION {
        e.par_chunks(1 << 14).map(coord_bounds).reduce(
            || ([u32::MAX; 3], [0; 3]),
            |a, b| {
                ([a.0[0].min(b.0[0]), a.0[1].min(b.0[1]), a.0[2].min(b.0[2])], [a.1[0].max(b.1[0]), a.1[1].max(b.1[1]), a.1[2].max(b.1[2])])
            },
        )
    } else {
        coord_bounds(e)
    };
    let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
        0
    } else if ext[1] >= ext[2] {
        1
    } else {
        2
    };
    let m = n / 2;
    split_at_median(e, scratch, axis, m);
    e[m].0 |= (axis as u64) << AXIS_SHIFT;
    let (left, rest) = e.split_at_mut(m);
    let right = &mut rest[1..];
    // Empty below the root's PAR_PARTITION threshold (then no split needs it).
    let (sl, sr) = if scratch.len() >= n {
        let (a, b) = scratch.split_at_mut(m);
        (a, &mut b[1..])
    } else {
        (&mut [][..], &mut [][..])
    };
    if n >= PAR_BUILD {
        rayon::join(|| build_rec(left, sl), || build_rec(right, sr));
    } else {
        build_rec(left, sl);
        build_rec(right, sr);
    }
}

impl<T: KdPoint> KdTree<T> {
    /// Builds the tree over `points` (at [`KdPoint::pos`]).
    pub fn build(points: Vec<T>) -> Self {
        let pos: Vec<Vec3> = points.par_iter().map(|p| p.pos()).collect();
        Self::build_with(&pos, points)
    }
}

impl<T: Copy + Send + Sync> KdTree<T> {
    /// Builds the tree over `items` at `positions` (same length; extra entries of
    /// the longer one are ignored). In parallel for large inputs; the result does not
    /// depend on the thread count.
    pub fn build_with(positions: &[Vec3], items: Vec<T>) -> Self {
        let n = positions.len().min(items.len()).min(u32::MAX as usize);
        let positions = &positions[..n];
        let (lo, hi) = positions
            .par_iter()
            .filter(|p| p.is_finite())
            .map(|&p| (p, p))
            .reduce(|| (Vec3::INFINITY, Vec3::NEG_INFINITY), |a, b| (a.0.min(b.0), a.1.max(b.1)));
        let (origin, step) = if lo.x <= hi.x { (lo, (hi - lo) / MASK as f32) } else { (Vec3::ZERO, Vec3::ZERO) };
        let frame = KdTree::<T> { points: Vec::new(), keys: Vec::new(), origin, step };
        let mut entries: Vec<(u64, u32)> = positions.par_iter().enumerate().map(|(i, &p)| (frame.quantise(p), i as u32)).collect();
        // Only ranges of at least PAR_PARTITION entries use the scratch buffer;
        // written in parallel so its pages are faulted in by both cores.
        let mut scratch: Vec<(u64, u32)> = Vec::new();
        if n >= PAR_PARTITION {
            scratch.par_extend((0..n).into_par_iter().map(|_| (0u64, 0u32)));
        }
        build_rec(&mut entries, &mut scratch);
        let points = entries.par_iter().map(|&(_, i)| items[i as usize]).collect();
        let keys = entries.into_par_iter().map(|(k, _)| k).collect();
        KdTree { points, keys, origin, step }
    }

    /// A tree over the points of several trees (positions as stored in each).
    pub fn merged(trees: &[&KdTree<T>]) -> Self {
        let total = trees.iter().map(|t| t.len()).sum();
        // Indexed parallel extends write in place: no serial concatenation.
        let (mut pos, mut items) = (Vec::with_capacity(total), Vec::with_capacity(total));
        for t in trees {
            pos.par_extend(t.keys.par_iter().map(|&k| t.decode(k)));
            items.par_extend(t.points.par_iter().copied());
        }
        Self::build_with(&pos, items)
    }
}

impl<T> KdTree<T> {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// Quantised position key (no axis bits) of `p` in this tree's frame.
    #[inline]
    fn quantise(&self, p: Vec3) -> u64 {
        let inv = Vec3::select(self.step.cmpgt(Vec3::ZERO), self.step.recip(), Vec3::ZERO);
        // Non-finite coordinates land on the box's lower corner (`as` saturates and
        // maps NaN to 0).
        let q = (p - self.origin) * inv + 0.5;
        // Truncating q + 0.5 rounds to nearest (q ≥ 0); cheaper than `round`.
        let c = |v: f32| (v as u64).min(MASK);
        c(q.x) | (c(q.y) << BITS) | (c(q.z) << (2 * BITS))
    }

    /// Where this tree stores (and would store) a point given at `p`.
    pub fn stored_position(&self, p: Vec3) -> Vec3 {
        self.decode(self.quantise(p))
    }

    #[inline(always)]
    fn decode(&self, key: u64) -> Vec3 {
        let q = Vec3::new(coord(key, 0) as f32, coord(key, 1) as f32, coord(key, 2) as f32);
        q * self.step + self.origin
    }

    /// Position of the point at tree index `i`, as stored (quantised) and searched.
    #[inline]
    pub fn position(&self, i: usize) -> Vec3 {
        self.decode(self.keys[i])
    }

    /// Bytes held by the tree: positions and payload (the struct itself aside).
    pub fn memory_bytes(&self) -> usize {
        self.keys.len() * std::mem::size_of::<u64>() + self.points.len() * std::mem::size_of::<T>()
    }

    /// Finds up to `k` nearest points to `p` within distance² `max_r2` for which
    /// `filter(payload, position)` holds. Results are in `heap.items` (unordered);
    /// returns the squared radius of the region searched: the k-th distance² if k
    /// were found, else `max_r2`.
    pub fn knn(&self, p: Vec3, k: usize, max_r2: f32, heap: &mut KnnHeap, filter: &impl Fn(&T, Vec3) -> bool) -> f32 {
        heap.items.clear();
        if k == 0 || self.keys.is_empty() {
            return max_r2;
        }
        let mut r2 = max_r2;
        let mut stack = std::mem::take(&mut heap.stack);
        stack.clear();
        stack.push(Pending { lo: 0, hi: self.keys.len() as u32, rd: 0.0, off: [0.0; 3] });
        while let Some(mut t) = stack.pop() {
            if t.rd >= r2 {
                continue;
            }
            // Descend towards p, leaving the far sides on the stack.
            loop {
                let (lo, hi) = (t.lo as usize, t.hi as usize);
                if hi - lo <= LEAF {
                    // Distances first (no branches), then the points inside the
                    // radius from a bit mask: one mispredicted branch per leaf
                    // rather than one per point. `r2` only shrinks, so the mask is a
                    // superset and each point is tested again as before.
                    let keys = &self.keys[lo..hi];
                    let mut d2s = [0.0f32; LEAF];
                    for (d, &key) in d2s.iter_mut().zip(keys) {
                        *d = (self.decode(key) - p).length_squared();
                    }
                    let mut mask = 0u32;
                    for (j, &d) in d2s[..keys.len()].iter().enumerate() {
                        mask |= ((d < r2) as u32) << j;
                    }
                    while mask != 0 {
                        let j = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let d2 = d2s[j];
                        if d2 < r2 && filter(&self.points[lo + j], self.decode(keys[j])) {
                            heap.push(k, d2, (lo + j) as u32, &mut r2);
                        }
                    }
                    break;
                }
                let m = lo + (hi - lo) / 2;
                prefetch(&self.keys, &self.points, lo, m);
                prefetch(&self.keys, &self.points, m + 1, hi);
                let key = self.keys[m];
                let axis = key_axis(key);
                let q = self.decode(key);
                let d2 = (q - p).length_squared();
                if d2 < r2 && filter(&self.points[m], q) {
                    heap.push(k, d2, m as u32, &mut r2);
                }
                let diff = p[axis] - q[axis];
                let mut far = t;
                far.rd = t.rd - t.off[axis] * t.off[axis] + diff * diff;
                far.off[axis] = diff;
                if diff < 0.0 {
                    far.lo = m as u32 + 1;
                    t.hi = m as u32;
                } else {
                    far.hi = m as u32;
                    t.lo = m as u32 + 1;
                }
                if far.rd < r2 {
                    stack.push(far);
                }
            }
        }
        heap.stack = stack;
        if heap.items.len() > k {
            r2 = heap.keep_nearest(k);
        }
        if heap.items.len() == k { r2 } else { max_r2 }
    }

    /// Calls `f(index, distance²)` for every point within distance² `r2` of `p`.
    pub fn for_each_within(&self, p: Vec3, r2: f32, f: &mut impl FnMut(usize, f32)) {
        if self.keys.is_empty() {
            return;
        }
        // Far sides pending; the depth of a median-split tree is below 64.
        let mut stack = [(0u32, 0u32); 64];
        stack[0] = (0, self.keys.len() as u32);
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let (mut lo, mut hi) = (stack[sp].0 as usize, stack[sp].1 as usize);
            loop {
                if hi - lo <= LEAF {
                    for i in lo..hi {
                        let d2 = (self.decode(self.keys[i]) - p).length_squared();
                        if d2 <= r2 {
                            f(i, d2);
                        }
                    }
                    break;
                }
                let m = lo + (hi - lo) / 2;
                let key = self.keys[m];
                let q = self.decode(key);
                let d2 = (q - p).length_squared();
                if d2 <= r2 {
                    f(m, d2);
                }
                let axis = key_axis(key);
                let d = p[axis] - q[axis];
                let (near, far) = if d < 0.0 { ((lo, m), (m + 1, hi)) } else { ((m + 1, hi), (lo, m)) };
                if d * d <= r2 {
                    stack[sp] = (far.0 as u32, far.1 as u32);
                    sp += 1;
                }
                (lo, hi) = near;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{hash_words, u32_to_unit};

    #[derive(Clone, Copy, Debug, PartialEq)]
    struct P(Vec3, u32);
    impl KdPoint for P {
        fn pos(&self) -> Vec3 {
            self.0
        }
    }

    fn rnd(k: u64, j: u64) -> f32 {
        u32_to_unit(hash_words(&[k, j]) as u32)
    }

    fn points(n: usize, on_faces: bool) -> Vec<P> {
        (0..n as u64)
            .map(|i| {
                let mut v = Vec3::new(rnd(i, 0), rnd(i, 1), rnd(i, 2)) * Vec3::new(3.0, 1.0, 0.5) - 0.25;
                if on_faces {
                    // Snap one coordinate to a face of the box (photons on walls).
                    let a = (hash_words(&[i, 9]) % 3) as usize;
                    v[a] = if rnd(i, 4) < 0.5 { -0.25 } else { 0.5 };
                }
                P(v, i as u32)
            })
            .collect()
    }

    #[test]
    fn quantised_positions_are_close_and_payload_follows() {
        let pts = points(3000, false);
        let tree = KdTree::build(pts.clone());
        assert_eq!(tree.len(), 3000);
        assert_eq!(tree.memory_bytes(), 3000 * (8 + std::mem::size_of::<P>()));
        let mut seen = vec![false; pts.len()];
        for i in 0..tree.len() {
            let P(orig, id) = tree.points[i];
            assert!(!seen[id as usize]);
            seen[id as usize] = true;
            // Half a step of 1/(2^20 − 1) of the box per axis.
            let err = (tree.position(i) - orig).abs();
            assert!(err.max_element() <= 3.0 / MASK as f32, "{orig} -> {}", tree.position(i));
        }
        // Degenerate axes (all points on one plane) are exact.
        let flat: Vec<P> = pts.iter().map(|p| P(Vec3::new(p.0.x, 0.3, p.0.z), p.1)).collect();
        let t = KdTree::build(flat);
        assert!((0..t.len()).all(|i| t.position(i).y == 0.3));
    }

    #[test]
    fn knn_equals_brute_force() {
        for on_faces in [false, true] {
            let pts = points(5000, on_faces);
            let tree = KdTree::build(pts.clone());
            // Brute force over the positions as stored.
            let stored: Vec<(Vec3, u32)> = (0..tree.len()).map(|i| (tree.position(i), tree.points[i].1)).collect();
            let mut heap = KnnHeap::default();
            for q in 0..300u64 {
                let p = Vec3::new(rnd(q, 5), rnd(q, 6), rnd(q, 7)) * 1.2 - 0.1;
                for (k, max_r) in [(1, 10.0f32), (10, 10.0), (50, 0.08), (100, 0.2), (LEAF + 1, 10.0)] {
                    let filter = |x: &P, pos: Vec3| !x.1.is_multiple_of(7) && pos.x > -0.2;
                    let r2 = tree.knn(p, k, max_r * max_r, &mut heap, &filter);
                    let mut got: Vec<u32> = heap.items.iter().map(|&(_, i)| tree.points[i as usize].1).collect();
                    got.sort_unstable();
                    let mut all: Vec<(f32, u32)> = stored
                        .iter()
                        .filter(|x| filter(&pts[x.1 as usize], x.0))
                        .map(|x| ((x.0 - p).length_squared(), x.1))
                        .filter(|&(d, _)| d < max_r * max_r)
                        .collect();
                    all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                    all.truncate(k);
                    let mut want: Vec<u32> = all.iter().map(|a| a.1).collect();
                    want.sort_unstable();
                    assert_eq!(got, want, "query {q} k {k}");
                    for &(d2, i) in &heap.items {
                        assert_eq!(d2, (tree.position(i as usize) - p).length_squared());
                    }
                    if want.len() == k {
                        assert_eq!(r2, all[k - 1].0);
                    } else {
                        assert_eq!(r2, max_r * max_r);
                    }
                }
                let mut within = Vec::new();
                tree.for_each_within(p, 0.01, &mut |i, _| within.push(tree.points[i].1));
                within.sort_unstable();
                let mut want: Vec<u32> = stored.iter().filter(|x| (x.0 - p).length_squared() <= 0.01).map(|x| x.1).collect();
                want.sort_unstable();
                assert_eq!(within, want);
            }
        }
    }

    /// Every node's range: left side ≤ median ≤ right side on the node's axis.
    fn assert_valid(t: &KdTree<P>, lo: usize, hi: usize) {
        if hi - lo <= LEAF {
            return;
        }
        let m = lo + (hi - lo) / 2;
        let a = key_axis(t.keys[m]);
        let c = coord(t.keys[m], a);
        assert!(t.keys[lo..m].iter().all(|&k| coord(k, a) <= c));
        assert!(t.keys[m + 1..hi].iter().all(|&k| coord(k, a) >= c));
        assert_valid(t, lo, m);
        assert_valid(t, m + 1, hi);
    }

    #[test]
    fn build_is_valid_and_independent_of_thread_count() {
        // Large enough for the parallel median split at the top levels; the faces
        // give many equal coordinates.
        let pts = points(3 * PAR_PARTITION, true);
        let build = |threads| rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| KdTree::build(pts.clone()));
        let (a, b) = (build(1), build(3));
        assert_eq!(a.keys, b.keys);
        assert_eq!(a.points, b.points);
        assert_valid(&a, 0, a.len());
        let mut heap = KnnHeap::default();
        for q in 0..20u64 {
            let p = Vec3::new(rnd(q, 5), rnd(q, 6), rnd(q, 7));
            let r2 = a.knn(p, 30, f32::INFINITY, &mut heap, &|_, _| true);
            let mut d: Vec<f32> = (0..a.len()).map(|i| (a.position(i) - p).length_squared()).collect();
            d.select_nth_unstable_by(29, f32::total_cmp);
            assert_eq!(r2, d[29]);
        }
        let m = KdTree::merged(&[&a, &b]);
        assert_eq!(m.len(), 2 * a.len());
        assert_valid(&m, 0, m.len());
    }

    #[test]
    fn small_and_degenerate_trees() {
        let t: KdTree<P> = KdTree::build(Vec::new());
        let mut h = KnnHeap::default();
        assert_eq!(t.knn(Vec3::ZERO, 5, 1.0, &mut h, &|_, _| true), 1.0);
        assert!(h.items.is_empty());
        t.for_each_within(Vec3::ZERO, 1.0, &mut |_, _| panic!("empty"));
        // All points equal, plus a non-finite one: no panic, every point found.
        let mut same: Vec<P> = (0..100).map(|i| P(Vec3::splat(1.0), i)).collect();
        same.push(P(Vec3::NAN, 100));
        let t = KdTree::build(same);
        t.knn(Vec3::splat(1.0), 200, f32::INFINITY, &mut h, &|_, _| true);
        assert_eq!(h.items.len(), 101);
    }
}
