//! Environment-map sampling against its pdf: a synthetic map (smooth gradient, a
//! bright 2×2 "sun", rotated by `to_world`) sampled with `EnvMap::sample`, judged
//! against `EnvMap::pdf`; planted: the same samples against the pdf of the map turned
//! by another 40°.

use super::{DirCase, Outcome};
use crate::light::envmap::EnvMap;
use crate::math::Frame;
use crate::texture::Image;
use anyhow::Result;
use glam::{Mat4, Vec3};
use std::f64::consts::PI;
use std::sync::Arc;

fn sky() -> Result<Arc<Image>> {
    let (w, h) = (32u32, 17u32);
    let px = (0..w * h)
        .map(|k| {
            let (i, j) = (k % w, k / w);
            let b = if (11..13).contains(&i) && (4..6).contains(&j) { 30.0 } else { 0.2 + 0.8 * (j as f32 / h as f32) + 0.02 * i as f32 };
            [b, 0.9 * b, 0.7 * b, 1.0]
        })
        .collect();
    Ok(Arc::new(Image::new(w, h, px, false)?))
}

/// The pass case and the planted one.
pub(super) fn env_cases() -> Result<Vec<DirCase>> {
    let img = sky()?;
    let map = Arc::new(EnvMap::new(img.clone(), 1.0, Mat4::from_rotation_y(0.7))?);
    let turned = Arc::new(EnvMap::new(img, 1.0, Mat4::from_rotation_y(0.7 + 40f32.to_radians()))?);
    let case = |name: &str, pdf_of: Arc<EnvMap>, expected| {
        let m = map.clone();
        DirCase {
            name: name.into(),
            expected,
            frame: Frame::new(Vec3::Y),
            theta_max: PI,
            can_fail: false,
            sample: Box::new(move |_, u| m.sample(u).map(|s| s.0)),
            pdf: Box::new(move |w| pdf_of.pdf(w) as f64),
        }
    };
    Ok(vec![case("chi2/env/envmap", map.clone(), Outcome::Pass), case("chi2/planted/envmap_vs_turned_pdf", turned, Outcome::Fail)])
}
