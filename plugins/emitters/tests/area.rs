//! The `area` emitter on triangles: every direction it samples is one in which a traced ray
//! finds the light, with the density `pdf_direction` gives that hit, including points drawn on
//! (or within rounding of) the triangles' edges, where u is 0 or 1/2.

use glam::{Vec2, Vec3};
use lumis_core::emitter::{Emitter, EmitterContext, EmitterHit, ReferencePoint};
use lumis_core::geometry::{self, Geometry, Ray, ShapeGeometry};
use lumis_core::params::Params;
use lumis_core::registry::{self, EmitterPlugin};
use lumis_core::scene::description::{RotationDescription, TransformDescription};
use lumis_core::scene::transform::transform_matrix;
use std::sync::Arc;

/// A two-sided 2 × 2 square light in the plane y = 0 (two triangles sharing a diagonal), and the
/// geometry rays are traced against.
fn square_light() -> (Arc<dyn Emitter>, Geometry) {
    light_on_square("\"radiance\": 2, \"two_sided\": true")
}

/// An `area` light with `params` on the 2 × 2 square in the plane y = 0, whose front faces −y
/// (the rectangle faces +z and is turned by 90° about x).
fn light_on_square(params: &str) -> (Arc<dyn Emitter>, Geometry) {
    let m = transform_matrix(&TransformDescription {
        rotate: vec![RotationDescription {
            axis: [1.0, 0.0, 0.0],
            angle: 90.0,
        }],
        ..Default::default()
    })
    .unwrap();
    let shape = ShapeGeometry::Mesh(geometry::rectangle().transformed(&m));
    (area_light(&shape, params), Geometry::new(vec![shape]))
}

/// An `area` light on `shape` with `params` (RON fields without their braces).
fn area_light(shape: &ShapeGeometry, params: &str) -> Arc<dyn Emitter> {
    lumis_emitters::link();
    let plugin = registry::find::<EmitterPlugin>("area").unwrap();
    let values = ron::from_str(&format!("{{{params}}}")).unwrap();
    let mut params = Params::new("area", plugin.params, values).unwrap();
    (plugin.create)(&mut params, &EmitterContext { shape: Some(shape) }).unwrap()
}

/// Reference points: near, far, grazing (as in the chi-square test), and others around.
const FROM: [Vec3; 5] = [
    Vec3::new(0.3, 0.4, -0.2),
    Vec3::new(3.0, 40.0, 5.0),
    Vec3::new(2.5, 0.01, 0.3),
    Vec3::new(-7.0, -3.0, 11.0),
    Vec3::new(0.9, -0.05, 0.99),
];

/// u values in [0, 1) at and next to the places where the warp puts points on an edge: 0, the
/// split between the two triangles at 1/2, and the top, each with its f32 neighbours.
fn edge_values() -> Vec<f32> {
    let ulp = f32::EPSILON / 2.0; // spacing of f32 just below 1 (and of the sampler's u)
    let mut v = Vec::new();
    for k in 0..4 {
        v.push(k as f32 * 1e-7 * 0.6);
        v.push(0.5 - k as f32 * ulp);
        v.push(0.5 + k as f32 * 2.0 * ulp);
        v.push(1.0 - (k + 1) as f32 * ulp);
    }
    v
}

/// Checks one sample: the ray along it meets the light where the sample says, with its pdf.
/// Returns whether `sample_direction` gave a sample at all.
fn check(light: &dyn Emitter, geometry: &Geometry, from: Vec3, u: Vec2) -> bool {
    let reference = ReferencePoint { position: from };
    let Some(ls) = light.sample_direction(&reference, u) else {
        return false;
    };
    let hit = geometry
        .intersect(&Ray {
            origin: from,
            direction: ls.wi,
            t_max: f32::INFINITY,
        })
        .unwrap_or_else(|| {
            panic!("from {from}, u = {u:?}: the ray along the sample {ls:?} misses the light")
        });
    let hit = EmitterHit {
        position: hit.position,
        normal: hit.geometric_normal,
        distance: hit.t,
    };
    let pdf = light.pdf_direction(&reference, ls.wi, Some(&hit));
    assert!(
        (pdf - ls.pdf).abs() <= 1e-4 * ls.pdf,
        "from {from}, u = {u:?}: pdf through the hit {pdf}, sample's {}",
        ls.pdf
    );
    let p = ls.position.unwrap();
    assert!(
        (p - hit.position).length() <= 1e-5 * (1.0 + (p - from).length()),
        "from {from}, u = {u:?}: sampled point {p}, hit {}",
        hit.position
    );
    true
}

#[test]
fn samples_on_the_edges_of_a_square_light_are_reached_by_their_rays() {
    let (light, geometry) = square_light();
    let along: Vec<f32> = (0..2048).map(|k| (k as f32 + 0.37) / 2048.0).collect();
    let mut returned = 0;
    for from in FROM {
        for &e in &edge_values() {
            for &t in &along {
                for u in [Vec2::new(e, t), Vec2::new(t, e), Vec2::new(e, e)] {
                    returned += check(light.as_ref(), &geometry, from, u) as usize;
                }
            }
        }
    }
    // Only points within rounding of an edge may be refused: nearly all are returned.
    let tried = FROM.len() * edge_values().len() * along.len() * 3;
    assert!(returned * 10 > tried * 9, "{returned} of {tried} returned");
}

/// Away from the edges (u at least 1e-4 from 0, 1/2 and 1) every u gives a sample.
#[test]
fn samples_away_from_the_edges_are_all_returned() {
    let (light, geometry) = square_light();
    let grid: Vec<f32> = (0..300)
        .map(|k| 1e-4 + (0.5 - 2e-4) * k as f32 / 299.0)
        .flat_map(|x| [x, x + 0.5])
        .collect();
    for from in FROM {
        for &x in &grid {
            for &y in &grid {
                let u = Vec2::new(x, y);
                assert!(
                    check(light.as_ref(), &geometry, from, u),
                    "from {from}: no sample for u = {u:?}"
                );
            }
        }
    }
}

/// A one-sided light emits from its front only: seen from behind, it gives no sample and `eval`
/// gives nothing; seen from the front, every sample carries its radiance. Also for a one-sided
/// sphere, whose front is its outside.
#[test]
fn one_sided_lights_emit_from_their_front_only() {
    let (light, geometry) = light_on_square("\"radiance\": 2");
    let grid: Vec<Vec2> = (0..400)
        .map(|k| Vec2::new((k % 20) as f32 + 0.5, (k / 20) as f32 + 0.5) / 20.0)
        .collect();
    for (from, front) in [
        (Vec3::new(0.3, -1.5, 0.2), true),
        (Vec3::new(-2.0, -0.1, 1.0), true),
        (Vec3::new(0.3, 1.5, 0.2), false),
        (Vec3::new(4.0, 0.2, -3.0), false),
    ] {
        let reference = ReferencePoint { position: from };
        let returned = grid
            .iter()
            .filter(|&&u| check(light.as_ref(), &geometry, from, u))
            .count();
        assert_eq!(
            returned,
            if front { grid.len() } else { 0 },
            "from {from}: {returned} samples"
        );
        let to_centre = (-from).normalize();
        let hit = geometry
            .intersect(&Ray {
                origin: from,
                direction: to_centre,
                t_max: f32::INFINITY,
            })
            .unwrap();
        let hit = EmitterHit {
            position: hit.position,
            normal: hit.geometric_normal,
            distance: hit.t,
        };
        let expected = if front { Vec3::splat(2.0) } else { Vec3::ZERO };
        assert_eq!(light.eval(to_centre, Some(&hit)), expected, "from {from}");
        let sample = light.sample_direction(&reference, Vec2::splat(0.3));
        assert_eq!(sample.is_some(), front, "from {from}");
    }
    // A one-sided sphere seen from inside shows its back: nothing.
    let sphere = ShapeGeometry::Sphere(lumis_core::geometry::Sphere {
        center: Vec3::ZERO,
        radius: 1.0,
    });
    let light = area_light(&sphere, "\"radiance\": 3");
    let inside = ReferencePoint {
        position: Vec3::new(0.2, -0.3, 0.1),
    };
    assert!(
        grid.iter()
            .all(|&u| light.sample_direction(&inside, u).is_none()),
        "a one-sided sphere lights its inside"
    );
}

/// A hit seen exactly edge-on has no solid-angle density (its area density over a zero cosine):
/// zero, never infinite or NaN.
#[test]
fn edge_on_hits_have_zero_density() {
    let (light, _) = square_light();
    let reference = ReferencePoint {
        position: Vec3::new(-3.0, 0.0, 0.5),
    };
    for normal in [Vec3::Y, -Vec3::Y] {
        let hit = EmitterHit {
            position: Vec3::new(0.0, 0.0, 0.5),
            normal,
            distance: 3.0,
        };
        assert_eq!(light.pdf_direction(&reference, Vec3::X, Some(&hit)), 0.0);
    }
    // And a hit so far that the density overflows is none either.
    let hit = EmitterHit {
        position: Vec3::new(0.0, 0.0, 0.5),
        normal: -Vec3::Y,
        distance: 1e30,
    };
    let wi = Vec3::new(0.0, 1.0, 0.0);
    assert_eq!(light.pdf_direction(&reference, wi, Some(&hit)), 0.0);
}

/// Seen from outside, a sphere light's density is uniform over the cone it subtends:
/// 1 / (2π (1 − cos θmax)), here against the closed form in f64 for cones from a hemisphere down
/// to 1e-5 sr, on both sides of the switch to the series that keeps tiny cones accurate. The
/// tolerance is the f32 evaluation's: a few ε, which the direct formula 1 − √(1 − sin²θmax)
/// (used above sin²θmax = 1e-3) amplifies by its cancellation, 1 / sin²θmax.
#[test]
fn sphere_light_density_is_that_of_its_cone() {
    let radius = 0.5f32;
    let sphere = ShapeGeometry::Sphere(lumis_core::geometry::Sphere {
        center: Vec3::new(1.0, 2.0, -1.0),
        radius,
    });
    let light = area_light(&sphere, "\"radiance\": 1");
    for sin2_max in [0.9f64, 0.25, 0.01, 2e-3, 9e-4, 5e-4, 1e-5] {
        let distance = radius as f64 / sin2_max.sqrt();
        let from =
            Vec3::new(1.0, 2.0, -1.0) - (distance * glam::DVec3::new(0.48, 0.6, 0.64)).as_vec3();
        let reference = ReferencePoint { position: from };
        let to_centre = Vec3::new(1.0, 2.0, -1.0) - from;
        let d2 = to_centre.as_dvec3().length_squared();
        let one_minus_cos = {
            let x = (radius as f64).powi(2) / d2;
            x / (1.0 + (1.0 - x).sqrt())
        };
        let expected = 1.0 / (std::f64::consts::TAU * one_minus_cos);
        let pdf = light.pdf_direction(&reference, to_centre.normalize(), None) as f64;
        // Below sin²θmax = 1e-3 the plugin's series has no cancellation.
        let amplification = if sin2_max < 1e-3 {
            1.0
        } else {
            1.0 + 1.0 / sin2_max
        };
        let tolerance = 16.0 * f32::EPSILON as f64 * amplification;
        assert!(
            ((pdf - expected) / expected).abs() <= tolerance,
            "sin²θmax = {sin2_max}: pdf {pdf}, closed form {expected}"
        );
        // The sample's density is the same.
        let sample = light
            .sample_direction(&reference, Vec2::new(0.3, 0.6))
            .unwrap();
        assert!(((sample.pdf as f64 - expected) / expected).abs() <= tolerance);
    }
}

/// Nothing is sampled where the density is not a positive finite number: from a point in a
/// square light's plane (every point seen edge-on), or toward a sphere so small and far that its
/// cone's solid angle underflows.
#[test]
fn degenerate_configurations_give_no_sample() {
    let (light, _) = square_light();
    for from in [Vec3::new(3.0, 0.0, 0.2), Vec3::new(-0.5, 0.0, 4.0)] {
        let reference = ReferencePoint { position: from };
        for k in 0..100 {
            let u = Vec2::new((k % 10) as f32 + 0.5, (k / 10) as f32 + 0.5) / 10.0;
            assert!(
                light.sample_direction(&reference, u).is_none(),
                "from {from} in the light's plane, u = {u:?}"
            );
        }
    }
    let speck = ShapeGeometry::Sphere(lumis_core::geometry::Sphere {
        center: Vec3::ZERO,
        radius: 1e-20,
    });
    let light = area_light(&speck, "\"radiance\": 1");
    let reference = ReferencePoint {
        position: Vec3::new(0.0, 0.0, 1e3),
    };
    assert!(
        light
            .sample_direction(&reference, Vec2::splat(0.4))
            .is_none()
    );
}

/// `scale` multiplies the radiance that samples and `eval` carry.
#[test]
fn scale_multiplies_the_radiance() {
    let (light, geometry) = light_on_square("\"radiance\": (1, 2, 3), \"scale\": 2.5");
    let from = Vec3::new(0.2, -2.0, 0.1);
    let sample = light
        .sample_direction(&ReferencePoint { position: from }, Vec2::splat(0.3))
        .unwrap();
    assert_eq!(sample.radiance, Vec3::new(2.5, 5.0, 7.5));
    let hit = geometry
        .intersect(&Ray {
            origin: from,
            direction: sample.wi,
            t_max: f32::INFINITY,
        })
        .unwrap();
    let hit = EmitterHit {
        position: hit.position,
        normal: hit.geometric_normal,
        distance: hit.t,
    };
    assert_eq!(light.eval(sample.wi, Some(&hit)), Vec3::new(2.5, 5.0, 7.5));
}

/// How many of `light`'s samples, drawn from reference points around `shape` (uniform in a cube
/// of side 8 about the origin, and 10⁻¹ or 10⁻² from the shape's points), have their shadow ray
/// blocked by `shape` alone, out of how many samples. Rays that meet the shape at grazing angles
/// (cosine under 10⁻²) are left out, as are nearer points: there the shape's own rounding at the
/// ray's end (10⁻⁷ of its size) can exceed what is left by the ray's stopping 10⁻⁴ of its length
/// short, which is no geometry, and rays that skip the shape are spared it too.
fn samples_blocked_by_own_shape(light: &dyn Emitter, shape: &ShapeGeometry) -> (usize, usize) {
    use lumis_core::geometry::SHADOW_EPSILON;
    let geometry = Geometry::new(vec![shape.clone()]);
    let mut sampler = lumis_core::sampler::Sampler::new(17, 0, 0);
    let (mut blocked, mut drawn) = (0, 0);
    for k in 0..4000 {
        let u = sampler.next_2d();
        let mut from = Vec3::new(u.x, u.y, sampler.next_1d()) * 8.0 - 4.0;
        if k % 2 == 1 {
            // Beside a point of the shape itself: the shading point of a surface that touches it.
            if let Some(own) = light.sample_direction(&ReferencePoint { position: from }, u) {
                let near = own.position.expect("an area light's sample has a position");
                let offset = 10f32.powi(-1 - (k / 2 % 2)) * (from - near).normalize_or_zero();
                from = near + offset;
            }
        }
        let Some(ls) =
            light.sample_direction(&ReferencePoint { position: from }, sampler.next_2d())
        else {
            continue;
        };
        let target = ls.position.expect("an area light's sample has a position");
        let along = Ray {
            origin: from,
            direction: ls.wi,
            t_max: f32::INFINITY,
        };
        let Some(first) = geometry.intersect(&along) else {
            continue;
        };
        if first.geometric_normal.dot(ls.wi).abs() < 1e-2 {
            continue;
        }
        drawn += 1;
        let ray = Ray {
            origin: from,
            direction: target - from,
            t_max: 1.0 - SHADOW_EPSILON,
        };
        blocked += geometry.occluded(&ray) as usize;
    }
    (blocked, drawn)
}

/// Where the `area` light declares that its shape never blocks its samples (shadow rays then
/// skip the shape), no sample's shadow ray is blocked by the shape: spheres, seen from outside,
/// from inside and from next to their surface, and planar meshes, also turned so that their
/// vertices are rounded off the plane. A folded mesh does not declare it, and rightly: a
/// two-sided cube's samples on faces turned away are blocked by the faces in front.
#[test]
fn shapes_declared_never_to_block_their_samples_do_not() {
    let turned = transform_matrix(&TransformDescription {
        rotate: vec![RotationDescription {
            axis: [0.3, 1.0, 0.7],
            angle: 37.0,
        }],
        scale: Some([1.5, 0.25, 1.0]),
        translate: Some([0.1, -0.7, 0.4]),
        ..Default::default()
    })
    .unwrap();
    let never_blocking = [
        ShapeGeometry::Sphere(geometry::Sphere {
            center: Vec3::new(0.2, -0.1, 0.3),
            radius: 1.3,
        }),
        ShapeGeometry::Sphere(geometry::Sphere {
            center: Vec3::new(1.0, 2.0, -0.5),
            radius: 0.01,
        }),
        ShapeGeometry::Mesh(geometry::rectangle()),
        ShapeGeometry::Mesh(geometry::rectangle().transformed(&turned)),
        ShapeGeometry::Mesh(geometry::disk(24).transformed(&turned)),
    ];
    for shape in &never_blocking {
        let light = area_light(shape, "\"radiance\": 1, \"two_sided\": true");
        assert!(light.own_shape_never_blocks_samples(), "{shape:?}");
        let (blocked, drawn) = samples_blocked_by_own_shape(light.as_ref(), shape);
        // 4000 of 4000 draws for the spheres, 3068 to 3217 for the flat shapes (rays grazing
        // them left out).
        assert!(drawn > 3000, "{drawn} samples of {shape:?}");
        assert_eq!(blocked, 0, "of {drawn} samples of {shape:?}");
    }
    for folded in [geometry::cube(), geometry::cube().transformed(&turned)] {
        let shape = ShapeGeometry::Mesh(folded);
        let light = area_light(&shape, "\"radiance\": 1, \"two_sided\": true");
        assert!(!light.own_shape_never_blocks_samples());
        let (blocked, drawn) = samples_blocked_by_own_shape(light.as_ref(), &shape);
        // About half: 1921 of 3841 and 1752 of 3724 (a face turned away is hidden by one in
        // front), against none for the shapes above.
        assert!(3 * blocked > drawn, "{blocked} of {drawn} blocked");
    }
}

/// The tests of `lumis_emitters::area` (`plugins/emitters/src/area.rs`).
mod surely_met {
    use glam::Vec3;

    use lumis_core::geometry::{Ray, ray_meets_triangle};

    use lumis_core::math::lanes::V3;

    use std::f32::consts::TAU;

    use lumis_core::math::Frame;
    use lumis_core::math::warp::square_to_triangle_barycentrics;
    use lumis_core::sampler::Sampler;
    use lumis_emitters::area::*;

    /// Wherever `surely_meets` skips the watertight test, the test would have found the
    /// triangle: triangles of every shape (slivers of aspect 10⁴ too), near and far from the
    /// origin, seen from distances of 10⁻³ to 10⁴ of their size and at grazing angles down to
    /// 10⁻⁵ rad, at points drawn uniformly and at points within a few ulps to 10⁻³ of an edge or
    /// a vertex. And the skip is no rarity: it covers 9 in 10 points drawn uniformly and seen
    /// from 0.1 to 100 times the triangle's size at elevations above 0.05 rad (95.5 % here).
    #[test]
    fn points_deemed_surely_met_are_met() {
        let mut sampler = Sampler::new(3, 0, 0);
        let (mut ordinary, mut skipped_ordinary, mut skipped_near_edge) = (0u32, 0u32, 0u32);
        let mut triangles: Vec<[Vec3; 3]> = vec![
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [
                Vec3::new(-1.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1e-4, 0.0),
            ],
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1e-4, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            [
                Vec3::new(1e4, 2e4, -3e4),
                Vec3::new(1e4 + 3.0, 2e4, -3e4),
                Vec3::new(1e4, 2e4 + 2.0, -3e4 + 1.0),
            ],
            [
                Vec3::new(-500.0, 0.0, -500.0),
                Vec3::new(500.0, 0.0, -500.0),
                Vec3::new(0.0, 0.0, 700.0),
            ],
        ];
        // And random ones: anywhere within ±1000, of size 1e-2 to 10, some of them slivers.
        for k in 0..20 {
            let mut point = || {
                let (a, b) = (sampler.next_2d(), sampler.next_2d());
                Vec3::new(a.x - 0.5, a.y - 0.5, b.x - 0.5)
            };
            let (offset, size) = (
                point() * 2000.0,
                10f32.powf(-2.0 + 3.0 * point().x.abs() * 2.0),
            );
            let (a, b) = (offset + point() * size, offset + point() * size);
            // A third vertex near the edge ab (a sliver) or anywhere.
            let squeeze = if k % 2 == 0 { 1e-3 } else { 1.0 };
            let c = (a + b) * 0.5 + point() * size * squeeze;
            triangles.push([a, b, c]);
        }
        for (index, p) in triangles.iter().enumerate() {
            let size = TriangleSize::of(p);
            let normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
            for case in 0..40_000 {
                let (u, v, w) = (sampler.next_2d(), sampler.next_2d(), sampler.next_2d());
                // Barycentrics: uniform, or one of them (or two: a vertex) within a few ulps to
                // 1e-3 of zero.
                let (mut b0, mut b1) = square_to_triangle_barycentrics(u);
                let near_edge = case % 3 != 0;
                if near_edge {
                    let tiny = 10f32.powf(-3.0 - 4.0 * w.x) * (w.y - 0.5).signum();
                    match case % 4 {
                        0 => b0 = tiny.abs(),
                        1 => b1 = tiny.abs(),
                        2 => b1 = 1.0 - b0 - tiny.abs(),
                        _ => (b0, b1) = (tiny.abs(), tiny.abs()),
                    }
                }
                let b2 = 1.0 - b0 - b1;
                if b0.min(b1).min(b2) < 0.0 {
                    continue;
                }
                // The origin: at a distance 1e-3 to 1e4 times the triangle's size, at an
                // elevation over its plane down to 1e-5 rad (grazing) or up to 90°.
                let grazing = case % 5 == 0;
                let elevation = if grazing {
                    10f32.powf(-5.0 + 3.0 * v.x)
                } else {
                    0.05 + 1.5 * v.x
                };
                let distance = size.longest_edge * 10f32.powf(-3.0 + 7.0 * v.y);
                let frame = Frame::from_normal(normal);
                let phi = TAU * w.y;
                let local = Vec3::new(
                    elevation.cos() * phi.cos(),
                    elevation.cos() * phi.sin(),
                    elevation.sin() * if case % 2 == 0 { 1.0 } else { -1.0 },
                );
                let point = b0 * p[0] + b1 * p[1] + b2 * p[2];
                let origin = point + distance * frame.to_world(local);
                // As `sample_direction` computes them.
                let to = point - origin;
                let wi = to.normalize_or_zero();
                let cos = normal.dot(wi).abs();
                let sure = surely_meets::<f32>(
                    [b0, b1, b2],
                    V3::splat(to),
                    V3::splat(origin),
                    cos,
                    (size.longest_edge, size.inv_min_height),
                );
                // Seen at 0.1 to 100 times its size, neither a sliver nor far from the origin.
                if !near_edge
                    && !grazing
                    && (2.0 / 7.0..5.0 / 7.0).contains(&v.y)
                    && (index == 0 || index == 4)
                {
                    ordinary += 1;
                    skipped_ordinary += sure as u32;
                }
                if sure {
                    skipped_near_edge += (b0.min(b1).min(b2) < 1e-2) as u32;
                    let ray = Ray {
                        origin,
                        direction: wi,
                        t_max: f32::INFINITY,
                    };
                    assert!(
                        ray_meets_triangle(&ray, p),
                        "triangle {p:?}: barycentrics ({b0}, {b1}, {b2}) from {origin} missed"
                    );
                }
            }
        }
        // Points that skip the test close to an edge: where a bound too tight would show.
        assert!(
            skipped_near_edge > 1_000,
            "only {skipped_near_edge} points within 1e-2 of an edge skipped the test"
        );
        assert!(
            skipped_ordinary as f64 > 0.9 * ordinary as f64,
            "{skipped_ordinary} of {ordinary} ordinary points skipped the test"
        );
    }
}
