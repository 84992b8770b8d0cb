//! Mitsuba `<bsdf>` plug-ins → photonlab materials, one function per plug-in.
//!
//! Mapped now: `diffuse` → Lambertian, `dielectric` → smooth dielectric (η = int/ext),
//! `conductor` with `material="none"` → mirror, `twosided` (photonlab's BSDFs already
//! reflect on both sides). The remaining plug-ins (`conductor` presets and η/k,
//! `roughconductor`, `plastic`, `roughplastic`, `roughdielectric`, `thindielectric`,
//! `mask`) read and check all their parameters here and then stop with a clear error
//! until their BSDFs exist in `src/material/`; connecting one is the `todo_bsdf` call
//! in its function.

use super::presets;
use super::textures::{TextureCache, texture};
use super::xml::{Plugin, SpectrumValue};
use crate::material::{Bsdf, Dielectric, Lambertian, Material, Mirror};
use crate::math::Color;
use crate::texture::{Slot, Texture};
use anyhow::Result;
use glam::Vec3;

/// A mapped material with the textures it needs bound.
pub struct Mapped {
    /// The material (textured slots hold a placeholder constant).
    pub material: Material,
    /// Textured parameters.
    pub textures: Vec<(Slot, Texture)>,
    /// True when Mitsuba's BSDF is black from behind and no `twosided` wraps it
    /// (photonlab's reflect on both sides: reported as a warning).
    pub one_sided: bool,
}

fn name_of(p: &Plugin) -> String {
    p.id.clone().unwrap_or_else(|| p.ty.clone())
}

fn plain(p: &Plugin, bsdf: Bsdf, one_sided: bool) -> Mapped {
    Mapped { material: Material { name: name_of(p), bsdf, emission: Color::ZERO }, textures: Vec::new(), one_sided }
}

/// Maps a `<bsdf>`.
pub fn bsdf(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let m = match p.ty.as_str() {
        "diffuse" => diffuse(p, cache)?,
        "dielectric" => dielectric(p)?,
        "conductor" => conductor(p, cache)?,
        "twosided" => twosided(p, cache)?,
        "roughconductor" => roughconductor(p, cache)?,
        "roughdielectric" => roughdielectric(p)?,
        "thindielectric" => thindielectric(p)?,
        "plastic" => plastic(p, cache)?,
        "roughplastic" => roughplastic(p, cache)?,
        "mask" => mask(p, cache)?,
        other => {
            return Err(p.err(format!(
                "BSDF type `{other}` is not supported (diffuse, dielectric, thindielectric, roughdielectric, conductor, \
                 roughconductor, plastic, roughplastic, twosided, mask)"
            )));
        }
    };
    p.finish()?;
    Ok(m)
}

/// A colour parameter, constant or textured.
enum Param {
    Const(Color),
    Tex(Texture),
}

impl Param {
    /// The constant, or a placeholder (0.5) for a texture, plus the binding.
    fn split(self, slot: Slot, textures: &mut Vec<(Slot, Texture)>) -> Color {
        match self {
            Param::Const(c) => c,
            Param::Tex(t) => {
                textures.push((slot, t));
                Color::splat(0.5)
            }
        }
    }
}

fn colour(p: &Plugin, name: &str, default: f32, cache: &mut TextureCache) -> Result<Param> {
    Ok(match p.spectrum(name)? {
        None => Param::Const(Color::splat(default)),
        Some(SpectrumValue::Rgb(c)) => {
            if c.min_element() < 0.0 {
                return Err(p.err(format!("`{name}` must not be negative, got {c}")));
            }
            Param::Const(c)
        }
        Some(SpectrumValue::Texture(t)) => Param::Tex(texture(&t, cache)?),
    })
}

/// A constant colour (textures not supported for this parameter).
fn const_colour(p: &Plugin, name: &str, default: f32) -> Result<Color> {
    match p.spectrum(name)? {
        None => Ok(Color::splat(default)),
        Some(SpectrumValue::Rgb(c)) if c.min_element() >= 0.0 => Ok(c),
        Some(SpectrumValue::Rgb(c)) => Err(p.err(format!("`{name}` must not be negative, got {c}"))),
        Some(SpectrumValue::Texture(t)) => Err(t.err(format!("a texture on `{name}` of {} is not supported", p.what()))),
    }
}

/// An IOR given as a number or one of Mitsuba's names.
fn ior(p: &Plugin, name: &str, default: &str) -> Result<f32> {
    match p.number_or_name(name)? {
        Some(Ok(v)) if v > 0.0 => Ok(v),
        Some(Ok(v)) => Err(p.err(format!("`{name}` must be positive, got {v}"))),
        Some(Err((s, loc))) => presets::ior(&s).ok_or_else(|| anyhow::anyhow!("{loc}: {}: unknown IOR name `{s}` for `{name}`", p.what())),
        None => presets::ior(default).ok_or_else(|| p.err(format!("unknown default IOR `{default}`"))),
    }
}

fn todo_bsdf(p: &Plugin, params: impl std::fmt::Debug) -> anyhow::Error {
    p.err(format!("this BSDF is not supported yet by this build (parameters read: {params:?})"))
}

fn diffuse(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let mut textures = Vec::new();
    let albedo = colour(p, "reflectance", 0.5, cache)?.split(Slot::DiffuseReflectance, &mut textures);
    let mut m = plain(p, Bsdf::Lambertian(Lambertian { albedo }), true);
    m.textures = textures;
    Ok(m)
}

fn dielectric(p: &Plugin) -> Result<Mapped> {
    let int = ior(p, "int_ior", "bk7")?;
    let ext = ior(p, "ext_ior", "air")?;
    if const_colour(p, "specular_reflectance", 1.0)? != Color::ONE {
        return Err(p.err("specular_reflectance other than 1 is not supported"));
    }
    let tint = const_colour(p, "specular_transmittance", 1.0)?;
    Ok(plain(p, Bsdf::Dielectric(Dielectric { ior: int / ext, tint }), false))
}

/// Conductor parameters: a preset (`material`) or explicit `eta`/`k`.
#[derive(Debug)]
#[allow(dead_code)] // read by `todo_bsdf`'s message until the conductor BSDFs exist
struct ConductorParams {
    eta: Vec3,
    k: Vec3,
    ext_eta: f32,
    specular_reflectance: Color,
}

fn conductor_params(p: &Plugin) -> Result<Option<ConductorParams>> {
    let material = p.string("material")?;
    let (eta, k) = (p.spectrum("eta")?, p.spectrum("k")?);
    let specular_reflectance = const_colour(p, "specular_reflectance", 1.0)?;
    let ext_eta = ior(p, "ext_eta", "air")?;
    let rgb = |v: Option<SpectrumValue>, name: &str| match v {
        Some(SpectrumValue::Rgb(c)) => Ok(c),
        Some(SpectrumValue::Texture(t)) => Err(t.err(format!("a texture on `{name}` is not supported"))),
        None => Err(p.err(format!("`eta` and `k` must be given together (missing `{name}`)"))),
    };
    let (eta, k) = match (material, eta.is_some() || k.is_some()) {
        (Some(_), true) => return Err(p.err("give either `material` or `eta`/`k`, not both")),
        (Some((name, loc)), false) if name == "none" => {
            let _ = loc;
            return Ok(None);
        }
        (Some((name, loc)), false) => {
            presets::conductor(&name).ok_or_else(|| anyhow::anyhow!("{loc}: {}: unknown conductor preset `{name}`", p.what()))?
        }
        (None, true) => (rgb(eta, "eta")?, rgb(k, "k")?),
        // Mitsuba 3's default material is `none`: a perfect mirror.
        (None, false) => return Ok(None),
    };
    Ok(Some(ConductorParams { eta, k, ext_eta, specular_reflectance }))
}

fn conductor(p: &Plugin, _cache: &mut TextureCache) -> Result<Mapped> {
    // `material="none"` (the default) reflects everything: photonlab's mirror.
    match conductor_params(p)? {
        None => {
            let reflectance = const_colour(p, "specular_reflectance", 1.0)?;
            Ok(plain(p, Bsdf::Mirror(Mirror { reflectance }), true))
        }
        Some(c) => Err(todo_bsdf(p, c)),
    }
}

/// Microfacet distribution and roughness.
#[derive(Debug)]
#[allow(dead_code)]
struct Rough {
    /// `ggx` or `beckmann`.
    distribution: String,
    alpha: f32,
    sample_visible: bool,
}

fn rough(p: &Plugin) -> Result<Rough> {
    let distribution = p.string("distribution")?.map_or_else(|| "beckmann".to_string(), |s| s.0);
    if distribution != "ggx" && distribution != "beckmann" {
        return Err(p.err(format!("distribution must be `ggx` or `beckmann`, got `{distribution}`")));
    }
    if p.float("alpha_u")?.is_some() || p.float("alpha_v")?.is_some() {
        return Err(p.err("anisotropic roughness (alpha_u/alpha_v) is not supported"));
    }
    let alpha = p.float_or("alpha", 0.1)?;
    if alpha.is_nan() || alpha <= 0.0 {
        return Err(p.err(format!("alpha must be positive, got {alpha}")));
    }
    let sample_visible = p.bool_or("sample_visible", true)?;
    Ok(Rough { distribution, alpha, sample_visible })
}

fn roughconductor(p: &Plugin, _cache: &mut TextureCache) -> Result<Mapped> {
    let r = rough(p)?;
    let c = conductor_params(p)?;
    Err(todo_bsdf(p, (r, c)))
}

fn roughdielectric(p: &Plugin) -> Result<Mapped> {
    let r = rough(p)?;
    let iors = (ior(p, "int_ior", "bk7")?, ior(p, "ext_ior", "air")?);
    let spec = (const_colour(p, "specular_reflectance", 1.0)?, const_colour(p, "specular_transmittance", 1.0)?);
    Err(todo_bsdf(p, (r, iors, spec)))
}

fn thindielectric(p: &Plugin) -> Result<Mapped> {
    let iors = (ior(p, "int_ior", "bk7")?, ior(p, "ext_ior", "air")?);
    let spec = (const_colour(p, "specular_reflectance", 1.0)?, const_colour(p, "specular_transmittance", 1.0)?);
    Err(todo_bsdf(p, (iors, spec)))
}

fn plastic(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let iors = (ior(p, "int_ior", "polypropylene")?, ior(p, "ext_ior", "air")?);
    let mut textures = Vec::new();
    let kd = colour(p, "diffuse_reflectance", 0.5, cache)?.split(Slot::DiffuseReflectance, &mut textures);
    let ks = const_colour(p, "specular_reflectance", 1.0)?;
    let nonlinear = p.bool_or("nonlinear", false)?;
    Err(todo_bsdf(p, (iors, kd, ks, nonlinear)))
}

fn roughplastic(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let r = rough(p)?;
    let iors = (ior(p, "int_ior", "polypropylene")?, ior(p, "ext_ior", "air")?);
    let mut textures = Vec::new();
    let kd = colour(p, "diffuse_reflectance", 0.5, cache)?.split(Slot::DiffuseReflectance, &mut textures);
    let ks = const_colour(p, "specular_reflectance", 1.0)?;
    let nonlinear = p.bool_or("nonlinear", false)?;
    Err(todo_bsdf(p, (r, iors, kd, ks, nonlinear)))
}

fn twosided(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let inner = p.children("bsdf");
    match inner.as_slice() {
        [b] => {
            if b.ty == "twosided" {
                return Err(b.err("a twosided BSDF inside another"));
            }
            let mut m = bsdf(b, cache)?;
            if let Some(id) = &p.id {
                m.material.name = id.clone();
            }
            m.one_sided = false;
            Ok(m)
        }
        [_, b] => Err(b.err("twosided with different front and back BSDFs is not supported")),
        _ => Err(p.err("needs exactly one nested <bsdf>")),
    }
}

fn mask(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let opacity = colour(p, "opacity", 0.5, cache)?;
    let inner = p.child("bsdf")?.ok_or_else(|| p.err("needs a nested <bsdf>"))?;
    let m = bsdf(&inner, cache)?;
    let o = match opacity {
        Param::Const(c) => format!("{c}"),
        Param::Tex(_) => "texture".into(),
    };
    Err(todo_bsdf(p, (o, m.material.name)))
}
