//! The stratified hemisphere gather behind irradiance-cache entries, with Ward &
//! Heckbert's (1992) irradiance gradients.
//!
//! The hemisphere about the facing shading normal is split into M × N strata of
//! equal projected solid angle (sin²θ ∈ [j/M, (j+1)/M), φ ∈ [2πk/N, 2π(k+1)/N)), one
//! jittered ray per stratum, so E = π/(MN) Σ L_jk. The rotational gradient is
//! π/(MN) Σ_k v_k Σ_j −tanθ_j L_jk and the translational gradient is the sum over
//! the boundaries between neighbouring strata of the radiance difference divided by
//! the nearer hit distance, in the form of Křivánek & Gautron ("Practical Global
//! Illumination with Irradiance Caching", 2009, eq. 5.5/5.6 for cosine-weighted
//! strata).

use crate::accel::TraversalStats;
use crate::integrator::photon::context::{GatherPoint, PhotonContext};
use crate::math::{Color, Frame};
use crate::photon::estimate::facing_shading_normal;
use glam::Vec3;
use std::f32::consts::PI;

/// What one stratified gather measured.
#[derive(Clone, Copy, Debug, Default)]
pub struct HemisphereResult {
    /// Irradiance about the facing shading normal.
    pub irradiance: Color,
    /// Rotational gradient, one vector per colour channel.
    pub rot_grad: [Vec3; 3],
    /// Translational gradient, one vector per colour channel.
    pub trans_grad: [Vec3; 3],
    /// Harmonic mean of the hit distances (escaped rays count as infinitely far).
    pub harmonic_distance: f32,
    /// Smallest hit distance over rays at least 10° above the tangent plane.
    pub min_distance: f32,
}

/// Strata (M in θ, N in φ) for about `n` rays: N ≈ πM as Ward recommends.
pub fn strata(n: u32) -> (u32, u32) {
    let m = ((n as f32 / PI).sqrt().round() as u32).max(1);
    let k = ((n as f32 / m as f32).round() as u32).max(3);
    (m, k)
}

/// Gathers at `it` with about `n` stratified rays and computes the gradients.
pub fn gather(ctx: &PhotonContext, at: &GatherPoint, n: u32, stats: &mut TraversalStats) -> HemisphereResult {
    let GatherPoint { world, it, wo, key, .. } = *at;
    let (m, nk) = strata(n);
    let nrm = facing_shading_normal(it, wo);
    let frame = Frame::new(nrm);
    let side = wo.dot(it.sp.ng);
    let count = (m * nk) as usize;
    let mut l = vec![Color::ZERO; count];
    let mut d = vec![f32::INFINITY; count];
    let (mut inv_d, mut min_d) = (0.0f32, f32::INFINITY);
    for j in 0..m {
        for k in 0..nk {
            let idx = (j * nk + k) as usize;
            let (u0, u1) = (key.uniform(2 * idx as u64), key.uniform(2 * idx as u64 + 1));
            let sin2 = (j as f32 + u0) / m as f32;
            let (sin_t, cos_t) = (sin2.sqrt(), (1.0 - sin2).max(0.0).sqrt());
            let phi = 2.0 * PI * (k as f32 + u1) / nk as f32;
            let wi = frame.to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t));
            if wi.dot(it.sp.ng) * side <= 0.0 {
                continue;
            }
            let (li, dist) = ctx.gather_ray(world, world.spawn(it, wi), 0, key.child(idx as u64 + 1), stats);
            l[idx] = li;
            d[idx] = dist;
            if dist.is_finite() {
                inv_d += 1.0 / dist.max(1e-6);
                if cos_t > 0.174 {
                    min_d = min_d.min(dist);
                }
            }
        }
    }
    let dir = |phi: f32| frame.to_world(Vec3::new(phi.cos(), phi.sin(), 0.0));
    let mut e = Color::ZERO;
    let mut rot = [Vec3::ZERO; 3];
    let mut trans = [Vec3::ZERO; 3];
    let add = |g: &mut [Vec3; 3], c: Color, v: Vec3| {
        for (ch, gv) in g.iter_mut().enumerate() {
            *gv += v * c[ch];
        }
    };
    for j in 0..m {
        let (jm, mf) = (j as f32, m as f32);
        let cos_minus = (1.0 - jm / mf).sqrt();
        let sin_minus = (jm / mf).sqrt();
        let cos_mid = (1.0 - (jm + 0.5) / mf).sqrt();
        let sin_mid = ((jm + 0.5) / mf).sqrt();
        let cos_plus = (1.0 - (jm + 1.0) / mf).max(0.0).sqrt();
        let tan_mid = sin_mid / cos_mid.max(1e-6);
        for k in 0..nk {
            let idx = (j * nk + k) as usize;
            let phi_mid = 2.0 * PI * (k as f32 + 0.5) / nk as f32;
            let u_k = dir(phi_mid);
            let v_k = dir(phi_mid - 0.5 * PI);
            let v_k_minus = dir(2.0 * PI * k as f32 / nk as f32 + 0.5 * PI);
            e += l[idx];
            add(&mut rot, l[idx] * -tan_mid, v_k);
            if j > 0 {
                let other = ((j - 1) * nk + k) as usize;
                let md = d[idx].min(d[other]);
                if md.is_finite() && md > 0.0 {
                    let f = 2.0 * PI * cos_minus * cos_minus * sin_minus / (nk as f32 * md);
                    add(&mut trans, (l[idx] - l[other]) * f, u_k);
                }
            }
            let prev = (j * nk + if k == 0 { nk - 1 } else { k - 1 }) as usize;
            let md = d[idx].min(d[prev]);
            if md.is_finite() && md > 0.0 {
                let f = cos_mid * (cos_minus - cos_plus) / (md * sin_mid.max(1e-6));
                add(&mut trans, (l[idx] - l[prev]) * f, v_k_minus);
            }
        }
    }
    let scale = PI / count as f32;
    for g in &mut rot {
        *g *= scale;
    }
    HemisphereResult {
        irradiance: e * scale,
        rot_grad: rot,
        trans_grad: trans,
        harmonic_distance: if inv_d > 0.0 { count as f32 / inv_d } else { f32::INFINITY },
        min_distance: min_d,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strata_follow_ward() {
        assert_eq!(strata(64), (5, 13));
        assert_eq!(strata(1), (1, 3));
        let (m, n) = strata(256);
        assert!((m * n) as i32 - 256 < 12 && n >= 3 * m);
    }
}
