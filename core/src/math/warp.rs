//! Warps from the unit square to directions and points, each with its density.

use crate::math::lanes::{Lanes, V3};
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_4, PI};

/// Concentric map of the unit square to the unit disk (Shirley–Chiu), area-preserving up to π.
pub fn square_to_disk_concentric(u: Vec2) -> Vec2 {
    let (x, y) = square_to_disk_concentric_lanes(u.x, u.y);
    Vec2::new(x, y)
}

/// [`square_to_disk_concentric`] in each lane of (`u0`, `u1`).
#[inline(always)]
pub fn square_to_disk_concentric_lanes<L: Lanes>(u0: L, u1: L) -> (L, L) {
    let (one, zero) = (L::splat(1.0), L::splat(0.0));
    let (ox, oy) = (L::splat(2.0) * u0 - one, L::splat(2.0) * u1 - one);
    let x_larger = ox.abs().gt(oy.abs());
    let r = L::select(x_larger, ox, oy);
    let theta = L::select(
        x_larger,
        L::splat(FRAC_PI_4) * (oy / ox),
        L::splat(PI * 0.5) - L::splat(FRAC_PI_4) * (ox / oy),
    );
    let (sin, cos) = theta.sin_cos();
    let centre = ox.eq(zero) & oy.eq(zero);
    (
        L::select(centre, zero, r * cos),
        L::select(centre, zero, r * sin),
    )
}

/// Cosine-weighted hemisphere around +z; density cos θ / π.
pub fn square_to_cosine_hemisphere(u: Vec2) -> Vec3 {
    square_to_cosine_hemisphere_lanes::<f32>(u.x, u.y).lane(0)
}

/// [`square_to_cosine_hemisphere`] in each lane of (`u0`, `u1`).
#[inline(always)]
pub fn square_to_cosine_hemisphere_lanes<L: Lanes>(u0: L, u1: L) -> V3<L> {
    let (x, y) = square_to_disk_concentric_lanes(u0, u1);
    let z = (L::splat(1.0) - (x * x + y * y)).max(L::splat(0.0)).sqrt();
    V3::new(x, y, z)
}

/// Density of [`square_to_cosine_hemisphere`] in solid angle.
#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cosine_hemisphere_pdf_lanes(cos_theta)
}

/// [`cosine_hemisphere_pdf`] in each lane.
#[inline(always)]
pub fn cosine_hemisphere_pdf_lanes<L: Lanes>(cos_theta: L) -> L {
    let zero = L::splat(0.0);
    L::select(cos_theta.gt(zero), cos_theta * L::splat(FRAC_1_PI), zero)
}

/// Uniform barycentric coordinates (b0, b1) on a triangle; b2 = 1 − b0 − b1. Density 1/area.
pub fn square_to_triangle_barycentrics(u: Vec2) -> (f32, f32) {
    square_to_triangle_barycentrics_lanes(u.x, u.y)
}

/// [`square_to_triangle_barycentrics`] in each lane of (`u0`, `u1`).
#[inline(always)]
pub fn square_to_triangle_barycentrics_lanes<L: Lanes>(u0: L, u1: L) -> (L, L) {
    // Heitz 2019, "A Low-Distortion Map Between Triangle and Square".
    let two = L::splat(2.0);
    let upper = u1.gt(u0);
    let (b0_upper, b1_lower) = (u0 / two, u1 / two);
    (
        L::select(upper, b0_upper, u0 - b1_lower),
        L::select(upper, u1 - b0_upper, b1_lower),
    )
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
