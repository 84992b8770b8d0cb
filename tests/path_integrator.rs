//! End-to-end checks of the reference `path` integrator.

use photonlab::config::RenderConfig;
use photonlab::pipeline::render_scene;
use photonlab::scene::builtin::{cornell, furnace};

/// White furnace: inside a closed diffuse sphere of albedo a emitting L_e, every
/// pixel's radiance is L_e / (1 − a), for every Russian-roulette policy.
#[test]
fn white_furnace_every_rr_policy() {
    let (a, le) = (0.6f32, 1.0f32);
    let expect = le / (1.0 - a);
    for (rr, max_depth) in [("off", Some(60)), ("fixed:0.7", None), ("albedo", None), ("throughput", None), ("throughput:0", None)] {
        let cfg = RenderConfig { spp: 128, rr: rr.into(), max_depth, seed: 3, resolution: Some([16, 16]), ..Default::default() };
        let out = render_scene(furnace(a, le, 24), &cfg, true).unwrap();
        let mean = out.film.mean();
        for c in mean.to_array() {
            // 32768 paths: the standard error is below 0.5 % for every policy.
            assert!((c - expect).abs() < 0.015 * expect, "rr {rr}: mean {mean} expected {expect}");
        }
        // Every pixel individually (128 spp; roulette on every bounce has a per-pixel
        // standard error of about 7 %).
        for p in &out.film.pixels {
            assert!((p.x - expect).abs() < 0.3 * expect, "rr {rr}: pixel {p} expected {expect}");
        }
    }
}

/// Truncating paths (max depth without roulette) must lose exactly the energy of
/// the missing bounces: sum_{k=0}^{d} a^k L_e. This makes the furnace test able to fail.
#[test]
fn furnace_truncation_bias_is_visible() {
    let (a, le) = (0.6f32, 1.0f32);
    let cfg = RenderConfig { spp: 64, rr: "off".into(), max_depth: Some(2), seed: 3, resolution: Some([8, 8]), ..Default::default() };
    let out = render_scene(furnace(a, le, 24), &cfg, true).unwrap();
    let want = le * (1.0 + a + a * a);
    let m = out.film.mean().x;
    assert!((m - want).abs() < 0.01 * want, "mean {m} expected {want}");
    assert!((m - le / (1.0 - a)).abs() > 0.1);
}

/// The image is a pure function of the inputs: bit-identical for 1 and 2 threads,
/// for every sampler.
#[test]
fn deterministic_across_thread_counts() {
    for sampler in ["random", "halton", "hammersley", "sobol"] {
        let mut imgs = Vec::new();
        for threads in [1, 2, 2] {
            let cfg = RenderConfig { spp: 4, sampler: sampler.into(), threads, seed: 11, resolution: Some([40, 30]), ..Default::default() };
            imgs.push(render_scene(cornell(), &cfg, true).unwrap().film);
        }
        assert_eq!(imgs[0].pixels, imgs[1].pixels, "{sampler}: 1 vs 2 threads");
        assert_eq!(imgs[1].pixels, imgs[2].pixels, "{sampler}: run to run");
    }
}

/// A low-resolution Cornell box is finite everywhere and shows the expected colour
/// bleeding: the floor near the red (left) wall is redder than near the green wall.
#[test]
fn cornell_colour_bleeding() {
    let cfg = RenderConfig { spp: 64, seed: 1, resolution: Some([32, 32]), ..Default::default() };
    let out = render_scene(cornell(), &cfg, true).unwrap();
    let f = &out.film;
    assert!(f.pixels.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
    // Region averages (x0..x1, y0..y1).
    let avg = |x0: u32, x1: u32, y0: u32, y1: u32| {
        let mut s = glam::Vec3::ZERO;
        for y in y0..y1 {
            for x in x0..x1 {
                s += f.get(x, y);
            }
        }
        s / ((x1 - x0) * (y1 - y0)) as f32
    };
    let left_wall = avg(1, 4, 10, 20);
    let right_wall = avg(28, 31, 10, 20);
    assert!(left_wall.x > 2.0 * left_wall.y, "left wall should be red: {left_wall}");
    assert!(right_wall.y > 1.5 * right_wall.x, "right wall should be green: {right_wall}");
    // Floor strips next to each wall (bottom rows, between the blocks' shadows).
    let floor_left = avg(4, 9, 28, 31);
    let floor_right = avg(23, 28, 28, 31);
    let rg = |c: glam::Vec3| c.x / c.y;
    assert!(rg(floor_left) > rg(floor_right) * 1.1, "floor near red wall {floor_left} vs near green wall {floor_right}");
    // Ceiling light visible at the top centre.
    let brightest = (0..8).flat_map(|y| (0..32).map(move |x| (x, y))).map(|(x, y)| f.get(x, y).x).fold(0.0f32, f32::max);
    assert!(brightest > 5.0, "light should be visible near the top: {brightest}");
}

/// A closed perfect mirror (reflectance 1) never lowers a path's throughput, so
/// throughput- and albedo-based roulette never end it. With `max_depth` unset the
/// render must still finish: the safety cap ends each path after
/// `SAFETY_MAX_DEPTH` bounces (one closest-hit ray per bounce plus the camera ray).
#[test]
fn trapped_paths_end_at_the_safety_cap() {
    use photonlab::config::SAFETY_MAX_DEPTH;
    use photonlab::material::{Bsdf, Mirror};
    use photonlab::scene::LightDesc;
    for rr in ["throughput", "albedo"] {
        let mut s = furnace(0.5, 0.0, 8);
        for m in &mut s.materials {
            m.bsdf = Bsdf::Mirror(Mirror { reflectance: glam::Vec3::ONE });
        }
        s.lights.push(LightDesc::Point { position: glam::Vec3::new(0.0, 0.2, 0.1), intensity: glam::Vec3::ONE });
        let cfg = RenderConfig { spp: 1, rr: rr.into(), seed: 1, resolution: Some([4, 4]), ..Default::default() };
        let out = render_scene(s, &cfg, true).unwrap();
        let closest = out.rays().rays;
        let paths = 16u64;
        assert!(closest >= paths * SAFETY_MAX_DEPTH as u64, "rr {rr}: {closest} closest-hit rays: paths ended early");
        assert!(closest <= paths * (SAFETY_MAX_DEPTH as u64 + 1), "rr {rr}: {closest} closest-hit rays: cap not applied");
        assert!(out.film.mean().is_finite());
    }
}
