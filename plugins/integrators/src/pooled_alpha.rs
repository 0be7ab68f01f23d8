//! `pooled_alpha`: direct lighting with α chosen from pilot statistics pooled over a pixel's
//! neighbourhood, against the pilot noise of a small per-pixel M. A pilot pass (in
//! `preprocess`) draws M samples per light at α = ½ at camera sample 0's shading point of every
//! pixel (docs/integrators.md, "Pilot passes"); each pixel keeps, per light, its estimate of the
//! objective at 17 evenly spaced α in the clamp interval (or the paper's sums Î₁, Î₂); these are
//! summed over the pixels within `radius` (a square window) whose surface is similar (same
//! BSDF, normals within about 25°, depths within 10 %: an edge-stopping box filter); α is the
//! minimum of the pooled objective (the best node refined by a parabola through it and its
//! neighbours), or the paper's ½ + ¼ Î₁/Î₂. Then N samples at α per light, balance weights;
//! camera sample 0 reuses the pilot: (M·L̂_pilot + (N − M)·L̂)/N from N − M fresh samples.
//! Unbiased: α depends only on the pilot. Delta lights take one light sample each.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `pilot_samples` (integer, default 0 = N/8, in [0, 1048576]): M, the pilot's samples per
//!   light per pixel (at most N).
//! - `radius` (integer, default 2, in [0, 64]): the pooling window is (2·radius + 1)² pixels.
//! - `objective` (choice, default "exact"): "exact" — the pooled m̂(α), the second moment of
//!   the mixture estimator (as `exact_alpha`); "stratified" — the pooled variance of the
//!   stratified estimator (as `exact_alpha` with `variance: "stratified"`); "second_order" — the
//!   paper's α̂ from the pooled Î₁, Î₂.
//! - `clamp` (interval, default (0.025, 0.975), within [0, 1]): the interval α is chosen in.
//! - `statistics` (choice, default "pilot"): where the statistics come from: "pilot" — the
//!   pilot pass above; "passes" — the earlier passes of a render in passes (docs/integrators.md,
//!   "Learned α"): every sample adds the objective (or Î₁, Î₂) to its pixel's sums, pooled as
//!   above over a window whose radius is `radius` pixels at 256 pixels along the image's larger
//!   side and scales with it; every sample of a pass at the α its pixel and light learned before
//!   it; the first pass (and a one-pass render) at α = ½. `pilot_samples` does not apply.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples".
//!
//! Memory: 4 · 18 bytes per pixel and light for the pilot's statistics (4 · 3 for
//! "second_order"), plus 12 for its estimate, during `preprocess`; then 4 + 12 per pixel and
//! light.

use crate::allocation::{Allocation, Weighted};
use crate::alpha_family::{
    CLAMP_SPEC, STATISTICS_SPEC, pilot_samples_spec, read_clamp, read_learns, read_pilot_samples,
};
use crate::learned::{AlphaMap, LearnedAlpha, NODES, Pooled, alpha_of};
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use crate::moments::{Objective, PilotSamples};
use crate::phase::{LightEstimate, Observer, PhaseRole, SampleSplit};
use crate::pilot::{self, PilotEstimates, SampleCosts, Surface};
use crate::sampling::LightSampling;
use crate::second_order::SecondOrderMoments;
use crate::weighting::{Balance, PerSample, Weighting};
use lumis_core::integrator::Integrator;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;
use lumis_core::scene::Scene;
use rayon::prelude::*;

/// The plugin's name in scene files.
pub const NAME: &str = "pooled_alpha";
/// Parameter: the pooling window's radius, in pixels.
pub const RADIUS: &str = "radius";
/// Parameter: what α minimises, [`EXACT`], [`STRATIFIED`] or [`SECOND_ORDER`].
pub const OBJECTIVE: &str = "objective";
pub const EXACT: &str = "exact";
pub const STRATIFIED: &str = "stratified";
pub const SECOND_ORDER: &str = "second_order";

static PARAMS: &[ParamSpec] = &[
    SAMPLES_SPEC,
    pilot_samples_spec(
        "M, pilot samples per light per pixel at α = ½, reused by camera sample 0 (0: N/8)",
    ),
    ParamSpec {
        name: RADIUS,
        kind: ParamKind::Int {
            default: Some(2),
            min: 0,
            max: 64,
        },
        unit: "pixels",
        description: "radius of the square window of similar pixels whose pilot statistics are pooled",
    },
    ParamSpec {
        name: OBJECTIVE,
        kind: ParamKind::Choice {
            options: &[EXACT, STRATIFIED, SECOND_ORDER],
            default: EXACT,
        },
        unit: "",
        description: "exact: minimum of the pooled second moment; stratified: of the pooled variance of the stratified estimator; second_order: the paper's α̂ from pooled sums",
    },
    CLAMP_SPEC,
    STATISTICS_SPEC,
    AOVS_SPEC,
];

/// Pools the pilot's per-pixel values (`per_light` per light) over the similar pixels of each
/// pixel's window, and turns them into α.
fn pool(
    scene: &Scene,
    surfaces: &[Option<Surface>],
    values: &[f32],
    pooled: Pooled,
    radius: u32,
    clamp: [f64; 2],
) -> AlphaMap {
    let window = scene.window;
    let lights = scene.emitters.len();
    let per_light = pooled.per_light();
    let (width, height) = (window.width as i64, window.height as i64);
    let r = radius as i64;
    let mut alphas = vec![f32::NAN; (window.width * window.height) as usize * lights];
    alphas
        .par_chunks_mut((window.width as usize * lights).max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let mut sum = vec![0.0f32; per_light];
            for x in 0..width {
                let p = (y as i64 * width + x) as usize;
                let Some(surface) = surfaces[p] else {
                    continue;
                };
                for light in 0..lights {
                    if scene.emitters[light].is_delta() {
                        continue;
                    }
                    sum.fill(0.0);
                    for qy in (y as i64 - r).max(0)..(y as i64 + r + 1).min(height) {
                        for qx in (x - r).max(0)..(x + r + 1).min(width) {
                            let q = (qy * width + qx) as usize;
                            if !surfaces[q].is_some_and(|s| surface.similar(&s)) {
                                continue;
                            }
                            let v = &values[(q * lights + light) * per_light..][..per_light];
                            for (s, v) in sum.iter_mut().zip(v) {
                                *s += v;
                            }
                        }
                    }
                    let alpha = alpha_of(pooled, &sum, clamp, SampleCosts::EQUAL)
                        .unwrap_or(0.5)
                        .clamp(clamp[0], clamp[1]);
                    row[x as usize * lights + light] = alpha as f32;
                }
            }
        });
    AlphaMap::new(window, lights, alphas)
}

/// The allocation: N samples at the pooled α, camera sample 0 reusing the pilot.
pub struct PooledAlpha {
    /// N, samples per light per camera sample.
    pub samples: u32,
    pub pilot_samples: u32,
    pub radius: u32,
    pub pooled: Pooled,
    pub clamp: [f64; 2],
    pub alphas: AlphaMap,
    pub estimates: PilotEstimates,
}

impl Allocation for PooledAlpha {
    fn estimate<W: Weighting + ?Sized>(
        &self,
        sampling: &mut LightSampling,
        weighting: &W,
    ) -> LightEstimate {
        let alpha = self.alphas.at(sampling, self.clamp);
        let value = self.estimates.reuse_at_camera_sample_zero(
            sampling,
            self.samples,
            |sampling, fresh| {
                let split = SampleSplit::new(alpha, fresh);
                sampling.phase(split, PhaseRole::ESTIMATE, weighting, &mut ())
            },
        );
        LightEstimate { value, alpha }
    }

    fn preprocess(&mut self, scene: &Scene) {
        let (pooled, clamp) = (self.pooled, self.clamp);
        let step = (clamp[1] - clamp[0]) / (NODES - 1) as f64;
        let (surfaces, values, estimates) = pilot::run::<f32>(
            scene,
            self.pilot_samples,
            pooled.per_light(),
            |_, phase, out| match pooled {
                Pooled::Nodes(objective) => {
                    let pilot = PilotSamples::new(phase);
                    if !pilot.informative() {
                        return;
                    }
                    for (k, v) in out[..NODES].iter_mut().enumerate() {
                        *v = pilot.objective(objective, clamp[0] + step * k as f64) as f32;
                    }
                    out[NODES] = 1.0;
                }
                Pooled::Cost { stratified } => {
                    let mut nodes = [0.0; NODES];
                    if PilotSamples::new(phase).add_variance_at_nodes(stratified, clamp, &mut nodes)
                    {
                        for (v, n) in out[..NODES].iter_mut().zip(nodes) {
                            *v = n as f32;
                        }
                        out[NODES] = 1.0;
                    }
                }
                Pooled::SecondOrder => {
                    let mut moments = SecondOrderMoments::default();
                    moments.observe(phase, &[]);
                    out[0] = moments.i1 as f32;
                    out[1] = moments.i2 as f32;
                    out[2] = if moments.i2 > 0.0 { 1.0 } else { 0.0 };
                }
            },
        );
        self.alphas = pool(scene, &surfaces, &values, pooled, self.radius, clamp);
        self.estimates = estimates;
    }
}

/// Reads `objective`.
fn read_pooled(params: &mut Params) -> Result<Pooled, PluginError> {
    Ok(match params.choice(OBJECTIVE)? {
        EXACT => Pooled::Nodes(Objective::Mixture),
        STRATIFIED => Pooled::Nodes(Objective::Stratified),
        _ => Pooled::SecondOrder,
    })
}

/// The allocation of the parameters above but `samples`, `statistics` and `aovs`, for N =
/// `samples` (also `path`'s at its first vertex).
pub fn read_allocation(params: &mut Params, samples: u32) -> Result<PooledAlpha, PluginError> {
    let pilot_samples = read_pilot_samples(params, 8, samples)?;
    let radius = params.int(RADIUS)? as u32;
    let pooled = read_pooled(params)?;
    let clamp = read_clamp(params)?;
    Ok(PooledAlpha {
        samples,
        pilot_samples,
        radius,
        pooled,
        clamp,
        alphas: AlphaMap::default(),
        estimates: PilotEstimates::default(),
    })
}

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    if read_learns(params)? {
        let radius = params.int(RADIUS)? as u32;
        let pooled = read_pooled(params)?;
        let clamp = read_clamp(params)?;
        let allocation = LearnedAlpha::new(samples, pooled, clamp, radius);
        return MisIntegrator::boxed(params, Weighted(allocation, PerSample(Balance)));
    }
    let allocation = read_allocation(params, samples)?;
    MisIntegrator::boxed(params, Weighted(allocation, PerSample(Balance)))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting with α from pilot statistics pooled over similar neighbouring pixels (exact, stratified or second-order)",
        params: PARAMS,
        create,
    }
}
