//! The ray–sphere test, and a sphere's bounding box.

use super::ray::Ray;
use super::shapes::Sphere;
use crate::math::{gamma, next_float_down, next_float_up};
use obvhs::aabb::Aabb;

/// The smallest t in (t_min_bound, t_max) where the ray meets the sphere.
#[inline]
pub(super) fn intersect_sphere(ray: &Ray, t_max: f32, s: &Sphere) -> Option<f32> {
    if ends_before_sphere(ray, t_max, s) {
        return None;
    }
    sphere_roots(ray, t_max, s)
}

/// Whether the ray ends outside the sphere before its closest approach to the centre, so that
/// no root lies before its end: a shadow ray stopping short of a point on this sphere (the
/// common case), decided without the divisions and square roots of [`sphere_roots`]. The end
/// must lie outside by more than rounding can move it: the end point is off by a few units of
/// roundoff of the lengths that make it (`reach`, bounded by 1-norms), which moves its squared
/// distance from the centre by about twice that times the radius, near the surface.
/// [`SPHERE_END_MARGIN`] is 16 units of roundoff: `spheres_skipped_have_no_root_before_the_ray_ends`
/// finds no root skipped with 1 unit, and finds one with a quarter (in between was not tried).
/// A tested margin, not a proof.
#[inline]
fn ends_before_sphere(ray: &Ray, t_max: f32, s: &Sphere) -> bool {
    let f = ray.origin - s.center;
    let a = ray.direction.length_squared();
    let b = -f.dot(ray.direction);
    let r2 = s.radius * s.radius;
    let reach = f.abs().element_sum() + t_max * ray.direction.abs().element_sum();
    let margin = SPHERE_END_MARGIN * (s.radius * reach + r2);
    b > t_max * a && (f + t_max * ray.direction).length_squared() - r2 > margin
}

/// The margin of [`ends_before_sphere`], in units of roundoff.
const SPHERE_END_MARGIN: f32 = 16.0 * f32::EPSILON;

/// [`intersect_sphere`]'s answer, computed in full.
#[inline]
fn sphere_roots(ray: &Ray, t_max: f32, s: &Sphere) -> Option<f32> {
    // Ray Tracing Gems, ch. 7: a discriminant that does not cancel catastrophically.
    let f = ray.origin - s.center;
    let a = ray.direction.length_squared();
    let b = -f.dot(ray.direction);
    let l = f + (b / a) * ray.direction;
    let disc = a * (s.radius * s.radius - l.length_squared());
    if disc < 0.0 || a == 0.0 {
        return None;
    }
    let q = b + b.signum() * disc.sqrt();
    let (mut t0, mut t1) = if q == 0.0 {
        (0.0, 0.0)
    } else {
        (q / a, (f.length_squared() - s.radius * s.radius) / q)
    };
    if t0 > t1 {
        std::mem::swap(&mut t0, &mut t1);
    }
    // Roots closer than the rounding error of the computation are the surface the ray left.
    let t_eps = gamma(16) * (f.length() + s.radius) / a.sqrt();
    [t0, t1].into_iter().find(|&t| t > t_eps && t < t_max)
}

/// The box of a sphere, rounded outward (`center ± radius` in f32 may round inward).
pub(super) fn sphere_box(center: glam::Vec3, radius: f32) -> Aabb {
    let lo = (center - radius).to_array().map(next_float_down);
    let hi = (center + radius).to_array().map(next_float_up);
    Aabb::new(lo.into(), hi.into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::ray::SHADOW_EPSILON;
    use glam::Vec3;

    /// `ends_before_sphere` skips the full sphere test only where it finds no root before the
    /// ray's end: shadow rays toward points on the sphere that the origin sees, from 1.01 to
    /// 10⁴ radii away, ending 10⁻⁴ short of them (as shadow rays do; these are skipped) or
    /// 10⁻⁶ short of or beyond them (the full test's own rounding), and random rays of random
    /// lengths; radii from 10⁻³ to 10³, centres up to 10⁴ radii away.
    #[test]
    fn spheres_skipped_have_no_root_before_the_ray_ends() {
        let mut sampler = crate::sampler::Sampler::new(17, 0, 0);
        let mut uniform = move || sampler.next_1d();
        let mut pick = |n: u32| (uniform() * n as f32) as i32;
        let unit = |pick: &mut dyn FnMut(u32) -> i32| loop {
            let v =
                Vec3::new(pick(2001) as f32, pick(2001) as f32, pick(2001) as f32) / 1000.0 - 1.0;
            if v.length_squared() > 1e-4 {
                return v.normalize();
            }
        };
        let (mut skipped, mut shadow, mut shadow_skipped) = (0, 0, 0);
        for i in 0..300_000 {
            let scale = 10f32.powi(pick(7) - 3);
            let sphere = Sphere {
                center: unit(&mut pick) * 10f32.powi(pick(5)) * scale,
                radius: scale,
            };
            let ray = if i % 2 == 0 {
                let away = [1.01, 1.5, 3.0, 30.0, 1e4][pick(5) as usize];
                let origin = sphere.center + unit(&mut pick) * scale * away;
                // A point the origin sees: on the cap facing it.
                let Some(normal) = (0..64)
                    .map(|_| unit(&mut pick))
                    .find(|&n| n.dot(origin - sphere.center) > sphere.radius * 1.0001)
                else {
                    continue;
                };
                let target = sphere.center + normal * sphere.radius;
                let t_max = [1.0 - SHADOW_EPSILON, 1.0 - 1e-6, 1.0 + 1e-6][pick(3) as usize];
                shadow += (t_max == 1.0 - SHADOW_EPSILON) as usize;
                Ray {
                    origin,
                    direction: target - origin,
                    t_max,
                }
            } else {
                Ray {
                    origin: sphere.center + unit(&mut pick) * scale * 10f32.powi(pick(4)),
                    direction: unit(&mut pick),
                    t_max: 10f32.powi(pick(6) - 2) * scale,
                }
            };
            if ends_before_sphere(&ray, ray.t_max, &sphere) {
                assert_eq!(
                    sphere_roots(&ray, ray.t_max, &sphere),
                    None,
                    "{sphere:?}, {ray:?}: skipped, but the full test finds a root"
                );
                skipped += 1;
                shadow_skipped += (ray.t_max == 1.0 - SHADOW_EPSILON) as usize;
            }
        }
        // Most shadow rays ending as shadow rays do are skipped (87 % at this seed; the rest end
        // too close to the surface for the margin), and random rays too.
        assert!(
            shadow_skipped * 100 > shadow * 80 && skipped > shadow_skipped + 20_000,
            "{skipped} rays skipped; {shadow_skipped} of {shadow} shadow rays"
        );
    }
}
