//! Warps from the unit square to directions and points, each with its density.

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_4, PI};

/// Concentric map of the unit square to the unit disk (Shirley–Chiu), area-preserving up to π.
pub fn square_to_disk_concentric(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, FRAC_PI_4 * (o.y / o.x))
    } else {
        (o.y, PI * 0.5 - FRAC_PI_4 * (o.x / o.y))
    };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// Cosine-weighted hemisphere around +z; density cos θ / π.
pub fn square_to_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = square_to_disk_concentric(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Density of [`square_to_cosine_hemisphere`] in solid angle.
#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    if cos_theta > 0.0 {
        cos_theta * FRAC_1_PI
    } else {
        0.0
    }
}

/// Uniform barycentric coordinates (b0, b1) on a triangle; b2 = 1 − b0 − b1. Density 1/area.
pub fn square_to_triangle_barycentrics(u: Vec2) -> (f32, f32) {
    // Heitz 2019, "A Low-Distortion Map Between Triangle and Square".
    let (b0, b1) = if u.y > u.x {
        let b0 = u.x / 2.0;
        (b0, u.y - b0)
    } else {
        let b1 = u.y / 2.0;
        (u.x - b1, b1)
    };
    (b0, b1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn cosine_hemisphere_stays_in_domain(x in 0.0f32..1.0, y in 0.0f32..1.0) {
            let w = square_to_cosine_hemisphere(Vec2::new(x, y));
            prop_assert!((w.length() - 1.0).abs() < 1e-4);
            prop_assert!(w.z >= 0.0);
        }

        #[test]
        fn triangle_barycentrics_stay_in_triangle(x in 0.0f32..1.0, y in 0.0f32..1.0) {
            let (b0, b1) = square_to_triangle_barycentrics(Vec2::new(x, y));
            prop_assert!(b0 >= 0.0 && b1 >= 0.0 && b0 + b1 <= 1.0 + 1e-6);
        }
    }
}
