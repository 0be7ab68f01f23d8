//! The perspective pinhole camera.

use crate::geometry::Ray;
use crate::math::lanes::{Lanes, V3};
use glam::{Vec2, Vec3, Vec4};

#[derive(Clone, Debug)]
pub struct Camera {
    position: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    /// tan(fov_y / 2).
    tan_half_fov: f32,
    width: f32,
    height: f32,
}

impl Camera {
    /// A camera at `position` looking at `target`; `fov_y` is the vertical field of view in
    /// degrees; `width`, `height` the full film size in pixels.
    pub fn new(
        position: Vec3,
        target: Vec3,
        up: Vec3,
        fov_y: f32,
        width: u32,
        height: u32,
    ) -> Result<Self, String> {
        if !(fov_y > 0.0 && fov_y < 180.0) {
            return Err(format!(
                "camera `fov` must be in (0, 180) degrees, found {fov_y}"
            ));
        }
        let max = crate::limits::MAX_COORDINATE;
        for (name, v) in [("position", position), ("target", target), ("up", up)] {
            if !v.is_finite() {
                return Err(format!(
                    "camera `{name}` must be finite, found {}",
                    crate::limits::fmt_f32s(&v.to_array())
                ));
            }
            if v.abs().max_element() > max {
                return Err(format!(
                    "camera `{name}` {} is beyond the supported coordinates, ±{}",
                    crate::limits::fmt_f32s(&v.to_array()),
                    crate::limits::fmt_f32(max)
                ));
            }
        }
        // Scaled before normalising: a camera 1e-25 from its target still has a direction.
        let forward = crate::geometry::unit_normal(target - position);
        if forward == Vec3::ZERO {
            return Err("camera `position` and `target` must differ".into());
        }
        let right = forward.cross(up).normalize_or_zero();
        if right == Vec3::ZERO {
            return Err("camera `up` must not be parallel to the viewing direction".into());
        }
        Ok(Camera {
            position,
            forward,
            right,
            up: right.cross(forward),
            tan_half_fov: (fov_y.to_radians() * 0.5).tan(),
            width: width as f32,
            height: height as f32,
        })
    }

    /// The primary ray through film position `film` (pixels; x right, y down).
    pub fn generate_ray(&self, film: Vec2) -> Ray {
        self.ray_along(self.directions(film.x, film.y).lane(0))
    }

    /// The primary rays through film positions `film[i]`, four at a time: each the ray
    /// [`generate_ray`](Self::generate_ray) gives, bit for bit.
    #[inline]
    pub fn generate_rays(&self, film: [Vec2; 4]) -> [Ray; 4] {
        let directions = self.directions(
            Vec4::from_array(film.map(|f| f.x)),
            Vec4::from_array(film.map(|f| f.y)),
        );
        std::array::from_fn(|i| self.ray_along(directions.lane(i)))
    }

    /// The unit directions through film positions (`x`, `y`), one formula for one lane or four.
    #[inline(always)]
    fn directions<L: Lanes>(&self, x: L, y: L) -> V3<L> {
        let aspect = self.width / self.height;
        let (two, one) = (L::splat(2.0), L::splat(1.0));
        let tan_half_fov = L::splat(self.tan_half_fov);
        let x = (two * x / L::splat(self.width) - one) * tan_half_fov * L::splat(aspect);
        let y = (one - two * y / L::splat(self.height)) * tan_half_fov;
        (V3::splat(self.forward) + V3::splat(self.right) * x + V3::splat(self.up) * y).normalize()
    }

    fn ray_along(&self, direction: Vec3) -> Ray {
        Ray {
            origin: self.position,
            direction,
            t_max: f32::INFINITY,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_target_and_right_is_right() {
        let c = Camera::new(Vec3::ZERO, Vec3::Z, Vec3::Y, 90.0, 200, 100).unwrap();
        let centre = c.generate_ray(Vec2::new(100.0, 50.0));
        assert!(centre.direction.abs_diff_eq(Vec3::Z, 1e-6));
        // Looking down +z with +y up, screen right is -x (right-handed).
        let right_edge = c.generate_ray(Vec2::new(200.0, 50.0)).direction;
        assert!(right_edge.x < 0.0);
        // Vertical fov 90: the top edge ray is 45 degrees up.
        let top = c.generate_ray(Vec2::new(100.0, 0.0)).direction;
        assert!((top.y - top.z).abs() < 1e-6 && top.y > 0.0);
    }

    /// Four rays at once are the rays one at a time, bit for bit, and those are glam's `Vec3`
    /// formula (what the camera computed before it had a lane form).
    #[test]
    fn rays_by_fours_are_the_rays_one_by_one() {
        let c = Camera::new(
            Vec3::new(0.3, 2.0, 15.0),
            Vec3::new(0.0, -1.5, 2.5),
            Vec3::Y,
            28.0,
            320,
            240,
        )
        .unwrap();
        let mut sampler = crate::sampler::Sampler::new(5, 0, 0);
        for _ in 0..2000 {
            let film: [Vec2; 4] =
                std::array::from_fn(|_| sampler.next_2d() * Vec2::new(330.0, 250.0) - 5.0);
            let rays = c.generate_rays(film);
            for (f, ray) in film.into_iter().zip(rays) {
                let one = c.generate_ray(f);
                let aspect = c.width / c.height;
                let x = (2.0 * f.x / c.width - 1.0) * c.tan_half_fov * aspect;
                let y = (1.0 - 2.0 * f.y / c.height) * c.tan_half_fov;
                let glam = (c.forward + x * c.right + y * c.up).normalize();
                for axis in 0..3 {
                    assert_eq!(ray.direction[axis].to_bits(), one.direction[axis].to_bits());
                    assert_eq!(one.direction[axis].to_bits(), glam[axis].to_bits(), "{f}");
                }
                assert_eq!((ray.origin, ray.t_max), (c.position, f32::INFINITY));
            }
        }
    }

    #[test]
    fn invalid_cameras_are_refused() {
        assert!(Camera::new(Vec3::ZERO, Vec3::ZERO, Vec3::Y, 40.0, 1, 1).is_err());
        assert!(Camera::new(Vec3::ZERO, Vec3::Y, Vec3::Y, 40.0, 1, 1).is_err());
        assert!(Camera::new(Vec3::ZERO, Vec3::Z, Vec3::Y, 180.0, 1, 1).is_err());
        let e = Camera::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::Z, Vec3::Y, 40.0, 1, 1);
        assert!(e.unwrap_err().contains("camera `position` must be finite"));
        let e = Camera::new(Vec3::ZERO, Vec3::splat(1e13), Vec3::Y, 40.0, 1, 1);
        assert!(e.unwrap_err().contains("camera `target`"));
    }
}
