//! A thin panel hanging 1 cm under a zero-thickness ceiling lit from above
//! (`lamp-panel`): the room is closed and lit only from outside, so its interior is
//! black. The panel's upper side faces the same way as the roof's lit top, 1 cm
//! away, so every estimate with a disc thicker than 1 cm (photon estimates,
//! precomputed-irradiance lookups at final-gather hits, the irradiance cache's
//! entries built from them) found the roof's photons through the ceiling: final-gather
//! rays from the ceiling into the gap lit the ceiling around the panel and the
//! panel's outline (image means 0.012–0.038 at 128², 4 spp, 200k photons; `path`: 0).

use photonlab::config::RenderConfig;
use photonlab::pipeline::render_scene;
use photonlab::scene::builtin::builtin;

#[test]
fn lamp_panel_room_stays_dark_for_every_gather_and_progressive_integrator() {
    let scene = builtin("lamp-panel").unwrap();
    let res = Some([32, 32]);
    let mean = |cfg: RenderConfig| render_scene(scene.clone(), &cfg, true).unwrap().film.mean().max_element();
    let reference = mean(RenderConfig { spp: 32, resolution: res, ..Default::default() });
    let bound = (10.0 * reference).max(1e-5);
    let photon = |gather: &str| {
        let cfg = RenderConfig { integrator: "photon".into(), spp: 2, resolution: res, seed: 3, ..Default::default() }
            .with("gather", gather)
            .with("photons", 100_000);
        if gather == "direct" { cfg } else { cfg.with("gather_samples", 32).with("gather_per", "sample") }
    };
    let mut runs: Vec<(String, RenderConfig)> =
        ["direct", "final_gather", "precomputed", "irradiance_cache"].iter().map(|g| (format!("photon, {g}"), photon(g))).collect();
    let progressive = |name: &str| {
        RenderConfig { integrator: name.into(), resolution: res, seed: 3, ..Default::default() }
            .with("passes", 2)
            .with("photons_per_pass", 100_000)
    };
    runs.push(("sppm".into(), progressive("sppm").with("sppm_direct", "photons")));
    runs.push(("ppm".into(), progressive("ppm")));
    let mut bad = Vec::new();
    for (name, cfg) in runs {
        let m = mean(cfg);
        eprintln!("lamp-panel, {name}: interior mean {m:.3e} (path {reference:.1e})");
        if m > bound {
            bad.push(format!("{name}: {m:.3e}"));
        }
    }
    assert!(bad.is_empty(), "the room under the lit ceiling glows (bound {bound:.1e}): {bad:?}");
}
