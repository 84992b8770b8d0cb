use super::*;
use crate::camera::Camera;
use crate::integrator::Integrator;
use crate::material::Material;
use crate::param::Reader;
use crate::registry::{make_accel, make_rr};
use crate::scene::LightDesc;
use crate::scene::{Face, MeshData, Placement, Scene};

#[test]
fn update_keeps_a_uniform_density_estimate_and_shrinks_the_radius() {
    // Photons of flux 1 arrive uniformly, `rho` per unit area per pass: the estimate
    // τ / (p π r²) must stay rho whatever the radius, while r² falls like p^(α−1).
    let (rho, alpha) = (2000.0f64, 2.0 / 3.0);
    let mut px = PixelStats::new(1.0);
    let mut r2_at = Vec::new();
    for pass in 1..=400u32 {
        let m = (rho * std::f64::consts::PI * px.r * px.r).round() as u64;
        px.update(m, DVec3::splat(m as f64), alpha);
        let est = px.radiance(pass, 1).x as f64;
        assert!((est / rho - 1.0).abs() < 0.02, "pass {pass}: {est} vs {rho}");
        r2_at.push(px.r * px.r);
    }
    let slope = (r2_at[399] / r2_at[39]).ln() / 10f64.ln();
    assert!((slope - (alpha - 1.0)).abs() < 0.05, "r² slope {slope}");
    // No photons: nothing changes.
    let before = px;
    px.update(0, DVec3::ZERO, alpha);
    assert_eq!((before.r, before.n), (px.r, px.n));
}

#[test]
fn grid_visits_every_photon_within_the_radius_once() {
    let mut photons = Vec::new();
    let mut h = 7u64;
    let mut u = || {
        h = crate::math::mix64(h);
        (h >> 40) as f32 / (1u64 << 24) as f32
    };
    for i in 0..5000 {
        let pos = Vec3::new(u() * 4.0 - 2.0, u() * 4.0 - 2.0, u() * 0.5);
        // The power carries the photon's index, to find it again in the sorted grid.
        photons.push(GridPhoton { pos, power: Color::splat(i as f32), dir: Vec3::Z, normal: Vec3::Z });
    }
    let r = 0.3f32;
    let mut grid = PhotonGrid::default();
    grid.for_each_candidate(Vec3::ZERO, r, |_| panic!("an empty grid has no photons"));
    grid.build(&photons, 2.0 * r);
    for q in 0..200 {
        let p = Vec3::new(u() * 4.0 - 2.0, u() * 4.0 - 2.0, u() * 0.5);
        let rq = r * (0.2 + 0.8 * (q % 5) as f32 / 4.0);
        let mut seen = vec![0u32; photons.len()];
        grid.for_each_candidate(p, rq, |ph| seen[ph.power.x as usize] += 1);
        for (i, ph) in photons.iter().enumerate() {
            assert!(seen[i] <= 1, "photon {i} visited twice");
            if (ph.pos - p).length() <= rq {
                assert_eq!(seen[i], 1, "photon {i} within the radius was missed");
            }
        }
    }
}

/// A single-sided square (the floor of zero thickness, normal +y) lit from above by a
/// point light; the camera looks at it from below.
fn thin_floor_seen_from_below() -> World {
    let mut m = MeshData::default();
    let s = 2.0;
    m.positions = vec![Vec3::new(-s, 0.0, -s), Vec3::new(s, 0.0, -s), Vec3::new(s, 0.0, s), Vec3::new(-s, 0.0, s)];
    m.faces = vec![Face { v: [0, 2, 1], n: None, material: 0, line: 0 }, Face { v: [0, 3, 2], n: None, material: 0, line: 0 }];
    m.materials = vec![Material::diffuse("floor", Color::splat(0.8))];
    let cam = Camera::new(Vec3::new(0.0, -1.5, 0.01), Vec3::ZERO, Vec3::Z, 60.0, 16, 16).unwrap();
    let mut scene = Scene::new("thin-floor", cam);
    scene.add_mesh(&m, &Placement::default(), None).unwrap();
    scene.lights.push(LightDesc::Point { position: Vec3::new(0.0, 1.0, 0.0), intensity: Color::splat(5.0) });
    let accel = make_accel("bvh", &scene.triangles).unwrap();
    World::new(scene, accel).unwrap()
}

#[test]
fn photons_on_the_far_side_of_a_thin_wall_do_not_leak() {
    let world = thin_floor_seen_from_below();
    let cfg = RenderConfig { integrator: "sppm".into(), ..Default::default() }
        .with("passes", 3)
        .with("photons_per_pass", 20_000)
        .with("sppm_direct", "photons")
        .with("sppm_radius", 0.2);
    let r = Reader::new(&cfg.params);
    let mut sppm = SppmIntegrator::new(&cfg, &r, make_rr("throughput").unwrap(), true).unwrap();
    let (film, _) = sppm.run(&world, &mut |_, _, _| {}).unwrap();
    // Every pixel sees the unlit underside, within 0.2 of thousands of photons on top.
    assert_eq!(film.mean(), Color::ZERO);
    assert!(sppm.stats()["photons_kept"] > 10_000.0);
    // The same floor seen from above is lit (the test can fail).
    let mut above = thin_floor_seen_from_below();
    above.scene.camera = Camera::new(Vec3::new(0.0, 1.5, 0.01), Vec3::ZERO, Vec3::Z, 60.0, 16, 16).unwrap();
    let (film, _) = sppm.run(&above, &mut |_, _, _| {}).unwrap();
    assert!(film.mean().x > 0.1, "{}", film.mean());
}

#[test]
fn bad_settings_are_named() {
    let err = |key: &str, v: toml::Value| {
        let c = RenderConfig { integrator: "sppm".into(), ..Default::default() }.with(key, v);
        SppmSetup::read(&c, &Reader::new(&c.params)).unwrap_err().to_string()
    };
    assert!(err("sppm_direct", "both".into()).contains("sppm_direct"));
    assert!(err("sppm_radius", (-1.0).into()).contains("sppm_radius"));
    assert!(err("alpha", f64::NAN.into()).contains("alpha"));
    assert!(err("photons_per_pass", 0.into()).contains("photons_per_pass"));
}
