//! Small math helpers shared by every module: colours, orthonormal frames and the
//! canonical warps from the unit square to sphere, hemisphere, cone and triangle.

use glam::Vec3;
use std::f32::consts::PI;

/// Linear RGB radiance / power / reflectance triple.
pub type Color = Vec3;

/// Mean of the three channels: the scalar "power" used to build light and photon
/// distributions (any positive weight keeps the estimators unbiased).
#[inline]
pub fn mean(c: Color) -> f32 {
    (c.x + c.y + c.z) * (1.0 / 3.0)
}

/// Largest channel.
#[inline]
pub fn max_component(c: Color) -> f32 {
    c.x.max(c.y).max(c.z)
}

/// True when every channel is finite.
#[inline]
pub fn is_finite(c: Color) -> bool {
    c.x.is_finite() && c.y.is_finite() && c.z.is_finite()
}

/// Orthonormal frame around a unit normal (Duff et al. 2017 branchless construction).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// First tangent.
    pub s: Vec3,
    /// Second tangent.
    pub t: Vec3,
    /// Normal.
    pub n: Vec3,
}

impl Frame {
    /// Builds a frame whose third axis is `n` (must be unit length).
    #[inline]
    pub fn new(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }
    /// World to local coordinates.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }
    /// Local to world coordinates.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Cosine-weighted direction on the +z hemisphere (Malley's method on a concentric disc).
#[inline]
pub fn cosine_hemisphere(u: [f32; 2]) -> Vec3 {
    let d = concentric_disc(u);
    let z = (1.0 - d[0] * d[0] - d[1] * d[1]).max(0.0).sqrt();
    Vec3::new(d[0], d[1], z)
}

/// Pdf (solid angle) of [`cosine_hemisphere`].
#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) / PI
}

/// Shirley–Chiu concentric map from the square to the unit disc.
#[inline]
pub fn concentric_disc(u: [f32; 2]) -> [f32; 2] {
    let ox = 2.0 * u[0] - 1.0;
    let oy = 2.0 * u[1] - 1.0;
    if ox == 0.0 && oy == 0.0 {
        return [0.0, 0.0];
    }
    // θ = a or π/2 − a with a in [−π/4, π/4]: sin and cos of a by polynomials
    // (a libm `sincosf` was 3 % of a `precomputed` render).
    if ox.abs() > oy.abs() {
        let (s, c) = sin_cos_quarter((PI / 4.0) * (oy / ox));
        [ox * c, ox * s]
    } else {
        let (s, c) = sin_cos_quarter((PI / 4.0) * (ox / oy));
        [oy * s, oy * c]
    }
}

/// sin a and cos a for a in [−π/4, π/4]: Taylor polynomials to a⁹ and a¹⁰, whose
/// truncation error (below 3e-10 there) is far under f32 rounding.
#[inline(always)]
pub fn sin_cos_quarter(a: f32) -> (f32, f32) {
    let a2 = a * a;
    let s = a * (1.0 + a2 * (-1.0 / 6.0 + a2 * (1.0 / 120.0 + a2 * (-1.0 / 5040.0 + a2 * (1.0 / 362_880.0)))));
    let c = 1.0 + a2 * (-0.5 + a2 * (1.0 / 24.0 + a2 * (-1.0 / 720.0 + a2 * (1.0 / 40_320.0 - a2 * (1.0 / 3_628_800.0)))));
    (s, c)
}

/// Uniform direction on the unit sphere.
#[inline]
pub fn uniform_sphere(u: [f32; 2]) -> Vec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Pdf of [`uniform_sphere`].
pub const UNIFORM_SPHERE_PDF: f32 = 1.0 / (4.0 * PI);

/// Uniform direction inside the cone of half-angle `acos(cos_max)` around +z.
#[inline]
pub fn uniform_cone(u: [f32; 2], cos_max: f32) -> Vec3 {
    let cos_t = 1.0 - u[0] * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u[1];
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// Pdf of [`uniform_cone`].
#[inline]
pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Barycentrics (b1, b2) of a point uniform in area on a triangle.
#[inline]
pub fn uniform_triangle(u: [f32; 2]) -> [f32; 2] {
    let su = u[0].sqrt();
    [1.0 - su, u[1] * su]
}

/// Power heuristic (β = 2) weight of strategy `f` against `g`, with one sample each.
#[inline]
pub fn power_heuristic(f_pdf: f32, g_pdf: f32) -> f32 {
    let f2 = f_pdf * f_pdf;
    let g2 = g_pdf * g_pdf;
    if f2 + g2 == 0.0 {
        0.0
    } else if f2.is_infinite() {
        1.0
    } else {
        f2 / (f2 + g2)
    }
}

/// Mirror `v` about `n` (both pointing away from the surface).
#[inline]
pub fn reflect(v: Vec3, n: Vec3) -> Vec3 {
    2.0 * v.dot(n) * n - v
}

/// SplitMix64 finaliser: a cheap, well-mixed 64-bit hash used to derive independent
/// per-pixel / per-dimension seeds.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash of several words (order-sensitive).
#[inline]
pub fn hash_words(words: &[u64]) -> u64 {
    let mut h = 0x51_7C_C1_B7_27_22_0A_95u64;
    for &w in words {
        h = mix64(h ^ w);
    }
    h
}

/// Maps 32 random bits to a float in [0, 1).
#[inline]
pub fn u32_to_unit(x: u32) -> f32 {
    // 24 high bits -> exactly representable, strictly below 1.
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// The largest f32 strictly below 1.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// 64-bit FNV-1a, stable across platforms and compiler versions (cache keys).
#[derive(Clone, Copy)]
pub struct Fnv(pub u64);

impl Default for Fnv {
    fn default() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    /// Adds bytes.
    pub fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 ^= *b as u64;
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }
    /// Adds a length-prefixed string (so concatenations cannot collide).
    pub fn str(&mut self, s: &str) {
        self.write(&(s.len() as u64).to_le_bytes());
        self.write(s.as_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal() {
        for n in [Vec3::Z, -Vec3::Z, Vec3::X, Vec3::new(0.3, -0.5, 0.8).normalize()] {
            let f = Frame::new(n);
            assert!((f.s.length() - 1.0).abs() < 1e-5);
            assert!((f.t.length() - 1.0).abs() < 1e-5);
            assert!(f.s.dot(f.t).abs() < 1e-5 && f.s.dot(n).abs() < 1e-5);
            let v = Vec3::new(0.2, 0.4, -0.7);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
        }
    }

    #[test]
    fn quarter_sin_cos_is_accurate_and_the_disc_map_unchanged() {
        for i in 0..=20_000 {
            let a = (i as f64 / 20_000.0 - 0.5) * std::f64::consts::FRAC_PI_2;
            let (s, c) = sin_cos_quarter(a as f32);
            let (ws, wc) = (a as f32 as f64).sin_cos();
            assert!((s as f64 - ws).abs() <= 1.2e-7 && (c as f64 - wc).abs() <= 1.2e-7, "{a}: {s} {c}");
        }
        // The polynomial map against the textbook one (θ from libm), over the square.
        for i in 0..200 {
            for j in 0..200 {
                let u = [(i as f32 + 0.37) / 200.0, (j as f32 + 0.71) / 200.0];
                let (ox, oy) = (2.0 * u[0] as f64 - 1.0, 2.0 * u[1] as f64 - 1.0);
                let (r, t) = if ox.abs() > oy.abs() {
                    (ox, std::f64::consts::FRAC_PI_4 * (oy / ox))
                } else {
                    (oy, std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * (ox / oy))
                };
                let d = concentric_disc(u);
                assert!((d[0] as f64 - r * t.cos()).abs() < 3e-7 && (d[1] as f64 - r * t.sin()).abs() < 3e-7, "{u:?}");
            }
        }
    }

    #[test]
    fn warps_stay_in_domain() {
        for i in 0..100 {
            let u = [(i as f32 + 0.5) / 100.0, ((i * 37) % 100) as f32 / 100.0];
            assert!(cosine_hemisphere(u).z >= 0.0);
            assert!((uniform_sphere(u).length() - 1.0).abs() < 1e-5);
            let b = uniform_triangle(u);
            assert!(b[0] >= 0.0 && b[1] >= 0.0 && b[0] + b[1] <= 1.0 + 1e-6);
        }
        assert!(u32_to_unit(u32::MAX) < 1.0);
    }
}
