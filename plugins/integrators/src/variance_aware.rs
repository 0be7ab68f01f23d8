//! `variance_aware`: direct lighting with the variance-aware MIS weights of Grittmann, Georgiev,
//! Slusallek and Křivánek (SIGGRAPH Asia 2019): the balance heuristic with each technique's
//! n·p scaled by a factor c_t, w_t = c_t n_t p_t / Σ_k c_k n_k p_k, so that a technique whose own
//! estimate has a low variance relative to its mean gets more weight. Their "moment" form,
//! c_t = E[F_t²] / V[F_t] = 1 + μ_t² / V_t, with F_t = f / p_t the one-sample estimate of
//! technique t alone (unweighted), μ_t its mean and V_t its variance, measured by a pilot pass
//! and pooled over blocks of pixels (their 16 × 16, here `block`); as they do, c_t = 1 where
//! the block's V_t or μ_t is 0. Counts: N/2 per technique (n_B = ⌊N/2 + ½⌋). Delta lights take
//! one light sample each.
//!
//! The pilot (in `preprocess`): at camera sample 0's shading point of every pixel, M samples
//! per light at α = ½ (docs/integrators.md, "Pilot passes"), giving per technique Σ F_t, Σ F_t²
//! and the count; a block's μ_t and its second moment are the means over all its pilot samples,
//! V_t the pooled within-pixel variance (Σ over pixels of Σ (F − F̄_pixel)², over Σ (n − 1)).
//! Grittmann et al. measure V_t across the pixels of a block from one sample per pixel, which
//! also counts the image's variation within the block; with M samples per pixel the
//! within-pixel variance is the technique's own. Camera sample 0 reuses the pilot: its estimate
//! is (M·L̂_pilot + (N − M)·L̂)/N, with N − M fresh samples; other camera samples draw N. Unbiased:
//! the factors depend only on the pilot.
//!
//! Parameters:
//! - `samples` (integer, default 256, in [1, 1048576]): N, samples per light per camera sample.
//! - `pilot_samples` (integer, default 0 = N/4, in [0, 1048576]): M, the pilot's samples per
//!   light per pixel (at most N).
//! - `block` (integer, default 16, in [1, 4096]): edge of the square blocks of pixels the
//!   factors are pooled over.
//! - `aovs` (list, default []): any of "alpha", "sampling_variance", "samples".

use crate::allocation::Method;
use crate::alpha_family::{self, pilot_samples_spec, read_pilot_samples};
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC, read_samples};
use crate::phase::{LightEstimate, Phase, PhaseRole, SampleSplit};
use crate::pilot::{self, PilotEstimates};
use crate::sampling::LightSampling;
use crate::weighting::{Balance, PerSample, Weighting};
use bytemuck::{Pod, Zeroable};
use glam::UVec2;
use lumis_core::integrator::Integrator;
use lumis_core::math::{Rgb, luminance};
use lumis_core::output::Window;
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::registry::IntegratorPlugin;
use lumis_core::scene::Scene;

/// The plugin's name in scene files.
pub const NAME: &str = "variance_aware";
/// Parameter: M, the pilot's samples per light per pixel.
pub const PILOT_SAMPLES: &str = alpha_family::PILOT_SAMPLES;
/// Parameter: edge of the blocks the factors are pooled over, in pixels.
pub const BLOCK: &str = "block";

static PARAMS: &[ParamSpec] = &[
    SAMPLES_SPEC,
    pilot_samples_spec(
        "M, pilot samples per light per pixel at α = ½, reused by camera sample 0 (0: N/4)",
    ),
    ParamSpec {
        name: BLOCK,
        kind: ParamKind::Int {
            default: Some(16),
            min: 1,
            max: 4096,
        },
        unit: "pixels",
        description: "edge of the square blocks of pixels the variance factors are pooled over",
    },
    AOVS_SPEC,
];

/// The balance heuristic with each technique's n·p scaled by its factor (c_B, c_L).
pub struct ScaledBalance(pub [f32; 2]);

impl Weighting for ScaledBalance {
    fn weigh(&self, phase: &Phase, contributions: &mut [Rgb]) -> Rgb {
        PerSample(Balance).weigh_scaled(phase, contributions, self.0)
    }
}

/// What a pilot pixel keeps of one technique's samples of one light, F = f / p_t its
/// one-sample estimates.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct TechniqueSums {
    /// Σ F.
    sum: f64,
    /// Σ F².
    sum_sq: f64,
    /// The number of samples.
    count: f64,
}

/// What a block pools of one technique's pilot sums over its pixels.
#[derive(Clone, Copy, Debug, Default)]
struct BlockSums {
    /// Σ F, Σ F² and the number of samples.
    sum: f64,
    sum_sq: f64,
    count: f64,
    /// Σ over pixels of the squared deviations from the pixel's mean, Σ (F − F̄_pixel)².
    deviations: f64,
    /// Σ over pixels of n − 1: the degrees of freedom of `deviations`.
    degrees: f64,
}

/// The techniques (BSDF, then light) of one light at one pilot pixel.
type PixelSums = [TechniqueSums; 2];
/// f64 values per pilot pixel and light.
const PER_LIGHT: usize = size_of::<PixelSums>() / size_of::<f64>();

/// The factors (c_B, c_L) per block of the window and light.
#[derive(Clone, Debug, Default)]
pub struct BlockFactors {
    window: Option<Window>,
    block: u32,
    blocks_x: u32,
    lights: usize,
    factors: Vec<[f32; 2]>,
}

impl BlockFactors {
    /// The factors at `pixel` (film coordinates) for `light`; (1, 1) outside the pilot.
    pub fn get(&self, pixel: UVec2, light: usize) -> [f32; 2] {
        let Some(w) = self.window else {
            return [1.0, 1.0];
        };
        let (Some(x), Some(y)) = (pixel.x.checked_sub(w.x), pixel.y.checked_sub(w.y)) else {
            return [1.0, 1.0];
        };
        let (bx, by) = (x / self.block, y / self.block);
        let i = (by * self.blocks_x + bx) as usize * self.lights + light;
        self.factors.get(i).copied().unwrap_or([1.0, 1.0])
    }
}

/// c = 1 + μ² / V, or 1 where V or μ is 0 (Grittmann et al.'s guard).
pub fn moment_factor(mean: f64, variance: f64) -> f32 {
    if variance > 0.0 && mean != 0.0 {
        let c = 1.0 + mean * mean / variance;
        if c.is_finite() { c as f32 } else { 1.0 }
    } else {
        1.0
    }
}

/// Pools per-pixel technique statistics (`PER_LIGHT` per light) over blocks.
fn block_factors(scene: &Scene, stats: &[f64], block: u32) -> BlockFactors {
    let window = scene.window;
    let lights = scene.emitters.len();
    let (blocks_x, blocks_y) = (window.width.div_ceil(block), window.height.div_ceil(block));
    let mut factors = vec![[1.0f32; 2]; (blocks_x * blocks_y) as usize * lights];
    for by in 0..blocks_y {
        for bx in 0..blocks_x {
            for light in 0..lights {
                let mut pooled = [BlockSums::default(); 2];
                for y in by * block..((by + 1) * block).min(window.height) {
                    for x in bx * block..((bx + 1) * block).min(window.width) {
                        let p = (y * window.width + x) as usize;
                        let s: &PixelSums = bytemuck::from_bytes(bytemuck::cast_slice(
                            &stats[(p * lights + light) * PER_LIGHT..][..PER_LIGHT],
                        ));
                        for (pooled, s) in pooled.iter_mut().zip(s) {
                            if s.count < 1.0 {
                                continue;
                            }
                            pooled.sum += s.sum;
                            pooled.sum_sq += s.sum_sq;
                            pooled.count += s.count;
                            pooled.deviations += (s.sum_sq - s.sum * s.sum / s.count).max(0.0);
                            pooled.degrees += s.count - 1.0;
                        }
                    }
                }
                let c = pooled.map(|pooled| {
                    if pooled.count == 0.0 || pooled.degrees == 0.0 {
                        return 1.0;
                    }
                    moment_factor(
                        pooled.sum / pooled.count,
                        pooled.deviations / pooled.degrees,
                    )
                });
                factors[(by * blocks_x + bx) as usize * lights + light] = c;
            }
        }
    }
    BlockFactors {
        window: Some(window),
        block,
        blocks_x,
        lights,
        factors,
    }
}

/// The method: N/2 samples per technique, weighed by [`ScaledBalance`] with the block's
/// factors (its own weights: a [`Method`], given no weighting), camera sample 0 reusing the
/// pilot.
pub struct VarianceAware {
    /// N, samples per light per camera sample.
    pub samples: u32,
    pub pilot_samples: u32,
    pub block: u32,
    pub factors: BlockFactors,
    pub estimates: PilotEstimates,
}

impl Method for VarianceAware {
    fn estimate(&self, sampling: &mut LightSampling) -> LightEstimate {
        let factors = self.factors.get(sampling.pixel(), sampling.light());
        let value = self.estimates.reuse_at_camera_sample_zero(
            sampling,
            self.samples,
            |sampling, fresh| {
                let split = SampleSplit::new(0.5, fresh);
                sampling.phase(split, PhaseRole::ESTIMATE, &ScaledBalance(factors), &mut ())
            },
        );
        LightEstimate {
            value,
            alpha: SampleSplit::new(0.5, self.samples).alpha(),
        }
    }

    fn preprocess(&mut self, scene: &Scene) {
        let (_, stats, estimates) =
            pilot::run::<f64>(scene, self.pilot_samples, PER_LIGHT, |_, phase, out| {
                let techniques: &mut PixelSums =
                    bytemuck::from_bytes_mut(bytemuck::cast_slice_mut(out));
                for (i, r) in phase.records.iter().enumerate() {
                    let bsdf = i < phase.split.n_bsdf as usize;
                    // F_t = f / p_t of the technique that drew the sample (a Dirac sample's f
                    // is already f / p_B); black samples are zeros of F_t.
                    let own = if bsdf { r.p_bsdf } else { r.p_light };
                    let f = luminance(r.f) as f64;
                    let value = if r.is_black() || f == 0.0 {
                        0.0
                    } else if r.delta {
                        f
                    } else {
                        f / own as f64
                    };
                    let sums = &mut techniques[if bsdf { 0 } else { 1 }];
                    sums.sum += value;
                    sums.sum_sq += value * value;
                    sums.count += 1.0;
                }
            });
        self.factors = block_factors(scene, &stats, self.block);
        self.estimates = estimates;
    }
}

/// The method of the parameters above but `samples` and `aovs`, for N = `samples` (also
/// `path`'s at its first vertex).
pub fn read_method(params: &mut Params, samples: u32) -> Result<VarianceAware, PluginError> {
    let pilot_samples = read_pilot_samples(params, 4, samples)?;
    let block = params.int(BLOCK)? as u32;
    Ok(VarianceAware {
        samples,
        pilot_samples,
        block,
        factors: BlockFactors::default(),
        estimates: PilotEstimates::default(),
    })
}

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let samples = read_samples(params)?;
    let method = read_method(params, samples)?;
    MisIntegrator::boxed(params, method)
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting with variance-aware MIS weights (Grittmann et al. 2019) from a pilot pass pooled over blocks of pixels",
        params: PARAMS,
        create,
    }
}
