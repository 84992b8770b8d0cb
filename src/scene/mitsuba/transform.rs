//! Mitsuba's transform operations as matrices (its `Transform4f` conventions: a
//! `<matrix>` is row-major; `lookat` maps +z to the viewing direction, +y to up and
//! +x to up × direction, i.e. to the left of the image).

use anyhow::{Result, bail};
use glam::{Mat4, Vec3};

/// Rotation by `angle_deg` about `axis` (right-handed).
pub fn rotate(axis: Vec3, angle_deg: f32) -> Result<Mat4> {
    let a = axis.normalize_or_zero();
    if a == Vec3::ZERO {
        bail!("the rotation axis is zero");
    }
    Ok(Mat4::from_axis_angle(a, angle_deg.to_radians()))
}

/// `<matrix value="...">`: 16 numbers (4×4) or 9 (3×3), row-major.
pub fn matrix(xs: &[f64]) -> Result<Mat4> {
    let m = match xs.len() {
        16 => {
            let mut c = [0.0f32; 16];
            for (i, v) in xs.iter().enumerate() {
                c[i] = *v as f32;
            }
            Mat4::from_cols_array(&c).transpose()
        }
        9 => {
            let f = |i: usize| xs[i] as f32;
            Mat4::from_cols_array(&[f(0), f(3), f(6), 0.0, f(1), f(4), f(7), 0.0, f(2), f(5), f(8), 0.0, 0.0, 0.0, 0.0, 1.0])
        }
        n => bail!("needs 16 (or 9) numbers, got {n}"),
    };
    if m.determinant() == 0.0 || !m.is_finite() {
        bail!("the matrix is singular");
    }
    Ok(m)
}

/// Mitsuba's `look_at(origin, target, up)`; without `up` an arbitrary perpendicular.
pub fn look_at(origin: Vec3, target: Vec3, up: Option<Vec3>) -> Result<Mat4> {
    let dir = (target - origin).normalize_or_zero();
    if dir == Vec3::ZERO {
        bail!("origin and target coincide");
    }
    let up = match up {
        Some(u) => u,
        None => crate::math::Frame::new(dir).s,
    };
    let left = up.cross(dir).normalize_or_zero();
    if left == Vec3::ZERO {
        bail!("`up` is zero or parallel to the viewing direction");
    }
    let new_up = dir.cross(left);
    Ok(Mat4::from_cols(left.extend(0.0), new_up.extend(0.0), dir.extend(0.0), origin.extend(1.0)))
}

/// Applies `m` to a normal (inverse transpose).
pub fn normal_matrix(m: &Mat4) -> Mat4 {
    m.inverse().transpose()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_major_matrix_and_lookat() {
        let m = matrix(&[1.0, 0.0, 0.0, 5.0, 0.0, 1.0, 0.0, 6.0, 0.0, 0.0, 1.0, 7.0, 0.0, 0.0, 0.0, 1.0]).unwrap();
        assert_eq!(m.transform_point3(Vec3::ZERO), Vec3::new(5.0, 6.0, 7.0));
        let l = look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Some(Vec3::Y)).unwrap();
        assert!((l.transform_vector3(Vec3::Z) - Vec3::NEG_Z).length() < 1e-6);
        // +x is the image's left: viewed from +z towards the origin, left is -x.
        assert!((l.transform_vector3(Vec3::X) - Vec3::NEG_X).length() < 1e-6);
        assert!(look_at(Vec3::ZERO, Vec3::ZERO, None).is_err());
        assert!(matrix(&[0.0; 16]).is_err());
    }
}
