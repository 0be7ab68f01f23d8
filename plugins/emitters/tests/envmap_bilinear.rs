//! `envmap` with `interpolation: "bilinear"` and `orientation: "mitsuba"`: chi-square of the
//! piecewise-bilinear warp against its density, samples that agree with `eval` and `pdf`,
//! Mitsuba 3's texel placement, and furnace checks (a uniform map gives πL; a varied map gives
//! the irradiance that quadrature of `eval` gives).

use glam::{Vec2, Vec3};
use lumis_core::chi2::{Chi2Test, FAMILY_FALSE_ALARM, sidak, test_seed};
use lumis_core::emitter::{Emitter, EmitterContext, ReferencePoint};
use lumis_core::math::Rgb;
use lumis_core::params::Params;
use lumis_core::registry::{self, EmitterPlugin};
use lumis_core::sampler::Sampler;
use lumis_emitters::envmap::{EnvironmentMap, Interpolation, MapSettings, Orientation};
use std::f64::consts::PI;
use std::sync::Arc;

fn emitter(params: &str) -> Arc<dyn Emitter> {
    lumis_emitters::link();
    let plugin = registry::find::<EmitterPlugin>("envmap").unwrap();
    let values = ron::from_str(&format!("{{{params}}}")).unwrap();
    let mut p = Params::new("envmap", plugin.params, values)
        .unwrap()
        .with_base_dir(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../.."));
    let e = (plugin.create)(&mut p, &EmitterContext { shape: None }).unwrap();
    p.finish().unwrap();
    e
}

fn bilinear(w: usize, h: usize, pixels: Vec<Rgb>, rotation: f32) -> EnvironmentMap {
    let settings = MapSettings {
        rotation_degrees: rotation,
        interpolation: Interpolation::Bilinear,
        orientation: Orientation::Mitsuba,
        ..MapSettings::default()
    };
    EnvironmentMap::with_settings(w, h, pixels, &settings).unwrap()
}

/// Pixels drawn from a fixed stream: positive, varied by two orders of magnitude.
fn varied_pixels(w: usize, h: usize, stream: u64) -> Vec<Rgb> {
    let mut s = Sampler::new(test_seed(), stream, 0);
    (0..w * h)
        .map(|_| {
            let u = s.next_2d();
            let level = 10f32.powf(2.0 * u.x - 1.0);
            Rgb::new(level, level * (0.5 + u.y), level * (1.5 - u.y))
        })
        .collect()
}

/// A black map but for pixel (x, y).
fn hot_pixel(w: usize, h: usize, x: usize, y: usize) -> Vec<Rgb> {
    let mut pixels = vec![Rgb::ZERO; w * h];
    pixels[y * w + x] = Rgb::new(50.0, 40.0, 30.0);
    pixels
}

/// Mitsuba 3's direction of map coordinates (u, v) (its `uv_to_direction`), written from its
/// convention rather than from lumis' code: φ = 2πu, θ = πv.
fn mitsuba_direction(u: f64, v: f64) -> Vec3 {
    let (phi, theta) = (2.0 * PI * u, PI * v);
    Vec3::new(
        (phi.sin() * theta.sin()) as f32,
        theta.cos() as f32,
        (-phi.cos() * theta.sin()) as f32,
    )
}

const ORIGIN: ReferencePoint = ReferencePoint {
    position: Vec3::ZERO,
};

type Case = (String, Arc<dyn Emitter>, Chi2Test);

#[test]
fn bilinear_sampling_passes_chi_square() {
    let mut cases: Vec<Case> = Vec::new();
    let test = |axis: Vec3, cos_cap: f64| Chi2Test {
        axis,
        cos_cap,
        seed: test_seed(),
        ..Chi2Test::default()
    };
    // A real HDR map, turned, over the whole sphere.
    cases.push((
        "studio".into(),
        emitter(
            "\"file\": \"scenes/envmaps/studio.exr\", \"rotation\": 30, \
             \"interpolation\": \"bilinear\", \"orientation\": \"mitsuba\"",
        ),
        test(Vec3::Y, -1.0),
    ));
    // A small varied map: few patches, large ones, both poles inside one row of patches each.
    cases.push((
        "varied 5x3".into(),
        Arc::new(bilinear(5, 3, varied_pixels(5, 3, 1), 0.0)),
        test(Vec3::new(0.3, 0.2, 0.9).normalize(), -1.0),
    ));
    // One hot pixel spreads over the four patches around it: binned in a cap about it.
    let (w, h) = (64, 33);
    let hot_u = (20.0 + 0.5) / w as f64;
    let hot_v = 9.0 / (h - 1) as f64;
    cases.push((
        "hot pixel".into(),
        Arc::new(bilinear(w, h, hot_pixel(w, h, 20, 9), 0.0)),
        test(mitsuba_direction(hot_u, hot_v), 0.15f64.cos()),
    ));
    // A hot pixel in the last column: its patches wrap across the seam to column 0.
    let seam_u = (w as f64 - 0.5) / w as f64;
    cases.push((
        "hot pixel on the seam".into(),
        Arc::new(bilinear(w, h, hot_pixel(w, h, w - 1, 16), -75.0)),
        test(
            {
                // The map is turned by −75° about y.
                let d = mitsuba_direction(seam_u, 0.5);
                let (s, c) = (-75f32).to_radians().sin_cos();
                Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
            },
            0.15f64.cos(),
        ),
    ));
    // A hot pixel next to the pole: the patches between it and the pole have zero weight on
    // the pole's row.
    cases.push((
        "hot pixel by the pole".into(),
        Arc::new(bilinear(w, h, hot_pixel(w, h, 7, 1), 0.0)),
        test(Vec3::Y, 0.25f64.cos()),
    ));
    let alpha = sidak(FAMILY_FALSE_ALARM, cases.len());
    for (name, light, test) in &cases {
        test.run(
            |s| light.sample_direction(&ORIGIN, s.next_2d()).map(|ls| ls.wi),
            |wi| light.pdf_direction(&ORIGIN, wi, None) as f64,
        )
        .assert_passes(alpha, name);
    }
}

/// A sample's radiance and density are those `eval` and `pdf_direction` give its direction.
#[test]
fn bilinear_samples_agree_with_eval_and_pdf() {
    let maps: Vec<(&str, Arc<dyn Emitter>)> = vec![
        (
            "studio",
            emitter("\"file\": \"scenes/envmaps/studio.exr\", \"interpolation\": \"bilinear\""),
        ),
        (
            "varied",
            Arc::new(bilinear(7, 4, varied_pixels(7, 4, 2), 12.0)),
        ),
    ];
    for (name, map) in maps {
        let mut s = Sampler::new(test_seed(), 3, 3);
        let mut accepted = 0;
        for _ in 0..20_000 {
            let Some(ls) = map.sample_direction(&ORIGIN, s.next_2d()) else {
                continue;
            };
            accepted += 1;
            let pdf = map.pdf_direction(&ORIGIN, ls.wi, None);
            assert!(
                (pdf - ls.pdf).abs() <= 1e-3 * ls.pdf,
                "{name}: pdf {pdf} vs {}",
                ls.pdf
            );
            assert_eq!(map.eval(ls.wi, None), ls.radiance, "{name}");
            assert!(ls.radiance.min_element() >= 0.0 && ls.radiance.is_finite());
        }
        assert!(accepted > 19_900, "{name}: {accepted} samples accepted");
    }
}

/// Pixel (i, j) is read at Mitsuba's u = (i + ½)/W, θ = πj/(H − 1), and halfway between two
/// pixels (across the seam too) the radiance is their mean.
#[test]
fn bilinear_places_pixels_as_mitsuba() {
    let (w, h) = (6, 5);
    let pixels = varied_pixels(w, h, 3);
    let map = bilinear(w, h, pixels.clone(), 0.0);
    let close = |a: Rgb, b: Rgb| (a - b).abs().max_element() <= 1e-4 * b.max_element();
    for j in 1..h - 1 {
        let v = j as f64 / (h - 1) as f64;
        for i in 0..w {
            let d = mitsuba_direction((i as f64 + 0.5) / w as f64, v);
            let at = map.eval(d, None);
            assert!(close(at, pixels[j * w + i]), "pixel ({i}, {j}): {at}");
            let next = (i + 1) % w;
            let mid = mitsuba_direction((i as f64 + 1.0) / w as f64, v);
            let expected = (pixels[j * w + i] + pixels[j * w + next]) * 0.5;
            assert!(
                close(map.eval(mid, None), expected),
                "between ({i}, {j}) and next"
            );
        }
    }
    // A quarter of the way from row 1 to row 2.
    let d = mitsuba_direction(2.5 / w as f64, 1.25 / (h - 1) as f64);
    let expected = pixels[w + 2] * 0.75 + pixels[2 * w + 2] * 0.25;
    assert!(close(map.eval(d, None), expected));
    // The first row sits on the pole: straight up reads between row 0's pixels only.
    let top = map.eval(Vec3::Y, None);
    let row0 = &pixels[..w];
    let lo = row0
        .iter()
        .fold(Rgb::splat(f32::INFINITY), |a, p| a.min(*p));
    let hi = row0.iter().fold(Rgb::ZERO, |a, p| a.max(*p));
    assert!(
        top.cmpge(lo * 0.9999).all() && top.cmple(hi * 1.0001).all(),
        "pole reads {top}, row 0 spans {lo}..{hi}"
    );
}

/// Irradiance on a surface with normal n at the origin, by light sampling: mean and standard
/// error.
fn irradiance(light: &dyn Emitter, n: Vec3, samples: usize) -> (f64, f64) {
    let mut s = Sampler::new(test_seed(), 17, 0);
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for _ in 0..samples {
        let v = light
            .sample_direction(&ORIGIN, s.next_2d())
            .map_or(0.0, |ls| {
                (ls.radiance.y * ls.wi.dot(n).max(0.0) / ls.pdf) as f64
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
fn uniform_bilinear_map_gives_pi_l_furnace() {
    let radiance = 1.7f32;
    let map = bilinear(32, 17, vec![Rgb::splat(radiance); 32 * 17], 40.0);
    for n in [Vec3::Y, Vec3::new(0.6, -0.3, 0.7).normalize(), -Vec3::Y] {
        let (e, se) = irradiance(&map, n, 200_000);
        let expected = PI * radiance as f64;
        assert!(
            se < 0.01 * expected && (e - expected).abs() < 4.0 * se,
            "n = {n}: E = {e} ± {se}, expected {expected}"
        );
    }
}

/// Irradiance of a varied map by light sampling against midpoint quadrature of `eval` over the
/// sphere in (φ, θ), whose error (the map is smooth within patches, 4000 × 2000 nodes) is far
/// below the sampling's.
#[test]
fn varied_bilinear_map_irradiance_matches_quadrature() {
    let (w, h) = (8, 5);
    let map = bilinear(w, h, varied_pixels(w, h, 4), 20.0);
    for n in [Vec3::Y, Vec3::new(-0.5, 0.2, 0.8).normalize()] {
        let (nu, nv) = (4000, 2000);
        let mut quadrature = 0.0f64;
        for j in 0..nv {
            let theta = PI * (j as f64 + 0.5) / nv as f64;
            for i in 0..nu {
                let phi = 2.0 * PI * (i as f64 + 0.5) / nu as f64;
                let d = Vec3::new(
                    (theta.sin() * phi.sin()) as f32,
                    theta.cos() as f32,
                    (theta.sin() * phi.cos()) as f32,
                );
                quadrature += map.eval(d, None).y as f64 * d.dot(n).max(0.0) as f64 * theta.sin();
            }
        }
        quadrature *= (PI / nv as f64) * (2.0 * PI / nu as f64);
        let (e, se) = irradiance(&map, n, 400_000);
        assert!(
            (e - quadrature).abs() < 4.0 * se && se < 0.01 * quadrature,
            "n = {n}: sampled {e} ± {se}, quadrature {quadrature}"
        );
    }
}

#[test]
fn bilinear_needs_two_rows_and_black_maps_are_never_sampled() {
    let settings = MapSettings {
        interpolation: Interpolation::Bilinear,
        ..MapSettings::default()
    };
    let err = EnvironmentMap::with_settings(4, 1, vec![Rgb::ONE; 4], &settings)
        .err()
        .unwrap();
    assert!(err.contains("at least 2 pixels high"), "{err}");
    let black = bilinear(4, 3, vec![Rgb::ZERO; 12], 0.0);
    assert!(black.sample_direction(&ORIGIN, Vec2::splat(0.3)).is_none());
    assert_eq!(black.pdf_direction(&ORIGIN, Vec3::X, None), 0.0);
}
