//! The MIS integrator family: direct lighting at the first surface a camera ray hits, each
//! non-delta light estimated with N samples by a [`Method`] (an allocation, how many samples
//! each technique gets in which phases, with a weighting, how a phase's samples combine), delta
//! lights with one sample each, and emission seen by the camera added once. A plugin of the
//! family is one file that picks the method (e.g. `balance`: α = ½, balance weights) and
//! registers itself.

use crate::allocation::Method;
use crate::aovs::{self, AovRequest, LightTally};
use crate::estimator::{emitted, estimate_delta_light};
use crate::phase::LightEstimate;
use crate::sampling::{LightSampling, PhaseBuffers};
use crate::shading_point::ShadingPoint;
use lumis_core::geometry::PACKET_SIZE;
use lumis_core::integrator::{CameraSample, Integrator, PacketSums, shade_one_by_one};
use lumis_core::math::Rgb;
use lumis_core::output::Aov;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::passes::PassContext;
use lumis_core::registry::IntegratorPlugin;
use lumis_core::scene::Scene;
use lumis_core::scene::description::PluginSpec;

/// Name of the parameter N, samples per light per camera sample.
pub const SAMPLES: &str = "samples";
/// Name of the parameter listing the AOV layers to write ([`aovs::NAMES`]).
pub const AOVS: &str = "aovs";

/// `samples`, shared by the family.
pub const SAMPLES_SPEC: ParamSpec = ParamSpec {
    name: SAMPLES,
    kind: ParamKind::Int {
        default: Some(256),
        min: 1,
        max: 1 << 20,
    },
    unit: "",
    description: "N: samples per light per camera sample",
};

/// `aovs`, shared by the family.
pub const AOVS_SPEC: ParamSpec = ParamSpec {
    name: AOVS,
    kind: ParamKind::List {
        options: aovs::NAMES,
    },
    unit: "",
    description: "extra output layers: alpha (per light, combined, and coloured), sampling_variance (V[L_1] per pixel, summed over lights), samples (BSDF and light sample counts)",
};

/// Reads `samples`, N, which a plugin gives its allocation.
pub fn read_samples(params: &mut Params) -> Result<u32, PluginError> {
    Ok(params.int(SAMPLES)? as u32)
}

/// Whether `plugin` is given N, as the members of the family are (through `samples`).
pub fn takes_samples(plugin: &IntegratorPlugin) -> bool {
    plugin.params.iter().any(|p| p.name == SAMPLES)
}

/// Sets N = `samples` in the description of an integrator that [`takes_samples`]: how a
/// program (the study) gives a member of the family its budget.
pub fn set_samples(spec: &mut PluginSpec, samples: u32) {
    let value = ron::Value::Number(u64::from(samples).into());
    spec.params.insert(SAMPLES.into(), value);
}

/// A member of the MIS family: a method known at compile time, so that a plugin's whole
/// per-sample path is compiled for it (no dynamic call per sample, nor per phase).
pub struct MisIntegrator<M> {
    method: M,
    aovs: AovRequest,
}

impl<M: Method + 'static> MisIntegrator<M> {
    /// Reads the family's `aovs` and runs `method` (which was given N, `samples`).
    pub fn new(params: &mut Params, method: M) -> Result<Self, PluginError> {
        Ok(MisIntegrator {
            aovs: AovRequest::from_names(&params.list(AOVS)?),
            method,
        })
    }

    /// As [`new`](Self::new), boxed as a plugin's `create` returns it.
    pub fn boxed(params: &mut Params, method: M) -> Result<Box<dyn Integrator>, PluginError> {
        Ok(Box::new(Self::new(params, method)?))
    }
}

impl<M: Method> Integrator for MisIntegrator<M> {
    fn aovs(&self, scene: &Scene) -> Vec<Aov> {
        self.aovs.declare(scene)
    }

    fn pixel_sums(&self, scene: &Scene) -> usize {
        self.aovs.pixel_sums(scene) + self.method.pixel_sums(scene)
    }

    fn preprocess(&mut self, scene: &Scene) {
        self.method.preprocess(scene);
    }

    fn begin_pass(&mut self, scene: &Scene, pass: &PassContext<'_>) {
        let offset = self.aovs.pixel_sums(scene);
        self.method.begin_pass(scene, pass, offset);
    }

    fn shade(&self, scene: &Scene, sample: &mut CameraSample, sums: &mut [f64]) -> Rgb {
        let ray = sample.ray;
        let mut traced_now = None;
        let Some(hit) = sample.hit(scene, &mut traced_now) else {
            return scene.environment_radiance(ray.direction);
        };
        let mut radiance = emitted(scene, hit, ray.direction);
        let sp = ShadingPoint::new(scene, hit, -ray.direction);
        // The method's statistics follow the AOVs' sums.
        let learning = self.method.learning();
        let (aov_sums, learned_sums) = sums.split_at_mut(self.aovs.pixel_sums(scene));
        PhaseBuffers::with_thread_local(|buffers| {
            for (light, emitter) in scene.emitters.iter().enumerate() {
                if emitter.is_delta() {
                    radiance += estimate_delta_light(scene, &sp, light, &mut sample.sampler);
                    continue;
                }
                let mut tally = LightTally::default();
                let mut sampling = LightSampling::new(
                    scene,
                    &sp,
                    light,
                    sample.pixel,
                    &mut sample.sampler,
                    buffers,
                )
                .with_camera_sample(sample.index);
                if self.aovs.any() {
                    sampling = sampling.with_tally(&mut tally);
                }
                let estimate = self.method.estimate(&mut sampling);
                radiance += estimate.value;
                if learning {
                    self.method.observe(&sampling, learned_sums);
                }
                if self.aovs.any() {
                    self.aovs.add(aov_sums, light, &estimate, &tally);
                }
            }
        });
        radiance
    }

    /// Each light's phases for the packet's samples drawn together
    /// ([`Method::estimate_together`]), whatever pixels they belong to, when there are several
    /// samples and neither an AOV nor the method's learning asks for statistics (their sums
    /// would be added in another order); one by one otherwise, each sample adding to its own
    /// pixel's sums.
    fn shade_together(
        &self,
        scene: &Scene,
        samples: &mut [CameraSample],
        sums: &mut PacketSums<'_>,
        radiance: &mut [Rgb],
    ) {
        // A packet of one (a tile's last sample) has nothing to share, and the packet's arrays
        // below would cost it more than its own batches do.
        if self.aovs.any()
            || self.method.learning()
            || samples.len() == 1
            || samples.len() > PACKET_SIZE
        {
            return shade_one_by_one(self, scene, samples, sums, radiance);
        }
        assert_eq!(samples.len(), radiance.len(), "one estimate per sample");
        let mut points: [Option<ShadingPoint>; PACKET_SIZE] = Default::default();
        for ((sample, point), radiance) in samples.iter().zip(&mut points).zip(radiance.iter_mut())
        {
            let ray = sample.ray;
            let mut traced_now = None;
            *radiance = match sample.hit(scene, &mut traced_now) {
                None => scene.environment_radiance(ray.direction),
                Some(hit) => {
                    let emitted = emitted(scene, hit, ray.direction);
                    *point = Some(ShadingPoint::new(scene, hit, -ray.direction));
                    emitted
                }
            };
        }
        PhaseBuffers::with_thread_local_wave(|buffers| {
            for (light, emitter) in scene.emitters.iter().enumerate() {
                if emitter.is_delta() {
                    let shaded = samples.iter_mut().zip(&points).zip(radiance.iter_mut());
                    for ((sample, point), radiance) in shaded {
                        if let Some(sp) = point {
                            *radiance +=
                                estimate_delta_light(scene, sp, light, &mut sample.sampler);
                        }
                    }
                    continue;
                }
                let mut lit = samples.iter_mut().zip(&points).zip(buffers.iter_mut());
                let mut samplings: [Option<LightSampling>; PACKET_SIZE] =
                    std::array::from_fn(|_| {
                        let ((sample, point), buffers) = lit.next()?;
                        let sp = point.as_ref()?;
                        let sampling = LightSampling::new(
                            scene,
                            sp,
                            light,
                            sample.pixel,
                            &mut sample.sampler,
                            buffers,
                        );
                        Some(sampling.with_camera_sample(sample.index))
                    });
                let mut estimates = [LightEstimate::default(); PACKET_SIZE];
                self.method
                    .estimate_together(&mut samplings, &mut estimates);
                let estimated = samplings.iter().zip(&estimates).zip(radiance.iter_mut());
                for ((sampling, estimate), radiance) in estimated {
                    if sampling.is_some() {
                        *radiance += estimate.value;
                    }
                }
            }
        });
    }

    fn resolve(&self, scene: &Scene, sums: &[f64], _samples: u32, aovs: &mut [f32]) {
        self.aovs
            .resolve(scene, &sums[..self.aovs.pixel_sums(scene)], aovs);
    }
}
