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

use glam::{UVec2, Vec2, Vec3};
use lumis_core::accel::{Intersection, Ray};
use lumis_core::bsdf::Bsdf;
use lumis_core::emitter::{EmitterHit, EmitterSample, ReferencePoint};
use lumis_core::math::{Frame, Rgb, luminance};
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

    /// BSDF value (with cosine) toward a light sample, zero when it cannot reflect there. A
    /// light point closer to the surface's plane than the rounding error of the shading point
    /// (a light lying on the surface) is on no definite side of it, and lights nothing.
    fn eval_toward(&self, sample: &EmitterSample) -> Rgb {
        let height = self.normal.dot(sample.wi);
        let undecided = sample.position.is_some_and(|p| {
            height * (p - self.hit.position).length() <= self.normal.abs().dot(self.hit.error)
        });
        if height <= 0.0 || undecided {
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

impl SampleSplit {
    /// `n` samples with a fraction `alpha` from the BSDF: n_B = ⌊α·n + ½⌋, n_L = n − n_B. When
    /// 0 < α < 1 and n ≥ 2 each technique keeps at least one sample, so that neither technique's
    /// support is ever dropped (a mirror needs BSDF samples, a point-like light light samples).
    /// The weights use these realised counts, so the estimate is unbiased for any α.
    pub fn new(alpha: f64, n: u32) -> Self {
        let mut n_bsdf = ((alpha * n as f64 + 0.5).floor() as u32).min(n);
        if alpha > 0.0 && alpha < 1.0 && n >= 2 {
            n_bsdf = n_bsdf.clamp(1, n - 1);
        }
        SampleSplit {
            n_bsdf,
            n_light: n - n_bsdf,
        }
    }

    pub fn total(&self) -> u32 {
        self.n_bsdf + self.n_light
    }
}

/// How the samples of the two techniques are weighted (Veach 1997).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Heuristic {
    /// w_i = n_i p_i / Σ n_k p_k: the mixture (defensive) estimator.
    Balance,
    /// w_i = (n_i p_i)² / Σ (n_k p_k)².
    Power,
    /// w_i = 1 for the technique with the larger n_i p_i.
    Maximum,
}

impl Heuristic {
    /// Weight of the technique with n·p = `mine` against the other's `other`, written with the
    /// ratio other/mine so that huge or tiny densities neither overflow nor divide 0 by 0.
    #[inline]
    fn weight(self, mine: f32, other: f32) -> f32 {
        if mine == other {
            return 0.5;
        }
        let r = other / mine;
        match self {
            Heuristic::Balance => 1.0 / (1.0 + r),
            Heuristic::Power => 1.0 / (1.0 + r * r),
            Heuristic::Maximum => {
                if r < 1.0 {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }
}

/// Where a BSDF-sampled ray reaches light `light`, if it does: the emitter hit (None for the
/// environment) and the radiance arriving.
fn reaches_light(scene: &Scene, light: usize, ray: &Ray) -> Option<(Option<EmitterHit>, Rgb)> {
    let emitter = scene.emitters[light].as_ref();
    // Most BSDF rays meet something other than this light: only its hits need the surface.
    match scene.first_hit(ray) {
        None if scene.environment == Some(light) => Some((None, emitter.eval(ray.direction, None))),
        None => None,
        Some(first) if scene.emitter_of_shape(first.shape) == Some(light) => {
            let hit = scene.geometry.surface(ray, &first);
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

/// One light's estimate at one shading point, with the statistics the integrators report.
#[derive(Clone, Copy, Debug, Default)]
pub struct LightEstimate {
    /// The estimate of the reflected radiance from this light, L̂_j.
    pub value: Rgb,
    /// Σ Y and Σ Y² of the one-sample estimates Y_i = N · (sample i's contribution), luminance.
    pub sum: f64,
    pub sum_sq: f64,
    pub samples: u32,
    /// Σ f² Δp / p̄³ and Σ f² Δp² / p̄⁴ over the samples (only when asked for): the paper's I₁
    /// and I₂ times the number of samples.
    pub i1: f64,
    pub i2: f64,
}

impl LightEstimate {
    fn add(&mut self, contribution: Rgb, n: f32) {
        self.value += contribution;
        let y = (luminance(contribution) * n) as f64;
        self.sum += y;
        self.sum_sq += y * y;
    }

    /// Accumulates the α statistics of one sample of scalar integrand f and densities p_B, p_L.
    fn add_alpha_terms(&mut self, f: f32, p_bsdf: f32, p_light: f32) {
        let (f, p_b, p_l) = (f as f64, p_bsdf as f64, p_light as f64);
        let p_bar = 0.5 * (p_b + p_l);
        if f == 0.0 || p_bar.is_nan() || p_bar <= 0.0 || !p_bar.is_finite() {
            return;
        }
        let delta_p = 0.5 * (p_b - p_l);
        let f2 = f * f;
        self.i1 += f2 * delta_p / (p_bar * p_bar * p_bar);
        self.i2 += f2 * delta_p * delta_p / (p_bar * p_bar * p_bar * p_bar);
    }
}

/// The estimate of the radiance reflected at `sp` from non-delta light `light`, with `split`
/// samples weighted by `heuristic`; `alpha_terms` also accumulates the α statistics (meant for
/// samples taken at α = ½, which are a stratified sample of p̄).
pub fn estimate_light(
    scene: &Scene,
    sp: &ShadingPoint,
    light: usize,
    split: SampleSplit,
    heuristic: Heuristic,
    alpha_terms: bool,
    sampler: &mut Sampler,
) -> LightEstimate {
    let emitter = scene.emitters[light].as_ref();
    let reference = ReferencePoint {
        position: sp.hit.position,
    };
    let (n_b, n_l) = (split.n_bsdf as f32, split.n_light as f32);
    let n = n_b + n_l;
    let mut estimate = LightEstimate {
        samples: split.total(),
        ..Default::default()
    };

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
            // For α, p_B → ∞ makes both f²Δp/p̄³ and f²Δp²/p̄⁴ tend to 4 (f/p_B)².
            let weight = s.weight * le;
            estimate.add(weight / n_b, n);
            if alpha_terms {
                let w = luminance(weight) as f64;
                estimate.i1 += 4.0 * w * w;
                estimate.i2 += 4.0 * w * w;
            }
            continue;
        }
        let p_light = emitter.pdf_direction(&reference, wi, hit.as_ref());
        let f = s.weight * s.pdf * le;
        let w = heuristic.weight(n_b * s.pdf, n_l * p_light);
        estimate.add(f * (w / (n_b * s.pdf)), n);
        if alpha_terms {
            estimate.add_alpha_terms(luminance(f), s.pdf, p_light);
        }
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
        let f = f * ls.radiance;
        let w = heuristic.weight(n_l * ls.pdf, n_b * p_bsdf);
        estimate.add(f * (w / (n_l * ls.pdf)), n);
        if alpha_terms {
            estimate.add_alpha_terms(luminance(f), p_bsdf, ls.pdf);
        }
    }
    estimate
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

/// The unclamped second-order α from the sums of [`LightEstimate`]: ½ + ¼ · I₁ / I₂, or `None`
/// when I₂ is zero or not finite (no sample saw the light, or p_B = p_L everywhere).
pub fn second_order_alpha(i1: f64, i2: f64) -> Option<f64> {
    let ratio = i1 / i2;
    (i2 > 0.0 && i2.is_finite() && ratio.is_finite()).then_some(0.5 + 0.25 * ratio)
}

/// The camera sample `index` of `pixel`: its random stream and primary ray.
pub fn camera_sample(scene: &Scene, pixel: UVec2, index: u32) -> (Sampler, Ray) {
    let pixel_index = pixel.y as u64 * scene.width as u64 + pixel.x as u64;
    let mut sampler = Sampler::new(scene.seed, pixel_index, index as u64);
    // The offset is drawn either way, so that the rest of the sample stream does not depend on it.
    let offset = sampler.next_2d();
    let film = pixel.as_vec2()
        + if scene.jitter {
            offset
        } else {
            Vec2::splat(0.5)
        };
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

#[cfg(test)]
mod tests {
    use super::*;

    /// α̂ from a synthetic integrand on [0, 1]: p_B is a box of height k (width 1/k), p_L = 1,
    /// and f follows `f_of(p_B, p_L)`. Half the samples come from each density (a stratified
    /// sample of p̄), as at α = ½.
    fn synthetic_alpha(k: f32, f_of: impl Fn(f32, f32) -> f32) -> f64 {
        let mut e = LightEstimate::default();
        let n = 20_000;
        for i in 0..n {
            let u = (i as f32 + 0.5) / n as f32;
            for x in [u / k, u] {
                let p_bsdf = if x < 1.0 / k { k } else { 0.0 };
                e.add_alpha_terms(f_of(p_bsdf, 1.0), p_bsdf, 1.0);
            }
        }
        second_order_alpha(e.i1, e.i2).unwrap()
    }

    #[test]
    fn a_near_mirror_lobe_under_a_broad_light_gives_three_quarters() {
        // f concentrated where p_B is: the supplemental's §1.4 limit.
        let alpha = synthetic_alpha(1e4, |p_b, _| p_b);
        assert!((alpha - 0.75).abs() < 1e-3, "{alpha}");
    }

    #[test]
    fn a_tiny_light_over_a_broad_lobe_gives_one_quarter() {
        // Swap roles: f follows the concentrated density, now the light's.
        let mut e = LightEstimate::default();
        let k = 1e4f32;
        for i in 0..20_000 {
            let u = (i as f32 + 0.5) / 20_000.0;
            for x in [u / k, u] {
                let p_light = if x < 1.0 / k { k } else { 0.0 };
                e.add_alpha_terms(p_light, 1.0, p_light);
            }
        }
        let alpha = second_order_alpha(e.i1, e.i2).unwrap();
        assert!((alpha - 0.25).abs() < 1e-3, "{alpha}");
    }

    #[test]
    fn undefined_estimates_give_none_and_equal_densities_give_one_half() {
        assert_eq!(second_order_alpha(0.0, 0.0), None);
        assert_eq!(second_order_alpha(1.0, f64::INFINITY), None);
        // p_B = p_L everywhere: Δp = 0, I₂ = 0, so α is undefined (the integrator uses ½).
        let mut e = LightEstimate::default();
        for i in 0..100 {
            e.add_alpha_terms(1.0 + i as f32, 2.0, 2.0);
        }
        assert_eq!(second_order_alpha(e.i1, e.i2), None);
    }

    #[test]
    fn sample_splits_round_and_keep_both_techniques() {
        assert_eq!(
            SampleSplit::new(0.5, 256),
            SampleSplit {
                n_bsdf: 128,
                n_light: 128
            }
        );
        assert_eq!(
            SampleSplit::new(0.025, 16),
            SampleSplit {
                n_bsdf: 1,
                n_light: 15
            }
        );
        assert_eq!(
            SampleSplit::new(0.975, 16),
            SampleSplit {
                n_bsdf: 15,
                n_light: 1
            }
        );
        assert_eq!(
            SampleSplit::new(1.0, 16),
            SampleSplit {
                n_bsdf: 16,
                n_light: 0
            }
        );
        assert_eq!(
            SampleSplit::new(0.0, 16),
            SampleSplit {
                n_bsdf: 0,
                n_light: 16
            }
        );
        assert_eq!(SampleSplit::new(0.3, 1).total(), 1);
    }

    #[test]
    fn heuristic_weights_of_the_two_techniques_sum_to_one() {
        for h in [Heuristic::Balance, Heuristic::Power, Heuristic::Maximum] {
            for (a, b) in [(1.0f32, 3.0f32), (2.0, 2.0), (5.0, 0.0), (1e-30, 1e30)] {
                let sum = h.weight(a, b) + h.weight(b, a);
                assert!((sum - 1.0).abs() < 1e-6, "{h:?} {a} {b}: {sum}");
            }
        }
    }
}
