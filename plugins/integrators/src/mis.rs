//! The MIS integrator family: direct lighting at the first surface a camera ray hits, each
//! non-delta light estimated with N samples by an [`Allocation`] (how many samples each
//! technique gets, in which phases) and a [`Weighting`] (how a phase's samples combine), delta
//! lights with one sample each, and emission seen by the camera added once. A plugin of the
//! family is one file that picks the two (e.g. `balance`: α = ½, balance weights) and
//! registers itself.

use crate::allocation::{Allocation, LightSampling, PhaseBuffers};
use crate::aovs::{self, AovRequest, LightTally};
use crate::estimator::{ShadingPoint, emitted, estimate_delta_light};
use crate::weighting::Weighting;
use lumis_core::integrator::{CameraSample, Integrator};
use lumis_core::math::Rgb;
use lumis_core::output::Aov;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::scene::Scene;

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

/// A member of the MIS family: an allocation and a weighting, both known at compile time, so
/// that a plugin's whole per-sample path is compiled for them (no dynamic call per sample, nor
/// per phase).
pub struct MisIntegrator<A, W> {
    /// N, samples per light per camera sample.
    samples: u32,
    allocation: A,
    weighting: W,
    aovs: AovRequest,
}

impl<A: Allocation + 'static, W: Weighting + 'static> MisIntegrator<A, W> {
    /// Reads the family's parameters (`samples`, `aovs`) and combines `allocation` and
    /// `weighting`.
    pub fn new(params: &mut Params, allocation: A, weighting: W) -> Result<Self, PluginError> {
        Ok(MisIntegrator {
            samples: params.int(SAMPLES)? as u32,
            aovs: AovRequest::from_names(&params.list(AOVS)?),
            allocation,
            weighting,
        })
    }

    /// As [`new`](Self::new), boxed as a plugin's `create` returns it.
    pub fn boxed(
        params: &mut Params,
        allocation: A,
        weighting: W,
    ) -> Result<Box<dyn Integrator>, PluginError> {
        Ok(Box::new(Self::new(params, allocation, weighting)?))
    }
}

impl<A: Allocation, W: Weighting> Integrator for MisIntegrator<A, W> {
    fn aovs(&self, scene: &Scene) -> Vec<Aov> {
        self.aovs.declare(scene)
    }

    fn pixel_sums(&self, scene: &Scene) -> usize {
        self.aovs.pixel_sums(scene)
    }

    fn preprocess(&mut self, scene: &Scene) {
        self.allocation.preprocess(scene);
        self.weighting.preprocess(scene);
    }

    fn shade(&self, scene: &Scene, sample: &mut CameraSample, sums: &mut [f64]) -> Rgb {
        let ray = sample.ray;
        let Some(hit) = sample.intersect(scene) else {
            return scene.environment_radiance(ray.direction);
        };
        let mut radiance = emitted(scene, &hit, ray.direction);
        let sp = ShadingPoint::new(scene, hit, -ray.direction);
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
                    self.samples,
                    &mut sample.sampler,
                    buffers,
                )
                .with_camera_sample(sample.index);
                if self.aovs.any() {
                    sampling = sampling.with_tally(&mut tally);
                }
                let estimate = self.allocation.estimate(&mut sampling, &self.weighting);
                radiance += estimate.value;
                if self.aovs.any() {
                    self.aovs.add(sums, light, &estimate, &tally);
                }
            }
        });
        radiance
    }

    fn resolve(&self, scene: &Scene, sums: &[f64], _samples: u32, aovs: &mut [f32]) {
        self.aovs.resolve(scene, sums, aovs);
    }
}
