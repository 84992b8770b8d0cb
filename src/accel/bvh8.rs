//! `bvh8`: the wide BVH of [`super::wide`] with 8 children per node (one AVX2
//! register per box plane).

/// 8-wide BVH (`bvh8`).
pub type Bvh8 = super::wide::WideBvh<8>;
