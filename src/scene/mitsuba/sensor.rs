//! Mitsuba `<sensor type="perspective">` with its `hdrfilm` and sampler → the
//! pinhole camera and the default sample count.

use super::xml::Plugin;
use crate::camera::Camera;
use anyhow::{Result, anyhow};
use glam::{Mat4, Vec3};

/// What the sensor describes.
pub struct SensorOut {
    /// The camera.
    pub camera: Camera,
    /// `sample_count` of its sampler.
    pub spp: Option<u32>,
}

/// Converts Mitsuba's field of view along `axis` to photonlab's vertical one.
pub fn vertical_fov(fov_deg: f32, axis: &str, width: u32, height: u32) -> Result<f32> {
    let (w, h) = (width as f32, height as f32);
    let t = (fov_deg.to_radians() * 0.5).tan();
    let tan_y = match axis {
        "x" => t * h / w,
        "y" => t,
        "diagonal" => t * h / (w * w + h * h).sqrt(),
        "smaller" => {
            if w < h {
                t * h / w
            } else {
                t
            }
        }
        "larger" => {
            if w > h {
                t * h / w
            } else {
                t
            }
        }
        other => return Err(anyhow!("fov_axis must be x, y, diagonal, smaller or larger, got `{other}`")),
    };
    Ok(2.0 * tan_y.atan().to_degrees())
}

/// Reads a sensor.
pub fn sensor(p: &Plugin, warnings: &mut Vec<String>) -> Result<SensorOut> {
    if p.ty != "perspective" {
        return Err(p.err(format!("sensor type `{}` is not supported (perspective)", p.ty)));
    }
    let to_world = p.transform("to_world")?.unwrap_or(Mat4::IDENTITY);
    let (fov, axis) = match (p.float("fov")?, p.string("focal_length")?) {
        (Some(_), Some(_)) => return Err(p.err("give either `fov` or `focal_length`, not both")),
        (Some(f), None) => (f, p.string("fov_axis")?.map_or_else(|| "x".to_string(), |s| s.0)),
        (None, f) => {
            // Mitsuba: a 35 mm film's diagonal (43.27 mm) over the focal length.
            let s = f.map_or_else(|| "50mm".to_string(), |s| s.0);
            let mm: f32 = s.trim().trim_end_matches("mm").trim().parse().map_err(|_| p.err(format!("cannot parse focal_length `{s}`")))?;
            if mm.is_nan() || mm <= 0.0 {
                return Err(p.err(format!("focal_length must be positive, got `{s}`")));
            }
            (2.0 * (36.0f32.hypot(24.0) / (2.0 * mm)).atan().to_degrees(), "diagonal".to_string())
        }
    };
    for clip in ["near_clip", "far_clip"] {
        if let Some(v) = p.float(clip)? {
            warnings.push(format!("{}: {}: `{clip}` = {v} is not applied (photonlab has no clip planes)", p.loc, p.what()));
        }
    }
    let film = p.child("film")?;
    let (mut width, mut height) = (768u32, 576u32);
    if let Some(f) = &film {
        if f.ty != "hdrfilm" {
            return Err(f.err("film type must be `hdrfilm`"));
        }
        let dim = |name: &str, d: u32| -> Result<u32> {
            match f.int(name)? {
                None => Ok(d),
                Some(v) if (1..=65536).contains(&v) => Ok(v as u32),
                Some(v) => Err(f.err(format!("`{name}` must be in 1..=65536, got {v}"))),
            }
        };
        width = dim("width", width)?;
        height = dim("height", height)?;
        // Output-only settings: photonlab always writes float EXR + sRGB PNG.
        for k in ["file_format", "pixel_format", "component_format"] {
            f.ignore(k);
        }
        if f.bool_or("sample_border", false)? {
            return Err(f.err("sample_border is not supported"));
        }
        match f.child("rfilter")? {
            Some(r) if r.ty == "box" => r.finish()?,
            Some(r) => return Err(r.err("photonlab integrates each pixel with a box filter; only rfilter `box` is supported")),
            None => warnings.push(format!(
                "{}: <film> has no <rfilter>: Mitsuba's default is `gaussian`, photonlab uses a box filter (add <rfilter type=\"box\"/>)",
                f.loc
            )),
        }
        f.finish()?;
    }
    let mut spp = None;
    if let Some(s) = p.child("sampler")? {
        let known = ["independent", "stratified", "multijitter", "orthogonal", "ldsampler"];
        if !known.contains(&s.ty.as_str()) {
            return Err(s.err(format!("unknown sampler type (known: {})", known.join(", "))));
        }
        if let Some(n) = s.int("sample_count")? {
            if !(1..=1 << 24).contains(&n) {
                return Err(s.err(format!("sample_count must be positive, got {n}")));
            }
            spp = Some(n as u32);
        }
        // The sampler itself is chosen on photonlab's command line.
        s.ignore("seed");
        s.ignore("jitter");
        s.ignore("scramble_seed");
        s.finish()?;
    }
    let vfov = vertical_fov(fov, &axis, width, height).map_err(|e| p.err(e))?;
    let eye = to_world.transform_point3(Vec3::ZERO);
    let forward = to_world.transform_vector3(Vec3::Z);
    let up = to_world.transform_vector3(Vec3::Y);
    let left = to_world.transform_vector3(Vec3::X);
    // photonlab's image x axis is forward × up; Mitsuba's is −x (its +x is left).
    if forward.cross(up).dot(left) > 0.0 {
        return Err(p.err("a mirrored camera transform (negative determinant) is not supported"));
    }
    let camera = Camera::new(eye, eye + forward.normalize_or_zero(), up, vfov, width, height).map_err(|e| p.err(e))?;
    p.finish()?;
    Ok(SensorOut { camera, spp })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fov_axes() {
        assert!((vertical_fov(90.0, "y", 200, 100).unwrap() - 90.0).abs() < 1e-4);
        // tan(45°)·100/200 = 0.5.
        assert!((vertical_fov(90.0, "x", 200, 100).unwrap() - 2.0 * 0.5f32.atan().to_degrees()).abs() < 1e-4);
        assert!((vertical_fov(90.0, "smaller", 200, 100).unwrap() - 90.0).abs() < 1e-4);
        assert!((vertical_fov(90.0, "larger", 100, 200).unwrap() - 90.0).abs() < 1e-4);
        assert!(vertical_fov(90.0, "z", 1, 1).is_err());
    }
}
