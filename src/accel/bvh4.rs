//! `bvh4`: the wide BVH of [`super::wide`] with 4 children per node (one SSE
//! register per box plane).

/// 4-wide BVH (`bvh4`).
pub type Bvh4 = super::wide::WideBvh<4>;
