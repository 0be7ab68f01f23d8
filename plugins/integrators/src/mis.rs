//! The MIS integrator family: direct lighting at the first hit, each light estimated by
//! [`estimate_light`] with a sample split and a weighting chosen by the plugin, delta lights with
//! one sample each, emission seen by the camera added once. Plugins (`bsdf`, `light`, `balance`,
//! `power`, `max`, `alpha`) differ only in their [`Strategy`].

use crate::estimator::{
    Heuristic, LightEstimate, SampleSplit, ShadingPoint, camera_sample, emitted,
    estimate_delta_light, estimate_light, second_order_alpha,
};
use glam::UVec2;
use lumis_core::integrator::{Aov, Integrator, PixelOutput};
use lumis_core::math::{Rgb, luminance};
use lumis_core::params::{ParamKind, ParamSpec, Params, PluginError};
use lumis_core::scene::Scene;

/// How each light's N samples are split and weighted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Strategy {
    /// A fixed fraction α of BSDF samples, weighted by a heuristic.
    Fixed { alpha: f64, heuristic: Heuristic },
    /// Per shading point and light: M samples at α = ½ give L̂₁ and α̂, the other N − M samples
    /// at α̂ give L̂₂; the estimate is (M·L̂₁ + (N − M)·L̂₂) / N (paper, Table 2).
    Integrated { alpha_samples: u32, clamp: [f64; 2] },
    /// Per shading point and light: M samples at α = ½ give α̂ only; N fresh samples at α̂ give
    /// the estimate (paper, Table 1).
    Preprocessed { alpha_samples: u32, clamp: [f64; 2] },
}

/// Which AOV layers are written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AovRequest {
    pub alpha: bool,
    pub sampling_variance: bool,
    pub samples: bool,
}

/// A member of the MIS family.
pub struct MisIntegrator {
    pub strategy: Strategy,
    /// N, samples per light per camera sample.
    pub samples: u32,
    pub aovs: AovRequest,
}

/// `samples`, shared by the family.
pub const SAMPLES: ParamSpec = ParamSpec {
    name: "samples",
    kind: ParamKind::Int {
        default: Some(256),
        min: 1,
        max: 1 << 20,
    },
    unit: "",
    description: "N: samples per light per camera sample",
};

/// `aovs`, shared by the family.
pub const AOVS: ParamSpec = ParamSpec {
    name: "aovs",
    kind: ParamKind::List {
        options: &["alpha", "sampling_variance", "samples"],
    },
    unit: "",
    description: "extra output layers: alpha (per light, combined, and coloured), sampling_variance (V[L_1] per pixel, summed over lights), samples (BSDF and light sample counts)",
};

/// Reads `samples` and `aovs` and builds the integrator.
pub fn create(params: &mut Params, strategy: Strategy) -> Result<MisIntegrator, PluginError> {
    let samples = params.int("samples")? as u32;
    let list = params.list("aovs")?;
    let aovs = AovRequest {
        alpha: list.contains(&"alpha"),
        sampling_variance: list.contains(&"sampling_variance"),
        samples: list.contains(&"samples"),
    };
    Ok(MisIntegrator {
        strategy,
        samples,
        aovs,
    })
}

/// `create` of the plugins with a fixed split and weighting (`bsdf`, `light`, `balance`, `power`,
/// `max`).
pub fn create_fixed(
    params: &mut Params,
    alpha: f64,
    heuristic: Heuristic,
) -> Result<Box<dyn Integrator>, PluginError> {
    Ok(Box::new(create(
        params,
        Strategy::Fixed { alpha, heuristic },
    )?))
}

/// The supplemental's §5.1 colouring: red = light sampling, green = BSDF sampling, yellow = ½.
pub fn alpha_color(alpha: f64) -> [f32; 3] {
    let m = alpha.max(1.0 - alpha);
    [((1.0 - alpha) / m) as f32, (alpha / m) as f32, 0.0]
}

/// Per-light statistics gathered over a pixel's camera samples.
#[derive(Clone, Copy, Debug, Default)]
struct LightStats {
    alpha_sum: f64,
    shaded: u32,
    contribution: f64,
    sum: f64,
    sum_sq: f64,
    count: f64,
}

impl MisIntegrator {
    /// The estimate of one non-delta light at one shading point, the α it used, and the
    /// samples whose spread measures V[L_{1,α}].
    fn shade_light(
        &self,
        scene: &Scene,
        sp: &ShadingPoint,
        light: usize,
        sampler: &mut lumis_core::sampler::Sampler,
    ) -> (Rgb, f64, LightEstimate, SampleSplit) {
        let n = self.samples;
        let flags = sp.bsdf.flags();
        let pure_delta = flags.delta && !flags.diffuse && !flags.glossy;
        let balance = Heuristic::Balance;
        match self.strategy {
            Strategy::Fixed { alpha, heuristic } => {
                // Light sampling can never reach a Dirac lobe: "light only" gives it BSDF samples.
                let alpha = if alpha == 0.0 && pure_delta {
                    1.0
                } else {
                    alpha
                };
                let split = SampleSplit::new(alpha, n);
                let e = estimate_light(scene, sp, light, split, heuristic, false, sampler);
                (e.value, split.n_bsdf as f64 / n as f64, e, split)
            }
            Strategy::Integrated {
                alpha_samples,
                clamp,
            } => {
                let m = alpha_samples.min(n);
                let first_split = SampleSplit::new(0.5, m);
                let first = estimate_light(scene, sp, light, first_split, balance, true, sampler);
                let alpha = second_order_alpha(first.i1, first.i2)
                    .unwrap_or(0.5)
                    .clamp(clamp[0], clamp[1]);
                let rest = n - m;
                if rest == 0 {
                    return (first.value, alpha, first, first_split);
                }
                let second_split = SampleSplit::new(alpha, rest);
                let second =
                    estimate_light(scene, sp, light, second_split, balance, false, sampler);
                let value = (first.value * m as f32 + second.value * rest as f32) / n as f32;
                let spread = if rest >= 2 { second } else { first };
                let total = SampleSplit {
                    n_bsdf: first_split.n_bsdf + second_split.n_bsdf,
                    n_light: first_split.n_light + second_split.n_light,
                };
                (value, alpha, spread, total)
            }
            Strategy::Preprocessed {
                alpha_samples,
                clamp,
            } => {
                let pilot = estimate_light(
                    scene,
                    sp,
                    light,
                    SampleSplit::new(0.5, alpha_samples),
                    balance,
                    true,
                    sampler,
                );
                let alpha = second_order_alpha(pilot.i1, pilot.i2)
                    .unwrap_or(0.5)
                    .clamp(clamp[0], clamp[1]);
                let split = SampleSplit::new(alpha, n);
                let e = estimate_light(scene, sp, light, split, balance, false, sampler);
                (e.value, alpha, e, split)
            }
        }
    }

    fn any_aov(&self) -> bool {
        self.aovs.alpha || self.aovs.sampling_variance || self.aovs.samples
    }
}

fn area_lights(scene: &Scene) -> impl Iterator<Item = usize> + '_ {
    (0..scene.emitters.len()).filter(|&j| !scene.emitters[j].is_delta())
}

impl Integrator for MisIntegrator {
    fn aovs(&self, scene: &Scene) -> Vec<Aov> {
        let rgb = || vec!["R".to_string(), "G".to_string(), "B".to_string()];
        let mut aovs = Vec::new();
        if self.aovs.alpha {
            let mut channels = vec!["combined".to_string()];
            channels.extend(area_lights(scene).map(|j| format!("light{j}")));
            aovs.push(Aov {
                name: "alpha".into(),
                channels,
                preview: false,
            });
            aovs.push(Aov {
                name: "alpha_color".into(),
                channels: rgb(),
                preview: true,
            });
            for j in area_lights(scene) {
                aovs.push(Aov {
                    name: format!("alpha_color_light{j}"),
                    channels: rgb(),
                    preview: true,
                });
            }
        }
        if self.aovs.sampling_variance {
            aovs.push(Aov {
                name: "sampling_variance".into(),
                channels: vec!["Y".into()],
                preview: false,
            });
        }
        if self.aovs.samples {
            aovs.push(Aov {
                name: "samples".into(),
                channels: vec!["bsdf".into(), "light".into()],
                preview: false,
            });
        }
        aovs
    }

    fn render_pixel(&self, scene: &Scene, pixel: UVec2, out: &mut PixelOutput<'_>) {
        // Statistics only when an AOV asks for them, in a buffer each thread reuses: no
        // allocation per pixel (with one camera sample a pixel, per sample).
        if !self.any_aov() {
            return self.shade_pixel(scene, pixel, out, &mut []);
        }
        PIXEL_STATS.with_borrow_mut(|stats| {
            stats.clear();
            stats.resize(scene.emitters.len(), LightStats::default());
            self.shade_pixel(scene, pixel, out, stats);
        });
    }
}

thread_local! {
    static PIXEL_STATS: std::cell::RefCell<Vec<LightStats>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

impl MisIntegrator {
    /// Renders one pixel; `stats` (one entry per light, or empty when no AOV is asked for)
    /// gathers what the AOVs report.
    fn shade_pixel(
        &self,
        scene: &Scene,
        pixel: UVec2,
        out: &mut PixelOutput<'_>,
        stats: &mut [LightStats],
    ) {
        let (mut bsdf_samples, mut light_samples) = (0u64, 0u64);
        let mut total = glam::DVec3::ZERO;
        for s in 0..scene.spp {
            let (mut sampler, ray) = camera_sample(scene, pixel, s);
            let Some(hit) = scene.intersect(&ray) else {
                total += scene.environment_radiance(ray.direction).as_dvec3();
                continue;
            };
            let mut radiance = emitted(scene, &hit, ray.direction);
            let sp = ShadingPoint::new(scene, hit, -ray.direction);
            for (light, emitter) in scene.emitters.iter().enumerate() {
                if emitter.is_delta() {
                    radiance += estimate_delta_light(scene, &sp, light, &mut sampler);
                    continue;
                }
                let (value, alpha, spread, split) =
                    self.shade_light(scene, &sp, light, &mut sampler);
                radiance += value;
                if let Some(st) = stats.get_mut(light) {
                    st.alpha_sum += alpha;
                    st.shaded += 1;
                    st.contribution += luminance(value) as f64;
                    st.sum += spread.sum;
                    st.sum_sq += spread.sum_sq;
                    st.count += spread.samples as f64;
                    bsdf_samples += split.n_bsdf as u64;
                    light_samples += split.n_light as u64;
                }
            }
            total += radiance.as_dvec3();
        }
        out.color = (total / scene.spp as f64).as_vec3();
        if stats.is_empty() {
            return;
        }

        let mut aov = out.aovs.iter_mut();
        let mut put = |v: f32| {
            if let Some(slot) = aov.next() {
                *slot = if v.is_finite() { v } else { 0.0 };
            }
        };
        if self.aovs.alpha {
            let alpha_of = |j: usize| {
                let st = &stats[j];
                (st.shaded > 0).then(|| st.alpha_sum / st.shaded as f64)
            };
            // Combined: weighted by each light's contribution (a plain mean if all are black).
            let weight: f64 = area_lights(scene).map(|j| stats[j].contribution).sum();
            let combined = if weight > 0.0 {
                area_lights(scene)
                    .filter_map(|j| alpha_of(j).map(|a| a * stats[j].contribution))
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
        if self.aovs.sampling_variance {
            let variance: f64 = stats
                .iter()
                .filter(|st| st.count >= 2.0)
                .map(|st| ((st.sum_sq - st.sum * st.sum / st.count) / (st.count - 1.0)).max(0.0))
                .sum();
            put(variance as f32);
        }
        if self.aovs.samples {
            put(bsdf_samples as f32);
            put(light_samples as f32);
        }
    }
}
