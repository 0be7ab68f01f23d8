//! What the study keeps of each run: sums over pixel blocks of every per-pixel quantity it
//! reports (errors against the reference, ΔE, V[L₁], sample counts, luminance), the run's
//! luminance per pixel (for the variance across runs) and its times. A [`RunSummary`] is a pure
//! function of a cell's result and the reference; the statistics of a configuration
//! ([`ConfigurationStats`]) are a pure function of its runs' summaries.

use super::cell::CellResult;
use super::metrics;
use super::reference::Reference;
use super::stats::{Design, Jack, Stratum, median};
use lumis_core::math::{Rgb, luminance};
use lumis_integrators::aovs;

/// Square pixel blocks, the strata of the jackknife.
#[derive(Clone, Debug)]
pub struct Blocks {
    pub edge: u32,
    pub count: usize,
    /// The block of each pixel, row order.
    index: Vec<u32>,
}

impl Blocks {
    pub fn new(width: u32, height: u32, edge: u32) -> Self {
        let columns = width.div_ceil(edge);
        let rows = height.div_ceil(edge);
        let index = (0..height)
            .flat_map(|y| (0..width).map(move |x| (y / edge) * columns + x / edge))
            .collect();
        Blocks {
            edge,
            count: (columns * rows) as usize,
            index,
        }
    }

    pub fn of(&self, pixel: usize) -> usize {
        self.index[pixel] as usize
    }

    /// The sums of the pixels' `values` (in pixel order) over each block.
    pub fn sums(&self, values: impl Iterator<Item = f64>) -> Vec<f64> {
        let mut sums = vec![0.0; self.count];
        for (p, v) in values.enumerate() {
            sums[self.index[p] as usize] += v;
        }
        sums
    }
}

/// What the summaries of a scene's runs share: the reference, the per-pixel weights of the
/// relative errors and the blocks.
pub struct Context {
    pub reference: Reference,
    /// ε of the relative errors: (fraction · mean reference luminance)².
    pub epsilon: f64,
    /// 1 / (ref² + ε) per pixel.
    pub weights: Vec<f64>,
    pub blocks: Blocks,
    /// 2^exposure of the scene's preview, for the paper's tone map before ΔE.
    pub exposure_scale: f32,
    pub width: u32,
    pub height: u32,
}

impl Context {
    pub fn new(
        reference: Reference,
        epsilon_fraction: f64,
        block: u32,
        exposure_scale: f32,
        width: u32,
        height: u32,
    ) -> Self {
        let mean = reference.luminance.iter().sum::<f64>() / reference.luminance.len() as f64;
        let epsilon = (epsilon_fraction * mean).powi(2).max(f64::MIN_POSITIVE);
        Context {
            weights: reference
                .luminance
                .iter()
                .map(|r| 1.0 / (r * r + epsilon))
                .collect(),
            epsilon,
            reference,
            blocks: Blocks::new(width, height, block),
            exposure_scale,
            width,
            height,
        }
    }

    pub fn pixels(&self) -> usize {
        self.weights.len()
    }

    /// A design for `runs` runs over this scene's blocks.
    pub fn design(&self, runs: usize) -> Design {
        Design {
            runs,
            blocks: self.blocks.count,
        }
    }
}

/// One run of one configuration, reduced.
#[derive(Clone, Debug)]
pub struct RunSummary {
    pub run: u32,
    pub cpu_time: f64,
    pub wall_time: f64,
    /// Per block: Σ w · ((Y − ref)² − the reference's own variance), w = 1 / (ref² + ε): the
    /// relative squared error, from which the reference's expected share is removed.
    pub squared_error: Vec<f64>,
    /// Per block: Σ ΔE*ab against the reference.
    pub delta_e: Vec<f64>,
    /// Per block: Σ Y.
    pub luminance: Vec<f64>,
    /// Per block: Σ V[L₁] at the settled split and over the whole estimate (the paper's basis).
    pub sampling_variance: Option<Vec<f64>>,
    pub sampling_variance_estimate: Option<Vec<f64>>,
    /// Per block: Σ BSDF samples and Σ light samples.
    pub bsdf_samples: Option<Vec<f64>>,
    pub light_samples: Option<Vec<f64>>,
    /// Medians over the pixels that shade a point: α and V[L₁] (estimate basis).
    pub alpha_median: Option<f64>,
    pub sampling_variance_median: Option<f64>,
    /// The run's luminance per pixel.
    pub y: Vec<f32>,
    /// The run's image and α map (kept for the panel's configurations, first run).
    pub image: Option<Vec<Rgb>>,
    pub alpha: Option<Vec<f32>>,
}

impl RunSummary {
    /// Reduces a cell's result; keeps its image and α if `keep_images`.
    pub fn new(result: &CellResult, run: u32, context: &Context, keep_images: bool) -> Self {
        let reference = &context.reference;
        let image: Vec<Rgb> = result.color.iter().map(|&c| Rgb::from_array(c)).collect();
        let y: Vec<f32> = image.iter().map(|&c| luminance(c)).collect();
        let blocks = &context.blocks;
        let squared_error = blocks.sums(y.iter().enumerate().map(|(p, &v)| {
            let d = v as f64 - reference.luminance[p];
            context.weights[p] * (d * d - reference.variance[p])
        }));
        let delta_e = blocks.sums(
            metrics::lab_difference(&image, &reference.pixels, context.exposure_scale).into_iter(),
        );
        let luminance = blocks.sums(y.iter().map(|&v| v as f64));
        let channel = |layer, channel| result.channel(layer, channel);
        let block_sums = |values: &[f32]| blocks.sums(values.iter().map(|&v| v as f64));
        let counts = (
            channel(aovs::SAMPLE_COUNTS, aovs::BSDF),
            channel(aovs::SAMPLE_COUNTS, aovs::LIGHT),
        );
        // Pixels that shade a point with an area light: those with samples.
        let shaded: Option<Vec<bool>> = match counts {
            (Some(b), Some(l)) => Some(b.iter().zip(l).map(|(b, l)| b + l > 0.0).collect()),
            _ => None,
        };
        let median_over_shaded = |values: &[f32]| {
            let mut v: Vec<f64> = values
                .iter()
                .enumerate()
                .filter(|(p, _)| shaded.as_ref().is_none_or(|s| s[*p]))
                .map(|(_, &v)| v as f64)
                .collect();
            median(&mut v)
        };
        let alpha = channel(aovs::ALPHA, aovs::COMBINED);
        let estimate = channel(aovs::SAMPLING_VARIANCE, aovs::ESTIMATE);
        RunSummary {
            run,
            cpu_time: result.cpu_time,
            wall_time: result.wall_time,
            squared_error,
            delta_e,
            luminance,
            sampling_variance: channel(aovs::SAMPLING_VARIANCE, aovs::Y).map(block_sums),
            sampling_variance_estimate: estimate.map(block_sums),
            bsdf_samples: counts.0.map(block_sums),
            light_samples: counts.1.map(block_sums),
            alpha_median: alpha.map(median_over_shaded),
            sampling_variance_median: estimate.map(median_over_shaded),
            y,
            image: keep_images.then_some(image),
            alpha: if keep_images {
                alpha.map(<[f32]>::to_vec)
            } else {
                None
            },
        }
    }
}

/// Per pixel, the mean and the sum of squared deviations of the runs' luminance.
struct Spread {
    mean: Vec<f64>,
    squares: Vec<f64>,
}

impl Spread {
    fn new(runs: &[&RunSummary]) -> Self {
        let pixels = runs[0].y.len();
        let k = runs.len() as f64;
        let mut mean = vec![0.0; pixels];
        for r in runs {
            for (m, &y) in mean.iter_mut().zip(&r.y) {
                *m += y as f64 / k;
            }
        }
        let mut squares = vec![0.0; pixels];
        for r in runs {
            for ((s, &y), m) in squares.iter_mut().zip(&r.y).zip(&mean) {
                let d = y as f64 - m;
                *s += d * d;
            }
        }
        Spread { mean, squares }
    }

    /// Each pixel's variance across the runs (unbiased).
    fn variance(&self, runs: usize) -> impl Iterator<Item = f64> + '_ {
        let k1 = (runs - 1) as f64;
        self.squares.iter().map(move |s| s / k1)
    }

    /// Pixel p's variance across the runs without run `r` (whose value is `y`).
    fn variance_without(&self, p: usize, y: f32, runs: usize) -> f64 {
        let k = runs as f64;
        let d = y as f64 - self.mean[p];
        ((self.squares[p] - d * d * k / (k - 1.0)) / (k - 2.0)).max(0.0)
    }
}

/// Per-pixel variance across runs, weighted and summed over blocks, as a jackknife statistic:
/// Σ_p weight_p · V_p / P, and the share of the sum held by its largest 0.1 % of pixels.
fn variance_across_runs(
    runs: &[&RunSummary],
    spread: &Spread,
    weights: Option<&[f64]>,
    context: &Context,
    design: Design,
) -> (Jack, f64) {
    let k = runs.len();
    let weight = |p: usize| weights.map_or(1.0, |w| w[p]);
    let per_pixel: Vec<f64> = spread
        .variance(k)
        .enumerate()
        .map(|(p, v)| weight(p) * v)
        .collect();
    let full = context.blocks.sums(per_pixel.iter().copied());
    let mut left_out = vec![0.0; design.blocks * k];
    for (r, run) in runs.iter().enumerate() {
        for (p, &y) in run.y.iter().enumerate() {
            left_out[context.blocks.of(p) * k + r] += weight(p) * spread.variance_without(p, y, k);
        }
    }
    let jack = Jack::block_sum(
        design,
        &full,
        |b, r| left_out[b * k + r],
        context.pixels() as f64,
    );
    (jack, top_share(per_pixel))
}

/// The share of a sum of non-negative values held by its largest 0.1 % (at least one).
pub fn top_share(mut values: Vec<f64>) -> f64 {
    let total: f64 = values.iter().sum();
    let n = values.len().div_ceil(1000).max(1);
    if values.is_empty() || total <= 0.0 {
        return f64::NAN;
    }
    let cut = values.len() - n;
    values.select_nth_unstable_by(cut, f64::total_cmp);
    values[cut..].iter().sum::<f64>() / total
}

/// The statistics of one configuration over its first K runs, as jackknife statistics over
/// the design of K runs (so that configurations measured with the same seeds pair).
#[derive(Clone, Debug)]
pub struct ConfigurationStats {
    /// Mean over pixels of V_p / (ref² + ε), V_p the variance across runs: the robust
    /// relative variance.
    pub relative_variance: Jack,
    /// Mean over pixels of V_p: the plain V[L_N], dominated by bright pixels.
    pub variance: Jack,
    /// Shares of the two sums held by their largest 0.1 % of pixels.
    pub relative_variance_top: f64,
    pub variance_top: f64,
    /// Mean over runs and pixels of ((Y − ref)² − Var ref) / (ref² + ε).
    pub relative_mse: Jack,
    /// Mean ΔE*ab.
    pub delta_e: Jack,
    /// Mean over runs of the image's mean luminance.
    pub mean_luminance: Jack,
    /// Mean V[L₁], settled split and estimate basis.
    pub sampling_variance: Option<Jack>,
    pub sampling_variance_estimate: Option<Jack>,
    /// Median over pixels of V[L₁] (estimate basis), mean over runs.
    pub sampling_variance_median: Option<Jack>,
    /// Fraction of the samples drawn by BSDF sampling; median α over shaded pixels.
    pub bsdf_fraction: Option<Jack>,
    pub alpha_median: Option<Jack>,
    /// Mean CPU and wall time of a run.
    pub cpu_time: Jack,
    pub wall_time: f64,
    /// Per pixel variance across runs (for medians of per-pixel ratios).
    spread: Vec<f64>,
    runs: usize,
}

impl ConfigurationStats {
    /// The statistics of `runs` (runs 1 … K in order).
    pub fn new(runs: &[&RunSummary], context: &Context) -> Self {
        let k = runs.len();
        let design = context.design(k);
        let p = context.pixels() as f64;
        let spread = Spread::new(runs);
        let (relative_variance, relative_variance_top) =
            variance_across_runs(runs, &spread, Some(&context.weights), context, design);
        let (variance, variance_top) = variance_across_runs(runs, &spread, None, context, design);
        let block_mean = |f: &dyn Fn(&RunSummary) -> Option<&Vec<f64>>| -> Option<Jack> {
            let per_run: Option<Vec<&[f64]>> =
                runs.iter().map(|r| f(r).map(Vec::as_slice)).collect();
            Some(Jack::run_block_mean(design, &per_run?, p))
        };
        let global_mean = |f: &dyn Fn(&RunSummary) -> Option<f64>| -> Option<Jack> {
            let values: Option<Vec<f64>> = runs.iter().map(|r| f(r)).collect();
            Some(Jack::run_mean(design, Stratum::Global, &values?))
        };
        let bsdf = block_mean(&|r| r.bsdf_samples.as_ref());
        let light = block_mean(&|r| r.light_samples.as_ref());
        let bsdf_fraction = match (bsdf, light) {
            (Some(b), Some(l)) => Some(b.zip(&l, |b, l| b / (b + l))),
            _ => None,
        };
        let cpu: Vec<f64> = runs.iter().map(|r| r.cpu_time).collect();
        ConfigurationStats {
            relative_variance,
            variance,
            relative_variance_top,
            variance_top,
            relative_mse: block_mean(&|r| Some(&r.squared_error)).expect("always measured"),
            delta_e: block_mean(&|r| Some(&r.delta_e)).expect("always measured"),
            mean_luminance: block_mean(&|r| Some(&r.luminance)).expect("always measured"),
            sampling_variance: block_mean(&|r| r.sampling_variance.as_ref()),
            sampling_variance_estimate: block_mean(&|r| r.sampling_variance_estimate.as_ref()),
            sampling_variance_median: global_mean(&|r| r.sampling_variance_median),
            bsdf_fraction,
            alpha_median: global_mean(&|r| r.alpha_median),
            cpu_time: Jack::run_mean(design, Stratum::Time, &cpu),
            wall_time: runs.iter().map(|r| r.wall_time).sum::<f64>() / k as f64,
            spread: spread.variance(k).collect(),
            runs: k,
        }
    }

    /// Efficiency, 1 / (relative variance × CPU time).
    pub fn efficiency(&self) -> Jack {
        self.relative_variance
            .zip(&self.cpu_time, |v, t| 1.0 / (v * t))
    }

    /// The bias check: (mean luminance − the reference's) over its standard error (the runs'
    /// and the reference's).
    pub fn z(&self, context: &Context) -> f64 {
        let reference = context.reference.luminance.iter().sum::<f64>() / context.pixels() as f64;
        let e = self.mean_luminance.interval();
        (e.value - reference) / e.se.hypot(context.reference.mean_standard_error())
    }
}

/// The median over pixels of the ratio of two configurations' variances across runs (pixels
/// where both are zero left out), with its interval from the global jackknife: run k left out
/// of both, every pixel's variances recomputed.
pub fn median_variance_ratio(
    a_runs: &[&RunSummary],
    b_runs: &[&RunSummary],
    a: &ConfigurationStats,
    b: &ConfigurationStats,
) -> Jack {
    let k = a.runs;
    let design = Design {
        runs: k,
        blocks: a.relative_variance.design().blocks,
    };
    let ratios = |va: &dyn Fn(usize) -> f64, vb: &dyn Fn(usize) -> f64| {
        let mut r: Vec<f64> = (0..a.spread.len())
            .filter_map(|p| {
                let (x, y) = (va(p), vb(p));
                (x > 0.0 || y > 0.0).then(|| if y > 0.0 { x / y } else { f64::INFINITY })
            })
            .collect();
        median(&mut r)
    };
    let value = ratios(&|p| a.spread[p], &|p| b.spread[p]);
    let (sa, sb) = (Spread::new(a_runs), Spread::new(b_runs));
    let left_out: Vec<f64> = (0..k)
        .map(|r| {
            ratios(&|p| sa.variance_without(p, a_runs[r].y[p], k), &|p| {
                sb.variance_without(p, b_runs[r].y[p], k)
            })
        })
        .collect();
    Jack::global(design, value, &left_out)
}
