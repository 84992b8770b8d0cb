//! Spot light: full intensity within `cone_deg` of its axis, falling linearly in angle
//! to zero at `falloff_deg` (scene contract).

use super::LightSample;
use crate::math::Color;
use glam::Vec3;
use std::f32::consts::PI;

/// Intensity scale for a direction at `angle_deg` from the axis.
#[inline]
pub fn spot_falloff(angle_deg: f32, cone_deg: f32, falloff_deg: f32) -> f32 {
    if angle_deg <= cone_deg {
        1.0
    } else if angle_deg >= falloff_deg {
        0.0
    } else {
        (falloff_deg - angle_deg) / (falloff_deg - cone_deg)
    }
}

/// Emitted power (scalar intensity `i`): 2π·I·∫ falloff(θ) sin θ dθ, integrated
/// numerically because the falloff is linear in angle.
pub(super) fn power(i: f32, cone_deg: f32, falloff_deg: f32) -> f32 {
    let outer = falloff_deg.max(cone_deg).min(180.0);
    let n = 512;
    let mut s = 0.0f64;
    for k in 0..n {
        let th = (k as f64 + 0.5) / n as f64 * outer as f64;
        s += spot_falloff(th as f32, cone_deg, falloff_deg) as f64 * th.to_radians().sin();
    }
    let integral = s * (outer as f64).to_radians() / n as f64;
    2.0 * PI * i * integral as f32
}

pub(super) fn sample_li(position: Vec3, axis: Vec3, intensity: Color, cone_deg: f32, falloff_deg: f32, p: Vec3) -> Option<LightSample> {
    let d = position - p;
    let d2 = d.length_squared();
    if d2 <= 0.0 {
        return None;
    }
    let dist = d2.sqrt();
    let wi = d / dist;
    let angle = (-wi).dot(axis).clamp(-1.0, 1.0).acos().to_degrees();
    let w = spot_falloff(angle, cone_deg, falloff_deg);
    if w <= 0.0 {
        return None;
    }
    Some(LightSample { wi, dist, li: intensity * (w / d2), pdf: 1.0, delta: true, point: position, normal: Vec3::ZERO })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn falloff_is_linear_in_angle() {
        assert_eq!(spot_falloff(10.0, 30.0, 40.0), 1.0);
        assert!((spot_falloff(35.0, 30.0, 40.0) - 0.5).abs() < 1e-6);
        assert_eq!(spot_falloff(45.0, 30.0, 40.0), 0.0);
        // Hard edge when falloff == cone.
        assert_eq!(spot_falloff(30.5, 30.0, 30.0), 0.0);
        // Power of a full-sphere "spot" equals a point light's 4πI.
        assert!((power(1.0, 180.0, 180.0) - 4.0 * PI).abs() < 1e-3);
    }
}
