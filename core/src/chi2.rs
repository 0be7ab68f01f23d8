//! Chi-square goodness-of-fit test of a direction sampler against its density (as Mitsuba's
//! `ChiSquareTest`): for BSDF and emitter plugins, including third-party ones; and the small
//! statistical toolkit the suite's tests share (seed, multiplicity correction, derived limits).
//!
//! Sampled directions are histogrammed over equal-area bins in (φ, cos θ) about an axis; the
//! density is integrated over each bin with Simpson's rule; bins expecting fewer than 5 samples
//! are pooled; the statistic's p-value is compared with a significance level that the caller
//! corrects for the number of tests (Šidák). Any sample where the density is zero fails the test.
//!
//! Bins may cover a cap about the axis (`cos_cap > −1`) so that very sharp lobes are resolved;
//! samples outside the cap and failed samples share one bin, whose expected count is the rest of
//! the probability mass.
//!
//! Every statistical test takes its random numbers from [`test_seed`] (`LUMIS_TEST_SEED`, default
//! 0), so that a pass is not the luck of one seed: `docs/testing.md` runs the suite under several.
//! Each test function is one family of checks whose false-alarm rate is [`FAMILY_FALSE_ALARM`],
//! split over its checks with [`sidak`].
//!
//! Why one file of over 600 lines: the χ² harness and the statistical helpers every test crate
//! shares (one public module, so that third-party plugins test with the same code); with its tests.

use crate::sampler::Sampler;
use glam::{DVec3, Vec3};
use statrs::distribution::{Binomial, ChiSquared, ContinuousCDF, DiscreteCDF, Normal};
use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

/// The environment variable that selects the seed of the statistical tests.
pub const SEED_VARIABLE: &str = "LUMIS_TEST_SEED";

/// The probability that one statistical test function fails although the code is correct: the
/// family-wise level of its checks. With about fifteen such functions in the suite, a correct
/// build fails a given seed with probability about 1.5·10⁻³, and one of ten seeds with about
/// 1.5 % (docs/testing.md lists them).
pub const FAMILY_FALSE_ALARM: f64 = 1e-4;

/// The seed of the statistical tests: `LUMIS_TEST_SEED` when set, else 0.
///
/// # Panics
/// If the variable is set but is not an unsigned integer (a test run asked for a seed it cannot
/// have; running with another would hide that).
pub fn test_seed() -> u64 {
    match std::env::var(SEED_VARIABLE) {
        Ok(value) => value.trim().parse().unwrap_or_else(|_| {
            panic!("{SEED_VARIABLE}={value:?}: the test seed must be an unsigned integer")
        }),
        Err(_) => 0,
    }
}

/// The random numbers of stream `stream` of a statistical test under the suite's seed. Tests
/// (and the cases within a test) use distinct streams so that their numbers are independent.
pub fn test_sampler(stream: u64) -> Sampler {
    Sampler::new(test_seed(), stream, 0x7e57)
}

/// `run` applied to every case, the cases spread over the machine's cores (rayon's ordered
/// parallel map); the results come back in the cases' order. For a test function's independent
/// checks (each chi-square case draws from its own seeded stream, so where it runs changes
/// nothing): one long sequential loop would keep the suite's other core idle. A case's panic
/// reaches the caller.
pub fn run_side_by_side<C: Sync, T: Send>(
    cases: &[C],
    run: impl Fn(&C) -> T + Sync + Send,
) -> Vec<T> {
    use rayon::prelude::*;
    cases.par_iter().map(run).collect()
}

/// The per-test significance that keeps the family-wise level at `alpha` over `tests` tests.
/// Exact for independent tests; under any dependence the family-wise level stays below
/// `tests` times it, which is at most α (1 + α·tests/2) (Bonferroni).
pub fn sidak(alpha: f64, tests: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / tests.max(1) as f64)
}

/// The mean of independent estimates and its standard error (from their sample variance).
pub fn mean_and_standard_error(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (variance / n).sqrt())
}

/// The z such that a standard normal variable exceeds it in absolute value with probability
/// `alpha`: the two-sided limit of a z-test at significance `alpha`.
pub fn z_limit(alpha: f64) -> f64 {
    let normal = Normal::standard();
    normal.inverse_cdf(1.0 - alpha / 2.0)
}

/// The largest count of events, each of probability at most `probability` in `trials`
/// independent trials, that is exceeded with probability at most `alpha`: a count above it
/// means the events are more frequent than `probability`, at significance `alpha`.
pub fn binomial_limit(trials: u64, probability: f64, alpha: f64) -> u64 {
    let Ok(binomial) = Binomial::new(probability.clamp(0.0, 1.0), trials) else {
        return trials;
    };
    // P(X > k) falls with k; the limit is near the mean, a few standard deviations above it.
    let mut k = 0;
    while k < trials && binomial.sf(k) > alpha {
        k += 1;
    }
    k
}

/// The configuration of one test.
#[derive(Clone, Debug)]
pub struct Chi2Test {
    /// The pole of the (φ, cos θ) parameterisation.
    pub axis: Vec3,
    /// Bins cover cos θ in [cos_cap, 1]; −1 covers the whole sphere.
    pub cos_cap: f64,
    pub theta_bins: usize,
    pub phi_bins: usize,
    pub samples: usize,
    /// Simpson nodes per axis of each integration region (odd; regions are refined adaptively).
    pub integration_nodes: usize,
    /// The seed of the sampler's stream; [`test_seed`] by default.
    pub seed: u64,
    /// The normal of a plane through the origin across which the density may jump between two
    /// positive values (a BSDF's horizon, where reflection meets transmission): integration
    /// regions that straddle it are refined to the depth limit, as those across the edge of
    /// the density's support are. [`test_bsdf`] sets the shading normal; `None` by default.
    pub horizon: Option<Vec3>,
}

impl Default for Chi2Test {
    fn default() -> Self {
        Chi2Test {
            axis: Vec3::Z,
            cos_cap: -1.0,
            theta_bins: 32,
            phi_bins: 64,
            samples: 1_000_000,
            integration_nodes: 5,
            seed: test_seed(),
            horizon: None,
        }
    }
}

/// The result of a test, with both histograms for inspection.
#[derive(Clone, Debug)]
pub struct Chi2Outcome {
    pub chi2: f64,
    pub degrees_of_freedom: usize,
    pub p_value: f64,
    /// Counts per bin (θ-major), then the outside-or-failed bin.
    pub observed: Vec<f64>,
    pub expected: Vec<f64>,
    /// Samples that landed where the density is zero.
    pub zero_density_samples: usize,
    /// ∫ pdf over the binned region (≤ 1 for a valid density).
    pub integral: f64,
    /// Estimated error of `integral` (Richardson, from Simpson at two resolutions).
    pub integral_error: f64,
    pub theta_bins: usize,
    pub phi_bins: usize,
}

/// Tests a BSDF's `sample` against its `pdf` at the shading point `ctx` for the outgoing
/// direction `wo` (local frame), over the whole sphere of directions (with the default
/// `cos_cap`): reflected and transmitted samples alike, the horizon (z = 0) a place where the
/// density may jump ([`Chi2Test::horizon`], unless the test gives another plane). Delta samples
/// cannot be binned against a density and count as failed samples.
pub fn test_bsdf(
    bsdf: &dyn crate::bsdf::Bsdf,
    ctx: &crate::bsdf::BsdfContext,
    wo: Vec3,
    test: &Chi2Test,
) -> Chi2Outcome {
    let test = Chi2Test {
        horizon: test.horizon.or(Some(Vec3::Z)),
        ..test.clone()
    };
    test.run(
        |s| {
            let u_lobe = s.next_1d();
            bsdf.sample(ctx, wo, u_lobe, s.next_2d())
                .filter(|b| !b.delta)
                .map(|b| b.wi)
        },
        |wi| bsdf.pdf(ctx, wo, wi) as f64,
    )
}

/// An orthonormal frame in f64 (Duff et al. 2017).
fn frame(n: DVec3) -> (DVec3, DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let s = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let t = DVec3::new(b, sign + n.y * n.y * a, -n.y);
    (s, t, n)
}

impl Chi2Test {
    /// Runs the test: `sample` draws one direction (None: the sampler failed or absorbed),
    /// `pdf` is the density in solid angle that `sample` is meant to have.
    pub fn run(
        &self,
        mut sample: impl FnMut(&mut Sampler) -> Option<Vec3>,
        pdf: impl Fn(Vec3) -> f64,
    ) -> Chi2Outcome {
        let (s, t, n) = frame(self.axis.as_dvec3().normalize());
        let u_max = 1.0 - self.cos_cap;
        let bins = self.theta_bins * self.phi_bins;
        let mut observed = vec![0.0; bins + 1];
        let mut zero_density_samples = 0;
        let mut sampler = Sampler::new(self.seed, 0x5eed, 0);
        for _ in 0..self.samples {
            let Some(d) = sample(&mut sampler) else {
                observed[bins] += 1.0;
                continue;
            };
            let density = pdf(d);
            if density.is_nan() || density <= 0.0 {
                zero_density_samples += 1;
            }
            let dd = d.as_dvec3().normalize();
            let (x, y, z) = (dd.dot(s), dd.dot(t), dd.dot(n));
            // 1 − cos θ without cancellation near the pole.
            let u = if z > 0.0 {
                (x * x + y * y) / (1.0 + z)
            } else {
                1.0 - z
            };
            if u >= u_max {
                observed[bins] += 1.0;
                continue;
            }
            let phi = y.atan2(x).rem_euclid(TAU);
            let i = ((u / u_max * self.theta_bins as f64) as usize).min(self.theta_bins - 1);
            let j = ((phi / TAU * self.phi_bins as f64) as usize).min(self.phi_bins - 1);
            observed[i * self.phi_bins + j] += 1.0;
        }

        // Expected counts: adaptive Simpson's rule in (u, φ), where dω = du dφ. Each node's
        // density, and its height above the horizon plane (1 without one).
        let horizon = self.horizon.map(|h| h.as_dvec3());
        let density = |u: f64, phi: f64| {
            let cos = 1.0 - u;
            let sin = (u * (2.0 - u)).max(0.0).sqrt();
            let d = s * (sin * phi.cos()) + t * (sin * phi.sin()) + n * cos;
            let height = horizon.map_or(1.0, |h| h.dot(d));
            (pdf(d.as_vec3()).max(0.0), height)
        };
        let integrator = Simpson2D {
            nodes: (self.integration_nodes.max(3) - 1).next_multiple_of(2) + 1,
            // Refine until a region's error is below a hundredth of one expected sample.
            tolerance: 0.01 / self.samples as f64,
            max_depth: 7,
        };
        let du = u_max / self.theta_bins as f64;
        let dphi = TAU / self.phi_bins as f64;
        let mut expected = vec![0.0; bins + 1];
        let mut error = vec![0.0; bins + 1];
        let mut integral = 0.0;
        for i in 0..self.theta_bins {
            for j in 0..self.phi_bins {
                let (mass, err) =
                    integrator.integrate(&density, [i as f64 * du, j as f64 * dphi], [du, dphi], 0);
                integral += mass;
                let k = i * self.phi_bins + j;
                expected[k] = mass * self.samples as f64;
                error[k] = err * self.samples as f64;
            }
        }
        expected[bins] = ((1.0 - integral) * self.samples as f64).max(0.0);
        error[bins] = error[..bins].iter().sum();

        let (chi2, degrees_of_freedom) = pooled_chi2(&observed, &expected, &error);
        let p_value = chi2_p_value(chi2, degrees_of_freedom);
        Chi2Outcome {
            chi2,
            degrees_of_freedom,
            p_value,
            observed,
            expected,
            zero_density_samples,
            integral,
            integral_error: error[bins] / self.samples as f64,
            theta_bins: self.theta_bins,
            phi_bins: self.phi_bins,
        }
    }
}

/// Adaptive 2D Simpson integration over rectangles: a region whose Simpson estimate changes by
/// more than the tolerance when split in four is split, so tabulated densities (discontinuous at
/// their cells' edges) and sharp lobes are integrated where they vary; a region across the edge
/// of the density's support (a light's silhouette, the horizon) is split to the depth limit
/// whatever its estimates, since both can miss a jump between their nodes alike.
struct Simpson2D {
    /// Nodes per axis of one region (odd).
    nodes: usize,
    tolerance: f64,
    max_depth: u32,
}

/// Simpson's estimate over one region, the smallest and largest density at its nodes, and
/// whether its nodes lie on both sides of the horizon.
struct RegionEstimate {
    integral: f64,
    least: f64,
    most: f64,
    straddles: bool,
}

impl Simpson2D {
    fn simpson(
        &self,
        f: &impl Fn(f64, f64) -> (f64, f64),
        origin: [f64; 2],
        size: [f64; 2],
    ) -> RegionEstimate {
        let last = self.nodes - 1;
        let weight = |k: usize| {
            if k == 0 || k == last {
                1.0
            } else if k % 2 == 1 {
                4.0
            } else {
                2.0
            }
        };
        // Nodes on a region's edge are moved just inside it, so that a density discontinuous
        // there is read from this region even after directions are rounded to f32.
        let at = |k: usize| (k as f64 / last as f64).clamp(1e-4, 1.0 - 1e-4);
        let (mut sum, mut least, mut most) = (0.0, f64::INFINITY, 0.0f64);
        let (mut above, mut below) = (false, false);
        for a in 0..=last {
            let x = origin[0] + at(a) * size[0];
            for b in 0..=last {
                let (value, height) = f(x, origin[1] + at(b) * size[1]);
                sum += weight(a) * weight(b) * value;
                least = least.min(value);
                most = most.max(value);
                above |= height > 0.0;
                below |= height < 0.0;
            }
        }
        RegionEstimate {
            integral: sum * size[0] * size[1] / (9.0 * (last * last) as f64),
            least,
            most,
            straddles: above && below,
        }
    }

    /// The integral over the rectangle and an estimate of its error.
    fn integrate(
        &self,
        f: &impl Fn(f64, f64) -> (f64, f64),
        origin: [f64; 2],
        size: [f64; 2],
        depth: u32,
    ) -> (f64, f64) {
        let whole = self.simpson(f, origin, size);
        let half = [size[0] / 2.0, size[1] / 2.0];
        let quarters = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]
            .map(|[a, b]| [origin[0] + a * half[0], origin[1] + b * half[1]]);
        let (mut parts, mut least, mut most) = (0.0, whole.least, whole.most);
        let mut straddles = whole.straddles;
        for &o in &quarters {
            let q = self.simpson(f, o, half);
            parts += q.integral;
            least = least.min(q.least);
            most = most.max(q.most);
            straddles |= q.straddles;
        }
        let difference = (parts - whole.integral).abs();
        // A jump the nodes may straddle: the edge of the support, or the horizon where a
        // reflected lobe meets a transmitted one.
        let across_jump = most > 0.0 && (least <= 0.0 || straddles);
        // Richardson: where the density is smooth, the refined estimate's error is about a
        // fifteenth of the difference.
        if !across_jump && difference / 15.0 <= self.tolerance {
            return (parts, difference / 15.0);
        }
        if depth >= self.max_depth {
            // Unresolved at the depth limit: a jump lies in the region, where Simpson's error
            // shrinks only in proportion to the region's size. Across a jump the region holds
            // between its least and its largest density over all of it (nothing and the
            // largest, across the support's edge).
            let error = if across_jump {
                (most - least.max(0.0)) * size[0] * size[1]
            } else {
                difference
            };
            return (parts, error.max(difference));
        }
        quarters.iter().fold((0.0, 0.0), |(sum, err), &o| {
            let (v, e) = self.integrate(f, o, half, depth + 1);
            (sum + v, err + e)
        })
    }
}

/// The probability that a χ² variable with `degrees_of_freedom` exceeds `chi2`.
fn chi2_p_value(chi2: f64, degrees_of_freedom: usize) -> f64 {
    if degrees_of_freedom == 0 {
        if chi2 == 0.0 { 1.0 } else { 0.0 }
    } else {
        ChiSquared::new(degrees_of_freedom as f64)
            .map(|d| d.sf(chi2))
            .unwrap_or(0.0)
    }
}

/// The p-value of Pearson's χ² test of a histogram: `observed` counts against `expected` ones
/// (the same total), bins expecting fewer than 5 pooled as in [`Chi2Test::run`]. For samplers
/// of other domains than directions (points on a triangle, discrete distributions).
pub fn histogram_p_value(observed: &[f64], expected: &[f64]) -> f64 {
    let (chi2, degrees_of_freedom) = pooled_chi2(observed, expected, &vec![0.0; observed.len()]);
    chi2_p_value(chi2, degrees_of_freedom)
}

/// χ² over bins, pooling those expecting fewer than 5 samples (including those whose integral
/// is zero: samples there raise the pooled bin's statistic; samples where the density itself is
/// zero are caught separately). Each bin's variance is its Poisson variance plus the square of
/// its expected count's integration error.
fn pooled_chi2(observed: &[f64], expected: &[f64], error: &[f64]) -> (f64, usize) {
    let mut order: Vec<usize> = (0..observed.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut chi2, mut bins) = (0.0, 0usize);
    let (mut pool_obs, mut pool_exp, mut pool_err) = (0.0, 0.0, 0.0);
    for &k in &order {
        if expected[k] < 5.0 || pool_exp > 0.0 && pool_exp < 5.0 {
            pool_obs += observed[k];
            pool_exp += expected[k];
            pool_err += error[k];
            continue;
        }
        chi2 += (observed[k] - expected[k]).powi(2) / (expected[k] + error[k] * error[k]);
        bins += 1;
    }
    if pool_exp > 0.0 || pool_err > 0.0 {
        chi2 += (pool_obs - pool_exp).powi(2) / (pool_exp + pool_err * pool_err).max(1e-300);
        bins += 1;
    }
    (chi2, bins.saturating_sub(1))
}

impl Chi2Outcome {
    /// Panics with a report, and writes the two histograms as PNG images, if the test fails at
    /// significance `alpha` (already corrected for the number of tests) or if any sample landed
    /// where the density is zero. Prints the outcome either way (seen with `--nocapture`), so
    /// that p-values can be collected over seeds.
    pub fn assert_passes(&self, alpha: f64, name: &str) {
        eprintln!(
            "chi2 `{name}`: p = {:.4e} (chi2 = {:.1}, dof = {}), {} zero-density samples, seed {}",
            self.p_value,
            self.chi2,
            self.degrees_of_freedom,
            self.zero_density_samples,
            test_seed()
        );
        let failed = self.p_value < alpha
            || self.zero_density_samples > 0
            || self.integral.is_nan()
            || self.integral >= 1.0 + 1e-3 + 4.0 * self.integral_error;
        if !failed {
            return;
        }
        let images = self.write_images(name);
        panic!(
            "chi-square test `{name}` failed (seed {}): p = {:.3e} < {alpha:.3e} (chi2 = {:.1}, dof = {}), {} samples \
             where the pdf is zero, pdf integral over the bins {:.5} ± {:.1e}; histograms: {images}",
            test_seed(),
            self.p_value,
            self.chi2,
            self.degrees_of_freedom,
            self.zero_density_samples,
            self.integral,
            self.integral_error
        );
    }

    /// Writes the histograms (see [`Chi2Outcome::write_images_to`]) into the directory named by
    /// `LUMIS_CHI2_DIR`, or else into a new temporary directory of their own, which is kept for
    /// inspection; returns a description of where, or why not.
    pub fn write_images(&self, name: &str) -> String {
        let dir = match std::env::var_os("LUMIS_CHI2_DIR") {
            Some(dir) => Ok(PathBuf::from(dir)),
            None => tempfile::Builder::new()
                .prefix("lumis-chi2-")
                .tempdir()
                .map(|dir| dir.keep())
                .map_err(|e| e.to_string()),
        };
        match dir.and_then(|dir| self.write_images_to(&dir, name)) {
            Ok(path) => format!(
                "{} (observed, expected, difference in standard deviations)",
                path.display()
            ),
            Err(e) => format!("not written: {e}"),
        }
    }

    /// Writes observed and expected histograms and their difference side by side (φ across, θ
    /// down) as `<name>.png` in `dir` (created if needed); returns the file's path.
    pub fn write_images_to(&self, dir: &Path, name: &str) -> Result<PathBuf, String> {
        let bins = self.theta_bins * self.phi_bins;
        let max = self.observed[..bins]
            .iter()
            .chain(&self.expected[..bins])
            .fold(0.0f64, |a, &b| a.max(b));
        // Each bin drawn as a 4 × 4 block, observed left and expected right, with the signed
        // difference (red: too many samples, blue: too few) in a third panel.
        const ZOOM: u32 = 4;
        let (w, h) = (self.phi_bins as u32, self.theta_bins as u32);
        let panel = w * ZOOM + 4;
        let width = 3 * panel;
        let mut img = vec![0u8; (width * h * ZOOM * 3) as usize];
        let level = |v: f64| (255.0 * (v / max.max(1e-300)).sqrt()) as u8;
        for i in 0..h {
            for j in 0..w {
                let k = (i * w + j) as usize;
                let (o, e) = (self.observed[k], self.expected[k]);
                let z = (o - e) / e.max(1.0).sqrt();
                let diff = [
                    (25.0 * z.max(0.0)).min(255.0) as u8,
                    0,
                    (25.0 * (-z).max(0.0)).min(255.0) as u8,
                ];
                for (x0, color) in [
                    (0, [level(o); 3]),
                    (panel, [level(e); 3]),
                    (2 * panel, diff),
                ] {
                    for dy in 0..ZOOM {
                        for dx in 0..ZOOM {
                            let (x, y) = (x0 + j * ZOOM + dx, i * ZOOM + dy);
                            let at = 3 * (y * width + x) as usize;
                            img[at..at + 3].copy_from_slice(&color);
                        }
                    }
                }
            }
        }
        let file: String = name
            .chars()
            .map(|c| if c.is_alphanumeric() { c } else { '_' })
            .collect();
        let path = dir.join(format!("{file}.png"));
        crate::image_io::write_rgb8_png(&path, width, h * ZOOM, img).map_err(|e| e.to_string())?;
        Ok(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::warp::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};

    #[test]
    fn cases_run_side_by_side_come_back_in_order() {
        // Uneven work, so that the workers finish out of order.
        let cases: Vec<u64> = (0..23).map(|i| (i * 7919) % 23).collect();
        let results = run_side_by_side(&cases, |&n| {
            (0..n * 20_000).for_each(|k| {
                std::hint::black_box(k);
            });
            n * n
        });
        let expected: Vec<u64> = cases.iter().map(|n| n * n).collect();
        assert_eq!(results, expected);
        let panicked = std::panic::catch_unwind(|| {
            run_side_by_side(&[1, 2, 3], |&n| assert!(n != 2, "case {n} fails"))
        });
        assert!(panicked.is_err(), "a failing case fails the caller");
    }

    #[test]
    fn a_correct_sampler_passes_and_a_wrong_density_fails() {
        let test = Chi2Test {
            samples: 200_000,
            ..Default::default()
        };
        // An edge of the square (u.x or u.y = 0, 1.2e-7 of draws) maps to the horizon, where
        // the density is zero: the sampler's users (the BSDFs) refuse such directions, and so
        // does this one.
        let good = test.run(
            |s| Some(square_to_cosine_hemisphere(s.next_2d())).filter(|w| w.z > 0.0),
            |d| cosine_hemisphere_pdf(d.z) as f64,
        );
        good.assert_passes(FAMILY_FALSE_ALARM, "cosine hemisphere");
        assert!((good.integral - 1.0).abs() < 1e-3);
        // Uniform-hemisphere density claimed for a cosine sampler.
        let bad = test.run(
            |s| Some(square_to_cosine_hemisphere(s.next_2d())),
            |d| if d.z > 0.0 { 1.0 / TAU } else { 0.0 },
        );
        assert!(bad.p_value < 1e-6, "{}", bad.p_value);
    }

    #[test]
    fn failures_write_the_histograms_as_an_image() {
        let dir = tempfile::tempdir().unwrap();
        let test = Chi2Test {
            samples: 10_000,
            ..Default::default()
        };
        let o = test.run(
            |s| Some(square_to_cosine_hemisphere(s.next_2d())),
            |d| if d.z > 0.0 { 1.0 / TAU } else { 0.0 },
        );
        let path = o.write_images_to(dir.path(), "cosine vs uniform").unwrap();
        assert_eq!(path, dir.path().join("cosine_vs_uniform.png"));
        let file = std::fs::File::open(&path).unwrap();
        let mut reader = png::Decoder::new(std::io::BufReader::new(file))
            .read_info()
            .unwrap();
        let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
        let frame = reader.next_frame(&mut pixels).unwrap();
        assert_eq!((frame.width, frame.height), (3 * (64 * 4 + 4), 32 * 4));
    }

    /// A failing test names a directory of its own, under the system's temporary directory,
    /// that holds its histograms.
    #[test]
    fn failures_report_a_fresh_directory_with_the_histograms() {
        let test = Chi2Test {
            samples: 10_000,
            ..Default::default()
        };
        let o = test.run(
            |s| Some(square_to_cosine_hemisphere(s.next_2d())),
            |d| if d.z > 0.0 { 1.0 / TAU } else { 0.0 },
        );
        let report = std::panic::catch_unwind(|| o.assert_passes(0.01, "fresh directory"))
            .expect_err("a wrong density fails");
        let message = report.downcast_ref::<String>().unwrap();
        let path = message
            .split_whitespace()
            .find(|w| w.ends_with("fresh_directory.png"))
            .map(PathBuf::from)
            .unwrap_or_else(|| panic!("no image path in: {message}"));
        let dir = path.parent().unwrap().to_path_buf();
        let exists = path.is_file();
        // Removed before asserting, so that the test leaves nothing behind either way.
        if std::env::var_os("LUMIS_CHI2_DIR").is_none() {
            std::fs::remove_dir_all(&dir).unwrap();
            assert!(dir.starts_with(std::env::temp_dir()), "{}", dir.display());
            let name = dir.file_name().unwrap().to_string_lossy();
            assert!(name.starts_with("lumis-chi2-"), "{name}");
        }
        assert!(exists, "{}", path.display());
    }

    #[test]
    fn samples_where_the_pdf_is_zero_are_caught() {
        let test = Chi2Test {
            samples: 10_000,
            ..Default::default()
        };
        let o = test.run(
            |s| Some(square_to_cosine_hemisphere(s.next_2d())),
            |d| if d.x > 0.0 { 1.0 } else { 0.0 },
        );
        assert!(o.zero_density_samples > 0);
    }

    #[test]
    fn caps_resolve_narrow_lobes() {
        // A Phong lobe cos^n θ with n = 1e6 (width ~1e-3 rad), tested in a cap of 5e-3 rad.
        let n = 1e6f64;
        let test = Chi2Test {
            cos_cap: (5e-3f64).cos(),
            samples: 200_000,
            ..Default::default()
        };
        let sample = |s: &mut Sampler| {
            let u = s.next_2d().as_dvec2();
            // cos θ = ξ^(1/(n+1)) with ξ = 1 − u in (0, 1] (u = 0 would give the horizon, where
            // the density is zero), kept as 1 − cos θ to stay accurate.
            let one_minus_cos = -((1.0 - u.x).ln() / (n + 1.0)).exp_m1();
            let sin = (one_minus_cos * (2.0 - one_minus_cos)).sqrt();
            let phi = TAU * u.y;
            Some(DVec3::new(sin * phi.cos(), sin * phi.sin(), 1.0 - one_minus_cos).as_vec3())
        };
        let pdf = |d: Vec3| {
            let d = d.as_dvec3();
            let one_minus_cos = (d.x * d.x + d.y * d.y) / (1.0 + d.z);
            (n + 1.0) / TAU * (n * (-one_minus_cos).ln_1p()).exp()
        };
        let o = test.run(sample, pdf);
        o.assert_passes(FAMILY_FALSE_ALARM, "Phong lobe n = 1e6");
        assert!((o.integral - 1.0).abs() < 1e-3, "{}", o.integral);
        // The same lobe claimed 10% wider fails.
        let wider = |d: Vec3| {
            let d = d.as_dvec3();
            let one_minus_cos = (d.x * d.x + d.y * d.y) / (1.0 + d.z);
            let m = n / 1.21;
            (m + 1.0) / TAU * (m * (-one_minus_cos).ln_1p()).exp()
        };
        assert!(test.run(sample, wider).p_value < 1e-6);
    }

    #[test]
    fn limits_match_their_distributions() {
        // Šidák: K tests at the per-test level keep the family at α exactly when independent.
        let per_test = sidak(0.01, 30);
        assert!((1.0 - (1.0 - per_test).powi(30) - 0.01).abs() < 1e-12);
        assert!(per_test >= 0.01 / 30.0);
        // Two-sided normal quantiles.
        assert!((z_limit(0.05) - 1.959_964).abs() < 1e-5);
        assert!((z_limit(2.0 * 0.001_349_898) - 3.0).abs() < 1e-5);
        // Binomial(100, 0.5) exceeds 63 with probability 0.0033 and 62 with 0.0060 (exact
        // tail sums).
        assert_eq!(binomial_limit(100, 0.5, 0.005), 63);
        // No event can happen: any event is a failure.
        assert_eq!(binomial_limit(1_000_000, 0.0, 1e-4), 0);
        // Poisson-like: mean 1, P(X > 6) = 8.3e-5 ≤ 1e-4 < P(X > 5) = 5.9e-4.
        assert_eq!(binomial_limit(1_000_000, 1e-6, 1e-4), 6);
    }

    #[test]
    fn the_seed_comes_from_the_environment() {
        // The variable is read, never written, by the tests (they run in parallel threads).
        let expected = std::env::var(SEED_VARIABLE).map_or(0, |v| v.trim().parse().unwrap());
        assert_eq!(test_seed(), expected);
        assert_eq!(Chi2Test::default().seed, expected);
        // Distinct streams under one seed are distinct.
        let first = |stream| {
            let mut s = test_sampler(stream);
            [s.next_1d(), s.next_1d(), s.next_1d(), s.next_1d()]
        };
        assert_ne!(first(1), first(2));
    }
}
