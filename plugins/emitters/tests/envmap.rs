//! The tests of `lumis_emitters::envmap` (`plugins/emitters/src/envmap.rs`).

use glam::{Vec2, Vec3};
use lumis_core::emitter::{Emitter, ReferencePoint};
use lumis_core::math::Rgb;
use lumis_emitters::envmap::*;
use std::f32::consts::TAU;

fn map(rotation: f32) -> EnvironmentMap {
    EnvironmentMap::new(8, 4, vec![Rgb::ONE; 32], 1.0, rotation)
}

#[test]
fn directions_and_map_coordinates_round_trip_at_poles_and_seam() {
    for rotation in [0.0, 30.0, -135.0] {
        let m = map(rotation);
        for uv in [
            Vec2::new(0.5, 0.5),
            Vec2::new(1e-6, 0.3),
            Vec2::new(1.0 - 1e-6, 0.7),
            Vec2::new(0.25, 1e-5),
            Vec2::new(0.75, 1.0 - 1e-5),
        ] {
            let d = m.to_direction(uv);
            assert!((d.length() - 1.0).abs() < 1e-5);
            let (back, _) = m.to_uv(d);
            // At the poles u is undefined; elsewhere u wraps at the seam.
            let du = (back.x - uv.x).abs();
            let pole = uv.y < 1e-4 || uv.y > 1.0 - 1e-4;
            assert!(
                pole || du.min(1.0 - du) < 1e-4,
                "rotation {rotation}: {uv} -> {d} -> {back}"
            );
            assert!(
                (back.y - uv.y).abs() < 1e-3,
                "rotation {rotation}: {uv} -> {back}"
            );
        }
    }
}

/// The prefetch's coordinates: within 3e-5 of the exact ones over the sphere (poles and
/// seam included), so that it reads the texel `eval` reads but where a pixel's edge lies
/// closer than that.
#[test]
fn approximate_coordinates_are_close_to_the_exact_ones() {
    let mut sampler = lumis_core::sampler::Sampler::new(7, 0, 0);
    for rotation in [0.0, 30.0, -135.0] {
        let m = map(rotation);
        let (mut worst_u, mut worst_v) = (0.0f32, 0.0f32);
        for i in 0..200_000 {
            let u = sampler.next_2d();
            let z = if i % 100 == 0 {
                1.0 - 1e-6 * u.x
            } else {
                1.0 - 2.0 * u.x
            };
            let r = (1.0 - z * z).max(0.0).sqrt();
            let (sin, cos) = (TAU * u.y).sin_cos();
            let d = Vec3::new(r * cos, z, r * sin);
            let (exact, _) = m.to_uv(d);
            let approximate = m.approximate_uv(d);
            let du = (exact.x - approximate.x).abs();
            // u wraps at the seam; at the poles it is undefined.
            if r > 1e-3 {
                worst_u = worst_u.max(du.min(1.0 - du));
            }
            worst_v = worst_v.max((exact.y - approximate.y).abs());
        }
        assert!(
            worst_u < 3e-5 && worst_v < 3e-5,
            "rotation {rotation}: {worst_u}, {worst_v}"
        );
    }
}

/// A turn about any axis carries the map's directions as that rotation does: about +x by
/// 90°, the map's up (+y) looks along +z; about (1, 1, 1) by 120°, +x goes to +y; about an
/// axis a hair off +y (the general frame) as about +y (the turn's own arithmetic), within
/// f32 rounding; and map coordinates of a turned direction come back to where they were.
#[test]
fn turns_about_any_axis_carry_directions_as_the_rotation_does() {
    let turned = |degrees: f32, axis: Vec3, orientation| {
        let settings = MapSettings {
            rotation_degrees: degrees,
            rotation_axis: axis,
            orientation,
            ..MapSettings::default()
        };
        EnvironmentMap::with_settings(8, 4, vec![Rgb::ONE; 32], &settings).unwrap()
    };
    let up = Vec2::new(0.3, 0.0);
    let about_x = turned(90.0, Vec3::X, Orientation::Lumis);
    assert!(about_x.to_direction(up).abs_diff_eq(Vec3::Z, 1e-6));
    let diagonal = turned(120.0, Vec3::ONE, Orientation::Lumis);
    // The map's −x (u = 1/4 on the equator) goes where a turn of (1, 1, 1) takes −x: −y.
    let quarter = Vec2::new(0.25, 0.5);
    assert!(
        diagonal
            .to_direction(quarter)
            .abs_diff_eq(Vec3::NEG_Y, 1e-6),
        "{}",
        diagonal.to_direction(quarter)
    );
    for orientation in [Orientation::Lumis, Orientation::Mitsuba] {
        for degrees in [0.0, 30.0, -135.0] {
            let general = turned(degrees, Vec3::new(1e-6, 1.0, 0.0), orientation);
            let about_y = turned(degrees, Vec3::Y, orientation);
            assert!(general.has_general_frame() && !about_y.has_general_frame());
            for uv in [
                Vec2::new(0.5, 0.5),
                Vec2::new(0.1, 0.3),
                Vec2::new(0.8, 0.9),
            ] {
                let (a, b) = (general.to_direction(uv), about_y.to_direction(uv));
                assert!(a.abs_diff_eq(b, 1e-5), "{degrees}: {a} vs {b}");
                let (back, _) = general.to_uv(a);
                assert!(back.abs_diff_eq(uv, 1e-5), "{degrees}: {back} vs {uv}");
            }
        }
    }
    let flat = MapSettings {
        rotation_axis: Vec3::ZERO,
        ..MapSettings::default()
    };
    let e = EnvironmentMap::with_settings(8, 4, vec![Rgb::ONE; 32], &flat)
        .map(|_| ())
        .unwrap_err();
    assert!(e.contains("rotation_axis"), "{e}");
}

#[test]
fn mapping_follows_the_documented_convention() {
    let m = map(0.0);
    for (uv, expected) in [
        (Vec2::new(0.5, 0.5), -Vec3::Z),
        (Vec2::new(0.0, 0.5), Vec3::Z),
        (Vec2::new(0.25, 0.5), -Vec3::X),
        (Vec2::new(0.3, 0.0), Vec3::Y),
    ] {
        let d = m.to_direction(uv);
        assert!(
            d.abs_diff_eq(expected, 1e-6),
            "{uv} gives {d}, not {expected}"
        );
    }
    // Mitsuba's orientation: centre toward +z, first quarter toward +x.
    let settings = MapSettings {
        orientation: Orientation::Mitsuba,
        ..MapSettings::default()
    };
    let mi = EnvironmentMap::with_settings(8, 4, vec![Rgb::ONE; 32], &settings).unwrap();
    assert!(
        mi.to_direction(Vec2::new(0.5, 0.5))
            .abs_diff_eq(Vec3::Z, 1e-6)
    );
    assert!(
        mi.to_direction(Vec2::new(0.25, 0.5))
            .abs_diff_eq(Vec3::X, 1e-6)
    );
    // Rotating by 90 degrees about +y carries the centre (-z) to -x.
    let r = map(90.0);
    assert!(
        r.to_direction(Vec2::new(0.5, 0.5))
            .abs_diff_eq(-Vec3::X, 1e-6)
    );
}

/// A map with a smooth gradient, a bright spot and a dim band: parts above and below its
/// mean.
fn varied_map(settings: &MapSettings) -> EnvironmentMap {
    let (w, h) = (48, 24);
    let pixels = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let spot = if (x - 30.0).abs() < 3.0 && (y - 8.0).abs() < 2.0 {
                40.0
            } else {
                0.0
            };
            Rgb::new(0.2 + 0.02 * x + spot, 0.5 + spot, 0.1 * y + spot)
        })
        .collect();
    EnvironmentMap::with_settings(w, h, pixels, settings).unwrap()
}

/// Compensated sampling has the density `pdf_direction` reports (chi-square, both
/// interpolations), and it differs from uncompensated sampling as intended: relatively more
/// density on the bright spot, the floor Ȳ/100 (relative to the map's mean) elsewhere.
#[test]
fn compensated_sampling_matches_its_pdf() {
    let r = ReferencePoint {
        position: Vec3::ZERO,
    };
    let mut outcomes = Vec::new();
    for interpolation in [Interpolation::Nearest, Interpolation::Bilinear] {
        let settings = MapSettings {
            interpolation,
            compensation: true,
            ..MapSettings::default()
        };
        let map = varied_map(&settings);
        let plain = varied_map(&MapSettings {
            interpolation,
            ..MapSettings::default()
        });
        let test = lumis_core::chi2::Chi2Test::default();
        outcomes.push((
            format!("compensated {interpolation:?}"),
            test.run(
                |s| map.sample_direction(&r, s.next_2d()).map(|ls| ls.wi),
                |wi| map.pdf_direction(&r, wi, None) as f64,
            ),
        ));
        // The spot's centre gains density, a dim direction loses it.
        let spot = map.to_direction(Vec2::new(30.5 / 48.0, 8.5 / 24.0));
        let dim = map.to_direction(Vec2::new(2.5 / 48.0, 1.5 / 24.0));
        let pdf = |m: &EnvironmentMap, d| m.pdf_direction(&r, d, None);
        assert!(pdf(&map, spot) > pdf(&plain, spot), "{interpolation:?}");
        assert!(pdf(&map, dim) < pdf(&plain, dim), "{interpolation:?}");
        assert!(
            pdf(&map, dim) > 0.0,
            "{interpolation:?}: the floor keeps it reachable"
        );
    }
    let alpha = lumis_core::chi2::sidak(0.01, outcomes.len());
    for (name, outcome) in &outcomes {
        outcome.assert_passes(alpha, name);
    }
}

/// A constant map is all at its mean: compensated, every pixel has the same (floor) weight,
/// so it is sampled as the plain map is, uniformly over the sphere's cells.
#[test]
fn a_constant_map_is_sampled_as_without_compensation() {
    let r = ReferencePoint {
        position: Vec3::ZERO,
    };
    for interpolation in [Interpolation::Nearest, Interpolation::Bilinear] {
        let make = |compensation| {
            let settings = MapSettings {
                interpolation,
                compensation,
                ..MapSettings::default()
            };
            EnvironmentMap::with_settings(16, 8, vec![Rgb::splat(2.0); 128], &settings).unwrap()
        };
        let (compensated, plain) = (make(true), make(false));
        for d in [
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.8).normalize(),
            Vec3::new(0.1, 0.9, -0.2).normalize(),
        ] {
            let (a, b) = (
                compensated.pdf_direction(&r, d, None),
                plain.pdf_direction(&r, d, None),
            );
            assert!(
                b > 0.0 && (a / b - 1.0).abs() < 1e-4,
                "{interpolation:?} {d}: {a} vs {b}"
            );
        }
    }
}
