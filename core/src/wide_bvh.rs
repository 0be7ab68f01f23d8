//! An eight-wide BVH with exact, uncompressed child boxes, and its traversal: obvhs builds a
//! binary BVH ([`crate::bvh`]), which is collapsed here into 8-wide nodes; the node test is ours.
//!
//! Why not obvhs's own traversal: its node test reads child boxes quantised to 8 bits (rounded
//! outward to a coarse grid, so rays enter children they miss), converts them to floats per
//! test, skips every box a ray leaves before an absolute t = 1e-4, and is built for SSE2 only.
//! Here each node holds its eight children's boxes as `f32` in structure-of-arrays form, so one
//! node test is a few 8-lane operations; x86-64 processors with AVX2 run a kernel compiled for
//! them with the node test in AVX intrinsics, chosen at run time (the binary still runs on any
//! x86-64), and every other processor runs the portable node test, which the compiler
//! vectorises for its baseline (SSE2 on x86-64, NEON on aarch64). Both compute the same IEEE operations in the same
//! order (no fused multiply-add: Rust never contracts), so results do not depend on the CPU
//! (a test compares the two bit for bit).
//!
//! The node test is conservative under rounding (Ize, "Robust BVH ray traversal", JCGT 2013;
//! pbrt-v4 §6.8.2): the far distance is enlarged by 2γ₃, the bound of the error of
//! `(plane − origin) · (1 / direction)`. A ray aimed exactly at the edge of a flat box (an
//! axis-aligned square light) therefore enters it, where a rounded slab test can miss it.

use crate::math::{gamma, next_float_down, next_float_up, prefetch};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use std::mem::MaybeUninit;

/// Marks a leaf in [`WideNode::child`]; the other bits are its first primitive.
const LEAF: u32 = 1 << 31;
/// An empty child slot in [`WideNode::child`] (its box is empty too, so no ray enters it).
const EMPTY: u32 = u32::MAX;
/// Most primitives in one leaf: a child with more becomes a node of its own.
const MAX_LEAF_PRIMITIVES: u32 = 3;

/// Entries of the traversal stack: a node pushes at most 7 children, and the tree has fewer
/// levels than [`crate::bvh::TRAVERSAL_STACK_SIZE`] ([`crate::bvh::build`] keeps it so).
const STACK_SIZE: usize = 7 * crate::bvh::TRAVERSAL_STACK_SIZE + 1;

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

/// Eight children's boxes and references (256 bytes, four cache lines).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
struct WideNode {
    /// min x, max x, min y, max y, min z, max z of each child; an empty slot has min = +∞ and
    /// max = −∞.
    bounds: [[f32; 8]; 6],
    /// Inner child: its node index; leaf: [`LEAF`] | its first primitive; empty: [`EMPTY`].
    child: [u32; 8],
    /// Primitives of each leaf child (1 to 3).
    count: [u8; 8],
}

impl WideNode {
    /// The union of the children's boxes.
    fn bounds(&self) -> Aabb {
        let min = |a: &[f32; 8]| a.iter().copied().fold(f32::INFINITY, f32::min);
        let max = |a: &[f32; 8]| a.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let b = &self.bounds;
        Aabb::new(
            glam::Vec3A::new(min(&b[0]), min(&b[2]), min(&b[4])),
            glam::Vec3A::new(max(&b[1]), max(&b[3]), max(&b[5])),
        )
    }

    /// Makes slot `slot` a leaf of the primitives under BVH2 node `child` (appended to
    /// `order`, their exact boxes' union as its box) if there are at most
    /// [`MAX_LEAF_PRIMITIVES`] of them; otherwise leaves the slot and returns false.
    fn try_leaf(
        &mut self,
        slot: usize,
        bvh2: &Bvh2,
        child: u32,
        exact: &[Aabb],
        scratch: &mut Vec<u32>,
        order: &mut Vec<u32>,
    ) -> bool {
        let Some(primitives) = small_subtree(bvh2, child, scratch) else {
            return false;
        };
        self.child[slot] = LEAF | order.len() as u32;
        self.count[slot] = primitives as u8;
        let first = order.len();
        leaf_primitives(bvh2, child, scratch, order);
        let bounds = order[first..]
            .iter()
            .fold(Aabb::empty(), |b, &p| b.union(&exact[p as usize]));
        self.set_child_bounds(slot, &bounds);
        true
    }

    fn set_child_bounds(&mut self, slot: usize, bounds: &Aabb) {
        for axis in 0..3 {
            self.bounds[2 * axis][slot] = bounds.min[axis];
            self.bounds[2 * axis + 1][slot] = bounds.max[axis];
        }
    }

    const EMPTY: WideNode = WideNode {
        bounds: [
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
        ],
        child: [EMPTY; 8],
        count: [0; 8],
    };
}

/// The BVH: node 0 is the root. Leaves index primitives in the tree's leaf order (returned by
/// [`WideBvh::build`]), which is the order the caller keeps its primitives in.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WideBvh {
    nodes: Vec<WideNode>,
}

impl WideBvh {
    /// Builds the tree over `boxes` (obvhs builds its BVH2 on the boxes × `scale`, a power of
    /// two that keeps obvhs' arithmetic in range; the nodes keep the exact unscaled boxes).
    /// Returns the tree and the primitives' leaf order: leaf slot `j` holds primitive `order[j]`.
    pub fn build(boxes: &[Aabb], scale: f32) -> (Self, Vec<u32>) {
        let (bvh, order, _) = crate::bvh::build(boxes, scale);
        (bvh, order)
    }

    /// Collapses `bvh2` (one primitive per leaf, as both of [`crate::bvh`]'s builders make)
    /// into 8-wide nodes, largest child first: each node starts from one BVH2 node and opens
    /// the child of largest surface area among its inner BVH2 nodes until it has 8 children
    /// (Wald, Benthin and Boulos 2008). Children with at most [`MAX_LEAF_PRIMITIVES`]
    /// primitives become leaves. `exact[p]` is the box of primitive `p` in the space rays are
    /// given in (not necessarily `bvh2`'s, whose boxes only rank children): the nodes hold
    /// unions of those exact boxes. Returns the tree, the primitives' leaf order and the tree's
    /// depth (levels of nodes).
    ///
    /// The root's inner children are collapsed in parallel, each into a tree of its own, and
    /// the trees are then laid out one after the other: the result does not depend on the
    /// number of threads.
    pub(crate) fn collapse(bvh2: &Bvh2, exact: &[Aabb]) -> (Self, Vec<u32>, usize) {
        use rayon::prelude::*;
        if bvh2.nodes.is_empty() {
            return (WideBvh::default(), Vec::new(), 0);
        }
        let mut root = WideNode::EMPTY;
        let mut order = Vec::with_capacity(exact.len());
        let mut scratch = Vec::new();
        let mut inner = Vec::new();
        let (children, count) = widest_first_children(bvh2, 0);
        for (slot, &child) in children[..count].iter().enumerate() {
            if !root.try_leaf(slot, bvh2, child, exact, &mut scratch, &mut order) {
                inner.push((slot, child));
            }
        }
        let parts: Vec<_> = inner
            .par_iter()
            .map(|&(_, child)| collapse_subtree(bvh2, child, exact))
            .collect();
        let mut nodes = crate::huge_pages::vec_with_capacity(
            1 + parts.iter().map(|p| p.nodes.len()).sum::<usize>(),
        );
        nodes.push(root);
        let mut deepest = 1;
        for (&(slot, _), part) in inner.iter().zip(parts) {
            let (node_offset, order_offset) = (nodes.len() as u32, order.len() as u32);
            nodes[0].child[slot] = node_offset;
            nodes[0].set_child_bounds(slot, &part.nodes[0].bounds());
            nodes.extend(part.nodes.into_iter().map(|mut node| {
                for child in node.child.iter_mut().filter(|c| **c != EMPTY) {
                    *child += if *child & LEAF != 0 {
                        order_offset
                    } else {
                        node_offset
                    };
                }
                node
            }));
            order.extend_from_slice(&part.order);
            deepest = deepest.max(1 + part.depth);
        }
        (WideBvh { nodes }, order, deepest)
    }

    /// Levels of nodes on the longest path from the root to a leaf (0 for an empty tree).
    #[cfg(test)]
    pub(crate) fn depth(&self) -> usize {
        if self.nodes.is_empty() {
            return 0;
        }
        let mut deepest = 0;
        let mut stack = vec![(0u32, 1usize)];
        while let Some((node, level)) = stack.pop() {
            deepest = deepest.max(level);
            for &child in &self.nodes[node as usize].child {
                if child != EMPTY && child & LEAF == 0 {
                    stack.push((child, level + 1));
                }
            }
        }
        deepest
    }

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
        closest_hit_kernel(&self.nodes, ray, t_max, hit, node_test)
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
        closest_hit_packet_kernel(
            &self.nodes,
            packet,
            t_max,
            closest,
            hit,
            packet_node_test,
            rays_entering,
        )
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
        any_hit_kernel(&self.nodes, ray, t_max, blocks, node_test)
    }
}

/// The 8-wide tree over one BVH2 subtree: its root is node 0, its leaves index `order`.
struct Subtree {
    nodes: Vec<WideNode>,
    order: Vec<u32>,
    depth: usize,
}

/// Up to 8 BVH2 nodes covering the subtree of `source`: starting from it, the inner node of
/// largest surface area is replaced by its two children until there are 8 or only leaves.
fn widest_first_children(bvh2: &Bvh2, source: u32) -> ([u32; 8], usize) {
    let mut children = [source; 8];
    let mut count = 1;
    while count < 8 {
        let mut widest: Option<(usize, f32)> = None;
        for (slot, &child) in children[..count].iter().enumerate() {
            let node = &bvh2.nodes[child as usize];
            let area = node.aabb().half_area();
            if !node.is_leaf() && widest.is_none_or(|(_, a)| area > a) {
                widest = Some((slot, area));
            }
        }
        let Some((slot, _)) = widest else { break };
        let first = bvh2.nodes[children[slot] as usize].first_index;
        children[slot] = first;
        children[count] = first + 1;
        count += 1;
    }
    (children, count)
}

/// Collapses the subtree of BVH2 node `source` (see [`WideBvh::collapse`]).
fn collapse_subtree(bvh2: &Bvh2, source: u32, exact: &[Aabb]) -> Subtree {
    let mut nodes = vec![WideNode::EMPTY];
    // Where each node's box goes in its parent: (parent, slot); the root has none.
    let mut slot_in_parent = vec![(0u32, 0u8)];
    let mut order = Vec::new();
    let mut depth = 0;
    // (wide node, the BVH2 node it stands for, its level)
    let mut work = vec![(0u32, source, 1usize)];
    let mut scratch = Vec::new();
    while let Some((wide, source, level)) = work.pop() {
        depth = depth.max(level);
        let (children, count) = widest_first_children(bvh2, source);
        let mut node = WideNode::EMPTY;
        for (slot, &child) in children[..count].iter().enumerate() {
            if !node.try_leaf(slot, bvh2, child, exact, &mut scratch, &mut order) {
                node.child[slot] = nodes.len() as u32;
                work.push((nodes.len() as u32, child, level + 1));
                slot_in_parent.push((wide, slot as u8));
                nodes.push(WideNode::EMPTY);
            }
        }
        nodes[wide as usize] = node;
    }
    // A node comes after its parent: filling boxes from the last node up gives every inner
    // child its box before its parent's box is read.
    for index in (1..nodes.len()).rev() {
        let bounds = nodes[index].bounds();
        let (parent, slot) = slot_in_parent[index];
        nodes[parent as usize].set_child_bounds(slot as usize, &bounds);
    }
    Subtree {
        nodes,
        order,
        depth,
    }
}

/// The number of primitives under BVH2 node `node` if it is at most [`MAX_LEAF_PRIMITIVES`],
/// found by visiting at most that many leaves and one fewer inner nodes. `stack` is scratch.
fn small_subtree(bvh2: &Bvh2, node: u32, stack: &mut Vec<u32>) -> Option<u32> {
    stack.clear();
    stack.push(node);
    let (mut primitives, mut inner) = (0, 0);
    while let Some(n) = stack.pop() {
        let n = &bvh2.nodes[n as usize];
        if n.is_leaf() {
            primitives += n.prim_count;
            if primitives > MAX_LEAF_PRIMITIVES {
                return None;
            }
        } else {
            inner += 1;
            if inner >= MAX_LEAF_PRIMITIVES {
                return None;
            }
            stack.extend([n.first_index + 1, n.first_index]);
        }
    }
    Some(primitives)
}

/// Appends the primitives under BVH2 node `node` to `order`, left to right. `stack` is scratch.
fn leaf_primitives(bvh2: &Bvh2, node: u32, stack: &mut Vec<u32>, order: &mut Vec<u32>) {
    stack.clear();
    stack.push(node);
    while let Some(n) = stack.pop() {
        let n = &bvh2.nodes[n as usize];
        if n.is_leaf() {
            let first = n.first_index as usize;
            order.extend_from_slice(&bvh2.primitive_indices[first..first + n.prim_count as usize]);
        } else {
            // Right pushed first: leaves come out left to right.
            stack.extend([n.first_index + 1, n.first_index]);
        }
    }
}

/// The box of a sphere, rounded outward (`center ± radius` in f32 may round inward).
pub fn sphere_box(center: glam::Vec3, radius: f32) -> Aabb {
    let lo = (center - radius).to_array().map(next_float_down);
    let hi = (center + radius).to_array().map(next_float_up);
    Aabb::new(lo.into(), hi.into())
}

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
    rays: usize,
}

/// Most rays in a [`PacketBoxTest`]: two 8-lane registers hold one value of each. 16 rather
/// than 8: the packet's node test is paid once for twice as many rays of one pixel (the
/// dragon, 8 against 16: × 1.058 and × 1.053 in two runs, 1.011 n.s. in a third;
/// docs/performance.md).
pub const PACKET_SIZE: usize = 16;

impl PacketBoxTest {
    /// The packet of `rays`; `None` if there are none or more than [`PACKET_SIZE`], or if they
    /// do not all share their origin and the sign of each direction component (trace those
    /// one by one).
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

    /// Makes `self` [`new`](Self::new)'s packet of the `count` rays `ray_of(0)`, …,
    /// `ray_of(count − 1)`, and returns whether they make one (if not, `self` is left in no
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
fn far_scale() -> f32 {
    1.0 + 2.0 * gamma(3)
}

/// The children of `node` that the ray enters before `t_max`, as a bit mask, and the distances
/// at which it enters them. Written lane-wise over arrays of 8 so that the compiler turns each
/// line into one 8-wide (AVX2) or two 4-wide (SSE2) operations.
#[inline(always)]
fn node_test(node: &WideNode, ray: &RayBoxTest, t_max: f32) -> (u32, [f32; 8]) {
    let mut t_near = [0.0f32; 8];
    let mut t_far = [t_max; 8];
    for axis in 0..3 {
        let near_planes = &node.bounds[ray.near[axis]];
        let far_planes = &node.bounds[ray.near[axis] ^ 1];
        let (o, inv) = (ray.origin[axis], ray.inv_direction[axis]);
        for lane in 0..8 {
            let n = (near_planes[lane] - o) * inv;
            let f = (far_planes[lane] - o) * inv;
            // Comparisons rather than f32::max/min: no NaN arises here, and these compile to
            // single max/min instructions.
            t_near[lane] = if n > t_near[lane] { n } else { t_near[lane] };
            t_far[lane] = if f < t_far[lane] { f } else { t_far[lane] };
        }
    }
    let scale = far_scale();
    let mut mask = 0u32;
    for lane in 0..8 {
        mask |= ((t_near[lane] <= t_far[lane] * scale) as u32) << lane;
    }
    (mask, t_near)
}

/// [`node_test`] for a packet: the children one of its rays may enter before `t_max` (the
/// largest of the rays' bounds), and distances no greater than any of theirs.
#[inline(always)]
fn packet_node_test(node: &WideNode, packet: &PacketBoxTest, t_max: f32) -> (u32, [f32; 8]) {
    let mut t_near = [0.0f32; 8];
    let mut t_far = [t_max; 8];
    for axis in 0..3 {
        let near_planes = &node.bounds[packet.near[axis]];
        let far_planes = &node.bounds[packet.near[axis] ^ 1];
        let o = packet.origin[axis];
        let (low, high) = (packet.inv_low[axis], packet.inv_high[axis]);
        for lane in 0..8 {
            let (near, far) = (near_planes[lane] - o, far_planes[lane] - o);
            let (n_low, n_high) = (near * low, near * high);
            let (f_low, f_high) = (far * low, far * high);
            let n = if n_low < n_high { n_low } else { n_high };
            let f = if f_low > f_high { f_low } else { f_high };
            t_near[lane] = if n > t_near[lane] { n } else { t_near[lane] };
            t_far[lane] = if f < t_far[lane] { f } else { t_far[lane] };
        }
    }
    let scale = far_scale();
    let mut mask = 0u32;
    for lane in 0..8 {
        mask |= ((t_near[lane] <= t_far[lane] * scale) as u32) << lane;
    }
    (mask, t_near)
}

/// The rays of `packet` that enter child `lane` of `node` before their `t_max` (a bit per
/// ray; lanes of `t_max` past the rays must hold a negative bound). Each ray's lane computes
/// what [`node_test`] computes for that ray alone, operation for operation.
#[inline(always)]
fn rays_entering(
    node: &WideNode,
    lane: usize,
    packet: &PacketBoxTest,
    t_max: &[f32; PACKET_SIZE],
) -> u32 {
    let mut t_near = [0.0f32; PACKET_SIZE];
    let mut t_far = *t_max;
    for axis in 0..3 {
        let near_plane = node.bounds[packet.near[axis]][lane] - packet.origin[axis];
        let far_plane = node.bounds[packet.near[axis] ^ 1][lane] - packet.origin[axis];
        let inv = &packet.inv[axis];
        for r in 0..PACKET_SIZE {
            let n = near_plane * inv[r];
            let f = far_plane * inv[r];
            t_near[r] = if n > t_near[r] { n } else { t_near[r] };
            t_far[r] = if f < t_far[r] { f } else { t_far[r] };
        }
    }
    let scale = far_scale();
    let mut mask = 0u32;
    for r in 0..PACKET_SIZE {
        mask |= ((t_near[r] <= t_far[r] * scale) as u32) << r;
    }
    mask
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

/// [`rays_entering`] in AVX intrinsics, the same operations in the same order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn rays_entering_avx2(
    node: &WideNode,
    lane: usize,
    packet: &PacketBoxTest,
    t_max: &[f32; PACKET_SIZE],
) -> u32 {
    use std::arch::x86_64::*;
    let mut mask = 0u32;
    for half in 0..PACKET_SIZE / 8 {
        let at = 8 * half;
        let mut t_near = _mm256_setzero_ps();
        // SAFETY: `t_max` holds PACKET_SIZE f32, a multiple of 8.
        let mut t_far = unsafe { _mm256_loadu_ps(t_max[at..].as_ptr()) };
        for axis in 0..3 {
            let near_plane = node.bounds[packet.near[axis]][lane] - packet.origin[axis];
            let far_plane = node.bounds[packet.near[axis] ^ 1][lane] - packet.origin[axis];
            // SAFETY: each row of `inv` is PACKET_SIZE f32.
            let inv = unsafe { _mm256_loadu_ps(packet.inv[axis][at..].as_ptr()) };
            let n = _mm256_mul_ps(_mm256_set1_ps(near_plane), inv);
            let f = _mm256_mul_ps(_mm256_set1_ps(far_plane), inv);
            t_near = _mm256_max_ps(n, t_near);
            t_far = _mm256_min_ps(f, t_far);
        }
        let far = _mm256_mul_ps(t_far, _mm256_set1_ps(far_scale()));
        mask |= (_mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_near, far)) as u32) << at;
    }
    mask
}

/// [`packet_node_test`] in AVX intrinsics, the same operations in the same order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn packet_node_test_avx2(node: &WideNode, packet: &PacketBoxTest, t_max: f32) -> (u32, [f32; 8]) {
    use std::arch::x86_64::*;
    let mut t_near = _mm256_setzero_ps();
    let mut t_far = _mm256_set1_ps(t_max);
    for axis in 0..3 {
        // SAFETY: each row of `bounds` is 8 f32.
        let (near_planes, far_planes) = unsafe {
            (
                _mm256_loadu_ps(node.bounds[packet.near[axis]].as_ptr()),
                _mm256_loadu_ps(node.bounds[packet.near[axis] ^ 1].as_ptr()),
            )
        };
        let o = _mm256_set1_ps(packet.origin[axis]);
        let low = _mm256_set1_ps(packet.inv_low[axis]);
        let high = _mm256_set1_ps(packet.inv_high[axis]);
        let (near, far) = (_mm256_sub_ps(near_planes, o), _mm256_sub_ps(far_planes, o));
        let n = _mm256_min_ps(_mm256_mul_ps(near, low), _mm256_mul_ps(near, high));
        let f = _mm256_max_ps(_mm256_mul_ps(far, low), _mm256_mul_ps(far, high));
        t_near = _mm256_max_ps(n, t_near);
        t_far = _mm256_min_ps(f, t_far);
    }
    let far = _mm256_mul_ps(t_far, _mm256_set1_ps(far_scale()));
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_near, far)) as u32;
    let mut near = [0.0f32; 8];
    // SAFETY: `near` holds 8 f32.
    unsafe { _mm256_storeu_ps(near.as_mut_ptr(), t_near) };
    (mask, near)
}

/// [`node_test`] in AVX intrinsics: the same operations in the same order (so the same
/// results, bit for bit), without the shuffles the compiler adds when it vectorises the
/// portable form.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn node_test_avx2(node: &WideNode, ray: &RayBoxTest, t_max: f32) -> (u32, [f32; 8]) {
    use std::arch::x86_64::*;
    let mut t_near = _mm256_setzero_ps();
    let mut t_far = _mm256_set1_ps(t_max);
    for axis in 0..3 {
        // SAFETY: each row of `bounds` is 8 f32.
        let (near_planes, far_planes) = unsafe {
            (
                _mm256_loadu_ps(node.bounds[ray.near[axis]].as_ptr()),
                _mm256_loadu_ps(node.bounds[ray.near[axis] ^ 1].as_ptr()),
            )
        };
        let o = _mm256_set1_ps(ray.origin[axis]);
        let inv = _mm256_set1_ps(ray.inv_direction[axis]);
        let n = _mm256_mul_ps(_mm256_sub_ps(near_planes, o), inv);
        let f = _mm256_mul_ps(_mm256_sub_ps(far_planes, o), inv);
        // max_ps(a, b) is `a > b ? a : b`, min_ps(a, b) `a < b ? a : b`, as in node_test.
        t_near = _mm256_max_ps(n, t_near);
        t_far = _mm256_min_ps(f, t_far);
    }
    let far = _mm256_mul_ps(t_far, _mm256_set1_ps(far_scale()));
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_near, far)) as u32;
    let mut near = [0.0f32; 8];
    // SAFETY: `near` holds 8 f32.
    unsafe { _mm256_storeu_ps(near.as_mut_ptr(), t_near) };
    (mask, near)
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

/// The value of `values` that no other one `replaces`, found as a tree of comparisons (lanes
/// half the array apart, then a quarter, ...), which compiles to a few vector minima or maxima.
/// Where two compare equal, the lower lane's is kept.
#[inline(always)]
fn extreme(mut values: [f32; PACKET_SIZE], replaces: impl Fn(f32, f32) -> bool) -> f32 {
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
    use glam::{Vec3, Vec3A};

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
        let (bvh, order) = WideBvh::build(&boxes, 1.0);
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

    /// The AVX2 node test gives the portable one's answers bit for bit (random boxes, empty
    /// slots, rays with zero direction components).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_avx2_node_test_equals_the_portable_one() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
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
            // SAFETY: AVX2 is present (checked above).
            let (mask_avx2, near_avx2) = unsafe { node_test_avx2(&node, &test, t_max) };
            assert_eq!(mask, mask_avx2);
            assert_eq!(near.map(f32::to_bits), near_avx2.map(f32::to_bits));
        }
    }

    /// A packet's node test lets through every child one of its rays' own test lets through,
    /// at a distance no greater than the ray's (so the packet visits every node its rays
    /// would); the rays found entering a child are those whose own test enters it; the AVX2
    /// forms give the portable ones' answers bit for bit. Random boxes,
    /// empty slots, packets from tight (one pixel) to wide, zero direction components.
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
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 is present (checked just above).
                let (mask_avx2, near_avx2) =
                    unsafe { packet_node_test_avx2(&node, &packet, packet_t_max) };
                assert_eq!(mask, mask_avx2);
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
