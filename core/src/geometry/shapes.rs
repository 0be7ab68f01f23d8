//! Shape geometry: triangle meshes (built-in or loaded) and analytic spheres, in world space.

use crate::limits::MAX_COORDINATE;
use crate::math::lanes::{LaneKernel, Lanes, V3, with_widest_lanes};
use glam::{DMat3, Mat4, Vec2, Vec3, Vec3A};
use std::f32::consts::TAU;

/// A triangle mesh in world space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals, when the source has them.
    pub normals: Option<Vec<Vec3>>,
    /// Counter-clockwise triangles: the geometric normal is (p1 − p0) × (p2 − p0).
    pub indices: Vec<[u32; 3]>,
    /// Per-vertex texture coordinates, when the source has them (glTF `TEXCOORD_0`, OBJ `vt`
    /// with v turned as Mitsuba turns it, PLY `u`/`v`, `s`/`t` or `texture_u`/`texture_v`).
    pub uvs: Option<Vec<Vec2>>,
}

/// A sphere in world space; its normal points outward.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

/// The geometry of one shape of the scene.
#[derive(Clone, Debug, PartialEq)]
pub enum ShapeGeometry {
    Mesh(Mesh),
    Sphere(Sphere),
}

impl ShapeGeometry {
    /// Whether every coordinate is finite and within ±[`MAX_COORDINATE`] (a sphere's centre
    /// plus its radius), as the BVH builder needs: it fails on sizes around 1e19. The scene
    /// loader checks this of every shape, and says what is wrong.
    pub fn within_coordinate_limit(&self) -> bool {
        match self {
            ShapeGeometry::Sphere(s) => {
                s.center.is_finite()
                    && s.radius.is_finite()
                    && s.center.abs().max_element() as f64 + s.radius as f64
                        <= MAX_COORDINATE as f64
            }
            ShapeGeometry::Mesh(mesh) => (mesh.positions.iter())
                .all(|p| p.is_finite() && p.abs().max_element() <= MAX_COORDINATE),
        }
    }
}

impl Mesh {
    /// Applies `m` to the positions, its inverse transpose to the normals, and keeps triangles
    /// counter-clockwise when `m` mirrors.
    pub fn transformed(mut self, m: &Mat4) -> Mesh {
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        // In f64: the inverse of a transform scaling by 1e-30 (determinant 1e-90) is out of
        // f32's range, not of f64's.
        let linear = DMat3::from_cols(
            m.x_axis.truncate().as_dvec3(),
            m.y_axis.truncate().as_dvec3(),
            m.z_axis.truncate().as_dvec3(),
        );
        let normal_matrix = linear.inverse().transpose();
        if let Some(normals) = &mut self.normals {
            for n in normals.iter_mut() {
                *n = (normal_matrix * n.as_dvec3())
                    .normalize_or_zero()
                    .as_vec3()
                    .normalize_or_zero();
            }
        }
        if linear.determinant() < 0.0 {
            for t in &mut self.indices {
                t.swap(1, 2);
            }
        }
        self
    }

    /// Every face turned the other way: winding reversed and normals negated.
    pub fn flipped(mut self) -> Mesh {
        for t in &mut self.indices {
            t.swap(1, 2);
        }
        if let Some(normals) = &mut self.normals {
            for n in normals.iter_mut() {
                *n = -*n;
            }
        }
        self
    }

    /// Appends another mesh (used to merge the nodes of one glTF shape). Normals and texture
    /// coordinates are kept where both meshes have them.
    pub fn append(&mut self, other: Mesh) {
        let offset = self.positions.len() as u32;
        let empty = self.positions.is_empty();
        merge_attribute(&mut self.normals, other.normals, empty);
        merge_attribute(&mut self.uvs, other.uvs, empty);
        self.positions.extend(other.positions);
        self.indices.extend(
            other
                .indices
                .iter()
                .map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]),
        );
    }

    pub fn triangle(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// The area of triangle `i`, computed in f64 so that neither the square of a tiny edge
    /// (1e-12: 1e-48) nor of a huge one (1e12: 1e48) leaves f32's range on the way.
    pub fn triangle_area(&self, i: usize) -> f32 {
        let [a, b, c] = self.triangle(i).map(Vec3::as_dvec3);
        (0.5 * (b - a).cross(c - a).length()) as f32
    }

    /// The unit geometric normal of triangle `i`, or zero for a degenerate triangle.
    pub fn triangle_normal(&self, i: usize) -> Vec3 {
        let [a, b, c] = self.triangle(i);
        unit_normal((b - a).cross(c - a))
    }
}

/// A vertex attribute of a mesh (`kept`, `empty` if it has no vertex yet) after another's
/// (`other`) is appended: kept only if both have it.
fn merge_attribute<T>(kept: &mut Option<Vec<T>>, other: Option<Vec<T>>, empty: bool) {
    match (kept.as_mut(), other) {
        (Some(a), Some(b)) => a.extend(b),
        (None, Some(b)) if empty => *kept = Some(b),
        _ => *kept = None,
    }
}

/// `v` scaled to unit length, or zero. Scaled by its largest component first, so that the
/// squared length neither underflows (components below 1e-19) nor overflows (above 1e19):
/// cross products of tiny or huge triangles' edges still give a unit normal.
#[inline]
pub fn unit_normal(v: Vec3) -> Vec3 {
    unit_normal_a(v.into()).into()
}

/// [`unit_normal`] in SIMD lanes: the same operations, rounded alike, with one division for
/// the three coordinates.
#[inline]
pub fn unit_normal_a(v: Vec3A) -> Vec3A {
    // `f32::max`, which ignores NaN as `Vec3::max_element` does (SSE's `maxps` does not).
    let a = v.abs();
    let largest = a.x.max(a.y).max(a.z);
    if largest > 0.0 && largest.is_finite() {
        // Times the reciprocal of the length, as `Vec3::normalize` (`Vec3A::normalize` divides).
        let v = v / largest;
        v * v.length_recip()
    } else {
        Vec3A::ZERO
    }
}

/// [`unit_normal_a`] of each of `normals`, in place, several at a time in lanes: the same
/// operations, rounded alike. One at a time, each waits on its chain of a division, a square
/// root and a division; in lanes, a packet's hits share those waits. Not inlined: inlined into
/// `Geometry::intersect_packet` it took more instructions (a 64 × 64 Cornell box: 47 000 more,
/// 0.03 % of its render's).
#[inline(never)]
pub fn unit_normals_a(normals: &mut [Vec3A]) {
    with_widest_lanes(UnitNormals { normals });
}

/// The kernel of [`unit_normals_a`].
struct UnitNormals<'a> {
    normals: &'a mut [Vec3A],
}

impl LaneKernel for UnitNormals<'_> {
    type Output = ();

    #[inline(always)]
    fn run<L: Lanes, const W: usize>(self) {
        for group in self.normals.chunks_mut(W) {
            // A last group of fewer than W repeats its last vector in the lanes left.
            let last = group.len() - 1;
            let v = V3::<L>::from_fn(|i| Vec3::from(group[i.min(last)]));
            let (x, y, z) = (v.x.abs(), v.y.abs(), v.z.abs());
            let largest = max_ignoring_nan(max_ignoring_nan(x, y), z);
            let usable = largest.gt(L::splat(0.0)) & largest.is_finite();
            let scaled = V3::new(v.x / largest, v.y / largest, v.z / largest);
            let unit = V3::select(usable, scaled.normalize(), V3::zero());
            for (i, normal) in group.iter_mut().enumerate() {
                *normal = unit.lane(i).into();
            }
        }
    }
}

/// `f32::max` in lanes: the other operand where one is NaN (`Lanes::max` gives its second).
#[inline(always)]
fn max_ignoring_nan<L: Lanes>(a: L, b: L) -> L {
    L::select(b.eq(b), a.max(b), a)
}

/// The square [−1, 1]² in the z = 0 plane, facing +z, with Mitsuba's `rectangle` texture
/// coordinates: ((x + 1)/2, (y + 1)/2).
pub fn rectangle() -> Mesh {
    let positions = vec![
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
    ];
    Mesh {
        uvs: Some(
            positions
                .iter()
                .map(|p| (p.truncate() + 1.0) / 2.0)
                .collect(),
        ),
        positions,
        normals: Some(vec![Vec3::Z; 4]),
        indices: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// The unit disk in the z = 0 plane, facing +z, as a fan of `segments` triangles. Its texture
/// coordinates are not per vertex: Mitsuba's polar (r, φ/2π) of a point of the disk is not
/// linear over a triangle of the fan, so the scene gives a disk a [`UvMapping::Polar`].
///
/// [`UvMapping::Polar`]: super::UvMapping::Polar
pub fn disk(segments: u32) -> Mesh {
    let mut positions = vec![Vec3::ZERO];
    positions.extend((0..segments).map(|i| {
        let phi = TAU * i as f32 / segments as f32;
        Vec3::new(phi.cos(), phi.sin(), 0.0)
    }));
    let indices = (0..segments)
        .map(|i| [0, 1 + i, 1 + (i + 1) % segments])
        .collect();
    Mesh {
        normals: Some(vec![Vec3::Z; positions.len()]),
        positions,
        indices,
        uvs: None,
    }
}

/// The cube [−1, 1]³ with outward faces and flat normals, each face mapped onto [0, 1]² in
/// texture space as Mitsuba's `cube` maps it ([`cube_face_uv`]).
pub fn cube() -> Mesh {
    let mut mesh = Mesh {
        positions: vec![],
        normals: Some(vec![]),
        indices: vec![],
        uvs: Some(vec![]),
    };
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = Vec3::ZERO;
            n[axis] = sign;
            // u × v = n for a counter-clockwise face seen from outside.
            let mut u = Vec3::ZERO;
            u[(axis + 1) % 3] = 1.0;
            let v = n.cross(u);
            let base = mesh.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let p = n + u * a + v * b;
                mesh.positions.push(p);
                if let Some(uvs) = &mut mesh.uvs {
                    uvs.push(cube_face_uv(n, p));
                }
            }
            if let Some(normals) = &mut mesh.normals {
                normals.extend([n; 4]);
            }
            mesh.indices.push([base, base + 1, base + 2]);
            mesh.indices.push([base, base + 2, base + 3]);
        }
    }
    mesh
}

/// The texture coordinates Mitsuba 3's `cube` gives point `p` of its face of outward normal
/// `n` (an axis): each face is [0, 1]², turned as Mitsuba's vertex table turns it (found by
/// intersecting its cube, `cube_uv_is_mitsubas` has the values).
fn cube_face_uv(n: Vec3, p: Vec3) -> Vec2 {
    let (x, y, z) = ((p.x + 1.0) / 2.0, (p.y + 1.0) / 2.0, (p.z + 1.0) / 2.0);
    match (n.x, n.y, n.z) {
        (_, -1.0, _) => Vec2::new(z, x),
        (_, 1.0, _) => Vec2::new(1.0 - x, 1.0 - z),
        (1.0, _, _) => Vec2::new(y, 1.0 - z),
        (-1.0, _, _) => Vec2::new(y, z),
        (_, _, 1.0) => Vec2::new(y, x),
        _ => Vec2::new(1.0 - y, x),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Normals made several at a time in lanes are `unit_normal_a`'s, bit for bit (both NaN
    /// counts as equal), with one, four and the widest lanes, for every count of vectors from
    /// 1 to 19 (full and partial groups): tiny, huge, degenerate, infinite and NaN coordinates.
    #[test]
    fn normals_made_together_are_made_as_one_at_a_time() {
        use crate::math::lanes::LaneKernel;
        let mut sampler = crate::sampler::Sampler::new(11, 0, 0);
        let special = [
            0.0,
            -0.0,
            1.0,
            -3.0,
            1e-30,
            1e30,
            f32::INFINITY,
            f32::NAN,
            f32::MIN,
        ];
        let mut coordinate = || {
            if sampler.next_1d() < 0.3 {
                sampler.pick(&special)
            } else {
                (sampler.next_1d() - 0.5) * 10f32.powi((sampler.next_1d() * 76.0) as i32 - 38)
            }
        };
        let vectors: Vec<Vec3A> = (0..4000)
            .map(|_| Vec3A::new(coordinate(), coordinate(), coordinate()))
            .collect();
        let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        let mut compared = 0;
        for count in 1..=19 {
            for chunk in vectors.chunks_exact(count).take(40) {
                let expected: Vec<Vec3A> = chunk.iter().map(|&v| unit_normal_a(v)).collect();
                let mut runs: [Vec<Vec3A>; 3] = std::array::from_fn(|_| chunk.to_vec());
                UnitNormals {
                    normals: &mut runs[0],
                }
                .run::<f32, 1>();
                UnitNormals {
                    normals: &mut runs[1],
                }
                .run::<glam::Vec4, 4>();
                unit_normals_a(&mut runs[2]);
                for run in &runs {
                    for ((got, want), v) in run.iter().zip(&expected).zip(chunk) {
                        let agree = (0..3).all(|axis| same(got[axis], want[axis]));
                        assert!(agree, "{v}: {got} against {want}");
                        compared += 1;
                    }
                }
            }
        }
        assert!(compared > 20_000, "{compared}");
    }

    /// The SIMD unit normal is the scalar formula's, bit for bit: scaled by the largest
    /// coordinate, then times the reciprocal of the length (tiny, huge and degenerate vectors).
    #[test]
    fn unit_normals_in_lanes_round_as_the_scalar_formula() {
        let scalar = |v: Vec3| {
            let largest = v.abs().max_element();
            if largest > 0.0 && largest.is_finite() {
                (v / largest).normalize()
            } else {
                Vec3::ZERO
            }
        };
        let mut sampler = crate::sampler::Sampler::new(9, 0, 0);
        let mut vectors = vec![Vec3::ZERO, Vec3::X, -Vec3::Z, Vec3::splat(f32::INFINITY)];
        for _ in 0..20_000 {
            let scale = 10f32.powi((sampler.next_1d() * 76.0) as i32 - 38);
            let v = Vec3::new(sampler.next_1d(), sampler.next_1d(), sampler.next_1d()) - 0.5;
            vectors.push(v * scale);
        }
        for v in vectors {
            let (lanes, expected) = (unit_normal(v), scalar(v));
            for axis in 0..3 {
                assert_eq!(lanes[axis].to_bits(), expected[axis].to_bits(), "{v}");
            }
        }
    }

    fn closed_mesh_volume(m: &Mesh) -> f32 {
        (0..m.indices.len())
            .map(|i| {
                let [a, b, c] = m.triangle(i);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn builtins_have_the_documented_size_and_orientation() {
        let r = rectangle();
        assert!(((0..2).map(|i| r.triangle_area(i)).sum::<f32>() - 4.0).abs() < 1e-6);
        let [a, b, c] = r.triangle(0);
        assert!((b - a).cross(c - a).normalize().abs_diff_eq(Vec3::Z, 1e-6));
        // Outward faces give a positive volume of 8.
        assert!((closed_mesh_volume(&cube()) - 8.0).abs() < 1e-5);
        let d = disk(256);
        let area: f32 = (0..256).map(|i| d.triangle_area(i)).sum();
        assert!((area - std::f32::consts::PI).abs() < 1e-3);
    }

    #[test]
    fn mirroring_keeps_faces_outward() {
        let m = Mat4::from_scale(Vec3::new(-2.0, 1.0, 1.0));
        assert!((closed_mesh_volume(&cube().transformed(&m)) - 16.0).abs() < 1e-4);
    }
}
