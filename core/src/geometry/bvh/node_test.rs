//! The node test: which of a node's eight children a ray (or a packet of rays) enters, as a
//! bit mask, and the distances at which it enters them. Each of the three node tests (a ray's,
//! a packet's, and which rays of a packet enter one child) is written once over [`Lanes`], a
//! child (or a ray) per lane, and compiled twice: eight lanes wide in AVX registers
//! ([`node_test_avx2`] and its packet twins) for the kernels that x86-64 processors with AVX2
//! run, chosen at run time (the binary still runs on any x86-64), and four wide (glam's `Vec4`:
//! SSE2 on x86-64, NEON on aarch64) for every other processor. Every lane computes the same
//! IEEE operations in the same order (no fused multiply-add: Rust never contracts), so results
//! do not depend on the CPU (tests compare the widths bit for bit, one lane at a time too). The
//! intrinsics are in `math/lanes.rs`.
//!
//! The node test is conservative under rounding (Ize, "Robust BVH ray traversal", JCGT 2013;
//! pbrt-v4 §6.8.2): the far distance is enlarged by 2γ₃, the bound of the error of
//! `(plane − origin) · (1 / direction)`. A ray aimed exactly at the edge of a flat box (an
//! axis-aligned square light) therefore enters it, where a rounded slab test can miss it.
//!
//! Why one file of 600 lines: the rays' and packets' set-up and the node tests that read it,
//! with their tests (over 250 lines), which check them together.

use super::{PACKET_SIZE, WideNode};
use crate::math::gamma;
#[cfg(target_arch = "x86_64")]
use crate::math::lanes::{LaneKernel, run_avx2};
use crate::math::lanes::{Lanes, Mask};
use glam::Vec4;

/// Per-ray constants of the node test: the origin, the reciprocal direction (with ±f32::MAX
/// for a zero component, so that no lane computes 0 · ∞), and which bound is near per axis.
#[derive(Clone, Copy, Debug)]
pub struct RayBoxTest {
    origin: [f32; 3],
    inv_direction: [f32; 3],
    /// Index into [`WideNode::bounds`] of each axis's near plane (min for a positive direction).
    near: [usize; 3],
}

impl RayBoxTest {
    /// The reciprocals in one 4-lane division, each lane rounding as a scalar division does.
    #[inline]
    pub fn new(origin: glam::Vec3, direction: glam::Vec3) -> Self {
        let inv = glam::Vec4::ONE / direction.extend(1.0);
        let inv = glam::Vec4::select(
            inv.is_finite_mask(),
            inv,
            glam::Vec4::splat(f32::MAX).copysign(inv),
        );
        let inv_direction = [inv.x, inv.y, inv.z];
        let near = [0, 1, 2].map(|axis| 2 * axis + (inv_direction[axis] < 0.0) as usize);
        RayBoxTest {
            origin: origin.to_array(),
            inv_direction,
            near,
        }
    }

    /// Whether the two rays can share a packet: the same origin, bit for bit, and the same
    /// near planes. The differences are OR-ed together in registers: compared as arrays, the
    /// fields of a ray just made were stored and read back wider than they were written, a
    /// read the store buffer cannot forward (a third of a packet's set-up time).
    #[inline(always)]
    fn shares_packet_with(&self, other: &RayBoxTest) -> bool {
        let near = (0..3).fold(0, |d, axis| d | (self.near[axis] ^ other.near[axis]));
        let origin = (0..3).fold(0, |d, axis| {
            d | (self.origin[axis].to_bits() ^ other.origin[axis].to_bits())
        });
        near == 0 && origin == 0
    }
}

/// Up to [`PACKET_SIZE`] rays that share an origin and the signs of their directions (a
/// pinhole camera's rays through one pixel), tested against a node's children together: per
/// axis, the interval of their reciprocal directions (Boulos et al., "Packet-based Whitted and
/// distribution ray tracing", 2007). A child passes if one of the rays might enter it: each
/// slab distance is the smaller (near plane) or the larger (far plane) of the distances
/// computed with the interval's two ends, and since `(plane − origin) · inv` is monotone in
/// `inv` and rounding is monotone, that bounds the same rounded distance computed with any
/// ray's own reciprocal, as [`node_test`] computes it. So the packet enters every child any of
/// its rays would enter alone. The rays' own reciprocals, lane by lane, then decide which rays
/// enter a leaf ([`rays_entering`]).
#[derive(Clone, Copy, Debug)]
pub struct PacketBoxTest {
    origin: [f32; 3],
    /// Per axis, the smallest and the largest reciprocal direction of the rays.
    inv_low: [f32; 3],
    inv_high: [f32; 3],
    /// Per axis, each ray's reciprocal direction (lanes past the rays repeat the last one).
    inv: [[f32; PACKET_SIZE]; 3],
    /// As [`RayBoxTest::near`], the same for every ray of the packet.
    near: [usize; 3],
    pub(super) rays: usize,
}

impl PacketBoxTest {
    /// The packet of `rays`; `None` if there are none or more than [`PACKET_SIZE`], or if they
    /// do not all share their origin and the sign of each direction component (trace those
    /// one by one). For the tests: the queries build their packets in place
    /// ([`set`](Self::set)).
    #[cfg(test)]
    pub fn new(rays: &[RayBoxTest]) -> Option<Self> {
        let mut packet = Self::EMPTY;
        packet.set(rays.len(), |r| rays[r]).then_some(packet)
    }

    /// No rays yet: a place for [`set`](Self::set) to build a packet in.
    pub const EMPTY: PacketBoxTest = PacketBoxTest {
        origin: [0.0; 3],
        inv_low: [0.0; 3],
        inv_high: [0.0; 3],
        inv: [[0.0; PACKET_SIZE]; 3],
        near: [0; 3],
        rays: 0,
    };

    /// Makes `self` the packet of the `count` rays `ray_of(0)`, …, `ray_of(count − 1)` (as
    /// `new` describes it), and returns whether they make one (if not, `self` is left in no
    /// particular state). Built in place, each ray made where it is read: a packet returned in
    /// an `Option`, or made from an array of rays, was copied whole, through `memcpy`.
    #[inline(always)]
    pub fn set(&mut self, count: usize, ray_of: impl Fn(usize) -> RayBoxTest) -> bool {
        if count == 0 || count > PACKET_SIZE {
            return false;
        }
        let first = ray_of(0);
        (self.origin, self.near, self.rays) = (first.origin, first.near, count);
        for r in 0..count {
            let ray = if r == 0 { first } else { ray_of(r) };
            if !ray.shares_packet_with(&first) {
                return false;
            }
            for (row, v) in self.inv.iter_mut().zip(ray.inv_direction) {
                row[r] = v;
            }
        }
        for (axis, row) in self.inv.iter_mut().enumerate() {
            // Lanes past the rays repeat the last one.
            let last = row[count - 1];
            row[count..].fill(last);
            // Each row's extremes as trees of comparisons, not as a scan from the first ray,
            // whose comparisons each waited on the one before. A reciprocal here is never NaN
            // (RayBoxTest::new), so the extremes are the scan's, but for the sign of a zero
            // bound where the rays' directions are infinite in both signs (which the slab test,
            // comparing products with it, does not see).
            self.inv_low[axis] = extreme(*row, |candidate, kept| candidate < kept);
            self.inv_high[axis] = extreme(*row, |candidate, kept| candidate > kept);
        }
        true
    }
}

/// 1 + 2γ₃: the far distance's enlargement that makes the slab test conservative.
pub(super) fn far_scale() -> f32 {
    1.0 + 2.0 * gamma(3)
}

/// The children of `node` that the ray enters before `t_max`, as a bit mask, and the distances
/// at which it enters them: the eight children as groups of `L::WIDTH`, a child per lane.
#[inline(always)]
pub(super) fn node_test_lanes<L: Lanes>(
    node: &WideNode,
    ray: &RayBoxTest,
    t_max: f32,
) -> (u32, [f32; 8]) {
    children_entered(
        t_max,
        #[inline(always)]
        |at, mut t_near: L, mut t_far: L| {
            for axis in 0..3 {
                let near_planes = L::load(&node.bounds[ray.near[axis]][at..]);
                let far_planes = L::load(&node.bounds[ray.near[axis] ^ 1][at..]);
                let (o, inv) = (
                    L::splat(ray.origin[axis]),
                    L::splat(ray.inv_direction[axis]),
                );
                let n = (near_planes - o) * inv;
                let f = (far_planes - o) * inv;
                // `n > t_near ? n : t_near` and `f < t_far ? f : t_far` (Lanes::max and min, one
                // maxps and one minps), not f32::max and min, which cost more around NaN.
                t_near = n.max(t_near);
                t_far = f.min(t_far);
            }
            (t_near, t_far)
        },
    )
}

/// [`node_test_lanes`] for a packet: the children one of its rays may enter before `t_max`
/// (the largest of the rays' bounds), and distances no greater than any of theirs.
#[inline(always)]
pub(super) fn packet_node_test_lanes<L: Lanes>(
    node: &WideNode,
    packet: &PacketBoxTest,
    t_max: f32,
) -> (u32, [f32; 8]) {
    children_entered(
        t_max,
        #[inline(always)]
        |at, mut t_near: L, mut t_far: L| {
            for axis in 0..3 {
                let o = L::splat(packet.origin[axis]);
                let near = L::load(&node.bounds[packet.near[axis]][at..]) - o;
                let far = L::load(&node.bounds[packet.near[axis] ^ 1][at..]) - o;
                let (low, high) = (
                    L::splat(packet.inv_low[axis]),
                    L::splat(packet.inv_high[axis]),
                );
                let n = (near * low).min(near * high);
                let f = (far * low).max(far * high);
                t_near = n.max(t_near);
                t_far = f.min(t_far);
            }
            (t_near, t_far)
        },
    )
}

/// What the node tests share: the eight children in groups of `L::WIDTH` (children `at..at +
/// L::WIDTH` a group), each group's interval [0, `t_max`] narrowed by `slabs(at, t_near,
/// t_far)` over the three axes; the children whose interval is not empty, the far end enlarged
/// by 2γ₃, as a bit mask, and their near distances. Callers mark `slabs` `#[inline(always)]`:
/// a closure left out of line is compiled without the AVX2 entry point's features, and each of
/// its lane operations becomes a call (+28 % instructions on Veach).
#[inline(always)]
fn children_entered<L: Lanes>(
    t_max: f32,
    slabs: impl Fn(usize, L, L) -> (L, L),
) -> (u32, [f32; 8]) {
    let scale = L::splat(far_scale());
    let (mut mask, mut near) = (0u32, [0.0f32; 8]);
    for group in 0..8 / L::WIDTH {
        let at = group * L::WIDTH;
        let (t_near, t_far) = slabs(at, L::splat(0.0), L::splat(t_max));
        mask |= t_near.le(t_far * scale).bits() << at;
        t_near.store(&mut near[at..]);
    }
    (mask, near)
}

/// The rays of `packet` that enter child `lane` of `node` before their `t_max` (a bit per
/// ray; lanes of `t_max` past the rays must hold a negative bound), as groups of `L::WIDTH`
/// rays, a ray per lane. Each ray's lane computes what [`node_test_lanes`] computes for that
/// ray alone, operation for operation.
#[inline(always)]
pub(super) fn rays_entering_lanes<L: Lanes>(
    node: &WideNode,
    lane: usize,
    packet: &PacketBoxTest,
    t_max: &[f32; PACKET_SIZE],
) -> u32 {
    let scale = L::splat(far_scale());
    let mut mask = 0u32;
    for group in 0..PACKET_SIZE / L::WIDTH {
        let at = group * L::WIDTH;
        let mut t_near = L::splat(0.0);
        let mut t_far = L::load(&t_max[at..]);
        for axis in 0..3 {
            let near_plane = node.bounds[packet.near[axis]][lane] - packet.origin[axis];
            let far_plane = node.bounds[packet.near[axis] ^ 1][lane] - packet.origin[axis];
            let inv = L::load(&packet.inv[axis][at..]);
            let n = L::splat(near_plane) * inv;
            let f = L::splat(far_plane) * inv;
            t_near = n.max(t_near);
            t_far = f.min(t_far);
        }
        mask |= t_near.le(t_far * scale).bits() << at;
    }
    mask
}

/// [`node_test_lanes`] four lanes wide (SSE2 or NEON registers), for processors without AVX2.
#[inline(always)]
pub(super) fn node_test(node: &WideNode, ray: &RayBoxTest, t_max: f32) -> (u32, [f32; 8]) {
    node_test_lanes::<Vec4>(node, ray, t_max)
}

/// [`packet_node_test_lanes`] four lanes wide.
#[inline(always)]
pub(super) fn packet_node_test(
    node: &WideNode,
    packet: &PacketBoxTest,
    t_max: f32,
) -> (u32, [f32; 8]) {
    packet_node_test_lanes::<Vec4>(node, packet, t_max)
}

/// [`rays_entering_lanes`] four lanes wide.
#[inline(always)]
pub(super) fn rays_entering(
    node: &WideNode,
    lane: usize,
    packet: &PacketBoxTest,
    t_max: &[f32; PACKET_SIZE],
) -> u32 {
    rays_entering_lanes::<Vec4>(node, lane, packet, t_max)
}

/// [`node_test_lanes`] eight lanes wide, in AVX registers: the whole node in one group.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn node_test_avx2(node: &WideNode, ray: &RayBoxTest, t_max: f32) -> (u32, [f32; 8]) {
    struct Test<'a>(&'a WideNode, &'a RayBoxTest, f32);
    impl LaneKernel for Test<'_> {
        type Output = (u32, [f32; 8]);
        #[inline(always)]
        fn run<L: Lanes, const W: usize>(self) -> Self::Output {
            node_test_lanes::<L>(self.0, self.1, self.2)
        }
    }
    run_avx2(Test(node, ray, t_max))
}

/// [`packet_node_test_lanes`] eight lanes wide, in AVX registers.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn packet_node_test_avx2(
    node: &WideNode,
    packet: &PacketBoxTest,
    t_max: f32,
) -> (u32, [f32; 8]) {
    struct Test<'a>(&'a WideNode, &'a PacketBoxTest, f32);
    impl LaneKernel for Test<'_> {
        type Output = (u32, [f32; 8]);
        #[inline(always)]
        fn run<L: Lanes, const W: usize>(self) -> Self::Output {
            packet_node_test_lanes::<L>(self.0, self.1, self.2)
        }
    }
    run_avx2(Test(node, packet, t_max))
}

/// [`rays_entering_lanes`] eight lanes wide, in AVX registers: the packet in two groups.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn rays_entering_avx2(
    node: &WideNode,
    lane: usize,
    packet: &PacketBoxTest,
    t_max: &[f32; PACKET_SIZE],
) -> u32 {
    struct Test<'a>(
        &'a WideNode,
        usize,
        &'a PacketBoxTest,
        &'a [f32; PACKET_SIZE],
    );
    impl LaneKernel for Test<'_> {
        type Output = u32;
        #[inline(always)]
        fn run<L: Lanes, const W: usize>(self) -> u32 {
            rays_entering_lanes::<L>(self.0, self.1, self.2, self.3)
        }
    }
    run_avx2(Test(node, lane, packet, t_max))
}

/// The value of `values` that no other one `replaces`, found as a tree of comparisons (lanes
/// half the array apart, then a quarter, ...), which compiles to a few vector minima or maxima.
/// Where two compare equal, the lower lane's is kept.
#[inline(always)]
pub(super) fn extreme(mut values: [f32; PACKET_SIZE], replaces: impl Fn(f32, f32) -> bool) -> f32 {
    let mut half = PACKET_SIZE / 2;
    while half > 0 {
        for i in 0..half {
            let (kept, candidate) = (values[i], values[i + half]);
            values[i] = if replaces(candidate, kept) {
                candidate
            } else {
                kept
            };
        }
        half /= 2;
    }
    values[0]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::next_float_up;
    use glam::{Vec3, Vec3A};
    use obvhs::aabb::Aabb;

    /// A packet's bounds of the reciprocals, found as trees, are the scan's from the first ray,
    /// bit for bit, on random values with repeated values and infinities among them; a zero
    /// bound of a row with zeros of both signs (reciprocals of infinite directions) compares
    /// equal to the scan's, possibly the other zero.
    #[test]
    fn the_extremes_of_a_row_are_the_scans() {
        let mut sampler = crate::sampler::Sampler::new(6, 0, 0);
        let special = [0.0, f32::INFINITY, f32::NEG_INFINITY, 1.0, -1.0, -0.0];
        let mut bit_for_bit = 0;
        for _ in 0..20_000 {
            let row: [f32; PACKET_SIZE] = std::array::from_fn(|_| {
                if sampler.next_1d() < 0.5 {
                    sampler.pick(&special)
                } else {
                    sampler.next_1d() - 0.5
                }
            });
            let scan = |replaces: fn(f32, f32) -> bool| {
                row.iter()
                    .fold(row[0], |kept, &v| if replaces(v, kept) { v } else { kept })
            };
            let orders: [fn(f32, f32) -> bool; 2] = [|a, b| a < b, |a, b| a > b];
            let both_zeros = row.iter().any(|v| v.to_bits() == 0)
                && row.iter().any(|v| v.to_bits() == (-0.0f32).to_bits());
            for replaces in orders {
                let (tree, scanned) = (extreme(row, replaces), scan(replaces));
                // Only a zero extreme of a row with both zeros may take the other sign.
                if both_zeros && scanned == 0.0 {
                    assert_eq!(tree, scanned, "{row:?}");
                } else {
                    assert_eq!(tree.to_bits(), scanned.to_bits(), "{row:?}");
                    bit_for_bit += 1;
                }
            }
        }
        assert!(
            bit_for_bit > 39_000,
            "{bit_for_bit} of 40000 compared bit for bit"
        );
    }

    /// The node test is conservative: a ray aimed at any point of a box's boundary, from any
    /// side, enters it, flat boxes included (the rounded slab test misses some).
    #[test]
    fn rays_aimed_at_box_boundaries_enter_the_box() {
        let boxes = [
            Aabb::new(Vec3A::new(-1.0, 0.0, -1.0), Vec3A::new(1.0, 0.0, 1.0)),
            Aabb::new(Vec3A::new(0.1, 0.2, 0.3), Vec3A::new(0.7, 1.9, 0.31)),
        ];
        let mut sampler = crate::sampler::Sampler::new(7, 0, 0);
        for b in boxes {
            let mut node = WideNode::EMPTY;
            for axis in 0..3 {
                node.bounds[2 * axis][0] = b.min[axis];
                node.bounds[2 * axis + 1][0] = b.max[axis];
            }
            for _ in 0..20_000 {
                let u = sampler.next_2d();
                let v = sampler.next_2d();
                // A point on the boundary: one coordinate on a face, the others inside.
                let face = (v.x * 6.0) as usize % 6;
                let (axis, on_max) = (face / 2, face % 2 == 1);
                let mut target: [f32; 3] = std::array::from_fn(|a| {
                    let s = if a == (axis + 1) % 3 { u.x } else { u.y };
                    b.min[a] + s * (b.max[a] - b.min[a])
                });
                target[axis] = if on_max { b.max[axis] } else { b.min[axis] };
                let target = Vec3::from(target);
                let dir = Vec3::new(v.y - 0.5, u.x * 2.0 - 1.0, u.y - 0.3);
                let origin = target + dir * 10.0;
                let test = RayBoxTest::new(origin, target - origin);
                let (mask, _) = node_test(&node, &test, 1.0);
                assert_eq!(mask & 1, 1, "box {b:?}, from {origin} to {target}");
                // Empty slots are never entered.
                assert_eq!(mask & !1, 0);
            }
        }
    }

    /// The node test gives the same answers, bit for bit, one lane at a time (`f32`), four
    /// (`Vec4`, the portable form) and eight (AVX2, where the processor has it): random boxes,
    /// empty slots, rays with zero direction components.
    #[test]
    fn node_tests_of_every_width_agree() {
        let mut sampler = crate::sampler::Sampler::new(5, 0, 0);
        let mut value = || {
            let u = sampler.next_2d();
            (u.x - 0.5) * 10.0 * u.y
        };
        for round in 0..5000 {
            let mut node = WideNode::EMPTY;
            for lane in 0..(round % 9) {
                for axis in 0..3 {
                    let (a, b) = (value(), value());
                    node.bounds[2 * axis][lane] = a.min(b);
                    node.bounds[2 * axis + 1][lane] = a.max(b);
                }
            }
            let origin = Vec3::new(value(), value(), value());
            let mut direction = Vec3::new(value(), value(), value());
            direction[round % 3] = if round % 2 == 0 { 0.0 } else { -0.0 };
            let test = RayBoxTest::new(origin, direction);
            let t_max = if round % 4 == 0 {
                f32::INFINITY
            } else {
                value().abs()
            };
            let (mask, near) = node_test(&node, &test, t_max);
            let (mask_one, near_one) = node_test_lanes::<f32>(&node, &test, t_max);
            assert_eq!(mask, mask_one, "round {round}");
            assert_eq!(near.map(f32::to_bits), near_one.map(f32::to_bits));
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 is present (checked just above).
                let (mask_avx2, near_avx2) = unsafe { node_test_avx2(&node, &test, t_max) };
                assert_eq!(mask, mask_avx2, "round {round}, AVX2");
                assert_eq!(near.map(f32::to_bits), near_avx2.map(f32::to_bits));
            }
        }
    }

    /// A packet's node test lets through every child one of its rays' own test lets through,
    /// at a distance no greater than the ray's (so the packet visits every node its rays
    /// would); the rays found entering a child are those whose own test enters it; one lane at
    /// a time and eight (AVX2) the tests give the portable forms' answers bit for bit. Random
    /// boxes, empty slots, packets from tight (one pixel) to wide, zero direction components.
    #[test]
    fn packet_node_tests_let_through_what_their_rays_do() {
        let mut sampler = crate::sampler::Sampler::new(17, 0, 0);
        let mut value = || {
            let u = sampler.next_2d();
            (u.x - 0.5) * 10.0 * u.y
        };
        let mut passed = [0usize; 2];
        for round in 0..5000 {
            let mut node = WideNode::EMPTY;
            for lane in 0..(round % 9) {
                for axis in 0..3 {
                    let (a, b) = (value(), value());
                    node.bounds[2 * axis][lane] = a.min(b);
                    node.bounds[2 * axis + 1][lane] = a.max(b);
                }
            }
            let origin = Vec3::new(value(), value(), value());
            let mut base = Vec3::new(value(), value(), value());
            if round % 7 == 0 {
                base[round % 3] = 0.0;
            }
            let spread = [1e-4, 1e-2, 0.3][round % 3];
            let rays: Vec<RayBoxTest> = (0..1 + round % PACKET_SIZE)
                .map(|_| {
                    let jitter = Vec3::new(value(), value(), value()) * spread;
                    // Keep the signs (zeros stay zeros), as a packet needs.
                    let d = (base + jitter * base.abs()).normalize_or(base);
                    RayBoxTest::new(origin, d)
                })
                .collect();
            let Some(packet) = PacketBoxTest::new(&rays) else {
                continue;
            };
            let t_maxes: Vec<f32> = rays
                .iter()
                .map(|_| {
                    if round % 4 == 0 {
                        f32::INFINITY
                    } else {
                        value().abs()
                    }
                })
                .collect();
            let packet_t_max = t_maxes.iter().copied().fold(0.0, f32::max);
            let (mask, near) = packet_node_test(&node, &packet, packet_t_max);
            let mut ray_t_max = [-1.0f32; PACKET_SIZE];
            ray_t_max[..rays.len()].copy_from_slice(&t_maxes);
            for lane in 0..8 {
                let entering = rays_entering(&node, lane, &packet, &ray_t_max);
                let alone = rays
                    .iter()
                    .zip(&t_maxes)
                    .enumerate()
                    .fold(0, |m, (r, (ray, &t))| {
                        m | ((node_test(&node, ray, t).0 >> lane) & 1) << r
                    });
                assert_eq!(entering, alone, "round {round}, lane {lane}");
                let one = rays_entering_lanes::<f32>(&node, lane, &packet, &ray_t_max);
                assert_eq!(one, alone, "round {round}, lane {lane}, one lane at a time");
                #[cfg(target_arch = "x86_64")]
                if std::is_x86_feature_detected!("avx2") {
                    // SAFETY: AVX2 is present (checked just above).
                    let avx2 = unsafe { rays_entering_avx2(&node, lane, &packet, &ray_t_max) };
                    assert_eq!(avx2, alone, "round {round}, lane {lane}, AVX2");
                }
            }
            for (ray, &t_max) in rays.iter().zip(&t_maxes) {
                let (ray_mask, ray_near) = node_test(&node, ray, t_max);
                assert_eq!(
                    ray_mask & !mask,
                    0,
                    "round {round}: a child a ray enters is culled"
                );
                for lane in 0..8 {
                    if ray_mask & (1 << lane) != 0 {
                        assert!(near[lane] <= ray_near[lane], "round {round}, lane {lane}");
                    }
                }
                passed[0] += ray_mask.count_ones() as usize;
            }
            passed[1] += mask.count_ones() as usize;
            let (mask_one, near_one) = packet_node_test_lanes::<f32>(&node, &packet, packet_t_max);
            assert_eq!(mask, mask_one, "round {round}, one lane at a time");
            assert_eq!(near.map(f32::to_bits), near_one.map(f32::to_bits));
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 is present (checked just above).
                let (mask_avx2, near_avx2) =
                    unsafe { packet_node_test_avx2(&node, &packet, packet_t_max) };
                assert_eq!(mask, mask_avx2, "round {round}, AVX2");
                assert_eq!(near.map(f32::to_bits), near_avx2.map(f32::to_bits));
            }
        }
        assert!(
            passed[0] > 2000 && passed[1] > 1000,
            "too few children entered: {passed:?}"
        );
    }

    /// Rays make a packet only from one origin, bit for bit, and with one sign per direction
    /// component: a ray one ulp away, or in another octant, makes none.
    #[test]
    fn packets_need_one_origin_and_one_octant() {
        let origin = Vec3::new(1.0, -2.0, 0.0);
        let (along, other) = (Vec3::new(1.0, 2.0, -3.0), Vec3::new(2.0, 1.0, -1.0));
        let first = RayBoxTest::new(origin, along);
        let packet = |second| PacketBoxTest::new(&[first, second]).is_some();
        assert!(packet(RayBoxTest::new(origin, other)));
        for axis in 0..3 {
            let mut moved = origin;
            moved[axis] = next_float_up(moved[axis]);
            assert!(
                !packet(RayBoxTest::new(moved, other)),
                "origin moved on axis {axis}"
            );
            let mut flipped = other;
            flipped[axis] = -flipped[axis];
            assert!(
                !packet(RayBoxTest::new(origin, flipped)),
                "direction flipped on {axis}"
            );
        }
        // −0 is not +0 here: the origins differ in their bits.
        let negative_zero = Vec3::new(1.0, -2.0, -0.0);
        assert!(!packet(RayBoxTest::new(negative_zero, other)));
    }
}
