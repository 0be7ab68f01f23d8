//! `balance`: direct lighting, multiple importance sampling with the balance heuristic.
//!
//! Per camera sample and per light, N = `samples` directions: ⌊N/2⌋ from the BSDF and the rest
//! from the light, combined with the balance heuristic (Veach 1997), which equals the mixture
//! estimator with α = N_B/N. Delta lights (point, directional) take one sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, range [1, 1048576]): N, samples per light per camera sample.

use crate::estimator::{SampleSplit, direct_lighting, render_pixel_with};
use glam::UVec2;
use lumis_core::integrator::{Integrator, PixelOutput};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;
use lumis_core::scene::Scene;

pub struct Balance {
    split: SampleSplit,
}

impl Integrator for Balance {
    fn render_pixel(&self, scene: &Scene, pixel: UVec2, out: &mut PixelOutput<'_>) {
        out.color = render_pixel_with(scene, pixel, |sp, sampler| {
            direct_lighting(scene, sp, self.split, sampler)
        });
    }
}

static PARAMS: &[ParamSpec] = &[ParamSpec {
    name: "samples",
    kind: ParamKind::Int {
        default: Some(256),
        min: 1,
        max: 1 << 20,
    },
    unit: "",
    description: "N: samples per light per camera sample, split evenly between BSDF and light",
}];

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let n = params.int("samples")? as u32;
    let n_bsdf = n / 2;
    Ok(Box::new(Balance {
        split: SampleSplit {
            n_bsdf,
            n_light: n - n_bsdf,
        },
    }))
}

inventory::submit! {
    IntegratorPlugin {
        name: "balance",
        description: "direct lighting, BSDF and light sampling combined by the balance heuristic",
        params: PARAMS,
        create,
    }
}
