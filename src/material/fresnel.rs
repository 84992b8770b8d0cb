//! Fresnel equations in the forms Mitsuba 3 uses (`include/mitsuba/render/fresnel.h`):
//! the dielectric one with the transmitted cosine and relative indices, the
//! conductor one with a complex index, and the hemispherical (diffuse) average.

/// Unpolarised dielectric Fresnel for a direction with cosine `cos_i` (positive
/// outside, negative inside) at an interface of relative index `eta` = η_inside / η_outside.
/// Returns the reflectance, the signed cosine of the transmitted direction (opposite
/// side; 0 on total internal reflection), η_it and η_ti = 1/η_it, as Mitsuba's `fresnel`.
pub fn fresnel_full(cos_i: f32, eta: f32) -> (f32, f32, f32, f32) {
    let outside = cos_i >= 0.0;
    let (eta_it, eta_ti) = if outside { (eta, 1.0 / eta) } else { (1.0 / eta, eta) };
    let cos_t2 = 1.0 - eta_ti * eta_ti * (1.0 - cos_i * cos_i).max(0.0);
    let ci = cos_i.abs();
    if cos_t2 <= 0.0 {
        return (1.0, 0.0, eta_it, eta_ti);
    }
    let ct = cos_t2.sqrt();
    let r = if eta == 1.0 {
        0.0
    } else if ci == 0.0 {
        1.0
    } else {
        let a_s = (ci - eta_it * ct) / (ci + eta_it * ct);
        let a_p = (ct - eta_it * ci) / (ct + eta_it * ci);
        0.5 * (a_s * a_s + a_p * a_p)
    };
    (r, if outside { -ct } else { ct }, eta_it, eta_ti)
}

/// Dielectric reflectance alone.
#[inline]
pub fn fresnel_dielectric_eta(cos_i: f32, eta: f32) -> f32 {
    fresnel_full(cos_i, eta).0
}

/// Unpolarised reflectance of a conductor with complex relative index η + i·k for a
/// direction with cosine `cos_i` ∈ [0, 1] (Mitsuba's `fresnel_conductor`).
pub fn fresnel_conductor(cos_i: f32, eta: f32, k: f32) -> f32 {
    let (c, eta, k) = (cos_i.clamp(0.0, 1.0) as f64, eta as f64, k as f64);
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let s4 = s2 * s2;
    let t1 = eta * eta - k * k - s2;
    let a2pb2 = (t1 * t1 + 4.0 * k * k * eta * eta).max(0.0).sqrt();
    let a = (0.5 * (a2pb2 + t1)).max(0.0).sqrt();
    let term1 = a2pb2 + c2;
    let term2 = 2.0 * c * a;
    let r_s = (term1 - term2) / (term1 + term2);
    let term3 = a2pb2 * c2 + s4;
    let term4 = term2 * s2;
    let r_p = r_s * (term3 - term4) / (term3 + term4);
    (0.5 * (r_s + r_p)) as f32
}

/// Hemispherical average 2∫F(μ)μ dμ of the dielectric reflectance seen from the side
/// where the relative index is `eta` (Mitsuba's `fresnel_diffuse_reflectance`, which
/// uses polynomial fits within 0.1 % of this for η ∈ [1, 2]; here by quadrature).
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let n = 4096;
    let mut s = 0.0f64;
    for i in 0..n {
        let mu = (i as f64 + 0.5) / n as f64;
        s += fresnel_dielectric_eta(mu as f32, eta) as f64 * 2.0 * mu;
    }
    (s / n as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_matches_existing_and_snell() {
        for ct in [0.05f32, 0.3, 0.7, 1.0] {
            let a = fresnel_dielectric_eta(ct, 1.5);
            let b = super::super::dielectric::fresnel_dielectric(ct, 1.0, 1.5);
            assert!((a - b).abs() < 1e-6);
            let (_, cos_t, _, eta_ti) = fresnel_full(ct, 1.5);
            let st = (1.0 - cos_t * cos_t).sqrt();
            assert!((st - eta_ti * (1.0 - ct * ct).sqrt()).abs() < 1e-5 && cos_t < 0.0);
            // From inside.
            let c = fresnel_dielectric_eta(-ct, 1.5);
            assert!((c - super::super::dielectric::fresnel_dielectric(ct, 1.5, 1.0)).abs() < 1e-6);
        }
    }

    #[test]
    fn conductor_limits() {
        // k = 0 reduces to the dielectric formula.
        for ct in [0.2f32, 0.6, 1.0] {
            assert!((fresnel_conductor(ct, 1.5, 0.0) - fresnel_dielectric_eta(ct, 1.5)).abs() < 1e-5);
        }
        // Normal incidence: ((η−1)² + k²)/((η+1)² + k²). Gold-ish red channel.
        let (e, k) = (0.143f32, 3.983f32);
        let r0 = ((e - 1.0).powi(2) + k * k) / ((e + 1.0).powi(2) + k * k);
        assert!((fresnel_conductor(1.0, e, k) - r0).abs() < 1e-5);
        assert!((fresnel_conductor(0.0, e, k) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn diffuse_reflectance_known_values() {
        // Egan & Hilgeman's fit of the internal value (light inside a medium of relative
        // index η > 1): −1.440/η² + 0.710/η + 0.668 + 0.0636·η (the fit Mitsuba 3 uses
        // for η < 1 in our convention), good to ~0.5 % for η ≤ 2.
        for eta in [1.33f32, 1.5, 1.9] {
            let e = eta as f64;
            let fit = -1.440 / (e * e) + 0.710 / e + 0.668 + 0.0636 * e;
            let q = fresnel_diffuse_reflectance(1.0 / eta) as f64;
            assert!((q - fit).abs() < 0.006 * fit, "η {eta}: {q} vs {fit}");
        }
        // External, η = 1.5: 0.0918 (hemispherical average of the Fresnel reflectance).
        assert!((fresnel_diffuse_reflectance(1.5) - 0.0918).abs() < 5e-4, "{}", fresnel_diffuse_reflectance(1.5));
        // Inside: 1 − (1 − F_dr,ext)/η².
        let ext = fresnel_diffuse_reflectance(1.5);
        let int = fresnel_diffuse_reflectance(1.0 / 1.5);
        assert!((int - (1.0 - (1.0 - ext) / 2.25)).abs() < 1e-3, "{int} {ext}");
    }
}
