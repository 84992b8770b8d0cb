//! The quantised wide node of `bvh8q`: child boxes as 8-bit offsets on a per-node
//! grid (see [`crate::accel::bvh8q`]).

use super::node::Node;

/// A quantised wide node: 8-bit child boxes on the node's grid, the grid, and the
/// child references (two cache lines for N = 8).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct QNode<const N: usize> {
    /// Lower grid coordinates per axis and lane (255 in empty slots).
    pub(super) qlo: [[u8; N]; 3],
    /// Upper grid coordinates per axis and lane (0 in empty slots).
    pub(super) qhi: [[u8; N]; 3],
    /// Grid origin (the lower corner of the union of the children's boxes).
    pub(super) origin: [f32; 3],
    /// Grid step per axis (a power of two).
    pub(super) scale: [f32; 3],
    /// Child references, as in [`Node`].
    pub(super) child: [u32; N],
    /// Bit i set when slot i holds a child.
    pub(super) valid: u32,
}

impl<const N: usize> QNode<N> {
    /// Quantises a node's child boxes outwards (exactly, in f64: every decoded lower
    /// plane origin + q·scale is ≤ the box's, every upper one ≥).
    pub(super) fn from_node(n: &Node<N>, empty: u32) -> Self {
        let mut q = QNode { qlo: [[255; N]; 3], qhi: [[0; N]; 3], origin: [0.0; 3], scale: [1.0; 3], child: n.child, valid: 0 };
        for i in 0..N {
            if n.child[i] != empty {
                q.valid |= 1 << i;
            }
        }
        for a in 0..3 {
            let lanes = (0..N).filter(|&i| q.valid & (1 << i) != 0);
            let lo = lanes.clone().map(|i| n.lo[a][i]).fold(f32::INFINITY, f32::min);
            let hi = lanes.map(|i| n.hi[a][i]).fold(f32::NEG_INFINITY, f32::max);
            if lo > hi {
                continue; // no child
            }
            let ext = hi as f64 - lo as f64;
            // Smallest power of two with ext / scale ≤ 255 (at least 2^-100, so that
            // scale / d stays a normal number).
            let mut e = if ext > 0.0 { (ext / 255.0).log2().ceil() as i32 } else { -100 };
            e = e.max(-100);
            while ext / 2f64.powi(e) > 255.0 {
                e += 1;
            }
            let scale = 2f64.powi(e);
            q.origin[a] = lo;
            q.scale[a] = scale as f32;
            for i in 0..N {
                if q.valid & (1 << i) == 0 {
                    continue;
                }
                let l = ((n.lo[a][i] as f64 - lo as f64) / scale).floor();
                let h = ((n.hi[a][i] as f64 - lo as f64) / scale).ceil();
                q.qlo[a][i] = l.clamp(0.0, 255.0) as u8;
                q.qhi[a][i] = h.clamp(0.0, 255.0) as u8;
                debug_assert!(lo as f64 + q.qlo[a][i] as f64 * scale <= n.lo[a][i] as f64);
                debug_assert!(lo as f64 + q.qhi[a][i] as f64 * scale >= n.hi[a][i] as f64);
            }
        }
        q
    }

    /// Per-ray absolute slack for the far distances of quantised boxes in a scene
    /// whose coordinates are at most `cmax` in magnitude: rounding (origin − o) and
    /// its product with 1/d errs by up to 2ε·(|origin| + |o|)/|d| on each of the near
    /// and far distances. Axes with a non-finite 1/d are skipped (their distances
    /// are ±∞ or NaN, which the test ignores).
    pub(super) fn slack(o: [f32; 3], inv: [f32; 3], cmax: [f32; 3]) -> f32 {
        let mut s = 0.0f32;
        for a in 0..3 {
            if inv[a].is_finite() {
                s = s.max((cmax[a] + o[a].abs()) * inv[a].abs());
            }
        }
        6.0 * f32::EPSILON * s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantised_node_is_two_cache_lines() {
        assert_eq!(std::mem::size_of::<QNode<8>>(), 128);
    }
}
