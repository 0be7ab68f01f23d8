//! Rays, where they meet a surface ([`Intersection`]), and the origins of the rays that leave
//! it ([`RayOrigin`]).
//!
//! Self-intersection is avoided as in pbrt-v4 (§6.8): each hit carries a conservative bound on
//! the rounding error of its position, and rays leave a surface from an origin pushed just past
//! that bound along the normal. The offset scales with the coordinates, so it holds at any scene
//! scale, unlike a fixed epsilon.

use crate::math::{next_float_down, next_float_up};
use glam::{Vec3, Vec3A};

/// A ray `origin + t · direction`, t in (0, t_max). `direction` need not be unit length.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3,
    pub direction: Vec3,
    pub t_max: f32,
}

/// `v` in lanes, read coordinate by coordinate. A query's ray is most often written just before
/// it is asked, by stores of one or two coordinates each, and a wider read of several of them
/// cannot be forwarded from those stores: it waits until they reach the cache. (That wait took
/// the largest share of `may_meet`'s time, and of the dragon's occlusion queries' set-up.) The
/// reads are volatile so that the compiler does not merge them again. The result must stay in
/// registers: a copy in memory would be read in lanes again.
#[inline(always)]
pub(super) fn read_coordinates(v: &Vec3) -> Vec3A {
    // SAFETY: each pointer is to one f32 of `v`, valid and aligned.
    let read = |c: &f32| unsafe { std::ptr::read_volatile(c) };
    Vec3A::new(read(&v.x), read(&v.y), read(&v.z))
}

/// A ray–surface intersection.
#[derive(Clone, Copy, Debug)]
pub struct Intersection {
    pub t: f32,
    pub position: Vec3,
    /// Conservative absolute error bound of `position`, per axis.
    pub error: Vec3,
    /// Unit geometric normal, oriented as the shape defines its front side.
    pub geometric_normal: Vec3,
    /// Unit shading normal (interpolated vertex normal, or the geometric one), on the same side
    /// as `geometric_normal`.
    pub shading_normal: Vec3,
    /// Index of the shape in the scene.
    pub shape: u32,
    /// Index of the triangle within its mesh (0 for spheres).
    pub primitive: u32,
}

/// pbrt-v4's OffsetRayOrigin: a point just outside the error box of `p`, on the side of `n`
/// that `w` points to.
#[inline(always)]
pub fn offset_ray_origin(p: Vec3, error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(error);
    let mut offset = d * n;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let mut po = p + offset;
    for i in 0..3 {
        if offset[i] > 0.0 {
            po[i] = next_float_up(po[i]);
        } else if offset[i] < 0.0 {
            po[i] = next_float_down(po[i]);
        }
    }
    po
}

/// Relative shortening of shadow rays, so that the target point's own surface is not reported
/// as an occluder.
pub const SHADOW_EPSILON: f32 = 1e-4;

impl Intersection {
    /// A ray leaving this point in direction `w`.
    #[inline]
    pub fn spawn_ray(&self, w: Vec3) -> Ray {
        RayOrigin::toward(self, w).ray(self, w)
    }

    /// A ray from this point to `target` that stops just short of it.
    #[inline]
    pub fn spawn_ray_to(&self, target: Vec3) -> Ray {
        RayOrigin::toward(self, target - self.position).ray_to(self, target)
    }
}

/// The origin [`offset_ray_origin`] gives at an intersection for the directions on one side of
/// its surface. [`Intersection::spawn_ray`] computes one per ray; a shading point computes one
/// for the viewer's side and reuses it for all its shadow and BSDF rays (at N samples per
/// light, 2N rays per light, nearly all on that side). A ray toward the other side computes its
/// own, so every ray is the one `spawn_ray` or `spawn_ray_to` gives.
#[derive(Clone, Copy, Debug)]
pub struct RayOrigin {
    point: Vec3,
    /// Whether the side is the one where w · n < 0.
    behind: bool,
}

impl RayOrigin {
    /// The origin of `hit`'s rays toward the side `side` points to.
    #[inline]
    pub fn toward(hit: &Intersection, side: Vec3) -> Self {
        let n = hit.geometric_normal;
        RayOrigin {
            point: offset_ray_origin(hit.position, hit.error, n, side),
            behind: side.dot(n) < 0.0,
        }
    }

    /// The origin for direction `w`: this one if `w` is on its side (by `offset_ray_origin`'s
    /// test), else computed for `w`.
    #[inline(always)]
    fn for_direction(&self, hit: &Intersection, w: Vec3) -> Vec3 {
        let n = hit.geometric_normal;
        if (w.dot(n) < 0.0) == self.behind {
            self.point
        } else {
            offset_ray_origin(hit.position, hit.error, n, w)
        }
    }

    /// A ray leaving `hit` in direction `w`.
    #[inline]
    pub fn ray(&self, hit: &Intersection, w: Vec3) -> Ray {
        Ray {
            origin: self.for_direction(hit, w),
            direction: w,
            t_max: f32::INFINITY,
        }
    }

    /// A ray from `hit` to `target` that stops just short of it.
    #[inline]
    pub fn ray_to(&self, hit: &Intersection, target: Vec3) -> Ray {
        let origin = self.for_direction(hit, target - hit.position);
        Ray {
            origin,
            direction: target - origin,
            t_max: 1.0 - SHADOW_EPSILON,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::gamma;

    /// A [`RayOrigin`] computed ahead spawns the rays pbrt's formula gives, each ray's origin
    /// offset toward its own direction, bit for bit: for points from 10⁻³ to 10⁶, random and
    /// axis-aligned normals, and directions on either side, in the tangent plane (w · n = 0),
    /// zero and NaN, whichever side the origin was computed for.
    #[test]
    fn an_origin_computed_ahead_spawns_each_rays_own() {
        let mut sampler = crate::sampler::Sampler::new(11, 0, 0);
        let unit = |sampler: &mut crate::sampler::Sampler| {
            let u = sampler.next_2d();
            let z = 1.0 - 2.0 * u.x;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = std::f32::consts::TAU * u.y;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        };
        let bits = |r: Ray| {
            (
                r.origin.to_array().map(f32::to_bits),
                r.direction.to_array().map(f32::to_bits),
                r.t_max.to_bits(),
            )
        };
        for i in 0..20_000 {
            let scale = 10f32.powf(sampler.next_1d() * 9.0 - 3.0);
            let position = unit(&mut sampler) * scale;
            let geometric_normal = match i % 4 {
                0 => Vec3::new(0.0, -0.0, if i % 8 == 0 { 1.0 } else { -1.0 }),
                _ => unit(&mut sampler),
            };
            let hit = Intersection {
                t: 1.0,
                position,
                error: Vec3::splat(gamma(7)) * position.abs() * sampler.next_1d(),
                geometric_normal,
                shading_normal: geometric_normal,
                shape: 0,
                primitive: 0,
            };
            let w = unit(&mut sampler);
            let tangent = geometric_normal.any_orthonormal_vector();
            let ahead = RayOrigin::toward(&hit, if i % 2 == 0 { w } else { -w });
            let offset =
                |w: Vec3| offset_ray_origin(hit.position, hit.error, hit.geometric_normal, w);
            for w in [w, -w, tangent, -tangent, Vec3::ZERO, Vec3::NAN] {
                let expected = Ray {
                    origin: offset(w),
                    direction: w,
                    t_max: f32::INFINITY,
                };
                assert_eq!(bits(ahead.ray(&hit, w)), bits(expected), "{hit:?} {w}");
                assert_eq!(bits(hit.spawn_ray(w)), bits(expected), "{hit:?} {w}");
                let target = hit.position + w * scale * sampler.next_1d();
                let origin = offset(target - hit.position);
                let expected = Ray {
                    origin,
                    direction: target - origin,
                    t_max: 1.0 - SHADOW_EPSILON,
                };
                assert_eq!(
                    bits(ahead.ray_to(&hit, target)),
                    bits(expected),
                    "to {target}"
                );
                assert_eq!(
                    bits(hit.spawn_ray_to(target)),
                    bits(expected),
                    "to {target}"
                );
            }
        }
    }
}
