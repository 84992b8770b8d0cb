//! Pinhole perspective camera following the scene contract: full vertical field of
//! view, pixel (0,0) top-left, +x right and +y down in the image, `up` up.

use crate::geometry::Ray;
use glam::Vec3;

/// Pinhole camera.
#[derive(Clone, Debug)]
pub struct Camera {
    /// Eye position.
    pub eye: Vec3,
    /// Point looked at.
    pub look_at: Vec3,
    /// Up vector.
    pub up: Vec3,
    /// Full vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    forward: Vec3,
    right: Vec3,
    up_img: Vec3,
    tan_half: f32,
}

impl Camera {
    /// Builds a camera; fails on a degenerate frame, field of view or resolution.
    pub fn new(eye: Vec3, look_at: Vec3, up: Vec3, fov_y_deg: f32, width: u32, height: u32) -> anyhow::Result<Self> {
        if !(eye.is_finite() && look_at.is_finite() && up.is_finite()) {
            return Err(anyhow::anyhow!("camera eye, look_at and up must be finite"));
        }
        if !(fov_y_deg > 0.0 && fov_y_deg < 180.0) {
            return Err(anyhow::anyhow!("camera fov_y_deg must be in (0, 180), got {fov_y_deg}"));
        }
        if width == 0 || height == 0 {
            return Err(anyhow::anyhow!("camera resolution must be positive, got {width}x{height}"));
        }
        let forward = (look_at - eye).normalize_or_zero();
        if forward == Vec3::ZERO {
            return Err(anyhow::anyhow!("camera eye and look_at coincide"));
        }
        let right = forward.cross(up).normalize_or_zero();
        if right == Vec3::ZERO {
            return Err(anyhow::anyhow!("camera up is zero or parallel to the viewing direction"));
        }
        let up_img = right.cross(forward);
        Ok(Camera { eye, look_at, up, fov_y_deg, width, height, forward, right, up_img, tan_half: (fov_y_deg.to_radians() * 0.5).tan() })
    }

    /// Same camera at another resolution.
    pub fn with_resolution(&self, width: u32, height: u32) -> anyhow::Result<Self> {
        Camera::new(self.eye, self.look_at, self.up, self.fov_y_deg, width, height)
    }

    /// Ray through image-plane position (x, y) in pixels (continuous; (0,0) is the
    /// top-left corner of the top-left pixel). Direction is unit length.
    #[inline]
    pub fn generate_ray(&self, x: f32, y: f32) -> Ray {
        let aspect = self.width as f32 / self.height as f32;
        let sx = (2.0 * x / self.width as f32 - 1.0) * self.tan_half * aspect;
        let sy = (1.0 - 2.0 * y / self.height as f32) * self.tan_half;
        let d = (self.forward + self.right * sx + self.up_img * sy).normalize();
        Ray::new(self.eye, d)
    }
}

impl Camera {
    /// Continuous image position (pixels) of a world point in front of the camera.
    pub fn project(&self, p: Vec3) -> Option<(f32, f32)> {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let aspect = self.width as f32 / self.height as f32;
        let sx = d.dot(self.right) / z / (self.tan_half * aspect);
        let sy = d.dot(self.up_img) / z / self.tan_half;
        Some(((sx + 1.0) * 0.5 * self.width as f32, (1.0 - sy) * 0.5 * self.height as f32))
    }
}

/// A world point as seen by the camera: what light tracing (connecting a light-path
/// vertex to the eye, pbrt's `Camera::SampleWi`, SmallVCM's `ConnectToCamera`) needs.
#[derive(Clone, Copy, Debug)]
pub struct CameraConnection {
    /// Continuous image position in pixels.
    pub raster: (f32, f32),
    /// Unit direction from the point towards the eye.
    pub to_eye: Vec3,
    /// Distance from the point to the eye.
    pub dist: f32,
    /// Density of the camera ray's direction at the eye, per unit solid angle, when the
    /// pixel position is uniform over a pixel of area one: d²/cos³ with d the distance of
    /// the image plane on which a pixel has area one and cos the angle to the axis. It
    /// is also the pixel's importance W_e (pinhole, box filter).
    pub pdf_dir: f32,
}

impl Camera {
    /// Distance of the image plane on which a pixel has area one (pixels are square).
    #[inline]
    pub fn image_plane_distance(&self) -> f32 {
        self.height as f32 / (2.0 * self.tan_half)
    }

    /// Viewing direction (unit).
    #[inline]
    pub fn forward(&self) -> Vec3 {
        self.forward
    }

    /// Solid-angle density of a camera ray through a uniform position inside a pixel
    /// (see [`CameraConnection::pdf_dir`]); `dir` need not be unit length.
    #[inline]
    pub fn pdf_dir(&self, dir: Vec3) -> f32 {
        let cos = dir.normalize().dot(self.forward);
        if cos <= 0.0 {
            return 0.0;
        }
        let d = self.image_plane_distance();
        d * d / (cos * cos * cos)
    }

    /// The camera's view of `p`, if `p` lies in front of it and inside the image.
    pub fn connect(&self, p: Vec3) -> Option<CameraConnection> {
        let (x, y) = self.project(p)?;
        if !(x >= 0.0 && y >= 0.0 && x < self.width as f32 && y < self.height as f32) {
            return None;
        }
        let d = self.eye - p;
        let dist = d.length();
        if dist.is_nan() || dist <= 0.0 {
            return None;
        }
        let to_eye = d / dist;
        let pdf_dir = self.pdf_dir(-to_eye);
        (pdf_dir > 0.0 && pdf_dir.is_finite()).then_some(CameraConnection { raster: (x, y), to_eye, dist, pdf_dir })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_and_fov() {
        let c = Camera::new(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 90.0, 200, 100).unwrap();
        let centre = c.generate_ray(100.0, 50.0);
        assert!((centre.d - (-Vec3::Z)).length() < 1e-6);
        // Top edge centre: 45 degrees up.
        let top = c.generate_ray(100.0, 0.0);
        assert!(top.d.y > 0.0 && (top.d.y - top.d.z.abs()).abs() < 1e-5);
        // Left edge: -x, aspect 2 -> tan = 2.
        let left = c.generate_ray(0.0, 50.0);
        assert!(left.d.x < 0.0 && (left.d.x / left.d.z - 2.0).abs() < 1e-5);
        let (px, py) = c.project(c.generate_ray(31.5, 72.25).at(3.0)).unwrap();
        assert!((px - 31.5).abs() < 1e-3 && (py - 72.25).abs() < 1e-3);
        assert!(Camera::new(Vec3::ZERO, Vec3::Z, Vec3::Y, 0.0, 1, 1).is_err());
        assert!(Camera::new(Vec3::ZERO, Vec3::Z, Vec3::Y, 40.0, 0, 1).is_err());
        assert!(Camera::new(Vec3::ZERO, Vec3::Y, Vec3::Y, 40.0, 1, 1).is_err());
    }

    #[test]
    fn connection_inverts_ray_generation_and_pdf_matches_pixel_solid_angle() {
        let c = Camera::new(Vec3::new(0.3, 1.0, 5.0), Vec3::new(0.0, 0.8, 0.0), Vec3::Y, 50.0, 64, 48).unwrap();
        for &(x, y) in &[(0.5f32, 0.5f32), (31.25, 20.5), (63.9, 47.9), (10.0, 40.0)] {
            let r = c.generate_ray(x, y);
            let p = r.at(4.0);
            let k = c.connect(p).unwrap();
            assert!((k.raster.0 - x).abs() < 2e-3 && (k.raster.1 - y).abs() < 2e-3, "{:?} vs {x},{y}", k.raster);
            assert!((k.to_eye + r.d).length() < 1e-5 && (k.dist - 4.0).abs() < 1e-4);
            // The solid angle of the pixel holding (x, y), from its four corner rays,
            // is 1 / pdf_dir (the density is uniform within a small pixel).
            let (px, py) = (x.floor(), y.floor());
            let corners = [
                c.generate_ray(px, py).d,
                c.generate_ray(px + 1.0, py).d,
                c.generate_ray(px + 1.0, py + 1.0).d,
                c.generate_ray(px, py + 1.0).d,
            ];
            let tri = |a: Vec3, b: Vec3, d: Vec3| 2.0 * (a.dot(b.cross(d))).abs().atan2(1.0 + a.dot(b) + b.dot(d) + d.dot(a));
            let omega = tri(corners[0], corners[1], corners[2]) + tri(corners[0], corners[2], corners[3]);
            let centre = c.generate_ray(px + 0.5, py + 0.5).d;
            let rel = (omega * c.pdf_dir(centre) - 1.0).abs();
            assert!(rel < 1e-3, "pixel solid angle × pdf = {}", omega * c.pdf_dir(centre));
        }
        // Behind the camera or outside the image: no connection.
        assert!(c.connect(Vec3::new(0.3, 1.0, 9.0)).is_none());
        assert!(c.connect(c.generate_ray(-3.0, 10.0).at(2.0)).is_none());
    }
}
