//! Point, spot and directional lights are Dirac deltas: flagged as such (integrators then skip BSDF
//! sampling toward them), reached by no ray (`eval` and `pdf_direction` are zero in every
//! direction), and their one sample per point carries all their light (its irradiance is tested
//! in `emitters.rs`). Area and environment lights are not deltas.

use glam::{Vec2, Vec3};
use lumis_core::emitter::{Emitter, EmitterContext, EmitterHit, ReferencePoint};
use lumis_core::geometry::{self, ShapeGeometry};
use lumis_core::params::Params;
use lumis_core::registry::{self, EmitterPlugin};
use std::sync::Arc;

fn emitter(kind: &str, params: &str, shape: Option<&ShapeGeometry>) -> Arc<dyn Emitter> {
    lumis_emitters::link();
    let plugin = registry::find::<EmitterPlugin>(kind).unwrap();
    let values = ron::from_str(&format!("{{{params}}}")).unwrap();
    let mut p = Params::new(kind, plugin.params, values)
        .unwrap()
        .with_base_dir(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../.."));
    (plugin.create)(&mut p, &EmitterContext { shape }).unwrap()
}

#[test]
fn delta_lights_are_flagged_and_reached_by_no_ray() {
    let reference = ReferencePoint {
        position: Vec3::new(0.5, -1.0, 2.0),
    };
    let hit = EmitterHit {
        position: Vec3::new(1.0, 3.0, 0.0),
        normal: Vec3::Y,
        distance: 2.0,
    };
    for light in [
        emitter("point", "\"position\": (1, 3, 0), \"intensity\": 4", None),
        emitter(
            "directional",
            "\"direction\": (0, -1, -1), \"irradiance\": 5",
            None,
        ),
        emitter(
            "spot",
            "\"position\": (1, 3, 0), \"direction\": (-0.5, -4, 2), \"intensity\": 4",
            None,
        ),
    ] {
        assert!(light.is_delta());
        // Whatever the direction, even the light's own, and with or without a surface hit.
        let toward = light
            .sample_direction(&reference, Vec2::splat(0.5))
            .unwrap()
            .wi;
        for wi in [toward, Vec3::Y, -toward, Vec3::new(0.6, 0.0, 0.8)] {
            for h in [None, Some(&hit)] {
                assert_eq!(light.pdf_direction(&reference, wi, h), 0.0);
                assert_eq!(light.eval(wi, h), Vec3::ZERO);
            }
        }
    }
    let square = ShapeGeometry::Mesh(geometry::rectangle());
    assert!(!emitter("area", "\"radiance\": 1", Some(&square)).is_delta());
    assert!(!emitter("envmap", "\"file\": \"scenes/envmaps/studio.exr\"", None).is_delta());
    assert!(!emitter("constant", "\"radiance\": 1", None).is_delta());
}

/// `scale` multiplies a delta light's intensity or irradiance; a point light out of f32 range
/// (its squared distance overflows) or at the shading point gives no sample.
#[test]
fn delta_light_samples_carry_their_scaled_power() {
    let reference = ReferencePoint {
        position: Vec3::new(1.0, 0.0, 4.0),
    };
    let point = emitter(
        "point",
        "\"position\": (1, 3, 0), \"intensity\": (4, 8, 12), \"scale\": 0.5",
        None,
    );
    let sample = point.sample_direction(&reference, Vec2::ZERO).unwrap();
    assert_eq!(sample.radiance, Vec3::new(2.0, 4.0, 6.0) / 25.0);
    assert_eq!(sample.pdf, 1.0);
    let sun = emitter(
        "directional",
        "\"direction\": (0, -1, 0), \"irradiance\": 5, \"scale\": 3",
        None,
    );
    let sample = sun.sample_direction(&reference, Vec2::ZERO).unwrap();
    assert_eq!((sample.radiance, sample.wi), (Vec3::splat(15.0), Vec3::Y));
    // A light so far that its squared distance leaves f32 is refused by its parameter range
    // (the sampler's own guard stays behind it).
    let plugin = registry::find::<EmitterPlugin>("point").unwrap();
    let values = ron::from_str("{\"position\": (3e19, 0, 0), \"intensity\": 1}").unwrap();
    let mut params = Params::new("point", plugin.params, values).unwrap();
    let error = (plugin.create)(&mut params, &EmitterContext { shape: None })
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(error.contains("position"), "{error}");
    let here = ReferencePoint {
        position: Vec3::new(1.0, 3.0, 0.0),
    };
    assert!(point.sample_direction(&here, Vec2::ZERO).is_none());
}
