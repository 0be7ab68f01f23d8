//! Any-hit queries for packets of up to eight rays (shadow rays from one shading point toward
//! one light): one fetch of a node serves every ray of the packet.
//!
//! Each node is first tested against the packet as a whole with interval arithmetic (Boulos
//! et al., "Geometric and arithmetic culling methods for entire ray packets", 2006): when the
//! rays share their origin, the distances at which they enter and leave a child's box lie
//! between those of the extreme reciprocal directions, so one 8-lane test over the children
//! culls the ones no ray of the packet enters. The children left are then tested against the
//! rays, eight rays in the lanes, with exactly the operations of the single-ray node test
//! ([`super::node_test`]): each ray visits exactly the leaves its single-ray query visits, so a
//! packet answers bit for bit as its rays one by one (a test checks it).
//!
//! Floating point: the interval test stays conservative under rounding because rounding is
//! monotone: every ray's rounded `(plane − origin) · (1 / direction)` lies between the rounded
//! products with the interval's ends.

use super::{EMPTY, LEAF, RayBoxTest, WideBvh, WideNode, far_scale};

/// Rays in a packet: one per lane.
pub const PACKET_SIZE: usize = 8;

/// Per-packet constants: each ray's origin, reciprocal direction and `t_max` in lanes, and the
/// packet's bounds for the interval test.
#[derive(Clone, Copy, Debug)]
pub struct PacketBoxTest {
    origin: [[f32; PACKET_SIZE]; 3],
    inv_direction: [[f32; PACKET_SIZE]; 3],
    t_max: [f32; PACKET_SIZE],
    /// Lanes that hold a ray.
    rays: u32,
    /// The interval test's constants when the rays share their origin (else no culling).
    bounds: Option<PacketBounds>,
}

/// Per axis, the ranges of the reciprocal directions of the packet's rays that point toward +
/// and toward − (`None` when none does); the shared origin; the largest `t_max`.
#[derive(Clone, Copy, Debug)]
struct PacketBounds {
    origin: [f32; 3],
    positive: [Option<(f32, f32)>; 3],
    negative: [Option<(f32, f32)>; 3],
    t_max: f32,
}

impl PacketBoxTest {
    /// The packet of `rays` (at most [`PACKET_SIZE`]), each as (its box test, its `t_max`).
    pub fn new(rays: &[(RayBoxTest, f32)]) -> Self {
        assert!(rays.len() <= PACKET_SIZE, "{} rays in a packet", rays.len());
        let mut packet = PacketBoxTest {
            origin: [[0.0; PACKET_SIZE]; 3],
            // Lanes without a ray: any finite non-zero value (they are masked out).
            inv_direction: [[1.0; PACKET_SIZE]; 3],
            t_max: [0.0; PACKET_SIZE],
            rays: (1u32 << rays.len()) - 1,
            bounds: None,
        };
        let Some((first, _)) = rays.first() else {
            return packet;
        };
        let mut bounds = PacketBounds {
            origin: first.origin,
            positive: [None; 3],
            negative: [None; 3],
            t_max: 0.0,
        };
        let mut shared = true;
        for (lane, (ray, t_max)) in rays.iter().enumerate() {
            shared &= ray.origin.map(f32::to_bits) == first.origin.map(f32::to_bits);
            packet.t_max[lane] = *t_max;
            bounds.t_max = bounds.t_max.max(*t_max);
            for axis in 0..3 {
                let inv = ray.inv_direction[axis];
                packet.origin[axis][lane] = ray.origin[axis];
                packet.inv_direction[axis][lane] = inv;
                // The same side test as RayBoxTest::near.
                let range = if inv < 0.0 {
                    &mut bounds.negative[axis]
                } else {
                    &mut bounds.positive[axis]
                };
                *range = Some(range.map_or((inv, inv), |(lo, hi)| (lo.min(inv), hi.max(inv))));
            }
        }
        packet.bounds = shared.then_some(bounds);
        packet
    }
}

/// The children of `node` that some ray of the packet may enter (a superset of those the rays'
/// own tests accept), as a bit mask.
#[inline(always)]
fn packet_node_test(node: &WideNode, bounds: &PacketBounds) -> u32 {
    let mut t_near = [0.0f32; 8];
    let mut t_far = [bounds.t_max; 8];
    for axis in 0..3 {
        let (lower, upper) = (&node.bounds[2 * axis], &node.bounds[2 * axis + 1]);
        let o = bounds.origin[axis];
        // Per side: where rays pointing that way enter (near plane) and leave (far plane).
        let mut near = [f32::INFINITY; 8];
        let mut far = [f32::NEG_INFINITY; 8];
        for (range, near_planes, far_planes) in [
            (bounds.positive[axis], lower, upper),
            (bounds.negative[axis], upper, lower),
        ] {
            let Some((lo, hi)) = range else { continue };
            for lane in 0..8 {
                let (n, f) = (near_planes[lane] - o, far_planes[lane] - o);
                let (n_lo, n_hi) = (n * lo, n * hi);
                let (f_lo, f_hi) = (f * lo, f * hi);
                let n_min = if n_lo < n_hi { n_lo } else { n_hi };
                let f_max = if f_lo > f_hi { f_lo } else { f_hi };
                near[lane] = if n_min < near[lane] {
                    n_min
                } else {
                    near[lane]
                };
                far[lane] = if f_max > far[lane] { f_max } else { far[lane] };
            }
        }
        for lane in 0..8 {
            t_near[lane] = if near[lane] > t_near[lane] {
                near[lane]
            } else {
                t_near[lane]
            };
            t_far[lane] = if far[lane] < t_far[lane] {
                far[lane]
            } else {
                t_far[lane]
            };
        }
    }
    let scale = far_scale();
    let mut mask = 0u32;
    for lane in 0..8 {
        mask |= ((t_near[lane] <= t_far[lane] * scale) as u32) << lane;
    }
    mask
}

/// The rays of the packet that enter child `slot` of `node`, as a bit mask over the lanes:
/// [`super::node_test`]'s operations, in its order, with the rays in the lanes.
#[inline(always)]
fn child_test(node: &WideNode, slot: usize, packet: &PacketBoxTest) -> u32 {
    let mut t_near = [0.0f32; PACKET_SIZE];
    let mut t_far = packet.t_max;
    for axis in 0..3 {
        let (lower, upper) = (node.bounds[2 * axis][slot], node.bounds[2 * axis + 1][slot]);
        let (o, inv) = (&packet.origin[axis], &packet.inv_direction[axis]);
        for lane in 0..PACKET_SIZE {
            let negative = inv[lane] < 0.0;
            let near_plane = if negative { upper } else { lower };
            let far_plane = if negative { lower } else { upper };
            let n = (near_plane - o[lane]) * inv[lane];
            let f = (far_plane - o[lane]) * inv[lane];
            t_near[lane] = if n > t_near[lane] { n } else { t_near[lane] };
            t_far[lane] = if f < t_far[lane] { f } else { t_far[lane] };
        }
    }
    let scale = far_scale();
    let mut mask = 0u32;
    for lane in 0..PACKET_SIZE {
        mask |= ((t_near[lane] <= t_far[lane] * scale) as u32) << lane;
    }
    mask & packet.rays
}

/// Entries of the packet traversal's stack: a node pushes at most 8 children.
const PACKET_STACK_SIZE: usize = 8 * crate::bvh::TRAVERSAL_STACK_SIZE;

impl WideBvh {
    /// Which rays of the packet are blocked: `blocks(lane, i)` tells whether primitive `i`
    /// blocks the ray in `lane` (its box test having accepted the primitive's leaf). Bit `lane`
    /// of the answer is the ray's [`WideBvh::any_hit`].
    #[inline]
    pub fn any_hit_packet(
        &self,
        packet: &PacketBoxTest,
        blocks: impl FnMut(usize, usize) -> bool,
    ) -> u32 {
        if self.nodes.is_empty() || packet.rays == 0 {
            return 0;
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2, checked just above.
            return unsafe { any_hit_packet_avx2(&self.nodes, packet, blocks) };
        }
        any_hit_packet_kernel(&self.nodes, packet, blocks)
    }
}

/// The kernel compiled for AVX2 (its lane-wise loops become 8-wide operations).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn any_hit_packet_avx2(
    nodes: &[WideNode],
    packet: &PacketBoxTest,
    blocks: impl FnMut(usize, usize) -> bool,
) -> u32 {
    any_hit_packet_kernel(nodes, packet, blocks)
}

#[inline(always)]
fn any_hit_packet_kernel(
    nodes: &[WideNode],
    packet: &PacketBoxTest,
    mut blocks: impl FnMut(usize, usize) -> bool,
) -> u32 {
    let mut stack = [(0u32, 0u32); PACKET_STACK_SIZE];
    let mut depth = 0;
    let (mut node, mut rays) = (0u32, packet.rays);
    let mut blocked = 0u32;
    loop {
        let current = &nodes[node as usize];
        let mut children = match &packet.bounds {
            // One ray left: its own tests cull as well.
            Some(bounds) if rays.count_ones() > 1 => packet_node_test(current, bounds),
            _ => (1 << 8) - 1,
        };
        for (slot, &child) in current.child.iter().enumerate() {
            if child == EMPTY {
                children &= !(1 << slot);
            }
        }
        while children != 0 {
            let slot = children.trailing_zeros() as usize;
            children &= children - 1;
            let entering = child_test(current, slot, packet) & rays;
            if entering == 0 {
                continue;
            }
            let child = current.child[slot];
            if child & LEAF != 0 {
                let first = (child & !LEAF) as usize;
                for primitive in first..first + current.count[slot] as usize {
                    let mut open = entering & !blocked;
                    while open != 0 {
                        let lane = open.trailing_zeros() as usize;
                        open &= open - 1;
                        if blocks(lane, primitive) {
                            blocked |= 1 << lane;
                        }
                    }
                }
                if blocked == packet.rays {
                    return blocked;
                }
                rays &= !blocked;
                if rays == 0 {
                    break;
                }
            } else {
                stack[depth] = (child, entering);
                depth += 1;
            }
        }
        // The next stacked node that still has a ray not yet blocked.
        loop {
            if depth == 0 {
                return blocked;
            }
            depth -= 1;
            (node, rays) = stack[depth];
            rays &= !blocked;
            if rays != 0 {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use obvhs::aabb::Aabb;

    /// Packets of random rays, sharing their origin or not, give each ray's single-ray answer
    /// (random boxes standing for primitives; a primitive blocks a ray when the ray enters its
    /// box before its `t_max`), through both kernels.
    #[test]
    fn packets_answer_as_their_rays_one_by_one() {
        let mut sampler = crate::sampler::Sampler::new(13, 0, 0);
        let mut point = |scale: f32| {
            let (a, b) = (sampler.next_2d(), sampler.next_2d());
            Vec3::new(a.x - 0.5, a.y - 0.5, b.x - 0.5) * scale
        };
        let boxes: Vec<Aabb> = (0..3000)
            .map(|_| {
                let c = point(20.0);
                let h = point(0.6).abs();
                Aabb::new((c - h).into(), (c + h).into())
            })
            .collect();
        let (bvh, order) = WideBvh::build(&boxes, 1.0);
        let leaf_boxes: Vec<Aabb> = order.iter().map(|&i| boxes[i as usize]).collect();
        let enters = |test: &RayBoxTest, b: &Aabb, t_max: f32| {
            let mut node = WideNode::EMPTY;
            for axis in 0..3 {
                node.bounds[2 * axis][0] = b.min[axis];
                node.bounds[2 * axis + 1][0] = b.max[axis];
            }
            super::super::node_test(&node, test, t_max).0 & 1 == 1
        };
        let (mut blocked_rays, mut open_rays) = (0, 0);
        for round in 0..1500 {
            let size = round % (PACKET_SIZE + 1);
            let shared_origin = round % 4 != 0;
            let origin = point(30.0);
            // A target region: small (a light seen from afar, coherent) or the whole scene.
            let (center, spread) = if round % 3 == 0 {
                (Vec3::ZERO, 30.0)
            } else {
                (point(20.0), 2.0)
            };
            let rays: Vec<(RayBoxTest, f32)> = (0..size)
                .map(|i| {
                    let o = if shared_origin {
                        origin
                    } else {
                        origin + point(1.0)
                    };
                    let target = center + point(spread);
                    // Shadow rays stop short of their target; some go to infinity.
                    let t_max = if (round + i) % 5 == 0 {
                        f32::INFINITY
                    } else {
                        0.9999
                    };
                    (RayBoxTest::new(o, target - o), t_max)
                })
                .collect();
            let packet = PacketBoxTest::new(&rays);
            // One ray shares its origin with itself.
            assert_eq!(
                packet.bounds.is_some(),
                size == 1 || size > 0 && shared_origin
            );
            let blocks = |lane: usize, i: usize| {
                let (test, t_max) = &rays[lane];
                enters(test, &leaf_boxes[i], *t_max)
            };
            let expected: u32 = rays
                .iter()
                .enumerate()
                .map(|(lane, (test, t_max))| {
                    let single =
                        bvh.any_hit(test, *t_max, |i| enters(test, &leaf_boxes[i], *t_max));
                    let brute = leaf_boxes.iter().any(|b| enters(test, b, *t_max));
                    assert_eq!(single, brute);
                    (single as u32) << lane
                })
                .sum();
            assert_eq!(any_hit_packet_kernel(&bvh.nodes, &packet, blocks), expected);
            assert_eq!(bvh.any_hit_packet(&packet, blocks), expected);
            blocked_rays += expected.count_ones();
            open_rays += size as u32 - expected.count_ones();
        }
        assert!(
            blocked_rays > 500 && open_rays > 500,
            "{blocked_rays} blocked, {open_rays} open"
        );
    }

    /// The interval test never culls a child that a ray of the packet enters.
    #[test]
    fn the_interval_test_keeps_every_child_a_ray_enters() {
        let mut sampler = crate::sampler::Sampler::new(17, 0, 0);
        let mut value = || {
            let u = sampler.next_2d();
            (u.x - 0.5) * 10.0 * u.y
        };
        let mut kept = 0;
        for round in 0..3000 {
            let mut node = WideNode::EMPTY;
            for lane in 0..8 {
                for axis in 0..3 {
                    let (a, b) = (value(), value());
                    node.bounds[2 * axis][lane] = a.min(b);
                    node.bounds[2 * axis + 1][lane] = a.max(b);
                }
            }
            let origin = Vec3::new(value(), value(), value());
            let rays: Vec<(RayBoxTest, f32)> = (0..1 + round % PACKET_SIZE)
                .map(|i| {
                    let mut direction = Vec3::new(value(), value(), value());
                    if (round + i) % 7 == 0 {
                        direction[i % 3] = 0.0;
                    }
                    let t_max = if i % 2 == 0 {
                        f32::INFINITY
                    } else {
                        value().abs()
                    };
                    (RayBoxTest::new(origin, direction), t_max)
                })
                .collect();
            let packet = PacketBoxTest::new(&rays);
            let culled = packet_node_test(&node, packet.bounds.as_ref().expect("shared origin"));
            for (lane, (ray, t_max)) in rays.iter().enumerate() {
                let (entered, _) = super::super::node_test(&node, ray, *t_max);
                assert_eq!(entered & !culled, 0, "round {round}, ray {lane}");
                for slot in 0..8 {
                    let by_packet = child_test(&node, slot, &packet) >> lane & 1;
                    assert_eq!(by_packet, entered >> slot & 1);
                }
            }
            kept += culled.count_ones();
        }
        // The test culls something (not a mask of all ones).
        assert!(kept < 3000 * 8, "{kept}");
    }
}
