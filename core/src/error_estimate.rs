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
//! e = (1/P) Σ_p (Ŷ_p − Y_p)² / d_p,      ê = (1/P) Σ_p (A_p − B_p)² / (4 d_p),
//! ```
//!
//! and e − ê = (1/P) Σ_p X_p Z_p / d_p, X and Z the halves' deviations from Y_p: a sum of
//! products of independent zero-mean terms, whatever the distribution of the samples. Its
//! variance, (1/P²) Σ_p Var(A_p)² / d_p², is estimated by (1/P²) Σ_p (A_p − B_p)⁴ / (12 d_p²)
//! (exact for normal half-means, larger for heavy-tailed ones), which gives the interval.

use crate::film_sums::FilmSums;
use statrs::distribution::{ContinuousCDF, Normal};

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
    /// An interval that holds e with probability `confidence` (normal approximation over the
    /// pixels): ê ± z √Var(e − ê), the lower end at least 0.
    pub low: f64,
    pub high: f64,
    /// Var(ê) around its expectation (half of Var(e − ê): e and ê are alike): what a prediction
    /// of later error from ê must allow for.
    pub variance: f64,
    /// Pixels with samples, over which the error is averaged.
    pub pixels: u64,
}

/// The two-sided normal quantile of `confidence` (0.95: 1.96).
pub fn two_sided_z(confidence: f64) -> f64 {
    standard_normal().inverse_cdf(0.5 + confidence / 2.0)
}

/// The one-sided normal quantile of `confidence` (0.95: 1.645).
pub fn one_sided_z(confidence: f64) -> f64 {
    standard_normal().inverse_cdf(confidence)
}

fn standard_normal() -> Normal {
    Normal::new(0.0, 1.0).expect("the standard normal distribution")
}

/// Per pixel (in the sums' order): the half-images' luminances A, B and the weight they share,
/// for pixels with samples.
fn halves(sums: &FilmSums) -> impl Iterator<Item = (usize, f64, f64)> + '_ {
    (0..sums.samples.len())
        .filter(|&p| sums.samples[p] > 0)
        .map(|p| {
            let [h0, h1] = sums.halves[p];
            let half = sums.weight[p] / 2.0;
            (p, h0 / half, h1 / half)
        })
}

/// The denominators' ε: (0.01 × the image's mean luminance)² for the relative MSE, 0 for the MSE.
fn epsilon(sums: &FilmSums, metric: Metric) -> f64 {
    if metric == Metric::Mse {
        return 0.0;
    }
    let (mut total, mut pixels) = (0.0, 0u64);
    for (_, a, b) in halves(sums) {
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

/// Pixel p's term (A − B)² / (4 d_p) of ê; 0 where d_p = 0 (a black pixel of a black image).
fn term(a: f64, b: f64, metric: Metric, epsilon: f64) -> f64 {
    let d = match metric {
        Metric::RelMse => ((a + b) / 2.0).powi(2) + epsilon,
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
    let (mut total, mut squares, mut pixels) = (0.0, 0.0, 0u64);
    for (_, a, b) in halves(sums) {
        let t = term(a, b, metric, epsilon);
        total += t;
        squares += t * t;
        pixels += 1;
    }
    if pixels == 0 {
        return None;
    }
    let n = pixels as f64;
    let value = total / n;
    // (A − B)⁴ / (12 d²) = (4/3) t² per pixel.
    let variance_of_difference = 4.0 / 3.0 * squares / (n * n);
    if !(value.is_finite() && variance_of_difference.is_finite()) {
        return None;
    }
    let half_width = two_sided_z(confidence) * variance_of_difference.sqrt();
    Some(ErrorEstimate {
        metric,
        confidence,
        value,
        low: (value - half_width).max(0.0),
        high: value + half_width,
        variance: variance_of_difference / 2.0,
        pixels,
    })
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
    for (p, a, b) in halves(sums) {
        map[sums.row_index(p)] = term(a, b, metric, epsilon);
    }
    map
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles() {
        assert!((two_sided_z(0.95) - 1.959_964).abs() < 1e-5);
        assert!((one_sided_z(0.95) - 1.644_854).abs() < 1e-5);
    }

    #[test]
    fn metrics_parse_by_name() {
        for m in [Metric::RelMse, Metric::Mse] {
            assert_eq!(Metric::parse(m.name()), Ok(m));
        }
        assert!(Metric::parse("rmse").unwrap_err().contains("relmse"));
    }
}
