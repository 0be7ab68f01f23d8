//! The variance of the mixture estimator at one shading point, exactly, as a function of α: a
//! test harness. A BSDF lobe (any [`Bsdf`], in its local frame, with a fixed ωo) is lit by a
//! spherical light seen under the angular radius θ_max around a direction, of constant radiance,
//! and sampled uniformly in its cone of directions (as the `area` emitter samples a sphere seen
//! from outside). Outside the cone f = 0, so every integral is over the cone, by quadrature:
//! composite Gauss–Legendre in the angle from the cone's axis (64 panels of 4 nodes, with the
//! sin θ′ of solid angle), trapezoids in azimuth (periodic, so spectrally accurate), 256 × 128
//! nodes, in f64.
//!
//! With f the luminance of BSDF · cos · L_e, p_B and p_L the two densities and q_α = α p_B + (1 −
//! α) p_L, it gives μ = ∫ f, the second moment m(α) = ∫ f²/q_α, the variance of the mixture
//! (one-sample) estimator m(α) − μ² and of the stratified one, its minimum α* over an interval,
//! the paper's second-order α̂ in the limit M → ∞ (exact I₁, I₂), and pilots of M samples drawn
//! by the BSDF's own `sample` and by cone sampling, as the integrators' records
//! ([`SampleRecord`]), to run any α estimator on ([`crate::moments::PilotSamples`],
//! [`crate::second_order::SecondOrderMoments`]). Tests use it to check where estimators of α land
//! (`tests/one_point.rs`).

use crate::estimator::SampleRecord;
use crate::moments::minimise_on_grid;
use glam::{DVec3, Vec2, Vec3};
use lumis_core::bsdf::{Bsdf, BsdfContext};
use lumis_core::math::{Frame, Rgb, luminance};
use lumis_core::sampler::Sampler;
use std::f64::consts::PI;

/// One quadrature node: its weight (solid angle) and the integrand's values there.
#[derive(Clone, Copy, Debug)]
struct Node {
    weight: f64,
    f: f64,
    p_bsdf: f64,
}

/// A BSDF lobe under a spherical light sampled in its cone.
pub struct OnePoint<'a> {
    bsdf: &'a dyn Bsdf,
    wo: Vec3,
    /// The light's frame (n: the cone's axis), in the BSDF's local frame.
    light_frame: Frame,
    /// 1 − cos θ_max.
    one_minus_cos_max: f64,
    radiance: f32,
    nodes: Vec<Node>,
}

/// Gauss–Legendre nodes and weights on [−1, 1], 4 points.
const GAUSS4: [(f64, f64); 4] = [
    (-0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
    (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
];

impl<'a> OnePoint<'a> {
    /// `bsdf` seen from `wo` (local frame, unit), lit by a sphere of constant `radiance` seen
    /// under the angular radius `radius` (radians, < π/2) around the unit direction `axis`.
    pub fn new(bsdf: &'a dyn Bsdf, wo: Vec3, axis: Vec3, radius: f64, radiance: f32) -> Self {
        let light_frame = Frame::from_normal(axis.normalize());
        // 1 − cos θ = 2 sin²(θ/2), free of cancellation for tiny cones.
        let one_minus_cos_max = 2.0 * (0.5 * radius).sin().powi(2);
        let mut point = OnePoint {
            bsdf,
            wo,
            light_frame,
            one_minus_cos_max,
            radiance,
            nodes: Vec::new(),
        };
        let (panels, azimuths) = (64, 128);
        let d_theta = radius / panels as f64;
        let d_phi = 2.0 * PI / azimuths as f64;
        for panel in 0..panels {
            for (x, w) in GAUSS4 {
                let theta = d_theta * (panel as f64 + 0.5 + 0.5 * x);
                let weight_theta = 0.5 * d_theta * w * theta.sin();
                for k in 0..azimuths {
                    let phi = d_phi * k as f64;
                    let local = DVec3::new(
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        theta.cos(),
                    );
                    let wi = light_frame.to_world(local.as_vec3());
                    point.nodes.push(Node {
                        weight: weight_theta * d_phi,
                        f: point.f(wi),
                        p_bsdf: bsdf.pdf(&BsdfContext::FRONT, wo, wi) as f64,
                    });
                }
            }
        }
        point
    }

    /// The integrand's luminance toward `wi`, inside the cone.
    fn f(&self, wi: Vec3) -> f64 {
        luminance(self.bsdf.eval(&BsdfContext::FRONT, self.wo, wi)) as f64 * self.radiance as f64
    }

    /// The light's density in its cone: 1 / (2π (1 − cos θ_max)).
    pub fn light_pdf(&self) -> f64 {
        1.0 / (2.0 * PI * self.one_minus_cos_max)
    }

    /// μ = ∫ f.
    pub fn mean(&self) -> f64 {
        self.nodes.iter().map(|n| n.weight * n.f).sum()
    }

    /// m(α) = ∫ f² / q_α.
    pub fn second_moment(&self, alpha: f64) -> f64 {
        let p_l = self.light_pdf();
        self.nodes
            .iter()
            .filter(|n| n.f > 0.0)
            .map(|n| n.weight * n.f * n.f / (alpha * n.p_bsdf + (1.0 - alpha) * p_l))
            .sum()
    }

    /// V[f / q_α] = m(α) − μ², the variance of the one-sample (mixture) estimator.
    pub fn variance(&self, alpha: f64) -> f64 {
        self.second_moment(alpha) - self.mean().powi(2)
    }

    /// N × the variance of the stratified estimator with a fraction α of BSDF samples:
    /// m(α) − α μ_B(α)² − (1 − α) μ_L(α)², μ_t = ∫ f p_t / q_α.
    pub fn stratified_variance(&self, alpha: f64) -> f64 {
        let p_l = self.light_pdf();
        let (mut m, mut mean_b, mut mean_l) = (0.0, 0.0, 0.0);
        for n in self.nodes.iter().filter(|n| n.f > 0.0) {
            let q = alpha * n.p_bsdf + (1.0 - alpha) * p_l;
            m += n.weight * n.f * n.f / q;
            mean_b += n.weight * n.f * n.p_bsdf / q;
            mean_l += n.weight * n.f * p_l / q;
        }
        m - alpha * mean_b * mean_b - (1.0 - alpha) * mean_l * mean_l
    }

    /// The α in `clamp` minimising `variance` (a function of α, e.g. [`Self::variance`]): the
    /// best of 17 evenly spaced points refined by golden section (to 10⁻⁴ of the interval).
    pub fn optimum(&self, clamp: [f64; 2], variance: impl Fn(f64) -> f64) -> f64 {
        minimise_on_grid(clamp, variance)
    }

    /// The paper's α̂ = ½ + ¼ I₁/I₂ from the exact integrals I₁ = ∫ f²Δp/p̄², I₂ = ∫ f²Δp²/p̄³
    /// (its limit as M → ∞), unclamped.
    pub fn second_order_alpha(&self) -> f64 {
        let p_l = self.light_pdf();
        let (mut i1, mut i2) = (0.0, 0.0);
        for n in self.nodes.iter().filter(|n| n.f > 0.0) {
            let p_bar = 0.5 * (n.p_bsdf + p_l);
            let delta = 0.5 * (n.p_bsdf - p_l);
            i1 += n.weight * n.f * n.f * delta / (p_bar * p_bar);
            i2 += n.weight * n.f * n.f * delta * delta / (p_bar * p_bar * p_bar);
        }
        0.5 + 0.25 * i1 / i2
    }

    /// Bounds on how far the paper's α̂ (its M → ∞ limit, unclamped) can be from α*, the α
    /// that minimises the second moment over [0, 1]. With t = 2α − 1 and r = Δp/p̄ ∈ [−1, 1],
    /// m(t) = ∫ f²/(p̄ (1 + t r)) has m′(t) = −∫ f² r/(p̄ (1 + t r)²) and m″(t) = 2 ∫ f² r²/(p̄
    /// (1 + t r)³) ≥ I₂/4 (as 1 + t r ≤ 2), so by the mean value theorem |t̂ − t*| ≤ 4 |m′(t̂)|/I₂,
    /// in α |α̂ − α*| ≤ 2 |m′(t̂)|/I₂; bounding m″ from below on that interval only and
    /// repeating tightens it: the *gradient* bound, computed by quadrature. α̂ zeroes the
    /// first two terms of the series of m′ in t, so |m′(t̂)| ≤ t̂² (3 − 2|t̂|)/(1 − |t̂|)² J₃ with
    /// J₃ = ∫ f² |r|³/p̄: the *Taylor* bound 2 t̂² (3 − 2|t̂|)/(1 − |t̂|)² J₃/I₂, quadratic in the
    /// distance of α̂ from ½, which says why α̂ is accurate near the crossover and nowhere else.
    /// Clamping both α̂ and α* to an interval only brings them closer. Returns α̂ and both
    /// bounds; they are infinite when |t̂| ≥ 1.
    pub fn second_order_error_bounds(&self) -> SecondOrderBounds {
        let p_l = self.light_pdf();
        let alpha = self.second_order_alpha();
        let t = 2.0 * alpha - 1.0;
        let (mut i2, mut j3, mut slope) = (0.0, 0.0, 0.0);
        for n in self.nodes.iter().filter(|n| n.f > 0.0) {
            let p_bar = 0.5 * (n.p_bsdf + p_l);
            let r = 0.5 * (n.p_bsdf - p_l) / p_bar;
            let w = n.weight * n.f * n.f / p_bar;
            i2 += w * r * r;
            j3 += w * (r * r * r).abs();
            slope -= w * r / (1.0 + t * r).powi(2);
        }
        if t.abs() >= 1.0 {
            return SecondOrderBounds {
                alpha,
                gradient: f64::INFINITY,
                taylor: f64::INFINITY,
            };
        }
        // t* is within δ = |m′(t̂)| / min m″ of t̂, the minimum taken over [t̂ − δ, t̂ + δ] ∩
        // [−1, 1] (m″ is convex: found by search); starting from the global m″ ≥ I₂/4, each
        // step's δ is valid and the next uses it to bound m″ from below more tightly.
        let mut delta = 4.0 * slope.abs() / i2;
        for _ in 0..8 {
            let range = [(t - delta).max(-1.0), (t + delta).min(1.0)];
            let t_low = minimise_on_grid(range, |u| self.second_moment_curvature(u));
            let curvature = self.second_moment_curvature(t_low).max(0.25 * i2);
            delta = delta.min(slope.abs() / curvature);
        }
        let a = t.abs();
        SecondOrderBounds {
            alpha,
            gradient: 0.5 * delta,
            taylor: 2.0 * a * a * (3.0 - 2.0 * a) / (1.0 - a).powi(2) * j3 / i2,
        }
    }

    /// m″(t) = 2 ∫ f² r² / (p̄ (1 + t r)³), t = 2α − 1, r = Δp/p̄.
    fn second_moment_curvature(&self, t: f64) -> f64 {
        let p_l = self.light_pdf();
        self.nodes
            .iter()
            .filter(|n| n.f > 0.0)
            .map(|n| {
                let p_bar = 0.5 * (n.p_bsdf + p_l);
                let r = 0.5 * (n.p_bsdf - p_l) / p_bar;
                2.0 * n.weight * n.f * n.f * r * r / (p_bar * (1.0 + t * r).powi(3))
            })
            .sum()
    }

    /// The largest 1 + r = 2 p_B/(p_B + p_L) where f > 0: how far the light is from a Dirac
    /// relative to the lobe. When it is ε, r ∈ [−1, −1 + ε] and α̂ ∈ [½ − 1/(4(1 − ε)), ¼]
    /// (the supplemental's concentrated-light limit, with its error).
    pub fn light_concentration(&self) -> f64 {
        let p_l = self.light_pdf();
        self.nodes
            .iter()
            .filter(|n| n.f > 0.0)
            .map(|n| 2.0 * n.p_bsdf / (n.p_bsdf + p_l))
            .fold(0.0, f64::max)
    }

    /// The optimal-MIS quantities at counts `n_bsdf`, `n_light` (Kondapaneni et al. 2019), by
    /// quadrature: A_ik = ∫ p_i p_k / p_mix and b_i = ∫ f p_i / p_mix, p_mix = n_B p_B + n_L
    /// p_L. A BSDF sample outside the cone (or a failed one) has f = p_L = 0, so it adds
    /// p_B/n_B to ∫ p_B²/p_mix: the BSDF's sampling mass outside the cone, 1 − ∫_cone p_B,
    /// over n_B.
    pub fn optimal_system(&self, n_bsdf: f64, n_light: f64) -> OptimalQuadrature {
        let p_l = self.light_pdf();
        let mut q = OptimalQuadrature {
            n: [n_bsdf, n_light],
            outside: 1.0 - self.bsdf_mass_in_cone(),
            ..OptimalQuadrature::default()
        };
        q.a[0][0] = q.outside / n_bsdf;
        for n in &self.nodes {
            let p_mix = n_bsdf * n.p_bsdf + n_light * p_l;
            let p = [n.p_bsdf, p_l];
            for i in 0..2 {
                for k in 0..2 {
                    q.a[i][k] += n.weight * p[i] * p[k] / p_mix;
                }
                q.b[i] += n.weight * n.f * p[i] / p_mix;
            }
        }
        q
    }

    /// ∫_cone p_B: the probability that a BSDF sample lands in the light's cone.
    pub fn bsdf_mass_in_cone(&self) -> f64 {
        self.nodes.iter().map(|n| n.weight * n.p_bsdf).sum()
    }

    /// The exact variance and mean of the multi-sample MIS estimator with counts n_B, n_L and
    /// the optimal weights' control-variate form with coefficients `coefficients` (a_B, a_L):
    /// ⟨F⟩ = a_B + a_L + Σ_t Σ_i g(x_ti), g = (f − a_B p_B − a_L p_L)/p_mix, whose variance
    /// is Σ_t n_t V_t[g]. Coefficients (0, 0) give the balance heuristic. Any coefficients give
    /// an unbiased estimator; those of [`OptimalQuadrature::solve`] the least variance of any
    /// weighting at these counts.
    pub fn weighted_variance(&self, q: &OptimalQuadrature, coefficients: [f64; 2]) -> (f64, f64) {
        let p_l = self.light_pdf();
        let [n_b, n_l] = q.n;
        let [a_b, a_l] = coefficients;
        // Per technique: E[g], E[g²]; the BSDF's samples outside the cone have g = −a_B/n_B.
        let outside_g = -a_b / n_b;
        let mut first = [q.outside * outside_g, 0.0];
        let mut second = [q.outside * outside_g * outside_g, 0.0];
        for n in &self.nodes {
            let p_mix = n_b * n.p_bsdf + n_l * p_l;
            let g = (n.f - a_b * n.p_bsdf - a_l * p_l) / p_mix;
            for (t, p) in [n.p_bsdf, p_l].into_iter().enumerate() {
                first[t] += n.weight * p * g;
                second[t] += n.weight * p * g * g;
            }
        }
        let variance =
            n_b * (second[0] - first[0] * first[0]) + n_l * (second[1] - first[1] * first[1]);
        let mean = a_b + a_l + n_b * first[0] + n_l * first[1];
        (variance, mean)
    }

    /// A pilot of `n_bsdf` samples drawn by the BSDF and `n_light` drawn uniformly in the cone,
    /// as the integrators' records (BSDF ones first), from the random stream `seed`.
    pub fn pilot(&self, n_bsdf: u32, n_light: u32, seed: u64) -> Vec<SampleRecord> {
        let mut sampler = Sampler::new(seed, 0, 0);
        let mut records = Vec::with_capacity((n_bsdf + n_light) as usize);
        let p_l = self.light_pdf() as f32;
        for _ in 0..n_bsdf {
            let (u_lobe, u) = (sampler.next_1d(), sampler.next_2d());
            let Some(s) = self.bsdf.sample(&BsdfContext::FRONT, self.wo, u_lobe, u) else {
                records.push(SampleRecord::default());
                continue;
            };
            let in_cone = self.in_cone(s.wi);
            records.push(SampleRecord {
                f: if in_cone {
                    s.weight * s.pdf * self.radiance
                } else {
                    Rgb::ZERO
                },
                p_bsdf: s.pdf,
                p_light: if in_cone { p_l } else { 0.0 },
                delta: s.delta,
            });
        }
        for _ in 0..n_light {
            let wi = self.sample_cone(sampler.next_2d());
            records.push(SampleRecord {
                f: self.bsdf.eval(&BsdfContext::FRONT, self.wo, wi) * self.radiance,
                p_bsdf: self.bsdf.pdf(&BsdfContext::FRONT, self.wo, wi),
                p_light: p_l,
                delta: false,
            });
        }
        records
    }

    /// Whether `wi` is in the light's cone.
    fn in_cone(&self, wi: Vec3) -> bool {
        1.0 - (self.light_frame.n.dot(wi) as f64) <= self.one_minus_cos_max
    }

    /// A direction uniform in the cone.
    fn sample_cone(&self, u: Vec2) -> Vec3 {
        let one_minus_cos = u.x as f64 * self.one_minus_cos_max;
        let cos = 1.0 - one_minus_cos;
        let sin = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y as f64;
        let local = DVec3::new(sin * phi.cos(), sin * phi.sin(), cos);
        self.light_frame.to_world(local.as_vec3())
    }
}

/// The paper's α̂ (M → ∞, unclamped) and two bounds on its distance to the optimum
/// ([`OnePoint::second_order_error_bounds`]).
#[derive(Clone, Copy, Debug)]
pub struct SecondOrderBounds {
    pub alpha: f64,
    /// ½ |m′(t̂)| / min m″ near t̂, from the exact slope at α̂.
    pub gradient: f64,
    /// 2 t̂² (3 − 2|t̂|)/(1 − |t̂|)² J₃/I₂, from the Taylor remainder.
    pub taylor: f64,
}

/// The optimal-MIS system of one shading point at given counts, by quadrature.
#[derive(Clone, Copy, Debug, Default)]
pub struct OptimalQuadrature {
    /// (n_B, n_L).
    pub n: [f64; 2],
    /// 1 − ∫_cone p_B.
    pub outside: f64,
    /// A_ik = ∫ p_i p_k / p_mix.
    pub a: [[f64; 2]; 2],
    /// b_i = ∫ f p_i / p_mix.
    pub b: [f64; 2],
}

impl OptimalQuadrature {
    /// The optimal coefficients a = A⁻¹ b.
    pub fn solve(&self) -> [f64; 2] {
        let [[a00, a01], [a10, a11]] = self.a;
        let det = a00 * a11 - a01 * a10;
        [
            (a11 * self.b[0] - a01 * self.b[1]) / det,
            (a00 * self.b[1] - a10 * self.b[0]) / det,
        ]
    }
}
