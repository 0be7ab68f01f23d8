//! The same-mean comparison of two sets of independent renders, pixel by pixel: the relative
//! bias δ̂ of one set against the other over the whole image or a block of pixels, weighted from an
//! independent pilot, its standard error, Welch–Satterthwaite degrees of freedom and Student's t
//! limit. Shared by the suite's same-mean tests (tests/integrators.rs, docs/testing.md) and
//! `benches/passes.rs`'s `bias` mode (docs/study.md, "Renders to a target error").

use crate::chi2::z_limit;

/// Side of the square pixel blocks tested on their own (for biases confined to one object).
pub const BLOCK: usize = 6;
/// Power stated (and required) by the same-mean test: the relative bias it detects with
/// probability at least 90 % is (limit + Φ⁻¹(0.9)) σ(δ̂).
pub const Z_POWER_90: f64 = 1.281_551_6;

/// Per-pixel luminance of independent renders: the mean over runs and the variance of that
/// mean (sample variance over runs / runs), and every run's image.
pub struct PixelMeans {
    pub mean: Vec<f64>,
    pub variance_of_mean: Vec<f64>,
    pub runs: u64,
    pub images: Vec<Vec<f64>>,
}

impl PixelMeans {
    /// The per-pixel statistics of `images` (each one render's luminance, the same pixels).
    pub fn new(images: Vec<Vec<f64>>) -> Self {
        let pixels = images.first().map_or(0, Vec::len);
        let (mut sum, mut sum_sq) = (vec![0.0; pixels], vec![0.0; pixels]);
        for image in &images {
            for (i, l) in image.iter().enumerate() {
                sum[i] += l;
                sum_sq[i] += l * l;
            }
        }
        let runs = images.len() as u64;
        let n = runs as f64;
        let mean: Vec<f64> = sum.iter().map(|s| s / n).collect();
        let variance_of_mean = sum_sq
            .iter()
            .zip(&mean)
            .map(|(s2, m)| ((s2 - n * m * m) / (n - 1.0)).max(0.0) / n)
            .collect();
        PixelMeans {
            mean,
            variance_of_mean,
            runs,
            images,
        }
    }
}

/// The pixels (row-order indices) of each block of [`BLOCK`]² pixels of a `width` × `height`
/// image, row of blocks by row of blocks; the blocks of the right and bottom edges may be smaller.
pub fn blocks(width: usize, height: usize) -> Vec<Vec<usize>> {
    (0..height.div_ceil(BLOCK))
        .flat_map(|by| (0..width.div_ceil(BLOCK)).map(move |bx| (bx, by)))
        .map(|(bx, by)| {
            (by * BLOCK..((by + 1) * BLOCK).min(height))
                .flat_map(|y| {
                    (bx * BLOCK..((bx + 1) * BLOCK).min(width)).map(move |x| y * width + x)
                })
                .collect()
        })
        .collect()
}

/// The region's weighted sum Σ w x of each run, and the variance of its mean over the runs:
/// the variance of Σ w x̄ whatever the correlation of the pixels within a render.
fn run_sums_variance(runs: &PixelMeans, weights: &[f64], pixels: &[usize]) -> f64 {
    let sums: Vec<f64> = runs
        .images
        .iter()
        .map(|image| pixels.iter().map(|&p| weights[p] * image[p]).sum())
        .collect();
    let n = sums.len() as f64;
    let mean = sums.iter().sum::<f64>() / n;
    sums.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / ((n - 1.0) * n)
}

/// The two-sided quantile of Student's t with ν degrees of freedom at false-alarm rate `alpha`,
/// from the normal one by the Cornish–Fisher expansion (Abramowitz & Stegun 26.7.5; relative
/// error below 10⁻³ for ν ≥ 10 at the rates used here).
pub fn t_limit(alpha: f64, nu: f64) -> f64 {
    let z = z_limit(alpha);
    let (z3, z5, z7) = (z.powi(3), z.powi(5), z.powi(7));
    z + (z3 + z) / (4.0 * nu)
        + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * nu * nu)
        + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * nu.powi(3))
}

/// The weighted comparison of two sets of runs over a region of pixels: the relative bias
/// δ̂ = Σ w d / Σ w μ (d the difference of pixel means, μ the pilot's mean, w = μ / σ² from the
/// pilot, which minimises the variance of δ̂ for a bias proportional to the image), its standard
/// error, and the Welch–Satterthwaite degrees of freedom of that error. With `coupled` the
/// pixels of one render may be correlated (a pilot pooled over blocks steers them all): each
/// side's variance is then that of its runs' weighted sums, with runs − 1 degrees of freedom;
/// otherwise the pixels are independent and the per-pixel variances add up.
pub struct Comparison {
    pub relative_bias: f64,
    pub standard_error: f64,
    pub degrees_of_freedom: f64,
}

impl Comparison {
    pub fn new(
        tested: &PixelMeans,
        reference: &PixelMeans,
        weights: &[f64],
        pilot_mean: &[f64],
        pixels: impl Iterator<Item = usize>,
        coupled: bool,
    ) -> Self {
        let (mut num, mut den, mut var, mut var2_over_df) = (0.0, 0.0, 0.0, 0.0);
        let pixels: Vec<usize> = pixels.filter(|&p| weights[p] != 0.0).collect();
        for &p in &pixels {
            let w = weights[p];
            num += w * (tested.mean[p] - reference.mean[p]);
            den += w * pilot_mean[p];
            let (a, b) = (
                w * w * tested.variance_of_mean[p],
                w * w * reference.variance_of_mean[p],
            );
            var += a + b;
            var2_over_df += a * a / (tested.runs - 1) as f64 + b * b / (reference.runs - 1) as f64;
        }
        if coupled && !pixels.is_empty() {
            let (a, b) = (
                run_sums_variance(tested, weights, &pixels),
                run_sums_variance(reference, weights, &pixels),
            );
            var = a + b;
            var2_over_df = a * a / (tested.runs - 1) as f64 + b * b / (reference.runs - 1) as f64;
        }
        Comparison {
            relative_bias: num / den,
            standard_error: var.sqrt() / den,
            degrees_of_freedom: if var2_over_df > 0.0 {
                var * var / var2_over_df
            } else {
                f64::INFINITY
            },
        }
    }

    pub fn t(&self) -> f64 {
        if self.standard_error == 0.0 {
            if self.relative_bias == 0.0 {
                0.0
            } else {
                f64::INFINITY
            }
        } else {
            self.relative_bias / self.standard_error
        }
    }
}

/// Pixel weights w = μ / Var(d) for the comparison of `tested` with the reference, from pilot
/// runs of both (independent of the compared runs, so the weights need not be exact): with
/// relative variances r = σ² / μ² of one render, Var(d) = μ² (r_tested / runs + r_reference /
/// reference_runs). Each r is floored at the lower quartile of its image's, so that a pixel whose
/// pilot runs happened to agree does not take all the weight. A pixel the tested method's pilot
/// never lit while the reference's did is a rare event for it (a small light reached by BSDF
/// sampling alone, say): its mean over the runs is far from normal, and it gets no weight.
pub fn weights(
    reference: &PixelMeans,
    tested: &PixelMeans,
    tested_runs: u64,
    reference_runs: u64,
) -> Vec<f64> {
    let relative = |p: &PixelMeans| -> (Vec<f64>, f64) {
        let r: Vec<f64> = p
            .mean
            .iter()
            .zip(&p.variance_of_mean)
            .map(|(m, v)| {
                if *m > 0.0 {
                    v * p.runs as f64 / (m * m)
                } else {
                    0.0
                }
            })
            .collect();
        let mut positive: Vec<f64> = r.iter().copied().filter(|r| *r > 0.0).collect();
        positive.sort_by(f64::total_cmp);
        let floor = positive.get(positive.len() / 4).copied().unwrap_or(0.0);
        (r, floor)
    };
    let (r_ref, floor_ref) = relative(reference);
    let (r_tested, floor_tested) = relative(tested);
    (0..reference.mean.len())
        .map(|p| {
            let mu = reference.mean[p];
            if mu <= 0.0 || r_ref[p] == 0.0 || tested.mean[p] <= 0.0 {
                return 0.0;
            }
            let var = r_tested[p].max(floor_tested) / tested_runs as f64
                + r_ref[p].max(floor_ref) / reference_runs as f64;
            1.0 / (mu * var)
        })
        .collect()
}
