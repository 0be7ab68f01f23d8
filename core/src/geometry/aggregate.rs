//! The scene's surfaces and the BVH over their primitives ([`Geometry`]), and the ray queries
//! over them: the closest hit, a packet's closest hits, occlusion, and queries about one shape.

use super::bvh::node_test::{PacketBoxTest, RayBoxTest};
use super::bvh::{PACKET_SIZE, WideBvh};
use super::may_meet::{may_meet_box, padded};
use super::packet::{Alone, PacketShear, triangle_hits};
use super::primitive::Primitive;
use super::ray::{Intersection, Ray, read_coordinates};
use super::shapes::{ShapeGeometry, unit_normal_a, unit_normals_a};
use super::triangle::RayShear;
use super::uv::UvMapping;
use crate::limits::MAX_COORDINATE;
use crate::math::gamma;
use glam::{Vec2, Vec3, Vec3A};
use obvhs::Boundable;
use obvhs::aabb::Aabb;
use rayon::prelude::*;
use std::cell::Cell;

thread_local! {
    static RAYS_TRACED: Cell<u64> = const { Cell::new(0) };
}

/// Number of ray queries made by the calling thread since the last call (for statistics; a
/// thread-local counter costs no lock).
pub fn take_ray_count() -> u64 {
    RAYS_TRACED.with(|c| c.replace(0))
}

#[inline]
fn count_rays(n: u64) {
    RAYS_TRACED.with(|c| c.set(c.get() + n));
}

/// The closest primitive a ray meets, as [`Geometry::first_hit`] finds it.
#[derive(Clone, Copy, Debug)]
pub struct FirstHit {
    pub t: f32,
    /// Index of the shape in the scene.
    pub shape: u32,
    /// The primitive's slot in the BVH's leaf order.
    slot: u32,
    /// Of a triangle; unused for spheres.
    barycentrics: [f32; 3],
}

/// Bytes the BVH build needs per primitive at its peak: the `Primitive` list twice, the BVH2
/// and its build buffers, the 8-wide nodes. Measured peaks when obvhs still converted to its
/// CWBVH (and built its conversion tables, 7 entries per BVH2 node, now gone): 277 (PLOC, a
/// 202 520-triangle dragon) and 308 (top-down, a 1 048 576-triangle disk), with the mesh itself
/// counted apart; not re-measured since, so the bound is kept.
pub const BVH_BYTES_PER_PRIMITIVE: u64 = 320;

/// The scene's surfaces and the BVH over them.
pub struct Geometry {
    pub(super) shapes: Vec<ShapeGeometry>,
    /// Primitives in BVH leaf order.
    primitives: Vec<Primitive>,
    bvh: WideBvh,
    /// Per shape: its bounding box, padded for [`Geometry::may_meet`] (empty for a shape with no
    /// primitive).
    shape_boxes: Vec<[Vec3; 2]>,
    /// Per shape: how its points map to texture coordinates ([`Geometry::uv`]).
    pub(super) uv_mappings: Vec<UvMapping>,
}

/// Size (largest extent) the scene has in the BVH's space, a power of two.
const BVH_SCENE_SIZE_LOG2: i32 = 10;

/// The power of two that scales a scene whose boxes span `total` to about 2^10 in the space
/// obvhs builds in: its builder and its CWBVH quantisation are tuned for scenes of ordinary
/// size (obvhs's own traversal also skipped every node before an absolute t = 1e-4). A power of
/// two scales coordinates exactly; the traversal uses the unscaled, exact boxes.
fn bvh_scale(total: &Aabb) -> f32 {
    let extent = (total.max - total.min).max_element();
    if !(extent > 0.0 && extent.is_finite()) {
        return 1.0;
    }
    let e = BVH_SCENE_SIZE_LOG2 - extent.log2().ceil() as i32;
    2f32.powi(e.clamp(-100, 100))
}

impl Geometry {
    /// Builds the BVH over every triangle and sphere of `shapes` (indexed as given).
    ///
    /// # Panics
    /// If a shape is not [`ShapeGeometry::within_coordinate_limit`] (the BVH builder would fail
    /// on it, e.g. on sizes around 1e19): the scene loader checks every shape first and reports
    /// it.
    pub fn new(shapes: Vec<ShapeGeometry>) -> Self {
        for (i, shape) in shapes.iter().enumerate() {
            assert!(
                shape.within_coordinate_limit(),
                "Geometry::new: shape {i} has a coordinate not finite or beyond ±{MAX_COORDINATE}"
            );
        }
        let capacity = shapes.iter().map(|s| match s {
            ShapeGeometry::Mesh(mesh) => mesh.indices.len(),
            ShapeGeometry::Sphere(_) => 1,
        });
        let mut prims = Vec::with_capacity(capacity.sum());
        for (shape_index, geometry) in shapes.iter().enumerate() {
            let shape = shape_index as u32;
            match geometry {
                ShapeGeometry::Mesh(mesh) => {
                    for i in 0..mesh.indices.len() {
                        let p = mesh.triangle(i);
                        // Degenerate triangles can never be hit; keep them out of the tree.
                        if (p[1] - p[0]).cross(p[2] - p[0]) != Vec3::ZERO {
                            prims.push(Primitive::Triangle {
                                p,
                                shape,
                                index: i as u32,
                            });
                        }
                    }
                }
                ShapeGeometry::Sphere(sphere) => prims.push(Primitive::Sphere {
                    sphere: *sphere,
                    shape,
                }),
            }
        }
        let boxes: Vec<Aabb> = prims.par_iter().map(Boundable::aabb).collect();
        let total = boxes.iter().fold(Aabb::empty(), |a, b| a.union(b));
        let scale = bvh_scale(&total);
        let mut shape_boxes = vec![[Vec3::INFINITY, Vec3::NEG_INFINITY]; shapes.len()];
        for (prim, bounds) in prims.iter().zip(&boxes) {
            let (Primitive::Triangle { shape, .. } | Primitive::Sphere { shape, .. }) = prim;
            let [lo, hi] = &mut shape_boxes[*shape as usize];
            *lo = lo.min(bounds.min.into());
            *hi = hi.max(bounds.max.into());
        }
        for [lo, hi] in shape_boxes
            .iter_mut()
            .filter(|[lo, hi]| lo.cmple(*hi).all())
        {
            (*lo, *hi) = padded(*lo, *hi);
        }
        let (bvh, order, _) = WideBvh::build(&boxes, scale);
        let mut primitives = crate::huge_pages::vec_with_capacity(order.len());
        primitives.par_extend(order.par_iter().map(|&i| prims[i as usize]));
        Geometry {
            uv_mappings: vec![UvMapping::Intrinsic; shapes.len()],
            shapes,
            primitives,
            bvh,
            shape_boxes,
        }
    }

    /// Whether `ray` may meet shape `shape` before its `t_max`: false only when it passes clear
    /// of the shape's padded bounding box, so that a query about one shape (does a BSDF ray
    /// drawn for a light reach it?) can skip the traversal for most rays. Never false for a ray
    /// on which [`Geometry::first_hit`] or [`Geometry::occluded`] could find that shape.
    pub fn may_meet(&self, ray: &Ray, shape: u32) -> bool {
        let [lo, hi] = self.shape_boxes[shape as usize];
        may_meet_box(ray, lo, hi)
    }

    pub fn shapes(&self) -> &[ShapeGeometry] {
        &self.shapes
    }

    /// The closest intersection along the ray, if any.
    pub fn intersect(&self, ray: &Ray) -> Option<Intersection> {
        self.first_hit(ray).map(|hit| self.surface(ray, &hit))
    }

    /// The closest primitive along the ray, without the surface's details: enough to tell which
    /// shape it is (e.g. whether a BSDF ray reached the light it was drawn for) before paying
    /// for the position, error bounds and normals with [`Geometry::surface`].
    pub fn first_hit(&self, ray: &Ray) -> Option<FirstHit> {
        self.closest_hit_among(ray, |_| true)
    }

    /// [`Geometry::first_hit`] for a ray leaving surface point `from`, without testing the
    /// triangle `from` lies on, which it cannot meet ([`Primitive::is_triangle_under`]).
    pub fn first_hit_leaving(&self, ray: &Ray, from: &Intersection) -> Option<FirstHit> {
        self.closest_hit_among(ray, |primitive| !primitive.is_triangle_under(from))
    }

    /// The closest hit on shape `shape` along the ray, every other shape ignored, as if it were
    /// alone in the scene: where light sampling could have drawn the direction of a BSDF ray
    /// that something else blocked. The same traversal and primitive tests as
    /// [`Geometry::first_hit`], so a ray that reaches the shape finds the same hit either way.
    pub fn first_hit_on_shape(&self, ray: &Ray, shape: u32) -> Option<FirstHit> {
        if !self.may_meet(ray, shape) {
            return None;
        }
        self.closest_hit_among(ray, |primitive| primitive.shape() == shape)
    }

    /// The closest hit along the ray among the primitives `counts` accepts.
    #[inline(always)]
    fn closest_hit_among(
        &self,
        ray: &Ray,
        counts: impl Fn(&Primitive) -> bool,
    ) -> Option<FirstHit> {
        count_rays(1);
        if self.primitives.is_empty() {
            return None;
        }
        let shear = RayShear::new(ray.direction);
        let boxes = RayBoxTest::new(ray.origin, ray.direction);
        // Of the closest hit so far (the traversal's last accepted primitive).
        let (mut t_hit, mut barycentrics) = (ray.t_max, [0.0; 3]);
        // The primitive tests are inlined into the traversal kernels: left to itself LLVM kept
        // them out of line in the AVX2 kernels, a call per primitive (2.5-4 % of a render's
        // instructions).
        let slot = self.bvh.closest_hit(
            &boxes,
            ray.t_max,
            #[inline(always)]
            |slot, t_max| {
                let primitive = &self.primitives[slot];
                if !counts(primitive) {
                    return None;
                }
                let (t, b) = primitive.hit(ray, &shear, t_max)?;
                (t_hit, barycentrics) = (t, b);
                Some(t)
            },
        )?;
        Some(FirstHit {
            t: t_hit,
            shape: self.primitives[slot].shape(),
            slot: slot as u32,
            barycentrics,
        })
    }

    /// The closest intersections along rays that share an origin, such as a pinhole camera's
    /// rays through neighbouring pixels: `hits[i]` is what [`Geometry::intersect`] returns for `rays[i]`,
    /// found by traversing the BVH once for up to [`PACKET_SIZE`] rays
    /// (`WideBvh::closest_hit_packet`). Each ray tests every primitive its own traversal
    /// would test before reaching its closest hit, so it finds that hit; only where two
    /// primitives are hit at exactly the same distance may the other order of the nodes give
    /// the other one. Rays that do not share an origin and direction signs are traced one by
    /// one.
    pub fn intersect_packet(&self, rays: &[Ray], hits: &mut [Option<Intersection>]) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        for (rays, hits) in rays.chunks(PACKET_SIZE).zip(hits.chunks_mut(PACKET_SIZE)) {
            let mut first_hits = [None; PACKET_SIZE];
            let first_hits = &mut first_hits[..rays.len()];
            self.first_hits(rays, first_hits);
            let mut normals = [Vec3A::ZERO; PACKET_SIZE];
            let normals = &mut normals[..rays.len()];
            self.triangle_normals(first_hits, normals);
            let surfaces = hits
                .iter_mut()
                .zip(first_hits.iter())
                .zip(rays)
                .zip(normals);
            for (((hit, first), ray), &mut normal) in surfaces {
                *hit = first.map(|first| self.surface_in_place(ray, &first, Some(normal)));
            }
        }
    }

    /// [`Geometry::first_hit`] for each of at most [`PACKET_SIZE`] rays, as one packet if they
    /// share an origin and direction signs.
    fn first_hits(&self, rays: &[Ray], hits: &mut [Option<FirstHit>]) {
        let n = rays.len();
        // Built in place (`PacketBoxTest::set`).
        let mut packet = PacketBoxTest::EMPTY;
        let is_packet = n > 1
            && !self.primitives.is_empty()
            && packet.set(n, |i| RayBoxTest::new(rays[i].origin, rays[i].direction));
        if !is_packet {
            for (hit, ray) in hits.iter_mut().zip(rays) {
                *hit = self.first_hit(ray);
            }
            return;
        }
        count_rays(n as u64);
        // Lanes past the rays repeat the last one. Made in place, as `packet` is.
        let mut shears = [RayShear::new(rays[n - 1].direction); PACKET_SIZE];
        for (shear, ray) in shears.iter_mut().zip(&rays[..n - 1]) {
            *shear = RayShear::new(ray.direction);
        }
        let mut t_max: [f32; PACKET_SIZE] = std::array::from_fn(|i| rays[i.min(n - 1)].t_max);
        let mut barycentrics = [[0.0; 3]; PACKET_SIZE];
        let mut closest = [None; PACKET_SIZE];
        let packet_shear = PacketShear::new(&shears);
        let origin = rays[0].origin;
        self.bvh.closest_hit_packet(
            &packet,
            &mut t_max,
            &mut closest,
            // Inlined, as in `closest_hit_among`.
            #[inline(always)]
            |slot, rays_in, t_max| {
                let primitive = &self.primitives[slot];
                let alone = Alone {
                    primitive,
                    rays,
                    shears: &shears,
                };
                // In lanes where several rays meet the triangle (a mesh's small triangles are
                // mostly met by one or two rays of a pixel, and the lanes cost more there).
                if rays_in.count_ones() >= 3
                    && let (Primitive::Triangle { p, .. }, Some(shear)) = (primitive, &packet_shear)
                {
                    return triangle_hits(
                        p,
                        origin,
                        shear,
                        rays_in,
                        t_max,
                        &mut barycentrics,
                        alone,
                    );
                }
                let (mut hits, mut left) = (0, rays_in);
                while left != 0 {
                    let r = left.trailing_zeros() as usize;
                    left &= left - 1;
                    if let Some((t, b)) = alone.hit(r, t_max[r]) {
                        (t_max[r], barycentrics[r]) = (t, b);
                        hits |= 1 << r;
                    }
                }
                hits
            },
        );
        for (r, hit) in hits.iter_mut().enumerate() {
            *hit = closest[r].map(|slot| FirstHit {
                t: t_max[r],
                shape: self.primitives[slot].shape(),
                slot: slot as u32,
                barycentrics: barycentrics[r],
            });
        }
    }

    /// The unit geometric normals of the triangles that `hits` met, computed together
    /// ([`unit_normals_a`]); zero for a miss or a sphere.
    fn triangle_normals(&self, hits: &[Option<FirstHit>], normals: &mut [Vec3A]) {
        for (normal, hit) in normals.iter_mut().zip(hits) {
            if let Some(hit) = hit
                && let Primitive::Triangle { p, .. } = &self.primitives[hit.slot as usize]
            {
                // Each vertex read from the primitive itself: `p.map` copied them to the stack
                // first, and read them back in lanes across the copy's stores.
                let vertex = |i: usize| Vec3A::from(p[i]);
                *normal = (vertex(1) - vertex(0)).cross(vertex(2) - vertex(0));
            }
        }
        unit_normals_a(normals);
    }

    /// The intersection record of a hit [`Geometry::first_hit`] found along `ray`.
    pub fn surface(&self, ray: &Ray, hit: &FirstHit) -> Intersection {
        self.surface_in_place(ray, hit, None)
    }

    /// [`surface`](Self::surface), inlined where a packet's records are kept: returned from a
    /// call, each was copied there in wider reads than its stores, which waited for them. A
    /// triangle's unit geometric normal is `triangle_normal` where the caller computed it.
    #[inline(always)]
    fn surface_in_place(
        &self,
        ray: &Ray,
        hit: &FirstHit,
        triangle_normal: Option<Vec3A>,
    ) -> Intersection {
        let t = hit.t;
        match self.primitives[hit.slot as usize] {
            Primitive::Triangle { p, shape, index } => {
                let [b0, b1, b2] = hit.barycentrics;
                // In SIMD lanes (Vec3A): the same operations per coordinate, rounded alike.
                let [p0, p1, p2] = p.map(Vec3A::from);
                let (q0, q1, q2) = (b0 * p0, b1 * p1, b2 * p2);
                let position = Vec3::from(q0 + q1 + q2);
                let error = Vec3::from(gamma(7) * (q0.abs() + q1.abs() + q2.abs()));
                let geometric_normal =
                    triangle_normal.unwrap_or_else(|| unit_normal_a((p1 - p0).cross(p2 - p0)));
                let mut shading_normal = geometric_normal;
                if let ShapeGeometry::Mesh(mesh) = &self.shapes[shape as usize]
                    && let Some(normals) = &mesh.normals
                {
                    let [i0, i1, i2] = mesh.indices[index as usize];
                    let normal = |i: u32| Vec3A::from(normals[i as usize]);
                    let n = b0 * normal(i0) + b1 * normal(i1) + b2 * normal(i2);
                    if let Some(n) = n.try_normalize() {
                        shading_normal = if n.dot(geometric_normal) < 0.0 { -n } else { n };
                    }
                }
                let (geometric_normal, shading_normal) =
                    (Vec3::from(geometric_normal), Vec3::from(shading_normal));
                Intersection {
                    t,
                    position,
                    error,
                    geometric_normal,
                    shading_normal,
                    shape,
                    primitive: index,
                }
            }
            Primitive::Sphere { sphere, shape } => {
                let raw = ray.origin + t * ray.direction;
                let v = raw - sphere.center;
                let n = v.normalize();
                // Reproject onto the sphere, which bounds the error by a few ulps of |v|.
                let position = sphere.center + n * sphere.radius;
                let error = gamma(5) * (n * sphere.radius).abs() + gamma(1) * position.abs();
                Intersection {
                    t,
                    position,
                    error,
                    geometric_normal: n,
                    shading_normal: n,
                    shape,
                    primitive: 0,
                }
            }
        }
    }

    /// Whether anything blocks the ray before `t_max`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.blocked_by(ray, true, |_| true)
    }

    /// Whether anything but shape `ignored` blocks the ray before `t_max`: for a shadow ray
    /// toward a point that shape cannot hide (see
    /// [`Emitter::own_shape_never_blocks_samples`](crate::emitter::Emitter::own_shape_never_blocks_samples)).
    /// A ray `leaving` a surface point is not tested against the triangle under that point,
    /// which it cannot meet ([`Primitive::is_triangle_under`]).
    #[inline]
    pub fn occluded_by_others(
        &self,
        ray: &Ray,
        ignored: Option<u32>,
        leaving: Option<&Intersection>,
    ) -> bool {
        let counts =
            |primitive: &Primitive| !leaving.is_some_and(|from| primitive.is_triangle_under(from));
        match ignored {
            None => self.blocked_by(ray, true, counts),
            // Inlined into the caller, which most often holds the ray in registers.
            Some(ignored) => self.blocked_by(ray, false, |primitive| {
                primitive.shape() != ignored && counts(primitive)
            }),
        }
    }

    /// Whether a primitive that `counts` blocks the ray before `t_max`. With `fresh` (behind a
    /// call, where the ray was just written) the traversal is set up from the ray's coordinates
    /// read one by one ([`read_coordinates`]); the primitive tests, later, read the ray itself.
    #[inline(always)]
    fn blocked_by(&self, ray: &Ray, fresh: bool, counts: impl Fn(&Primitive) -> bool) -> bool {
        count_rays(1);
        if self.primitives.is_empty() {
            return false;
        }
        let (origin, direction) = if fresh {
            let origin = Vec3::from(read_coordinates(&ray.origin));
            (origin, Vec3::from(read_coordinates(&ray.direction)))
        } else {
            (ray.origin, ray.direction)
        };
        let shear = RayShear::new(direction);
        let boxes = RayBoxTest::new(origin, direction);
        // Inlined, as in `closest_hit_among`.
        self.bvh.any_hit(
            &boxes,
            ray.t_max,
            #[inline(always)]
            |slot| {
                let primitive = &self.primitives[slot];
                counts(primitive) && primitive.hit(ray, &shear, ray.t_max).is_some()
            },
        )
    }
}

impl Geometry {
    /// The shapes' texture coordinate mappings, one per shape (all [`UvMapping::Intrinsic`]
    /// unless set).
    ///
    /// # Panics
    /// If there is not one per shape.
    pub fn with_uv_mappings(mut self, mappings: Vec<UvMapping>) -> Self {
        assert_eq!(
            mappings.len(),
            self.shapes.len(),
            "one UV mapping per shape"
        );
        self.uv_mappings = mappings;
        self
    }

    /// The texture coordinates of the surface point `hit` (a hit of this geometry), finite.
    pub fn uv(&self, hit: &Intersection) -> Vec2 {
        let shape = hit.shape as usize;
        self.uv_mappings[shape].uv(&self.shapes[shape], hit)
    }
}

#[cfg(test)]
mod tests;
