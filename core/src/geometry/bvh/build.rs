//! Building the BVH on any input: a binary BVH (obvhs's PLOC, or binned SAH below) collapsed
//! into [`WideBvh`]'s 8-wide nodes.
//!
//! obvhs's PLOC builder gives good trees fast on ordinary meshes, but on heavily overlapping
//! primitives (a fan of thin triangles sharing a vertex, as in a disk or a cylinder cap) it makes
//! trees whose depth grows linearly with the primitive count, in time that grows about
//! quadratically (a 65 536-triangle fan: depth 101, 17 s; 262 144: minutes). The traversal
//! ([`super::traverse`]) has a fixed stack sized for trees shallower than 32 levels, as obvhs's
//! own (which silently drops nodes past it in release builds). So:
//! - inputs whose primitive boxes overlap far more than a surface's do are built top-down with
//!   binned SAH, whose depth is bounded (below);
//! - every PLOC tree's depth is measured, and one as deep as the traversal stack is rebuilt the
//!   same way.

use super::{EMPTY, LEAF, MAX_LEAF_PRIMITIVES, TRAVERSAL_STACK_SIZE, WideBvh, WideNode};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::ploc::PlocBuilder;
use rayon::prelude::*;

/// Depth the top-down builder keeps its BVH2 within (the 8-wide tree is never deeper than the
/// BVH2 it collapses), leaving a margin below [`TRAVERSAL_STACK_SIZE`].
const MAX_BVH2_DEPTH: usize = TRAVERSAL_STACK_SIZE - 2;

/// Above this ratio of the summed half-areas of the primitives' boxes to the scene box's, boxes
/// overlap like a fan's, where PLOC is slow and deep: the top-down builder is used. Surfaces
/// stay far below it: each unit of surface area adds at most about one unit of box half-area,
/// and a closed surface has at most a few times its box's area (the repository's scenes and
/// meshes: below 3); a fan of n triangles reaches about n/16.
const OVERLAP_LIMIT: f32 = 64.0;

/// Which builder made a tree (for tests and statistics).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Builder {
    Ploc,
    BinnedSah,
}

impl WideBvh {
    /// Builds the 8-wide BVH over primitives with the boxes `exact` (obvhs builds on the boxes ×
    /// `scale`, a power of two); its depth is below [`TRAVERSAL_STACK_SIZE`]. Returns it, the
    /// primitives' leaf order (leaf slot `j` holds primitive `order[j]`) and the builder used.
    pub fn build(exact: &[Aabb], scale: f32) -> (WideBvh, Vec<u32>, Builder) {
        let scaled: Vec<Aabb> = exact
            .par_iter()
            .map(|b| Aabb::new(b.min * scale, b.max * scale))
            .collect();
        if !heavily_overlapping(&scaled) {
            // obvhs's `medium_build` preset without its conversion to a compressed CWBVH.
            let params = BvhBuildParams::medium_build();
            let mut bvh2 = PlocBuilder::with_capacity(scaled.len()).build(
                params.ploc_search_distance,
                &scaled,
                (0..scaled.len() as u32).collect(),
                params.sort_precision,
                params.search_depth_threshold,
            );
            ReinsertionOptimizer::default().run(&mut bvh2, params.reinsertion_batch_ratio, None);
            let (bvh, order, depth) = WideBvh::collapse(&bvh2, exact);
            if depth < TRAVERSAL_STACK_SIZE {
                return (bvh, order, Builder::Ploc);
            }
        }
        let (bvh, order, _) = WideBvh::collapse(&binned_sah_bvh2(&scaled), exact);
        (bvh, order, Builder::BinnedSah)
    }

    /// Collapses `bvh2` (one primitive per leaf, as both builders above make)
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
    fn collapse(bvh2: &Bvh2, exact: &[Aabb]) -> (Self, Vec<u32>, usize) {
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
}

fn heavily_overlapping(aabbs: &[Aabb]) -> bool {
    let total = aabbs.iter().fold(Aabb::empty(), |a, b| a.union(b));
    let scene = total.half_area() as f64;
    let sum: f64 = aabbs.iter().map(|a| a.half_area() as f64).sum();
    // A flat scene (zero area box) cannot overlap much; its sum is also zero then.
    scene > 0.0 && sum > OVERLAP_LIMIT as f64 * scene
}

/// Number of bins per axis of the SAH sweep (Wald 2007 uses 16 to 32; more buys little).
const BINS: usize = 16;

/// A top-down BVH2 with one primitive per leaf, split by binned SAH on the centroids (Wald,
/// "On fast construction of SAH-based bounding volume hierarchies", 2007), or at the median of
/// the widest centroid axis wherever SAH could make the tree deeper than [`MAX_BVH2_DEPTH`]
/// (the median halves the count, so at depth d a node of n primitives needs ⌈log₂ n⌉ more
/// levels, and is split so from the depth where that would no longer fit). Iterative: no
/// recursion depth to overflow.
fn binned_sah_bvh2(aabbs: &[Aabb]) -> Bvh2 {
    let n = aabbs.len();
    if n == 0 {
        return Bvh2::default();
    }
    let centroids: Vec<[f32; 3]> = aabbs.iter().map(|a| a.center().to_array()).collect();
    let mut indices: Vec<u32> = (0..n as u32).collect();
    let mut nodes = Vec::with_capacity(2 * n - 1);
    nodes.push(Bvh2Node::default());
    let mut stack = vec![(0usize, 0usize, n, 0usize)];
    while let Some((node, start, end, depth)) = stack.pop() {
        let range = &mut indices[start..end];
        let bounds = range
            .iter()
            .fold(Aabb::empty(), |b, &i| b.union(&aabbs[i as usize]));
        let count = end - start;
        if count == 1 {
            nodes[node] = Bvh2Node::new(bounds, 1, start as u32);
            continue;
        }
        let levels_needed = count.next_power_of_two().trailing_zeros() as usize;
        let split = if depth + levels_needed >= MAX_BVH2_DEPTH {
            None
        } else {
            sah_split(range, aabbs, &centroids)
        };
        let mid = match split {
            Some(mid) if mid > 0 && mid < count => mid,
            _ => median_split(range, &centroids),
        };
        let left = nodes.len();
        nodes.push(Bvh2Node::default());
        nodes.push(Bvh2Node::default());
        nodes[node] = Bvh2Node::new(bounds, 0, left as u32);
        stack.push((left, start, start + mid, depth + 1));
        stack.push((left + 1, start + mid, end, depth + 1));
    }
    Bvh2 {
        nodes,
        primitive_indices: indices,
        ..Bvh2::default()
    }
}

/// Bounds of the centroids of `range`.
fn centroid_bounds(range: &[u32], centroids: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for &i in range {
        let c = centroids[i as usize];
        for a in 0..3 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    (lo, hi)
}

/// Partitions `range` at the best binned-SAH plane; returns the size of the left part, or
/// `None` when the centroids coincide (no plane separates them).
fn sah_split(range: &mut [u32], aabbs: &[Aabb], centroids: &[[f32; 3]]) -> Option<usize> {
    let (lo, hi) = centroid_bounds(range, centroids);
    let mut best: Option<(f64, usize, usize)> = None; // (cost, axis, bins on the left)
    for axis in 0..3 {
        let extent = hi[axis] - lo[axis];
        if extent <= 0.0 {
            continue;
        }
        let scale = BINS as f32 / extent;
        let bin_of =
            |i: u32| (((centroids[i as usize][axis] - lo[axis]) * scale) as usize).min(BINS - 1);
        let mut counts = [0usize; BINS];
        let mut boxes = [Aabb::empty(); BINS];
        for &i in range.iter() {
            let b = bin_of(i);
            counts[b] += 1;
            boxes[b] = boxes[b].union(&aabbs[i as usize]);
        }
        // Sweep from the right: area × count of every suffix of bins.
        let mut right_cost = [0.0f64; BINS];
        let (mut box_r, mut count_r) = (Aabb::empty(), 0usize);
        for b in (1..BINS).rev() {
            box_r = box_r.union(&boxes[b]);
            count_r += counts[b];
            right_cost[b] = if count_r > 0 {
                box_r.half_area() as f64 * count_r as f64
            } else {
                0.0
            };
        }
        let (mut box_l, mut count_l) = (Aabb::empty(), 0usize);
        for b in 0..BINS - 1 {
            box_l = box_l.union(&boxes[b]);
            count_l += counts[b];
            if count_l == 0 || count_l == range.len() {
                continue;
            }
            let cost = box_l.half_area() as f64 * count_l as f64 + right_cost[b + 1];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b + 1));
            }
        }
    }
    let (_, axis, left_bins) = best?;
    let scale = BINS as f32 / (hi[axis] - lo[axis]);
    let goes_left = |i: &u32| {
        let b = (((centroids[*i as usize][axis] - lo[axis]) * scale) as usize).min(BINS - 1);
        b < left_bins
    };
    // In-place partition.
    let mut mid = 0;
    for j in 0..range.len() {
        if goes_left(&range[j]) {
            range.swap(mid, j);
            mid += 1;
        }
    }
    Some(mid)
}

/// Splits `range` in half at the median centroid of its widest axis (in index order if the
/// centroids coincide); returns the size of the left half.
fn median_split(range: &mut [u32], centroids: &[[f32; 3]]) -> usize {
    let (lo, hi) = centroid_bounds(range, centroids);
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(0);
    let mid = range.len() / 2;
    range.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
    });
    mid
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    /// The boxes of a fan of `n` thin triangles around the origin, as the built-in disk.
    fn fan(n: usize) -> Vec<Aabb> {
        (0..n)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / n as f32;
                let b = std::f32::consts::TAU * ((i + 1) % n) as f32 / n as f32;
                obvhs::triangle::Triangle {
                    v0: Vec3A::ZERO,
                    v1: Vec3A::new(a.cos(), a.sin(), 0.0),
                    v2: Vec3A::new(b.cos(), b.sin(), 0.0),
                }
                .aabb()
            })
            .collect()
    }

    /// obvhs's parallel build splits its work by the number of threads above 300 000 to
    /// 500 000 primitives; the tree must not depend on it, or an image would depend on the
    /// machine that loaded the scene (the build runs in the global pool, not the render's).
    #[test]
    fn the_tree_does_not_depend_on_the_number_of_threads() {
        let mut sampler = crate::sampler::Sampler::new(7, 0, 0);
        let mut unit = || sampler.next_1d();
        let boxes: Vec<Aabb> = (0..600_000)
            .map(|_| {
                let lo = Vec3A::new(unit(), unit(), unit()) * 100.0;
                Aabb::new(lo, lo + Vec3A::new(unit(), unit(), unit()))
            })
            .collect();
        let build_with = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| WideBvh::build(&boxes, 1.0))
        };
        let (bvh, order, builder) = build_with(1);
        assert_eq!(builder, Builder::Ploc);
        for threads in [2, 3, 8] {
            let (other, other_order, _) = build_with(threads);
            assert!(
                other_order == order,
                "{threads} threads: another leaf order"
            );
            assert!(other == bvh, "{threads} threads: other nodes");
        }
    }

    #[test]
    fn fans_get_shallow_trees_quickly() {
        // PLOC: depth 46 at 16 384 triangles, 101 at 65 536 (about 17 s).
        for n in [4096, 65536] {
            let start = std::time::Instant::now();
            let (bvh, order, builder) = WideBvh::build(&fan(n), 1.0);
            assert_eq!(builder, Builder::BinnedSah, "{n}");
            assert!(bvh.depth() < TRAVERSAL_STACK_SIZE, "{n}: {}", bvh.depth());
            assert_eq!(order.len(), n);
            // Generous for a loaded test machine: the build takes about 0.05 s.
            assert!(
                start.elapsed().as_secs_f64() < 5.0,
                "{n}: {:?}",
                start.elapsed()
            );
        }
    }

    #[test]
    fn the_depth_bound_holds_where_sah_would_make_a_chain() {
        // Boxes of doubling size nested around one corner: SAH peels one off per level.
        let nested: Vec<Aabb> = (0..200)
            .map(|i| Aabb::new(Vec3A::ZERO, Vec3A::splat(1.2f32.powi(i % 120))))
            .collect();
        let (bvh, order, depth) = WideBvh::collapse(&binned_sah_bvh2(&nested), &nested);
        assert!(depth < TRAVERSAL_STACK_SIZE, "{depth}");
        assert_eq!(bvh.depth(), depth);
        let mut seen = order;
        seen.sort_unstable();
        assert_eq!(seen, (0..200).collect::<Vec<u32>>());
    }

    #[test]
    fn ordinary_surfaces_keep_ploc() {
        // A 64 × 64 grid of small triangles: boxes that barely overlap.
        let mut tris = Vec::new();
        for y in 0..64 {
            for x in 0..64 {
                let p = Vec3A::new(x as f32, y as f32, 0.0);
                tris.push(
                    obvhs::triangle::Triangle {
                        v0: p,
                        v1: p + Vec3A::X,
                        v2: p + Vec3A::Y,
                    }
                    .aabb(),
                );
            }
        }
        let (bvh, _, builder) = WideBvh::build(&tris, 1.0);
        assert_eq!(builder, Builder::Ploc);
        assert!(bvh.depth() < TRAVERSAL_STACK_SIZE);
    }
}
