//! The watertight ray–triangle test (Woop, Benthin and Wald 2013, as pbrt-v4 §6.5.3 writes
//! it), for one ray; [`super::packet`] has it in lanes for the rays of a packet.

use super::ray::Ray;
use crate::math::gamma;
use glam::{Vec3, Vec3A, Vec4};

/// Per-ray constants of the watertight triangle test (Woop, Benthin, Wald 2013).
#[derive(Clone, Copy)]
pub(super) struct RayShear {
    /// The axis along which the direction is largest; the other two follow it cyclically.
    pub(super) kz: usize,
    pub(super) sx: f32,
    pub(super) sy: f32,
    pub(super) sz: f32,
}

impl RayShear {
    /// The three quotients in one 4-lane division (each lane rounds as a scalar division does),
    /// and the permutation by constants rather than run-time indices: a ray's set-up was 31
    /// instructions with three divisions, for every shadow and BSDF ray.
    #[inline]
    pub(super) fn new(d: Vec3) -> Self {
        let a = d.abs();
        // (kz, d[kx], d[ky], d[kz]) with kx = kz + 1 and ky = kz + 2, cyclically.
        let (kz, x, y, z) = if a.x > a.y && a.x > a.z {
            (0, d.y, d.z, d.x)
        } else if a.y > a.z {
            (1, d.z, d.x, d.y)
        } else {
            (2, d.x, d.y, d.z)
        };
        let [sx, sy, sz, _] = (Vec4::new(-x, -y, 1.0, 1.0) / Vec4::splat(z)).to_array();
        RayShear { kz, sx, sy, sz }
    }
}

/// pbrt-v4's watertight ray–triangle test: (t, b0, b1, b2), or None.
#[inline]
pub(super) fn intersect_triangle(
    ray: &Ray,
    shear: &RayShear,
    t_max: f32,
    p: &[Vec3; 3],
) -> Option<(f32, [f32; 3])> {
    // The axis permutation is fixed per ray: one well-predicted branch here lets each copy index
    // vertices with constants instead of run-time indices (the profile's hottest lines).
    match shear.kz {
        0 => intersect_triangle_permuted::<1, 2, 0>(ray, shear, t_max, p),
        1 => intersect_triangle_permuted::<2, 0, 1>(ray, shear, t_max, p),
        _ => intersect_triangle_permuted::<0, 1, 2>(ray, shear, t_max, p),
    }
}

/// Whether some of the edge functions are negative and some positive (the ray passes outside
/// the triangle), zeros counting as neither. The signs are compared in lanes and tested with
/// one branch: on a mesh of many small triangles the answer is hard to predict, and a branch
/// per comparison mispredicted more often (without them, with the range test below, the dragon
/// rendered × 1.051 [1.046, 1.057] faster).
#[inline(always)]
fn signs_differ(e0: f32, e1: f32, e2: f32) -> bool {
    let e = Vec3A::new(e0, e1, e2);
    e.cmplt(Vec3A::ZERO).any() & e.cmpgt(Vec3A::ZERO).any()
}

/// Whether t = `t_scaled` / `det` lies in (0, `t_max`], without dividing: `t_scaled` and `det`
/// are made positive by `det`'s sign (exactly) and compared with one branch, as the facing of
/// a mesh's triangles, hence `det`'s sign, is hard to predict. `det` is finite and not zero.
#[inline(always)]
fn scaled_t_in_range(t_scaled: f32, det: f32, t_max: f32) -> bool {
    const SIGN_BIT: u32 = 1 << 31;
    let toward = f32::from_bits(t_scaled.to_bits() ^ (det.to_bits() & SIGN_BIT));
    !((toward <= 0.0) | (toward > t_max * det.abs()))
}

/// [`intersect_triangle`] for the permutation (KX, KY, KZ) of [`RayShear`].
#[inline(always)]
fn intersect_triangle_permuted<const KX: usize, const KY: usize, const KZ: usize>(
    ray: &Ray,
    shear: &RayShear,
    t_max: f32,
    p: &[Vec3; 3],
) -> Option<(f32, [f32; 3])> {
    let RayShear { sx, sy, sz, .. } = *shear;
    let permute = |v: Vec3| {
        let a = v.to_array();
        Vec3::new(a[KX], a[KY], a[KZ])
    };
    let mut p0 = permute(p[0] - ray.origin);
    let mut p1 = permute(p[1] - ray.origin);
    let mut p2 = permute(p[2] - ray.origin);
    p0.x += sx * p0.z;
    p0.y += sy * p0.z;
    p1.x += sx * p1.z;
    p1.y += sy * p1.z;
    p2.x += sx * p2.z;
    p2.y += sy * p2.z;
    let mut e0 = p1.x * p2.y - p1.y * p2.x;
    let mut e1 = p2.x * p0.y - p2.y * p0.x;
    let mut e2 = p0.x * p1.y - p0.y * p1.x;
    if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
        // Exactly on an edge in f32: decide in f64 so neighbours agree.
        e0 = (p1.x as f64 * p2.y as f64 - p1.y as f64 * p2.x as f64) as f32;
        e1 = (p2.x as f64 * p0.y as f64 - p2.y as f64 * p0.x as f64) as f32;
        e2 = (p0.x as f64 * p1.y as f64 - p0.y as f64 * p1.x as f64) as f32;
    }
    if signs_differ(e0, e1, e2) {
        return None;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    p0.z *= sz;
    p1.z *= sz;
    p2.z *= sz;
    let t_scaled = e0 * p0.z + e1 * p1.z + e2 * p2.z;
    if !scaled_t_in_range(t_scaled, det, t_max) {
        return None;
    }
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    // Reject t that is not provably positive given the rounding error (pbrt-v4 §6.8.4).
    let max_zt = p0.z.abs().max(p1.z.abs()).max(p2.z.abs());
    let delta_z = gamma(3) * max_zt;
    let max_xt = p0.x.abs().max(p1.x.abs()).max(p2.x.abs());
    let max_yt = p0.y.abs().max(p1.y.abs()).max(p2.y.abs());
    let delta_x = gamma(5) * (max_xt + max_zt);
    let delta_y = gamma(5) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = e0.abs().max(e1.abs()).max(e2.abs());
    let delta_t =
        3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
    if t <= delta_t {
        return None;
    }
    Some((t, [e0 * inv_det, e1 * inv_det, e2 * inv_det]))
}

/// Whether `ray` meets the triangle `p` (within `ray.t_max`), decided by the same watertight test
/// and the same rounding as [`Geometry::intersect`]: emitters that draw points on triangles use
/// it to return only directions whose rays reach the triangle.
///
/// [`Geometry::intersect`]: super::Geometry::intersect
pub fn ray_meets_triangle(ray: &Ray, p: &[Vec3; 3]) -> bool {
    intersect_triangle(ray, &RayShear::new(ray.direction), ray.t_max, p).is_some()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The triangle test's sign and range tests, written for one branch each, answer as
    /// their forms with a branch per comparison, on random values and on zeros of both signs,
    /// infinities, NaN and the range's ends (t = t_max exactly, t = 0).
    #[test]
    fn the_triangle_tests_answer_as_their_branching_forms() {
        let specials = [
            0.0f32,
            -0.0,
            1.0,
            -1.0,
            2.5,
            -2.5,
            1e-30,
            -1e-30,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            3.0,
            -3.0,
        ];
        let mut sampler = crate::sampler::Sampler::new(5, 0, 0);
        let mut values: Vec<f32> = specials.to_vec();
        values.extend((0..24).map(|_| (sampler.next_1d() - 0.5) * 8.0));
        let mut in_range = [0usize; 2];
        for &a in &values {
            for &b in &values {
                for &c in &values {
                    let branching =
                        (a < 0.0 || b < 0.0 || c < 0.0) && (a > 0.0 || b > 0.0 || c > 0.0);
                    assert_eq!(signs_differ(a, b, c), branching, "signs of {a}, {b}, {c}");
                    // (t_scaled, det, t_max) = (a, b, |c|), det finite and not zero.
                    let (t_scaled, det, t_max) = (a, b, c.abs());
                    if det == 0.0 || !det.is_finite() {
                        continue;
                    }
                    let outside = (det < 0.0 && (t_scaled >= 0.0 || t_scaled < t_max * det))
                        || (det > 0.0 && (t_scaled <= 0.0 || t_scaled > t_max * det));
                    let inside = scaled_t_in_range(t_scaled, det, t_max);
                    assert_eq!(
                        inside, !outside,
                        "t_scaled {t_scaled}, det {det}, t_max {t_max}"
                    );
                    in_range[usize::from(inside)] += 1;
                }
            }
        }
        // Both answers occur often, for both signs of det (t = t_max exactly among them).
        assert!(scaled_t_in_range(-3.0, -1.0, 3.0) && !scaled_t_in_range(-3.0, -1.0, 2.5));
        assert!(in_range.iter().all(|&n| n > 1000), "{in_range:?}");
    }
}
