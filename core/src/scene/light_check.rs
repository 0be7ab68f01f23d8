//! Warnings (not errors) for scenes that cannot produce light, checked when a scene is loaded:
//! a scene with no emitter, or one where no light can reach the camera.
//!
//! The check follows the paths the renderer's integrators sample, all of which end after one
//! bounce (direct lighting): camera rays through a grid of pixel centres over the rendered
//! window, and at each point they hit, a few light samples of every emitter (lit, facing, and
//! unoccluded toward a BSDF that reflects or transmits there) and a few BSDF samples (reaching an emitter
//! or an environment that is not black). The first such path ends the check; a scene where none
//! is found gets a warning. It is a sample, so a light seen through a handful of pixels only can
//! be missed (the warning says "likely"); its cost is bounded by [`MAX_PROBE_RAYS`].

use super::Scene;
use crate::bsdf::{BsdfContext, Side};
use crate::emitter::{EmitterHit, ReferencePoint};
use crate::geometry::{Intersection, Ray};
use crate::math::{Frame, Rgb};
use glam::{Vec2, Vec3};

/// Largest number of rays the check traces (about 0.1 s on one core).
pub const MAX_PROBE_RAYS: usize = 1 << 19;

/// Light and BSDF samples per hit point (per emitter for light samples).
const SAMPLES: usize = 4;

/// The warnings for `scene`, each a sentence.
pub fn light_warnings(scene: &Scene) -> Vec<String> {
    if scene.emitters.is_empty() {
        return vec![
            "the scene has no emitter (no shape has an `emitter` and `emitters` is empty): the image will be black"
                .into(),
        ];
    }
    let per_point = 1 + SAMPLES * (scene.emitters.len() + 1);
    let points = (MAX_PROBE_RAYS / per_point).clamp(16, 64 * 64);
    let grid = (points as f64).sqrt() as u32;
    let window = scene.window;
    let (nx, ny) = (grid.min(window.width), grid.min(window.height));
    for j in 0..ny {
        for i in 0..nx {
            let film = Vec2::new(
                window.x as f32 + (i as f32 + 0.5) * window.width as f32 / nx as f32,
                window.y as f32 + (j as f32 + 0.5) * window.height as f32 / ny as f32,
            );
            if light_along(scene, &scene.camera.generate_ray(film)) {
                return Vec::new();
            }
        }
    }
    vec![format!(
        "no light is likely to reach the camera: of {} camera rays over the image, none sees an emitter, \
         nor a surface that an emitter lights directly (every integrator stops after one bounce); \
         the image will likely be black",
        nx * ny
    )]
}

/// Stratified points of the unit square, the same for every hit point.
fn square_samples() -> [Vec2; SAMPLES] {
    std::array::from_fn(|k| {
        let u = (k as f32 + 0.5) / SAMPLES as f32;
        // The golden ratio spreads the second coordinate.
        Vec2::new(u, (k as f32 * 0.618_034 + 0.31).fract())
    })
}

/// Whether the camera ray `ray` carries light: it sees an emitter, or a surface that reflects
/// some emitter's light toward it (one bounce).
fn light_along(scene: &Scene, ray: &Ray) -> bool {
    let hit = scene.intersect(ray);
    if emits_back(scene, ray, hit.as_ref()) {
        return true;
    }
    let Some(hit) = hit else {
        return false;
    };
    let wo_world = -ray.direction;
    let back = hit.geometric_normal.dot(wo_world) < 0.0;
    let (sign, side) = if back {
        (-1.0, Side::Back)
    } else {
        (1.0, Side::Front)
    };
    let frame = Frame::from_normal(sign * hit.shading_normal);
    let normal = sign * hit.geometric_normal;
    let wo = frame.to_local(wo_world);
    let (bsdf, flags) = scene.bsdf_seen_from(&hit, side);
    let uv = if flags.spatially_varying() {
        scene.geometry.uv(&hit)
    } else {
        Vec2::ZERO
    };
    let ctx = BsdfContext::new(uv, side);
    // As the shading point: ωi must leave on the side of the geometric surface its local z
    // says (the viewer's for reflection, the far one for transmission).
    let consistent = |wi: Vec3, local: Vec3| {
        let height = normal.dot(wi);
        (height > 0.0 && local.z > 0.0) || (height < 0.0 && local.z < 0.0)
    };
    let reference = ReferencePoint {
        position: hit.position,
    };
    for emitter in &scene.emitters {
        for u in square_samples() {
            let Some(sample) = emitter.sample_direction(&reference, u) else {
                continue;
            };
            let local = frame.to_local(sample.wi);
            if !nonzero(sample.radiance) || !consistent(sample.wi, local) {
                continue;
            }
            if !nonzero(bsdf.eval(&ctx, wo, local)) {
                continue;
            }
            let shadow = match sample.position {
                Some(target) => hit.spawn_ray_to(target),
                None => hit.spawn_ray(sample.wi),
            };
            if !scene.occluded(&shadow) {
                return true;
            }
        }
    }
    for (k, u) in square_samples().into_iter().enumerate() {
        let u_lobe = (k as f32 + 0.5) / SAMPLES as f32;
        let Some(s) = bsdf.sample(&ctx, wo, u_lobe, u) else {
            continue;
        };
        let wi = frame.to_world(s.wi);
        if !consistent(wi, s.wi) || !nonzero(s.weight) {
            continue;
        }
        let ray = hit.spawn_ray(wi);
        if emits_back(scene, &ray, scene.intersect(&ray).as_ref()) {
            return true;
        }
    }
    false
}

/// Whether `ray`, which ends at `hit`, ends on an emitter that sends light back along it (or
/// leaves the scene into a non-black environment).
fn emits_back(scene: &Scene, ray: &Ray, hit: Option<&Intersection>) -> bool {
    let Some(hit) = hit else {
        return nonzero(scene.environment_radiance(ray.direction));
    };
    scene.emitter_of(hit).is_some_and(|e| {
        let at = EmitterHit {
            position: hit.position,
            normal: hit.geometric_normal,
            distance: hit.t,
        };
        nonzero(scene.emitters[e].eval(ray.direction, Some(&at)))
    })
}

fn nonzero(c: Rgb) -> bool {
    c.max_element() > 0.0
}
