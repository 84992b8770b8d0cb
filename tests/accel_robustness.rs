//! Every accelerator returns the same closest hits and occlusion as testing every
//! triangle (`none`) on scenes at scales from 1e-20 to 1e20 made of flat,
//! degenerate, collinear, duplicated and large triangles, with random and
//! axis-parallel rays, and zero directions. Hits must agree bit for bit, ties on the
//! 400 copies of one triangle included. (A quantised-box rounding bug — nearest
//! instead of floor — fails it, and so does keeping the first of equal hits found.)

use glam::Vec3;
use photonlab::accel::TraversalStats;
use photonlab::geometry::Ray;

/// A uniform number in [0, 1) from a key (splitmix64 finaliser).
fn h(k: u64) -> f32 {
    let mut x = k.wrapping_mul(0x9E3779B97F4A7C15);
    x ^= x >> 31;
    x = x.wrapping_mul(0xBF58476D1CE4E5B9);
    x ^= x >> 29;
    (x >> 40) as f32 / (1u64 << 24) as f32
}

#[test]
fn accelerators_agree_with_testing_every_triangle_at_extreme_scales() {
    for scene in 0..12u64 {
        let scale = [1e-20f32, 1e-6, 1.0, 1e6, 1e20, 1.0][(scene % 6) as usize];
        let mut tris = Vec::new();
        for i in 0..2000u64 {
            let k = scene * 100000 + i * 10;
            let c = Vec3::new(h(k), h(k + 1), h(k + 2)) * scale;
            let kind = i % 5;
            let t = match kind {
                0 => [c, c + Vec3::new(h(k + 3), 0.0, 0.0) * scale, c + Vec3::new(0.0, h(k + 4), 0.0) * scale], // flat z
                1 => [c, c, c + Vec3::X * scale * 0.1],                                                         // degenerate
                2 => [c, c + Vec3::new(1.0, 1.0, 1.0) * scale * 0.01, c + Vec3::new(2.0, 2.0, 2.0) * scale * 0.01], // collinear
                3 => [Vec3::ZERO, Vec3::X * scale, Vec3::Y * scale],                                            // duplicates
                _ => [
                    c,
                    c + Vec3::new(h(k + 5), h(k + 6), h(k + 7)) * scale * 3.0,
                    c + Vec3::new(h(k + 8), -h(k + 9), h(k + 3)) * scale * 3.0,
                ], // big
            };
            tris.push(t);
        }
        let lin = photonlab::registry::make_accel("none", &tris).unwrap();
        let mut duplicate_hits = 0;
        for name in ["bvh8", "bvh8q", "bvh4", "bvh"] {
            let acc = photonlab::registry::make_accel(name, &tris).unwrap();
            let (mut s1, mut s2) = (TraversalStats::default(), TraversalStats::default());
            for r in 0..3000u64 {
                let k = scene * 7777 + r * 13;
                let o = (Vec3::new(h(k), h(k + 1), h(k + 2)) * 3.0 - 1.0) * scale;
                let mut d = Vec3::new(h(k + 3) - 0.5, h(k + 4) - 0.5, h(k + 5) - 0.5);
                if r % 7 == 0 {
                    d = Vec3::new(0.0, 0.0, if r % 2 == 0 { 1.0 } else { -1.0 });
                }
                if r % 11 == 0 {
                    d = Vec3::new(1.0, 0.0, 0.0);
                }
                let (mut o, mut d) = (o, d.normalize());
                if r % 5 == 2 {
                    // From below at the duplicated triangle (z = 0; nothing lies below it).
                    // At scale 1e20 the length overflows and the direction comes out
                    // zero: such rays must hit nothing (they once crashed `bvh4`).
                    let target = Vec3::new(h(k + 6) * 0.5, h(k + 7) * 0.5, 0.0) * scale;
                    o = Vec3::new(h(k + 8) - 0.5, h(k + 9) - 0.5, -1.0) * scale;
                    d = (target - o).normalize();
                }
                let ray = Ray::new(o, d);
                let a = lin.intersect(&ray, f32::INFINITY, &mut s1);
                let b = acc.intersect(&ray, f32::INFINITY, &mut s2);
                // The same hit, also among the 400 copies of one triangle: the lowest index.
                assert_eq!(a, b, "scene {scene} {name} ray {r}");
                duplicate_hits += u32::from(a.is_some_and(|h| h.tri % 5 == 3));
                assert_eq!(
                    lin.occluded(&ray, f32::INFINITY, &mut s1),
                    acc.occluded(&ray, f32::INFINITY, &mut s2),
                    "scene {scene} {name} shadow {r}"
                );
            }
        }
        // At 1e-20 and 1e20 its determinant under- or overflows: it is never hit.
        if (1e-10..1e10).contains(&scale) {
            assert!(duplicate_hits >= 40, "scene {scene}: only {duplicate_hits} hits on the duplicated triangle");
        }
    }
}
