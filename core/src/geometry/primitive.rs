//! The primitives the BVH's leaves hold: one triangle of a mesh, or a sphere.

use super::ray::{Intersection, Ray};
use super::shapes::Sphere;
use super::sphere::{intersect_sphere, sphere_box};
use super::triangle::{RayShear, intersect_triangle};
use glam::Vec3;
use obvhs::Boundable;
use obvhs::aabb::Aabb;

/// A primitive as the BVH leaves store it.
#[derive(Clone, Copy, Debug)]
pub(super) enum Primitive {
    Triangle {
        p: [Vec3; 3],
        shape: u32,
        index: u32,
    },
    Sphere {
        sphere: Sphere,
        shape: u32,
    },
}

impl Boundable for Primitive {
    fn aabb(&self) -> Aabb {
        match self {
            Primitive::Triangle { p, .. } => {
                Aabb::from_points(&[p[0].into(), p[1].into(), p[2].into()])
            }
            Primitive::Sphere { sphere, .. } => sphere_box(sphere.center, sphere.radius),
        }
    }
}

impl Primitive {
    /// Index of the shape the primitive belongs to.
    pub(super) fn shape(&self) -> u32 {
        match self {
            Primitive::Triangle { shape, .. } | Primitive::Sphere { shape, .. } => *shape,
        }
    }

    /// Whether this is the triangle that surface point `from` lies on. A ray leaving a point
    /// of a triangle leaves its plane and cannot meet it again: from its origin offset off the
    /// plane ([`RayOrigin`]) the watertight test finds t ≤ 0 and rejects it, after most of its
    /// work (the origin projects inside the triangle, so every edge test passes). A sphere is
    /// never skipped: a ray into it meets its far side.
    ///
    /// [`RayOrigin`]: super::RayOrigin
    #[inline(always)]
    pub(super) fn is_triangle_under(&self, from: &Intersection) -> bool {
        matches!(self, Primitive::Triangle { shape, index, .. }
            if *shape == from.shape && *index == from.primitive)
    }

    /// Where `ray` (with its `shear`) meets the primitive before `t_max`: the distance and the
    /// barycentrics (zero for a sphere).
    #[inline(always)]
    pub(super) fn hit(&self, ray: &Ray, shear: &RayShear, t_max: f32) -> Option<(f32, [f32; 3])> {
        let (t, b) = match self {
            Primitive::Triangle { p, .. } => intersect_triangle(ray, shear, t_max, p)?,
            Primitive::Sphere { sphere, .. } => (intersect_sphere(ray, t_max, sphere)?, [0.0; 3]),
        };
        (t < t_max).then_some((t, b))
    }
}
