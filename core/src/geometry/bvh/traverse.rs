//! The traversals: the closest hit of a ray or of each ray of a packet, and any hit, each a
//! kernel written once over its node test and compiled twice, for the baseline and for AVX2.

use super::node_test::{
    PacketBoxTest, RayBoxTest, extreme, far_scale, node_test, packet_node_test, rays_entering,
};
#[cfg(target_arch = "x86_64")]
use super::node_test::{node_test_avx2, packet_node_test_avx2, rays_entering_avx2};
use super::{LEAF, PACKET_SIZE, TRAVERSAL_STACK_SIZE, WideBvh, WideNode};
use crate::math::prefetch;
use std::mem::MaybeUninit;

/// Entries of the traversal stack: a node pushes at most 7 children, and the tree has fewer
/// levels than [`TRAVERSAL_STACK_SIZE`] ([`WideBvh::build`] keeps it so).
const STACK_SIZE: usize = 7 * TRAVERSAL_STACK_SIZE + 1;

/// A traversal stack of at most [`STACK_SIZE`] entries, left uninitialised: zeroing 225
/// entries on every ray (a `[T; STACK_SIZE]` literal) cost 6 % of a render's instructions.
struct Stack<T: Copy> {
    entries: [MaybeUninit<T>; STACK_SIZE],
    len: usize,
}

impl<T: Copy> Stack<T> {
    #[inline(always)]
    fn new() -> Self {
        Stack {
            entries: [const { MaybeUninit::uninit() }; STACK_SIZE],
            len: 0,
        }
    }

    /// Panics (index out of bounds) rather than overflow: the tree's depth bounds it.
    #[inline(always)]
    fn push(&mut self, entry: T) {
        self.entries[self.len].write(entry);
        self.len += 1;
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<T> {
        self.len = self.len.checked_sub(1)?;
        // SAFETY: every entry below the old length was written by `push`.
        Some(unsafe { self.entries[self.len].assume_init() })
    }
}

impl WideBvh {
    /// The closest primitive along the ray. `hit(i, t_max)` tests primitive `i` and returns its
    /// distance if it is hit before `t_max`; the answer is the last `i` it accepted.
    #[inline]
    pub fn closest_hit(
        &self,
        ray: &RayBoxTest,
        t_max: f32,
        hit: impl FnMut(usize, f32) -> Option<f32>,
    ) -> Option<usize> {
        if self.nodes.is_empty() {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2, checked just above.
            return unsafe { closest_hit_avx2(&self.nodes, ray, t_max, hit) };
        }
        closest_hit_baseline(&self.nodes, ray, t_max, hit)
    }

    /// The closest primitive along each ray of `packet`: `t_max[r]` is ray `r`'s bound,
    /// lowered to each hit accepted; `hit(i, rays, t_max)` tests primitive `i` for the rays whose
    /// bits are set in `rays`, lowers `t_max[r]` of each that hits it before `t_max[r]` to the
    /// distance, and returns their bits (a primitive against several rays at once: it can test
    /// them in SIMD lanes); `closest[r]` is the last primitive accepted for ray `r`. Both have
    /// a lane for every ray a packet can hold: past the packet's rays, `t_max` is not read and
    /// comes back negative, and `closest` is `None`. The packet
    /// visits every node one of its rays would visit alone, and in each, every ray tests the
    /// leaves its own node test would let through: each ray tests the primitives its own
    /// traversal would test, perhaps more, in another order.
    #[inline]
    pub fn closest_hit_packet(
        &self,
        packet: &PacketBoxTest,
        t_max: &mut [f32; PACKET_SIZE],
        closest: &mut [Option<usize>; PACKET_SIZE],
        hit: impl FnMut(usize, u32, &mut [f32; PACKET_SIZE]) -> u32,
    ) {
        *closest = [None; PACKET_SIZE];
        if self.nodes.is_empty() {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2, checked just above.
            return unsafe { closest_hit_packet_avx2(&self.nodes, packet, t_max, closest, hit) };
        }
        closest_hit_packet_baseline(&self.nodes, packet, t_max, closest, hit)
    }

    /// Whether `blocks(i)` holds for a primitive whose box the ray meets before `t_max`
    /// (stopping at the first).
    #[inline]
    pub fn any_hit(&self, ray: &RayBoxTest, t_max: f32, blocks: impl FnMut(usize) -> bool) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2, checked just above.
            return unsafe { any_hit_avx2(&self.nodes, ray, t_max, blocks) };
        }
        any_hit_baseline(&self.nodes, ray, t_max, blocks)
    }
}

/// The kernel compiled for the baseline (the node test and the caller's primitive tests
/// inlined), out of line as the AVX2 one is: inlined into the caller beside the call to the
/// AVX2 kernel, it enlarged the caller's frame and spills on the AVX2 path too (10
/// instructions a shadow ray, 0.6 % of a Veach render's).
#[inline(never)]
fn closest_hit_baseline(
    nodes: &[WideNode],
    ray: &RayBoxTest,
    t_max: f32,
    hit: impl FnMut(usize, f32) -> Option<f32>,
) -> Option<usize> {
    closest_hit_kernel(nodes, ray, t_max, hit, node_test)
}

#[inline(never)]
fn any_hit_baseline(
    nodes: &[WideNode],
    ray: &RayBoxTest,
    t_max: f32,
    blocks: impl FnMut(usize) -> bool,
) -> bool {
    any_hit_kernel(nodes, ray, t_max, blocks, node_test)
}

#[inline(never)]
fn closest_hit_packet_baseline(
    nodes: &[WideNode],
    packet: &PacketBoxTest,
    t_max: &mut [f32; PACKET_SIZE],
    closest: &mut [Option<usize>; PACKET_SIZE],
    hit: impl FnMut(usize, u32, &mut [f32; PACKET_SIZE]) -> u32,
) {
    closest_hit_packet_kernel(
        nodes,
        packet,
        t_max,
        closest,
        hit,
        packet_node_test,
        rays_entering,
    )
}

/// The kernel compiled for AVX2 (the node test and the caller's primitive tests inlined).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn closest_hit_avx2(
    nodes: &[WideNode],
    ray: &RayBoxTest,
    t_max: f32,
    hit: impl FnMut(usize, f32) -> Option<f32>,
) -> Option<usize> {
    // Closures in a `target_feature` function have its features: this call is safe.
    closest_hit_kernel(nodes, ray, t_max, hit, |n, r, t| node_test_avx2(n, r, t))
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn any_hit_avx2(
    nodes: &[WideNode],
    ray: &RayBoxTest,
    t_max: f32,
    blocks: impl FnMut(usize) -> bool,
) -> bool {
    any_hit_kernel(nodes, ray, t_max, blocks, |n, r, t| node_test_avx2(n, r, t))
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn closest_hit_packet_avx2(
    nodes: &[WideNode],
    packet: &PacketBoxTest,
    t_max: &mut [f32; PACKET_SIZE],
    closest: &mut [Option<usize>; PACKET_SIZE],
    hit: impl FnMut(usize, u32, &mut [f32; PACKET_SIZE]) -> u32,
) {
    closest_hit_packet_kernel(
        nodes,
        packet,
        t_max,
        closest,
        hit,
        |n, p, t| packet_node_test_avx2(n, p, t),
        |n, lane, p, t| rays_entering_avx2(n, lane, p, t),
    )
}

/// Asks for the four cache lines of a node the traversal is going to visit as soon as the node
/// test finds it, so that their misses overlap the tests before the visit.
#[inline(always)]
fn prefetch_node(node: &WideNode) {
    prefetch(&node.bounds[0]);
    prefetch(&node.bounds[2]);
    prefetch(&node.bounds[4]);
    prefetch(&node.child);
}

/// Closest-hit traversal: leaves are tested as their node is, inner children are visited
/// nearest first, and stacked ones the ray no longer reaches before its closest hit are skipped.
#[inline(always)]
fn closest_hit_kernel(
    nodes: &[WideNode],
    ray: &RayBoxTest,
    mut t_max: f32,
    mut hit: impl FnMut(usize, f32) -> Option<f32>,
    node_test: impl Fn(&WideNode, &RayBoxTest, f32) -> (u32, [f32; 8]),
) -> Option<usize> {
    let mut stack = Stack::new();
    let mut closest = None;
    let mut node = 0u32;
    let scale = far_scale();
    loop {
        let current = &nodes[node as usize];
        let (mut mask, t_near) = node_test(current, ray, t_max);
        // Inner children hit, nearest first (insertion sort of at most 8).
        let mut inner = [(0u32, 0.0f32); 8];
        let mut inner_count = 0;
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let child = current.child[lane];
            if child & LEAF != 0 {
                let first = (child & !LEAF) as usize;
                for primitive in first..first + current.count[lane] as usize {
                    if let Some(t) = hit(primitive, t_max) {
                        t_max = t;
                        closest = Some(primitive);
                    }
                }
            } else {
                prefetch_node(&nodes[child as usize]);
                let entry = (child, t_near[lane]);
                let mut i = inner_count;
                while i > 0 && inner[i - 1].1 > entry.1 {
                    inner[i] = inner[i - 1];
                    i -= 1;
                }
                inner[i] = entry;
                inner_count += 1;
            }
        }
        let bound = t_max * scale;
        if inner_count > 0 && inner[0].1 <= bound {
            for &entry in inner[1..inner_count].iter().rev() {
                stack.push(entry);
            }
            node = inner[0].0;
            continue;
        }
        // Pop the next child the ray still reaches before its closest hit.
        loop {
            let Some((next, t_enter)) = stack.pop() else {
                return closest;
            };
            if t_enter <= t_max * scale {
                node = next;
                break;
            }
        }
    }
}

/// [`closest_hit_kernel`] for a packet: the node test is the packet's, bounded by the largest
/// of the rays' `t_max`; the rays that enter each leaf are found as the node is visited, with
/// their bounds as they were then, as each ray's own traversal would find them.
#[inline(always)]
fn closest_hit_packet_kernel(
    nodes: &[WideNode],
    packet: &PacketBoxTest,
    t_max: &mut [f32; PACKET_SIZE],
    closest: &mut [Option<usize>; PACKET_SIZE],
    mut hit: impl FnMut(usize, u32, &mut [f32; PACKET_SIZE]) -> u32,
    node_test: impl Fn(&WideNode, &PacketBoxTest, f32) -> (u32, [f32; 8]),
    rays_entering: impl Fn(&WideNode, usize, &PacketBoxTest, &[f32; PACKET_SIZE]) -> u32,
) {
    // Lanes past the rays never enter anything. Whole arrays, copied in registers: a copy of
    // the rays' part alone, of a length known only at run time, was a call to `memcpy`.
    let mut ray_t_max = *t_max;
    for bound in &mut ray_t_max[packet.rays..] {
        *bound = -1.0;
    }
    let mut stack = Stack::new();
    let mut node = 0u32;
    let scale = far_scale();
    let mut packet_t_max = largest_bound(&ray_t_max);
    loop {
        let current = &nodes[node as usize];
        let (mut mask, t_near) = node_test(current, packet, packet_t_max);
        let mut inner = [(0u32, 0.0f32); 8];
        let mut inner_count = 0;
        let mut leaves = 0u32;
        let mut entering = [0u32; 8];
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let child = current.child[lane];
            if child & LEAF != 0 {
                leaves |= 1 << lane;
                entering[lane] = rays_entering(current, lane, packet, &ray_t_max);
            } else {
                prefetch_node(&nodes[child as usize]);
                let entry = (child, t_near[lane]);
                let mut i = inner_count;
                while i > 0 && inner[i - 1].1 > entry.1 {
                    inner[i] = inner[i - 1];
                    i -= 1;
                }
                inner[i] = entry;
                inner_count += 1;
            }
        }
        if leaves != 0 {
            while leaves != 0 {
                let lane = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let first = (current.child[lane] & !LEAF) as usize;
                for primitive in first..first + current.count[lane] as usize {
                    let mut hits = hit(primitive, entering[lane], &mut ray_t_max);
                    while hits != 0 {
                        let r = hits.trailing_zeros() as usize;
                        hits &= hits - 1;
                        closest[r] = Some(primitive);
                    }
                }
            }
            packet_t_max = largest_bound(&ray_t_max);
        }
        let bound = packet_t_max * scale;
        if inner_count > 0 && inner[0].1 <= bound {
            for &entry in inner[1..inner_count].iter().rev() {
                stack.push(entry);
            }
            node = inner[0].0;
            continue;
        }
        loop {
            let Some((next, t_enter)) = stack.pop() else {
                *t_max = ray_t_max;
                return;
            };
            if t_enter <= packet_t_max * scale {
                node = next;
                break;
            }
        }
    }
}

/// The largest of a packet's bounds, and 0: the fold of `f32::max` from 0, as a tree of
/// comparisons that compiles to a few vector maxima (the fold took 5 % of the Cornell box's
/// packet traversal). Each bound is raised to 0 first (a NaN too, which `f32::max` ignores);
/// after that, the order of the maxima does not change the result.
#[inline(always)]
fn largest_bound(t_max: &[f32; PACKET_SIZE]) -> f32 {
    let raised = t_max.map(|t| if t > 0.0 { t } else { 0.0 });
    extreme(raised, |candidate, kept| candidate > kept)
}

/// Any-hit traversal: stops at the first primitive that blocks the ray.
#[inline(always)]
fn any_hit_kernel(
    nodes: &[WideNode],
    ray: &RayBoxTest,
    t_max: f32,
    mut blocks: impl FnMut(usize) -> bool,
    node_test: impl Fn(&WideNode, &RayBoxTest, f32) -> (u32, [f32; 8]),
) -> bool {
    let mut stack = Stack::new();
    let mut node = 0u32;
    loop {
        let current = &nodes[node as usize];
        let (mut mask, _) = node_test(current, ray, t_max);
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let child = current.child[lane];
            if child & LEAF != 0 {
                let first = (child & !LEAF) as usize;
                for primitive in first..first + current.count[lane] as usize {
                    if blocks(primitive) {
                        return true;
                    }
                }
            } else {
                prefetch_node(&nodes[child as usize]);
                stack.push(child);
            }
        }
        let Some(next) = stack.pop() else {
            return false;
        };
        node = next;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use obvhs::aabb::Aabb;

    /// A packet's largest bound is the fold of `f32::max` from 0, bit for bit, on random
    /// bounds mixed with NaN, infinities, negative bounds (the lanes past the rays) and zeros of
    /// both signs.
    #[test]
    fn the_largest_bound_is_the_fold_of_the_bounds() {
        let mut sampler = crate::sampler::Sampler::new(5, 0, 0);
        let special = [
            0.0,
            -0.0,
            -1.0,
            f32::NAN,
            f32::INFINITY,
            f32::MIN_POSITIVE,
            1e30,
        ];
        let mut positive = 0;
        for _ in 0..20_000 {
            let bounds: [f32; PACKET_SIZE] = std::array::from_fn(|_| {
                let u = sampler.next_1d();
                if u < 0.25 {
                    sampler.pick(&special)
                } else {
                    sampler.next_1d() * 10f32.powi((u * 20.0) as i32 - 10)
                }
            });
            let fold = bounds.iter().copied().fold(0.0f32, f32::max);
            let tree = largest_bound(&bounds);
            assert_eq!(tree.to_bits(), fold.to_bits(), "{bounds:?}");
            positive += (fold > 0.0) as u32;
        }
        assert!(positive > 10_000, "{positive}");
    }

    /// A point uniform in the cube of side `scale` centred on the origin.
    fn random_point(sampler: &mut crate::sampler::Sampler, scale: f32) -> Vec3 {
        let (a, b) = (sampler.next_2d(), sampler.next_2d());
        Vec3::new(a.x - 0.5, a.y - 0.5, b.x - 0.5) * scale
    }

    /// A tree over 3000 random boxes (centres in a cube of side 20, half-sizes up to 0.3)
    /// standing for primitives, and the boxes in its leaf order.
    fn random_box_tree(sampler: &mut crate::sampler::Sampler) -> (WideBvh, Vec<Aabb>) {
        let boxes: Vec<Aabb> = (0..3000)
            .map(|_| {
                let c = random_point(sampler, 20.0);
                let h = random_point(sampler, 0.6).abs();
                Aabb::new((c - h).into(), (c + h).into())
            })
            .collect();
        let (bvh, order, _) = WideBvh::build(&boxes, 1.0);
        let leaf_boxes = order.iter().map(|&i| boxes[i as usize]).collect();
        (bvh, leaf_boxes)
    }

    /// A box primitive's distance: where the ray enters it (lane 0 of a one-child node), if
    /// before `t_max`.
    fn box_entry(test: &RayBoxTest, b: &Aabb, t_max: f32) -> Option<f32> {
        let mut node = WideNode::EMPTY;
        for axis in 0..3 {
            node.bounds[2 * axis][0] = b.min[axis];
            node.bounds[2 * axis + 1][0] = b.max[axis];
        }
        let (mask, t_near) = node_test(&node, test, f32::INFINITY);
        (mask & 1 == 1 && t_near[0] < t_max).then_some(t_near[0])
    }

    /// The kernel compiled for the baseline (what processors without AVX2 run) and the one the
    /// dispatch picks here give the brute-force answer on random boxes standing for primitives.
    #[test]
    fn both_kernels_find_the_closest_and_any_hit() {
        let mut sampler = crate::sampler::Sampler::new(11, 0, 0);
        let (bvh, leaf_boxes) = random_box_tree(&mut sampler);
        let mut point = |scale: f32| random_point(&mut sampler, scale);
        let mut hits = 0;
        for _ in 0..2000 {
            let origin = point(30.0);
            let direction = point(1.0);
            let t_max = if hits % 2 == 0 { f32::INFINITY } else { 20.0 };
            let test = RayBoxTest::new(origin, direction);
            let mut expected: Option<(f32, usize)> = None;
            for (i, b) in leaf_boxes.iter().enumerate() {
                if let Some(t) = box_entry(&test, b, expected.map_or(t_max, |e| e.0)) {
                    expected = Some((t, i));
                }
            }
            let hit = |i: usize, t: f32| box_entry(&test, &leaf_boxes[i], t);
            let blocks = |i: usize| box_entry(&test, &leaf_boxes[i], t_max).is_some();
            let t_of = |i: Option<usize>| i.map(|i| box_entry(&test, &leaf_boxes[i], t_max));
            let expected_t = expected.map(|e| Some(e.0));
            assert_eq!(
                t_of(closest_hit_kernel(&bvh.nodes, &test, t_max, hit, node_test)),
                expected_t
            );
            assert_eq!(t_of(bvh.closest_hit(&test, t_max, hit)), expected_t);
            assert_eq!(
                any_hit_kernel(&bvh.nodes, &test, t_max, blocks, node_test),
                expected.is_some()
            );
            assert_eq!(bvh.any_hit(&test, t_max, blocks), expected.is_some());
            hits += expected.is_some() as usize;
        }
        assert!(hits > 200, "only {hits} rays hit");
    }

    /// Packets find each ray's closest box as the ray alone finds it, with the portable kernel
    /// and with the dispatched one (random boxes standing for primitives, as above).
    #[test]
    fn packets_find_each_rays_closest_hit() {
        let mut sampler = crate::sampler::Sampler::new(23, 0, 0);
        let (bvh, leaf_boxes) = random_box_tree(&mut sampler);
        let mut point = |scale: f32| random_point(&mut sampler, scale);
        let (mut packets, mut hits) = (0, 0);
        for round in 0..600 {
            let origin = point(30.0);
            let base = point(1.0);
            let spread = [1e-3, 3e-2, 0.3][round % 3];
            let rays: Vec<RayBoxTest> = (0..1 + round % PACKET_SIZE)
                .map(|_| RayBoxTest::new(origin, base + point(spread)))
                .collect();
            let Some(packet) = PacketBoxTest::new(&rays) else {
                continue;
            };
            packets += 1;
            // Lanes past the rays are not read: NaN there changes nothing.
            let t_max0: [f32; PACKET_SIZE] = std::array::from_fn(|r| match r {
                _ if r >= rays.len() => f32::NAN,
                _ if (round + r) % 2 == 0 => f32::INFINITY,
                _ => 20.0,
            });
            let alone: Vec<Option<f32>> = rays
                .iter()
                .zip(&t_max0)
                .map(|(ray, &t_max)| {
                    let hit = |i: usize, t: f32| box_entry(ray, &leaf_boxes[i], t);
                    bvh.closest_hit(ray, t_max, hit)
                        .map(|i| hit(i, t_max).unwrap())
                })
                .collect();
            hits += alone.iter().flatten().count();
            let hit = |r: usize, i: usize, t: f32| box_entry(&rays[r], &leaf_boxes[i], t);
            // The primitive against each of the rays, one by one.
            let packet_hit = |i: usize, rays: u32, t_max: &mut [f32; PACKET_SIZE]| {
                let mut hits = 0;
                for r in (0..PACKET_SIZE).filter(|r| rays >> r & 1 != 0) {
                    if let Some(t) = hit(r, i, t_max[r]) {
                        t_max[r] = t;
                        hits |= 1 << r;
                    }
                }
                hits
            };
            let mut closest = [None; PACKET_SIZE];
            let mut t_max = t_max0;
            closest_hit_packet_kernel(
                &bvh.nodes,
                &packet,
                &mut t_max,
                &mut closest,
                packet_hit,
                packet_node_test,
                rays_entering,
            );
            let found = |closest: &[Option<usize>; PACKET_SIZE]| -> Vec<Option<f32>> {
                let (rays_closest, past) = closest.split_at(rays.len());
                assert!(past.iter().all(Option::is_none), "a lane past the rays hit");
                rays_closest
                    .iter()
                    .enumerate()
                    .map(|(r, c)| c.map(|i| hit(r, i, t_max0[r]).unwrap()))
                    .collect()
            };
            assert_eq!(found(&closest), alone, "round {round}, portable kernel");
            let mut t_max = t_max0;
            closest = [Some(0); PACKET_SIZE];
            bvh.closest_hit_packet(&packet, &mut t_max, &mut closest, packet_hit);
            assert_eq!(found(&closest), alone, "round {round}, dispatched kernel");
        }
        assert!(
            packets > 300 && hits > 200,
            "{packets} packets, {hits} hits"
        );
    }
}
