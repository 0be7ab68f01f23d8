//! [`Geometry`]'s queries against brute force over its primitives, on random scenes and rays,
//! and at the scales and angles where rounding decides.

use super::*;
use crate::geometry::ray::RayOrigin;
use crate::geometry::shapes::{Mesh, Sphere};
use crate::geometry::sphere::intersect_sphere;
use crate::geometry::triangle::intersect_triangle;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};

fn brute_force_closest(prims: &[Primitive], ray: &Ray) -> Option<(f32, u32)> {
    let shear = RayShear::new(ray.direction);
    let mut best: Option<(f32, u32)> = None;
    for prim in prims {
        let t_max = best.map_or(ray.t_max, |b| b.0);
        let (t, shape) = match prim {
            Primitive::Triangle { p, shape, .. } => (
                intersect_triangle(ray, &shear, t_max, p).map(|h| h.0),
                *shape,
            ),
            Primitive::Sphere { sphere, shape } => (intersect_sphere(ray, t_max, sphere), *shape),
        };
        if let Some(t) = t.filter(|&t| t < t_max) {
            best = Some((t, shape));
        }
    }
    best
}

fn point() -> impl Strategy<Value = Vec3> {
    (-10.0f32..10.0, -10.0f32..10.0, -10.0f32..10.0).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// Random triangles, some of them degenerate (repeated or collinear vertices), and spheres.
fn scene() -> impl Strategy<Value = Vec<ShapeGeometry>> {
    let triangle = (point(), point(), point(), 0u8..4).prop_map(|(a, b, c, kind)| match kind {
        0 => [a, a, b],                 // two equal vertices
        1 => [a, b, a + 2.0 * (b - a)], // collinear
        _ => [a, b, c],
    });
    // Some meshes with vertex normals, among them zero ones (an interpolated normal
    // without a direction).
    let mesh = (prop::collection::vec(triangle, 1..60), prop::bool::ANY).prop_map(
        |(tris, with_normals)| {
            let mut m = Mesh::default();
            for t in tris {
                let base = m.positions.len() as u32;
                m.positions.extend(t);
                m.indices.push([base, base + 1, base + 2]);
            }
            if with_normals {
                let normal = |(i, p): (usize, &Vec3)| match i % 5 {
                    0 => Vec3::ZERO,
                    _ => (*p * 0.7 + Vec3::X).normalize_or_zero(),
                };
                m.normals = Some(m.positions.iter().enumerate().map(normal).collect());
            }
            ShapeGeometry::Mesh(m)
        },
    );
    let sphere = (point(), 0.01f32..3.0)
        .prop_map(|(center, radius)| ShapeGeometry::Sphere(Sphere { center, radius }));
    (
        prop::collection::vec(mesh, 1..4),
        prop::collection::vec(sphere, 0..4),
    )
        .prop_map(|(mut a, b)| {
            a.extend(b);
            a
        })
}

fn ray() -> impl Strategy<Value = Ray> {
    (point(), point(), prop::bool::ANY, 0u8..4).prop_filter_map(
        "zero direction",
        |(o, d, finite, kind)| {
            let direction = match kind {
                // Along an axis, with signed zeros in the other components (-X is (-1, -0, -0)).
                0 => {
                    let axis = d.abs().max_position();
                    Vec3::AXES[axis] * d[axis].signum()
                }
                _ => d.normalize_or_zero(),
            };
            (d.length() > 1e-3).then_some(Ray {
                origin: o * 1.5,
                direction,
                t_max: if finite { 12.0 } else { f32::INFINITY },
            })
        },
    )
}

/// Runs `check` on 64 random scenes (`scene`) with 200 random rays (`ray`) each.
fn for_random_scenes_and_rays(
    check: impl Fn(&Geometry, &Ray) -> Result<(), proptest::test_runner::TestCaseError>,
) {
    let mut runner = TestRunner::new(Config {
        cases: 64,
        ..Config::default()
    });
    runner
        .run(
            &(scene(), prop::collection::vec(ray(), 200)),
            |(shapes, rays)| {
                let geometry = Geometry::new(shapes);
                rays.iter().try_for_each(|ray| check(&geometry, ray))
            },
        )
        .unwrap();
}

#[test]
fn bvh_answers_equal_brute_force() {
    for_random_scenes_and_rays(|geometry, ray| {
        let expected = brute_force_closest(&geometry.primitives, ray);
        let got = geometry.intersect(ray);
        prop_assert_eq!(got.map(|h| h.t), expected.map(|e| e.0), "ray {:?}", ray);
        prop_assert_eq!(geometry.occluded(ray), expected.is_some());
        if let Some(hit) = got {
            prop_assert!(hit.position.is_finite() && hit.geometric_normal.is_normalized());
        }
        Ok(())
    });
}

/// The closest hit on one shape, every other shape ignored, is the brute-force closest
/// among that shape's primitives (distance and shape), for every shape of the scene; and
/// where the ray's first hit is on that shape, the same hit.
#[test]
fn hits_on_one_shape_ignore_the_others() {
    for_random_scenes_and_rays(|geometry, ray| {
        let first = geometry.first_hit(ray);
        for shape in 0..geometry.shapes.len() as u32 {
            let own: Vec<Primitive> = (geometry.primitives.iter())
                .filter(|p| p.shape() == shape)
                .copied()
                .collect();
            let got = geometry.first_hit_on_shape(ray, shape);
            let expected = brute_force_closest(&own, ray);
            prop_assert_eq!(got.map(|h| (h.t, h.shape)), expected, "ray {:?}", ray);
            if let Some(first) = first.filter(|f| f.shape == shape) {
                let on_shape = got.expect("the first hit is on the shape");
                let (a, b) = (
                    geometry.surface(ray, &on_shape),
                    geometry.surface(ray, &first),
                );
                prop_assert_eq!((a.t, a.position), (b.t, b.position));
                prop_assert_eq!(a.geometric_normal, b.geometric_normal);
            }
        }
        Ok(())
    });
}

/// A shadow ray that ignores one shape is blocked exactly when the brute force finds a
/// primitive of another shape before its end, for every shape of the scene.
#[test]
fn occlusion_by_others_ignores_one_shape() {
    for_random_scenes_and_rays(|geometry, ray| {
        for shape in 0..geometry.shapes.len() as u32 {
            let others: Vec<Primitive> = (geometry.primitives.iter())
                .filter(|p| p.shape() != shape)
                .copied()
                .collect();
            prop_assert_eq!(
                geometry.occluded_by_others(ray, Some(shape), None),
                brute_force_closest(&others, ray).is_some(),
                "ray {:?}, shape {} ignored",
                ray,
                shape
            );
        }
        Ok(())
    });
}

/// Rays leaving a surface point skip the triangle under it ([`Primitive::is_triangle_under`])
/// and answer as the queries that test it: the same first hit (slot and distance) and the
/// same occlusion, for directions on both sides of the surface (grazing ones too), to
/// points and to infinity, with and without a shape ignored. Spheres are tested as before:
/// a ray into one meets its far side.
#[test]
fn rays_leaving_a_surface_answer_as_the_full_queries() {
    let leaving_triangles = Cell::new(0usize);
    let leaving_spheres = Cell::new(0usize);
    let mut sampler = crate::sampler::Sampler::new(7, 0, 0);
    let directions: Vec<Vec3> = (0..8)
        .map(|_| {
            let (u, v) = (sampler.next_2d(), sampler.next_1d());
            Vec3::new(2.0 * u.x - 1.0, 2.0 * u.y - 1.0, 2.0 * v - 1.0)
        })
        .collect();
    for_random_scenes_and_rays(|geometry, camera_ray| {
        let Some(hit) = geometry.intersect(camera_ray) else {
            return Ok(());
        };
        let on_triangle = matches!(geometry.shapes[hit.shape as usize], ShapeGeometry::Mesh(_));
        let counter = if on_triangle {
            &leaving_triangles
        } else {
            &leaving_spheres
        };
        counter.set(counter.get() + 1);
        let origin = RayOrigin::toward(&hit, -camera_ray.direction);
        let n = hit.geometric_normal;
        // Random directions, and grazing ones: nearly in the tangent plane, either side.
        let grazing = |w: Vec3| (w - n * w.dot(n)).normalize_or_zero() + n * 1e-4;
        let aims = directions
            .iter()
            .flat_map(|&w| [w, grazing(w), grazing(-w) - 2e-4 * n]);
        for w in aims.filter(|w| w.length_squared() > 0.0) {
            let ray = origin.ray(&hit, w.normalize());
            let (full, leaving) = (
                geometry.first_hit(&ray),
                geometry.first_hit_leaving(&ray, &hit),
            );
            prop_assert_eq!(
                full.map(|f| (f.slot, f.t.to_bits())),
                leaving.map(|f| (f.slot, f.t.to_bits())),
                "from {:?} toward {:?}",
                hit,
                w
            );
            prop_assert_eq!(
                geometry.occluded(&ray),
                geometry.occluded_by_others(&ray, None, Some(&hit))
            );
            let target = ray.origin + 3.0 * ray.direction;
            let shadow = origin.ray_to(&hit, target);
            for ignored in [None, Some(hit.shape), Some(0)] {
                prop_assert_eq!(
                    geometry.occluded_by_others(&shadow, ignored, None),
                    geometry.occluded_by_others(&shadow, ignored, Some(&hit)),
                    "from {:?} toward {:?}, {:?} ignored",
                    hit,
                    target,
                    ignored
                );
            }
        }
        Ok(())
    });
    // Enough points of both kinds for the comparison to mean something.
    assert!(
        leaving_triangles.get() > 1000 && leaving_spheres.get() > 25,
        "{} points on triangles, {} on spheres",
        leaving_triangles.get(),
        leaving_spheres.get()
    );
}

/// Packets of rays from one origin (nearly parallel as a pixel's camera rays, or spread
/// so that some do not share direction signs and are traced alone) get, ray by ray, the
/// intersection record [`Geometry::intersect`] gives, bit for bit (the normals made
/// together in lanes among them).
#[test]
fn packets_hit_what_each_ray_hits_alone() {
    let packets = Cell::new(0usize);
    let mut runner = TestRunner::new(Config {
        cases: 64,
        ..Config::default()
    });
    let packet = (
        ray(),
        prop::collection::vec(point(), 1..=PACKET_SIZE + 3),
        0usize..3,
    );
    runner
        .run(
            &(scene(), prop::collection::vec(packet, 30)),
            |(shapes, packets_drawn)| {
                let geometry = Geometry::new(shapes);
                for (ray, jitters, spread) in packets_drawn {
                    let spread = [1e-4, 1e-2, 0.3][spread];
                    let rays: Vec<Ray> = jitters
                        .iter()
                        .map(|j| Ray {
                            direction: (ray.direction + *j * spread).normalize_or(ray.direction),
                            ..ray
                        })
                        .collect();
                    let boxes: Vec<RayBoxTest> = rays
                        .iter()
                        .map(|r| RayBoxTest::new(r.origin, r.direction))
                        .collect();
                    if rays.len() > 1
                        && PacketBoxTest::new(&boxes[..rays.len().min(PACKET_SIZE)]).is_some()
                    {
                        packets.set(packets.get() + 1);
                    }
                    let mut hits = vec![None; rays.len()];
                    geometry.intersect_packet(&rays, &mut hits);
                    for (ray, hit) in rays.iter().zip(&hits) {
                        let alone = geometry.intersect(ray);
                        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                        let key = |h: &Option<Intersection>| {
                            h.map(|h| {
                                (
                                    (h.t.to_bits(), h.shape, h.primitive),
                                    [h.position, h.error].map(bits),
                                    [h.geometric_normal, h.shading_normal].map(bits),
                                )
                            })
                        };
                        prop_assert_eq!(key(hit), key(&alone), "ray {:?}", ray);
                    }
                }
                Ok(())
            },
        )
        .unwrap();
    assert!(
        packets.get() > 64 * 10,
        "only {} packets formed",
        packets.get()
    );
}

/// [`Geometry::may_meet`] on random scenes and rays: true for every shape the ray hits
/// (any of its primitives, not only the closest one).
#[test]
fn may_meet_holds_for_every_shape_hit() {
    let culled = Cell::new(0usize);
    for_random_scenes_and_rays(|geometry, ray| {
        for shape in 0..geometry.shapes.len() as u32 {
            let hit = geometry.primitives.iter().any(|prim| match prim {
                Primitive::Triangle { p, shape: s, .. } => {
                    let shear = RayShear::new(ray.direction);
                    *s == shape
                        && intersect_triangle(ray, &shear, ray.t_max, p)
                            .is_some_and(|(t, _)| t < ray.t_max)
                }
                Primitive::Sphere { sphere, shape: s } => {
                    *s == shape && intersect_sphere(ray, ray.t_max, sphere).is_some()
                }
            });
            let may = geometry.may_meet(ray, shape);
            prop_assert!(may || !hit, "shape {} hit by {:?}", shape, ray);
            culled.set(culled.get() + usize::from(!may));
        }
        Ok(())
    });
    // The test has power only if the cull culls: most random rays pass clear of a shape.
    let culled = culled.get();
    assert!(culled > 64 * 200, "only {culled} shape–ray pairs culled");
}

/// [`Geometry::may_meet`] where rounding decides: rays toward points within 1e-7 to 1e-3 of
/// a triangle's edges and vertices, on both sides, and rays grazing a sphere, from 1e-3 to
/// 1e4 times the shape's size, at elevations down to 1e-5 rad, at coordinates up to 3e4.
/// Every ray the watertight test (or the sphere test) lets hit is one `may_meet` keeps; and
/// rays passing 1 % of the size beside the shape are culled.
#[test]
fn may_meet_keeps_rays_that_hit_within_rounding() {
    let mut sampler = crate::sampler::Sampler::new(5, 0, 0);
    let (mut hits, mut beside, mut culled_beside) = (0u32, 0u32, 0u32);
    let triangles = [
        [Vec3::ZERO, Vec3::X, Vec3::Y],
        [
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::X,
            Vec3::new(0.0, 1e-4, 0.0),
        ],
        [
            Vec3::new(-2e4, 3e4, 1e4),
            Vec3::new(-2e4, 3e4 + 2.0, 1e4),
            Vec3::new(-2e4 + 1.0, 3e4, 1e4 + 3.0),
        ],
        [
            Vec3::new(-700.0, -300.0, 0.0),
            Vec3::new(600.0, -300.0, 50.0),
            Vec3::new(0.0, 400.0, -20.0),
        ],
    ];
    for p in triangles {
        let mut mesh = Mesh::default();
        mesh.positions.extend(p);
        mesh.indices.push([0, 1, 2]);
        let geometry = Geometry::new(vec![ShapeGeometry::Mesh(mesh)]);
        let size = (p[1] - p[0]).length().max((p[2] - p[0]).length());
        let normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
        let frame = crate::math::Frame::from_normal(normal);
        for case in 0..20_000 {
            let (u, v, w) = (sampler.next_2d(), sampler.next_2d(), sampler.next_2d());
            let side = if sampler.next_1d() < 0.5 { -1.0 } else { 1.0 };
            // A point on an edge (or at a vertex), moved off it by ±1e-7 to 1e-3 of the size,
            // in the triangle's plane.
            let (a, b) = (p[case % 3], p[(case + 1) % 3]);
            let on_edge = if case % 4 == 0 { a } else { a + u.x * (b - a) };
            let tiny = 10f32.powf(-7.0 + 4.0 * u.y) * size * (w.x - 0.5).signum();
            let sideways = normal.cross(b - a).normalize() * tiny;
            let target = on_edge + sideways;
            let grazing = case % 3 == 0;
            let elevation = if grazing {
                10f32.powf(-5.0 + 3.0 * v.x)
            } else {
                0.05 + 1.5 * v.x
            };
            let azimuth = std::f32::consts::TAU * v.y;
            let local = Vec3::new(
                elevation.cos() * azimuth.cos(),
                elevation.cos() * azimuth.sin(),
                elevation.sin() * side,
            );
            let distance = size * 10f32.powf(-3.0 + 7.0 * w.y);
            let origin = target + frame.to_world(local) * distance;
            let ray = Ray {
                origin,
                direction: (target - origin).normalize(),
                t_max: f32::INFINITY,
            };
            if geometry.occluded(&ray) {
                hits += 1;
                assert!(geometry.may_meet(&ray, 0), "culled a hit: {ray:?} of {p:?}");
            }
            // And a ray passing beside the triangle's box, above its top face by 1 % of the
            // box's size and 1e-3 of its coordinates, in any direction parallel to the face.
            let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
            let gap = 0.01 * (hi - lo).max_element() + 1e-3 * lo.abs().max(hi.abs()).max_element();
            let above = lo.lerp(hi, u.x).with_z(hi.z + gap);
            let along = Vec3::new(azimuth.cos(), azimuth.sin(), 0.0);
            let ray = Ray {
                origin: above - along * distance,
                direction: along,
                t_max: f32::INFINITY,
            };
            beside += 1;
            culled_beside += u32::from(!geometry.may_meet(&ray, 0));
        }
    }
    assert!(hits > 10_000, "only {hits} hits");
    assert_eq!(culled_beside, beside, "rays beside a vertex kept");

    // Rays grazing a sphere: aimed at a point at a tangent, moved in or out by ±1e-7 to 1e-3
    // of the radius.
    for (center, radius) in [(Vec3::ZERO, 1.0), (Vec3::new(3e3, -2e3, 1e4), 0.5)] {
        let sphere = Sphere { center, radius };
        let geometry = Geometry::new(vec![ShapeGeometry::Sphere(sphere)]);
        let mut sphere_hits = 0;
        for _ in 0..20_000 {
            let (u, v, w) = (sampler.next_2d(), sampler.next_2d(), sampler.next_2d());
            let z = 1.0 - 2.0 * u.x;
            let (sin_phi, cos_phi) = (std::f32::consts::TAU * u.y).sin_cos();
            let r = (1.0 - z * z).max(0.0).sqrt();
            let n = Vec3::new(r * cos_phi, r * sin_phi, z);
            let frame = crate::math::Frame::from_normal(n);
            let (sin_psi, cos_psi) = (std::f32::consts::TAU * w.x).sin_cos();
            let tangent = frame.to_world(Vec3::new(cos_psi, sin_psi, 0.0));
            let tiny = 10f32.powf(-7.0 + 4.0 * v.x) * radius * (w.y - 0.5).signum();
            let target = center + n * (radius + tiny);
            let distance = radius * 10f32.powf(-2.0 + 6.0 * v.y);
            let ray = Ray {
                origin: target - tangent * distance,
                direction: tangent,
                t_max: f32::INFINITY,
            };
            if geometry.occluded(&ray) {
                sphere_hits += 1;
                assert!(
                    geometry.may_meet(&ray, 0),
                    "culled a hit: {ray:?} of {sphere:?}"
                );
            }
        }
        assert!(sphere_hits > 5_000, "only {sphere_hits} hits");
    }
}

/// A disk of many segments (a fan, which the BVH builds top-down) with spheres and a tilted
/// plane: every ray gets the brute-force answer.
#[test]
fn fans_are_traversed_exactly() {
    let mut disk = crate::geometry::shapes::disk(20_000);
    disk.positions.iter_mut().for_each(|p| *p *= 3.0);
    let shapes = vec![
        ShapeGeometry::Mesh(disk),
        ShapeGeometry::Sphere(Sphere {
            center: Vec3::new(0.5, 0.2, 0.7),
            radius: 0.4,
        }),
    ];
    let geometry = Geometry::new(shapes);
    let mut runner = TestRunner::new(Config {
        cases: 16,
        ..Config::default()
    });
    runner
        .run(&prop::collection::vec(ray(), 300), |rays| {
            for ray in &rays {
                let expected = brute_force_closest(&geometry.primitives, ray);
                prop_assert_eq!(geometry.intersect(ray).map(|h| h.t), expected.map(|e| e.0));
                prop_assert_eq!(geometry.occluded(ray), expected.is_some());
            }
            Ok(())
        })
        .unwrap();
}

/// Rays spawned from a hit never hit the same surface again, however far from the origin the
/// scene is (a fixed epsilon fails at one of these scales).
#[test]
fn spawned_rays_do_not_self_intersect_at_any_scale() {
    for scale in [1e-3f32, 1.0, 1e3, 1e5] {
        let offset = Vec3::new(3.0, -2.0, 7.0) * scale;
        let mut plane = crate::geometry::shapes::rectangle();
        plane
            .positions
            .iter_mut()
            .for_each(|p| *p = *p * scale * 10.0 + offset);
        let sphere = Sphere {
            center: offset + Vec3::new(0.0, 0.0, 3.0) * scale,
            radius: scale,
        };
        let geometry = Geometry::new(vec![
            ShapeGeometry::Mesh(plane),
            ShapeGeometry::Sphere(sphere),
        ]);
        let mut sampler = crate::sampler::Sampler::new(1, 2, 3);
        let mut hits = 0;
        for _ in 0..2000 {
            let u = sampler.next_2d();
            let target = offset + Vec3::new(u.x * 4.0 - 2.0, u.y * 4.0 - 2.0, 0.0) * scale;
            let origin = offset + Vec3::new(0.3, 0.1, 8.0) * scale;
            let ray = Ray {
                origin,
                direction: (target - origin).normalize(),
                t_max: f32::INFINITY,
            };
            let Some(hit) = geometry.intersect(&ray) else {
                continue;
            };
            hits += 1;
            // Leave the surface on the side the ray came from, at a grazing angle too.
            let d = sampler.next_2d();
            let mut w = Vec3::new(d.x - 0.5, d.y - 0.5, 0.0) + hit.geometric_normal * 1e-3;
            if w.dot(hit.geometric_normal) * ray.direction.dot(hit.geometric_normal) > 0.0 {
                w = -w;
            }
            let w = w.normalize();
            if let Some(again) = geometry.intersect(&hit.spawn_ray(w)) {
                assert!(
                    again.shape != hit.shape || again.t > 1e-3 * scale,
                    "scale {scale}: self-intersection at t = {}",
                    again.t
                );
            }
        }
        assert!(hits > 1000, "scale {scale}: only {hits} hits");
    }
}

#[test]
fn shadow_rays_reach_points_on_surfaces() {
    let mut plane = crate::geometry::shapes::rectangle();
    plane
        .positions
        .iter_mut()
        .for_each(|p| *p = *p * 1e4 + Vec3::new(5e4, 0.0, 0.0));
    let geometry = Geometry::new(vec![ShapeGeometry::Mesh(plane)]);
    let origin = Vec3::new(5e4, 0.0, 1e4);
    let hit = geometry
        .intersect(&Ray {
            origin,
            direction: -Vec3::Z,
            t_max: f32::INFINITY,
        })
        .expect("plane below");
    for target in [Vec3::new(5e4, 0.0, 2e3), Vec3::new(4.2e4, 3e3, 5.0)] {
        assert!(
            !geometry.occluded(&hit.spawn_ray_to(target)),
            "blocked toward {target}"
        );
    }
}
