//! Building the BVH that [`crate::accel::Geometry`] traverses, on any input: a binary BVH
//! (obvhs's PLOC, or binned SAH below) collapsed into [`WideBvh`]'s 8-wide nodes.
//!
//! obvhs's PLOC builder gives good trees fast on ordinary meshes, but on heavily overlapping
//! primitives (a fan of thin triangles sharing a vertex, as in a disk or a cylinder cap) it makes
//! trees whose depth grows linearly with the primitive count, in time that grows about
//! quadratically (a 65 536-triangle fan: depth 101, 17 s; 262 144: minutes). The traversal
//! ([`crate::wide_bvh`]) has a fixed stack sized for trees shallower than 32 levels, as obvhs's
//! own (which silently drops nodes past it in release builds). So:
//! - inputs whose primitive boxes overlap far more than a surface's do are built top-down with
//!   binned SAH, whose depth is bounded (below);
//! - every PLOC tree's depth is measured, and one as deep as the traversal stack is rebuilt the
//!   same way.

use crate::wide_bvh::WideBvh;
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::ploc::PlocBuilder;
use rayon::prelude::*;

/// Trees must be shallower than this: the traversal's stack ([`crate::wide_bvh`]) is sized for
/// it (as obvhs's, `cwbvh::TRAVERSAL_STACK_SIZE`).
pub(crate) const TRAVERSAL_STACK_SIZE: usize = 32;

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
            pool.install(|| build(&boxes, 1.0))
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
            let (bvh, order, builder) = build(&fan(n), 1.0);
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
        let (bvh, _, builder) = build(&tris, 1.0);
        assert_eq!(builder, Builder::Ploc);
        assert!(bvh.depth() < TRAVERSAL_STACK_SIZE);
    }
}
