//! Equirectangular environment map (Mitsuba's `envmap`).
//!
//! Lookups follow Mitsuba 3 exactly: a direction `d` in the map's frame
//! (`to_world⁻¹·d`) has `u = atan2(d.x, −d.z)/2π`, `v = acos(d.y)/π`; the image is
//! interpolated bilinearly with texel columns centred at `(i + ½)/w` (wrapping in u)
//! and rows at `j/(h − 1)` (the first and last rows lie on the poles).
//!
//! Sampling: a 2-D piecewise-constant distribution over the bilinear cells, each
//! weighted by the mean luminance of its four corners times its solid angle; a
//! direction is uniform in (u, v) within its cell, so
//! `pdf(ω) = p_cell · w · (h − 1) / (2π² sin θ)`.

use crate::math::{Color, mean};
use crate::texture::Image;
use glam::{Mat3, Mat4, Vec2, Vec3};
use std::f32::consts::PI;
use std::sync::Arc;

/// Piecewise-constant 1-D distribution with continuous sampling.
#[derive(Clone, Debug)]
struct Pc1 {
    cdf: Vec<f64>,
    pmf: Vec<f32>,
}

impl Pc1 {
    fn new(w: &[f64]) -> Option<Pc1> {
        let total: f64 = w.iter().sum();
        if total <= 0.0 || !total.is_finite() {
            return None;
        }
        let mut cdf = Vec::with_capacity(w.len() + 1);
        let mut acc = 0.0;
        cdf.push(0.0);
        for &x in w {
            acc += x;
            cdf.push(acc / total);
        }
        Some(Pc1 { cdf, pmf: w.iter().map(|&x| (x / total) as f32).collect() })
    }
    /// Index and the position of `u` within its bin, in [0, 1).
    fn sample(&self, u: f32) -> (usize, f32) {
        let u = u as f64;
        let n = self.pmf.len();
        let mut i = self.cdf.partition_point(|&c| c <= u).saturating_sub(1).min(n - 1);
        while self.pmf[i] == 0.0 && i + 1 < n {
            i += 1;
        }
        let (a, b) = (self.cdf[i], self.cdf[i + 1]);
        let f = if b > a { ((u - a) / (b - a)).clamp(0.0, 1.0 - 1e-7) } else { 0.5 };
        (i, f as f32)
    }
}

/// An environment map ready for lookups and sampling.
#[derive(Clone, Debug)]
pub struct EnvMap {
    image: Arc<Image>,
    scale: f32,
    to_world: Mat3,
    to_local: Mat3,
    /// Row marginal (h − 1 rows), then one conditional per row (w columns).
    rows: Option<Pc1>,
    cols: Vec<Option<Pc1>>,
    /// ∫ mean(L) dω, approximated by each cell's corner mean times its solid angle
    /// (used to choose between lights only; the estimators do not depend on it).
    integral: f32,
}

fn luminance(c: [f32; 4]) -> f64 {
    (0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]).max(0.0) as f64
}

impl EnvMap {
    /// Builds the map and its sampling distribution.
    pub fn new(image: Arc<Image>, scale: f32, to_world: Mat4) -> anyhow::Result<EnvMap> {
        let (w, h) = (image.width as usize, image.height as usize);
        if h < 2 {
            anyhow::bail!("an environment map needs at least 2 rows, got {w}x{h}");
        }
        let m = Mat3::from_mat4(to_world);
        if m.determinant() == 0.0 {
            anyhow::bail!("environment map `to_world` is singular");
        }
        let t = |i: usize, j: usize| image.texel((i % w) as u32, j as u32);
        let mut row_w = Vec::with_capacity(h - 1);
        let mut cols = Vec::with_capacity(h - 1);
        let mut integral = 0.0f64;
        for j in 0..h - 1 {
            let (t0, t1) = (PI as f64 * j as f64 / (h - 1) as f64, PI as f64 * (j + 1) as f64 / (h - 1) as f64);
            let solid = (t0.cos() - t1.cos()) * 2.0 * PI as f64 / w as f64;
            let mut cw = Vec::with_capacity(w);
            for i in 0..w {
                let c = [t(i, j), t(i + 1, j), t(i, j + 1), t(i + 1, j + 1)];
                cw.push(c.iter().map(|&x| luminance(x)).sum::<f64>() * 0.25 * solid);
                integral += c.iter().map(|x| mean(Vec3::new(x[0], x[1], x[2])) as f64).sum::<f64>() * 0.25 * solid;
            }
            row_w.push(cw.iter().sum());
            cols.push(Pc1::new(&cw));
        }
        Ok(EnvMap {
            rows: Pc1::new(&row_w),
            cols,
            integral: (integral * scale as f64) as f32,
            to_local: m.inverse(),
            to_world: m,
            image,
            scale,
        })
    }

    /// ∫ mean(L) dω (scaled).
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// Mitsuba's (u, v) of a world direction.
    #[inline]
    fn uv(&self, d: Vec3) -> Vec2 {
        let v = (self.to_local * d).normalize_or_zero();
        let u = v.x.atan2(-v.z) * (0.5 / PI);
        Vec2::new(u - u.floor(), v.y.clamp(-1.0, 1.0).acos() / PI)
    }

    /// Position in the grid of bilinear cells (x in [0, w), y in [0, h − 1]).
    #[inline]
    fn grid(&self, uv: Vec2) -> Vec2 {
        let (w, h) = (self.image.width as f32, self.image.height as f32);
        let mut x = uv.x - 0.5 / w;
        x -= x.floor();
        Vec2::new(x * w, uv.y * (h - 1.0))
    }

    /// Radiance arriving from world direction `d` (pointing away from the scene).
    #[inline]
    pub fn eval(&self, d: Vec3) -> Color {
        let g = self.grid(self.uv(d));
        let (w, h) = (self.image.width, self.image.height);
        let i = (g.x.floor() as u32).min(w - 1);
        let j = (g.y.floor() as u32).min(h - 2);
        let (fx, fy) = (g.x - i as f32, g.y - j as f32);
        let t = |a: u32, b: u32| {
            let p = self.image.texel(a % w, b);
            Vec3::new(p[0], p[1], p[2])
        };
        let top = t(i, j) * (1.0 - fx) + t(i + 1, j) * fx;
        let bottom = t(i, j + 1) * (1.0 - fx) + t(i + 1, j + 1) * fx;
        (top * (1.0 - fy) + bottom * fy) * self.scale
    }

    /// Samples a direction towards the environment: (direction, radiance, pdf).
    #[inline]
    pub fn sample(&self, u: [f32; 2]) -> Option<(Vec3, Color, f32)> {
        let rows = self.rows.as_ref()?;
        let (j, fy) = rows.sample(u[0]);
        let (i, fx) = self.cols[j].as_ref()?.sample(u[1]);
        let (w, h) = (self.image.width as f32, self.image.height as f32);
        let gx = i as f32 + fx;
        let gy = j as f32 + fy;
        let mut su = gx / w + 0.5 / w;
        su -= su.floor();
        let (theta, phi) = (gy / (h - 1.0) * PI, su * 2.0 * PI);
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        // Mitsuba: sphdir(θ, φ) = (sinθ cosφ, sinθ sinφ, cosθ) → (y, z, −x).
        let local = Vec3::new(st * sp, ct, -st * cp);
        let d = (self.to_world * local).normalize_or_zero();
        let pdf = self.pdf(d);
        if pdf <= 0.0 || d == Vec3::ZERO {
            return None;
        }
        Some((d, self.eval(d), pdf))
    }

    /// Solid-angle pdf of [`EnvMap::sample`] for direction `d`.
    #[inline]
    pub fn pdf(&self, d: Vec3) -> f32 {
        let Some(rows) = &self.rows else { return 0.0 };
        let uv = self.uv(d);
        let g = self.grid(uv);
        let (w, h) = (self.image.width, self.image.height);
        let i = (g.x.floor() as usize).min(w as usize - 1);
        let j = (g.y.floor() as usize).min(h as usize - 2);
        let Some(c) = &self.cols[j] else { return 0.0 };
        let p = rows.pmf[j] * c.pmf[i];
        let sin_t = (uv.y * PI).sin();
        if sin_t <= 0.0 {
            return 0.0;
        }
        p * (w as f32) * (h - 1) as f32 / (2.0 * PI * PI * sin_t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::uniform_sphere;

    fn map() -> EnvMap {
        // 8x5 map with a bright texel and a gradient.
        let (w, h) = (8u32, 5u32);
        let px = (0..w * h)
            .map(|k| {
                let (i, j) = (k % w, k / w);
                let b = if (i, j) == (5, 1) { 20.0 } else { 0.1 + 0.05 * i as f32 + 0.02 * j as f32 };
                [b, 0.5 * b, 0.25 * b, 1.0]
            })
            .collect();
        let img = Image::new(w, h, px, false).unwrap();
        EnvMap::new(Arc::new(img), 2.0, Mat4::from_rotation_y(0.3)).unwrap()
    }

    #[test]
    fn pdf_integrates_to_one_and_matches_eval_direction() {
        let m = map();
        let n = 400;
        let (mut s, mut e) = (0.0f64, 0.0f64);
        for a in 0..n {
            for b in 0..n {
                let d = uniform_sphere([(a as f32 + 0.5) / n as f32, (b as f32 + 0.5) / n as f32]);
                s += m.pdf(d) as f64;
                e += mean(m.eval(d)) as f64;
            }
        }
        let norm = 4.0 * std::f64::consts::PI / (n * n) as f64;
        assert!((s * norm - 1.0).abs() < 5e-3, "∫pdf = {}", s * norm);
        // The integral is the cells' corner mean times their solid angle: an estimate
        // for light selection only (coarse here: 45° cells around a bright texel).
        assert!((e * norm / m.integral() as f64 - 1.0).abs() < 5e-2, "∫L {} vs {}", e * norm, m.integral());
        // Sampled directions carry their own pdf.
        for k in 0..50 {
            let u = [(k as f32 * 0.618) % 1.0, (k as f32 * 0.377 + 0.1) % 1.0];
            // (u = 0 is the pole, where the pdf vanishes: no sample.)
            let Some((d, l, p)) = m.sample(u) else { continue };
            assert!((p - m.pdf(d)).abs() <= 1e-3 * p, "{p} {}", m.pdf(d));
            assert_eq!(l, m.eval(d));
        }
    }

    #[test]
    fn mitsuba_orientation() {
        // A map bright only in its middle column band (u = 0.5) lights direction
        // +z in the map frame: atan2(0, -1) / 2π = 0.5.
        let (w, h) = (4u32, 3u32);
        let px = (0..w * h).map(|k| if k % w == 2 || k % w == 1 { [1.0; 4] } else { [0.0, 0.0, 0.0, 1.0] }).collect();
        let m = EnvMap::new(Arc::new(Image::new(w, h, px, false).unwrap()), 1.0, Mat4::IDENTITY).unwrap();
        assert!(m.eval(Vec3::Z).x > 0.99, "{}", m.eval(Vec3::Z));
        assert!(m.eval(-Vec3::Z).x < 0.01);
    }
}
