//! A primitive against the rays of a packet: the watertight triangle test in SIMD lanes
//! ([`triangle_hits`]), and each ray's own test ([`Alone`]) where the lanes do not pay.

use super::bvh::PACKET_SIZE;
use super::primitive::Primitive;
use super::ray::Ray;
use super::triangle::RayShear;
use crate::math::gamma;
use glam::{Vec3, Vec4};

/// One primitive's scalar test for the rays of a packet (a function, not a closure, so that it is
/// inlined where it is called from several places).
#[derive(Clone, Copy)]
pub(super) struct Alone<'a> {
    pub(super) primitive: &'a Primitive,
    pub(super) rays: &'a [Ray],
    pub(super) shears: &'a [RayShear; PACKET_SIZE],
}

impl Alone<'_> {
    /// [`Primitive::hit`] for ray `r`.
    #[inline(always)]
    pub(super) fn hit(&self, r: usize, t_max: f32) -> Option<(f32, [f32; 3])> {
        self.primitive.hit(&self.rays[r], &self.shears[r], t_max)
    }
}

/// The shears of a packet's rays ([`RayShear`]) in lanes, when they share the axis of their
/// largest direction component (a camera pixel's rays nearly always do).
pub(super) struct PacketShear {
    kz: usize,
    sx: [f32; PACKET_SIZE],
    sy: [f32; PACKET_SIZE],
    sz: [f32; PACKET_SIZE],
}

impl PacketShear {
    /// `None` if the rays' permutations differ. (Marked inline: in another file than its caller
    /// it was left out of line, 5 more instructions a packet.)
    #[inline]
    pub(super) fn new(shears: &[RayShear; PACKET_SIZE]) -> Option<Self> {
        let kz = shears[0].kz;
        shears.iter().all(|s| s.kz == kz).then(|| PacketShear {
            kz,
            sx: std::array::from_fn(|r| shears[r].sx),
            sy: std::array::from_fn(|r| shears[r].sy),
            sz: std::array::from_fn(|r| shears[r].sz),
        })
    }
}

/// [`intersect_triangle`] for the rays of a packet set in `rays` (which share `origin` and the
/// permutation of `shear`), four rays at a time, each lane computing what the scalar test
/// computes for its ray, operation for operation: a ray that hits the triangle before its
/// `t_max[r]` has `t_max[r]` lowered to the distance and `barycentrics[r]` set, and its bit set in
/// the result. A ray with an edge function exactly zero (which the scalar test decides again in
/// f64), or alone in its group of four, is given the scalar test (`alone`).
///
/// [`intersect_triangle`]: super::triangle::intersect_triangle
#[inline(always)]
pub(super) fn triangle_hits(
    p: &[Vec3; 3],
    origin: Vec3,
    shear: &PacketShear,
    rays: u32,
    t_max: &mut [f32; PACKET_SIZE],
    barycentrics: &mut [[f32; 3]; PACKET_SIZE],
    alone: Alone,
) -> u32 {
    // The lanes follow `intersect_triangle_permuted` line by line. Its permutation is picked
    // here at run time: once per triangle, not per ray.
    let [kx, ky, kz] = match shear.kz {
        0 => [1, 2, 0],
        1 => [2, 0, 1],
        _ => [0, 1, 2],
    };
    let permute = |v: Vec3| Vec3::new(v[kx], v[ky], v[kz]);
    // The same for every ray: they share the origin.
    let [q0, q1, q2] = p.map(|v| permute(v - origin));
    let splat = Vec4::splat;
    // f32::max in lanes: SSE's max gives its second operand when either is NaN, f32::max the
    // operand that is not NaN.
    let max = |a: Vec4, b: Vec4| Vec4::select(b.is_nan_mask(), a, a.max(b));
    let mut hits = 0u32;
    for group in 0..PACKET_SIZE / 4 {
        let lanes = (rays >> (4 * group)) & 0xf;
        let at = 4 * group;
        if lanes.count_ones() < 2 {
            // One ray (or none): the scalar test costs less than the lanes.
            if lanes != 0 {
                let r = at + lanes.trailing_zeros() as usize;
                if let Some((t, b)) = alone.hit(r, t_max[r]) {
                    (t_max[r], barycentrics[r]) = (t, b);
                    hits |= 1 << r;
                }
            }
            continue;
        }
        let sx = Vec4::from_slice(&shear.sx[at..]);
        let sy = Vec4::from_slice(&shear.sy[at..]);
        let sz = Vec4::from_slice(&shear.sz[at..]);
        let ray_t_max = Vec4::from_slice(&t_max[at..]);
        let (p0x, p0y) = (
            splat(q0.x) + sx * splat(q0.z),
            splat(q0.y) + sy * splat(q0.z),
        );
        let (p1x, p1y) = (
            splat(q1.x) + sx * splat(q1.z),
            splat(q1.y) + sy * splat(q1.z),
        );
        let (p2x, p2y) = (
            splat(q2.x) + sx * splat(q2.z),
            splat(q2.y) + sy * splat(q2.z),
        );
        let e0 = p1x * p2y - p1y * p2x;
        let e1 = p2x * p0y - p2y * p0x;
        let e2 = p0x * p1y - p0y * p1x;
        let zero = Vec4::ZERO;
        let exact_zero = e0.cmpeq(zero) | e1.cmpeq(zero) | e2.cmpeq(zero);
        let outside = (e0.cmplt(zero) | e1.cmplt(zero) | e2.cmplt(zero))
            & (e0.cmpgt(zero) | e1.cmpgt(zero) | e2.cmpgt(zero));
        let det = e0 + e1 + e2;
        let no_det = det.cmpeq(zero) | !det.is_finite_mask();
        let (p0z, p1z, p2z) = (splat(q0.z) * sz, splat(q1.z) * sz, splat(q2.z) * sz);
        let t_scaled = e0 * p0z + e1 * p1z + e2 * p2z;
        let bound = ray_t_max * det;
        let behind = (det.cmplt(zero) & (t_scaled.cmpge(zero) | t_scaled.cmplt(bound)))
            | (det.cmpgt(zero) & (t_scaled.cmple(zero) | t_scaled.cmpgt(bound)));
        let inv_det = Vec4::ONE / det;
        let t = t_scaled * inv_det;
        let max_zt = max(max(p0z.abs(), p1z.abs()), p2z.abs());
        let delta_z = splat(gamma(3)) * max_zt;
        let max_xt = max(max(p0x.abs(), p1x.abs()), p2x.abs());
        let max_yt = max(max(p0y.abs(), p1y.abs()), p2y.abs());
        let delta_x = splat(gamma(5)) * (max_xt + max_zt);
        let delta_y = splat(gamma(5)) * (max_yt + max_zt);
        let delta_e =
            splat(2.0) * (splat(gamma(2)) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = max(max(e0.abs(), e1.abs()), e2.abs());
        let delta_t = splat(3.0)
            * (splat(gamma(3)) * max_e * max_zt + delta_e * max_zt + delta_z * max_e)
            * inv_det.abs();
        // As `Primitive::hit` then asks: t < t_max.
        let hit = !(outside | no_det | behind | t.cmple(delta_t)) & t.cmplt(ray_t_max);
        let scalar = lanes & exact_zero.bitmask();
        let hit = lanes & !scalar & hit.bitmask();
        let (t, b) = (
            t.to_array(),
            [e0 * inv_det, e1 * inv_det, e2 * inv_det].map(|e| e.to_array()),
        );
        for lane in 0..4 {
            let r = at + lane;
            if hit >> lane & 1 != 0 {
                t_max[r] = t[lane];
                barycentrics[r] = [b[0][lane], b[1][lane], b[2][lane]];
                hits |= 1 << r;
            } else if scalar >> lane & 1 != 0
                && let Some((t, b)) = alone.hit(r, t_max[r])
            {
                (t_max[r], barycentrics[r]) = (t, b);
                hits |= 1 << r;
            }
        }
    }
    hits
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle::intersect_triangle;

    /// [`triangle_hits`] gives each ray of a packet what [`intersect_triangle`] gives it alone,
    /// bit for bit (hit or not, distance, barycentrics): rays from one origin in a narrow or a
    /// wide cone, toward random, degenerate, tiny and huge triangles and toward a triangle's
    /// edges and vertices (where an edge function may be exactly zero), with random bounds.
    #[test]
    fn triangles_in_lanes_hit_as_alone() {
        let mut sampler = crate::sampler::Sampler::new(29, 0, 0);
        let (mut lanes_hits, mut scalar_hits) = (0, 0);
        for round in 0..4000 {
            let mut point = |scale: f32| {
                let (a, b) = (sampler.next_2d(), sampler.next_2d());
                Vec3::new(a.x - 0.5, a.y - 0.5, b.x - 0.5) * scale
            };
            let scale = [1e-3, 1.0, 1e4][round % 3];
            let origin = point(10.0 * scale);
            let (a, b, c) = (point(scale), point(scale), point(scale));
            let p = match round % 5 {
                0 => [a, a, b],
                1 => [a, b, a + 2.0 * (b - a)],
                _ => [a, b, c],
            };
            let spread = [1e-3, 0.1, 1.0][round % 4 % 3];
            let target = (p[0] + p[1] + p[2]) / 3.0;
            let aims: Vec<Vec3> = (0..PACKET_SIZE)
                .map(|r| match r % 4 {
                    // A vertex, an edge's midpoint: edge functions may round to zero there.
                    0 => p[r % 3],
                    1 => 0.5 * (p[r % 3] + p[(r + 1) % 3]),
                    _ => target + point(spread * scale),
                })
                .collect();
            let rays: Vec<Ray> = aims
                .iter()
                .map(|&aim| Ray {
                    origin,
                    direction: aim - origin,
                    t_max: [f32::INFINITY, 1.0, 0.99, 2.0][round % 4],
                })
                .collect();
            let shears: [RayShear; PACKET_SIZE] =
                std::array::from_fn(|r| RayShear::new(rays[r].direction));
            let Some(shear) = PacketShear::new(&shears) else {
                continue;
            };
            let mut t_max: [f32; PACKET_SIZE] = std::array::from_fn(|r| rays[r].t_max);
            let mut barycentrics = [[0.0; 3]; PACKET_SIZE];
            let rays_in = (sampler.next_1d() * 65536.0) as u32 | 0x0f0f;
            let primitive = Primitive::Triangle {
                p,
                shape: 0,
                index: 0,
            };
            let alone = Alone {
                primitive: &primitive,
                rays: &rays,
                shears: &shears,
            };
            let hits = triangle_hits(
                &p,
                origin,
                &shear,
                rays_in,
                &mut t_max,
                &mut barycentrics,
                alone,
            );
            for r in 0..PACKET_SIZE {
                let expected = (rays_in >> r & 1 != 0)
                    .then(|| intersect_triangle(&rays[r], &shears[r], rays[r].t_max, &p))
                    .flatten()
                    .filter(|&(t, _)| t < rays[r].t_max);
                let got = (hits >> r & 1 != 0).then_some((t_max[r], barycentrics[r]));
                let bits =
                    |h: Option<(f32, [f32; 3])>| h.map(|(t, b)| (t.to_bits(), b.map(f32::to_bits)));
                assert_eq!(
                    bits(got),
                    bits(expected),
                    "round {round}, ray {r}: {:?}",
                    rays[r]
                );
                if expected.is_none() {
                    assert_eq!(t_max[r].to_bits(), rays[r].t_max.to_bits());
                }
                lanes_hits += usize::from(got.is_some() && r % 4 > 1);
                scalar_hits += usize::from(got.is_some() && r % 4 < 2);
            }
        }
        assert!(
            lanes_hits > 5000 && scalar_hits > 1000,
            "{lanes_hits} hits in the cone, {scalar_hits} at vertices and edges"
        );
    }
}
