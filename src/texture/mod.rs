//! Textures on material parameters: Mitsuba's `bitmap` (PNG/JPEG/EXR, bilinear or
//! nearest filtering, `repeat`/`mirror`/`clamp`, `to_uv`) and `checkerboard`.
//!
//! Texture space is Mitsuba's: `(0, 0)` is the top-left corner of an image (OBJ
//! readers flip `vt`'s v, as Mitsuba's does). A texture lives beside the material
//! ([`SceneTextures`] binds it to a material's parameter [`Slot`]); the world fills
//! the textured values in at each hit (`World::bsdf_at`).

mod bitmap;
mod checkerboard;
pub mod image;

pub use bitmap::{Bitmap, Filter, Wrap};
pub use checkerboard::Checkerboard;
pub use image::Image;

use crate::math::Color;
use glam::{Mat3, Vec2};

/// A texture.
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    /// Image lookup.
    Bitmap(Bitmap),
    /// Two-colour checkerboard.
    Checkerboard(Checkerboard),
}

impl Texture {
    /// RGB value at texture coordinates `uv`.
    #[inline]
    pub fn eval(&self, uv: Vec2) -> Color {
        match self {
            Texture::Bitmap(b) => b.eval(uv).truncate(),
            Texture::Checkerboard(c) => c.eval(uv),
        }
    }

    /// Scalar value (opacity): the alpha channel of images that have one when
    /// `alpha` is asked for, else the mean of RGB (a checkerboard's in Mitsuba's
    /// scalar phase, see [`Checkerboard::eval_1`]).
    #[inline]
    pub fn eval_1(&self, uv: Vec2, alpha: bool) -> f32 {
        match self {
            Texture::Bitmap(b) => {
                let v = b.eval(uv);
                if alpha && b.image.has_alpha { v.w } else { (v.x + v.y + v.z) / 3.0 }
            }
            Texture::Checkerboard(c) => c.eval_1(uv),
        }
    }
}

/// Applies a Mitsuba `to_uv` transform (a 4×4 whose x/y rows act on (u, v, 0, 1)).
#[inline]
pub fn apply_uv(m: &Mat3, uv: Vec2) -> Vec2 {
    m.transform_point2(uv)
}

/// Which material parameter a texture supplies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    /// Diffuse reflectance (Lambertian albedo, glossy Kd, plastics' diffuse part).
    DiffuseReflectance,
    /// Specular reflectance (mirror, conductors' scale, plastics' specular part,
    /// dielectrics' reflected part).
    SpecularReflectance,
    /// Specular transmittance (dielectrics' transmitted part).
    SpecularTransmittance,
    /// Opacity of a `mask` (alpha cut-outs; MTL `map_d`).
    Opacity {
        /// Read the image's alpha channel where it has one.
        alpha: bool,
    },
}

/// A texture bound to one parameter of one material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Binding {
    /// Scene material index.
    pub material: u32,
    /// The parameter.
    pub slot: Slot,
    /// Index into [`SceneTextures::textures`].
    pub texture: u32,
}

/// A scene's textures and their bindings.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneTextures {
    /// Textures.
    pub textures: Vec<Texture>,
    /// Bindings, any order.
    pub bindings: Vec<Binding>,
}

impl SceneTextures {
    /// Adds a texture and binds it; returns its index.
    pub fn bind(&mut self, material: u32, slot: Slot, texture: Texture) -> u32 {
        let t = match self.textures.iter().position(|x| *x == texture) {
            Some(i) => i as u32,
            None => {
                self.textures.push(texture);
                (self.textures.len() - 1) as u32
            }
        };
        self.bindings.push(Binding { material, slot, texture: t });
        t
    }

    /// True when nothing is textured.
    pub fn is_empty(&self) -> bool {
        self.bindings.is_empty()
    }
}
