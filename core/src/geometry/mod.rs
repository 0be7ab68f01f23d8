//! The scene's surfaces and the ray queries over them. Nothing here knows the scene file: shapes
//! arrive in world space as plain glam types, already checked (`scene::shape_check`).
//!
//! - `ray`: rays, intersection records, and the origins of rays leaving a surface (pbrt-v4's
//!   error bounds, §6.8).
//! - `shapes`: meshes and spheres, the built-in meshes, unit normals.
//! - `triangle`, `sphere`: the ray–primitive tests; `packet`: the triangle test for the
//!   rays of a packet in SIMD lanes.
//! - `primitive`: the primitives the BVH's leaves hold.
//! - `bvh`: the 8-wide BVH (its build, node tests and traversals).
//! - `may_meet`: the padded-box test of queries about one shape.
//! - `aggregate`: [`Geometry`], the surfaces with the BVH over them, and its queries.
//! - `uv`: texture coordinates of surface points ([`Geometry::uv`], [`UvMapping`]).
//!
//! The files are private: what plugins and the scene loader use is re-exported here, so that
//! the files can be split or merged without changing a plugin's imports.

mod aggregate;
mod bvh;
mod may_meet;
mod packet;
mod primitive;
mod ray;
mod shapes;
mod sphere;
mod triangle;
mod uv;

pub use aggregate::{BVH_BYTES_PER_PRIMITIVE, FirstHit, Geometry, take_ray_count};
/// Most rays [`Geometry::intersect_packet`] traces as one packet.
pub use bvh::PACKET_SIZE;
pub use ray::{Intersection, Ray, RayOrigin, SHADOW_EPSILON, offset_ray_origin};
pub use shapes::{Mesh, ShapeGeometry, Sphere, cube, disk, rectangle, unit_normal};
pub use triangle::ray_meets_triangle;
pub use uv::UvMapping;
