//! The perspective pinhole camera.

use crate::accel::Ray;
use glam::{Vec2, Vec3};

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
        let forward = crate::scene::shapes::unit_normal(target - position);
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
        let aspect = self.width / self.height;
        let x = (2.0 * film.x / self.width - 1.0) * self.tan_half_fov * aspect;
        let y = (1.0 - 2.0 * film.y / self.height) * self.tan_half_fov;
        let direction = (self.forward + x * self.right + y * self.up).normalize();
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
