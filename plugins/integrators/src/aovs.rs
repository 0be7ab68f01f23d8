//! The AOVs of the MIS integrators, by name: `alpha` (with its colourings), `sampling_variance`
//! and `samples` (docs/integrators.md). Other crates (the study, the tests) use the names below,
//! so that renaming a layer or channel breaks their build, not their results.
//!
//! What the layers need is kept per pixel as sums over camera samples (the pixel's f64 sums, see
//! `lumis_core::integrator`, which adds them across tiles and shards): a `LightSums` per
//! light of the scene, then the pixel's `SampleCounts`. Each light's statistics at a shading
//! point are gathered by a [`LightTally`], an observer of its phases.

use crate::phase::{LightEstimate, Observer, Phase};
use bytemuck::{Pod, Zeroable};
use lumis_core::math::{Rgb, luminance};
use lumis_core::output::Aov;
use lumis_core::scene::Scene;

/// Layer `alpha`: channel [`COMBINED`] and one channel per non-delta light ([`light_channel`]).
pub const ALPHA: &str = "alpha";
/// Layer `alpha_color`: the combined α coloured as in the supplemental's §5.1 (R, G, B).
pub const ALPHA_COLOR: &str = "alpha_color";
/// Layer `sampling_variance`: V[L_{1,α}] per pixel, summed over lights (channel [`Y`]).
pub const SAMPLING_VARIANCE: &str = "sampling_variance";
/// Layer `samples`: BSDF and light samples drawn in the pixel (channels [`BSDF`], [`LIGHT`]).
pub const SAMPLE_COUNTS: &str = "samples";
/// Channel of `alpha`: α of all lights, weighted by their contributions.
pub const COMBINED: &str = "combined";
/// Channel of `sampling_variance`: V[L₁] of the samples drawn at the split the method settled
/// on (the measured phases: for integrated α, the N − M samples at α̂).
pub const Y: &str = "Y";
/// Channel of `sampling_variance`: V[L₁] over every sample that makes the estimate (the counted
/// phases: for integrated α the M pilot samples at α = ½ too), each phase's unbiased variance
/// weighted by its sample count. This is the paper's basis: its integrated α's V[L₁] is the
/// mean of the pilot's and the second phase's when M = N/2. Equal to [`Y`] for one-phase methods.
pub const ESTIMATE: &str = "estimate";
/// Channels of `samples`.
pub const BSDF: &str = "bsdf";
pub const LIGHT: &str = "light";
/// The layers the `aovs` parameter may ask for.
pub const NAMES: &[&str] = &[ALPHA, SAMPLING_VARIANCE, SAMPLE_COUNTS];

/// Channel of `alpha` for light `j` (its index in the scene's emitters).
pub fn light_channel(j: usize) -> String {
    format!("light{j}")
}

/// Layer with the coloured α of light `j` alone.
pub fn alpha_color_light(j: usize) -> String {
    format!("{ALPHA_COLOR}_light{j}")
}

/// The supplemental's §5.1 colouring: red = light sampling, green = BSDF sampling, yellow = ½.
pub fn alpha_color(alpha: f64) -> [f32; 3] {
    let m = alpha.max(1.0 - alpha);
    [((1.0 - alpha) / m) as f32, (alpha / m) as f32, 0.0]
}

/// The sums a pixel keeps of one light over its shading points, in the pixel's f64 sums.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct LightSums {
    /// Σ α.
    alpha: f64,
    /// The number of shading points.
    points: f64,
    /// Σ of the light's contribution (luminance).
    luminance: f64,
    /// Σ Y, Σ Y² and the number of samples Y (the one-sample estimates of the measured phases).
    y: f64,
    y_sq: f64,
    y_count: f64,
    /// Σ n·s² and Σ n over the counted phases (s² a phase's unbiased variance of Y, n its
    /// sample count).
    counted_variance: f64,
    counted_samples: f64,
}

/// The BSDF and light samples counted in the pixel, after its lights' sums.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SampleCounts {
    /// BSDF samples.
    pub bsdf: f64,
    /// Light samples.
    pub light: f64,
}

/// f64 sums per light in a pixel's sums.
pub const PER_LIGHT: usize = size_of::<LightSums>() / size_of::<f64>();
/// f64 sums of the sample counts, after the lights'.
pub const COUNTS: usize = size_of::<SampleCounts>() / size_of::<f64>();

/// A pixel's sums (as long as [`AovRequest::pixel_sums`] says) seen as what they hold: one
/// [`LightSums`] per light, then the [`SampleCounts`]. The same memory, so that the sums still
/// add as plain f64s.
pub fn pixel_sums(sums: &[f64]) -> (&[LightSums], &SampleCounts) {
    let (lights, counts) = sums.split_at(sums.len() - COUNTS);
    (
        bytemuck::cast_slice(lights),
        bytemuck::from_bytes(bytemuck::cast_slice(counts)),
    )
}

/// [`pixel_sums`], to add to.
fn pixel_sums_mut(sums: &mut [f64]) -> (&mut [LightSums], &mut SampleCounts) {
    let (lights, counts) = sums.split_at_mut(sums.len() - COUNTS);
    (
        bytemuck::cast_slice_mut(lights),
        bytemuck::from_bytes_mut(bytemuck::cast_slice_mut(counts)),
    )
}

/// Which AOV layers are written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AovRequest {
    pub alpha: bool,
    pub sampling_variance: bool,
    pub samples: bool,
}

/// The statistics of one light at one shading point, gathered from its phases as their roles
/// say ([`crate::phase::PhaseRole`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct LightTally {
    /// Σ Y and Σ Y² over the measured phases' samples, Y_i = n × (contribution of sample i)
    /// in luminance, n the phase's sample count: one-sample estimates of the light.
    sum: f64,
    sum_sq: f64,
    /// Samples of the measured phases.
    count: u32,
    /// Σ n·s² and Σ n over the counted phases of two samples or more (n the phase's samples,
    /// s² the unbiased variance of its Y).
    counted_variance: f64,
    counted_samples: f64,
    /// Samples of the counted phases.
    n_bsdf: u32,
    n_light: u32,
}

impl LightTally {
    /// The samples of the counted phases, of both techniques.
    pub(crate) fn samples(&self) -> u32 {
        self.n_bsdf + self.n_light
    }
}

impl Observer for LightTally {
    fn observe(&mut self, phase: &Phase, contributions: &[Rgb]) {
        let role = phase.role;
        if role.counted {
            self.n_bsdf += phase.split.n_bsdf;
            self.n_light += phase.split.n_light;
        }
        if !(role.measured || role.counted) {
            return;
        }
        let n = phase.split.n_bsdf as f32 + phase.split.n_light as f32;
        let (mut sum, mut sum_sq) = (0.0, 0.0);
        for c in contributions {
            let y = (luminance(*c) * n) as f64;
            sum += y;
            sum_sq += y * y;
        }
        if role.measured {
            self.sum += sum;
            self.sum_sq += sum_sq;
            self.count += phase.split.total();
        }
        let count = phase.split.total() as f64;
        if role.counted && count >= 2.0 {
            let variance = ((sum_sq - sum * sum / count) / (count - 1.0)).max(0.0);
            self.counted_variance += count * variance;
            self.counted_samples += count;
        }
    }
}

impl LightSums {
    /// The mean α over the shading points, if any.
    fn mean_alpha(&self) -> Option<f64> {
        (self.points > 0.0).then(|| self.alpha / self.points)
    }

    /// V[L₁] of the measured phases ([`Y`]), if two samples or more.
    pub fn measured_variance(&self) -> Option<f64> {
        (self.y_count >= 2.0)
            .then(|| ((self.y_sq - self.y * self.y / self.y_count) / (self.y_count - 1.0)).max(0.0))
    }

    /// V[L₁] over the counted phases ([`ESTIMATE`]), if any had two samples.
    pub fn estimate_variance(&self) -> Option<f64> {
        (self.counted_samples > 0.0).then(|| self.counted_variance / self.counted_samples)
    }
}

fn area_lights(scene: &Scene) -> impl Iterator<Item = usize> + '_ {
    (0..scene.emitters.len()).filter(|&j| !scene.emitters[j].is_delta())
}

impl AovRequest {
    /// The request of an `aovs` list (names from [`NAMES`]).
    pub fn from_names(names: &[&str]) -> Self {
        AovRequest {
            alpha: names.contains(&ALPHA),
            sampling_variance: names.contains(&SAMPLING_VARIANCE),
            samples: names.contains(&SAMPLE_COUNTS),
        }
    }

    pub fn any(&self) -> bool {
        self.alpha || self.sampling_variance || self.samples
    }

    /// The layers, in the order their values are written.
    pub fn declare(&self, scene: &Scene) -> Vec<Aov> {
        let rgb = || vec!["R".to_string(), "G".to_string(), "B".to_string()];
        let mut aovs = Vec::new();
        if self.alpha {
            let mut channels = vec![COMBINED.to_string()];
            channels.extend(area_lights(scene).map(light_channel));
            aovs.push(Aov {
                name: ALPHA.into(),
                channels,
                preview: false,
            });
            aovs.push(Aov {
                name: ALPHA_COLOR.into(),
                channels: rgb(),
                preview: true,
            });
            for j in area_lights(scene) {
                aovs.push(Aov {
                    name: alpha_color_light(j),
                    channels: rgb(),
                    preview: true,
                });
            }
        }
        if self.sampling_variance {
            aovs.push(Aov {
                name: SAMPLING_VARIANCE.into(),
                channels: vec![Y.into(), ESTIMATE.into()],
                preview: false,
            });
        }
        if self.samples {
            aovs.push(Aov {
                name: SAMPLE_COUNTS.into(),
                channels: vec![BSDF.into(), LIGHT.into()],
                preview: false,
            });
        }
        aovs
    }

    /// Sums per pixel: none unless a layer is asked for.
    pub fn pixel_sums(&self, scene: &Scene) -> usize {
        if self.any() {
            PER_LIGHT * scene.emitters.len() + COUNTS
        } else {
            0
        }
    }

    /// Adds light `light`'s estimate at one shading point and its tally to the pixel's sums.
    pub fn add(
        &self,
        sums: &mut [f64],
        light: usize,
        estimate: &LightEstimate,
        tally: &LightTally,
    ) {
        let (lights, counts) = pixel_sums_mut(sums);
        let sums = &mut lights[light];
        sums.alpha += estimate.alpha;
        sums.points += 1.0;
        sums.luminance += luminance(estimate.value) as f64;
        sums.y += tally.sum;
        sums.y_sq += tally.sum_sq;
        sums.y_count += tally.count as f64;
        sums.counted_variance += tally.counted_variance;
        sums.counted_samples += tally.counted_samples;
        counts.bsdf += tally.n_bsdf as f64;
        counts.light += tally.n_light as f64;
    }

    /// The pixel's AOV values from its sums, in the order of [`declare`](Self::declare).
    pub fn resolve(&self, scene: &Scene, sums: &[f64], aovs: &mut [f32]) {
        if !self.any() {
            return;
        }
        let (stats, counts) = pixel_sums(sums);
        let mut aov = aovs.iter_mut();
        let mut put = |v: f32| {
            if let Some(slot) = aov.next() {
                *slot = if v.is_finite() { v } else { 0.0 };
            }
        };
        if self.alpha {
            let alpha_of = |j: usize| stats[j].mean_alpha();
            // Combined: weighted by each light's contribution (a plain mean if all are black).
            let weight: f64 = area_lights(scene).map(|j| stats[j].luminance).sum();
            let combined = if weight > 0.0 {
                area_lights(scene)
                    .filter_map(|j| alpha_of(j).map(|a| a * stats[j].luminance))
                    .sum::<f64>()
                    / weight
            } else {
                let (sum, count) = area_lights(scene)
                    .filter_map(alpha_of)
                    .fold((0.0, 0u32), |(s, n), a| (s + a, n + 1));
                if count == 0 {
                    f64::NAN
                } else {
                    sum / count as f64
                }
            };
            // Pixels with no shading point (background) get α = ½ and black colours.
            put(if combined.is_nan() {
                0.5
            } else {
                combined as f32
            });
            for j in area_lights(scene) {
                put(alpha_of(j).unwrap_or(0.5) as f32);
            }
            let color = |a: f64| if a.is_nan() { [0.0; 3] } else { alpha_color(a) };
            for c in color(combined) {
                put(c);
            }
            for j in area_lights(scene) {
                for c in color(alpha_of(j).unwrap_or(f64::NAN)) {
                    put(c);
                }
            }
        }
        if self.sampling_variance {
            let variance: f64 = stats.iter().filter_map(LightSums::measured_variance).sum();
            put(variance as f32);
            let estimate: f64 = stats.iter().filter_map(LightSums::estimate_variance).sum();
            put(estimate as f32);
        }
        if self.samples {
            put(counts.bsdf as f32);
            put(counts.light as f32);
        }
    }
}
