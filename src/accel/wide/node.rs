//! The float wide node: N child boxes as structure-of-arrays and the child
//! references (an interior node's index, or a leaf's run of triangle blocks).

/// Marks a child reference as a leaf: `LEAF | first block << 3 | (blocks − 1)`.
pub(super) const LEAF: u32 = 1 << 31;
/// Unused child slot (its box is inverted, so it is never entered).
pub(super) const EMPTY: u32 = u32::MAX;

/// A wide node: N child boxes (SoA) and child references.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(super) struct Node<const N: usize> {
    pub(super) lo: [[f32; N]; 3],
    pub(super) hi: [[f32; N]; 3],
    pub(super) child: [u32; N],
}

impl<const N: usize> Node<N> {
    pub(super) fn empty() -> Self {
        Node { lo: [[f32::INFINITY; N]; 3], hi: [[f32::NEG_INFINITY; N]; 3], child: [EMPTY; N] }
    }
}
