//! Mitsuba's multipliers on the BSDFs that have them (as a texture sets them at a
//! hit, by name): the reflected part scales by `specular_reflectance`, the transmitted
//! part by `specular_transmittance`, everything else (a plastic's base) stays: each
//! value is linear in its part's multiplier and, but for the base, 0 at 0. Sampled
//! directions, lobe choices and pdfs are those of the unscaled BSDF.

use super::*;

const R: Color = Color::new(0.2, 0.5, 0.8);
const T: Color = Color::new(0.9, 0.6, 0.3);

/// One of each BSDF with `specular_reflectance` (and `specular_transmittance`).
fn bsdfs() -> Vec<(Bsdf, bool)> {
    let (eta, k) = (Color::new(0.2, 0.9, 1.1), Color::new(3.9, 2.4, 1.9));
    let ggx = MicrofacetType::Ggx;
    vec![
        (Bsdf::Mirror(Mirror { reflectance: Color::ONE }), false),
        (Bsdf::Conductor(Conductor { eta, k, specular_reflectance: Color::ONE }), false),
        (Bsdf::RoughConductor(RoughConductor { distribution: ggx, alpha: 0.3, eta, k, specular_reflectance: Color::ONE }), false),
        (Bsdf::Dielectric(Dielectric::new(1.5, Color::ONE)), true),
        (
            Bsdf::RoughDielectric(RoughDielectric {
                distribution: MicrofacetType::Beckmann,
                alpha: 0.3,
                int_ior: 1.5,
                ext_ior: 1.0,
                specular_reflectance: Color::ONE,
                specular_transmittance: Color::ONE,
            }),
            true,
        ),
        (
            Bsdf::ThinDielectric(ThinDielectric {
                int_ior: 1.5,
                ext_ior: 1.0,
                specular_reflectance: Color::ONE,
                specular_transmittance: Color::ONE,
            }),
            true,
        ),
        (Bsdf::Plastic(Plastic::new(Color::new(0.6, 0.3, 0.1), Color::ONE, 1.5, 1.0, false)), false),
        (Bsdf::RoughPlastic(RoughPlastic::new(ggx, 0.2, Color::new(0.6, 0.3, 0.1), Color::ONE, 1.5, 1.0, true)), false),
    ]
}

/// The BSDF with its multipliers set by name.
fn with(b: &Bsdf, transmits: bool, r: Color, t: Color) -> Bsdf {
    let mut b = b.clone();
    assert!(b.set_color_param("specular_reflectance", r), "{}", b.kind_name());
    assert_eq!(b.set_color_param("specular_transmittance", t), transmits, "{}", b.kind_name());
    b
}

fn close(a: Color, b: Color, what: &str) {
    assert!((a - b).abs().max_element() <= 2e-6 * (1.0 + b.abs().max_element()), "{what}: {a} vs {b}");
}

/// Expected value of a part linear in the multipliers: `zero` (both 0) plus the
/// multiplier of the part (R for reflection, T for transmission) times `one − zero`.
fn expect(zero: Color, one: Color, reflect: bool) -> Color {
    zero + (if reflect { R } else { T }) * (one - zero)
}

fn dirs() -> Vec<Vec3> {
    let d = [[0.3, 0.1, 0.9], [-0.5, 0.2, 0.7], [0.8, 0.0, 0.2], [-0.2, 0.1, -0.9], [0.6, -0.3, -0.5], [0.0, 0.0, 1.0]];
    d.iter().map(|v| Vec3::from_array(*v).normalize()).collect()
}

#[test]
fn reflected_part_scales_by_specular_reflectance_transmitted_by_specular_transmittance() {
    let sps = [ShadingPoint::new(Vec3::Z, Vec3::Z), ShadingPoint::new(Vec3::Z, Vec3::new(0.1, -0.05, 1.0).normalize())];
    let mut checked = [0usize; 3];
    for (b, transmits) in bsdfs() {
        let name = b.kind_name();
        // Every part but a plastic's base is scaled: with both multipliers 0 only the
        // base is left (the base is not delta).
        let base = matches!(b, Bsdf::Plastic(_) | Bsdf::RoughPlastic(_));
        let vanishes = |c: Color, delta: bool| assert!((base && !delta) || c == Color::ZERO, "{name}: {c} with multipliers 0");
        let (zero, one, scaled) =
            (with(&b, transmits, Color::ZERO, Color::ZERO), with(&b, transmits, Color::ONE, Color::ONE), with(&b, transmits, R, T));
        for sp in &sps {
            for wo in dirs() {
                let reflects = |wi: Vec3| wi.dot(sp.ng) * wo.dot(sp.ng) > 0.0;
                // eval and pdf: value scaled per part, pdf unchanged; reflection reciprocal.
                for wi in dirs() {
                    let v = scaled.eval(sp, wo, wi);
                    vanishes(zero.eval(sp, wo, wi), false);
                    close(v, expect(zero.eval(sp, wo, wi), one.eval(sp, wo, wi), reflects(wi)), &format!("{name} eval {wo} {wi}"));
                    assert_eq!(scaled.pdf(sp, wo, wi), one.pdf(sp, wo, wi), "{name} pdf");
                    if reflects(wi) && v.max_element() > 0.0 {
                        close(scaled.eval(sp, wi, wo), v, &format!("{name} reciprocity"));
                        checked[0] += 1;
                    }
                }
                // Sampling: same direction, lobe and pdf; the weight scaled by its part.
                for u_lobe in [0.01f32, 0.3, 0.6, 0.97] {
                    for u in [[0.2f32, 0.7], [0.55, 0.1], [0.9, 0.45]] {
                        let s = scaled.sample(sp, wo, u_lobe, u, TransportMode::Radiance);
                        let (s0, s1) = (
                            zero.sample(sp, wo, u_lobe, u, TransportMode::Radiance),
                            one.sample(sp, wo, u_lobe, u, TransportMode::Radiance),
                        );
                        assert_eq!(s.is_some(), s1.is_some(), "{name} sample {wo}");
                        let (Some(s), Some(s0), Some(s1)) = (s, s0, s1) else { continue };
                        assert!(s.wi == s1.wi && s.pdf == s1.pdf && s.delta == s1.delta && s0.wi == s1.wi, "{name} {wo}");
                        close(s.weight, expect(s0.weight, s1.weight, reflects(s.wi)), &format!("{name} weight {wo} → {}", s.wi));
                        vanishes(s0.weight, s.delta);
                        checked[1 + usize::from(!reflects(s.wi))] += 1;
                    }
                }
                // The delta lobes a Whitted-style tracer follows.
                let ((b, n), (b0, _), (b1, n1)) = (
                    scaled.specular_branches(sp, wo, TransportMode::Importance),
                    zero.specular_branches(sp, wo, TransportMode::Importance),
                    one.specular_branches(sp, wo, TransportMode::Importance),
                );
                assert_eq!(n, n1, "{name} branches");
                for i in 0..n {
                    assert_eq!(b[i].0, b1[i].0, "{name} branch direction");
                    close(b[i].1, expect(b0[i].1, b1[i].1, reflects(b[i].0)), &format!("{name} branch {i}"));
                    vanishes(b0[i].1, true);
                }
            }
        }
    }
    // Both parts and reciprocal pairs were met.
    assert!(checked.iter().all(|&c| c > 50), "{checked:?}");
}

/// The smooth dielectric, explicitly: Fresnel-chosen lobes, the reflected weight is
/// `specular_reflectance`, the refracted one the tint times the radiance scaling.
#[test]
fn smooth_dielectric_weights() {
    let g = Bsdf::Dielectric(Dielectric { ior: 1.5, tint: T, specular_reflectance: R });
    let sp = ShadingPoint::new(Vec3::Z, Vec3::Z);
    let wo = Vec3::new(0.6, 0.0, 0.8);
    let f = dielectric::fresnel_dielectric(0.8, 1.0, 1.5);
    let r = g.sample(&sp, wo, 0.5 * f, [0.0; 2], TransportMode::Radiance).unwrap();
    assert!(r.wi.z > 0.0 && r.pdf == f && r.weight == R, "{r:?}");
    let t = g.sample(&sp, wo, 0.99, [0.0; 2], TransportMode::Radiance).unwrap();
    assert!(t.wi.z < 0.0 && (t.pdf - (1.0 - f)).abs() < 1e-7);
    close(t.weight, T / 2.25, "refracted");
    assert_eq!(g.albedo(), T.max(R * dielectric::fresnel(1.0, 1.5)));
}
