//! Texture coordinates of surface points, computed when a shading point's BSDF asks for them
//! (it varies over the surface), from the hit's shape, primitive and position: a hit record
//! carries none, so that a scene without textures pays nothing for them (no barycentrics kept
//! per hit, no vertex UV read).
//!
//! The parameterisations are Mitsuba 3's: a mesh's vertex UVs interpolated over its triangle
//! (a mesh without them: the barycentrics (b1, b2)), `rectangle` and `cube` as vertex UVs of
//! their meshes, `sphere` (φ/2π, θ/π) and `disk` (r, φ/2π) in the shape's own frame.

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

impl UvMapping {
    /// The texture coordinates of the point `hit` on `shape`, the shape this mapping is
    /// for; finite.
    pub(super) fn uv(&self, shape: &ShapeGeometry, hit: &Intersection) -> Vec2 {
        let uv = match (self, shape) {
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
mod tests;
