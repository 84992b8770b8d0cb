//! Mitsuba `<emitter>` plug-ins: `area` (on a shape), `point`, `spot`,
//! `directional`, `constant` and `envmap`.
//!
//! Mitsuba's spot light falls off linearly in angle from `beam_width` to
//! `cutoff_angle`, which is the scene contract's spot with `cone_deg = beam_width`
//! and `falloff_deg = cutoff_angle`.

use super::textures::TextureCache;
use super::xml::{Plugin, SpectrumValue};
use crate::math::Color;
use crate::scene::LightDesc;
use anyhow::{Result, anyhow};
use glam::{Mat4, Vec3};

fn rgb(p: &Plugin, name: &str, default: f32) -> Result<Color> {
    match p.spectrum(name)? {
        None => Ok(Color::splat(default)),
        Some(SpectrumValue::Rgb(c)) if c.min_element() >= 0.0 && c.is_finite() => Ok(c),
        Some(SpectrumValue::Rgb(c)) => Err(p.err(format!("`{name}` must be finite and non-negative, got {c}"))),
        Some(SpectrumValue::Texture(t)) => Err(t.err(format!("a texture on `{name}` of {} is not supported", p.what()))),
    }
}

/// An `area` emitter nested in a shape: its radiance.
pub fn area(p: &Plugin) -> Result<Color> {
    if p.ty != "area" {
        return Err(p.err("only `area` emitters can be nested in a shape"));
    }
    let r = rgb(p, "radiance", 1.0)?;
    p.finish()?;
    Ok(r)
}

/// A top-level emitter.
pub fn emitter(p: &Plugin, cache: &mut TextureCache) -> Result<LightDesc> {
    let to_world = p.transform("to_world")?;
    let l = match p.ty.as_str() {
        "point" => {
            let position = match (p.point("position")?, to_world) {
                (Some(_), Some(_)) => return Err(p.err("give either `position` or `to_world`, not both")),
                (Some(q), None) => q,
                (None, m) => m.unwrap_or(Mat4::IDENTITY).transform_point3(Vec3::ZERO),
            };
            LightDesc::Point { position, intensity: rgb(p, "intensity", 1.0)? }
        }
        "spot" => {
            let m = to_world.unwrap_or(Mat4::IDENTITY);
            let cutoff = p.float_or("cutoff_angle", 20.0)?;
            let beam = p.float_or("beam_width", cutoff * 0.75)?;
            if !(cutoff > 0.0 && cutoff <= 180.0 && beam >= 0.0 && beam <= cutoff) {
                return Err(p.err(format!("need 0 <= beam_width <= cutoff_angle <= 180 and cutoff_angle > 0, got {beam} and {cutoff}")));
            }
            let direction = m.transform_vector3(Vec3::Z).normalize_or_zero();
            if direction == Vec3::ZERO {
                return Err(p.err("`to_world` maps the spot's axis to zero"));
            }
            LightDesc::Spot {
                position: m.transform_point3(Vec3::ZERO),
                direction,
                intensity: rgb(p, "intensity", 1.0)?,
                cone_deg: beam,
                falloff_deg: cutoff,
            }
        }
        "directional" => {
            let d = match (p.vector("direction")?, to_world) {
                (Some(_), Some(_)) => return Err(p.err("give either `direction` or `to_world`, not both")),
                (Some(d), None) => d,
                (None, m) => m.unwrap_or(Mat4::IDENTITY).transform_vector3(Vec3::Z),
            };
            let direction = d.normalize_or_zero();
            if direction == Vec3::ZERO {
                return Err(p.err("the direction is zero"));
            }
            LightDesc::Directional { direction, irradiance: rgb(p, "irradiance", 1.0)? }
        }
        "constant" => {
            if to_world.is_some() {
                return Err(p.err("`to_world` has no effect on a constant environment"));
            }
            LightDesc::Constant { radiance: rgb(p, "radiance", 1.0)? }
        }
        "envmap" => {
            let (name, loc) = p.string("filename")?.ok_or_else(|| p.err("needs a `filename` (an equirectangular EXR)"))?;
            let scale = p.float_or("scale", 1.0)?;
            if scale < 0.0 {
                return Err(p.err(format!("scale must not be negative, got {scale}")));
            }
            let image = cache.image(loc.resolve(&name), false).map_err(|e| anyhow!("{loc}: {e}"))?;
            let m = to_world.unwrap_or(Mat4::IDENTITY);
            LightDesc::Envmap { image, scale, to_world: m }
        }
        "area" => return Err(p.err("an `area` emitter must be nested in a <shape>")),
        other => {
            return Err(p.err(format!("emitter type `{other}` is not supported (area, point, spot, directional, constant, envmap)")));
        }
    };
    p.finish()?;
    Ok(l)
}
