//! Mitsuba `<bsdf>` plug-ins → photonlab materials, one function per plug-in.
//!
//! Each plug-in reads and checks all its parameters (Mitsuba 3's names and defaults) and
//! maps onto the BSDF of the same name in `src/material/`: `diffuse` → Lambertian,
//! `dielectric` → smooth dielectric (η = int/ext), `conductor` (`material="none"`: a
//! perfect mirror; presets or `eta`/`k`, divided by `ext_eta`), `roughconductor`,
//! `plastic`, `roughplastic`, `roughdielectric`, `thindielectric`, `twosided` and `mask`.
//! Photonlab's Lambertian and mirror reflect on both sides, so a bare `diffuse` or
//! `conductor none` is reported as a warning (Mitsuba's are black from behind); the
//! microfacet and plastic BSDFs are one-sided exactly as in Mitsuba, and `twosided`
//! makes them two-sided.
//!
//! Every reflectance parameter takes a constant or a texture: `reflectance`,
//! `diffuse_reflectance`, `specular_reflectance`, `specular_transmittance` and a
//! mask's `opacity`. `eta`, `k`, the IORs and the roughness are constants only.

use super::presets;
use super::textures::{TextureCache, texture};
use super::xml::{Plugin, SpectrumValue};
use crate::material::{
    Bsdf, Conductor, Dielectric, Lambertian, Mask, Material, MicrofacetType, Mirror, Plastic, RoughConductor, RoughDielectric,
    RoughPlastic, ThinDielectric, TwoSided,
};
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
        "dielectric" => dielectric(p, cache)?,
        "conductor" => conductor(p, cache)?,
        "twosided" => twosided(p, cache)?,
        "roughconductor" => roughconductor(p, cache)?,
        "roughdielectric" => roughdielectric(p, cache)?,
        "thindielectric" => thindielectric(p, cache)?,
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

/// `specular_reflectance` (default 1), constant or bound to its slot.
fn specular_reflectance(p: &Plugin, cache: &mut TextureCache, textures: &mut Vec<(Slot, Texture)>) -> Result<Color> {
    Ok(colour(p, "specular_reflectance", 1.0, cache)?.split(Slot::SpecularReflectance, textures))
}

/// `specular_transmittance` (default 1), constant or bound to its slot.
fn specular_transmittance(p: &Plugin, cache: &mut TextureCache, textures: &mut Vec<(Slot, Texture)>) -> Result<Color> {
    Ok(colour(p, "specular_transmittance", 1.0, cache)?.split(Slot::SpecularTransmittance, textures))
}

/// A mapped material with its bound textures.
fn with_textures(p: &Plugin, bsdf: Bsdf, one_sided: bool, textures: Vec<(Slot, Texture)>) -> Mapped {
    Mapped { textures, ..plain(p, bsdf, one_sided) }
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

fn diffuse(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let mut textures = Vec::new();
    let albedo = colour(p, "reflectance", 0.5, cache)?.split(Slot::DiffuseReflectance, &mut textures);
    let mut m = plain(p, Bsdf::Lambertian(Lambertian { albedo }), true);
    m.textures = textures;
    Ok(m)
}

fn dielectric(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let (int, ext, specular_reflectance, tint, textures) = dielectric_params(p, cache)?;
    let b = Dielectric { ior: int / ext, tint, specular_reflectance };
    Ok(with_textures(p, Bsdf::Dielectric(b), false, textures))
}

/// Conductor parameters: a preset (`material`) or explicit `eta`/`k`.
struct ConductorParams {
    /// Relative index η / ext_eta.
    eta: Vec3,
    /// Relative absorption k / ext_eta.
    k: Vec3,
}

fn conductor_params(p: &Plugin) -> Result<Option<ConductorParams>> {
    let material = p.string("material")?;
    let (eta, k) = (p.spectrum("eta")?, p.spectrum("k")?);
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
    if eta.min_element() < 0.0 || k.min_element() < 0.0 {
        return Err(p.err(format!("`eta` and `k` must not be negative, got {eta} and {k}")));
    }
    Ok(Some(ConductorParams { eta: eta / ext_eta, k: k / ext_eta }))
}

fn conductor(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let mut textures = Vec::new();
    let specular_reflectance = specular_reflectance(p, cache, &mut textures)?;
    // `material="none"` (the default) reflects everything: photonlab's mirror.
    Ok(match conductor_params(p)? {
        None => with_textures(p, Bsdf::Mirror(Mirror { reflectance: specular_reflectance }), true, textures),
        Some(c) => with_textures(p, Bsdf::Conductor(Conductor { eta: c.eta, k: c.k, specular_reflectance }), false, textures),
    })
}

/// Microfacet distribution and roughness.
struct Rough {
    distribution: MicrofacetType,
    alpha: f32,
}

fn rough(p: &Plugin) -> Result<Rough> {
    // Mitsuba 3's default distribution is Beckmann.
    let distribution = match p.string("distribution")?.map(|s| s.0).as_deref() {
        None | Some("beckmann") => MicrofacetType::Beckmann,
        Some("ggx") => MicrofacetType::Ggx,
        Some(other) => return Err(p.err(format!("distribution must be `ggx` or `beckmann`, got `{other}`"))),
    };
    if p.float("alpha_u")?.is_some() || p.float("alpha_v")?.is_some() {
        return Err(p.err("anisotropic roughness (alpha_u/alpha_v) is not supported"));
    }
    let alpha = p.float_or("alpha", 0.1)?;
    if alpha.is_nan() || alpha <= 0.0 {
        return Err(p.err(format!("alpha must be positive, got {alpha}")));
    }
    // Visible-normal sampling is always used; `false` (Mitsuba's full-distribution
    // sampling) converges to the same image with more variance, so it is accepted.
    let _ = p.bool_or("sample_visible", true)?;
    Ok(Rough { distribution, alpha })
}

fn roughconductor(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let r = rough(p)?;
    let mut textures = Vec::new();
    let specular_reflectance = specular_reflectance(p, cache, &mut textures)?;
    // `material="none"` (Mitsuba 3's default): η = 0, k = 1, a Fresnel term of one.
    let (eta, k) = match conductor_params(p)? {
        Some(c) => (c.eta, c.k),
        None => (Vec3::ZERO, Vec3::ONE),
    };
    let b = RoughConductor { distribution: r.distribution, alpha: r.alpha, eta, k, specular_reflectance };
    Ok(with_textures(p, Bsdf::RoughConductor(b), false, textures))
}

/// The three dielectrics' parameters: interior and exterior IOR, the multipliers on
/// the reflected and the transmitted part (constant or textured), the textures.
type DielectricParams = (f32, f32, Color, Color, Vec<(Slot, Texture)>);

fn dielectric_params(p: &Plugin, cache: &mut TextureCache) -> Result<DielectricParams> {
    let (int, ext) = (ior(p, "int_ior", "bk7")?, ior(p, "ext_ior", "air")?);
    let mut textures = Vec::new();
    let r = specular_reflectance(p, cache, &mut textures)?;
    let t = specular_transmittance(p, cache, &mut textures)?;
    Ok((int, ext, r, t, textures))
}

fn roughdielectric(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let r = rough(p)?;
    let (int_ior, ext_ior, specular_reflectance, specular_transmittance, textures) = dielectric_params(p, cache)?;
    let b =
        RoughDielectric { distribution: r.distribution, alpha: r.alpha, int_ior, ext_ior, specular_reflectance, specular_transmittance };
    Ok(with_textures(p, Bsdf::RoughDielectric(b), false, textures))
}

fn thindielectric(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let (int_ior, ext_ior, specular_reflectance, specular_transmittance, textures) = dielectric_params(p, cache)?;
    let b = ThinDielectric { int_ior, ext_ior, specular_reflectance, specular_transmittance };
    Ok(with_textures(p, Bsdf::ThinDielectric(b), false, textures))
}

/// The parameters both plastics share.
struct PlasticParams {
    int_ior: f32,
    ext_ior: f32,
    kd: Color,
    ks: Color,
    nonlinear: bool,
    textures: Vec<(Slot, Texture)>,
}

fn plastic_params(p: &Plugin, cache: &mut TextureCache) -> Result<PlasticParams> {
    let (int_ior, ext_ior) = (ior(p, "int_ior", "polypropylene")?, ior(p, "ext_ior", "air")?);
    let mut textures = Vec::new();
    let kd = colour(p, "diffuse_reflectance", 0.5, cache)?.split(Slot::DiffuseReflectance, &mut textures);
    let ks = specular_reflectance(p, cache, &mut textures)?;
    let nonlinear = p.bool_or("nonlinear", false)?;
    Ok(PlasticParams { int_ior, ext_ior, kd, ks, nonlinear, textures })
}

fn plastic(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let q = plastic_params(p, cache)?;
    let mut m = plain(p, Bsdf::Plastic(Plastic::new(q.kd, q.ks, q.int_ior, q.ext_ior, q.nonlinear)), false);
    m.textures = q.textures;
    Ok(m)
}

fn roughplastic(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let r = rough(p)?;
    let q = plastic_params(p, cache)?;
    let b = RoughPlastic::new(r.distribution, r.alpha, q.kd, q.ks, q.int_ior, q.ext_ior, q.nonlinear);
    let mut m = plain(p, Bsdf::RoughPlastic(b), false);
    m.textures = q.textures;
    Ok(m)
}

/// True for BSDFs that let light through (not allowed inside `twosided`, whose sides
/// only reflect, as Mitsuba's documentation requires).
fn transmits(b: &Bsdf) -> bool {
    matches!(b, Bsdf::Dielectric(_) | Bsdf::RoughDielectric(_) | Bsdf::ThinDielectric(_) | Bsdf::Mask(_))
}

/// True for photonlab BSDFs that already reflect on both sides.
fn both_sides(b: &Bsdf) -> bool {
    matches!(b, Bsdf::Lambertian(_) | Bsdf::Mirror(_) | Bsdf::Glossy(_))
}

fn twosided(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let inner = p.children("bsdf");
    let mut sides = Vec::new();
    for b in inner.iter() {
        if b.ty == "twosided" {
            return Err(b.err("a twosided BSDF inside another"));
        }
        let m = bsdf(b, cache)?;
        if transmits(&m.material.bsdf) {
            return Err(b.err("twosided needs a BSDF that only reflects (it has no transmission)"));
        }
        sides.push(m);
    }
    let name = name_of(p);
    let mut m = match sides.len() {
        1 => {
            let mut m = sides.pop().expect("one side");
            if !both_sides(&m.material.bsdf) {
                m.material.bsdf = Bsdf::TwoSided(TwoSided::new(m.material.bsdf));
            }
            m
        }
        2 => {
            let back = sides.pop().expect("two sides");
            let front = sides.pop().expect("two sides");
            if !front.textures.is_empty() || !back.textures.is_empty() {
                return Err(p.err("textures on a twosided BSDF with different front and back BSDFs are not supported"));
            }
            let bsdf = Bsdf::TwoSided(TwoSided { front: Box::new(front.material.bsdf), back: Box::new(back.material.bsdf) });
            Mapped { material: Material { name: String::new(), bsdf, emission: Color::ZERO }, textures: Vec::new(), one_sided: false }
        }
        _ => return Err(p.err("needs one or two nested <bsdf>")),
    };
    m.material.name = name;
    m.one_sided = false;
    Ok(m)
}

fn mask(p: &Plugin, cache: &mut TextureCache) -> Result<Mapped> {
    let opacity = colour(p, "opacity", 0.5, cache)?;
    let inner = p.child("bsdf")?.ok_or_else(|| p.err("needs a nested <bsdf>"))?;
    let mut m = bsdf(&inner, cache)?;
    let opacity = match opacity {
        Param::Const(c) => {
            if c.max_element() > 1.0 {
                return Err(p.err(format!("`opacity` must lie in [0, 1], got {c}")));
            }
            crate::math::mean(c)
        }
        Param::Tex(t) => {
            m.textures.push((Slot::Opacity { alpha: false }, t));
            0.5
        }
    };
    m.material.bsdf = Bsdf::Mask(Mask { opacity, nested: Box::new(m.material.bsdf) });
    m.material.name = name_of(p);
    Ok(m)
}
