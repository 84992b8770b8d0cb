//! The optimal collapse of a binary build tree into N-wide nodes (Ylitie et al.
//! 2017): a bottom-up dynamic programme over SAH costs, then the emission of the
//! chosen nodes and leaves (laid out depth-first).

use super::node::{LEAF, Node, node_ref};
use super::tri_block::TriBlock;
use crate::accel::bvh::BuildNode;
use glam::Vec3;

/// Most triangle blocks (of four) in one leaf.
pub(super) const LEAF_BLOCKS: usize = 8;
/// Largest subtree (in references) the collapse may turn into one leaf. With the
/// greedy collapse, 8 or 16 gave 1.01–1.04× on the dragon and the sphere from
/// outside; with the optimal one, 32 builds the same Sponza tree as 16.
pub(super) const LEAF_SAH_MAX: usize = 16;

/// Output of the collapse: nodes, triangle blocks, and the build's triangle order.
pub(super) struct Collapse<'a, const N: usize> {
    pub(super) nodes: Vec<Node<N>>,
    pub(super) blocks: Vec<TriBlock>,
    pub(super) order: &'a [u32],
    pub(super) tris: &'a [[Vec3; 3]],
    pub(super) depth: usize,
}

/// The range of the build order a subtree's leaves cover (contiguous: leaves are
/// numbered depth-first).
fn span(node: &BuildNode) -> (usize, usize) {
    let mut l = node;
    while let BuildNode::Interior { children, .. } = l {
        l = &children[0];
    }
    let mut r = node;
    while let BuildNode::Interior { children, .. } = r {
        r = &children[1];
    }
    let (BuildNode::Leaf { first: a, .. }, BuildNode::Leaf { first: b, count, .. }) = (l, r) else { unreachable!() };
    (*a, b + count)
}

/// One binary node's entry of the optimal collapse (Ylitie et al. 2017): the least
/// SAH cost of covering its subtree with at most i items (leaves or wide nodes) of
/// a parent, for i = 1..=N, and the choices that reach it.
#[derive(Clone, Copy)]
pub(super) struct DpEntry<const N: usize> {
    /// cost[i − 1]: at most i items.
    cost: [f64; N],
    /// Items given to the left child where that cost splits the subtree between the
    /// children (0: the cost with one item fewer, or, for i = 1, the node itself).
    split: [u8; N],
    /// The same for the children of a wide node made from this node (N items).
    node_split: u8,
    /// As a single item the node is a leaf.
    leaf: bool,
    /// Index of the right child's entry (the left one follows this entry).
    right: u32,
}

/// Surface area in f64 (no overflow for boxes up to f32::MAX).
fn area64(b: &crate::geometry::Aabb) -> f64 {
    let d = (b.max - b.min).as_dvec3().max(glam::DVec3::ZERO);
    2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
}

/// Fills `dp` in pre-order for the subtree at `node` (SAH: node visit and block
/// test cost 1, per unit area); returns the subtree's reference span.
pub(super) fn dp_collapse<const N: usize>(node: &BuildNode, dp: &mut Vec<DpEntry<N>>) -> (usize, usize) {
    let at = dp.len();
    dp.push(DpEntry { cost: [0.0; N], split: [0; N], node_split: 0, leaf: true, right: 0 });
    let area = area64(node.bounds());
    let blocks = |n: usize| n.div_ceil(4) as f64;
    match node {
        BuildNode::Leaf { first, count, .. } => {
            dp[at].cost = [area * blocks(*count); N];
            (*first, first + count)
        }
        BuildNode::Interior { children, .. } => {
            let (a, _) = dp_collapse(&children[0], dp);
            let right = dp.len();
            let (_, b) = dp_collapse(&children[1], dp);
            let (l, r) = (dp[at + 1].cost, dp[right].cost);
            // dist[j − 1]: the least cost of covering both children with j items.
            // (k = 1 unless another split is cheaper, so that every split is valid
            // even where costs are not finite.)
            let mut dist = [f64::INFINITY; N];
            let mut dsplit = [1u8; N];
            for j in 2..=N {
                dist[j - 1] = l[0] + r[j - 2];
                for k in 2..j {
                    let c = l[k - 1] + r[j - k - 1];
                    if c < dist[j - 1] {
                        dist[j - 1] = c;
                        dsplit[j - 1] = k as u8;
                    }
                }
            }
            let inner = area + dist[N - 1];
            let small = b - a <= LEAF_SAH_MAX;
            let leaf = if small { area * blocks(b - a) } else { f64::INFINITY };
            let e = &mut dp[at];
            e.right = right as u32;
            e.node_split = dsplit[N - 1];
            e.leaf = small && leaf <= inner;
            e.cost[0] = leaf.min(inner);
            for i in 2..=N {
                if dist[i - 1] < e.cost[i - 2] {
                    e.cost[i - 1] = dist[i - 1];
                    e.split[i - 1] = dsplit[i - 1];
                } else {
                    e.cost[i - 1] = e.cost[i - 2];
                }
            }
            (a, b)
        }
    }
}

/// The items (binary nodes with their entry index) that cover `node`'s subtree with
/// at most `i` items at least cost, left to right.
fn dp_items<'a, const N: usize>(node: &'a BuildNode, at: usize, i: usize, dp: &[DpEntry<N>], out: &mut Vec<(&'a BuildNode, usize)>) {
    let BuildNode::Interior { children, .. } = node else {
        out.push((node, at));
        return;
    };
    let mut i = i;
    while i > 1 && dp[at].split[i - 1] == 0 {
        i -= 1;
    }
    if i == 1 {
        out.push((node, at));
        return;
    }
    let k = dp[at].split[i - 1] as usize;
    dp_items(&children[0], at + 1, k, dp, out);
    dp_items(&children[1], dp[at].right as usize, i - k, dp, out);
}

/// Emits the subtree at `node` (entry `at` of `dp`) as the optimal collapse chose
/// it: a leaf, or a wide node over the chosen items; returns its reference. The
/// root (depth 1) is always a node.
pub(super) fn collapse<const N: usize>(node: &BuildNode, at: usize, dp: &[DpEntry<N>], out: &mut Collapse<N>, depth: usize) -> u32 {
    out.depth = out.depth.max(depth);
    let BuildNode::Interior { children, .. } = node else {
        let BuildNode::Leaf { first, count, .. } = node else { unreachable!() };
        return emit_leaf(out, *first, first + count);
    };
    if depth > 1 && dp[at].leaf {
        let (a, b) = span(node);
        return emit_leaf(out, a, b);
    }
    let nodes = &mut out.nodes;
    let idx = nodes.len();
    nodes.push(Node::empty());
    let k = dp[at].node_split as usize;
    let mut kids = Vec::with_capacity(N);
    dp_items(&children[0], at + 1, k, dp, &mut kids);
    dp_items(&children[1], dp[at].right as usize, N - k, dp, &mut kids);
    let mut filled = Node::empty();
    for (slot, (k, _)) in kids.iter().enumerate() {
        let b = k.bounds();
        for a in 0..3 {
            filled.lo[a][slot] = b.min[a];
            filled.hi[a][slot] = b.max[a];
        }
    }
    for (slot, (k, kat)) in kids.iter().enumerate() {
        filled.child[slot] = collapse(k, *kat, dp, out, depth + 1);
    }
    out.nodes[idx] = filled;
    node_ref::<N>(idx)
}

/// Pushes the blocks of a leaf over build-order range `first..end`; its reference.
fn emit_leaf<const N: usize>(out: &mut Collapse<N>, first: usize, end: usize) -> u32 {
    let block = out.blocks.len();
    assert!(block < (1 << 27), "bvh{N}: more than 2^29 triangles are not supported");
    // Pre-split parts of one triangle that meet in a leaf are tested once.
    let mut ids = [0u32; 4 * LEAF_BLOCKS];
    let mut n = 0;
    for &id in &out.order[first..end] {
        if !ids[..n].contains(&id) {
            ids[n] = id;
            n += 1;
        }
    }
    for chunk in ids[..n].chunks(4) {
        out.blocks.push(TriBlock::new(out.tris, chunk));
    }
    LEAF | (block as u32) << 3 | (n.div_ceil(4) as u32 - 1)
}

#[cfg(test)]
mod tests {
    use super::super::cpu::Simd;
    use super::super::{Shape, WideBvh, rnd};
    use super::*;
    use crate::geometry::Aabb;

    /// A random binary build tree with `leaves` leaves of 1–4 references each
    /// (numbered in order from `first`), random leaf boxes, interior boxes the union.
    fn random_tree(leaves: usize, seed: &mut u64, first: &mut usize) -> BuildNode {
        if leaves == 1 {
            let c = Vec3::new(rnd(seed), rnd(seed), rnd(seed)) * 10.0;
            let e = Vec3::new(rnd(seed), rnd(seed), rnd(seed)) * 3.0 + Vec3::splat(0.01);
            let count = 1 + (rnd(seed) * 4.0) as usize % 4;
            *first += count;
            return BuildNode::Leaf { bounds: Aabb { min: c - e, max: c + e }, first: *first - count, count };
        }
        let l = 1 + ((rnd(seed) * (leaves - 1) as f32) as usize).min(leaves - 2);
        let a = random_tree(l, seed, first);
        let b = random_tree(leaves - l, seed, first);
        BuildNode::Interior { bounds: a.bounds().union(b.bounds()), children: Box::new([a, b]) }
    }

    /// Every way to cover `n`'s subtree with at most `max` subtrees.
    fn cuts(n: &BuildNode, max: usize) -> Vec<Vec<&BuildNode>> {
        let mut out = vec![vec![n]];
        if let BuildNode::Interior { children, .. } = n {
            for a in cuts(&children[0], max) {
                for b in cuts(&children[1], max) {
                    if a.len() + b.len() <= max {
                        out.push([a.clone(), b].concat());
                    }
                }
            }
        }
        out
    }

    /// Least SAH cost of `n` as a wide node of at most `max` children, by enumerating
    /// every cut of its children (memoised by address).
    fn brute_node(n: &BuildNode, max: usize, memo: &mut std::collections::HashMap<usize, f64>) -> f64 {
        let BuildNode::Interior { children, .. } = n else { return f64::INFINITY };
        if let Some(c) = memo.get(&(n as *const BuildNode as usize)) {
            return *c;
        }
        let mut best = f64::INFINITY;
        for a in cuts(&children[0], max) {
            for b in cuts(&children[1], max) {
                if a.len() + b.len() <= max {
                    let c: f64 = a.iter().chain(&b).map(|m| brute_item(m, max, memo)).sum();
                    best = best.min(c);
                }
            }
        }
        let c = area64(n.bounds()) + best;
        memo.insert(n as *const BuildNode as usize, c);
        c
    }

    /// Least SAH cost of `n` as one child: a leaf (if small enough) or a wide node.
    fn brute_item(n: &BuildNode, max: usize, memo: &mut std::collections::HashMap<usize, f64>) -> f64 {
        let (a, b) = span(n);
        let small = matches!(n, BuildNode::Leaf { .. }) || b - a <= LEAF_SAH_MAX;
        let leaf = if small { area64(n.bounds()) * (b - a).div_ceil(4) as f64 } else { f64::INFINITY };
        leaf.min(brute_node(n, max, memo))
    }

    /// The SAH cost of the tree `collapse` emits for `root`, in absolute area units.
    fn collapsed_cost<const N: usize>(root: &BuildNode) -> f64 {
        let refs = span(root).1;
        let order: Vec<u32> = (0..refs as u32).collect();
        let tris = vec![[Vec3::ZERO, Vec3::X, Vec3::Y]; refs];
        let mut out = Collapse::<N> { nodes: Vec::new(), blocks: Vec::new(), order: &order, tris: &tris, depth: 0 };
        let mut dp = Vec::new();
        dp_collapse::<N>(root, &mut dp);
        assert_eq!(collapse::<N>(root, 0, &dp, &mut out, 1), 0, "the root is a node");
        let (nodes, blocks, depth) = (out.nodes, out.blocks, out.depth);
        let w = WideBvh::<N> {
            nodes,
            qnodes: Vec::new(),
            blocks,
            depth,
            cmax: [0.0; 3],
            shape: Shape::default(),
            simd: Simd::Portable,
            quant: false,
        };
        let sh = w.float_shape();
        (sh.node_sah + sh.leaf_sah) * area64(root.bounds())
    }

    /// The dynamic programme finds the optimum (checked against enumerating every
    /// collapse of small random trees) and `collapse` builds exactly that tree.
    #[test]
    fn optimal_collapse_matches_brute_force() {
        let mut seed = 7u64;
        let (mut merged, mut partial) = (false, false);
        for trial in 0..60 {
            let leaves = 2 + trial % 11;
            let root = random_tree(leaves, &mut seed, &mut 0);
            let want4 = brute_node(&root, 4, &mut Default::default());
            let got4 = collapsed_cost::<4>(&root);
            assert!((got4 - want4).abs() <= 1e-5 * want4, "trial {trial} (N = 4): collapsed {got4}, optimum {want4}");
            if leaves <= 9 {
                let want8 = brute_node(&root, 8, &mut Default::default());
                let got8 = collapsed_cost::<8>(&root);
                assert!((got8 - want8).abs() <= 1e-5 * want8, "trial {trial} (N = 8): collapsed {got8}, optimum {want8}");
            }
            // The trees exercise leaves merged from several binary leaves and nodes
            // with free slots (cheaper than opening a child).
            let mut dp = Vec::new();
            dp_collapse::<4>(&root, &mut dp);
            merged |= dp.iter().zip(0..).any(|(e, i)| e.leaf && e.right != 0 && i > 0);
            partial |= dp.iter().any(|e| e.right != 0 && e.cost[3] == e.cost[2]);
        }
        assert!(merged && partial);
    }
}
