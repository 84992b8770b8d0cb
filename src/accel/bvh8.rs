//! `bvh8`: the wide BVH of [`super::bvh4`] with 8 children per node (one AVX2
//! register per box plane).

/// 8-wide BVH (`bvh8`).
pub type Bvh8 = super::bvh4::WideBvh<8>;
