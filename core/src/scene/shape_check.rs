//! The checks every shape of a scene passes once in world space, with messages that say what
//! is wrong: the limits within which the BVH and the intersection arithmetic stay exact
//! (docs/robustness.md).

use crate::geometry::{Mesh, ShapeGeometry};
use crate::limits::{MAX_COORDINATE, MIN_SHAPE_SIZE, fmt_f32};
use glam::Vec3;

/// "(x, y, z)" for messages.
fn fmt_point(p: Vec3) -> String {
    crate::limits::fmt_f32s(&p.to_array())
}

/// Checks that a shape (in world space) lies where the BVH and the intersection arithmetic stay
/// exact: every coordinate finite and within ±[`MAX_COORDINATE`] ([`check_coordinates`]), a
/// size of at least [`MIN_SHAPE_SIZE`], and for a mesh at least one triangle with an area at f32
/// precision. The message says what is wrong; the caller names the shape.
pub fn check_shape(shape: &ShapeGeometry) -> Result<(), String> {
    check_coordinates(shape)?;
    match shape {
        ShapeGeometry::Sphere(s) => {
            if s.radius < MIN_SHAPE_SIZE {
                return Err(format!(
                    "the sphere's radius {} is below the smallest supported size, {}",
                    fmt_f32(s.radius),
                    fmt_f32(MIN_SHAPE_SIZE)
                ));
            }
        }
        ShapeGeometry::Mesh(mesh) => {
            let (lo, hi) = mesh.positions.iter().fold(
                (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                |(lo, hi), p| (lo.min(*p), hi.max(*p)),
            );
            let size = (hi - lo).as_dvec3().length();
            if size < MIN_SHAPE_SIZE as f64 {
                return Err(format!(
                    "its size (bounding-box diagonal) is {}, below the smallest supported size, {}",
                    fmt_f32(size as f32),
                    fmt_f32(MIN_SHAPE_SIZE)
                ));
            }
            if !has_area(mesh) {
                return Err(
                    "none of its triangles has an area at f32 precision (the shape is flat, or too small for its distance from the origin)"
                        .into(),
                );
            }
        }
    }
    Ok(())
}

/// Whether at least one of the mesh's triangles has an area at f32 precision.
pub fn has_area(mesh: &Mesh) -> bool {
    (0..mesh.indices.len()).any(|i| {
        let [a, b, c] = mesh.triangle(i);
        (b - a).cross(c - a) != Vec3::ZERO
    })
}

/// Checks that every coordinate of a shape is finite and within ±[`MAX_COORDINATE`], which the
/// BVH builder needs (it fails on sizes around 1e19): the shapes it accepts are those
/// [`ShapeGeometry::within_coordinate_limit`] accepts, which `Geometry::new` asserts.
pub fn check_coordinates(shape: &ShapeGeometry) -> Result<(), String> {
    let max = MAX_COORDINATE;
    match shape {
        ShapeGeometry::Sphere(s) => {
            if !(s.center.is_finite() && s.radius.is_finite()) {
                return Err(format!(
                    "the sphere's centre {} or radius {} is not finite after its transform",
                    fmt_point(s.center),
                    fmt_f32(s.radius)
                ));
            }
            let reach = s.center.abs().max_element() as f64 + s.radius as f64;
            if reach > max as f64 {
                return Err(format!(
                    "the sphere (centre {}, radius {}) reaches coordinates of {}, beyond the supported ±{}",
                    fmt_point(s.center),
                    fmt_f32(s.radius),
                    fmt_f32(reach as f32),
                    fmt_f32(max)
                ));
            }
        }
        ShapeGeometry::Mesh(mesh) => {
            if let Some(p) = mesh.positions.iter().find(|p| !p.is_finite()) {
                return Err(format!(
                    "a vertex is at {} after the transform: not finite",
                    fmt_point(*p)
                ));
            }
            if let Some(p) = mesh.positions.iter().find(|p| p.abs().max_element() > max) {
                return Err(format!(
                    "a vertex is at {} after the transform, beyond the supported ±{} (reduce `scale` or `translate`, or choose a larger unit)",
                    fmt_point(*p),
                    fmt_f32(max)
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Mesh, Sphere};
    use crate::math::next_float_up;

    /// `check_coordinates` refuses exactly the shapes `Geometry::new` refuses
    /// ([`ShapeGeometry::within_coordinate_limit`]): spheres and triangles at, inside and one
    /// ulp beyond the limit, reaching it by their radius, and with infinite or NaN values.
    #[test]
    fn coordinates_are_refused_as_the_bvh_needs() {
        let max = MAX_COORDINATE;
        let coordinates = [
            0.0,
            -1.0,
            0.75 * max,
            max,
            -max,
            next_float_up(max),
            -next_float_up(max),
            f32::INFINITY,
            f32::NAN,
        ];
        let radii = [0.5, 0.25 * max, 0.5 * max, f32::INFINITY, f32::NAN];
        let mut shapes = Vec::new();
        for x in coordinates {
            let p = Vec3::new(0.0, x, 1.0);
            shapes.extend(radii.map(|radius| ShapeGeometry::Sphere(Sphere { center: p, radius })));
            shapes.push(ShapeGeometry::Mesh(Mesh {
                positions: vec![Vec3::ZERO, Vec3::X, p],
                normals: None,
                indices: vec![[0, 1, 2]],
                uvs: None,
            }));
        }
        let mut refused = 0;
        for shape in &shapes {
            let checked = check_coordinates(shape);
            assert_eq!(
                checked.is_ok(),
                shape.within_coordinate_limit(),
                "{shape:?}: {checked:?}"
            );
            refused += usize::from(checked.is_err());
        }
        assert!(
            refused > 20 && shapes.len() - refused > 10,
            "{refused} of {}",
            shapes.len()
        );
    }
}
