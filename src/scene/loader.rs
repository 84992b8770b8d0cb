//! Scene TOML reading per `scene-format.md`, for scene files and for the inline scene
//! of an experiment manifest.
//!
//! Reading is two steps. [`SceneDesc::from_toml`] turns an already-parsed TOML value
//! (a whole scene file, or a manifest's `scene` table) plus the directory relative
//! paths start from into a checked description: every problem of the TOML itself
//! (unknown key, wrong type, bad placement, material or light) is reported there, with
//! `file:line`, before any mesh is read. [`SceneDesc::build`] then reads the OBJ/MTL
//! files and makes the [`Scene`]. [`load_scene`] does both for a scene file.
//!
//! Choices where the contract is silent:
//! * `[camera]`: `eye`, `look_at`, `fov_y_deg` and `resolution` are required; `up`
//!   defaults to `[0, 1, 0]`.
//! * `[[light]]`: every key of its type is required (no defaults), so that a scene
//!   means the same thing to every tool that reads it. Spot lights need
//!   `0 <= cone_deg <= falloff_deg <= 180` and `falloff_deg > 0`; directions are
//!   normalised and must not be zero.
//! * Colours are `[r, g, b]` arrays of finite, non-negative numbers; `scale` may be a
//!   number or `[sx, sy, sz]`, finite and non-zero.
//! * Unknown keys and unknown material or light types are errors.
//! * A mesh whose OBJ has no faces is skipped with a warning.
//!
//! Manifest extensions ([`Dialect::Inline`] only; a scene file using one is an error,
//! so scene files stay exactly the contract that other tools read):
//! * `builtin = "NAME"` or `file = "PATH.toml"`: a base scene the table adds to; its
//!   camera is kept unless the table gives a `[camera]`, which is then optional.
//! * `[camera]` `resolution` may be left out (the manifest's resolution is used).
//! * `[[mesh]]` `fit_height = H` (instead of `scale`): the model is moved so that the
//!   bottom centre of its bounding box is the origin and scaled uniformly to height
//!   `H`; `rotate_y_deg` and `translate` then apply as usual (so `translate` is where
//!   the bottom centre goes). For models whose units and origin depend on where they
//!   were downloaded from.
//! * `[[mesh]]` `download = "..."`: where to get a missing model (shown in the error);
//!   `download` beside `file` says the same for the base scene file's models.
//!
//! Every error is one line naming the scene (or manifest) file, with `line:column`
//! where the TOML parser or the value's position tells it, and the OBJ/MTL
//! `file:line` for errors inside a mesh.

use super::builtin::{BUILTINS, builtin};
use super::obj::{ObjFile, load_obj};
use super::{Placement, Scene, unit_or_zero};
use crate::camera::Camera;
use crate::material::{Bsdf, Dielectric, Glossy, Lambertian, Material, MicrofacetType, Mirror, Plastic, RoughConductor, RoughPlastic};
use crate::math::Color;
use crate::scene::LightDesc;
use anyhow::{Result, anyhow, bail};
use glam::Vec3;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use toml::Spanned;
use toml::de::{DeTable, DeValue, ValueDeserializer};

/// A scene table: the contract's keys, plus the manifest's base-scene keys.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneToml {
    camera: Option<Spanned<CameraToml>>,
    #[serde(default)]
    mesh: Vec<Spanned<MeshToml>>,
    #[serde(default)]
    light: Vec<Spanned<LightToml>>,
    /// Extension: a built-in base scene.
    builtin: Option<Spanned<String>>,
    /// Extension: a scene file as base scene.
    file: Option<Spanned<String>>,
    /// Extension: where to get the base scene file's models when they are missing.
    download: Option<Spanned<String>>,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraToml {
    eye: [f32; 3],
    look_at: [f32; 3],
    #[serde(default = "default_up")]
    up: [f32; 3],
    fov_y_deg: f32,
    /// Required in a scene file; optional (extension) inline.
    resolution: Option<[u32; 2]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshToml {
    obj: String,
    #[serde(default)]
    scale: Option<Scale>,
    #[serde(default)]
    rotate_y_deg: Option<f32>,
    #[serde(default)]
    translate: Option<[f32; 3]>,
    #[serde(default)]
    material: Option<OverrideToml>,
    /// Extension: scale to this height, standing on `translate`.
    fit_height: Option<Spanned<f32>>,
    /// Extension: where to download a missing model.
    download: Option<Spanned<String>>,
}
/// `scale = s` or `scale = [sx, sy, sz]`.
struct Scale(Vec3);

impl<'de> Deserialize<'de> for Scale {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Scale;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number or an array of 3 numbers")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> std::result::Result<Scale, E> {
                Ok(Scale(Vec3::splat(v as f32)))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> std::result::Result<Scale, E> {
                Ok(Scale(Vec3::splat(v as f32)))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> std::result::Result<Scale, E> {
                Ok(Scale(Vec3::splat(v as f32)))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<Scale, A::Error> {
                let mut c = [0.0f32; 3];
                for (i, slot) in c.iter_mut().enumerate() {
                    *slot = seq.next_element()?.ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<f32>()?.is_some() {
                    return Err(serde::de::Error::invalid_length(4, &self));
                }
                Ok(Scale(Vec3::from_array(c)))
            }
        }
        d.deserialize_any(V)
    }
}

/// The contract's material override table (aliases and defaults).
#[derive(Deserialize)]
#[serde(tag = "type", deny_unknown_fields)]
enum OverrideToml {
    #[serde(rename = "diffuse", alias = "lambertian")]
    Diffuse {
        #[serde(alias = "kd")]
        albedo: Option<[f32; 3]>,
    },
    #[serde(rename = "mirror")]
    Mirror {
        #[serde(alias = "ks")]
        reflectance: Option<[f32; 3]>,
    },
    #[serde(rename = "glass", alias = "dielectric")]
    Glass {
        ior: Option<f32>,
        #[serde(alias = "tf")]
        tint: Option<[f32; 3]>,
    },
    #[serde(rename = "glossy")]
    Glossy {
        #[serde(alias = "albedo")]
        kd: Option<[f32; 3]>,
        ks: Option<[f32; 3]>,
        #[serde(alias = "exponent")]
        ns: Option<f32>,
    },
    /// Mitsuba 3's `roughconductor` (defaults as Mitsuba's: Beckmann, α 0.1, η 0 + 1i,
    /// a perfect reflector).
    #[serde(rename = "roughconductor")]
    RoughConductor {
        distribution: Option<String>,
        alpha: Option<f32>,
        eta: Option<[f32; 3]>,
        k: Option<[f32; 3]>,
        specular_reflectance: Option<[f32; 3]>,
    },
    /// Mitsuba 3's `roughplastic` (Beckmann, α 0.1, indices 1.49 / 1.000277).
    #[serde(rename = "roughplastic")]
    RoughPlastic {
        distribution: Option<String>,
        alpha: Option<f32>,
        diffuse_reflectance: Option<[f32; 3]>,
        specular_reflectance: Option<[f32; 3]>,
        int_ior: Option<f32>,
        ext_ior: Option<f32>,
        nonlinear: Option<bool>,
    },
    /// Mitsuba 3's `plastic`.
    #[serde(rename = "plastic")]
    Plastic {
        diffuse_reflectance: Option<[f32; 3]>,
        specular_reflectance: Option<[f32; 3]>,
        int_ior: Option<f32>,
        ext_ior: Option<f32>,
        nonlinear: Option<bool>,
    },
    #[serde(rename = "emitter")]
    Emitter {
        #[serde(alias = "ke")]
        radiance: Option<[f32; 3]>,
        #[serde(alias = "kd")]
        albedo: Option<[f32; 3]>,
    },
}

#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
enum LightToml {
    Point { position: [f32; 3], intensity: [f32; 3] },
    Spot { position: [f32; 3], direction: [f32; 3], intensity: [f32; 3], cone_deg: f32, falloff_deg: f32 },
    Directional { direction: [f32; 3], irradiance: [f32; 3] },
}

/// Checks a colour: finite, non-negative.
fn colour(c: [f32; 3], what: &str) -> anyhow::Result<Color> {
    let v = Vec3::from_array(c);
    if !v.is_finite() || v.min_element() < 0.0 {
        return Err(anyhow!("{what} must be finite and non-negative, got {c:?}"));
    }
    Ok(v)
}

/// Checks a finite vector.
fn finite(c: [f32; 3], what: &str) -> anyhow::Result<Vec3> {
    let v = Vec3::from_array(c);
    if v.is_finite() { Ok(v) } else { Err(anyhow!("{what} must be finite, got {c:?}")) }
}

/// Checks and normalises a direction.
fn direction(c: [f32; 3], what: &str) -> anyhow::Result<Vec3> {
    let v = unit_or_zero(finite(c, what)?);
    if v == Vec3::ZERO { Err(anyhow!("{what} must not be zero")) } else { Ok(v) }
}

/// Mitsuba's `distribution` names (default Beckmann).
fn microfacet_type(name: Option<&str>) -> anyhow::Result<MicrofacetType> {
    match name.unwrap_or("beckmann") {
        "beckmann" => Ok(MicrofacetType::Beckmann),
        "ggx" => Ok(MicrofacetType::Ggx),
        other => Err(anyhow!("distribution must be \"beckmann\" or \"ggx\", got \"{other}\"")),
    }
}

/// A roughness α (default 0.1, Mitsuba's): finite and positive.
fn roughness(alpha: Option<f32>) -> anyhow::Result<f32> {
    let a = alpha.unwrap_or(0.1);
    if a.is_finite() && a > 0.0 { Ok(a) } else { Err(anyhow!("alpha must be finite and positive, got {a}")) }
}

/// Interior and exterior indices (defaults 1.49 and 1.000277, Mitsuba's plastics').
fn iors(int_ior: Option<f32>, ext_ior: Option<f32>) -> anyhow::Result<(f32, f32)> {
    let (i, e) = (int_ior.unwrap_or(1.49), ext_ior.unwrap_or(1.000_277));
    for (name, v) in [("int_ior", i), ("ext_ior", e)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(anyhow!("{name} must be finite and positive, got {v}"));
        }
    }
    Ok((i, e))
}

/// Builds the override material with the contract's defaults.
fn override_material(m: &OverrideToml, name: &str) -> anyhow::Result<Material> {
    let grey = [0.5f32; 3];
    let mut mat = Material::diffuse(name, Color::splat(0.5));
    match m {
        OverrideToml::Diffuse { albedo } => mat.bsdf = Bsdf::Lambertian(Lambertian { albedo: colour(albedo.unwrap_or(grey), "albedo")? }),
        OverrideToml::Mirror { reflectance } => {
            mat.bsdf = Bsdf::Mirror(Mirror { reflectance: colour(reflectance.unwrap_or([1.0; 3]), "reflectance")? })
        }
        OverrideToml::Glass { ior, tint } => {
            let ior = ior.unwrap_or(1.5);
            if !(ior.is_finite() && ior > 0.0) {
                return Err(anyhow::anyhow!("ior must be finite and positive, got {ior}"));
            }
            mat.bsdf = Bsdf::Dielectric(Dielectric::new(ior, colour(tint.unwrap_or([1.0; 3]), "tint")?));
        }
        OverrideToml::Glossy { kd, ks, ns } => {
            let exponent = ns.unwrap_or(1.0);
            if !(exponent.is_finite() && exponent >= 0.0) {
                return Err(anyhow::anyhow!("ns must be finite and non-negative, got {exponent}"));
            }
            mat.bsdf = Bsdf::Glossy(Glossy { kd: colour(kd.unwrap_or(grey), "kd")?, ks: colour(ks.unwrap_or([0.0; 3]), "ks")?, exponent });
        }
        OverrideToml::RoughConductor { distribution, alpha, eta, k, specular_reflectance } => {
            mat.bsdf = Bsdf::RoughConductor(RoughConductor {
                distribution: microfacet_type(distribution.as_deref())?,
                alpha: roughness(*alpha)?,
                eta: colour(eta.unwrap_or([0.0; 3]), "eta")?,
                k: colour(k.unwrap_or([1.0; 3]), "k")?,
                specular_reflectance: colour(specular_reflectance.unwrap_or([1.0; 3]), "specular_reflectance")?,
            })
        }
        OverrideToml::RoughPlastic { distribution, alpha, diffuse_reflectance, specular_reflectance, int_ior, ext_ior, nonlinear } => {
            let (int_ior, ext_ior) = iors(*int_ior, *ext_ior)?;
            mat.bsdf = Bsdf::RoughPlastic(RoughPlastic::new(
                microfacet_type(distribution.as_deref())?,
                roughness(*alpha)?,
                colour(diffuse_reflectance.unwrap_or(grey), "diffuse_reflectance")?,
                colour(specular_reflectance.unwrap_or([1.0; 3]), "specular_reflectance")?,
                int_ior,
                ext_ior,
                nonlinear.unwrap_or(false),
            ))
        }
        OverrideToml::Plastic { diffuse_reflectance, specular_reflectance, int_ior, ext_ior, nonlinear } => {
            let (int_ior, ext_ior) = iors(*int_ior, *ext_ior)?;
            mat.bsdf = Bsdf::Plastic(Plastic::new(
                colour(diffuse_reflectance.unwrap_or(grey), "diffuse_reflectance")?,
                colour(specular_reflectance.unwrap_or([1.0; 3]), "specular_reflectance")?,
                int_ior,
                ext_ior,
                nonlinear.unwrap_or(false),
            ))
        }
        OverrideToml::Emitter { radiance, albedo } => {
            mat.bsdf = Bsdf::Lambertian(Lambertian { albedo: colour(albedo.unwrap_or(grey), "albedo")? });
            mat.emission = colour(radiance.unwrap_or([0.0; 3]), "radiance")?;
        }
    }
    Ok(mat)
}

/// Converts a `[[light]]` entry.
fn light_desc(l: &LightToml) -> anyhow::Result<LightDesc> {
    Ok(match *l {
        LightToml::Point { position, intensity } => {
            LightDesc::Point { position: finite(position, "position")?, intensity: colour(intensity, "intensity")? }
        }
        LightToml::Spot { position, direction: dir, intensity, cone_deg, falloff_deg } => {
            if !(cone_deg >= 0.0 && cone_deg <= falloff_deg && falloff_deg <= 180.0 && falloff_deg > 0.0) {
                return Err(anyhow::anyhow!(
                    "spot light needs 0 <= cone_deg <= falloff_deg <= 180 and falloff_deg > 0, got cone_deg {cone_deg}, falloff_deg {falloff_deg}"
                ));
            }
            LightDesc::Spot {
                position: finite(position, "position")?,
                direction: direction(dir, "direction")?,
                intensity: colour(intensity, "intensity")?,
                cone_deg,
                falloff_deg,
            }
        }
        LightToml::Directional { direction: dir, irradiance } => {
            LightDesc::Directional { direction: direction(dir, "direction")?, irradiance: colour(irradiance, "irradiance")? }
        }
    })
}

/// 1-based line and column of a byte offset (also used for manifest errors).
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// The text a parsed TOML value's spans point into, and the file that names it in
/// messages.
#[derive(Clone, Copy)]
pub struct TomlSource<'a> {
    /// File named in messages.
    pub file: &'a Path,
    /// Its text.
    pub text: &'a str,
}

impl TomlSource<'_> {
    /// `file:line` of a byte offset.
    pub fn line(&self, offset: usize) -> String {
        format!("{}:{}", self.file.display(), line_col(self.text, offset).0)
    }

    fn at<T>(&self, s: &Spanned<T>) -> String {
        self.line(s.span().start)
    }

    /// A TOML parse or deserialisation error as `file:line:column: message`.
    pub fn error(&self, e: &toml::de::Error) -> anyhow::Error {
        let msg = e.message().replace('\n', " ");
        match e.span() {
            Some(s) => {
                let (l, c) = line_col(self.text, s.start);
                anyhow!("{}:{l}:{c}: {msg}", self.file.display())
            }
            None => anyhow!("{}: {msg}", self.file.display()),
        }
    }
}

/// Which keys a scene table may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dialect {
    /// A scene file: exactly the contract.
    File,
    /// A manifest's `[scene]` table: the contract plus the extensions listed in the
    /// module documentation; its tables are named `[scene.camera]`, `[[scene.mesh]]`, …
    /// in messages.
    Inline,
}

impl Dialect {
    fn prefix(self) -> &'static str {
        match self {
            Dialect::File => "",
            Dialect::Inline => "scene.",
        }
    }
}

/// The scene an inline scene adds to (manifest extension).
#[derive(Clone, Debug, PartialEq)]
pub enum SceneBase {
    /// A built-in scene by name.
    Builtin(String),
    /// A scene file (its path resolved against the manifest's directory).
    File(PathBuf),
}

impl SceneBase {
    /// A built-in base scene, checking the name.
    pub fn builtin(name: &str) -> Result<SceneBase> {
        if BUILTINS.contains(&name) {
            Ok(SceneBase::Builtin(name.to_string()))
        } else {
            bail!("unknown built-in scene `{name}` (known: {}; a scene file path must end in .toml)", BUILTINS.join(", "))
        }
    }
}

/// A `[camera]`, checked.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraDesc {
    /// Eye position.
    pub eye: Vec3,
    /// Point the optical axis passes through.
    pub look_at: Vec3,
    /// Up vector.
    pub up: Vec3,
    /// Full vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Image size; `None` (inline only) takes the resolution passed to `build`.
    pub resolution: Option<[u32; 2]>,
    /// `file:line: [camera]`, for messages.
    pub at: String,
}

impl CameraDesc {
    fn camera(&self, resolution: Option<[u32; 2]>) -> Result<Camera> {
        let [w, h] = self.resolution.or(resolution).ok_or_else(|| anyhow!("{}: missing field `resolution`", self.at))?;
        Camera::new(self.eye, self.look_at, self.up, self.fov_y_deg, w, h).map_err(|e| anyhow!("{}: {e}", self.at))
    }
}

/// A `[[mesh]]`, checked but not read yet.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshDesc {
    /// OBJ file (relative paths already resolved).
    pub obj: PathBuf,
    /// Placement (with `fit_height`, its scale is replaced when the model is read).
    pub placement: Placement,
    /// Extension: uniform scale to this height, bounding box bottom centre at the origin.
    pub fit_height: Option<f32>,
    /// Material override for every triangle.
    pub material: Option<Material>,
    /// Extension: where to download the model when it is missing.
    pub download: Option<String>,
    /// `file:line: [[mesh]] N`, for messages.
    pub at: String,
}

/// A scene description: what a scene file or a manifest's inline scene says, checked,
/// with no mesh file read yet.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneDesc {
    /// Base scene the description adds to (inline only).
    pub base: Option<SceneBase>,
    /// Camera (replaces the base scene's).
    pub camera: Option<CameraDesc>,
    /// Meshes, in order (after the base scene's).
    pub meshes: Vec<MeshDesc>,
    /// Non-geometric lights (after the base scene's).
    pub lights: Vec<LightDesc>,
    /// Extension: where to get the base scene file's models when they are missing.
    pub base_download: Option<String>,
    /// The file (scene file) or `file:line` of the table (inline), for messages about
    /// the whole scene.
    pub at: String,
}

/// Error for an extension key used in a scene file.
fn not_in_file<T>(src: &TomlSource, key: &str, v: &Option<Spanned<T>>) -> Result<()> {
    match v {
        Some(s) => bail!("{}: `{key}` is an experiment-manifest extension, not a scene-file key (scene-format.md)", src.at(s)),
        None => Ok(()),
    }
}

impl SceneDesc {
    /// A description that is just a base scene (a manifest's `scene = "NAME"`).
    pub fn of_base(base: SceneBase, at: String) -> SceneDesc {
        SceneDesc { base: Some(base), camera: None, meshes: vec![], lights: vec![], base_download: None, at }
    }

    /// Reads a scene table from an already-parsed TOML value: `src` is the text its
    /// spans point into (for `file:line` in messages), `dir` the directory relative
    /// paths start from, `dialect` whether the manifest extensions are allowed.
    pub fn from_toml(value: Spanned<DeValue<'_>>, src: TomlSource, dir: &Path, dialect: Dialect) -> Result<SceneDesc> {
        let p = dialect.prefix();
        let at = match dialect {
            Dialect::File => src.file.display().to_string(),
            Dialect::Inline => src.line(value.span().start),
        };
        let doc = SceneToml::deserialize(ValueDeserializer::from(value)).map_err(|e| src.error(&e))?;
        if dialect == Dialect::File {
            not_in_file(&src, "builtin", &doc.builtin)?;
            not_in_file(&src, "file", &doc.file)?;
            not_in_file(&src, "download", &doc.download)?;
        }
        if let (Some(d), None) = (&doc.download, &doc.file) {
            bail!("{}: [scene]: `download` names where a base scene file's models come from; give it with `file`", src.at(d));
        }
        let base = match (&doc.builtin, &doc.file) {
            (Some(_), Some(f)) => bail!("{}: [scene]: give `builtin` or `file`, not both", src.at(f)),
            (Some(b), None) => Some(SceneBase::builtin(b.get_ref()).map_err(|e| anyhow!("{}: [scene]: {e}", src.at(b)))?),
            (None, Some(f)) => Some(SceneBase::File(dir.join(f.get_ref()))),
            (None, None) => None,
        };
        let camera = match &doc.camera {
            Some(c) => Some(camera_desc(c, &src, dialect)?),
            None if base.is_some() => None,
            None => match dialect {
                Dialect::File => bail!("{at}: missing field `camera`"),
                Dialect::Inline => bail!("{at}: [scene]: without a `builtin` or `file` base scene, a [scene.camera] is required"),
            },
        };
        let mut meshes = Vec::new();
        for (i, m) in doc.mesh.iter().enumerate() {
            meshes.push(mesh_desc(m, i, &src, dir, dialect)?);
        }
        let mut lights = Vec::new();
        for (i, l) in doc.light.iter().enumerate() {
            lights.push(light_desc(l.get_ref()).map_err(|e| anyhow!("{}: [[{p}light]] {}: {e}", src.at(l), i + 1))?);
        }
        let base_download = doc.download.as_ref().map(|d| d.get_ref().clone());
        Ok(SceneDesc { base, camera, meshes, lights, base_download, at })
    }

    /// Builds the scene: the base scene (if any), then the camera, the meshes (read
    /// now) and the lights. `name` names a scene without a base; `resolution` is used
    /// where the camera gives none.
    ///
    /// Non-fatal remarks (undefined materials, negative scales, dropped zero-area
    /// triangles, ignored MTL statements) end up in `scene.warnings`.
    pub fn build(&self, name: &str, resolution: Option<[u32; 2]>) -> Result<Scene> {
        let camera = self.camera.as_ref().map(|c| c.camera(resolution)).transpose()?;
        let mut scene = match (&self.base, camera) {
            (Some(base), camera) => {
                let mut s = match base {
                    SceneBase::Builtin(b) => builtin(b).map_err(|e| anyhow!("{}: {e:#}", self.at))?,
                    SceneBase::File(f) => load_scene(f)?,
                };
                if let Some(c) = camera {
                    s.camera = c;
                }
                s
            }
            (None, Some(c)) => Scene::new(name, c),
            (None, None) => bail!("{}: missing field `camera`", self.at),
        };
        for m in &self.meshes {
            m.add_to(&mut scene)?;
        }
        scene.lights.extend(self.lights.iter().cloned());
        scene.validate().map_err(|e| anyhow!("{}: {e}", self.at))?;
        Ok(scene)
    }
}

fn camera_desc(c: &Spanned<CameraToml>, src: &TomlSource, dialect: Dialect) -> Result<CameraDesc> {
    let at = format!("{}: [{}camera]", src.at(c), dialect.prefix());
    let t = c.get_ref();
    if dialect == Dialect::File && t.resolution.is_none() {
        bail!("{at}: missing field `resolution`");
    }
    let d = CameraDesc {
        eye: Vec3::from_array(t.eye),
        look_at: Vec3::from_array(t.look_at),
        up: Vec3::from_array(t.up),
        fov_y_deg: t.fov_y_deg,
        resolution: t.resolution,
        at,
    };
    // Checked now (frame, field of view, resolution), so that a manifest fails before
    // anything renders.
    d.camera(Some([1, 1]))?;
    Ok(d)
}

fn mesh_desc(m: &Spanned<MeshToml>, i: usize, src: &TomlSource, dir: &Path, dialect: Dialect) -> Result<MeshDesc> {
    let at = format!("{}: [[{}mesh]] {}", src.at(m), dialect.prefix(), i + 1);
    let mt = m.get_ref();
    if dialect == Dialect::File {
        not_in_file(src, "fit_height", &mt.fit_height)?;
        not_in_file(src, "download", &mt.download)?;
    }
    let placement = Placement {
        scale: mt.scale.as_ref().map_or(Vec3::ONE, |s| s.0),
        rotate_y_deg: mt.rotate_y_deg.unwrap_or(0.0),
        translate: Vec3::from_array(mt.translate.unwrap_or([0.0; 3])),
    };
    if !placement.scale.is_finite() || placement.scale.cmpeq(Vec3::ZERO).any() {
        bail!("{at}: scale must be finite and non-zero, got {:?}", placement.scale.to_array());
    }
    if !placement.rotate_y_deg.is_finite() || !placement.translate.is_finite() {
        bail!("{at}: rotate_y_deg and translate must be finite");
    }
    let fit_height = mt.fit_height.as_ref().map(|h| *h.get_ref());
    if let Some(h) = fit_height {
        if mt.scale.is_some() {
            bail!("{at}: give `fit_height` or `scale`, not both");
        }
        if !(h.is_finite() && h > 0.0) {
            bail!("{at}: fit_height must be finite and positive, got {h}");
        }
    }
    let material = match &mt.material {
        Some(o) => Some(override_material(o, &format!("{} (override)", mt.obj)).map_err(|e| anyhow!("{at}: material: {e}"))?),
        None => None,
    };
    Ok(MeshDesc {
        obj: dir.join(&mt.obj),
        placement,
        fit_height,
        material,
        download: mt.download.as_ref().map(|d| d.get_ref().clone()),
        at,
    })
}

impl MeshDesc {
    /// Reads the OBJ and adds its triangles to `scene`.
    fn add_to(&self, scene: &mut Scene) -> Result<()> {
        let at = &self.at;
        let ObjFile { mut mesh, warnings, uvs, maps } = load_obj(&self.obj).map_err(|e| anyhow!("{at}: {e}"))?;
        scene.warnings.extend(warnings);
        let mut place = self.placement;
        if place.scale.min_element() < 0.0 {
            let mirrored = place.scale.x * place.scale.y * place.scale.z < 0.0;
            scene.warnings.push(if mirrored {
                format!("{at}: negative scale mirrors the mesh; its triangles' front sides flip with it (not corrected)")
            } else {
                format!("{at}: negative scale components (an even number: a rotation, not a mirror)")
            });
        }
        if mesh.faces.is_empty() {
            scene.warnings.push(format!("{at}: {} has no faces", self.obj.display()));
            return Ok(());
        }
        if let Some(h) = self.fit_height {
            // Bottom centre of the bounding box to the origin, then scale to height `h`.
            let (lo, hi) = mesh
                .positions
                .iter()
                .fold((Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)), |(a, b), p| (a.min(*p), b.max(*p)));
            let height = hi.y - lo.y;
            if !(height > 0.0 && height.is_finite()) {
                bail!("{at}: fit_height: {} is flat (zero height), it cannot be scaled to a height", self.obj.display());
            }
            let offset = Vec3::new(0.5 * (lo.x + hi.x), lo.y, 0.5 * (lo.z + hi.z));
            for p in &mut mesh.positions {
                *p -= offset;
            }
            place.scale = Vec3::splat(h / height);
        }
        let before = scene.dropped_degenerate;
        let mat_base = scene.materials.len() as u32;
        let has_uvs = uvs.faces.iter().any(Option::is_some);
        scene
            .add_mesh_uv(&mesh, has_uvs.then_some(&uvs), &place, self.material.as_ref())
            .map_err(|e| anyhow!("{at}: {}: {e}", self.obj.display()))?;
        if self.material.is_none() {
            super::textures::bind_mtl_maps(scene, mat_base, &maps, at)?;
        }
        let dropped = scene.dropped_degenerate - before;
        if dropped > 0 {
            scene.warnings.push(format!("{at}: dropped {dropped} zero-area triangle(s) of {}", self.obj.display()));
        }
        Ok(())
    }
}

/// Loads a scene file (TOML with OBJ/MTL meshes) following `scene-format.md`, or a
/// Mitsuba 3 XML scene (`.xml`, [`super::mitsuba`]).
///
/// Non-fatal remarks (undefined materials, negative scales, dropped zero-area
/// triangles, ignored MTL statements) end up in `scene.warnings`.
pub fn load_scene(path: &Path) -> Result<Scene> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("xml")) {
        return super::mitsuba::load_mitsuba(path);
    }
    let desc = read_scene_file(path)?;
    let name = path.file_stem().map_or_else(|| "scene".to_string(), |s| s.to_string_lossy().into_owned());
    let mut scene = desc.build(&name, None)?;
    scene.source = Some(path.to_path_buf());
    Ok(scene)
}

/// Reads and checks a TOML scene file's description without reading its meshes.
pub fn read_scene_file(path: &Path) -> Result<SceneDesc> {
    let text = std::fs::read_to_string(path).map_err(|e| anyhow!("{}: cannot read scene file: {e}", path.display()))?;
    let src = TomlSource { file: path, text: &text };
    let doc = DeTable::parse(&text).map_err(|e| src.error(&e))?;
    let value = Spanned::new(doc.span(), DeValue::Table(doc.into_inner()));
    SceneDesc::from_toml(value, src, path.parent().unwrap_or(Path::new("")), Dialect::File)
}

#[cfg(test)]
#[path = "loader_tests.rs"]
mod tests;
