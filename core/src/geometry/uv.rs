//! Texture coordinates of surface points, computed when a shading point's BSDF asks for them
//! (it varies over the surface), from the hit's shape, primitive and position: a hit record
//! carries none, so that a scene without textures pays nothing for them (no barycentrics kept
//! per hit, no vertex UV read).
//!
//! The parameterisations are Mitsuba 3's: a mesh's vertex UVs interpolated over its triangle
//! (a mesh without them: the barycentrics (b1, b2)), `rectangle` and `cube` as vertex UVs of
//! their meshes, `sphere` (φ/2π, θ/π) and `disk` (r, φ/2π) in the shape's own frame.

use super::aggregate::Geometry;
use super::ray::Intersection;
use super::shapes::{Mesh, ShapeGeometry};
use glam::{Affine3A, Mat3, Vec2, Vec3};
use std::f64::consts::{PI, TAU};

/// How a shape's points map to texture coordinates where its geometry does not say it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UvMapping {
    /// From the shape itself: a mesh's vertex UVs interpolated at the point (its barycentrics
    /// (b1, b2) without them, as Mitsuba's meshes); a sphere's (φ/2π, θ/π) about the world's
    /// axes.
    Intrinsic,
    /// Mitsuba's `sphere`: (φ/2π, θ/π) of the point's direction from the centre in the
    /// sphere's own frame, `to_object` the inverse of the linear part of its transform.
    Sphere { to_object: Mat3 },
    /// Mitsuba's `disk`: (r, φ/2π) of the point in the disk's own plane (z = 0),
    /// `to_object` the inverse of its transform.
    Polar { to_object: Affine3A },
}

impl Geometry {
    /// The shapes' texture coordinate mappings, one per shape (all [`UvMapping::Intrinsic`]
    /// unless set).
    ///
    /// # Panics
    /// If there is not one per shape.
    pub fn with_uv_mappings(mut self, mappings: Vec<UvMapping>) -> Self {
        assert_eq!(
            mappings.len(),
            self.shapes.len(),
            "one UV mapping per shape"
        );
        self.uv_mappings = mappings;
        self
    }

    /// The texture coordinates of the surface point `hit` (a hit of this geometry), finite.
    pub fn uv(&self, hit: &Intersection) -> Vec2 {
        let shape = hit.shape as usize;
        let uv = match (&self.uv_mappings[shape], &self.shapes[shape]) {
            (UvMapping::Sphere { to_object }, ShapeGeometry::Sphere(sphere)) => {
                spherical(*to_object * (hit.position - sphere.center))
            }
            (UvMapping::Polar { to_object }, _) => polar(to_object.transform_point3(hit.position)),
            (_, ShapeGeometry::Sphere(sphere)) => spherical(hit.position - sphere.center),
            (_, ShapeGeometry::Mesh(mesh)) => mesh_uv(mesh, hit.primitive as usize, hit.position),
        };
        if uv.is_finite() { uv } else { Vec2::ZERO }
    }
}

/// Mitsuba's sphere coordinates of direction `d`: (φ/2π, θ/π), φ in [0, 2π) from +x toward +y,
/// θ from +z.
fn spherical(d: Vec3) -> Vec2 {
    let d = d.as_dvec3();
    let length = d.length();
    let mut phi = d.y.atan2(d.x);
    if phi < 0.0 {
        phi += TAU;
    }
    let theta = (d.z / length).clamp(-1.0, 1.0).acos();
    Vec2::new((phi / TAU) as f32, (theta / PI) as f32)
}

/// Mitsuba's disk coordinates of point `p` of the plane z = 0: (r, φ/2π), φ in [0, 2π).
fn polar(p: Vec3) -> Vec2 {
    let (x, y) = (p.x as f64, p.y as f64);
    let mut phi = y.atan2(x);
    if phi < 0.0 {
        phi += TAU;
    }
    Vec2::new(x.hypot(y) as f32, (phi / TAU) as f32)
}

/// The texture coordinates of point `p` of triangle `triangle` of `mesh`: its vertex UVs
/// interpolated, or its barycentrics (b1, b2). The barycentrics are those of `p`'s projection
/// onto the triangle's plane, in f64 (a hit is on the plane within its error bound).
fn mesh_uv(mesh: &Mesh, triangle: usize, p: Vec3) -> Vec2 {
    let [a, b, c] = mesh.triangle(triangle).map(Vec3::as_dvec3);
    let (e1, e2, v) = (b - a, c - a, p.as_dvec3() - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (v1, v2) = (v.dot(e1), v.dot(e2));
    let determinant = d11 * d22 - d12 * d12;
    let (b1, b2) = if determinant > 0.0 {
        (
            (d22 * v1 - d12 * v2) / determinant,
            (d11 * v2 - d12 * v1) / determinant,
        )
    } else {
        (0.0, 0.0)
    };
    match &mesh.uvs {
        Some(uvs) => {
            let [i0, i1, i2] = mesh.indices[triangle].map(|i| uvs[i as usize].as_dvec2());
            (i0 + (i1 - i0) * b1 + (i2 - i0) * b2).as_vec2()
        }
        None => Vec2::new(b1 as f32, b2 as f32),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Ray, Sphere, cube, disk, rectangle};
    use glam::{Affine3A, Mat4, Quat};

    /// The texture coordinates where `ray` meets the geometry.
    fn uv_along(geometry: &Geometry, origin: Vec3, direction: Vec3) -> Vec2 {
        let ray = Ray {
            origin,
            direction,
            t_max: f32::INFINITY,
        };
        let hit = geometry.intersect(&ray).expect("the ray meets the shape");
        geometry.uv(&hit)
    }

    fn close(a: Vec2, b: Vec2) -> bool {
        (a - b).abs().max_element() < 2e-5
    }

    /// Mitsuba 3.9.1's texture coordinates (`scene.ray_intersect(ray).uv`, scalar_rgb) at the
    /// same rays, for its `cube`, `rectangle`, `disk` and `sphere` (unrotated and turned 90°
    /// about z): each face of the cube, the polar disk, the spherical angles in the shape's
    /// frame.
    #[test]
    fn built_in_shapes_have_mitsubas_texture_coordinates() {
        let cube_hits = [
            ((0.0, -3.0, 0.2), (0.0, 1.0, 0.0), (0.6, 0.5)),
            ((0.3, 3.0, 0.2), (0.0, -1.0, 0.0), (0.35, 0.4)),
            ((3.0, 0.3, 0.2), (-1.0, 0.0, 0.0), (0.65, 0.4)),
            ((0.3, 0.5, 3.0), (0.0, 0.0, -1.0), (0.75, 0.65)),
            ((-3.0, 0.3, 0.2), (1.0, 0.0, 0.0), (0.65, 0.6)),
            ((0.3, 0.5, -3.0), (0.0, 0.0, 1.0), (0.25, 0.65)),
        ];
        let geometry = Geometry::new(vec![ShapeGeometry::Mesh(cube())]);
        for (origin, direction, uv) in cube_hits {
            let got = uv_along(&geometry, origin.into(), direction.into());
            assert!(
                close(got, uv.into()),
                "cube from {origin:?}: {got} against {uv:?}"
            );
        }
        let down = Vec3::new(0.0, 0.0, -1.0);
        let above = Vec3::new(0.3, -0.6, 3.0);
        let geometry = Geometry::new(vec![ShapeGeometry::Mesh(rectangle())]);
        assert!(close(
            uv_along(&geometry, above, down),
            Vec2::new(0.65, 0.2)
        ));
        // A disk of 1024 segments, so that its fan covers the point; the mapping is polar.
        let geometry = Geometry::new(vec![ShapeGeometry::Mesh(disk(1024))]).with_uv_mappings(vec![
            UvMapping::Polar {
                to_object: Affine3A::IDENTITY,
            },
        ]);
        let got = uv_along(&geometry, above, down);
        assert!(close(got, Vec2::new(0.67082, 0.823792)), "disk: {got}");
        let unit = ShapeGeometry::Sphere(Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        });
        let geometry = Geometry::new(vec![unit.clone()]);
        for (origin, uv) in [
            ((0.3, -0.6, 3.0), (0.823792, 0.0700243)),
            ((0.3, 0.6, -3.0), (0.176208, 0.929976)),
            ((3.0, 0.1, 0.2), (0.0053032, 0.478822)),
        ] {
            let origin = Vec3::from(origin);
            let got = uv_along(&geometry, origin, -origin);
            assert!(
                close(got, uv.into()),
                "sphere from {origin}: {got} against {uv:?}"
            );
        }
        let turned = Mat4::from_quat(Quat::from_rotation_z(90f32.to_radians()));
        let geometry = Geometry::new(vec![unit]).with_uv_mappings(vec![UvMapping::Sphere {
            to_object: Mat3::from_mat4(turned).inverse(),
        }]);
        let got = uv_along(&geometry, Vec3::new(3.0, 0.1, 0.2), -Vec3::X);
        assert!(
            close(got, Vec2::new(0.766272, 0.435906)),
            "turned sphere: {got}"
        );
    }

    /// A mesh's vertex UVs are interpolated at the hit; without them, the hit's barycentrics
    /// (b1, b2) are its coordinates, as in Mitsuba. A mapping that gives no finite value (a
    /// degenerate transform) gives (0, 0).
    #[test]
    fn meshes_interpolate_their_vertex_uvs() {
        let triangle = |uvs| Mesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::new(4.0, 0.0, 0.0),
                Vec3::new(0.0, 2.0, 0.0),
            ],
            normals: None,
            indices: vec![[0, 1, 2]],
            uvs,
        };
        let point = Vec3::new(1.0, 0.5, 5.0);
        let down = -Vec3::Z;
        let plain = Geometry::new(vec![ShapeGeometry::Mesh(triangle(None))]);
        assert!(close(uv_along(&plain, point, down), Vec2::new(0.25, 0.25)));
        let uvs = vec![
            Vec2::new(0.5, 0.5),
            Vec2::new(1.5, 0.5),
            Vec2::new(0.5, -1.5),
        ];
        let textured = Geometry::new(vec![ShapeGeometry::Mesh(triangle(Some(uvs)))]);
        assert!(close(
            uv_along(&textured, point, down),
            Vec2::new(0.75, 0.0)
        ));
        let degenerate = plain.with_uv_mappings(vec![UvMapping::Polar {
            to_object: Affine3A::from_mat4(Mat4::ZERO).inverse(),
        }]);
        assert_eq!(uv_along(&degenerate, point, down), Vec2::ZERO);
    }
}
