//! The matrix of a shape's `transform` in the scene file, and the checks every transform
//! passes (the scene file's and glTF nodes').

use super::description::TransformDescription;
use glam::{DMat3, DVec3, Mat4, Vec3};

/// sin and cos of an angle in degrees, exact at multiples of 90° (so that a plane turned by
/// 90° has an exactly perpendicular normal, not one tilted by cos(π/2) ≈ −4e-8 in f32).
fn sin_cos_degrees(degrees: f32) -> (f32, f32) {
    let quarter_turns = degrees / 90.0;
    if quarter_turns == quarter_turns.round() {
        return match (quarter_turns as i64).rem_euclid(4) {
            0 => (0.0, 1.0),
            1 => (1.0, 0.0),
            2 => (0.0, -1.0),
            _ => (-1.0, 0.0),
        };
    }
    let (sin, cos) = (degrees as f64).to_radians().sin_cos();
    (sin as f32, cos as f32)
}

/// Rotation by `degrees` about the unit `axis` (Rodrigues' formula, right-handed).
fn rotation(axis: Vec3, degrees: f32) -> Mat4 {
    let (s, c) = sin_cos_degrees(degrees);
    let t = 1.0 - c;
    let Vec3 { x, y, z } = axis;
    Mat4::from_cols(
        glam::Vec4::new(c + t * x * x, t * x * y + s * z, t * x * z - s * y, 0.0),
        glam::Vec4::new(t * x * y - s * z, c + t * y * y, t * y * z + s * x, 0.0),
        glam::Vec4::new(t * x * z + s * y, t * y * z - s * x, c + t * z * z, 0.0),
        glam::Vec4::W,
    )
}

/// Fails naming `field` when a value of it is not finite.
fn finite(field: &str, values: &[f32]) -> Result<(), String> {
    if values.iter().all(|v| v.is_finite()) {
        return Ok(());
    }
    Err(format!(
        "transform `{field}` must be finite, found {}",
        crate::limits::fmt_f32s(values)
    ))
}

/// The matrix of a transform description, or a message saying what is wrong with it: a field
/// that is not finite, a projective or singular matrix. Its scale is checked by what it does to
/// the shape ([`check_shape`](super::shape_check::check_shape)), not here.
pub fn transform_matrix(t: &TransformDescription) -> Result<Mat4, String> {
    if let Some(s) = &t.scale {
        finite("scale", s)?;
    }
    for r in &t.rotate {
        finite("rotate.axis", &r.axis)?;
        finite("rotate.angle", &[r.angle])?;
    }
    if let Some(v) = &t.translate {
        finite("translate", v)?;
    }
    if let Some(look) = &t.look_at {
        finite("look_at.origin", &look.origin)?;
        finite("look_at.target", &look.target)?;
        finite("look_at.up", &look.up)?;
    }
    if let Some(m) = &t.matrix {
        finite("matrix", m)?;
    }
    let scale = Mat4::from_scale(Vec3::from(t.scale.unwrap_or([1.0; 3])));
    let m = if let Some(matrix) = t.matrix {
        if t.scale.is_some() || !t.rotate.is_empty() || t.translate.is_some() || t.look_at.is_some()
        {
            return Err(
                "`matrix` cannot be combined with scale, rotate, translate or look_at".into(),
            );
        }
        let last_row = &matrix[12..16];
        if last_row != [0.0, 0.0, 0.0, 1.0] {
            return Err(format!(
                "the last row of `matrix` must be (0, 0, 0, 1), found {}: projective transforms are not supported",
                crate::limits::fmt_f32s(last_row)
            ));
        }
        Mat4::from_cols_array(&matrix).transpose()
    } else if let Some(look) = &t.look_at {
        if !t.rotate.is_empty() || t.translate.is_some() {
            return Err("`look_at` cannot be combined with rotate or translate".into());
        }
        let origin = Vec3::from(look.origin);
        let dir = (Vec3::from(look.target) - origin).normalize_or_zero();
        let right = Vec3::from(look.up).cross(dir).normalize_or_zero();
        if dir == Vec3::ZERO || right == Vec3::ZERO {
            return Err(
                "`look_at` needs distinct origin and target, and `up` not along the view".into(),
            );
        }
        let up = dir.cross(right);
        Mat4::from_cols(
            right.extend(0.0),
            up.extend(0.0),
            dir.extend(0.0),
            origin.extend(1.0),
        ) * scale
    } else {
        let mut m = scale;
        for r in &t.rotate {
            let axis = Vec3::from(r.axis).normalize_or_zero();
            if axis == Vec3::ZERO {
                return Err("a rotation axis must not be zero".into());
            }
            m = rotation(axis, r.angle) * m;
        }
        Mat4::from_translation(Vec3::from(t.translate.unwrap_or([0.0; 3]))) * m
    };
    check_affine(&m)?;
    Ok(m)
}

/// How far the columns of the linear part are from parallel: |det| / (|c₀| |c₁| |c₂|), which is
/// 1 for orthogonal columns of any length and 0 for a singular matrix (Hadamard's inequality).
/// Unlike the determinant it does not depend on the scale, so a transform scaling by 1e-20 is
/// not mistaken for a singular one. `None` if a column is zero.
pub fn column_independence(m: &Mat4) -> Option<f64> {
    let cols: [DVec3; 3] = [m.x_axis, m.y_axis, m.z_axis].map(|c| c.truncate().as_dvec3());
    let lengths = cols.map(|c| c.length());
    if lengths.iter().any(|&l| !(l > 0.0 && l.is_finite())) {
        return None;
    }
    let det = DMat3::from_cols(cols[0], cols[1], cols[2]).determinant();
    Some(det.abs() / (lengths[0] * lengths[1] * lengths[2]))
}

/// Smallest [`column_independence`] accepted: below it the shape is squashed flat along some
/// direction to within f32 rounding (about 1e-7 relative), and its normals are meaningless.
const MIN_COLUMN_INDEPENDENCE: f64 = 1e-6;

/// Refuses transforms that are not finite, not affine, or (nearly) singular.
pub fn check_affine(m: &Mat4) -> Result<(), String> {
    if !m.is_finite() {
        return Err("the transform is not finite (its parts multiply beyond f32's range)".into());
    }
    let row = m.row(3);
    if row != glam::Vec4::W {
        return Err(format!(
            "the transform is projective (last row {:?}, not (0, 0, 0, 1))",
            row.to_array()
        ));
    }
    match column_independence(m) {
        Some(q) if q >= MIN_COLUMN_INDEPENDENCE => Ok(()),
        _ => Err(
            "the transform is singular: it flattens the shape (a zero scale, or axes that coincide)"
                .into(),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::description::RotationDescription;

    #[test]
    fn transforms_apply_scale_then_rotations_then_translation() {
        let t = TransformDescription {
            scale: Some([2.0, 1.0, 1.0]),
            rotate: vec![RotationDescription {
                axis: [0.0, 0.0, 1.0],
                angle: 90.0,
            }],
            translate: Some([0.0, 0.0, 5.0]),
            ..Default::default()
        };
        let m = transform_matrix(&t).unwrap();
        assert!(
            m.transform_point3(Vec3::X)
                .abs_diff_eq(Vec3::new(0.0, 2.0, 5.0), 1e-5)
        );
        let bad = TransformDescription {
            scale: Some([0.0, 1.0, 1.0]),
            ..Default::default()
        };
        assert!(transform_matrix(&bad).is_err());
    }
}
