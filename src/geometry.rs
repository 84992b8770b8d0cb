//! Rays, hits, bounding boxes and the one ray/triangle test every accelerator shares
//! (so `none` and `bvh` agree to the bit on the closest hit).

use glam::Vec3;

/// A ray with origin and (not necessarily unit) direction; valid for t in (0, t_max).
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Origin.
    pub o: Vec3,
    /// Direction.
    pub d: Vec3,
}

impl Ray {
    /// New ray.
    #[inline]
    pub fn new(o: Vec3, d: Vec3) -> Self {
        Ray { o, d }
    }
    /// Point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }
}

/// Closest-hit record returned by an accelerator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Index of the triangle in the scene's triangle array.
    pub tri: u32,
    /// Barycentric weight of vertex 1.
    pub b1: f32,
    /// Barycentric weight of vertex 2.
    pub b2: f32,
}

/// Axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box (union identity).
    pub const EMPTY: Aabb = Aabb { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };
    /// Grows the box to contain `p`.
    #[inline]
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    /// Union of two boxes.
    #[inline]
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
    /// Box of a triangle.
    #[inline]
    pub fn of_triangle(t: &[Vec3; 3]) -> Aabb {
        Aabb { min: t[0].min(t[1]).min(t[2]), max: t[0].max(t[1]).max(t[2]) }
    }
    /// Extent (max − min).
    #[inline]
    pub fn diagonal(&self) -> Vec3 {
        self.max - self.min
    }
    /// Centre.
    #[inline]
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }
    /// Surface area (0 for empty boxes).
    #[inline]
    pub fn area(&self) -> f32 {
        let d = self.diagonal();
        if d.x < 0.0 || d.y < 0.0 || d.z < 0.0 { 0.0 } else { 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x) }
    }
    /// True when no point has been added.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }
    /// Common part of two boxes ([`Aabb::EMPTY`] when they are disjoint).
    #[inline]
    pub fn intersection(&self, o: &Aabb) -> Aabb {
        let b = Aabb { min: self.min.max(o.min), max: self.max.min(o.max) };
        if b.min.cmpgt(b.max).any() { Aabb::EMPTY } else { b }
    }
    /// True when `p` lies in the box (boundary included).
    pub fn contains_point(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }
    /// True when `o` lies in the box (boundary included).
    pub fn contains_box(&self, o: &Aabb) -> bool {
        o.is_empty() || (self.contains_point(o.min) && self.contains_point(o.max))
    }
}

/// Möller–Trumbore ray/triangle test with precomputed edges. Returns (t, b1, b2) for
/// 0 < t < t_max. Edge-on and back-facing hits both count (surfaces are two-sided
/// for visibility).
#[inline(always)]
pub fn intersect_triangle(o: Vec3, d: Vec3, v0: Vec3, e1: Vec3, e2: Vec3, t_max: f32) -> Option<(f32, f32, f32)> {
    let pvec = d.cross(e2);
    let det = e1.dot(pvec);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let tvec = o - v0;
    let u = tvec.dot(pvec) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qvec = tvec.cross(e1);
    let v = d.dot(qvec) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(qvec) * inv;
    if t > 0.0 && t < t_max { Some((t, u, v)) } else { None }
}

/// `d` with every zero component replaced by ±2⁻⁶⁰ (sign kept): for rays along
/// surface normals (area probes), which are often axis-aligned. The wide BVHs cannot
/// cull along an axis a ray is parallel to (infinite inverse direction: no culling on
/// that axis, by design of the integer-compare node test): on the cornell-glass floor
/// every probe tested the same 472 child boxes and 1036 triangles (every node touching
/// the floor's plane), where a photon ray tests ~21 and ~8. The nudge restores culling
/// (`bvh8`: 8× fewer box and 20× fewer triangle tests per probe, `bvh4` 1.6× and
/// 4.6×; `bvh8q` 12 % more box but 44 % fewer triangle tests, as its shared slack
/// grows with the huge inverse; `bvh` unchanged). Over a distance t it moves the ray
/// by t·2⁻⁶⁰, far below the f32 spacing of coordinates, so it meets the same
/// triangles (`area_probes_along_axes_agree_…` in the sppm tests checks).
#[inline]
pub fn off_axis(d: Vec3) -> Vec3 {
    const TINY: f32 = 1.0 / (1u64 << 60) as f32;
    d.to_array().map(|c| if c == 0.0 { TINY.copysign(c) } else { c }).into()
}

/// Offsets a surface point along the geometric normal, towards the side `dir` leaves
/// on, far enough that a ray spawned there does not re-hit its own triangle. The
/// offset is relative to the coordinate magnitude because f32 rounding error is.
#[inline]
pub fn offset_origin(p: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
    let scale = 1.0 + p.abs().max_element();
    let eps = 2e-5 * scale;
    if ng.dot(dir) >= 0.0 { p + ng * eps } else { p - ng * eps }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn off_axis_direction_has_no_zero_component() {
        for n in [Vec3::Y, -Vec3::X, Vec3::Z, Vec3::new(0.6, 0.0, -0.8), Vec3::new(0.0, -0.0, 1.0)] {
            let d = off_axis(-n);
            assert!(d.to_array().iter().all(|c| *c != 0.0), "{d}");
            assert!((d + n).abs().max_element() <= 1e-18, "{d} vs {}", -n);
            assert!(d.dot(-n) > 0.0);
        }
    }

    #[test]
    fn triangle_hit_and_miss() {
        let v0 = Vec3::ZERO;
        let e1 = Vec3::X;
        let e2 = Vec3::Y;
        let h = intersect_triangle(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, v0, e1, e2, 10.0).unwrap();
        assert!((h.0 - 1.0).abs() < 1e-6 && (h.1 - 0.25).abs() < 1e-6 && (h.2 - 0.25).abs() < 1e-6);
        assert!(intersect_triangle(Vec3::new(0.75, 0.75, 1.0), -Vec3::Z, v0, e1, e2, 10.0).is_none());
        assert!(intersect_triangle(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, v0, e1, e2, 0.5).is_none());
        assert!(intersect_triangle(Vec3::new(0.25, 0.25, 1.0), Vec3::Z, v0, e1, e2, 10.0).is_none());
    }

    #[test]
    fn aabb_area() {
        let mut b = Aabb::EMPTY;
        assert_eq!(b.area(), 0.0);
        b.grow(Vec3::ZERO);
        b.grow(Vec3::ONE);
        assert!((b.area() - 6.0).abs() < 1e-6);
    }
}
