//! `bvh`: binary bounding volume hierarchy.
//!
//! Build: binned surface-area heuristic (16 bins over the centroid bounds, per axis),
//! leaves of at most 8 triangles, subtrees built in parallel with `rayon::join` (the
//! result does not depend on the thread count). The tree is then flattened depth-first
//! into 32-byte nodes (left child follows its parent) and the triangles are copied in
//! leaf order. Traversal: ordered (nearer child first, by slab entry distance) with a
//! fixed 64-entry stack; shadow rays stop at the first hit.

use super::{Accel, PreTriangle, TraversalStats, replaces, test_limit};
use crate::geometry::{Aabb, Hit, Ray, intersect_triangle};
use glam::Vec3;

/// Most SAH bins any build uses (array size).
const MAX_BINS: usize = 32;
/// The binary tree's leaf size and SAH node-visit cost (relative to a triangle test).
const BINARY_PARAMS: BuildParams = BuildParams { max_leaf: 8, traversal_cost: 1.0, block: 1, bins: 16 };
/// Build depth beyond which nodes are split by count (keeps the depth, and so the
/// traversal stack, bounded: 64 + log2(2^32) < STACK).
const MAX_SAH_DEPTH: usize = 64;
const STACK: usize = 100;

/// Flattened node: for interior nodes `count == 0` and the right child is `index`
/// (the left child is the next node); for leaves `index` is the first triangle.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Node {
    min: [f32; 3],
    index: u32,
    max: [f32; 3],
    count: u32,
}

/// Binary build tree (also collapsed into the wide trees of `bvh4`/`bvh8`). Leaves
/// index the primitive order returned by [`build_tree`].
pub(crate) enum BuildNode {
    Leaf { bounds: Aabb, first: usize, count: usize },
    Interior { bounds: Aabb, children: Box<[BuildNode; 2]> },
}

impl BuildNode {
    /// The node's box.
    pub(crate) fn bounds(&self) -> &Aabb {
        match self {
            BuildNode::Leaf { bounds, .. } | BuildNode::Interior { bounds, .. } => bounds,
        }
    }
}

/// Leaf-size limit and SAH node cost of a build.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BuildParams {
    /// Largest leaf (larger sets are always split).
    pub max_leaf: usize,
    /// Cost of a node visit relative to a triangle test.
    pub traversal_cost: f32,
    /// Triangles tested together (a leaf of n costs ⌈n / block⌉ tests), so that
    /// leaves of a SIMD-tested tree fill their blocks.
    pub block: usize,
    /// SAH bins per axis (at most 32).
    pub bins: usize,
}

impl BuildParams {
    #[inline]
    pub(crate) fn leaf_cost(&self, n: usize) -> f32 {
        n.div_ceil(self.block) as f32
    }
}

/// Builds the binary SAH tree over `tris`; returns it with the triangle order its
/// leaves index (None for an empty list).
pub(crate) fn build_tree(tris: &[[Vec3; 3]], params: BuildParams) -> Option<(BuildNode, Vec<u32>)> {
    let mut prims: Vec<Prim> = tris
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let bounds = Aabb::of_triangle(t);
            Prim { bounds, centroid: bounds.center(), index: i as u32 }
        })
        .collect();
    if prims.is_empty() {
        return None;
    }
    let root = build_rec(&mut prims, 0, 0, &params);
    Some((root, prims.iter().map(|p| p.index).collect()))
}

/// Binary BVH.
pub struct Bvh {
    nodes: Vec<Node>,
    tris: Vec<PreTriangle>,
    tri_index: Vec<u32>,
}

struct Prim {
    bounds: Aabb,
    centroid: Vec3,
    index: u32,
}

fn build_rec(prims: &mut [Prim], offset: usize, depth: usize, params: &BuildParams) -> BuildNode {
    let mut bounds = Aabb::EMPTY;
    let mut cb = Aabb::EMPTY;
    for p in prims.iter() {
        bounds = bounds.union(&p.bounds);
        cb.grow(p.centroid);
    }
    let n = prims.len();
    if n <= 2 {
        return BuildNode::Leaf { bounds, first: offset, count: n };
    }
    // Binned SAH over all three axes.
    let bins = params.bins.clamp(2, MAX_BINS);
    let ext = cb.diagonal();
    let mut best: Option<(usize, usize, f32)> = None;
    for axis in 0..3 {
        if ext[axis] <= 0.0 {
            continue;
        }
        let mut bin_bounds = [Aabb::EMPTY; MAX_BINS];
        let mut bin_count = [0usize; MAX_BINS];
        let k = bins as f32 / ext[axis];
        for p in prims.iter() {
            let b = (((p.centroid[axis] - cb.min[axis]) * k) as usize).min(bins - 1);
            bin_count[b] += 1;
            bin_bounds[b] = bin_bounds[b].union(&p.bounds);
        }
        let mut right_area = [0.0f32; MAX_BINS];
        let mut right_count = [0usize; MAX_BINS];
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        for i in (1..bins).rev() {
            acc = acc.union(&bin_bounds[i]);
            cnt += bin_count[i];
            right_area[i] = acc.area();
            right_count[i] = cnt;
        }
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        for i in 0..bins - 1 {
            acc = acc.union(&bin_bounds[i]);
            cnt += bin_count[i];
            if cnt == 0 || right_count[i + 1] == 0 {
                continue;
            }
            let cost = acc.area() * params.leaf_cost(cnt) + right_area[i + 1] * params.leaf_cost(right_count[i + 1]);
            if best.is_none_or(|b| cost < b.2) {
                best = Some((axis, i, cost));
            }
        }
    }
    let parent_area = bounds.area().max(f32::MIN_POSITIVE);
    let leaf_cost = params.leaf_cost(n);
    let split = best
        .filter(|_| depth < MAX_SAH_DEPTH)
        .filter(|&(_, _, cost)| n > params.max_leaf || params.traversal_cost + cost / parent_area < leaf_cost);
    let mid = match split {
        Some((axis, bin, _)) => {
            let k = bins as f32 / ext[axis];
            let mut i = 0;
            let mut j = n;
            while i < j {
                let b = (((prims[i].centroid[axis] - cb.min[axis]) * k) as usize).min(bins - 1);
                if b <= bin {
                    i += 1;
                } else {
                    j -= 1;
                    prims.swap(i, j);
                }
            }
            i
        }
        None if n <= params.max_leaf => return BuildNode::Leaf { bounds, first: offset, count: n },
        // All centroids coincide (or no valid split): split by count.
        None => n / 2,
    };
    let (l, r) = prims.split_at_mut(mid);
    let (a, b) = if n > 4096 {
        rayon::join(|| build_rec(l, offset, depth + 1, params), || build_rec(r, offset + mid, depth + 1, params))
    } else {
        (build_rec(l, offset, depth + 1, params), build_rec(r, offset + mid, depth + 1, params))
    };
    BuildNode::Interior { bounds, children: Box::new([a, b]) }
}

fn flatten(node: &BuildNode, nodes: &mut Vec<Node>) {
    let at = nodes.len();
    match node {
        BuildNode::Leaf { bounds, first, count } => {
            nodes.push(Node { min: bounds.min.to_array(), index: *first as u32, max: bounds.max.to_array(), count: *count as u32 })
        }
        BuildNode::Interior { bounds, children } => {
            nodes.push(Node { min: bounds.min.to_array(), index: 0, max: bounds.max.to_array(), count: 0 });
            flatten(&children[0], nodes);
            nodes[at].index = nodes.len() as u32;
            flatten(&children[1], nodes);
        }
    }
}

impl Bvh {
    /// Builds the hierarchy over `tris`.
    pub fn build(tris: &[[Vec3; 3]]) -> Self {
        let Some((root, tri_index)) = build_tree(tris, BINARY_PARAMS) else {
            return Bvh { nodes: Vec::new(), tris: Vec::new(), tri_index: Vec::new() };
        };
        let mut nodes = Vec::with_capacity(2 * tri_index.len() / 2 + 1);
        flatten(&root, &mut nodes);
        drop(root);
        let tris = tri_index.iter().map(|&i| PreTriangle::new(&tris[i as usize])).collect();
        Bvh { nodes, tris, tri_index }
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Entry distance of the ray into a node's box, or +inf on a miss.
    #[inline(always)]
    fn slab(node: &Node, o: Vec3, inv_d: Vec3, t_max: f32) -> f32 {
        let t0 = (Vec3::from_array(node.min) - o) * inv_d;
        let t1 = (Vec3::from_array(node.max) - o) * inv_d;
        let tmin = t0.min(t1).max_element().max(0.0);
        // Widened by 1 + 2γ₃ (Ize 2013): without it rounding can cull a flat box
        // (an axis-aligned wall) that the ray does hit; seen on Sponza.
        let tmax = t0.max(t1).min_element().min(t_max) * (1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5));
        // Written so a NaN (0·inf on a slab boundary) never produces a false hit skip:
        // NaN comparisons are false, and max/min above ignore NaN operands.
        if tmin <= tmax { tmin } else { f32::INFINITY }
    }
}

impl Accel for Bvh {
    fn name(&self) -> &'static str {
        "bvh"
    }

    fn intersect(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> Option<Hit> {
        stats.rays += 1;
        if self.nodes.is_empty() {
            return None;
        }
        let o = ray.o;
        let d = ray.d;
        let inv_d = d.recip();
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        let mut stack = [0u32; STACK];
        let mut sp = 0usize;
        let mut node_i = 0usize;
        stats.node_tests += 1;
        if Self::slab(&self.nodes[0], o, inv_d, t_best) == f32::INFINITY {
            return None;
        }
        loop {
            let node = &self.nodes[node_i];
            if node.count > 0 {
                let first = node.index as usize;
                for k in first..first + node.count as usize {
                    let t = &self.tris[k];
                    stats.tri_tests += 1;
                    if let Some((th, b1, b2)) = intersect_triangle(o, d, t.v0, t.e1, t.e2, test_limit(t_best, &best)) {
                        let tri = self.tri_index[k];
                        if replaces(th, tri, &best) {
                            t_best = th;
                            best = Some(Hit { t: th, tri, b1, b2 });
                        }
                    }
                }
            } else {
                let l = node_i + 1;
                let r = node.index as usize;
                stats.node_tests += 2;
                let tl = Self::slab(&self.nodes[l], o, inv_d, t_best);
                let tr = Self::slab(&self.nodes[r], o, inv_d, t_best);
                match (tl < f32::INFINITY, tr < f32::INFINITY) {
                    (true, true) => {
                        let (near, far) = if tl <= tr { (l, r) } else { (r, l) };
                        // The depth bound of the build guarantees room on the stack.
                        stack[sp] = far as u32;
                        sp += 1;
                        node_i = near;
                        continue;
                    }
                    (true, false) => {
                        node_i = l;
                        continue;
                    }
                    (false, true) => {
                        node_i = r;
                        continue;
                    }
                    (false, false) => {}
                }
            }
            // Pop, skipping nodes that can no longer beat the current closest hit.
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                let cand = stack[sp] as usize;
                stats.node_tests += 1;
                if Self::slab(&self.nodes[cand], o, inv_d, t_best) < f32::INFINITY {
                    node_i = cand;
                    break;
                }
            }
        }
    }

    fn occluded(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> bool {
        stats.shadow_rays += 1;
        if self.nodes.is_empty() {
            return false;
        }
        let o = ray.o;
        let d = ray.d;
        let inv_d = d.recip();
        let mut stack = [0u32; STACK];
        let mut sp = 0usize;
        stack[sp] = 0;
        sp += 1;
        while sp > 0 {
            sp -= 1;
            let ni = stack[sp] as usize;
            let node = &self.nodes[ni];
            stats.node_tests += 1;
            if Self::slab(node, o, inv_d, t_max) == f32::INFINITY {
                continue;
            }
            if node.count > 0 {
                let first = node.index as usize;
                for t in &self.tris[first..first + node.count as usize] {
                    stats.tri_tests += 1;
                    if intersect_triangle(o, d, t.v0, t.e1, t.e2, t_max).is_some() {
                        return true;
                    }
                }
            } else {
                stack[sp] = node.index;
                stack[sp + 1] = (ni + 1) as u32;
                sp += 2;
            }
        }
        false
    }

    fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node>() + self.tris.len() * std::mem::size_of::<PreTriangle>() + self.tri_index.len() * 4
    }
}

#[cfg(test)]
mod tests {
    use super::super::linear::Linear;
    use super::*;
    use crate::math::{hash_words, uniform_sphere};

    fn unit(h: u64) -> f32 {
        (h >> 40) as f32 / (1u64 << 24) as f32
    }

    /// A bumpy sphere with many small triangles plus a few large overlapping ones.
    fn test_mesh() -> Vec<[Vec3; 3]> {
        let mut tris = Vec::new();
        let (nu, nv) = (40, 20);
        let p = |i: usize, j: usize| {
            let th = std::f32::consts::PI * j as f32 / nv as f32;
            let ph = 2.0 * std::f32::consts::PI * i as f32 / nu as f32;
            let r = 1.0 + 0.1 * ((5.0 * ph).sin() * (3.0 * th).cos());
            Vec3::new(r * th.sin() * ph.cos(), r * th.cos(), r * th.sin() * ph.sin())
        };
        for j in 0..nv {
            for i in 0..nu {
                tris.push([p(i, j), p(i + 1, j), p(i + 1, j + 1)]);
                tris.push([p(i, j), p(i + 1, j + 1), p(i, j + 1)]);
            }
        }
        for k in 0..50u64 {
            let c = uniform_sphere([unit(hash_words(&[k, 1])), unit(hash_words(&[k, 2]))]) * 0.8;
            tris.push([c, c + Vec3::new(0.3, 0.05, 0.0), c + Vec3::new(0.0, 0.3, 0.1)]);
        }
        // An axis-aligned room of 8×8-quad walls: flat boxes, where an unwidened slab
        // test loses hits to rounding.
        for axis in 0..3 {
            for side in [-1.8f32, 1.8] {
                for (i, j) in (0..8).flat_map(|i| (0..8).map(move |j| (i, j))) {
                    let p = |a: f32, b: f32| {
                        let mut v = [0.0f32; 3];
                        v[axis] = side;
                        v[(axis + 1) % 3] = -2.0 + 0.5 * a;
                        v[(axis + 2) % 3] = -2.0 + 0.5 * b;
                        Vec3::from_array(v)
                    };
                    let (a, b) = (i as f32, j as f32);
                    tris.push([p(a, b), p(a + 1.0, b), p(a + 1.0, b + 1.0)]);
                    tris.push([p(a, b), p(a + 1.0, b + 1.0), p(a, b + 1.0)]);
                }
            }
        }
        tris
    }

    /// Every accelerator returns the closest hit of brute force (same triangle, same
    /// distance and barycentrics, the lowest index of equal hits) and the same
    /// shadow-ray answer, on rays from inside and outside.
    #[test]
    fn accels_equal_linear_on_random_rays() {
        let mut tris = test_mesh();
        // Exact copies of every third triangle, after the originals: each copy ties
        // with its original at every hit, and only the lower index may win.
        let first_copy = tris.len() as u32;
        let copies: Vec<_> = tris.iter().step_by(3).copied().collect();
        tris.extend(copies);
        let lin = Linear::build(&tris);
        for name in crate::registry::ACCELS.iter().filter(|n| **n != "none") {
            let acc = crate::registry::make_accel(name, &tris).unwrap();
            let (mut s1, mut s2) = (TraversalStats::default(), TraversalStats::default());
            let n = 100_000u64;
            let (mut hits, mut occluded, mut ties) = (0, 0, 0u64);
            for k in 0..n {
                let o = uniform_sphere([unit(hash_words(&[k, 3])), unit(hash_words(&[k, 4]))]) * (0.2 + 1.5 * unit(hash_words(&[k, 5])));
                let mut d = uniform_sphere([unit(hash_words(&[k, 6])), unit(hash_words(&[k, 7]))]);
                if k % 4 == 0 {
                    // Aim at a wall point on a grid line, where flat boxes meet.
                    let mut v = [0.0f32; 3];
                    let axis = (k / 4 % 3) as usize;
                    v[axis] = if k % 8 == 0 { 1.8 } else { -1.8 };
                    v[(axis + 1) % 3] = -2.0 + 0.5 * (hash_words(&[k, 8]) % 9) as f32;
                    v[(axis + 2) % 3] = -2.0 + 4.0 * unit(hash_words(&[k, 9]));
                    d = Vec3::from_array(v) - o;
                }
                let ray = Ray::new(o, d);
                let a = lin.intersect(&ray, f32::INFINITY, &mut s1);
                let b = acc.intersect(&ray, f32::INFINITY, &mut s2);
                match (a, b) {
                    (None, None) => {}
                    (Some(a), Some(b)) => {
                        hits += 1;
                        ties += u64::from(a.tri < first_copy && a.tri % 3 == 0);
                        // The same hit bit for bit, ties (the duplicated triangles)
                        // included: the lowest index wins whatever the traversal order.
                        assert_eq!(a, b, "{name} ray {k}");
                    }
                    _ => panic!("{name} ray {k}: linear {a:?} {name} {b:?}"),
                }
                // Shadow rays ending before, beyond, or just short of the closest hit.
                let tm = match (a, k % 3) {
                    (None, _) => 3.0,
                    (Some(h), 0) => h.t * 1.5,
                    (Some(h), 1) => h.t * 0.999,
                    (Some(h), _) => h.t * 0.5,
                };
                let occ = lin.occluded(&ray, tm, &mut s1);
                occluded += occ as u32;
                assert_eq!(occ, acc.occluded(&ray, tm, &mut s2), "{name} shadow ray {k}");
            }
            assert!(hits > n / 2 && occluded > n as u32 / 10 && u64::from(occluded) < hits, "{name}: {hits} hits, {occluded} occluded");
            // About a third of the hits are on a triangle that has a copy.
            assert!(ties * 5 > hits, "{name}: {ties} ties in {hits} hits");
            assert_eq!(s1.rays, s2.rays);
            assert!(s2.tri_tests * 10 < s1.tri_tests, "{name} should test far fewer triangles");
        }
    }

    #[test]
    fn empty_and_degenerate_inputs() {
        let bvh = Bvh::build(&[]);
        let mut s = TraversalStats::default();
        assert!(bvh.intersect(&Ray::new(Vec3::ZERO, Vec3::X), 1.0, &mut s).is_none());
        // Many triangles with the same centroid still build.
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let bvh = Bvh::build(&vec![t; 100]);
        assert!(bvh.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z), 5.0, &mut s).is_some());
    }
}
