//! Per-pixel budgets: each pass of a render in passes gives each pixel camera samples in
//! proportion to what its error buys per sample, decided from the passes before it only
//! (docs/integrators.md, "Per-pixel budgets").
//!
//! The planner ([`crate::passes`]) decides a pass for the average pixel: n̄ samples now, P̄ planned
//! to the end. Minimising Σ_p v_p / N_p (the image's relative MSE, v_p the pixel's relative
//! variance per sample, N_p its samples) at a fixed total Σ_p N_p c_p gives N_p ∝ √(v_p / c_p).
//! Here c_p is taken equal for all pixels: a per-pixel clock would make the allocation, hence
//! the image, depend on the machine's load; the MIS integrators' cost per camera sample varies
//! little over the pixels that have a surface. v_p is estimated from the half-images the error
//! estimate keeps ((H₀ − H₁)² n / W² estimates the variance per sample, one degree of freedom),
//! averaged over a window of the image ([`POOL`], a fraction of the image's size, so that the
//! allocation does not depend on the resolution), then dilated (a maximum over the same window)
//! so that the neighbours of an isolated noisy pixel are not starved, floored at [`FLOOR`] of the
//! average and capped at [`CAP`] times it (a firefly does not take the pass).
//!
//! Each pixel p then gets a target total N_p = f_p (D̄ + P̄) (f_p its share, of mean one; D̄ the
//! average samples so far), hence R_p = N_p − D_p samples still to come (at least [`FLOOR`] P̄),
//! scaled so that they average P̄; the pass gives it n_p = R_p n̄ / P̄ of them and plans P_p =
//! R_p, both even (each half-image holds half of every pass), n_p rounded with its error carried
//! to the next pixel so that the pass costs what the uniform pass would (n_p may be 0 before the
//! last pass, at least 2 in it), P_p ≥ n_p + 2 before the last pass. The combination rule holds per pixel: u_k = (T − M_k)/P_k with the pixel's own
//! M_k and P_k, both fixed before the pass, and the last pass (P_p = n_p) brings its weights to
//! one, so each pixel's image is unbiased.

use crate::error_estimate::{EPSILON_FRACTION, Metric};
use crate::film_sums::FilmSums;
use crate::passes::{Budget, History, PixelPasses, PlannedPass};

/// The window over which the variance per sample is averaged, and the allocation dilated: its
/// radius as a fraction of the image's larger side (at least one pixel): 4 pixels at 256.
pub const POOL: f64 = 1.0 / 64.0;

/// No pixel's share of a pass falls below this fraction of the average.
pub const FLOOR: f64 = 0.25;

/// No pixel's share of a pass exceeds this multiple of the average.
pub const CAP: f64 = 16.0;

/// How a render in passes spreads each pass's samples over the pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Budgets {
    /// The same samples for every pixel.
    #[default]
    Uniform,
    /// Each pixel in proportion to √(v_p / c_p), from earlier passes.
    PerPixel,
}

impl Budgets {
    pub fn name(self) -> &'static str {
        match self {
            Budgets::Uniform => "uniform",
            Budgets::PerPixel => "per-pixel",
        }
    }

    pub fn parse(text: &str) -> Result<Budgets, String> {
        match text {
            "uniform" => Ok(Budgets::Uniform),
            "per-pixel" => Ok(Budgets::PerPixel),
            _ => Err(format!(
                "unknown budgets `{text}`: uniform (the same samples for every pixel) or per-pixel"
            )),
        }
    }
}

/// What each pixel gets in `pass` (the planner's pass for the average pixel), decided from
/// `history` and `sums` (the passes before it): the same for all when `budgets` is uniform, on
/// the first pass (no data), or when the sums keep no half-images; else each pixel its share.
pub fn budget(
    budgets: Budgets,
    metric: Metric,
    history: &History,
    sums: &FilmSums,
    pass: PlannedPass,
) -> Budget {
    if budgets == Budgets::Uniform || history.passes.is_empty() || sums.halves.is_empty() {
        return Budget::uniform(history.mass, pass);
    }
    let shares = shares(sums, metric);
    let pixels = shares.len();
    let done: Vec<u32> = sums.samples.clone();
    let mean_done = done.iter().map(|&d| d as f64).sum::<f64>() / pixels.max(1) as f64;
    let now = f64::from(pass.end) - f64::from(history.samples());
    let planned = pass.planned as f64;
    let last = pass.planned == u64::from(pass.end - history.samples());
    let mut remaining: Vec<f64> = shares
        .iter()
        .zip(&done)
        .map(|(f, &d)| (f * (mean_done + planned) - d as f64).max(FLOOR * planned))
        .collect();
    let mean_remaining = remaining.iter().sum::<f64>() / pixels.max(1) as f64;
    for r in &mut remaining {
        *r *= planned / mean_remaining;
    }
    // Rounded to even numbers with the rounding error carried to the next pixel (in the sums'
    // fixed order), so that the pass's total is the uniform pass's: a pixel may get no sample
    // in a pass before the last (its weights wait), and gets at least 2 in the last.
    let mut carry = 0.0;
    let passes = remaining
        .iter()
        .zip(&done)
        .map(|(&r, &d)| {
            let wanted = if last { r } else { r * now / planned } + carry;
            let n = even(wanted, if last { 2 } else { 0 });
            carry = wanted - f64::from(n);
            let p = if last {
                u64::from(n)
            } else {
                u64::from(even(r, 2)).max(u64::from(n) + 2)
            };
            PlannedPass {
                end: d + n,
                planned: p,
            }
        })
        .collect();
    Budget {
        mass: history.mass,
        pixels: PixelPasses::PerPixel(passes),
    }
}

/// `x` rounded to the nearest even number of samples, at least `least`.
fn even(x: f64, least: u32) -> u32 {
    let n = 2.0 * (x / 2.0).round();
    n.clamp(f64::from(least), f64::from(u32::MAX - 1)) as u32
}

/// Each pixel's share of a pass (in the sums' order, mean one): √v_p pooled, dilated, floored and
/// capped.
fn shares(sums: &FilmSums, metric: Metric) -> Vec<f64> {
    let (w, h) = (sums.window.width as usize, sums.window.height as usize);
    let pixels = w * h;
    // Per pixel (row order): the pixel's mean luminance and its variance per sample.
    let mut mean = vec![0.0; pixels];
    let mut variance = vec![0.0; pixels];
    let mut known = vec![false; pixels];
    for p in 0..pixels {
        let (n, weight, [h0, h1]) = (sums.samples[p], sums.weight[p], sums.halves[p]);
        if n < 2 || weight <= 0.0 {
            continue;
        }
        let row = sums.row_index(p);
        mean[row] = (h0 + h1) / weight;
        variance[row] = f64::from(n) * (h0 - h1).powi(2) / (weight * weight);
        known[row] = true;
    }
    let image_mean = mean.iter().sum::<f64>() / pixels.max(1) as f64;
    let epsilon = (EPSILON_FRACTION * image_mean).powi(2);
    let relative: Vec<f64> = (0..pixels)
        .map(|i| match metric {
            Metric::RelMse => variance[i] / (mean[i] * mean[i] + epsilon).max(f64::MIN_POSITIVE),
            Metric::Mse => variance[i],
        })
        .collect();
    let radius = ((POOL * w.max(h) as f64).round() as usize).max(1);
    let pooled = box_mean(&relative, &known, w, h, radius);
    let root: Vec<f64> = pooled.iter().map(|v| v.max(0.0).sqrt()).collect();
    let dilated = window_max(&root, w, h, radius);
    let average = dilated.iter().sum::<f64>() / pixels.max(1) as f64;
    let mut shares: Vec<f64> = if average > 0.0 && average.is_finite() {
        dilated
            .iter()
            .map(|a| (a / average).clamp(FLOOR, CAP))
            .collect()
    } else {
        vec![1.0; pixels]
    };
    let mean_share = shares.iter().sum::<f64>() / pixels.max(1) as f64;
    for s in &mut shares {
        *s /= mean_share;
    }
    // Back to the sums' (tile-major) order.
    (0..pixels).map(|p| shares[sums.row_index(p)]).collect()
}

/// The mean of `values` over the known pixels of the (2r + 1)² window around each pixel of a
/// `w` × `h` image (row order); 0 where the window has none.
fn box_mean(values: &[f64], known: &[bool], w: usize, h: usize, r: usize) -> Vec<f64> {
    // Summed-area tables of the values and of the known pixels.
    let mut sum = vec![0.0; (w + 1) * (h + 1)];
    let mut count = vec![0.0; (w + 1) * (h + 1)];
    for y in 0..h {
        for x in 0..w {
            let (v, k) = if known[y * w + x] {
                (values[y * w + x], 1.0)
            } else {
                (0.0, 0.0)
            };
            let at = (y + 1) * (w + 1) + x + 1;
            sum[at] = v + sum[at - 1] + sum[at - w - 1] - sum[at - w - 2];
            count[at] = k + count[at - 1] + count[at - w - 1] - count[at - w - 2];
        }
    }
    let area = |t: &[f64], x0: usize, y0: usize, x1: usize, y1: usize| {
        t[y1 * (w + 1) + x1] - t[y0 * (w + 1) + x1] - t[y1 * (w + 1) + x0] + t[y0 * (w + 1) + x0]
    };
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let (x0, y0) = (x.saturating_sub(r), y.saturating_sub(r));
            let (x1, y1) = ((x + r + 1).min(w), (y + r + 1).min(h));
            let n = area(&count, x0, y0, x1, y1);
            if n > 0.5 {
                out[y * w + x] = area(&sum, x0, y0, x1, y1) / n;
            }
        }
    }
    out
}

/// The maximum of `values` over the (2r + 1)² window around each pixel (separable).
fn window_max(values: &[f64], w: usize, h: usize, r: usize) -> Vec<f64> {
    let mut rows = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            rows[y * w + x] = values[y * w + x0..y * w + x1]
                .iter()
                .fold(0.0, |m: f64, &v| m.max(v));
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
            out[y * w + x] = (y0..y1).fold(0.0, |m: f64, yy| m.max(rows[yy * w + x]));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chi2::{FAMILY_FALSE_ALARM, mean_and_standard_error, test_sampler, z_limit};
    use crate::output::Window;
    use crate::passes::{PassRecord, give, sample_weight};
    use crate::sampler::Sampler;

    const SIDE: u32 = 32;
    /// The left half's samples: `BRIGHT` with probability `P`, else uniform in [0, `DIM`]
    /// (heavy-tailed: the noise the decisions see predicts the estimate); the right half's:
    /// uniform in [0, 2 `MEAN`]. Both of mean `MEAN`.
    const P: f64 = 0.02;
    const BRIGHT: f64 = 40.0;
    const DIM: f64 = 0.5;
    const MEAN: f64 = P * BRIGHT + (1.0 - P) * DIM / 2.0;

    fn image() -> FilmSums {
        let window = Window {
            x: 0,
            y: 0,
            width: SIDE,
            height: SIDE,
        };
        FilmSums::empty(SIDE, SIDE, window, 0, true)
    }

    fn noisy(sums: &FilmSums, p: usize) -> bool {
        sums.row_index(p) % (SIDE as usize) < SIDE as usize / 2
    }

    /// Renders `budget`'s pass on `sums`, each sample weighted by the rule; also adds each
    /// sample, unweighted, to `plain` (the pixels' plain sums).
    fn render(sums: &mut FilmSums, budget: &Budget, sampler: &mut Sampler, plain: &mut [f64]) {
        for (p, plain) in plain.iter_mut().enumerate() {
            let plan = budget.pixel(p);
            let u = sample_weight(budget.mass, sums.weight[p], plan.planned);
            let noisy = noisy(sums, p);
            for index in sums.samples[p]..plan.end {
                let x = if !noisy {
                    2.0 * MEAN * f64::from(sampler.next_1d())
                } else if sampler.next_1d() < P as f32 {
                    BRIGHT
                } else {
                    DIM * f64::from(sampler.next_1d())
                };
                *plain += x;
                sums.color[p].x += u * x;
                sums.halves[p][(index & 1) as usize] += u * x;
            }
            sums.weight[p] = give(sums.weight[p], u, plan.end - sums.samples[p]);
            sums.samples[p] = plan.end;
        }
    }

    /// Four passes of 4 + 4 + 8 + 16 average samples with per-pixel budgets; the sums and the
    /// pixels' plain sums.
    fn run(sampler: &mut Sampler) -> (FilmSums, Vec<f64>) {
        let mut sums = image();
        let mut plain = vec![0.0; sums.samples.len()];
        let mut history = History::default();
        for (end, planned) in [(4, 32), (8, 28), (16, 24), (32, 16)] {
            let pass = PlannedPass { end, planned };
            if history.passes.is_empty() {
                history.mass = planned as f64;
            }
            let budget = budget(Budgets::PerPixel, Metric::Mse, &history, &sums, pass);
            render(&mut sums, &budget, sampler, &mut plain);
            history.passes.push(PassRecord {
                pass,
                seconds: 0.0,
                error: None,
            });
        }
        (sums, plain)
    }

    /// The noisy half gets several times the samples of the quiet half (its variance per sample
    /// is about 80 times as large: √80 ≈ 9, less the first, uniform pass and the cap), and every
    /// pixel's weights sum to the mass.
    #[test]
    fn samples_follow_the_noise_and_weights_are_complete() {
        let (sums, _) = run(&mut test_sampler(47));
        let (mut noisy_samples, mut quiet_samples) = (0.0, 0.0);
        for p in 0..sums.samples.len() {
            let mass = sums.weight[p];
            assert!((mass - 32.0).abs() < 1e-9, "pixel {p}: mass {mass}");
            let column = sums.row_index(p) % SIDE as usize;
            if column < 12 {
                noisy_samples += f64::from(sums.samples[p]);
            } else if column >= 20 {
                quiet_samples += f64::from(sums.samples[p]);
            }
        }
        let ratio = noisy_samples / quiet_samples;
        assert!((3.0..20.0).contains(&ratio), "noisy/quiet samples {ratio}");
        // The total is the uniform render's, within a sample.
        let total: u64 = sums.samples.iter().map(|&n| u64::from(n)).sum();
        let uniform = 32 * sums.samples.len() as u64;
        assert!(
            total.abs_diff(uniform) <= 2,
            "{total} samples, uniform {uniform}"
        );
    }

    /// Over replicate renders, the mean of the images' noisy half is the samples' mean within
    /// the suite's false-alarm limit (z from the replicates' own spread); the same samples
    /// averaged with equal weights (the plain mean of a pixel's samples, whose number depended
    /// on them) are biased low, caught by the same limit.
    #[test]
    fn per_pixel_budgets_are_unbiased_where_equal_weights_are_not() {
        let replicates = 300;
        let mut sampler = test_sampler(4700);
        let (mut rule, mut equal) = (Vec::new(), Vec::new());
        for _ in 0..replicates {
            let (sums, plain) = run(&mut sampler);
            let (mut a, mut b, mut n) = (0.0, 0.0, 0.0);
            for p in (0..sums.samples.len()).filter(|&p| noisy(&sums, p)) {
                a += sums.color[p].x / sums.weight[p];
                b += plain[p] / f64::from(sums.samples[p]);
                n += 1.0;
            }
            rule.push(a / n);
            equal.push(b / n);
        }
        let z = |estimates: &[f64]| {
            let (m, se) = mean_and_standard_error(estimates);
            (m - MEAN) / se
        };
        let limit = z_limit(FAMILY_FALSE_ALARM / 2.0);
        let (z_rule, z_equal) = (z(&rule), z(&equal));
        eprintln!("per-pixel budgets: z = {z_rule:+.2}; equal weights: z = {z_equal:+.2}");
        assert!(z_rule.abs() < limit, "the rule is biased: z = {z_rule}");
        assert!(
            z_equal < -limit,
            "the biased variant was not caught: z = {z_equal}"
        );
    }

    #[test]
    fn names_parse_back() {
        for b in [Budgets::Uniform, Budgets::PerPixel] {
            assert_eq!(Budgets::parse(b.name()), Ok(b));
        }
        assert!(
            Budgets::parse("adaptive")
                .unwrap_err()
                .contains("per-pixel")
        );
    }
}
