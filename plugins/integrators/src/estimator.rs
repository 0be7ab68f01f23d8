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
//! j only if it reaches light j (a ray that leaves the scene reaches the environment). A delta
//! BSDF sample (a mirror) has no density to compare: only BSDF sampling can produce it, so it
//! contributes weight · L_e / n_bsdf. Delta lights (point, directional) cannot be reached by BSDF
//! sampling: each takes one light sample, with no MIS.

use glam::{UVec2, Vec3};
use lumis_core::accel::{Intersection, Ray};
use lumis_core::bsdf::Bsdf;
use lumis_core::emitter::{EmitterHit, EmitterSample, ReferencePoint};
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

    /// Whether the light sample is unoccluded: a shadow ray to its point, or to infinity.
    fn sees(&self, scene: &Scene, sample: &EmitterSample) -> bool {
        let ray = match sample.position {
            Some(target) => self.hit.spawn_ray_to(target),
            None => self.hit.spawn_ray(sample.wi),
        };
        !scene.occluded(&ray)
    }

    /// BSDF value (with cosine) toward a light sample, zero when it cannot reflect there.
    fn eval_toward(&self, sample: &EmitterSample) -> Rgb {
        if !self.reflects_toward(sample.wi) {
            return Rgb::ZERO;
        }
        self.bsdf.eval(self.wo, self.frame.to_local(sample.wi))
    }
}

/// How many samples of each technique one light receives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleSplit {
    pub n_bsdf: u32,
    pub n_light: u32,
}

/// Where a BSDF-sampled ray reaches light `light`, if it does: the emitter hit (None for the
/// environment) and the radiance arriving.
fn reaches_light(scene: &Scene, light: usize, ray: &Ray) -> Option<(Option<EmitterHit>, Rgb)> {
    let emitter = scene.emitters[light].as_ref();
    match scene.intersect(ray) {
        None if scene.environment == Some(light) => Some((None, emitter.eval(ray.direction, None))),
        None => None,
        Some(hit) if scene.emitter_of(&hit) == Some(light) => {
            let h = EmitterHit {
                position: hit.position,
                normal: hit.geometric_normal,
                distance: hit.t,
            };
            Some((Some(h), emitter.eval(ray.direction, Some(&h))))
        }
        Some(_) => None,
    }
}

/// The balance-heuristic estimate of the radiance reflected at `sp` from non-delta light `light`.
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
        let Some((hit, le)) = reaches_light(scene, light, &sp.hit.spawn_ray(wi)) else {
            continue;
        };
        if le == Rgb::ZERO {
            continue;
        }
        if s.delta {
            // Light sampling cannot produce a Dirac direction: the BSDF technique takes it all.
            sum += s.weight * le / n_b;
            continue;
        }
        let p_light = emitter.pdf_direction(&reference, wi, hit.as_ref());
        // f / (n_B p_B + n_L p_L), with f = weight · p_B.
        sum += s.weight * le * (s.pdf / (n_b * s.pdf + n_l * p_light));
    }

    for _ in 0..split.n_light {
        let Some(ls) = emitter.sample_direction(&reference, sampler.next_2d()) else {
            continue;
        };
        let f = sp.eval_toward(&ls);
        if f == Rgb::ZERO || !sp.sees(scene, &ls) {
            continue;
        }
        let p_bsdf = sp.bsdf.pdf(sp.wo, sp.frame.to_local(ls.wi));
        sum += f * ls.radiance / (n_b * p_bsdf + n_l * ls.pdf);
    }
    sum
}

/// One sample of a delta light (point, directional): its contribution, with no MIS.
pub fn estimate_delta_light(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    sampler: &mut Sampler,
) -> Rgb {
    let reference = ReferencePoint {
        position: sp.hit.position,
    };
    let Some(ls) = scene.emitters[light].sample_direction(&reference, sampler.next_2d()) else {
        return Rgb::ZERO;
    };
    let f = sp.eval_toward(&ls);
    if f == Rgb::ZERO || !sp.sees(scene, &ls) {
        return Rgb::ZERO;
    }
    f * ls.radiance / ls.pdf
}

/// Direct lighting from every light: MIS with `split` for the others, one sample per delta light.
pub fn direct_lighting(
    scene: &Scene,
    sp: &ShadingPoint,
    split: SampleSplit,
    sampler: &mut Sampler,
) -> Rgb {
    let mut sum = Rgb::ZERO;
    for (light, emitter) in scene.emitters.iter().enumerate() {
        sum += if emitter.is_delta() {
            estimate_delta_light(scene, sp, light, sampler)
        } else {
            estimate_light(scene, sp, light, split, sampler)
        };
    }
    sum
}

/// The camera sample `index` of `pixel`: its random stream and primary ray.
pub fn camera_sample(scene: &Scene, pixel: UVec2, index: u32) -> (Sampler, Ray) {
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
/// camera rays that hit a surface, the shading point, and returns the reflected radiance. Rays
/// that leave the scene see the environment.
pub fn render_pixel_with(
    scene: &Scene,
    pixel: UVec2,
    mut per_sample: impl FnMut(&ShadingPoint, &mut Sampler) -> Rgb,
) -> Rgb {
    let mut total = glam::DVec3::ZERO;
    for s in 0..scene.spp {
        let (mut sampler, ray) = camera_sample(scene, pixel, s);
        let radiance = match scene.intersect(&ray) {
            None => scene.environment_radiance(ray.direction),
            Some(hit) => {
                let emitted = emitted(scene, &hit, ray.direction);
                let sp = ShadingPoint::new(scene, hit, -ray.direction);
                emitted + per_sample(&sp, &mut sampler)
            }
        };
        total += radiance.as_dvec3();
    }
    (total / scene.spp as f64).as_vec3()
}
