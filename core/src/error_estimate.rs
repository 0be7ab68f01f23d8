//! The error of a render's image, estimated from two independent half-images: the camera samples
//! of even index and those of odd index (Cycles' half buffers). docs/integrators.md, "Passes",
//! states what is estimated and why it is unbiased at a planned stop.
//!
//! Per pixel p, with H₀, H₁ the halves' weighted luminance sums and M the pixel's weight (each half
//! holds M/2 of it: every pass has an even number of samples), the half-images are A = 2H₀/M and
//! B = 2H₁/M, and the image is Ŷ = (A + B)/2. With d_p the metric's denominator (Y_p² + ε for the
//! relative MSE, 1 for the MSE), the image's error and its estimate are
//!
//! ```text
//! e = (1/P) Σ_p (Ŷ_p − Y_p)² / d_p,      ê = (1/P) Σ_p (A_p − B_p)² / (4 d̂_p),
//! ```
//!
//! and with d̂ = d, e − ê = (1/P) Σ_p X_p Z_p / d_p, X and Z the halves' deviations from Y_p: a
//! sum of products of independent zero-mean terms, whatever the distribution of the samples. Its
//! variance, (1/P²) Σ_p Var(A_p)² / d_p², is estimated by (1/P²) Σ_p (A_p − B_p)⁴ / (12 d_p²)
//! (exact for normal half-means, larger for heavy-tailed ones).
//!
//! **The relative MSE's denominator.** Y_p is unknown. Its plug-in Ŷ_p² is biased and, worse,
//! holds the numerator: Ŷ² = AB + (A − B)²/4, so the term (A − B)²/4 / (Ŷ² + ε) is below one
//! however bright the sample one half caught, and ê reads low where it matters (Cornell at 8
//! spp: half the true error). The denominator here is the bias-corrected square
//! Ŷ² − (A − B)²/4 = AB, unbiased for Y² since the halves are independent (E[AB] = E[A] E[B] =
//! Y²), which takes the numerator out of the denominator. It is floored at Ŷ²/4 (reached only when
//! one half is more than 13.9 times the other, as when one half holds the pixel's only bright
//! sample and the other none): AB → 0 would make one pixel's term unbounded; the floor bounds
//! each term at four times the plug-in's, i.e. at 4. This is not exactly unbiased (a ratio of
//! dependent estimates), and is not claimed to be; measured (docs/study.md), the mean of ê/e at
//! fixed samples goes from 0.62–0.98 with the plug-in to 1.07–1.78 on Cornell (8 to 512 spp),
//! conservative where the plug-in was optimistic, and tends to one as the samples grow.
//!
//! The interval and the bound a stop is planned with use the distribution of e/ê rather than a
//! normal one: each pixel's term of e and of ê is c_p χ²₁ (normal half-means, c_p the pixel's
//! variance over d_p), the terms of e from X + Z and those of ê from X − Z, independent; so e and
//! ê are each about (Σc/P) χ²_ν/ν with ν = 2(Σc)²/Σ Var t (Satterthwaite), and e/ê is about
//! F(ν, ν), ν at most the pixels. A few dominant pixels (fireflies) make ν small and the interval
//! wide and skewed upwards, where a normal interval over 1 200 pixels would be narrow.
//!
//! **A conservative ν.** ν is estimated from the terms, and two things make the plug-in read
//! high (measured in docs/study.md: with ν̂ = 3(Σt)²/Σt² the bound ê·F⁻¹(0.975; ν̂, ν̂) missed e
//! in 6–10 % of Cornell's renders at 128–512 spp). Normal half-means give E t² = 3c² and
//! Var t = 2c², hence that ν̂; heavy-tailed ones have excess kurtosis κ, E t² = (3 + κ)c² and
//! Var t = (2 + κ)c², and only Var t ≤ E t² holds whatever κ: the distribution-free
//! 2(Σt)²/Σt² (the normal form reads high by up to 3/2). And Σt² is itself a sum of a few large
//! terms when few pixels dominate (t² of a χ²₁ term has a kurtosis near 100), so in the typical
//! render it misses the rare large terms and ν̂ reads high however the samples are distributed.
//! Its variance is at most Σ E t⁴, estimated by Σt⁴, so the variance taken for ê is the upper
//! confidence limit (Σt² + z √Σt⁴)/P² at the interval's one-sided confidence (z = 1.96 at 95 %):
//! ν = 2(Σt)²/(Σt² + z √Σt⁴). With many alike pixels this is about 2/3 of the normal ν; with few
//! dominant ones much less, which is where the normal ν failed.

use crate::film_sums::{FilmSums, for_each_pixel_in_rows};
use statrs::distribution::{ContinuousCDF, FisherSnedecor, Normal};

/// ε of the relative MSE as a fraction of the image's mean luminance, as `lumis study`'s default
/// `--epsilon`: a pixel's denominator is Y² + (0.01 Ȳ)², so that black pixels do not dominate.
pub const EPSILON_FRACTION: f64 = 0.01;

/// What an error is measured in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Metric {
    /// Per-pixel squared error of the luminance over (Y² + ε), averaged over the image.
    RelMse,
    /// Per-pixel squared error of the luminance, averaged over the image.
    Mse,
}

impl Metric {
    pub fn name(self) -> &'static str {
        match self {
            Metric::RelMse => "relmse",
            Metric::Mse => "mse",
        }
    }

    pub fn parse(text: &str) -> Result<Metric, String> {
        match text {
            "relmse" => Ok(Metric::RelMse),
            "mse" => Ok(Metric::Mse),
            _ => Err(format!(
                "unknown error metric `{text}`: relmse (relative MSE) or mse"
            )),
        }
    }
}

/// An image's estimated error with its interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorEstimate {
    pub metric: Metric,
    /// The two-sided confidence of `low`..`high`.
    pub confidence: f64,
    /// ê: an unbiased estimate of the image's error e.
    pub value: f64,
    /// An interval that holds e with probability at least `confidence`: `high` is ê times the
    /// upper quantile of F(ν, ν) ([`ErrorEstimate::degrees_of_freedom`]); `low` is the same
    /// from the plug-in denominator Ŷ², which reads low (for the relative MSE; the same
    /// estimate for the MSE): ê's denominator is conservative, so the interval's low end is
    /// taken from the estimate that errs the other way.
    pub low: f64,
    pub high: f64,
    /// Var(ê) around its expectation, 2ê²/ν, estimated conservatively (the module's comment,
    /// "A conservative ν"): what a prediction of later error from ê must allow for.
    pub variance: f64,
    /// Pixels with samples, over which the error is averaged.
    pub pixels: u64,
}

impl ErrorEstimate {
    /// ν, the effective degrees of freedom of ê (2ê²/Var ê, at most the pixels); `None` when ê
    /// or its variance is 0: no sample has shown any error, which says nothing of the error of
    /// light no sample has found yet (an unknown error, not a zero one).
    pub fn degrees_of_freedom(&self) -> Option<f64> {
        let nu = 2.0 * self.value * self.value / self.variance;
        (self.value > 0.0 && self.variance > 0.0 && nu.is_finite())
            .then(|| nu.min(self.pixels as f64))
    }

    /// A bound that the error of an image whose expected error is this estimate's stays below
    /// with one-sided probability `confidence`: ê times the `confidence` quantile of F(ν, ν),
    /// for ê's own error and the image's fluctuation together. `None` when the error is unknown.
    pub fn upper_bound(&self, confidence: f64) -> Option<f64> {
        let nu = self.degrees_of_freedom()?;
        Some(self.value * ratio_quantile(nu, confidence))
    }
}

/// The `p` quantile of F(ν, ν), the distribution of the ratio of two independent χ²_ν/ν; for
/// large ν its logarithm is normal with variance 4/ν.
pub fn ratio_quantile(nu: f64, p: f64) -> f64 {
    if nu > 1e4 {
        return (standard_normal().inverse_cdf(p) * (4.0 / nu).sqrt()).exp();
    }
    FisherSnedecor::new(nu, nu)
        .expect("positive degrees of freedom")
        .inverse_cdf(p)
}

fn standard_normal() -> Normal {
    Normal::new(0.0, 1.0).expect("the standard normal distribution")
}

/// Per pixel with samples, in the sums' order: its half-images' luminances A and B.
fn halves(sums: &FilmSums) -> impl Iterator<Item = (f64, f64)> + '_ {
    (0..sums.samples.len())
        .filter(|&p| sums.samples[p] > 0)
        .map(|p| half_images(sums, p))
}

/// Pixel `p`'s half-images' luminances A and B (it must have samples).
#[inline]
fn half_images(sums: &FilmSums, p: usize) -> (f64, f64) {
    let [h0, h1] = sums.halves[p];
    let half = sums.weight[p] / 2.0;
    (h0 / half, h1 / half)
}

/// The denominators' ε: (0.01 × the image's mean luminance)² for the relative MSE, 0 for the MSE.
fn epsilon(sums: &FilmSums, metric: Metric) -> f64 {
    if metric == Metric::Mse {
        return 0.0;
    }
    let (mut total, mut pixels) = (0.0, 0u64);
    for (a, b) in halves(sums) {
        total += (a + b) / 2.0;
        pixels += 1;
    }
    let mean = if pixels > 0 {
        total / pixels as f64
    } else {
        0.0
    };
    (EPSILON_FRACTION * mean).powi(2)
}

/// Pixel p's term (A − B)² / (4 d̂_p) of ê; 0 where d̂_p = 0 (a black pixel of a black image).
/// d̂_p is max(AB, Ŷ²/4) + ε for the relative MSE (the module's comment says why), or with
/// `plug_in` Ŷ² + ε, which reads low: the interval's low end.
fn term(a: f64, b: f64, metric: Metric, epsilon: f64, plug_in: bool) -> f64 {
    let square = ((a + b) / 2.0).powi(2);
    let d = match metric {
        Metric::RelMse if plug_in => square + epsilon,
        Metric::RelMse => (a * b).max(square / 4.0) + epsilon,
        Metric::Mse => 1.0,
    };
    if d > 0.0 {
        (a - b).powi(2) / (4.0 * d)
    } else {
        0.0
    }
}

/// The error of the image `sums` resolve to, estimated from its half-images; `None` when the
/// sums keep no halves (a render with an odd number of samples in some pass) or no pixel has
/// samples. Pixels are visited in the sums' order, so the estimate is the same, bit for bit,
/// for sums merged from shards.
pub fn estimate(sums: &FilmSums, metric: Metric, confidence: f64) -> Option<ErrorEstimate> {
    if sums.halves.is_empty() {
        return None;
    }
    let epsilon = epsilon(sums, metric);
    // ê's terms, and the plug-in's (the same for the MSE) for the interval's low end.
    let (mut terms, mut low_terms) = (TermSums::default(), TermSums::default());
    for (a, b) in halves(sums) {
        terms.add(term(a, b, metric, epsilon, false));
        low_terms.add(term(a, b, metric, epsilon, true));
    }
    let tail = (1.0 - confidence) / 2.0;
    let z = standard_normal().inverse_cdf(1.0 - tail);
    let value = terms.mean()?;
    let mut estimate = ErrorEstimate {
        metric,
        confidence,
        value,
        low: value,
        high: value,
        variance: terms.variance(z),
        pixels: terms.pixels,
    };
    if !(value.is_finite() && estimate.variance.is_finite()) {
        return None;
    }
    let plug_in = ErrorEstimate {
        value: low_terms.mean()?,
        variance: low_terms.variance(z),
        ..estimate
    };
    if let Some(nu) = estimate.degrees_of_freedom() {
        estimate.high = value * ratio_quantile(nu, 1.0 - tail);
    }
    if let Some(nu) = plug_in.degrees_of_freedom() {
        estimate.low = plug_in.value * ratio_quantile(nu, tail);
    }
    Some(estimate)
}

/// The sums of the per-pixel terms that ê and its variance are computed from.
#[derive(Default)]
struct TermSums {
    total: f64,
    squares: f64,
    fourths: f64,
    pixels: u64,
}

impl TermSums {
    fn add(&mut self, t: f64) {
        let square = t * t;
        self.total += t;
        self.squares += square;
        self.fourths += square * square;
        self.pixels += 1;
    }

    /// ê, the terms' mean; `None` without terms.
    fn mean(&self) -> Option<f64> {
        (self.pixels > 0).then(|| self.total / self.pixels as f64)
    }

    /// Var(ê), conservatively: Σ Var t ≤ Σ E t² whatever the samples' kurtosis, and Σ E t² at
    /// its upper confidence limit Σt² + z √Σt⁴ (the module's comment, "A conservative ν").
    fn variance(&self, z: f64) -> f64 {
        let n = self.pixels as f64;
        (self.squares + z * self.fourths.sqrt()) / (n * n)
    }
}

/// Each pixel's term of ê (row order of the window: `width` × `height`), for the heat map; 0
/// where a pixel has no samples. One pixel's term is a one-degree-of-freedom estimate: noisy by
/// itself, meaningful averaged over neighbours.
pub fn error_map(sums: &FilmSums, metric: Metric) -> Vec<f64> {
    let window = sums.window;
    let mut map = vec![0.0; window.width as usize * window.height as usize];
    if sums.halves.is_empty() {
        return map;
    }
    let epsilon = epsilon(sums, metric);
    for_each_pixel_in_rows(window, |p, row| {
        if sums.samples[p] > 0 {
            let (a, b) = half_images(sums, p);
            map[row] = term(a, b, metric, epsilon, false);
        }
    });
    map
}

#[cfg(test)]
mod tests {
    use super::*;

    /// F(ν, ν)'s quantiles: reciprocal about the median, the large-ν approximation continuous
    /// with the exact one, wide for few degrees of freedom (F(1, 1) at 0.975: tan²(0.4875 π)).
    #[test]
    fn ratio_quantiles() {
        for nu in [1.0, 7.5, 100.0, 5000.0] {
            let (lo, hi) = (ratio_quantile(nu, 0.025), ratio_quantile(nu, 0.975));
            assert!((lo * hi - 1.0).abs() < 1e-6, "{nu}: {lo} {hi}");
        }
        let exact = ratio_quantile(1e4, 0.95);
        let approximate = ratio_quantile(1.0001e4, 0.95);
        assert!(
            (exact / approximate - 1.0).abs() < 1e-4,
            "{exact} {approximate}"
        );
        let f11 = (0.4875 * std::f64::consts::PI).tan().powi(2);
        assert!((ratio_quantile(1.0, 0.975) / f11 - 1.0).abs() < 1e-6);
    }

    /// A pixel whose samples are heavy-tailed (a bright value in 5 % of them, 20 times the
    /// typical one), 8 samples per half: over 20 000 replicates the mean of its relative-MSE term
    /// is at least the true Var(Ŷ)/Y² (the bias-corrected denominator reads high here, about
    /// 1.12 times), where the plug-in Ŷ² reads low (about 0.48 times), both decided at the
    /// suite's false-alarm limit.
    #[test]
    fn the_relative_error_is_not_hidden_by_its_own_denominator() {
        use crate::chi2::{FAMILY_FALSE_ALARM, mean_and_standard_error, test_sampler, z_limit};
        let (p, bright, per_half, replicates) = (0.05, 20.0, 8, 20_000);
        let mean = p * bright + (1.0 - p) * 0.5;
        let variance = p * bright * bright + (1.0 - p) / 3.0 - mean * mean;
        let truth = variance / (2.0 * per_half as f64) / (mean * mean);
        let mut sampler = test_sampler(46);
        let mut half = || {
            (0..per_half)
                .map(|_| {
                    if sampler.next_1d() < p as f32 {
                        bright
                    } else {
                        f64::from(sampler.next_1d())
                    }
                })
                .sum::<f64>()
                / per_half as f64
        };
        let (mut new, mut plug_in) = (Vec::new(), Vec::new());
        for _ in 0..replicates {
            let (a, b) = (half(), half());
            new.push(term(a, b, Metric::RelMse, 0.0, false));
            plug_in.push(term(a, b, Metric::RelMse, 0.0, true));
        }
        let z = |terms: &[f64]| {
            let (m, se) = mean_and_standard_error(terms);
            (m - truth) / se
        };
        let limit = z_limit(FAMILY_FALSE_ALARM / 2.0);
        let (z_new, z_plug_in) = (z(&new), z(&plug_in));
        assert!(z_new > -limit, "the estimate reads low: z = {z_new}");
        assert!(
            z_plug_in < -limit,
            "the plug-in is not caught: z = {z_plug_in}"
        );
    }

    /// 64 pixels of which 4 dominate (4 times the others' spread), their samples heavy-tailed
    /// (a bright value in 5 % of them, 20 times the typical one), 8 samples per half, the MSE:
    /// over 1 000 replicate images the one-sided bound ê·F⁻¹(0.975; ν, ν) holds the true error at
    /// least at its nominal rate with the conservative ν (18–25 misses at seeds 0–4), and the
    /// normal ν̂ = 3(Σt)²/Σt² is caught missing more (79–101): both against the binomial limit
    /// of misses at 2.5 % at the suite's false-alarm rate (46). About 0.05 s.
    #[test]
    fn the_conservative_nu_bounds_the_error_where_the_normal_nu_did_not() {
        use crate::chi2::{FAMILY_FALSE_ALARM, binomial_limit, test_sampler};
        let (pixels, dominant, per_half, replicates) = (64, 4, 8, 1000);
        let (p, bright, tail) = (0.05, 20.0, 0.025);
        let mean = p * bright + (1.0 - p) * 0.5;
        let z = standard_normal().inverse_cdf(1.0 - tail);
        let mut sampler = test_sampler(4646);
        let (mut misses, mut normal_misses) = (0, 0);
        for _ in 0..replicates {
            let (mut terms, mut error) = (TermSums::default(), 0.0);
            for pixel in 0..pixels {
                let scale = if pixel < dominant { 4.0 } else { 1.0 };
                let mut half = || {
                    let sum: f64 = (0..per_half)
                        .map(|_| {
                            if sampler.next_1d() < p as f32 {
                                bright
                            } else {
                                f64::from(sampler.next_1d())
                            }
                        })
                        .sum();
                    scale * sum / per_half as f64
                };
                let (a, b) = (half(), half());
                terms.add(term(a, b, Metric::Mse, 0.0, false));
                error += ((a + b) / 2.0 - scale * mean).powi(2) / pixels as f64;
            }
            let value = terms.mean().expect("terms");
            let conservative = ErrorEstimate {
                metric: Metric::Mse,
                confidence: 1.0 - 2.0 * tail,
                value,
                low: value,
                high: value,
                variance: terms.variance(z),
                pixels: terms.pixels,
            };
            let normal = ErrorEstimate {
                variance: 2.0 / 3.0 * terms.squares / (pixels * pixels) as f64,
                ..conservative
            };
            for (estimate, count) in [(conservative, &mut misses), (normal, &mut normal_misses)] {
                let bound = estimate.upper_bound(1.0 - tail).expect("a bound");
                *count += u64::from(error > bound);
            }
        }
        let limit = binomial_limit(replicates, tail, FAMILY_FALSE_ALARM / 2.0);
        eprintln!("misses of {replicates}: conservative ν {misses}, normal ν̂ {normal_misses}");
        assert!(
            misses <= limit,
            "the conservative bound misses {misses} of {replicates} (limit {limit})"
        );
        assert!(
            normal_misses > limit,
            "the normal bound is not caught: {normal_misses} misses of {replicates} (limit {limit})"
        );
    }

    #[test]
    fn metrics_parse_by_name() {
        for m in [Metric::RelMse, Metric::Mse] {
            assert_eq!(Metric::parse(m.name()), Ok(m));
        }
        assert!(Metric::parse("rmse").unwrap_err().contains("relmse"));
    }
}
