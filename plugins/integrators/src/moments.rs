//! What a pilot phase (samples of both techniques, at a known split) says about the variance of
//! the mixture estimator at any other split α, and the α that minimises it: the exact minimum
//! of the pilot's estimate of the second moment (`exact_alpha`), of the variance of the
//! stratified estimator the integrators actually use, and of variance × cost (`cost_alpha`).
//!
//! A pilot of M samples, n_B from the BSDF and n_L from the light (β = n_B / M), is a
//! stratified sample of p_s = β p_B + (1 − β) p_L. With y = f / p_s and r_t = p_t / p_s, the
//! mixture q_α = α p_B + (1 − α) p_L has q_α / p_s = d(α) = r_L + α (r_B − r_L), and
//!
//! ```text
//!   m̂(α)   = (1/M) Σ y² / d(α)          estimates ∫ f² / q_α, the second moment of f / q_α;
//!   μ̂_t(α) = (1/M) Σ y r_t / d(α)       estimates ∫ f p_t / q_α, the mean of technique t's
//!                                        samples' f / q_α (α μ̂_B + (1 − α) μ̂_L = μ̂ = (1/M) Σ y).
//! ```
//!
//! Squares of means (μ², μ_t²) are estimated without bias, stratum by stratum (the pilot's
//! samples are two independent strata), so that the noise of a small pilot does not favour one
//! split over another.
//!
//! m̂ is convex in α (each term is y² / d with d linear and positive), so its minimum over an
//! interval is found by a safeguarded Newton iteration on m̂′. With N samples at α, the mixture
//! (one-sample) estimator has variance (m − μ²) / N, and the stratified estimator the
//! integrators use (exactly n_B = αN BSDF samples) (m − α μ_B² − (1 − α) μ_L²) / N: smaller by
//! α (1 − α)(μ_B − μ_L)² / N, most where the techniques see different parts of f. Neither this
//! nor variance × cost need be convex: they are minimised on a grid refined by golden section.
//!
//! A Dirac BSDF sample (p_B → ∞) has r_B = 1/β, r_L = 0 and y = f_rec / β (its record's f is
//! already divided by the Dirac density). Black records add nothing but count in M.

use crate::estimator::SampleRecord;
use crate::phase::Phase;
use lumis_core::math::luminance;

/// What is minimised over α (each divided by N, which does not move the minimum).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Objective {
    /// The second moment m(α) of the mixture estimator, i.e. its variance m(α) − μ².
    Mixture,
    /// The variance of the stratified estimator, m(α) − α μ_B(α)² − (1 − α) μ_L(α)².
    Stratified,
    /// A variance (mixture or stratified, `stratified`) times the cost of N samples at α,
    /// α c_B + (1 − α) c_L: the inverse of the efficiency.
    Cost {
        stratified: bool,
        bsdf: f64,
        light: f64,
    },
}

/// Sums over the samples of one stratum (one technique's samples) of a quantity z: Σ z and
/// Σ z².
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct StratumSums {
    sum: f64,
    sum_sq: f64,
}

impl StratumSums {
    #[inline]
    fn add(&mut self, z: f64) {
        self.sum += z;
        self.sum_sq += z * z;
    }
}

/// The mean of z over a pilot of two strata (n_B BSDF samples, n_L light samples), and an
/// unbiased estimate of its square: β² U_B + 2β(1 − β) z̄_B z̄_L + (1 − β)² U_L, with U_s =
/// ((Σ_s z)² − Σ_s z²) / (n_s (n_s − 1)) the unbiased estimate of the square of stratum s's
/// mean (the square of the sample mean would exceed it by the mean's variance, and bias a
/// minimum toward the split that shrinks that variance). A stratum of fewer than two samples
/// falls back to the square of its mean.
fn mean_and_square(strata: [StratumSums; 2], counts: [f64; 2]) -> (f64, f64) {
    let m = counts[0] + counts[1];
    let mean_of = |s: StratumSums, n: f64| if n > 0.0 { s.sum / n } else { 0.0 };
    let square_of = |s: StratumSums, n: f64| {
        if n >= 2.0 {
            (s.sum * s.sum - s.sum_sq) / (n * (n - 1.0))
        } else {
            mean_of(s, n).powi(2)
        }
    };
    let (b, l) = (counts[0] / m, counts[1] / m);
    let (mean_b, mean_l) = (mean_of(strata[0], counts[0]), mean_of(strata[1], counts[1]));
    let mean = b * mean_b + l * mean_l;
    let square = b * b * square_of(strata[0], counts[0])
        + 2.0 * b * l * mean_b * mean_l
        + l * l * square_of(strata[1], counts[1]);
    (mean, square)
}

/// The pilot's estimates at one α.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PilotSums {
    /// m̂(α).
    pub second_moment: f64,
    /// μ̂_B(α), μ̂_L(α).
    pub mean_bsdf: f64,
    pub mean_light: f64,
    /// Unbiased estimates of μ_B(α)² and μ_L(α)².
    pub square_bsdf: f64,
    pub square_light: f64,
}

/// A pilot phase's records, read as estimates of functions of α.
#[derive(Clone, Copy, Debug)]
pub struct PilotSamples<'a> {
    records: &'a [SampleRecord],
    n_bsdf: usize,
    /// β = n_B / M.
    beta: f64,
    /// 1 / M.
    inv_count: f64,
}

impl<'a> PilotSamples<'a> {
    /// The records of `phase`, drawn at its split.
    pub fn new(phase: &Phase<'a>) -> Self {
        Self::from_records(phase.records, phase.split.n_bsdf, phase.split.n_light)
    }

    /// `records`, the first `n_bsdf` drawn from the BSDF and the next `n_light` from the light.
    pub fn from_records(records: &'a [SampleRecord], n_bsdf: u32, n_light: u32) -> Self {
        let m = (n_bsdf + n_light).max(1) as f64;
        PilotSamples {
            records,
            n_bsdf: n_bsdf as usize,
            beta: n_bsdf as f64 / m,
            inv_count: 1.0 / m,
        }
    }

    /// (f, p_s, p_B, p_L) of a record, if it is not black and has a positive finite p_s: the
    /// one filter of [`term`](Self::term) and [`weighted_densities`](Self::weighted_densities)
    /// (a Dirac sample's as p_s = β, p_B = 1, p_L = 0).
    #[inline(always)]
    fn densities(&self, r: &SampleRecord) -> Option<(f64, f64, f64, f64)> {
        if r.is_black() {
            return None;
        }
        let beta = self.beta;
        let f = luminance(r.f) as f64;
        if r.delta {
            return (beta > 0.0 && f != 0.0).then_some((f, beta, 1.0, 0.0));
        }
        let (p_b, p_l) = (r.p_bsdf as f64, r.p_light as f64);
        let p_s = beta * p_b + (1.0 - beta) * p_l;
        (p_s > 0.0 && p_s.is_finite() && f != 0.0).then_some((f, p_s, p_b, p_l))
    }

    /// (y, r_B, r_L) of a record, if it is not black and has a positive finite p_s.
    #[inline]
    fn term(&self, r: &SampleRecord) -> Option<(f64, f64, f64)> {
        self.densities(r)
            .map(|(f, p_s, p_b, p_l)| (f / p_s, p_b / p_s, p_l / p_s))
    }

    /// (y, r_B, r_L) of every record that is not black and has a positive finite p_s.
    #[inline]
    fn terms(&self) -> impl Iterator<Item = (f64, f64, f64)> + '_ {
        self.records.iter().filter_map(|r| self.term(r))
    }

    /// The pilot's stratum sizes (n_B, n_L).
    fn counts(&self) -> [f64; 2] {
        let n_b = self.n_bsdf.min(self.records.len());
        [n_b as f64, (self.records.len() - n_b) as f64]
    }

    /// μ̂ = (1/M) Σ y, the pilot's (balance) estimate of the integral, in luminance.
    pub fn mean(&self) -> f64 {
        self.terms().map(|(y, _, _)| y).sum::<f64>() * self.inv_count
    }

    /// μ̂ and an unbiased estimate of μ².
    pub fn mean_and_square(&self) -> (f64, f64) {
        let mut strata = [StratumSums::default(); 2];
        for (i, r) in self.records.iter().enumerate() {
            if let Some((y, _, _)) = self.term(r) {
                strata[usize::from(i >= self.n_bsdf)].add(y);
            }
        }
        mean_and_square(strata, self.counts())
    }

    /// The paper's Î₁ and Î₂ ([`crate::second_order`]), the integrals ∫ f² Δp / p̄² and
    /// ∫ f² Δp² / p̄³ that samples at α = ½ estimate, estimated from these records at their own
    /// split: with b = p̄ / p_s and d = Δp / p_s, the means of y² d / b² and y² d² / b³ (at
    /// β = ½ the paper's terms; a Dirac sample adds 2β y² to both, the paper's 4 (f/p_B)² at ½).
    pub fn second_order(&self) -> (f64, f64) {
        let (mut i1, mut i2) = (0.0, 0.0);
        for (y, r_b, r_l) in self.terms() {
            let (b, d) = (0.5 * (r_b + r_l), 0.5 * (r_b - r_l));
            let y2 = y * y;
            i1 += y2 * d / (b * b);
            i2 += y2 * d * d / (b * b * b);
        }
        (i1 * self.inv_count, i2 * self.inv_count)
    }

    /// m̂, μ̂_B, μ̂_L and the unbiased estimates of μ_B² and μ_L² at `alpha`.
    pub fn sums(&self, alpha: f64) -> PilotSums {
        let mut second_moment = 0.0;
        // Per technique t (B, L), its quantity y r_t / d summed per stratum.
        let mut z = [[StratumSums::default(); 2]; 2];
        // A term whose q_α is 0 (α at 0 or 1, where the other technique alone has density)
        // makes m̂ infinite, as it is.
        for (i, r) in self.records.iter().enumerate() {
            let Some((y, r_b, r_l)) = self.term(r) else {
                continue;
            };
            let stratum = usize::from(i >= self.n_bsdf);
            let inv = 1.0 / (r_l + alpha * (r_b - r_l));
            second_moment += y * y * inv;
            if r_b > 0.0 {
                z[0][stratum].add(y * r_b * inv);
            }
            if r_l > 0.0 {
                z[1][stratum].add(y * r_l * inv);
            }
        }
        let counts = self.counts();
        let (mean_bsdf, square_bsdf) = mean_and_square(z[0], counts);
        let (mean_light, square_light) = mean_and_square(z[1], counts);
        PilotSums {
            second_moment: second_moment * self.inv_count,
            mean_bsdf,
            mean_light,
            square_bsdf,
            square_light,
        }
    }

    /// m̂′(α) and m̂″(α).
    fn second_moment_slopes(&self, alpha: f64) -> (f64, f64) {
        let (mut d1, mut d2) = (0.0, 0.0);
        for (y, r_b, r_l) in self.terms() {
            let delta = r_b - r_l;
            // Where q_α = 0 the slope is infinite, toward the technique with density there.
            let inv = 1.0 / (r_l + alpha * delta);
            let a = y * y * delta * inv * inv;
            d1 -= a;
            d2 += 2.0 * a * delta * inv;
        }
        (d1 * self.inv_count, d2 * self.inv_count)
    }

    /// Whether α matters at all: some record with f ≠ 0 where p_B ≠ p_L. If not (no sample saw
    /// the light, or the densities agree), every α gives the same estimate.
    pub fn informative(&self) -> bool {
        self.terms().any(|(_, r_b, r_l)| r_b != r_l)
    }

    /// The α in `clamp` that minimises m̂ exactly (to 10⁻⁶), or `None` if the pilot is not
    /// [`informative`](Self::informative). m̂ is convex: if its slope is ≥ 0 at the lower bound
    /// or ≤ 0 at the upper, that bound; otherwise Newton steps on m̂′ = 0 kept inside a
    /// bracket that shrinks with the sign of m̂′ (bisection when a step leaves it).
    pub fn exact_minimum(&self, clamp: [f64; 2]) -> Option<f64> {
        if !self.informative() {
            return None;
        }
        let [mut lo, mut hi] = clamp;
        if self.second_moment_slopes(lo).0 >= 0.0 {
            return Some(lo);
        }
        if self.second_moment_slopes(hi).0 <= 0.0 {
            return Some(hi);
        }
        let mut alpha = 0.5 * (lo + hi);
        for _ in 0..60 {
            let (d1, d2) = self.second_moment_slopes(alpha);
            if d1 < 0.0 {
                lo = alpha;
            } else if d1 > 0.0 {
                hi = alpha;
            } else {
                break;
            }
            let newton = alpha - d1 / d2;
            let next = if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            let converged = (next - alpha).abs() < 1e-6 || hi - lo < 1e-6;
            alpha = next;
            if converged {
                break;
            }
        }
        Some(alpha)
    }

    /// The objective at `alpha` (+∞ where it is infinite or undefined: at α = 0 or 1 when the
    /// excluded technique alone reaches part of f).
    pub fn objective(&self, objective: Objective, alpha: f64) -> f64 {
        let value = self.objective_value(objective, alpha);
        if value.is_nan() { f64::INFINITY } else { value }
    }

    /// Adds the objective at `K` evenly spaced α of `clamp` (its ends included) to `out`, if
    /// the pilot is [`informative`](Self::informative) (returned; nothing is added if not):
    /// what a learning allocation keeps per pixel ([`crate::learned`]). m̂ at every α in one
    /// pass over the records, with one division per record and one per α: y² / d(α) =
    /// (f² / p_s) / q_α; the other objectives α by α ([`objective`](Self::objective)).
    pub fn add_objective_at_nodes<const K: usize>(
        &self,
        objective: Objective,
        clamp: [f64; 2],
        out: &mut [f64; K],
    ) -> bool {
        let nodes = nodes_of::<K>(clamp);
        if objective != Objective::Mixture {
            if !self.informative() {
                return false;
            }
            for (v, &alpha) in out.iter_mut().zip(&nodes) {
                *v += self.objective(objective, alpha);
            }
            return true;
        }
        let Some(sums) = self.second_moments_at(&nodes) else {
            return false;
        };
        for (v, s) in out.iter_mut().zip(sums) {
            *v += s * self.inv_count;
        }
        true
    }

    /// M m̂ at each of `nodes`, if the pilot is [`informative`](Self::informative), in one
    /// pass over the records. AVX runs the nodes four lanes wide; without FMA, every lane
    /// rounds as SSE2's would, so the sums are the same bit for bit on every processor.
    #[inline]
    fn second_moments_at<const K: usize>(&self, nodes: &[f64; K]) -> Option<[f64; K]> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the processor has AVX.
            return unsafe { self.second_moments_avx(nodes) };
        }
        self.second_moments(nodes)
    }

    /// Adds the variance V̂(α) at `K` evenly spaced α of `clamp` (its ends included) to `out`,
    /// if the pilot is [`informative`](Self::informative) and every value is finite
    /// (returned; nothing is added if not): the mixture's m̂(α) − μ̂² (μ̂² unbiased) or, with
    /// `stratified`, the stratified estimator's, *not* clamped at 0. What a learned cost-aware
    /// α keeps per pixel ([`crate::learned`]): each value is an unbiased estimate, so their sum
    /// over camera samples is one too, which a clamp per sample would bias upward.
    pub fn add_variance_at_nodes<const K: usize>(
        &self,
        stratified: bool,
        clamp: [f64; 2],
        out: &mut [f64; K],
    ) -> bool {
        let nodes = nodes_of::<K>(clamp);
        let variances: [f64; K] = if stratified {
            if !self.informative() {
                return false;
            }
            nodes.map(|alpha| {
                let s = self.sums(alpha);
                s.second_moment - alpha * s.square_bsdf - (1.0 - alpha) * s.square_light
            })
        } else {
            let Some(sums) = self.second_moments_at(&nodes) else {
                return false;
            };
            let square = self.mean_and_square().1;
            sums.map(|s| s * self.inv_count - square)
        };
        if !variances.iter().all(|v| v.is_finite()) {
            return false;
        }
        for (o, v) in out.iter_mut().zip(variances) {
            *o += v;
        }
        true
    }

    /// M m̂ at each of `nodes`, if the pilot is [`informative`](Self::informative).
    #[inline(always)]
    fn second_moments<const K: usize>(&self, nodes: &[f64; K]) -> Option<[f64; K]> {
        let mut sums = [0.0; K];
        let mut informative = false;
        for r in self.records {
            let Some((w, p_b, p_l)) = self.weighted_densities(r) else {
                continue;
            };
            informative |= p_b != p_l;
            let delta = p_b - p_l;
            for (s, &alpha) in sums.iter_mut().zip(nodes) {
                *s += w / (p_l + alpha * delta);
            }
        }
        informative.then_some(sums)
    }

    /// [`second_moments`](Self::second_moments) compiled for AVX.
    ///
    /// # Safety
    /// The processor must have AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn second_moments_avx<const K: usize>(&self, nodes: &[f64; K]) -> Option<[f64; K]> {
        self.second_moments(nodes)
    }

    /// (f² / p_s, p_B, p_L) of a record: y² / d(α) is the first over p_L + α (p_B − p_L) (a
    /// Dirac sample's: f_rec² / β over α).
    #[inline(always)]
    fn weighted_densities(&self, r: &SampleRecord) -> Option<(f64, f64, f64)> {
        self.densities(r)
            .map(|(f, p_s, p_b, p_l)| (f * f / p_s, p_b, p_l))
    }

    fn objective_value(&self, objective: Objective, alpha: f64) -> f64 {
        let s = self.sums(alpha);
        let stratified =
            || s.second_moment - alpha * s.square_bsdf - (1.0 - alpha) * s.square_light;
        match objective {
            Objective::Mixture => s.second_moment,
            Objective::Stratified => stratified(),
            Objective::Cost {
                stratified: strat,
                bsdf,
                light,
            } => {
                let variance = if strat {
                    stratified()
                } else {
                    s.second_moment - self.mean_and_square().1
                };
                variance.max(0.0) * (alpha * bsdf + (1.0 - alpha) * light)
            }
        }
    }

    /// The α in `clamp` that minimises `objective`, or `None` if the pilot is not
    /// [`informative`](Self::informative): exact for [`Objective::Mixture`]; otherwise the best
    /// of 17 evenly spaced α refined by golden section between its neighbours (to 10⁻⁴ of the
    /// interval), as the objective need not be convex.
    pub fn minimise(&self, objective: Objective, clamp: [f64; 2]) -> Option<f64> {
        if objective == Objective::Mixture {
            return self.exact_minimum(clamp);
        }
        if !self.informative() {
            return None;
        }
        Some(minimise_on_grid(clamp, |a| self.objective(objective, a)))
    }
}

/// `K` evenly spaced α of `clamp`, its ends included: where learning allocations keep their
/// objective.
fn nodes_of<const K: usize>(clamp: [f64; 2]) -> [f64; K] {
    let step = (clamp[1] - clamp[0]) / (K.max(2) - 1) as f64;
    std::array::from_fn(|k| clamp[0] + step * k as f64)
}

/// The minimum over `clamp` of `f`: the best of 17 evenly spaced points, then golden section
/// on the two intervals around it.
pub fn minimise_on_grid(clamp: [f64; 2], f: impl Fn(f64) -> f64) -> f64 {
    const NODES: usize = 17;
    let [lo, hi] = clamp;
    if hi <= lo {
        return lo;
    }
    let at = |k: usize| lo + (hi - lo) * k as f64 / (NODES - 1) as f64;
    let (mut best, mut best_value) = (0, f64::INFINITY);
    for k in 0..NODES {
        let v = f(at(k));
        if v < best_value {
            (best, best_value) = (k, v);
        }
    }
    let (mut a, mut b) = (at(best.saturating_sub(1)), at((best + 1).min(NODES - 1)));
    let ratio = 0.5 * (5f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (b - ratio * (b - a), a + ratio * (b - a));
    let (mut f1, mut f2) = (f(x1), f(x2));
    while b - a > 1e-4 * (hi - lo) {
        if f1 <= f2 {
            (b, x2, f2) = (x2, x1, f1);
            x1 = b - ratio * (b - a);
            f1 = f(x1);
        } else {
            (a, x1, f1) = (x1, x2, f2);
            x2 = a + ratio * (b - a);
            f2 = f(x2);
        }
    }
    let (x, value) = if f1 <= f2 { (x1, f1) } else { (x2, f2) };
    // The grid node wins if the refinement found nothing lower (a minimum at a bound).
    if value <= best_value { x } else { at(best) }
}
