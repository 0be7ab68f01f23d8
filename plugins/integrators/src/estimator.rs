//! The per-light direct-lighting estimator every MIS integrator is built on.
//!
//! At a shading point x with outgoing direction ωo and one non-delta light j, it draws `n_bsdf`
//! directions from the BSDF and `n_light` from the light and forms the multi-sample balance
//! heuristic estimate, which equals the mixture ("defensive") estimator
//!
//! ```text
//!   L̂_j = Σ_i f(ω_i) / (n_bsdf · p_B(ω_i) + n_light · p_L(ω_i))
//! ```
//!
//! over all n_bsdf + n_light samples, f = BSDF · cos · L_e,j · V. A BSDF sample counts for light
//! j only if it reaches light j. A delta BSDF sample (a mirror) has no density to compare: only
//! BSDF sampling can produce it, so it contributes weight · L_e / n_bsdf.

use glam::{UVec2, Vec3};
use lumis_core::accel::Intersection;
use lumis_core::bsdf::Bsdf;
use lumis_core::emitter::{EmitterHit, ReferencePoint};
use lumis_core::math::{Frame, Rgb};
use lumis_core::sampler::Sampler;
use lumis_core::scene::Scene;

/// A surface point seen by the camera, with its shading frame turned toward the viewer
/// (surfaces are two-sided).
pub struct ShadingPoint<'a> {
    pub hit: Intersection,
    pub frame: Frame,
    /// Geometric normal on the viewer's side.
    pub normal: Vec3,
    /// ωo in the local shading frame.
    pub wo: Vec3,
    pub bsdf: &'a dyn Bsdf,
}

impl<'a> ShadingPoint<'a> {
    pub fn new(scene: &'a Scene, hit: Intersection, wo_world: Vec3) -> Self {
        let flip = hit.geometric_normal.dot(wo_world) < 0.0;
        let sign = if flip { -1.0 } else { 1.0 };
        let frame = Frame::from_normal(sign * hit.shading_normal);
        ShadingPoint {
            frame,
            normal: sign * hit.geometric_normal,
            wo: frame.to_local(wo_world),
            bsdf: scene.bsdf(&hit),
            hit,
        }
    }

    /// Reflection only: ωi must leave on the viewer's side of the geometric surface, or shading
    /// normals would let light leak through.
    #[inline]
    fn reflects_toward(&self, wi_world: Vec3) -> bool {
        self.normal.dot(wi_world) > 0.0
    }
}

/// How many samples of each technique one light receives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleSplit {
    pub n_bsdf: u32,
    pub n_light: u32,
}

/// The balance-heuristic estimate of the radiance reflected at `sp` from light `light`.
pub fn estimate_light(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    split: SampleSplit,
    sampler: &mut Sampler,
) -> Rgb {
    let emitter = scene.emitters[light].as_ref();
    let reference = ReferencePoint {
        position: sp.hit.position,
    };
    let (n_b, n_l) = (split.n_bsdf as f32, split.n_light as f32);
    let mut sum = Rgb::ZERO;

    for _ in 0..split.n_bsdf {
        let (u_lobe, u) = (sampler.next_1d(), sampler.next_2d());
        let Some(s) = sp.bsdf.sample(sp.wo, u_lobe, u) else {
            continue;
        };
        let wi = sp.frame.to_world(s.wi);
        if !sp.reflects_toward(wi) {
            continue;
        }
        let Some(hit) = scene.intersect(&sp.hit.spawn_ray(wi)) else {
            continue;
        };
        if scene.emitter_of(&hit) != Some(light) {
            continue;
        }
        let emitter_hit = EmitterHit {
            position: hit.position,
            normal: hit.geometric_normal,
            distance: hit.t,
        };
        let le = emitter.eval(wi, Some(&emitter_hit));
        if le == Rgb::ZERO {
            continue;
        }
        if s.delta {
            // Light sampling cannot produce a Dirac direction: the BSDF technique takes it all.
            sum += s.weight * le / n_b;
            continue;
        }
        let p_light = emitter.pdf_direction(&reference, wi, Some(&emitter_hit));
        // f / (n_B p_B + n_L p_L), with f = weight · p_B.
        sum += s.weight * le * (s.pdf / (n_b * s.pdf + n_l * p_light));
    }

    for _ in 0..split.n_light {
        let Some(ls) = emitter.sample_direction(&reference, sampler.next_2d()) else {
            continue;
        };
        if !sp.reflects_toward(ls.wi) {
            continue;
        }
        let wi = sp.frame.to_local(ls.wi);
        let f = sp.bsdf.eval(sp.wo, wi);
        if f == Rgb::ZERO {
            continue;
        }
        let Some(target) = ls.position else { continue };
        if scene.occluded(&sp.hit.spawn_ray_to(target)) {
            continue;
        }
        let p_bsdf = sp.bsdf.pdf(sp.wo, wi);
        sum += f * ls.radiance / (n_b * p_bsdf + n_l * ls.pdf);
    }
    sum
}

/// The camera sample `index` of `pixel`: its random stream and primary ray.
pub fn camera_sample(scene: &Scene, pixel: UVec2, index: u32) -> (Sampler, lumis_core::accel::Ray) {
    let pixel_index = pixel.y as u64 * scene.width as u64 + pixel.x as u64;
    let mut sampler = Sampler::new(scene.seed, pixel_index, index as u64);
    let film = pixel.as_vec2() + sampler.next_2d();
    (sampler, scene.camera.generate_ray(film))
}

/// Radiance emitted toward the camera by the surface a primary ray hit (added once per sample).
pub fn emitted(scene: &Scene, hit: &Intersection, wi: Vec3) -> Rgb {
    match scene.emitter_of(hit) {
        Some(e) => {
            let h = EmitterHit {
                position: hit.position,
                normal: hit.geometric_normal,
                distance: hit.t,
            };
            scene.emitters[e].eval(wi, Some(&h))
        }
        None => Rgb::ZERO,
    }
}

/// Averages `per_sample` over the pixel's camera samples: `per_sample` gets the sampler and, for
/// camera rays that hit a surface, the shading point, and returns the reflected radiance.
pub fn render_pixel_with(
    scene: &Scene,
    pixel: UVec2,
    mut per_sample: impl FnMut(&ShadingPoint, &mut Sampler) -> Rgb,
) -> Rgb {
    let mut total = glam::DVec3::ZERO;
    for s in 0..scene.spp {
        let (mut sampler, ray) = camera_sample(scene, pixel, s);
        let Some(hit) = scene.intersect(&ray) else {
            continue;
        };
        let mut radiance = emitted(scene, &hit, ray.direction);
        let sp = ShadingPoint::new(scene, hit, -ray.direction);
        radiance += per_sample(&sp, &mut sampler);
        total += radiance.as_dvec3();
    }
    (total / scene.spp as f64).as_vec3()
}
