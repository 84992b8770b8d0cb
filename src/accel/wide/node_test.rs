//! The ray-box test of one node, per SIMD level: the portable lane loops (which LLVM
//! vectorises) and the dispatch to the explicit x86 instructions of [`super::x86`].

#[cfg(target_arch = "x86_64")]
use super::cpu::AVX2;
use super::node::Node;
use super::qnode::QNode;
use super::ray::{ROBUST, RayPre};
#[cfg(target_arch = "x86_64")]
use super::x86;

/// Tests the ray against all N child boxes; returns the hit mask and entry distances.
///
/// A zero direction component makes the inverse ±∞ and a slab plane through the
/// origin gives 0·∞ = NaN; every fold below keeps its accumulator when the new value
/// is NaN (`x < acc` is false), so that axis is ignored, as it should be for a ray
/// lying in the slab. Compiled as plain compare-and-select, each fold is one
/// `minps`/`maxps`.
#[inline(always)]
pub(super) fn node_test<const N: usize, const L: u8>(n: &Node<N>, r: &RayPre, t_max: f32, tmin: &mut [f32; N]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        let base = n as *const Node<N> as *const u8;
        // In bounds: every offset addresses one of the node's six plane arrays.
        let planes = r.planes.map(|off| base.wrapping_add(off) as *const f32);
        if N == 8 && L >= AVX2 {
            // SAFETY: L is AVX2 or AVX512 only inside those traversals (CPU checked at
            // build), and every plane array holds N = 8 floats, as does `tmin`.
            return unsafe { x86::node_test8(&planes, r, t_max, tmin.as_mut_ptr()) };
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
    let plane = |k: usize| if (r.octant >> (k % 3) & 1 == 1) == (k < 3) { &n.hi[k % 3] } else { &n.lo[k % 3] };
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
pub(super) fn qnode_test<const N: usize, const L: u8>(n: &QNode<N>, r: &RayPre, t_max: f32, tmin: &mut [f32; N]) -> u32 {
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
