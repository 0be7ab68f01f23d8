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

use crate::allocation::{Allocation, LightEstimate, LightSampling, SampleSplit};
use crate::balance::Balance;
use crate::mis::{AOVS_SPEC, MisIntegrator, SAMPLES_SPEC};
use crate::phase::{Phase, PhaseRole};
use crate::pilot::{self, PilotEstimates};
use crate::weighting::{PerSample, Weighting};
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
pub const PILOT_SAMPLES: &str = "pilot_samples";
/// Parameter: edge of the blocks the factors are pooled over, in pixels.
pub const BLOCK: &str = "block";

/// `pilot_samples`, shared with `pooled_alpha`.
pub const fn pilot_samples_spec(default_text: &'static str) -> ParamSpec {
    ParamSpec {
        name: PILOT_SAMPLES,
        kind: ParamKind::Int {
            default: Some(0),
            min: 0,
            max: 1 << 20,
        },
        unit: "",
        description: default_text,
    }
}

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

/// Reads `pilot_samples` (0: N / `fraction`, at least 2; at most N).
pub fn read_pilot_samples(params: &mut Params, fraction: u32) -> Result<u32, PluginError> {
    let n = params.int(SAMPLES_SPEC.name)? as u32;
    let given = params.int(PILOT_SAMPLES)? as u32;
    let m = if given == 0 {
        (n / fraction).max(2).min(n)
    } else {
        given
    };
    if m > n {
        return Err(PluginError::Invalid(format!(
            "{}: `{PILOT_SAMPLES}` ({m}) cannot exceed `{}` ({n}): camera sample 0's estimate is made of the pilot's M samples and N − M fresh ones",
            params.plugin(),
            SAMPLES_SPEC.name
        )));
    }
    Ok(m)
}

/// The balance heuristic with each technique's n·p scaled by its factor (c_B, c_L).
pub struct ScaledBalance(pub [f32; 2]);

impl Weighting for ScaledBalance {
    fn weigh(&self, phase: &Phase, contributions: &mut [Rgb]) -> Rgb {
        PerSample(Balance).weigh_scaled(phase, contributions, self.0)
    }
}

/// Per pilot pixel and light: Σ F, Σ F², n for the BSDF technique, then for the light's.
const PER_LIGHT: usize = 6;

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
                // Per technique: Σ F, Σ F², count, Σ within-pixel squared deviations, Σ (n − 1).
                let mut t = [[0.0f64; 5]; 2];
                for y in by * block..((by + 1) * block).min(window.height) {
                    for x in bx * block..((bx + 1) * block).min(window.width) {
                        let p = (y * window.width + x) as usize;
                        let s = &stats[(p * lights + light) * PER_LIGHT..][..PER_LIGHT];
                        for (k, acc) in t.iter_mut().enumerate() {
                            let (sum, sum_sq, n) = (s[3 * k], s[3 * k + 1], s[3 * k + 2]);
                            if n < 1.0 {
                                continue;
                            }
                            acc[0] += sum;
                            acc[1] += sum_sq;
                            acc[2] += n;
                            acc[3] += (sum_sq - sum * sum / n).max(0.0);
                            acc[4] += n - 1.0;
                        }
                    }
                }
                let c = t.map(|acc| {
                    if acc[2] == 0.0 || acc[4] == 0.0 {
                        return 1.0;
                    }
                    moment_factor(acc[0] / acc[2], acc[3] / acc[4])
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

/// The allocation: N/2 per technique, weighed by [`ScaledBalance`] with the block's factors,
/// camera sample 0 reusing the pilot.
pub struct VarianceAware {
    pub pilot_samples: u32,
    pub block: u32,
    pub factors: BlockFactors,
    pub estimates: PilotEstimates,
}

impl Allocation for VarianceAware {
    fn estimate<W: Weighting + ?Sized>(
        &self,
        sampling: &mut LightSampling,
        _weighting: &W,
    ) -> LightEstimate {
        let n = sampling.samples();
        let reused = sampling.camera_sample() == 0
            && self
                .estimates
                .get(sampling.pixel(), sampling.light())
                .is_some();
        let fresh = if reused {
            n - self.pilot_samples.min(n)
        } else {
            n
        };
        let factors = self.factors.get(sampling.pixel(), sampling.light());
        let split = SampleSplit::new(0.5, fresh);
        let value = if fresh > 0 {
            sampling.phase(split, PhaseRole::ESTIMATE, &ScaledBalance(factors), &mut ())
        } else {
            Rgb::ZERO
        };
        LightEstimate {
            value: self.estimates.combine(sampling, value, fresh),
            alpha: SampleSplit::new(0.5, n).n_bsdf as f64 / n as f64,
        }
    }

    fn preprocess(&mut self, scene: &Scene) {
        let (_, stats, estimates) =
            pilot::run::<f64>(scene, self.pilot_samples, PER_LIGHT, |_, phase, out| {
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
                    let k = if bsdf { 0 } else { 3 };
                    out[k] += value;
                    out[k + 1] += value * value;
                    out[k + 2] += 1.0;
                }
            });
        self.factors = block_factors(scene, &stats, self.block);
        self.estimates = estimates;
    }
}

fn create(params: &mut Params) -> Result<Box<dyn Integrator>, PluginError> {
    let pilot_samples = read_pilot_samples(params, 4)?;
    let block = params.int(BLOCK)? as u32;
    let allocation = VarianceAware {
        pilot_samples,
        block,
        factors: BlockFactors::default(),
        estimates: PilotEstimates::default(),
    };
    MisIntegrator::boxed(params, allocation, PerSample(Balance))
}

inventory::submit! {
    IntegratorPlugin {
        name: NAME,
        description: "direct lighting with variance-aware MIS weights (Grittmann et al. 2019) from a pilot pass pooled over blocks of pixels",
        params: PARAMS,
        create,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::SampleRecord;

    #[test]
    fn factors_follow_the_moment_form_and_its_guards() {
        assert_eq!(moment_factor(2.0, 4.0), 2.0);
        assert_eq!(moment_factor(0.0, 4.0), 1.0);
        assert_eq!(moment_factor(3.0, 0.0), 1.0);
    }

    /// With factors (c_B, c_L) a sample's weight is c_t n_t p_t / Σ c_k n_k p_k: the BSDF and
    /// light samples at one direction still sum to one, and factors (1, 1) are the balance
    /// heuristic bit for bit.
    #[test]
    fn scaled_weights_are_a_partition_of_unity() {
        let r = SampleRecord {
            f: Rgb::ONE,
            p_bsdf: 0.7,
            p_light: 2.5,
            delta: false,
        };
        let records = [r, r, r, r, r];
        let split = SampleSplit {
            n_bsdf: 2,
            n_light: 3,
        };
        let phase = Phase::of(split, &records);
        for factors in [[1.0, 1.0], [4.0, 1.0], [1.0, 30.0]] {
            let mut c = [Rgb::ZERO; 5];
            ScaledBalance(factors).weigh(&phase, &mut c);
            // Weight = contribution · n p / f.
            let w_b = c[0].x * 2.0 * 0.7;
            let w_l = c[2].x * 3.0 * 2.5;
            assert!((w_b + w_l - 1.0).abs() < 1e-6, "{factors:?}");
            let expected = factors[0] * 1.4 / (factors[0] * 1.4 + factors[1] * 7.5);
            assert!((w_b - expected).abs() < 1e-6);
        }
        let mut a = [Rgb::ZERO; 5];
        let mut b = [Rgb::ZERO; 5];
        ScaledBalance([1.0, 1.0]).weigh(&phase, &mut a);
        PerSample(Balance).weigh(&phase, &mut b);
        assert_eq!(a, b);
    }
}
