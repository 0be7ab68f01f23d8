//! Shape geometry: triangle meshes (built-in or from glTF) and analytic spheres, in world space.

use super::description::TransformDescription;
use glam::{Mat3, Mat4, Vec3};
use std::f32::consts::TAU;

/// A triangle mesh in world space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals, when the source has them.
    pub normals: Option<Vec<Vec3>>,
    /// Counter-clockwise triangles: the geometric normal is (p1 − p0) × (p2 − p0).
    pub indices: Vec<[u32; 3]>,
}

/// A sphere in world space; its normal points outward.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

/// The geometry of one shape of the scene.
#[derive(Clone, Debug, PartialEq)]
pub enum ShapeGeometry {
    Mesh(Mesh),
    Sphere(Sphere),
}

impl Mesh {
    /// Applies `m` to the positions, its inverse transpose to the normals, and keeps triangles
    /// counter-clockwise when `m` mirrors.
    pub fn transformed(mut self, m: &Mat4) -> Mesh {
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        let normal_matrix = Mat3::from_mat4(*m).inverse().transpose();
        if let Some(normals) = &mut self.normals {
            for n in normals.iter_mut() {
                *n = (normal_matrix * *n).normalize_or_zero();
            }
        }
        if m.determinant() < 0.0 {
            for t in &mut self.indices {
                t.swap(1, 2);
            }
        }
        self
    }

    /// Every face turned the other way: winding reversed and normals negated.
    pub fn flipped(mut self) -> Mesh {
        for t in &mut self.indices {
            t.swap(1, 2);
        }
        if let Some(normals) = &mut self.normals {
            for n in normals.iter_mut() {
                *n = -*n;
            }
        }
        self
    }

    /// Appends another mesh (used to merge the nodes of one glTF shape).
    pub fn append(&mut self, other: Mesh) {
        let offset = self.positions.len() as u32;
        let normals_kept = self.normals.is_some() || self.positions.is_empty();
        match (&mut self.normals, other.normals) {
            (Some(a), Some(b)) if normals_kept => a.extend(b),
            (None, Some(b)) if self.positions.is_empty() => self.normals = Some(b),
            _ => self.normals = None,
        }
        self.positions.extend(other.positions);
        self.indices.extend(
            other
                .indices
                .iter()
                .map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]),
        );
    }

    pub fn triangle(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    pub fn triangle_area(&self, i: usize) -> f32 {
        let [a, b, c] = self.triangle(i);
        0.5 * (b - a).cross(c - a).length()
    }
}

/// The square [−1, 1]² in the z = 0 plane, facing +z.
pub fn rectangle() -> Mesh {
    Mesh {
        positions: vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ],
        normals: Some(vec![Vec3::Z; 4]),
        indices: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// The unit disk in the z = 0 plane, facing +z, as a fan of `segments` triangles.
pub fn disk(segments: u32) -> Mesh {
    let mut positions = vec![Vec3::ZERO];
    positions.extend((0..segments).map(|i| {
        let phi = TAU * i as f32 / segments as f32;
        Vec3::new(phi.cos(), phi.sin(), 0.0)
    }));
    let indices = (0..segments)
        .map(|i| [0, 1 + i, 1 + (i + 1) % segments])
        .collect();
    Mesh {
        normals: Some(vec![Vec3::Z; positions.len()]),
        positions,
        indices,
    }
}

/// The cube [−1, 1]³ with outward faces and flat normals.
pub fn cube() -> Mesh {
    let mut mesh = Mesh {
        positions: vec![],
        normals: Some(vec![]),
        indices: vec![],
    };
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = Vec3::ZERO;
            n[axis] = sign;
            // u × v = n for a counter-clockwise face seen from outside.
            let mut u = Vec3::ZERO;
            u[(axis + 1) % 3] = 1.0;
            let v = n.cross(u);
            let base = mesh.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                mesh.positions.push(n + u * a + v * b);
            }
            if let Some(normals) = &mut mesh.normals {
                normals.extend([n; 4]);
            }
            mesh.indices.push([base, base + 1, base + 2]);
            mesh.indices.push([base, base + 2, base + 3]);
        }
    }
    mesh
}

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

/// The matrix of a transform description, or a message saying what is wrong with it.
pub fn transform_matrix(t: &TransformDescription) -> Result<Mat4, String> {
    let scale = Mat4::from_scale(Vec3::from(t.scale.unwrap_or([1.0; 3])));
    let m = if let Some(matrix) = t.matrix {
        if t.scale.is_some() || !t.rotate.is_empty() || t.translate.is_some() || t.look_at.is_some()
        {
            return Err(
                "`matrix` cannot be combined with scale, rotate, translate or look_at".into(),
            );
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
    if !m.is_finite() || m.determinant().abs() < 1e-30 {
        return Err("the transform is singular or not finite".into());
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::description::RotationDescription;

    fn closed_mesh_volume(m: &Mesh) -> f32 {
        (0..m.indices.len())
            .map(|i| {
                let [a, b, c] = m.triangle(i);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn builtins_have_the_documented_size_and_orientation() {
        let r = rectangle();
        assert!(((0..2).map(|i| r.triangle_area(i)).sum::<f32>() - 4.0).abs() < 1e-6);
        let [a, b, c] = r.triangle(0);
        assert!((b - a).cross(c - a).normalize().abs_diff_eq(Vec3::Z, 1e-6));
        // Outward faces give a positive volume of 8.
        assert!((closed_mesh_volume(&cube()) - 8.0).abs() < 1e-5);
        let d = disk(256);
        let area: f32 = (0..256).map(|i| d.triangle_area(i)).sum();
        assert!((area - std::f32::consts::PI).abs() < 1e-3);
    }

    #[test]
    fn mirroring_keeps_faces_outward() {
        let m = transform_matrix(&TransformDescription {
            scale: Some([-2.0, 1.0, 1.0]),
            ..Default::default()
        })
        .unwrap();
        assert!((closed_mesh_volume(&cube().transformed(&m)) - 16.0).abs() < 1e-4);
    }

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
