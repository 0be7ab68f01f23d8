//! Tests of every built-in emitter: chi-square of `sample_direction` against `pdf_direction`,
//! agreement of a sample's radiance and pdf with `eval` and `pdf_direction`, and irradiance
//! against analytic values.
//!
//! Why one file of over 600 lines: every emitter's sampling, evaluation and irradiance tests,
//! sharing the emitter fixtures and limits.

use glam::{Vec2, Vec3};
use lumis_core::chi2::{
    Chi2Test, FAMILY_FALSE_ALARM, binomial_limit, run_side_by_side, sidak, test_sampler, z_limit,
};
use lumis_core::emitter::{Emitter, EmitterContext, EmitterHit, ReferencePoint};
use lumis_core::geometry::{self, Geometry, Ray, ShapeGeometry, Sphere};
use lumis_core::math::Rgb;
use lumis_core::math::lanes::{DEFAULT_WIDTH, limit_width, widest_width};
use lumis_core::params::Params;
use lumis_core::registry::{self, EmitterPlugin};
use lumis_emitters::envmap::EnvironmentMap;
use std::f64::consts::PI;
use std::sync::Arc;

fn emitter(kind: &str, params: &str, shape: Option<&ShapeGeometry>) -> Arc<dyn Emitter> {
    lumis_emitters::link();
    let plugin = registry::find::<EmitterPlugin>(kind).unwrap();
    let values = ron::from_str(&format!("{{{params}}}")).unwrap();
    let mut p = Params::new(kind, plugin.params, values)
        .unwrap()
        .with_base_dir(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../.."));
    let e = (plugin.create)(&mut p, &EmitterContext { shape }).unwrap();
    p.finish().unwrap();
    e
}

/// A light on a shape, with the geometry that rays hit it through.
struct ShapeLight {
    light: Arc<dyn Emitter>,
    geometry: Geometry,
}

impl ShapeLight {
    fn new(shape: ShapeGeometry, params: &str) -> Self {
        let light = emitter("area", params, Some(&shape));
        ShapeLight {
            light,
            geometry: Geometry::new(vec![shape]),
        }
    }

    fn hit(&self, from: Vec3, wi: Vec3) -> Option<EmitterHit> {
        let h = self.geometry.intersect(&Ray {
            origin: from,
            direction: wi,
            t_max: f32::INFINITY,
        })?;
        Some(EmitterHit {
            position: h.position,
            normal: h.geometric_normal,
            distance: h.t,
        })
    }

    /// The density of `wi` as the integrator computes it: through the surface it reaches.
    fn pdf(&self, from: Vec3, wi: Vec3) -> f64 {
        let r = ReferencePoint { position: from };
        self.light
            .pdf_direction(&r, wi, self.hit(from, wi).as_ref()) as f64
    }
}

/// A 2 x 2 square light in the plane y = 0 (two-sided, so every sample counts), seen from `from`.
fn square_light() -> ShapeLight {
    light_on_square("\"radiance\": 2, \"two_sided\": true")
}

/// An `area` light with `params` on the 2 x 2 square in the plane y = 0, two triangles sharing a
/// diagonal (the rectangle, which faces +z, turned by 90° about x).
fn light_on_square(params: &str) -> ShapeLight {
    let m = lumis_core::scene::transform::transform_matrix(
        &lumis_core::scene::description::TransformDescription {
            rotate: vec![lumis_core::scene::description::RotationDescription {
                axis: [1.0, 0.0, 0.0],
                angle: 90.0,
            }],
            ..Default::default()
        },
    )
    .unwrap();
    ShapeLight::new(
        ShapeGeometry::Mesh(geometry::rectangle().transformed(&m)),
        params,
    )
}

/// A sphere light of radiance 3 at the origin; two-sided to be seen from inside.
fn sphere_light(radius: f32, two_sided: bool) -> ShapeLight {
    let params = format!("\"radiance\": 3, \"two_sided\": {two_sided}");
    ShapeLight::new(
        ShapeGeometry::Sphere(Sphere {
            center: Vec3::ZERO,
            radius,
        }),
        &params,
    )
}

fn chi2_shape_light(
    light: &ShapeLight,
    from: Vec3,
    test: &Chi2Test,
) -> lumis_core::chi2::Chi2Outcome {
    let r = ReferencePoint { position: from };
    test.run(
        |s| {
            light
                .light
                .sample_direction(&r, s.next_2d())
                .map(|ls| ls.wi)
        },
        |wi| light.pdf(from, wi),
    )
}

/// A synthetic map: black but for pixel (x, y) of a w x h map.
fn hot_pixel_map(w: usize, h: usize, x: usize, y: usize) -> EnvironmentMap {
    let mut pixels = vec![Rgb::ZERO; w * h];
    pixels[y * w + x] = Rgb::new(50.0, 40.0, 30.0);
    EnvironmentMap::new(w, h, pixels, 1.0, 0.0)
}

/// The studio map turned by 40° about a tilted axis, in Mitsuba's orientation (as `lumis
/// import` writes a Mitsuba env map under a general rotation).
const TILTED_STUDIO: &str = "\"file\": \"scenes/envmaps/studio.exr\", \"rotation\": 40, \
                             \"rotation_axis\": (1, 2, -0.5), \"orientation\": \"mitsuba\", \
                             \"interpolation\": \"bilinear\"";

/// A named chi-square case: how to run it, and its bins.
type Chi2Case = (
    String,
    Box<dyn Fn(&Chi2Test) -> lumis_core::chi2::Chi2Outcome + Send + Sync>,
    Chi2Test,
);

#[test]
fn chi_square_sampling_matches_pdf() {
    let square = square_light();
    let mut cases: Vec<Chi2Case> = Vec::new();
    // Triangle light: near, far, and grazing (almost in the light's plane).
    for (name, from) in [
        ("near", Vec3::new(0.3, 0.4, -0.2)),
        ("far", Vec3::new(3.0, 40.0, 5.0)),
        ("grazing", Vec3::new(2.5, 0.01, 0.3)),
    ] {
        let square = square_light();
        // Bins over a cap about the light resolve it when it looks small or thin. At grazing it
        // is a horizontal sliver ~0.01 rad high: the cap's pole is tilted off it, so that it
        // crosses bins rather than lying along the φ = 0 edge of the cap's frame.
        let (axis, cap, nodes) = match name {
            "far" => (-from.normalize(), 0.1f64.cos(), 5),
            "grazing" => (
                (-from.normalize() + Vec3::new(0.0, 0.1, 0.0)).normalize(),
                0.7f64.cos(),
                17,
            ),
            _ => (-from.normalize(), -1.0, 5),
        };
        cases.push((
            format!("triangle light {name}"),
            Box::new(move |t: &Chi2Test| chi2_shape_light(&square, from, t)),
            Chi2Test {
                axis,
                cos_cap: cap,
                integration_nodes: nodes,
                ..Chi2Test::default()
            },
        ));
    }
    drop(square);
    // Sphere light of radius 1/2 (not 1, so that r² and r differ): near (cone nearly a
    // hemisphere), far (tiny cone), grazing directions along the cone's edge are covered by
    // both; and from inside (area sampling). Distances in radii.
    for (name, distance) in [
        ("near", 1.05f32),
        ("mid", 3.0),
        ("far", 1000.0),
        ("inside", 0.5),
    ] {
        let sphere = sphere_light(0.5, distance < 1.0);
        let from = Vec3::new(0.6, 0.0, 0.8) * (0.5 * distance);
        let sin_max = (1.0 / distance as f64).min(1.0);
        let cap = if distance > 1.0 {
            (1.2 * sin_max.asin()).min(PI).cos()
        } else {
            -1.0
        };
        cases.push((
            format!("sphere light {name}"),
            Box::new(move |t: &Chi2Test| chi2_shape_light(&sphere, from, t)),
            Chi2Test {
                axis: -from.normalize(),
                cos_cap: cap,
                ..Chi2Test::default()
            },
        ));
    }
    // Environment maps: one hot pixel (tested in a cap around it), and a real HDR map.
    let hot = Arc::new(hot_pixel_map(64, 32, 20, 9));
    let r = ReferencePoint {
        position: Vec3::ZERO,
    };
    let hot_direction = hot.sample_direction(&r, Vec2::splat(0.5)).unwrap().wi;
    {
        let hot = hot.clone();
        cases.push((
            "envmap hot pixel".into(),
            Box::new(move |t: &Chi2Test| {
                t.run(
                    |s| hot.sample_direction(&r, s.next_2d()).map(|ls| ls.wi),
                    |wi| hot.pdf_direction(&r, wi, None) as f64,
                )
            }),
            Chi2Test {
                axis: hot_direction,
                cos_cap: 0.15f64.cos(),
                ..Chi2Test::default()
            },
        ));
    }
    let studio = emitter(
        "envmap",
        "\"file\": \"scenes/envmaps/studio.exr\", \"rotation\": 30",
        None,
    );
    cases.push((
        "envmap studio".into(),
        Box::new(move |t: &Chi2Test| {
            t.run(
                |s| studio.sample_direction(&r, s.next_2d()).map(|ls| ls.wi),
                |wi| studio.pdf_direction(&r, wi, None) as f64,
            )
        }),
        Chi2Test {
            axis: Vec3::Y,
            ..Chi2Test::default()
        },
    ));
    // The same map turned about a tilted axis (the general frame, not the turn about y), and
    // the uniform environment over the whole sphere.
    for (name, kind, params) in [
        ("envmap studio tilted", "envmap", TILTED_STUDIO),
        ("constant", "constant", "\"radiance\": (1, 2, 3)"),
    ] {
        let light = emitter(kind, params, None);
        cases.push((
            name.into(),
            Box::new(move |t: &Chi2Test| {
                t.run(
                    |s| light.sample_direction(&r, s.next_2d()).map(|ls| ls.wi),
                    |wi| light.pdf_direction(&r, wi, None) as f64,
                )
            }),
            Chi2Test {
                axis: Vec3::Y,
                ..Chi2Test::default()
            },
        ));
    }
    let alpha = sidak(FAMILY_FALSE_ALARM, cases.len());
    let outcomes = run_side_by_side(&cases, |(_, run, test)| run(test));
    for ((name, _, _), outcome) in cases.iter().zip(outcomes) {
        outcome.assert_passes(alpha, name);
    }
}

/// A light sample's radiance and pdf are what `eval` and `pdf_direction` give its direction, so
/// its weight radiance / pdf is the integrand over the density.
#[test]
fn samples_agree_with_eval_and_pdf() {
    let mut s = test_sampler(1);
    for (name, light) in [
        ("square", square_light()),
        ("sphere", sphere_light(0.5, false)),
        // Two-sided, so that it is seen from inside, where it is sampled by area.
        ("two-sided sphere", sphere_light(0.5, true)),
    ] {
        for from in [
            Vec3::new(0.2, 1.5, -0.3),
            Vec3::new(4.0, 0.3, 1.0),
            Vec3::new(0.1, 0.2, 0.1),
        ] {
            let r = ReferencePoint { position: from };
            for _ in 0..2000 {
                let Some(ls) = light.light.sample_direction(&r, s.next_2d()) else {
                    continue;
                };
                let hit = light
                    .hit(from, ls.wi)
                    .unwrap_or_else(|| panic!("{name}: sample misses its light"));
                let pdf = light.light.pdf_direction(&r, ls.wi, Some(&hit));
                assert!(
                    (pdf - ls.pdf).abs() <= 2e-3 * ls.pdf,
                    "{name} from {from}: pdf {pdf} vs sample {}",
                    ls.pdf
                );
                assert_eq!(light.light.eval(ls.wi, Some(&hit)), ls.radiance, "{name}");
                let p = ls.position.unwrap();
                assert!(
                    (p - hit.position).length() < 1e-3 * (1.0 + from.length()),
                    "{name}: {p} vs {}",
                    hit.position
                );
            }
        }
    }
    let r = ReferencePoint {
        position: Vec3::ZERO,
    };
    for (kind, params) in [
        ("envmap", "\"file\": \"scenes/envmaps/studio.exr\""),
        ("envmap", TILTED_STUDIO),
        ("constant", "\"radiance\": (1, 2, 3), \"scale\": 2"),
    ] {
        let light = emitter(kind, params, None);
        for _ in 0..20_000 {
            let Some(ls) = light.sample_direction(&r, s.next_2d()) else {
                continue;
            };
            let pdf = light.pdf_direction(&r, ls.wi, None);
            assert!(
                (pdf - ls.pdf).abs() <= 1e-3 * ls.pdf,
                "{params}: pdf {pdf} vs {}",
                ls.pdf
            );
            assert_eq!(light.eval(ls.wi, None), ls.radiance, "{params}");
            assert!(ls.radiance.min_element() >= 0.0 && ls.radiance.is_finite());
            assert!((ls.wi.length() - 1.0).abs() < 1e-5, "{params}: {}", ls.wi);
        }
    }
}

/// `eval_pdf` gives `eval` and `pdf_direction` bit for bit: environment maps of both
/// placements (which override it to convert each direction once), turned or not, in every
/// direction; area lights (the trait's default) in the directions that reach them.
#[test]
fn eval_pdf_is_eval_and_pdf_direction_bit_for_bit() {
    let mut s = test_sampler(4);
    let same = |light: &dyn Emitter, r: &ReferencePoint, wi: Vec3, hit: Option<&EmitterHit>| {
        let (radiance, pdf) = light.eval_pdf(r, wi, hit);
        let (expected_radiance, expected_pdf) =
            (light.eval(wi, hit), light.pdf_direction(r, wi, hit));
        assert_eq!(
            radiance.to_array().map(f32::to_bits),
            expected_radiance.to_array().map(f32::to_bits),
            "{wi}"
        );
        assert_eq!(pdf.to_bits(), expected_pdf.to_bits(), "{wi}");
        pdf > 0.0
    };
    for params in [
        "\"file\": \"scenes/envmaps/studio.exr\"",
        "\"file\": \"scenes/envmaps/studio.exr\", \"rotation\": 37",
        "\"file\": \"scenes/envmaps/studio.exr\", \"interpolation\": \"bilinear\"",
        TILTED_STUDIO,
    ] {
        let map = emitter("envmap", params, None);
        let r = ReferencePoint {
            position: Vec3::ZERO,
        };
        let mut positive = 0;
        for _ in 0..20_000 {
            let (a, b) = (s.next_2d(), s.next_2d());
            let wi = Vec3::new(a.x - 0.5, a.y - 0.5, b.x - 0.5).normalize_or_zero();
            positive += same(map.as_ref(), &r, wi, None) as usize;
        }
        assert!(
            positive > 10_000,
            "{params}: only {positive} directions of positive density"
        );
    }
    for (name, light) in [
        ("square", square_light()),
        ("sphere", sphere_light(0.5, false)),
    ] {
        let from = Vec3::new(0.2, 1.5, -0.3);
        let r = ReferencePoint { position: from };
        let mut reached = 0;
        for _ in 0..2000 {
            let Some(ls) = light.light.sample_direction(&r, s.next_2d()) else {
                continue;
            };
            let hit = light.hit(from, ls.wi);
            reached += same(light.light.as_ref(), &r, ls.wi, hit.as_ref()) as usize;
        }
        assert!(
            reached > 1000,
            "{name}: only {reached} samples reached the light"
        );
    }
}

/// Irradiance on an unoccluded surface with normal n at x, by light sampling: mean and its
/// standard error.
fn irradiance(light: &dyn Emitter, x: Vec3, n: Vec3, samples: usize) -> (f64, f64) {
    let r = ReferencePoint { position: x };
    let mut s = test_sampler(2);
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for _ in 0..samples {
        let v = light.sample_direction(&r, s.next_2d()).map_or(0.0, |ls| {
            (ls.radiance.x * ls.wi.dot(n).max(0.0) / ls.pdf) as f64
        });
        sum += v;
        sum2 += v * v;
    }
    let mean = sum / samples as f64;
    (
        mean,
        ((sum2 / samples as f64 - mean * mean).max(0.0) / samples as f64).sqrt(),
    )
}

#[test]
fn uniform_environment_gives_pi_l_on_an_upward_plane() {
    let radiance = 1.7f32;
    let map = EnvironmentMap::new(32, 16, vec![Rgb::splat(radiance); 32 * 16], 1.0, 0.0);
    let (e, se) = irradiance(&map, Vec3::ZERO, Vec3::Y, 200_000);
    let expected = PI * radiance as f64;
    assert!(
        se < 0.01 * expected && (e - expected).abs() < z_limit(FAMILY_FALSE_ALARM) * se,
        "E = {e} ± {se}, expected {expected}"
    );
}

#[test]
fn sphere_light_gives_pi_l_r2_over_d2_on_axis() {
    let (r, d) = (0.25f32, 2.0f32);
    let light = sphere_light(r, false);
    let x = Vec3::new(0.0, -d, 0.0);
    let (e, se) = irradiance(light.light.as_ref(), x, Vec3::Y, 200_000);
    let expected = PI * 3.0 * (r as f64 / d as f64).powi(2);
    assert!(
        se < 0.01 * expected && (e - expected).abs() < z_limit(FAMILY_FALSE_ALARM) * se,
        "E = {e} ± {se}, expected {expected}"
    );
}

#[test]
fn point_light_gives_i_cos_over_d2_exactly() {
    let light = emitter(
        "point",
        "\"position\": (1, 3, 0), \"intensity\": (4, 8, 12)",
        None,
    );
    let x = Vec3::new(1.0, 0.0, 4.0);
    let n = Vec3::new(0.0, 1.0, -1.0).normalize();
    let (e, se) = irradiance(light.as_ref(), x, n, 16);
    let to = Vec3::new(1.0, 3.0, 0.0) - x;
    let expected = 4.0 * to.normalize().dot(n) as f64 / to.length_squared() as f64;
    assert_eq!(se, 0.0);
    assert!(
        (e - expected).abs() < 1e-6 * expected,
        "E = {e}, expected {expected}"
    );
    // Coincident light and surface: no light, and no NaN.
    assert!(
        light
            .sample_direction(
                &ReferencePoint {
                    position: Vec3::new(1.0, 3.0, 0.0)
                },
                Vec2::ZERO
            )
            .is_none()
    );
}

/// A spot light gives I·falloff(θ)·cos / d², with Mitsuba's falloff (`spot.cpp`): 1 within the
/// beam width, (cutoff − θ)/(cutoff − beam) between beam and cut-off, 0 from the cut-off on.
/// Points at chosen angles from the axis: in the beam, half-way through the transition, just
/// inside and just outside the cut-off, behind the light.
#[test]
fn spot_light_gives_i_falloff_cos_over_d2_exactly() {
    let position = Vec3::new(1.0, 3.0, 0.0);
    let axis = Vec3::new(0.0, -1.0, 0.3).normalize();
    let light = emitter(
        "spot",
        "\"position\": (1, 3, 0), \"direction\": (0, -1, 0.3), \"intensity\": 8, \
         \"cutoff_angle\": 30, \"beam_width\": 10",
        None,
    );
    // A direction at `degrees` from the axis, turned about x (the axis lies in the y–z plane).
    let at_angle = |degrees: f32| glam::Quat::from_rotation_x(degrees.to_radians()) * axis;
    for (degrees, falloff) in [
        (0.0f64, 1.0f64),
        (9.0, 1.0),
        (20.0, 0.5),
        (25.0, 0.25),
        (29.9, 0.005),
        (30.1, 0.0),
        (90.0, 0.0),
        (180.0, 0.0),
    ] {
        let x = position + at_angle(degrees as f32) * 2.5;
        let n = -at_angle(degrees as f32 * 0.8);
        let (e, se) = irradiance(light.as_ref(), x, n, 4);
        let to = position - x;
        let expected =
            8.0 * falloff * to.normalize().dot(n).max(0.0) as f64 / to.length_squared() as f64;
        assert_eq!(se, 0.0, "{degrees}°");
        assert!(
            (e - expected).abs() <= 2e-4 * expected.max(1e-3),
            "{degrees}°: E = {e}, expected {expected}"
        );
    }
    // The default beam is 3/4 of the cut-off (15° of 20°): full at 14°, half-way at 17.5°.
    let default_beam = emitter(
        "spot",
        "\"position\": (0, 0, 0), \"direction\": (0, 0, 1), \"intensity\": 1",
        None,
    );
    for (degrees, falloff) in [(14.0f32, 1.0f32), (17.5, 0.5)] {
        let d = glam::Quat::from_rotation_x(degrees.to_radians()) * Vec3::Z;
        let sample = default_beam
            .sample_direction(&ReferencePoint { position: d }, Vec2::ZERO)
            .unwrap();
        assert!(
            (sample.radiance.x - falloff).abs() < 1e-4,
            "{degrees}°: {}",
            sample.radiance.x
        );
    }
}

/// A spot light's cone is refused when it has no angle or the beam is wider than the cone;
/// 180° (every direction but straight back) is a cone.
#[test]
fn spot_cones_out_of_range_are_refused() {
    let create = |params: &str| {
        let plugin = registry::find::<EmitterPlugin>("spot").unwrap();
        let values = ron::from_str(&format!("{{{params}}}")).unwrap();
        Params::new("spot", plugin.params, values)
            .map_err(|e| e.to_string())
            .and_then(|mut p| {
                (plugin.create)(&mut p, &EmitterContext { shape: None })
                    .map(|_| ())
                    .map_err(|e| e.to_string())
            })
    };
    let base = "\"position\": (0, 0, 0), \"intensity\": 1";
    for (extra, expect) in [
        (
            "\"direction\": (0, 0, 1), \"cutoff_angle\": 0",
            "cutoff_angle",
        ),
        (
            "\"direction\": (0, 0, 1), \"cutoff_angle\": 181",
            "cutoff_angle",
        ),
        (
            "\"direction\": (0, 0, 1), \"cutoff_angle\": 20, \"beam_width\": 25",
            "beam_width",
        ),
        ("\"direction\": (0, 0, 0)", "direction"),
    ] {
        let e = create(&format!("{base}, {extra}")).unwrap_err();
        assert!(e.contains(expect), "{extra}: {e}");
    }
    create(&format!(
        "{base}, \"direction\": (0, 0, 1), \"cutoff_angle\": 180"
    ))
    .unwrap();
}

#[test]
fn directional_light_gives_its_irradiance_times_cos_exactly() {
    let light = emitter(
        "directional",
        "\"direction\": (0, -1, -1), \"irradiance\": 5",
        None,
    );
    let n = Vec3::new(0.3, 1.0, 0.2).normalize();
    let (e, se) = irradiance(light.as_ref(), Vec3::new(7.0, -2.0, 1.0), n, 16);
    let expected = 5.0 * Vec3::new(0.0, 1.0, 1.0).normalize().dot(n) as f64;
    assert_eq!(se, 0.0);
    assert!(
        (e - expected).abs() < 1e-6 * expected,
        "E = {e}, expected {expected}"
    );
}

#[test]
fn invalid_and_black_environment_pixels_are_never_sampled() {
    let (w, h) = (16, 8);
    let mut pixels = vec![Rgb::splat(1.0); w * h];
    pixels[3 * w + 4] = Rgb::new(f32::NAN, 1.0, 1.0);
    pixels[5 * w + 9] = Rgb::new(-2.0, -1.0, -3.0);
    pixels[2 * w + 2] = Rgb::splat(f32::INFINITY);
    let map = EnvironmentMap::new(w, h, pixels, 1.0, 0.0);
    let r = ReferencePoint {
        position: Vec3::ZERO,
    };
    let mut s = test_sampler(3);
    let samples: u64 = 100_000;
    let mut failed = 0u64;
    for _ in 0..samples {
        // On a pixel's edge, rounding may carry a direction into a black neighbour: the
        // sample then fails (rarely) rather than carrying radiance `eval` would not give.
        let Some(ls) = map.sample_direction(&r, s.next_2d()) else {
            failed += 1;
            continue;
        };
        assert!(
            ls.radiance.is_finite() && ls.radiance.min_element() >= 0.0,
            "{:?}",
            ls.radiance
        );
        // The all-negative pixel reads as black and is never chosen; the NaN one keeps G and B.
        assert!(ls.radiance.max_element() > 0.0, "sampled a black pixel");
    }
    // Failed samples are lost light: at most a fraction 1e-4 of them may fail (measured: 4.5e-5,
    // directions so close to a pole that sin θ rounds to 0; pixel edges add far fewer).
    let limit = binomial_limit(samples, 1e-4, FAMILY_FALSE_ALARM);
    assert!(
        failed <= limit,
        "{failed} failed samples of {samples}, more than the {limit} a failure rate of 1e-4 gives \
         at significance {FAMILY_FALSE_ALARM}"
    );
    let black = EnvironmentMap::new(w, h, vec![Rgb::ZERO; w * h], 1.0, 0.0);
    assert!(black.sample_direction(&r, Vec2::splat(0.3)).is_none());
    assert_eq!(black.pdf_direction(&r, Vec3::Y, None), 0.0);
}

/// u values at and next to the places where a warp or the choice of a triangle changes: 0, the
/// quarters, fifths and the half (where the square's two triangles meet), and the top, each with
/// its f32 neighbours. On the square, u.x at 0, 1/2 and just below 1/2 and 1, or u.y at 0 or
/// just below 1, puts the point on a triangle's edge.
fn edge_values() -> Vec<f32> {
    let mut v = vec![
        0.0,
        f32::from_bits(1),
        1e-7,
        0.999_999_9,
        1.0 - f32::EPSILON / 2.0,
    ];
    for base in [0.2f32, 0.25, 0.4, 0.5, 0.6, 0.75, 0.8] {
        v.extend([
            f32::from_bits(base.to_bits() - 1),
            base,
            f32::from_bits(base.to_bits() + 1),
        ]);
    }
    v
}

/// An `area` light with `params` on five triangles of different sizes (areas 2 to 2.5e-4, one
/// a sliver), orientations and planes.
fn light_on_triangles(params: &str) -> ShapeLight {
    let triangles = [
        [
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ],
        [
            Vec3::ZERO,
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-0.3, 0.0, 0.0),
        ],
        [
            Vec3::new(1.0, 1.0, 0.2),
            Vec3::new(1.5, 1.0, 0.2),
            Vec3::new(1.25, 1.001, 0.2),
        ],
        [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.5),
            Vec3::new(0.0, 1.0, 1.2),
        ],
        [
            Vec3::new(-1.0, 2.0, -1.0),
            Vec3::new(1.0, 2.0, -1.0),
            Vec3::new(0.0, 2.0, 1.0),
        ],
    ];
    let mesh = geometry::Mesh {
        positions: triangles.iter().flatten().copied().collect(),
        normals: None,
        indices: (0..triangles.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect(),
        uvs: None,
    };
    ShapeLight::new(ShapeGeometry::Mesh(mesh), params)
}

/// `sample_direction_batch` gives what `sample_direction` gives, bit for bit, for every
/// emitter: area lights on triangles (the square, one- and two-sided, and five triangles of
/// different areas, seen from in front, from behind, from within their plane and from on them)
/// and on spheres (one- and two-sided, from far, mid, near, just outside, on the surface and
/// inside, where the sampling switches from cone to area), and the environment map, whose
/// batches run in lanes, at every width (four, eight where the processor has AVX2, sixteen where
/// it has AVX-512); and the delta lights, which use the trait's default. Batches of every length
/// a group of four, eight or sixteen can end with, of u from a seeded stream with, in some lanes, values on and next to the
/// edges of the warps (points on a triangle's edge, the cone's rim, the diagonal u.x = u.y of
/// the triangle warp). Each output starts as a NaN sentinel, so an element the batch leaves
/// unwritten fails.
#[test]
fn batches_give_what_single_calls_give_bit_for_bit() {
    const LENGTHS: [usize; 12] = [1, 2, 3, 4, 5, 7, 8, 9, 15, 17, 33, 64];
    const ROUNDS: usize = 12;
    let bits = |s: &Option<lumis_core::emitter::EmitterSample>| {
        s.map(|s| {
            (
                s.wi.to_array().map(f32::to_bits),
                s.position.map(|p| p.to_array().map(f32::to_bits)),
                s.pdf.to_bits(),
                s.radiance.to_array().map(f32::to_bits),
            )
        })
    };
    let sentinel = lumis_core::emitter::EmitterSample {
        wi: Vec3::NAN,
        position: Some(Vec3::NAN),
        pdf: f32::NAN,
        radiance: Rgb::NAN,
    };
    let edges = edge_values();
    let around = |center: Vec3, radius: f32, distances: &[f32]| -> Vec<Vec3> {
        distances
            .iter()
            .map(|d| center + Vec3::new(0.6, 0.0, 0.8) * (radius * d))
            .collect()
    };
    // Distances in radii: far (a cone too thin for 1 − cos θ to be computed directly), mid,
    // near, just outside (the cone nearly a hemisphere), on the surface, inside, at the centre.
    let sphere_distances = [1e5, 1000.0, 3.0, 1.05, 1.0 + 1e-6, 1.0, 0.5, 0.0];
    // In front (y < 0: the square faces −y), behind, within its plane, on it.
    let square_from = vec![
        Vec3::new(0.3, -0.4, -0.2),
        Vec3::new(0.3, 0.4, -0.2),
        Vec3::new(3.0, 40.0, 5.0),
        Vec3::new(2.5, 0.01, 0.3),
        Vec3::new(2.5, 0.0, 0.3),
        Vec3::new(-7.0, -3.0, 11.0),
        Vec3::new(0.9, -0.05, 0.99),
        Vec3::new(0.2, 0.0, 0.1),
    ];
    let triangles_from = vec![
        Vec3::new(0.3, 0.4, -0.2),
        Vec3::new(0.5, 0.5, 3.0),
        Vec3::new(10.0, -20.0, 5.0),
        Vec3::new(0.5, 0.3, 0.0),
        Vec3::new(0.2, 5.0, 0.3),
    ];
    let offset = Vec3::new(1.0, -2.0, 0.5);
    let cases: Vec<(&str, Arc<dyn Emitter>, Vec<Vec3>)> = vec![
        (
            "two-sided square",
            square_light().light,
            square_from.clone(),
        ),
        (
            "one-sided square",
            light_on_square("\"radiance\": (1, 2, 3)").light,
            square_from,
        ),
        (
            "one-sided triangles",
            light_on_triangles("\"radiance\": 2").light,
            triangles_from.clone(),
        ),
        (
            "two-sided triangles",
            light_on_triangles("\"radiance\": 2, \"two_sided\": true").light,
            triangles_from,
        ),
        (
            "one-sided sphere",
            sphere_light(0.5, false).light,
            around(Vec3::ZERO, 0.5, &sphere_distances),
        ),
        (
            "two-sided sphere",
            sphere_light(0.5, true).light,
            around(Vec3::ZERO, 0.5, &sphere_distances),
        ),
        (
            "offset two-sided sphere",
            ShapeLight::new(
                ShapeGeometry::Sphere(Sphere {
                    center: offset,
                    radius: 0.3,
                }),
                "\"radiance\": (1, 2, 3), \"two_sided\": true",
            )
            .light,
            around(offset, 0.3, &sphere_distances),
        ),
        (
            "envmap",
            emitter("envmap", "\"file\": \"scenes/envmaps/studio.exr\"", None),
            vec![Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0)],
        ),
        (
            "turned envmap",
            emitter(
                "envmap",
                "\"file\": \"scenes/envmaps/studio.exr\", \"rotation\": 30",
                None,
            ),
            vec![Vec3::new(-4.0, 0.5, 2.0)],
        ),
        (
            "bilinear envmap, Mitsuba's orientation",
            emitter(
                "envmap",
                "\"file\": \"scenes/envmaps/studio.exr\", \"interpolation\": \"bilinear\", \
                 \"orientation\": \"mitsuba\", \"rotation\": -75",
                None,
            ),
            vec![Vec3::ZERO],
        ),
        (
            "tilted envmap",
            emitter("envmap", TILTED_STUDIO, None),
            vec![Vec3::ZERO],
        ),
        (
            "constant envmap",
            emitter("constant", "\"radiance\": (1, 2, 3)", None),
            vec![Vec3::ZERO],
        ),
        (
            "point",
            emitter(
                "point",
                "\"position\": (1, 3, 0), \"intensity\": (4, 8, 12)",
                None,
            ),
            vec![Vec3::new(1.0, 0.0, 4.0), Vec3::new(1.0, 3.0, 0.0)],
        ),
        (
            "spot",
            emitter(
                "spot",
                "\"position\": (1, 3, 0), \"direction\": (0, -1, 0.2), \
                 \"intensity\": (4, 8, 12), \"cutoff_angle\": 30",
                None,
            ),
            vec![Vec3::new(1.0, 0.0, 0.4), Vec3::new(1.0, 0.0, 4.0)],
        ),
        (
            "directional",
            emitter(
                "directional",
                "\"direction\": (0, -1, -1), \"irradiance\": 5",
                None,
            ),
            vec![Vec3::new(7.0, -2.0, 1.0)],
        ),
    ];
    let mut s = test_sampler(9);
    let mut mixed_area = 0;
    // Every kernel width, four, eight (with AVX2) and sixteen (with AVX-512): the same results
    // either way.
    for width in [4, 8, 16] {
        limit_width(width);
        if widest_width() != width {
            // The processor has no lanes this wide: its widest were tested already.
            continue;
        }
        for (name, light, from) in &cases {
            let (mut some, mut none, mut mixed) = (0usize, 0usize, 0usize);
            let from_all: &[Vec3] = from;
            for &from in from {
                let r = ReferencePoint { position: from };
                for round in 0..ROUNDS {
                    for len in LENGTHS {
                        let u: Vec<Vec2> = (0..len)
                            .map(|k| {
                                let mut u = s.next_2d();
                                let edge = edges[((s.next_1d() * edges.len() as f32) as usize)
                                    .min(edges.len() - 1)];
                                match (k * 5 + round) % 8 {
                                    4 => u.x = edge,
                                    5 => u.y = edge,
                                    6 => u = Vec2::new(edge, edges[(k + round) % edges.len()]),
                                    7 => u.y = u.x,
                                    _ => {}
                                }
                                u
                            })
                            .collect();
                        // One reference point in even rounds; in odd ones, each element from one of
                        // the case's points (the camera samples of a pixel).
                        let references: Vec<ReferencePoint> = (0..len)
                            .map(|k| match round % 2 {
                                0 => r,
                                _ => ReferencePoint {
                                    position: from_all[(k + round) % from_all.len()],
                                },
                            })
                            .collect();
                        let mut out = vec![Some(sentinel); len];
                        // The one point given once in rounds divisible by four.
                        let reference_argument = match round % 4 {
                            0 => std::slice::from_ref(&r),
                            _ => &references[..],
                        };
                        light.sample_direction_batch(reference_argument, &u, &mut out);
                        for (k, (&uk, batch)) in u.iter().zip(&out).enumerate() {
                            let single = light.sample_direction(&references[k], uk);
                            assert_eq!(
                                bits(batch),
                                bits(&single),
                                "{name} from {from:?}, {width} lanes: batch of {len}, element {k}, u {uk:?}: \
                             batch {batch:?}, single {single:?}"
                            );
                            some += single.is_some() as usize;
                            none += single.is_none() as usize;
                        }
                        let drawn = out.iter().filter(|s| s.is_some()).count();
                        mixed += (drawn > 0 && drawn < len) as usize;
                    }
                }
            }
            // Area lights have five references or more, the others one or two.
            let area = !(name.contains("envmap")
                || *name == "point"
                || *name == "spot"
                || *name == "directional");
            let least = if area { 2_500 } else { 900 };
            assert!(
                some >= least,
                "{name}, {width} lanes: only {some} samples compared"
            );
            if name.starts_with("one-sided") || *name == "point" || *name == "spot" {
                assert!(none > 0, "{name}: no failed sample compared");
            }
            if area {
                mixed_area += mixed;
            }
        }
    }
    limit_width(DEFAULT_WIDTH);
    // Batches of area lights in which some lanes give a sample and others none (points on
    // edges, faces seen edge-on or from behind): where a lane's mask matters.
    assert!(
        mixed_area >= 100,
        "only {mixed_area} batches of area lights mixed samples and failed ones"
    );
}

/// `eval_pdf_batch` gives what `eval_pdf` gives, bit for bit, for the environment maps, whose
/// batches run in lanes (nearest, turned, and bilinear in Mitsuba's orientation), at both
/// widths and every length a group of four or eight can end with: random directions and, in
/// some lanes, the poles, the seam (φ = ±π, where u wraps), the axes and directions just off
/// them. Each output starts as a NaN sentinel, so an element the batch leaves unwritten fails.
#[test]
fn eval_pdf_batches_give_what_single_calls_give_bit_for_bit() {
    const LENGTHS: [usize; 12] = [1, 2, 3, 4, 5, 7, 8, 9, 15, 17, 33, 64];
    let maps = [
        ("envmap", "\"file\": \"scenes/envmaps/studio.exr\""),
        (
            "turned envmap",
            "\"file\": \"scenes/envmaps/studio.exr\", \"rotation\": 30",
        ),
        (
            "bilinear envmap, Mitsuba's orientation",
            "\"file\": \"scenes/envmaps/studio.exr\", \"interpolation\": \"bilinear\", \
             \"orientation\": \"mitsuba\", \"rotation\": -75",
        ),
        ("tilted envmap", TILTED_STUDIO),
    ];
    let special = [
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Z,
        Vec3::NEG_Z,
        Vec3::new(0.0, 0.3, -1.0).normalize(),
        Vec3::new(-1e-7, 0.3, -1.0).normalize(),
        Vec3::new(1e-7, 0.3, -1.0).normalize(),
        Vec3::new(1e-4, 1.0, 0.0).normalize(),
        Vec3::new(0.0, -1.0, 1e-4).normalize(),
    ];
    let bits = |(le, pdf): (Rgb, f32)| (le.to_array().map(f32::to_bits), pdf.to_bits());
    let mut s = test_sampler(13);
    for width in [4, 8, 16] {
        limit_width(width);
        if widest_width() != width {
            // The processor has no lanes this wide: its widest were tested already.
            continue;
        }
        for (name, params) in maps {
            let map = emitter("envmap", params, None);
            let (mut compared, mut lit) = (0usize, 0usize);
            let references = [
                ReferencePoint {
                    position: Vec3::ZERO,
                },
                ReferencePoint {
                    position: Vec3::new(1.0, 2.0, 3.0),
                },
            ];
            for round in 0..12 {
                for len in LENGTHS {
                    let wi: Vec<Vec3> = (0..len)
                        .map(|k| match (k + round) % 3 {
                            0 => special[(k + round) % special.len()],
                            _ => {
                                let u = s.next_2d();
                                let z = 1.0 - 2.0 * u.x;
                                let r = (1.0 - z * z).max(0.0).sqrt();
                                let phi = std::f32::consts::TAU * u.y;
                                Vec3::new(r * phi.cos(), r * phi.sin(), z)
                            }
                        })
                        .collect();
                    // One reference point in even rounds, one per direction in odd ones.
                    let each: Vec<ReferencePoint> = (0..len)
                        .map(|k| references[(round % 2) * (k % 2)])
                        .collect();
                    let reference_argument = match round % 2 {
                        0 => &references[..1],
                        _ => &each[..],
                    };
                    let mut out = vec![(Rgb::NAN, f32::NAN); len];
                    map.eval_pdf_batch(reference_argument, &wi, &mut out);
                    for (k, (&wi, &batch)) in wi.iter().zip(&out).enumerate() {
                        let single = map.eval_pdf(&each[k], wi, None);
                        assert_eq!(
                            bits(batch),
                            bits(single),
                            "{name}, {width} lanes: batch of {len}, element {k}, ωi {wi:?}: \
                             batch {batch:?}, single {single:?}"
                        );
                        compared += 1;
                        lit += (single.1 > 0.0) as usize;
                    }
                }
            }
            assert!(
                lit > compared / 2,
                "{name}: only {lit} of {compared} lookups lit"
            );
        }
    }
    limit_width(DEFAULT_WIDTH);
}
