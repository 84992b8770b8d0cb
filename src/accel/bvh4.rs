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

use super::bvh::{BuildNode, BuildParams};
use super::bvh8q::QNode;
use super::{Accel, PreTriangle, TraversalStats};
use crate::geometry::{Hit, Ray};
use glam::Vec3;
use std::mem::MaybeUninit;

/// Most triangle blocks (of four) in one leaf.
const LEAF_BLOCKS: usize = 8;
/// Largest subtree (in references) the collapse may turn into one leaf. With the
/// greedy collapse, 8 or 16 gave 1.01–1.04× on the dragon and the sphere from
/// outside; with the optimal one, 32 builds the same Sponza tree as 16.
const LEAF_SAH_MAX: usize = 16;
/// Largest leaf of the underlying binary build.
pub const MAX_LEAF: usize = 4;
/// Extra triangle references the spatial splits may add (fraction of the count;
/// Embree's default replication limit is 1.2, i.e. 0.2). 1.0 lowered the SAH cost on
/// Sponza by only 0.7 % more.
const SPATIAL: f32 = 0.2;
/// SAH node-visit cost of the underlying binary build, relative to a triangle test.
const TRAVERSAL_COST: f32 = 2.0;
/// Marks a child reference as a leaf: `LEAF | first block << 3 | (blocks − 1)`.
const LEAF: u32 = 1 << 31;
/// Unused child slot (its box is inverted, so it is never entered).
const EMPTY: u32 = u32::MAX;
/// Relative widening of far distances in the integer-compare node test
/// ([`RayPre::fast_planes`]).
const FAR_WIDEN: f32 = 1.0 + 8.0 * f32::EPSILON;
/// Far-distance widening of the robust slab test: 1 + 2γ₃ with γₙ = nε/(1 − nε).
const ROBUST: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);
/// Binary depth is at most 64 SAH levels + 32 count splits; each wide level pushes at
/// most N − 1 entries.
const MAX_DEPTH: usize = 96;

/// A wide node: N child boxes (SoA) and child references.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct Node<const N: usize> {
    pub(crate) lo: [[f32; N]; 3],
    pub(crate) hi: [[f32; N]; 3],
    pub(crate) child: [u32; N],
}

impl<const N: usize> Node<N> {
    fn empty() -> Self {
        Node { lo: [[f32::INFINITY; N]; 3], hi: [[f32::NEG_INFINITY; N]; 3], child: [EMPTY; N] }
    }
}

/// Up to four triangles of one leaf as structure-of-arrays (v0, e1 = v1 − v0,
/// e2 = v2 − v0 per axis and lane) with their scene indices; unused lanes hold a
/// zero-area triangle, which the test rejects (det = 0).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct TriBlock {
    v0: [[f32; 4]; 3],
    e1: [[f32; 4]; 3],
    e2: [[f32; 4]; 3],
    id: [u32; 4],
}

impl TriBlock {
    fn new(tris: &[[Vec3; 3]], ids: &[u32]) -> Self {
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
    fn intersect(&self, o: Vec3, d: Vec3, t_max: f32) -> (u32, [f32; 4], [f32; 4], [f32; 4]) {
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

/// 4-wide BVH (`bvh4`).
pub type Bvh4 = WideBvh<4>;

/// Per-ray values every node test reuses.
struct RayPre {
    o: [f32; 3],
    inv: [f32; 3],
    /// Per axis: the near plane is the box maximum (direction negative).
    neg: [bool; 3],
    /// Byte offsets in a node of the near (x, y, z) then far (x, y, z) plane arrays,
    /// chosen once per ray so the node test does no per-node selection.
    planes: [usize; 6],
    /// The same for quantised nodes (byte arrays qlo[3][N] then qhi[3][N]; set
    /// only for them).
    qplanes: [usize; 6],
    /// o·inv per axis, for the fused-multiply-subtract form of the AVX2 node test.
    oi: [f32; 3],
    /// Absolute error bound of that form's distances: rounding o·inv loses up to
    /// ulp(|o·inv|), which can exceed the relative slack of [`ROBUST`] for boxes close
    /// to an origin far from the world origin; 0 where o·inv is not finite (those
    /// lanes become NaN and are ignored, which only ever keeps a box).
    slack: f32,
    /// Near-plane distance t = plane·`near_c` − `near_b` and far-plane distance
    /// plane·`far_c` − `far_b` per axis, for the integer-compare node test (see
    /// [`RayPre::fast_planes`]); set only for float nodes.
    near_c: [f32; 3],
    near_b: [f32; 3],
    far_c: [f32; 3],
    far_b: [f32; 3],
}

impl RayPre {
    #[inline(always)]
    fn new<const N: usize>(ray: &Ray) -> Self {
        let inv = ray.d.recip().to_array();
        let o = ray.o.to_array();
        let oi = [o[0] * inv[0], o[1] * inv[1], o[2] * inv[2]];
        let big = oi.iter().filter(|v| v.is_finite()).fold(0.0f32, |m, v| m.max(v.abs()));
        let neg = [inv[0] < 0.0, inv[1] < 0.0, inv[2] < 0.0];
        // Node<N> holds lo[3][N] then hi[3][N] (repr(C)).
        let lo = |a: usize| a * N * 4;
        let hi = |a: usize| (3 + a) * N * 4;
        let pick = |a: usize, near: bool| if neg[a] == near { hi(a) } else { lo(a) };
        let planes = [pick(0, true), pick(1, true), pick(2, true), pick(0, false), pick(1, false), pick(2, false)];
        let z = [0.0; 3];
        RayPre { o, inv, neg, planes, qplanes: [0; 6], oi, slack: 4.0 * f32::EPSILON * big, near_c: z, near_b: z, far_c: z, far_b: z }
    }

    /// Plane-distance coefficients for the node test that compares distances as
    /// integers (`x86::node_test8`), given the largest coordinate magnitude of the
    /// scene per axis.
    ///
    /// An axis whose inverse direction is infinite, or so large that a product could
    /// overflow (|inv|·max(|o|, scene) ≥ 2^100), gets coefficient 0 and offsets ±∞:
    /// near distance −∞ and far +∞, so it never culls (as the NaN lanes of the float
    /// test). Otherwise the near offset is raised and the far one lowered by
    /// s = 16 ε·|o·inv| (plus the smallest normal, for underflow), and the far
    /// coefficient and offset are scaled by 1 + 8 ε. With u = ε/2 and T the exact
    /// distance: near ≤ T(1 + 2u + u²), because s exceeds the rounding of o·inv and
    /// of the offset; far ≥ T(1 + 13u) for T ≥ 0 (and > 0 at T = 0), because s
    /// exceeds the rounding of o·inv, of both scaled constants and of plane·coef
    /// (≤ 4u|o·inv| + u|T|). So a box the ray crosses on [0, t_max] is never culled,
    /// and the entry distance never exceeds T(1 + 2u + u²), within the traversal's
    /// culling margin [`ROBUST`]. Finite values keep NaN out of every non-empty
    /// lane, which the integer comparison needs.
    fn fast_planes(&mut self, cmax: [f32; 3]) {
        for (a, c) in cmax.iter().enumerate() {
            let m = self.o[a].abs().max(*c);
            // Also true for NaN (∞·0).
            let parallel = (self.inv[a].abs() * m).partial_cmp(&2f32.powi(100)) != Some(std::cmp::Ordering::Less);
            if parallel {
                (self.near_c[a], self.near_b[a], self.far_c[a], self.far_b[a]) = (0.0, f32::INFINITY, 0.0, f32::NEG_INFINITY);
                continue;
            }
            let s = 16.0 * f32::EPSILON * self.oi[a].abs() + f32::MIN_POSITIVE;
            self.near_c[a] = self.inv[a];
            self.near_b[a] = self.oi[a] + s;
            self.far_c[a] = self.inv[a] * FAR_WIDEN;
            self.far_b[a] = self.oi[a] * FAR_WIDEN - s;
        }
    }
}

/// Tests the ray against all N child boxes; returns the hit mask and entry distances.
///
/// A zero direction component makes the inverse ±∞ and a slab plane through the
/// origin gives 0·∞ = NaN; every fold below keeps its accumulator when the new value
/// is NaN (`x < acc` is false), so that axis is ignored, as it should be for a ray
/// lying in the slab. Compiled as plain compare-and-select, each fold is one
/// `minps`/`maxps`.
#[inline(always)]
fn node_test<const N: usize, const L: u8>(n: &Node<N>, r: &RayPre, t_max: f32, tmin: &mut [f32; N]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        let base = n as *const Node<N> as *const u8;
        // In bounds: every offset addresses one of the node's six plane arrays.
        let planes = r.planes.map(|off| base.wrapping_add(off) as *const f32);
        if N == 8 && L == AVX512 {
            // SAFETY: L is AVX512 only inside the AVX-512 traversal (CPU checked at
            // build), and every plane array holds N = 8 floats, as does `tmin`.
            return unsafe { x86::node_test8(&planes, r, t_max, tmin.as_mut_ptr()) };
        }
        if N == 8 && L == AVX2 {
            // SAFETY: L is AVX2 only inside the AVX2 traversal (CPU checked at build),
            // and every plane array holds N = 8 floats, as does `tmin`.
            return unsafe { x86::node_test8_float(&planes, r, t_max, tmin.as_mut_ptr()) };
        }
        if N == 4 && L >= AVX2 {
            // SAFETY: as above, with N = 4.
            return unsafe { x86::node_test4_fma(&planes, r, t_max, tmin.as_mut_ptr()) };
        }
        if N == 4 {
            // SAFETY: SSE is part of x86-64; every plane array holds N = 4 floats.
            return unsafe { x86::node_test4(&planes, r, t_max, tmin.as_mut_ptr()) };
        }
    }
    // Plane k: near (k < 3) or far on axis k % 3.
    let plane = |k: usize| if r.neg[k % 3] == (k < 3) { &n.hi[k % 3] } else { &n.lo[k % 3] };
    slab_lanes::<N>(|k, i| (plane(k)[i] - r.o[k % 3]) * r.inv[k % 3], t_max, 0.0, tmin)
}

/// The slab test of N boxes, lane by lane, given the plane distances `t(k, i)`
/// (plane k: near x, y, z, far x, y, z; lane i): entry distances to `tmin`, the hit
/// mask returned, the far distance widened by [`ROBUST`] and `slack`.
#[inline(always)]
fn slab_lanes<const N: usize>(t: impl Fn(usize, usize) -> f32, t_max: f32, slack: f32, tmin: &mut [f32; N]) -> u32 {
    let mut hit = [false; N];
    for i in 0..N {
        let (tnx, tny, tnz, tfx, tfy, tfz) = (t(0, i), t(1, i), t(2, i), t(3, i), t(4, i), t(5, i));
        let mut t0 = 0.0f32;
        t0 = if tnx > t0 { tnx } else { t0 };
        t0 = if tny > t0 { tny } else { t0 };
        t0 = if tnz > t0 { tnz } else { t0 };
        let mut t1 = t_max;
        t1 = if tfx < t1 { tfx } else { t1 };
        t1 = if tfy < t1 { tfy } else { t1 };
        t1 = if tfz < t1 { tfz } else { t1 };
        tmin[i] = t0;
        hit[i] = t0 <= t1 * ROBUST + slack;
    }
    let mut mask = 0u32;
    for (i, h) in hit.iter().enumerate() {
        mask |= (*h as u32) << i;
    }
    mask
}

/// [`node_test`] for a quantised node: plane distance (origin − o)/d + q·(scale/d).
/// The distances may err by the ray's slack (which then includes
/// [`QNode::slack`]) but never cull a box the ray crosses.
#[inline(always)]
fn qnode_test<const N: usize, const L: u8>(n: &QNode<N>, r: &RayPre, t_max: f32, tmin: &mut [f32; N]) -> u32 {
    let mut s = [0.0f32; 3];
    let mut b = [0.0f32; 3];
    for a in 0..3 {
        s[a] = n.scale[a] * r.inv[a];
        b[a] = (n.origin[a] - r.o[a]) * r.inv[a];
    }
    let base = n as *const QNode<N> as *const u8;
    #[cfg(target_arch = "x86_64")]
    if N == 8 && L >= AVX2 {
        let planes = r.qplanes.map(|off| base.wrapping_add(off));
        // SAFETY: L ≥ AVX2 only inside the AVX2 and AVX-512 traversals (CPU checked at build);
        // every plane pointer addresses 8 bytes of the node, `tmin` holds 8 floats.
        return unsafe { x86::qnode_test8(&planes, &s, &b, r, t_max, tmin.as_mut_ptr()) } & n.valid;
    }
    // SAFETY: every offset addresses one of the node's six N-byte plane arrays.
    let plane = |k: usize| unsafe { &*(base.add(r.qplanes[k]) as *const [u8; N]) };
    slab_lanes::<N>(|k, i| (plane(k)[i] as f32).mul_add(s[k % 3], b[k % 3]), t_max, r.slack, tmin) & n.valid
}

/// The node test with explicit vector instructions: the lane loop above compiles to
/// the same arithmetic, but LLVM turns its hit mask into a chain of packs instead of
/// one `movmskps`, which cost ~15 % of the traversal.
#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{FAR_WIDEN, ROBUST, RayPre};
    use std::arch::x86_64::*;

    /// 8 lanes with AVX2/FMA, compared as floats (the AVX2 level: there the integer
    /// form of [`node_test8`] measured 0.94–1.0×): t = plane·inv − o·inv in one
    /// fused operation per plane, the far distance widened by [`ROBUST`] and the
    /// ray's absolute `slack`. Safety: as [`node_test8`].
    #[inline(always)]
    pub(super) unsafe fn node_test8_float(planes: &[*const f32; 6], r: &RayPre, t_max: f32, tmin: *mut f32) -> u32 {
        // SAFETY: the caller's guarantees (AVX2/FMA; 8 floats behind every pointer).
        unsafe {
            slabs8(
                |k| {
                    let a = k % 3;
                    _mm256_fmsub_ps(_mm256_loadu_ps(planes[k]), _mm256_set1_ps(r.inv[a]), _mm256_set1_ps(r.oi[a]))
                },
                r,
                t_max,
                tmin,
            )
        }
    }

    /// 8 lanes with AVX2/FMA: t = plane·c − b in one fused operation per plane
    /// (measured 1.1–1.3× faster traversal than subtract-then-multiply), with the
    /// widening folded into c and b ([`RayPre::fast_planes`]). The distances are
    /// compared as signed integers, which order non-negative floats as floats do and
    /// put every negative float below +0: the entry distance max(near, +0) and a
    /// negative far distance (box behind the origin) come out right, and the folds
    /// form trees of integer min/max (shorter than the float test's chain, and
    /// compiled with AVX-512 into a mask-register compare; this is the AVX-512 level's
    /// test). An empty lane (box +∞…−∞) gets entry +∞ and exit −∞ from any axis with
    /// a non-zero coefficient; a parallel axis (coefficient 0) gives 0·∞ = NaN, which
    /// the integer folds never prefer to those, and if all three are parallel, NaN
    /// entry and exit still fail the comparison, so it is never entered. Safety: the CPU must
    /// support AVX2 and FMA; `planes` (near x, y, z, far x, y, z) and `tmin` must
    /// point to 8 floats each.
    #[inline(always)]
    pub(super) unsafe fn node_test8(planes: &[*const f32; 6], r: &RayPre, t_max: f32, tmin: *mut f32) -> u32 {
        // SAFETY: the caller's guarantees (AVX2/FMA; 8 floats behind every pointer).
        unsafe {
            let t = |k: usize| {
                let a = k % 3;
                let (c, b) = if k < 3 { (r.near_c[a], r.near_b[a]) } else { (r.far_c[a], r.far_b[a]) };
                _mm256_castps_si256(_mm256_fmsub_ps(_mm256_loadu_ps(planes[k]), _mm256_set1_ps(c), _mm256_set1_ps(b)))
            };
            let t0 = _mm256_max_epi32(_mm256_max_epi32(t(0), t(1)), _mm256_max_epi32(t(2), _mm256_setzero_si256()));
            let t1 = _mm256_min_epi32(
                _mm256_min_epi32(t(3), t(4)),
                _mm256_min_epi32(t(5), _mm256_set1_epi32((t_max * FAR_WIDEN).to_bits() as i32)),
            );
            _mm256_storeu_si256(tmin as *mut __m256i, t0);
            !_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(t0, t1))) as u32 & 0xff
        }
    }

    /// Orders the hit children of a node with three or more hits, without branches:
    /// the nearest child is returned (a minimum over keys distance | lane), and all
    /// hit children go to `out` farthest first (a bitonic network over the same keys,
    /// non-hit lanes last), so the caller counts the first popcount − 1 of them as
    /// pushed. Stored distances have their 3 low bits cleared (at most 7 ulps
    /// smaller, which only ever keeps an entry on pop). Safety: AVX2 and AVX-512
    /// F/VL; `tmin` (non-negative distances, as `node_test8` leaves them) and `child`
    /// must point to 8 values.
    #[inline(always)]
    pub(super) unsafe fn sort_hits8(
        tmin: *const f32,
        mask: u32,
        child: *const u32,
        out: &mut [std::mem::MaybeUninit<super::Entry>; 8],
    ) -> u32 {
        // SAFETY: the caller's guarantees; `out` holds 8 entries of 8 bytes.
        unsafe {
            let k = mask as __mmask8;
            let t = _mm256_loadu_si256(tmin as *const __m256i);
            let key = _mm256_or_si256(_mm256_and_si256(t, _mm256_set1_epi32(!7)), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
            let m = _mm256_mask_blend_epi32(k, _mm256_set1_epi32(i32::MAX), key);
            let m = _mm256_min_epi32(m, _mm256_permute4x64_epi64::<0x4E>(m));
            let m = _mm256_min_epi32(m, _mm256_shuffle_epi32::<0x4E>(m));
            let m = _mm256_min_epi32(m, _mm256_shuffle_epi32::<0xB1>(m));
            let nearest = *child.add((_mm256_cvtsi256_si32(m) & 7) as usize);
            // Bitonic sort, descending: per layer, each lane meets its partner and
            // keeps the larger key where the mask bit is set.
            let mut v = _mm256_mask_blend_epi32(k, _mm256_set1_epi32(-1), key);
            macro_rules! layer {
                ($partner:expr, $max:expr) => {
                    let p = $partner;
                    v = _mm256_mask_blend_epi32($max, _mm256_min_epi32(v, p), _mm256_max_epi32(v, p));
                };
            }
            layer!(_mm256_shuffle_epi32::<0xB1>(v), 0x99);
            layer!(_mm256_shuffle_epi32::<0x4E>(v), 0xc3);
            layer!(_mm256_shuffle_epi32::<0xB1>(v), 0xa5);
            layer!(_mm256_permute4x64_epi64::<0x4E>(v), 0x0f);
            layer!(_mm256_shuffle_epi32::<0x4E>(v), 0x33);
            layer!(_mm256_shuffle_epi32::<0xB1>(v), 0x55);
            let cs = _mm256_permutevar8x32_epi32(_mm256_loadu_si256(child as *const __m256i), _mm256_and_si256(v, _mm256_set1_epi32(7)));
            let ts = _mm256_and_si256(v, _mm256_set1_epi32(!7));
            let lo = _mm256_unpacklo_epi32(cs, ts);
            let hi = _mm256_unpackhi_epi32(cs, ts);
            let p = out.as_mut_ptr() as *mut __m256i;
            _mm256_storeu_si256(p, _mm256_permute2x128_si256::<0x20>(lo, hi));
            _mm256_storeu_si256(p.add(1), _mm256_permute2x128_si256::<0x31>(lo, hi));
            nearest
        }
    }

    /// 8 quantised lanes with AVX2/FMA: bytes widened to floats, then one fused
    /// multiply-add per plane. Safety: the CPU must support AVX2 and FMA; `planes`
    /// must point to 8 bytes each and `tmin` to 8 floats.
    #[inline(always)]
    pub(super) unsafe fn qnode_test8(planes: &[*const u8; 6], s: &[f32; 3], b: &[f32; 3], r: &RayPre, t_max: f32, tmin: *mut f32) -> u32 {
        // SAFETY: the caller's guarantees (AVX2/FMA; 8 bytes behind every plane
        // pointer, 8 floats at `tmin`).
        unsafe {
            slabs8(
                |k| {
                    let a = k % 3;
                    let q = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(planes[k] as *const __m128i)));
                    _mm256_fmadd_ps(q, _mm256_set1_ps(s[a]), _mm256_set1_ps(b[a]))
                },
                r,
                t_max,
                tmin,
            )
        }
    }

    /// The slab test of 8 boxes given the plane distances `t(k)` (near x, y, z, far
    /// x, y, z): entry distances to `tmin`, the hit mask returned, the far distance
    /// widened by [`ROBUST`] and the ray's slack. Safety: AVX2 and FMA; `tmin` must
    /// point to 8 floats.
    #[inline(always)]
    unsafe fn slabs8(t: impl Fn(usize) -> __m256, r: &RayPre, t_max: f32, tmin: *mut f32) -> u32 {
        unsafe {
            let mut t0 = _mm256_setzero_ps();
            let mut t1 = _mm256_set1_ps(t_max);
            for a in 0..3 {
                // max/min return the second operand when either is NaN: the accumulator.
                t0 = _mm256_max_ps(t(a), t0);
                t1 = _mm256_min_ps(t(3 + a), t1);
            }
            t1 = _mm256_fmadd_ps(t1, _mm256_set1_ps(ROBUST), _mm256_set1_ps(r.slack));
            _mm256_storeu_ps(tmin, t0);
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1)) as u32
        }
    }

    /// 4 lanes with FMA, as [`node_test8`]. Safety: the CPU must support FMA;
    /// `planes` and `tmin` must point to 4 floats each.
    #[inline(always)]
    pub(super) unsafe fn node_test4_fma(planes: &[*const f32; 6], r: &RayPre, t_max: f32, tmin: *mut f32) -> u32 {
        unsafe {
            let mut t0 = _mm_setzero_ps();
            let mut t1 = _mm_set1_ps(t_max);
            for a in 0..3 {
                let oi = _mm_set1_ps(r.oi[a]);
                let inv = _mm_set1_ps(r.inv[a]);
                t0 = _mm_max_ps(_mm_fmsub_ps(_mm_loadu_ps(planes[a]), inv, oi), t0);
                t1 = _mm_min_ps(_mm_fmsub_ps(_mm_loadu_ps(planes[3 + a]), inv, oi), t1);
            }
            t1 = _mm_fmadd_ps(t1, _mm_set1_ps(ROBUST), _mm_set1_ps(r.slack));
            _mm_storeu_ps(tmin, t0);
            _mm_movemask_ps(_mm_cmple_ps(t0, t1)) as u32
        }
    }

    /// 4 lanes with SSE (always present on x86-64). Safety: `planes` and `tmin` must
    /// point to 4 floats each.
    #[inline(always)]
    pub(super) unsafe fn node_test4(planes: &[*const f32; 6], r: &RayPre, t_max: f32, tmin: *mut f32) -> u32 {
        unsafe {
            let mut t0 = _mm_setzero_ps();
            let mut t1 = _mm_set1_ps(t_max);
            for a in 0..3 {
                let o = _mm_set1_ps(r.o[a]);
                let inv = _mm_set1_ps(r.inv[a]);
                let tn = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(planes[a]), o), inv);
                let tf = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(planes[3 + a]), o), inv);
                t0 = _mm_max_ps(tn, t0);
                t1 = _mm_min_ps(tf, t1);
            }
            t1 = _mm_mul_ps(t1, _mm_set1_ps(ROBUST));
            _mm_storeu_ps(tmin, t0);
            _mm_movemask_ps(_mm_cmple_ps(t0, t1)) as u32
        }
    }
}

/// Traversal stack of (child reference, entry distance); never read beyond what was
/// pushed.
struct Stack<const C: usize> {
    items: [MaybeUninit<Entry>; C],
    len: usize,
}

/// A stack entry, laid out for vector stores (`x86::sort_hits8`).
#[derive(Clone, Copy)]
#[repr(C)]
struct Entry {
    child: u32,
    t: f32,
}

impl<const C: usize> Stack<C> {
    #[inline(always)]
    fn new() -> Self {
        Stack { items: [const { MaybeUninit::uninit() }; C], len: 0 }
    }
    #[inline(always)]
    fn push(&mut self, v: (u32, f32)) {
        // Bounds-checked: the build bounds the depth, so this never fails.
        self.items[self.len].write(Entry { child: v.0, t: v.1 });
        self.len += 1;
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32)> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every index below `len` was written by `push` or `top8` before.
        let e = unsafe { self.items[self.len].assume_init() };
        Some((e.child, e.t))
    }
    /// The next 8 slots, for a vector store of which the caller then counts `n`
    /// (≤ 8) entries with `grow`.
    #[inline(always)]
    fn top8(&mut self) -> &mut [MaybeUninit<Entry>; 8] {
        // Bounds-checked: the build bounds the depth (7 per level + 8), so this never fails.
        (&mut self.items[self.len..self.len + 8]).try_into().unwrap()
    }
    #[inline(always)]
    fn grow(&mut self, n: usize) {
        debug_assert!(self.len + n <= C);
        self.len += n;
    }
}

/// Stack capacity for the widest tree (N = 8).
const STACK: usize = 7 * MAX_DEPTH + 8;

/// Output of the collapse: nodes, triangle blocks, and the build's triangle order.
struct Collapse<'a, const N: usize> {
    nodes: Vec<Node<N>>,
    blocks: Vec<TriBlock>,
    order: &'a [u32],
    tris: &'a [[Vec3; 3]],
    depth: usize,
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
struct DpEntry<const N: usize> {
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
fn dp_collapse<const N: usize>(node: &BuildNode, dp: &mut Vec<DpEntry<N>>) -> (usize, usize) {
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
fn collapse<const N: usize>(node: &BuildNode, at: usize, dp: &[DpEntry<N>], out: &mut Collapse<N>, depth: usize) -> u32 {
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
    idx as u32
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

/// The closest-hit and any-hit entry points of one traversal level, compiled with
/// that level's target features (the `#[inline(always)]` traversal is compiled
/// into each).
macro_rules! simd_entries {
    ($intersect:ident, $occluded:ident, $level:ident, $features:literal) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $intersect(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> Option<Hit> {
            if self.quant {
                self.intersect_impl::<$level, true>(ray, t_max, stats)
            } else {
                self.intersect_impl::<$level, false>(ray, t_max, stats)
            }
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $occluded(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> bool {
            if self.quant {
                self.occluded_impl::<$level, true>(ray, t_max, stats)
            } else {
                self.occluded_impl::<$level, false>(ray, t_max, stats)
            }
        }
    };
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

    #[inline(always)]
    fn intersect_impl<const L: u8, const Q: bool>(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> Option<Hit> {
        stats.rays += 1;
        if self.nodes.is_empty() && self.qnodes.is_empty() {
            return None;
        }
        let r = self.ray_pre::<L, Q>(ray);
        let (o, d) = (ray.o, ray.d);
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        let mut stack = Stack::<STACK>::new();
        let mut cur = 0u32;
        let mut tmin = [0.0f32; N];
        // Counted locally (kept in registers), added to `stats` on return.
        let (mut node_tests, mut tri_tests) = (0u64, 0u64);
        loop {
            if cur & LEAF == 0 {
                let (mut mask, child) = self.visit::<L, Q>(cur, &r, t_best, &mut tmin);
                node_tests += N as u64;
                if mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    if mask == 0 {
                        cur = child[i];
                        // Requests all of the child's lines at once (the node test
                        // loads its planes in order and the child references last; a
                        // multi-block leaf is tested block by block), as Embree does:
                        // 1.05–1.10× on the DRAM-bound sphere-inside diffuse rays,
                        // neutral on the dragon and Sponza.
                        self.prefetch::<Q>(cur);
                        continue;
                    }
                    let j = mask.trailing_zeros() as usize;
                    if mask & (mask - 1) == 0 {
                        // Two (the common case): no sort. Both are prefetched before the
                        // comparison (which waits for the entry distances the node test
                        // stored), so that the nearer one's lines are already on their way.
                        self.prefetch::<Q>(child[i]);
                        self.prefetch::<Q>(child[j]);
                        let (near, far) = if tmin[j] < tmin[i] { (j, i) } else { (i, j) };
                        stack.push((child[far], tmin[far]));
                        cur = child[near];
                        continue;
                    }
                    // Three or more: visit the nearest now, stack the rest farthest first.
                    #[cfg(target_arch = "x86_64")]
                    if N == 8 && L == AVX512 && !Q {
                        let full = mask | 1 << i;
                        // SAFETY: L is AVX512 only inside the AVX-512 traversal (CPU checked
                        // at build); `tmin` and `child` hold 8 values, the node test left
                        // non-negative distances in `tmin`.
                        cur = unsafe { x86::sort_hits8(tmin.as_ptr(), full, child.as_ptr(), stack.top8()) };
                        stack.grow(full.count_ones() as usize - 1);
                        // Every hit child but the lowest lane's: prefetching all of them
                        // (the nearest is loaded next anyway) measured 0.94–0.97× on the
                        // Sponza-inside diffuse rays.
                        let mut m = mask;
                        while m != 0 {
                            self.prefetch::<Q>(child[m.trailing_zeros() as usize]);
                            m &= m - 1;
                        }
                        continue;
                    }
                    let mut hits: [(u32, f32); N] = [(0, 0.0); N];
                    hits[0] = (child[i], tmin[i]);
                    let mut k = 1;
                    while mask != 0 {
                        let i = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let e = (child[i], tmin[i]);
                        // Insertion sort, descending by distance.
                        let mut j = k;
                        while j > 0 && hits[j - 1].1 < e.1 {
                            hits[j] = hits[j - 1];
                            j -= 1;
                        }
                        hits[j] = e;
                        k += 1;
                    }
                    for h in &hits[..k - 1] {
                        self.prefetch::<Q>(h.0);
                        stack.push(*h);
                    }
                    cur = hits[k - 1].0;
                    continue;
                }
            } else {
                for block in self.leaf(cur) {
                    tri_tests += 4;
                    let (mut mask, t, u, v) = block.intersect(o, d, t_best);
                    if mask != 0 {
                        // The first lane of smallest t, as a sequential loop would pick.
                        let mut j = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        while mask != 0 {
                            let k = mask.trailing_zeros() as usize;
                            mask &= mask - 1;
                            if t[k] < t[j] {
                                j = k;
                            }
                        }
                        t_best = t[j];
                        best = Some(Hit { t: t[j], tri: block.id[j], b1: u[j], b2: v[j] });
                    }
                }
            }
            // Pop the next entry that can still hold a closer hit.
            loop {
                match stack.pop() {
                    None => {
                        stats.node_tests += node_tests;
                        stats.tri_tests += tri_tests;
                        return best;
                    }
                    Some((c, t)) if t <= t_best * ROBUST + r.slack => {
                        cur = c;
                        break;
                    }
                    Some(_) => {}
                }
            }
        }
    }

    #[inline(always)]
    fn occluded_impl<const L: u8, const Q: bool>(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> bool {
        stats.shadow_rays += 1;
        if self.nodes.is_empty() && self.qnodes.is_empty() {
            return false;
        }
        let r = self.ray_pre::<L, Q>(ray);
        let (o, d) = (ray.o, ray.d);
        let mut stack = Stack::<STACK>::new();
        let mut cur = 0u32;
        let mut tmin = [0.0f32; N];
        // Counted locally (kept in registers), added to `stats` on return.
        let (mut node_tests, mut tri_tests) = (0u64, 0u64);
        loop {
            if cur & LEAF == 0 {
                let (mut mask, child) = self.visit::<L, Q>(cur, &r, t_max, &mut tmin);
                node_tests += N as u64;
                if mask != 0 {
                    // Any order finds an occluder; go down the first, stack the others.
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    while mask != 0 {
                        let j = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        stack.push((child[j], 0.0));
                    }
                    cur = child[i];
                    continue;
                }
            } else {
                for block in self.leaf(cur) {
                    tri_tests += 4;
                    if block.intersect(o, d, t_max).0 != 0 {
                        stats.node_tests += node_tests;
                        stats.tri_tests += tri_tests;
                        return true;
                    }
                }
            }
            match stack.pop() {
                None => {
                    stats.node_tests += node_tests;
                    stats.tri_tests += tri_tests;
                    return false;
                }
                Some((c, _)) => cur = c,
            }
        }
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

    /// Per-ray values; with quantised nodes the slack also covers their rounding.
    #[inline(always)]
    fn ray_pre<const L: u8, const Q: bool>(&self, ray: &Ray) -> RayPre {
        let mut r = RayPre::new::<N>(ray);
        if Q {
            let qpick = |a: usize, near: bool| if r.neg[a] == near { (3 + a) * N } else { a * N };
            r.qplanes = [qpick(0, true), qpick(1, true), qpick(2, true), qpick(0, false), qpick(1, false), qpick(2, false)];
            r.slack += QNode::<N>::slack(r.o, r.inv, self.cmax);
        } else if L == AVX512 {
            r.fast_planes(self.cmax);
        }
        r
    }

    /// Tests the ray against the children of interior node `cur`: the hit mask
    /// (entry distances in `tmin`) and the child references.
    #[inline(always)]
    fn visit<const L: u8, const Q: bool>(&self, cur: u32, r: &RayPre, t_max: f32, tmin: &mut [f32; N]) -> (u32, &[u32; N]) {
        if Q {
            debug_assert!((cur as usize) < self.qnodes.len());
            // SAFETY: as in `node`, for the quantised copy of the node array.
            let q = unsafe { self.qnodes.get_unchecked(cur as usize) };
            (qnode_test::<N, L>(q, r, t_max, tmin), &q.child)
        } else {
            let n = self.node(cur);
            (node_test::<N, L>(n, r, t_max, tmin), &n.child)
        }
    }

    /// The node of an interior reference.
    #[inline(always)]
    fn node(&self, child: u32) -> &Node<N> {
        debug_assert!((child as usize) < self.nodes.len());
        // SAFETY: interior references are made only by `collapse` (or are the root,
        // 0, of a non-empty tree), each the index of a node it pushed.
        unsafe { self.nodes.get_unchecked(child as usize) }
    }

    /// Starts fetching a stacked child (its node's four lines or its triangle block),
    /// so that the memory latency overlaps the traversal of the nearer children.
    #[inline(always)]
    fn prefetch<const Q: bool>(&self, child: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let (p, lines) = if child & LEAF == 0 {
                if Q {
                    (self.qnodes.as_ptr().wrapping_add(child as usize) as *const i8, 2)
                } else {
                    (self.nodes.as_ptr().wrapping_add(child as usize) as *const i8, 4)
                }
            } else {
                (self.blocks.as_ptr().wrapping_add(((child & !LEAF) >> 3) as usize) as *const i8, (3 + 5 * (child & 7) as usize / 2).min(8))
            };
            for l in 0..lines {
                // SAFETY: prefetching is a hint that never faults, even out of bounds.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * l)) };
            }
        }
    }

    simd_entries!(intersect_avx2, occluded_avx2, AVX2, "avx2,fma");
    simd_entries!(intersect_avx512, occluded_avx512, AVX512, "avx2,fma,avx512f,avx512vl,avx512bw,avx512dq");
}

/// An empty vector with room for `cap` items whose pages the kernel is asked to back
/// with 2 MiB huge pages (Linux transparent huge pages in `madvise` mode). Incoherent
/// rays on a million-triangle tree touch a new 4 KiB page at almost every node, so
/// without this most node fetches also miss the TLB. The hint is advisory: nothing
/// changes where it is ignored. Untouched capacity costs address space only.
fn huge_vec<T>(cap: usize) -> Vec<T> {
    let v: Vec<T> = Vec::with_capacity(cap);
    #[cfg(target_os = "linux")]
    {
        let bytes = cap * std::mem::size_of::<T>();
        const HUGE: usize = 2 << 20;
        if bytes >= 2 * HUGE {
            // Only whole huge pages inside the allocation.
            let start = (v.as_ptr() as usize).next_multiple_of(HUGE);
            let end = (v.as_ptr() as usize + bytes) & !(HUGE - 1);
            if end > start {
                // SAFETY: the range lies inside this vector's allocation, which nothing
                // has touched yet; MADV_HUGEPAGE only changes how pages are backed.
                unsafe { libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE) };
            }
        }
    }
    v
}

/// Instruction set of the traversal. The AVX-512 level runs the integer-compare
/// node test (`x86::node_test8`), whose comparisons LLVM compiles to mask
/// registers (1.03–1.05× faster than the AVX2 level on this Zen 5, see README); the
/// AVX2 level keeps the float test, as the integer form measured 0.94–1.0× there.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
#[repr(u8)]
pub(crate) enum Simd {
    /// Lane loops only (no x86 extensions assumed).
    Portable,
    /// AVX2 and FMA.
    Avx2,
    /// AVX2, FMA and AVX-512 F/VL/BW/DQ.
    Avx512,
}

/// [`Simd`] levels as const-generic parameters of the traversal.
const PORTABLE: u8 = Simd::Portable as u8;
const AVX2: u8 = Simd::Avx2 as u8;
const AVX512: u8 = Simd::Avx512 as u8;

/// The traversal level to use: the best this CPU supports, or a lower one named by
/// the environment variable `PHOTONLAB_SIMD` (`portable`, `avx2`, `avx512`), so the
/// levels can be compared on one machine (`bench accel`). A level above the CPU's
/// is not used; an unknown value is reported and ignored.
pub(crate) fn detect_simd() -> Simd {
    let best = cpu_simd();
    let Ok(v) = std::env::var("PHOTONLAB_SIMD") else { return best };
    match v.as_str() {
        "portable" => Simd::Portable,
        "avx2" => best.min(Simd::Avx2),
        "avx512" => best,
        _ => {
            eprintln!("warning: PHOTONLAB_SIMD={v} is not one of portable, avx2, avx512; using {best:?}");
            best
        }
    }
}

/// The best traversal level this CPU supports.
fn cpu_simd() -> Simd {
    #[cfg(target_arch = "x86_64")]
    {
        use std::is_x86_feature_detected as has;
        if has!("avx2") && has!("fma") {
            if has!("avx512f") && has!("avx512vl") && has!("avx512bw") && has!("avx512dq") {
                return Simd::Avx512;
            }
            return Simd::Avx2;
        }
    }
    Simd::Portable
}

impl<const N: usize> Accel for WideBvh<N> {
    fn name(&self) -> &'static str {
        match (N, self.quant) {
            (8, true) => "bvh8q",
            (8, false) => "bvh8",
            _ => "bvh4",
        }
    }

    fn intersect(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        match self.simd {
            // SAFETY: `simd` names only a level the CPU reported (`detect_simd`).
            Simd::Avx512 => return unsafe { self.intersect_avx512(ray, t_max, stats) },
            // SAFETY: as above.
            Simd::Avx2 => return unsafe { self.intersect_avx2(ray, t_max, stats) },
            Simd::Portable => {}
        }
        if self.quant {
            self.intersect_impl::<PORTABLE, true>(ray, t_max, stats)
        } else {
            self.intersect_impl::<PORTABLE, false>(ray, t_max, stats)
        }
    }

    fn occluded(&self, ray: &Ray, t_max: f32, stats: &mut TraversalStats) -> bool {
        #[cfg(target_arch = "x86_64")]
        match self.simd {
            // SAFETY: as in `intersect`.
            Simd::Avx512 => return unsafe { self.occluded_avx512(ray, t_max, stats) },
            // SAFETY: as in `intersect`.
            Simd::Avx2 => return unsafe { self.occluded_avx2(ray, t_max, stats) },
            Simd::Portable => {}
        }
        if self.quant {
            self.occluded_impl::<PORTABLE, true>(ray, t_max, stats)
        } else {
            self.occluded_impl::<PORTABLE, false>(ray, t_max, stats)
        }
    }

    fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node<N>>()
            + self.qnodes.len() * std::mem::size_of::<QNode<N>>()
            + self.blocks.len() * std::mem::size_of::<TriBlock>()
    }

    fn simd_level(&self) -> Option<&'static str> {
        Some(match self.simd {
            Simd::Portable => "portable",
            Simd::Avx2 => "avx2",
            Simd::Avx512 => "avx512",
        })
    }

    fn sah_cost(&self) -> Option<f64> {
        let s = self.shape();
        Some(s.node_sah + s.leaf_sah)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Aabb;

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

    /// The portable traversal (the one non-AVX2 CPUs run) finds the same hits as the
    /// SIMD one, for float and quantised nodes and both widths.
    #[test]
    fn portable_and_simd_traversals_agree() {
        use crate::math::{hash_words, uniform_sphere};
        let unit = |h: u64| (h >> 40) as f32 / (1u64 << 24) as f32;
        let p = |k: u64, s: u64| uniform_sphere([unit(hash_words(&[k, s])), unit(hash_words(&[k, s + 1]))]);
        let tris: Vec<[Vec3; 3]> = (0..3000u64)
            .map(|k| {
                let c = p(k, 0) * (1.0 + unit(hash_words(&[k, 9])));
                [c, c + p(k, 2) * 0.2, c + p(k, 4) * 0.2]
            })
            .collect();
        // Tree `kind` (bvh4, bvh8, bvh8q) with the given traversal level.
        let make = |kind: usize, simd: Simd| -> Box<dyn Accel> {
            match kind {
                0 => Box::new(Bvh4 { simd, ..Bvh4::build(&tris) }),
                1 => Box::new(WideBvh::<8> { simd, ..WideBvh::<8>::build(&tris) }),
                _ => Box::new(WideBvh::<8> { simd, ..WideBvh::<8>::build_quantized(&tris) }),
            }
        };
        let mut s = TraversalStats::default();
        // Every level this CPU runs, each against the portable traversal.
        let levels: &[Simd] = match detect_simd() {
            Simd::Avx512 => &[Simd::Avx2, Simd::Avx512],
            Simd::Avx2 => &[Simd::Avx2],
            Simd::Portable => &[],
        };
        for (kind, &level) in (0..3).flat_map(|k| levels.iter().map(move |l| (k, l))) {
            let (a, b) = (make(kind, level), make(kind, Simd::Portable));
            let mut hits = 0;
            for k in 0..20_000u64 {
                let ray = Ray::new(p(k, 20) * 3.0, p(k, 22));
                let t_max = if k % 3 == 0 { 2.0 } else { f32::INFINITY };
                let (x, y) = (a.intersect(&ray, t_max, &mut s), b.intersect(&ray, t_max, &mut s));
                assert_eq!(x.map(|h| (h.tri, h.t.to_bits())), y.map(|h| (h.tri, h.t.to_bits())), "{} ray {k}", a.name());
                assert_eq!(a.occluded(&ray, t_max, &mut s), b.occluded(&ray, t_max, &mut s), "{} shadow ray {k}", a.name());
                hits += x.is_some() as u32;
            }
            assert!(hits > 1_000, "{}: {hits} hits", a.name());
        }
    }

    /// The integer node test against exact slab intersection in f64: it must report
    /// every box the ray meets on [0, t_max] (closed), never an empty lane, an entry
    /// distance no larger than the exact one times [`ROBUST`], and otherwise agree
    /// with the exact answer on almost every lane. Rays include directions with
    /// zero components and origins on box planes; boxes include flat ones.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn integer_node_test_is_conservative_and_skips_empty_lanes() {
        use crate::math::hash_words;
        if detect_simd() == Simd::Portable {
            eprintln!("skipped: no AVX2 on this CPU");
            return;
        }
        let unit = |k: u64, s: u64| (hash_words(&[k, s]) >> 40) as f32 / (1u64 << 24) as f32;
        let (mut lanes, mut agree, mut hits) = (0u32, 0u32, 0u32);
        let cmax = [4.0f32; 3];
        for k in 0..40_000u64 {
            let mut n = Node::<8>::empty();
            let filled = 1 + (k % 8) as usize;
            let grid = |v: f32| (v * 8.0).round() / 4.0 - 2.0; // planes on a coarse grid, so origins land on them
            for i in 0..filled {
                for a in 0..3 {
                    let (x, y) = (grid(unit(k, 10 + 2 * (3 * i + a) as u64)), grid(unit(k, 11 + 2 * (3 * i + a) as u64)));
                    (n.lo[a][i], n.hi[a][i]) = (x.min(y), x.max(y));
                }
                n.child[i] = i as u32;
            }
            let mut o = [0.0f32; 3];
            let mut d = [0.0f32; 3];
            for a in 0..3 {
                o[a] = if k % 3 == 0 { grid(unit(k, 100 + a as u64)) } else { unit(k, 100 + a as u64) * 6.0 - 3.0 };
                // About a quarter of the rays have one or two zero direction components.
                let zero = (k % 7 == 1 && a == (k % 3) as usize) || (k % 11 == 2 && a != (k % 3) as usize);
                d[a] = if zero { 0.0 } else { unit(k, 200 + a as u64) * 2.0 - 1.0 };
            }
            if d == [0.0; 3] {
                continue;
            }
            let t_max = if k % 4 == 0 { 1.5 } else { f32::INFINITY };
            let ray = Ray::new(Vec3::from(o), Vec3::from(d));
            let mut r = RayPre::new::<8>(&ray);
            r.fast_planes(cmax);
            let base = &n as *const Node<8> as *const u8;
            let planes = r.planes.map(|off| base.wrapping_add(off) as *const f32);
            let mut tmin = [0.0f32; 8];
            // SAFETY: AVX2 and FMA checked above; every plane array and `tmin` hold 8 floats.
            let mask = unsafe { x86::node_test8(&planes, &r, t_max, tmin.as_mut_ptr()) };
            for (i, &entry) in tmin.iter().enumerate() {
                let got = mask >> i & 1 == 1;
                if i >= filled {
                    assert!(!got, "ray {k}: empty lane {i} entered");
                    continue;
                }
                // Exact slab interval in f64.
                let (mut t0, mut t1) = (0.0f64, t_max as f64);
                for a in 0..3 {
                    let (lo, hi, oa, da) = (n.lo[a][i] as f64, n.hi[a][i] as f64, o[a] as f64, d[a] as f64);
                    if da == 0.0 {
                        if oa < lo || oa > hi {
                            t1 = -1.0;
                        }
                        continue;
                    }
                    let (x, y) = ((lo - oa) / da, (hi - oa) / da);
                    t0 = t0.max(x.min(y));
                    t1 = t1.min(x.max(y));
                }
                let exact = t0 <= t1;
                if exact {
                    assert!(got, "ray {k}: lane {i} culled, exact entry {t0} exit {t1}");
                    assert!((0.0..=t0 * ROBUST as f64).contains(&(entry as f64)), "ray {k}: lane {i} entry {entry}, exact {t0}");
                    hits += 1;
                }
                // Axes with a zero direction component are ignored (they never
                // cull), so agreement is counted on the other rays only.
                if !d.contains(&0.0) {
                    lanes += 1;
                    agree += (got == exact) as u32;
                }
            }
        }
        assert!(hits > 5_000, "{hits} boxes hit");
        assert!(agree as f64 > 0.9998 * lanes as f64, "{agree} of {lanes} lanes agree with the exact test");
    }

    fn rnd(seed: &mut u64) -> f32 {
        *seed = crate::math::hash_words(&[*seed]);
        (*seed >> 40) as f32 / (1u64 << 24) as f32
    }

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

    /// The branch-free ordering of three or more hit children: the nearest is
    /// returned, the others come farthest first, none is lost or invented.
    #[test]
    fn sorted_push_of_many_hits() {
        if detect_simd() != Simd::Avx512 {
            eprintln!("no AVX-512 on this CPU: the sorted push is not used, nothing to check");
            return;
        }
        let mut seed = 11u64;
        let mut checked = 0;
        for _ in 0..20_000 {
            let mask = (rnd(&mut seed) * 256.0) as u32 & 0xff;
            if mask.count_ones() < 3 {
                continue;
            }
            // Distances with ties and zeros; child references arbitrary.
            let tmin: [f32; 8] =
                std::array::from_fn(
                    |_| if rnd(&mut seed) < 0.2 { 0.0 } else { (rnd(&mut seed) * 8.0).floor() * 0.5 + rnd(&mut seed) * 1e-6 },
                );
            let child: [u32; 8] = std::array::from_fn(|i| 1000 + i as u32 * 7);
            let mut out = [const { MaybeUninit::uninit() }; 8];
            // SAFETY: AVX-512 checked above; 8 non-negative distances and children.
            let near = unsafe { x86::sort_hits8(tmin.as_ptr(), mask, child.as_ptr(), &mut out) };
            let k = mask.count_ones() as usize;
            // SAFETY: the function wrote all 8 entries.
            let got: Vec<Entry> = out[..k - 1].iter().map(|e| unsafe { e.assume_init() }).collect();
            let lane = |c: u32| ((c - 1000) / 7) as usize;
            let tmin_hit = (0..8).filter(|i| mask >> i & 1 == 1).map(|i| tmin[i]).fold(f32::INFINITY, f32::min);
            assert!(mask >> lane(near) & 1 == 1 && tmin[lane(near)] - tmin_hit <= 1e-6, "nearest {near} of {tmin:?} {mask:#b}");
            let mut lanes: Vec<usize> = got.iter().map(|e| lane(e.child)).chain([lane(near)]).collect();
            for w in got.windows(2) {
                assert!(w[0].t >= w[1].t, "not farthest first: {tmin:?} {mask:#b}");
            }
            for e in &got {
                let t = tmin[lane(e.child)];
                assert!(e.t <= t && e.t >= t * (1.0 - 1e-6) && e.t >= tmin[lane(near)] * (1.0 - 1e-6), "distance {} for {t}", e.t);
            }
            lanes.sort();
            assert_eq!(lanes, (0..8).filter(|i| mask >> i & 1 == 1).collect::<Vec<_>>(), "{tmin:?} {mask:#b}");
            checked += 1;
        }
        assert!(checked > 5000);
    }

    #[test]
    fn node_sizes_are_cache_line_multiples() {
        assert_eq!(std::mem::size_of::<Node<4>>(), 128);
        assert_eq!(std::mem::size_of::<Node<8>>(), 256);
        assert_eq!(std::mem::size_of::<TriBlock>(), 160);
    }

    #[test]
    fn empty_single_and_degenerate_inputs() {
        let mut s = TraversalStats::default();
        for bvh in [Box::new(Bvh4::build(&[])) as Box<dyn Accel>, Box::new(WideBvh::<8>::build(&[]))] {
            assert!(bvh.intersect(&Ray::new(Vec3::ZERO, Vec3::X), 1.0, &mut s).is_none());
            assert!(!bvh.occluded(&Ray::new(Vec3::ZERO, Vec3::X), 1.0, &mut s));
        }
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let one = Bvh4::build(&[t]);
        let h = one.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z), 5.0, &mut s).unwrap();
        assert_eq!((h.t, h.tri), (1.0, 0));
        // Many triangles with the same centroid still build and are found; an
        // axis-parallel ray starting on a box plane is not lost to 0·∞.
        let many = WideBvh::<8>::build(&vec![t; 100]);
        assert!(many.intersect(&Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z), 5.0, &mut s).is_some());
        assert!(many.occluded(&Ray::new(Vec3::new(0.0, 0.3, 1.0), -Vec3::Z), 5.0, &mut s));
    }
}
