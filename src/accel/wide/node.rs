//! The float wide node: N child boxes as structure-of-arrays and the child
//! references (an interior node's index, or a leaf's run of triangle blocks).

/// Marks a child reference as a leaf: `LEAF | first block << 3 | (blocks − 1)`.
pub(super) const LEAF: u32 = 1 << 31;
/// Unused child slot (its box is inverted, so it is never entered).
pub(super) const EMPTY: u32 = u32::MAX;

/// The reference of the float node at `index`: its byte offset in the node array
/// in units of 8 bytes, so that the traversal turns a reference into an address
/// with one scaled-index addressing mode (x86's largest scale is 8) instead of a
/// shift and an add on the dependent chain from one node to the next. The
/// quantised copy of the tree keeps the same references ([`node_index`]).
pub(super) const fn node_ref<const N: usize>(index: usize) -> u32 {
    let r = index * (size_of::<Node<N>>() / 8);
    assert!(r < LEAF as usize, "wide BVH: too many nodes for 31-bit references");
    r as u32
}

/// The array index of the node an interior reference names (inverse of [`node_ref`]).
#[inline(always)]
pub(super) const fn node_index<const N: usize>(r: u32) -> usize {
    r as usize / (size_of::<Node<N>>() / 8)
}

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
