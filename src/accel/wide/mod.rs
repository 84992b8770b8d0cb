//! `bvh4` and `bvh8`: wide bounding volume hierarchies (4 or 8 children per node).
//!
//! Build: the binary spatial-split SAH tree of `sbvh` (leaves of up to
//! [`MAX_LEAF`] triangle references), collapsed into N-wide nodes by the optimal
//! collapse of Ylitie et al. (2017): a bottom-up dynamic programme over the binary
//! tree finds, for every subtree, the least SAH cost (node visit and 4-triangle block
//! test cost 1 per unit area, the cost Embree's build statistics report) of covering
//! it with at most i = 1..N children of one node, each child a wide node or a leaf
//! of up to `LEAF_SAH_MAX` references. It replaced the greedy collapse (open the
//! child of largest area until N, plus Embree's leaf rule for left-over subtrees):
//! SAH cost 18.21 → 17.17 on Sponza, 1.04–1.06× on its inside diffuse and shadow rays.
//! Nodes are laid out depth-first.
//!
//! Node layout: child boxes as structure-of-arrays (`lo[axis][lane]`,
//! `hi[axis][lane]`), so one node test checks all N boxes in a few vector
//! instructions; the loops over lanes are written for LLVM's vectoriser and the whole
//! traversal is compiled three times, for AVX-512 and for AVX2 (chosen at run time,
//! `Simd`) and for the x86-64 baseline. Empty slots hold an inverted box, which no ray enters.
//!
//! Traversal: the near plane of each axis is chosen by the ray's direction sign once
//! per ray; box distances use the robust slab test of Ize (2013), the far distance
//! widened by 1 + 2γ₃, so rounding never culls a box that a triangle hit lies in.
//! Children are visited nearest first (for three or more hit children at the AVX-512
//! level without branches: `x86::sort_hits8`); stacked entries keep their entry
//! distance and are dropped on pop when a closer hit has been found. Shadow rays return at the
//! first hit. A leaf is a run of blocks of four triangles (one block at the default
//! [`MAX_LEAF`]), each tested together by a lane-wise copy of
//! [`crate::geometry::intersect_triangle`] (same operations, same order, so hits
//! agree bit for bit with the other accelerators), with the division deferred:
//! a division-free conservative reject drops the block first, as Embree's
//! Möller–Trumbore kernel does (measured 1.09–1.19× on the diffuse and shadow rays).
//! Per-ray plane offsets, local counters and unchecked child indexing gave another
//! 1.02–1.10× (two builds alternating in `bench accel`, 2026-11-23).
//!
//! Files: [`node`] (the float node), [`qnode`] (the quantised node of `bvh8q`),
//! [`tri_block`] (the four-triangle leaf block), [`collapse`] (binary tree to wide
//! nodes), [`ray`] (per-ray values), [`node_test`] (the box test per SIMD level,
//! portable lane loops), `x86` (the explicit x86 instructions), [`stack`],
//! [`traverse`] (the traversal loops and the [`crate::accel::Accel`] impl),
//! [`interleave`] (closest hits of a ray stream, several rays' traversals interleaved),
//! [`cpu`] (SIMD level detection, huge pages). This file: the tree type and its
//! build. The plug-ins `bvh4`, `bvh8` and `bvh8q` name its configurations.

mod collapse;
mod cpu;
mod interleave;
mod node;
mod node_test;
mod qnode;
mod ray;
mod stack;
mod traverse;
mod tri_block;
#[cfg(target_arch = "x86_64")]
mod x86;

use super::bvh::BuildParams;
use collapse::{Collapse, LEAF_BLOCKS, LEAF_SAH_MAX, collapse, dp_collapse};
use cpu::{Simd, detect_simd, huge_vec};
use glam::Vec3;
use node::{EMPTY, LEAF, Node};
use qnode::QNode;
use tri_block::TriBlock;

/// Largest leaf of the underlying binary build.
pub const MAX_LEAF: usize = 4;
/// Extra triangle references the spatial splits may add (fraction of the count;
/// Embree's default replication limit is 1.2, i.e. 0.2). 1.0 lowered the SAH cost on
/// Sponza by only 0.7 % more.
const SPATIAL: f32 = 0.2;
/// SAH node-visit cost of the underlying binary build, relative to a triangle test.
const TRAVERSAL_COST: f32 = 2.0;
/// Binary depth is at most 64 SAH levels + 32 count splits; each wide level pushes at
/// most N − 1 entries.
const MAX_DEPTH: usize = 96;

/// Wide BVH with N children per node (4 or 8).
pub struct WideBvh<const N: usize> {
    /// Float nodes (empty when quantised).
    nodes: Vec<Node<N>>,
    /// Quantised nodes (`bvh8q`; empty otherwise), same indices.
    qnodes: Vec<QNode<N>>,
    blocks: Vec<TriBlock>,
    depth: usize,
    /// Largest coordinate magnitude per axis (for the quantised nodes' slack).
    cmax: [f32; 3],
    /// Shape statistics, taken at build time.
    shape: Shape,
    /// Traversal instruction set, chosen at build time (runtime CPU detection).
    simd: Simd,
    /// Quantised nodes (`bvh8q`).
    quant: bool,
}

/// Shape of a wide BVH, for comparison with Embree's build statistics.
#[derive(Clone, Copy, Debug, Default)]
pub struct Shape {
    /// Interior nodes.
    pub nodes: usize,
    /// Used child slots over all nodes.
    pub children: usize,
    /// Fraction of child slots used.
    pub node_fill: f64,
    /// Triangle blocks (of four).
    pub blocks: usize,
    /// Fraction of block lanes holding a triangle.
    pub block_fill: f64,
    /// Σ area(node)/area(root) over interior nodes (the root counts 1).
    pub node_sah: f64,
    /// Σ area(leaf)/area(root) × blocks over leaves.
    pub leaf_sah: f64,
}

impl<const N: usize> WideBvh<N> {
    /// Builds the hierarchy over `tris`.
    pub fn build(tris: &[[Vec3; 3]]) -> Self {
        Self::build_impl(tris, false)
    }

    /// Builds the hierarchy over `tris` with quantised nodes (`bvh8q`).
    pub fn build_quantized(tris: &[[Vec3; 3]]) -> Self {
        Self::build_impl(tris, true)
    }

    fn build_impl(tris: &[[Vec3; 3]], quant: bool) -> Self {
        assert!(N == 4 || N == 8, "wide BVH supports 4 or 8 children");
        const { assert!(MAX_LEAF <= 4 * LEAF_BLOCKS && LEAF_SAH_MAX <= 4 * LEAF_BLOCKS, "a leaf must fit its triangle blocks") };
        let simd = detect_simd();
        let Some((root, order)) =
            super::sbvh::build(tris, &BuildParams { max_leaf: MAX_LEAF, traversal_cost: TRAVERSAL_COST, block: 4, bins: 16 }, SPATIAL)
        else {
            let (nodes, qnodes, blocks) = (Vec::new(), Vec::new(), Vec::new());
            return WideBvh { nodes, qnodes, blocks, depth: 0, cmax: [0.0; 3], shape: Shape::default(), simd, quant };
        };
        // Upper bounds (a leaf holds at least one triangle, a node at least two
        // children), reserved up front so the huge-page hint covers the final arrays.
        let mut out = Collapse::<N> { nodes: huge_vec(order.len()), blocks: huge_vec(order.len()), order: &order, tris, depth: 0 };
        let mut dp = Vec::new();
        dp_collapse::<N>(&root, &mut dp);
        let r = collapse::<N>(&root, 0, &dp, &mut out, 1);
        if r & LEAF != 0 {
            // A single leaf: give it a root node.
            let mut n = Node::empty();
            let b = root.bounds();
            for a in 0..3 {
                n.lo[a][0] = b.min[a];
                n.hi[a][0] = b.max[a];
            }
            n.child[0] = r;
            out.nodes.push(n);
        }
        assert!(out.depth <= MAX_DEPTH, "bvh{N}: tree depth {} exceeds the traversal stack", out.depth);
        let b = root.bounds();
        let cmax = [0, 1, 2].map(|a| b.min[a].abs().max(b.max[a].abs()));
        let mut w = WideBvh {
            nodes: out.nodes,
            qnodes: Vec::new(),
            blocks: out.blocks,
            depth: out.depth,
            cmax,
            shape: Shape::default(),
            simd,
            quant,
        };
        w.shape = w.float_shape();
        if quant {
            let mut q = huge_vec(w.nodes.len());
            q.extend(w.nodes.iter().map(|n| QNode::from_node(n, EMPTY)));
            w.qnodes = q;
            w.nodes = Vec::new();
        }
        w
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len().max(self.qnodes.len())
    }

    /// Depth of the tree in wide nodes.
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Shape statistics in the form Embree prints them (`verbose=3`): the SAH cost
    /// with node-visit and block-test costs 1, relative to the root's area.
    pub fn shape(&self) -> Shape {
        self.shape
    }

    fn float_shape(&self) -> Shape {
        let mut sh = Shape::default();
        if self.nodes.is_empty() {
            return sh;
        }
        let half = |n: &Node<N>, i: usize| {
            let d = [n.hi[0][i] - n.lo[0][i], n.hi[1][i] - n.lo[1][i], n.hi[2][i] - n.lo[2][i]];
            (d[0] * d[1] + d[1] * d[2] + d[2] * d[0]) as f64
        };
        let root = &self.nodes[0];
        let mut rb = [f32::INFINITY, f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY];
        for i in 0..N {
            if root.child[i] != EMPTY {
                for a in 0..3 {
                    rb[a] = rb[a].min(root.lo[a][i]);
                    rb[3 + a] = rb[3 + a].max(root.hi[a][i]);
                }
            }
        }
        let ra = {
            let d = [rb[3] - rb[0], rb[4] - rb[1], rb[5] - rb[2]];
            (d[0] * d[1] + d[1] * d[2] + d[2] * d[0]) as f64
        };
        sh.node_sah = 1.0;
        let mut lanes = 0usize;
        for n in &self.nodes {
            for i in 0..N {
                let c = n.child[i];
                if c == EMPTY {
                    continue;
                }
                sh.children += 1;
                let a = half(n, i) / ra;
                if c & LEAF == 0 {
                    sh.node_sah += a;
                } else {
                    let b = self.leaf(c);
                    sh.leaf_sah += a * b.len() as f64;
                    lanes += b.iter().map(|b| b.id.iter().filter(|&&i| i != u32::MAX).count()).sum::<usize>();
                }
            }
        }
        sh.nodes = self.nodes.len();
        sh.blocks = self.blocks.len();
        sh.block_fill = lanes as f64 / (4 * self.blocks.len()) as f64;
        sh.node_fill = sh.children as f64 / (N * self.nodes.len()) as f64;
        sh
    }

    /// The triangle blocks of a leaf reference.
    #[inline(always)]
    fn leaf(&self, child: u32) -> &[TriBlock] {
        let first = ((child & !LEAF) >> 3) as usize;
        let range = first..first + (child & 7) as usize + 1;
        debug_assert!(range.end <= self.blocks.len());
        // SAFETY: leaf references are made only by `collapse`, from blocks it pushed.
        unsafe { self.blocks.get_unchecked(range) }
    }
}

/// A pseudo-random number in [0, 1) for the tests, advancing `seed`.
#[cfg(test)]
fn rnd(seed: &mut u64) -> f32 {
    *seed = crate::math::hash_words(&[*seed]);
    (*seed >> 40) as f32 / (1u64 << 24) as f32
}
/// For the tests: `bvh4`, `bvh8` and `bvh8q` over `tris` at every traversal level this
/// CPU runs, the portable one included, as (level, tree).
#[cfg(test)]
fn trees_at_every_level(tris: &[[Vec3; 3]]) -> Vec<(Simd, Box<dyn crate::accel::Accel>)> {
    let levels: &[Simd] = match cpu::detect_simd() {
        Simd::Avx512 => &[Simd::Portable, Simd::Avx2, Simd::Avx512],
        Simd::Avx2 => &[Simd::Portable, Simd::Avx2],
        Simd::Portable => &[Simd::Portable],
    };
    let mut out: Vec<(Simd, Box<dyn crate::accel::Accel>)> = Vec::new();
    for &simd in levels {
        out.push((simd, Box::new(WideBvh::<4> { simd, ..WideBvh::<4>::build(tris) })));
        out.push((simd, Box::new(WideBvh::<8> { simd, ..WideBvh::<8>::build(tris) })));
        out.push((simd, Box::new(WideBvh::<8> { simd, ..WideBvh::<8>::build_quantized(tris) })));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{Accel, TraversalStats};
    use crate::geometry::Ray;

    #[test]
    fn node_sizes_are_cache_line_multiples() {
        assert_eq!(std::mem::size_of::<Node<4>>(), 128);
        assert_eq!(std::mem::size_of::<Node<8>>(), 256);
        assert_eq!(std::mem::size_of::<TriBlock>(), 160);
    }

    #[test]
    fn empty_single_and_degenerate_inputs() {
        let mut s = TraversalStats::default();
        for bvh in [Box::new(WideBvh::<4>::build(&[])) as Box<dyn Accel>, Box::new(WideBvh::<8>::build(&[]))] {
            assert!(bvh.intersect(&Ray::new(Vec3::ZERO, Vec3::X), 1.0, &mut s).is_none());
            assert!(!bvh.occluded(&Ray::new(Vec3::ZERO, Vec3::X), 1.0, &mut s));
        }
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let one = WideBvh::<4>::build(&[t]);
        let h = one.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z), 5.0, &mut s).unwrap();
        assert_eq!((h.t, h.tri), (1.0, 0));
        // Many triangles with the same centroid still build and are found; an
        // axis-parallel ray starting on a box plane is not lost to 0·∞.
        let many = WideBvh::<8>::build(&vec![t; 100]);
        assert!(many.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z), 5.0, &mut s).is_some());
        assert!(many.occluded(&Ray::new(Vec3::new(0.0, 0.3, 1.0), -Vec3::Z), 5.0, &mut s));
    }
}
