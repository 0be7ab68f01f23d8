//! The example methods beside the built-in balance heuristic: their renders converge to the same mean.

use lumis_core::chi2::{FAMILY_FALSE_ALARM, sidak, test_seed, z_limit};
use lumis_core::math::luminance;
use statrs::distribution::{ContinuousCDF, StudentsT};
use std::path::Path;

/// Independent renders of each method.
const RUNS: u64 = 64;

/// The luminance images of the Cornell box at 24 × 18 pixels, N = 16, one camera sample per
/// pixel through its centre, with `integrator` (its type and parameters), in each of `RUNS`
/// renders from the seeds at `first`.
fn images(integrator: &[&str], first: u64) -> Vec<Vec<f64>> {
    lumis_bsdfs::link();
    lumis_emitters::link();
    lumis_integrators::link();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../scenes/cornell.ron");
    let mut overrides: Vec<String> = [
        "film.width=24",
        "film.height=18",
        "sampler.spp=1",
        "sampler.jitter=false",
        "integrator.samples=16",
    ]
    .map(String::from)
    .to_vec();
    overrides.extend(integrator.iter().map(|s| format!("integrator.{s}")));
    let mut loaded = lumis_core::scene::load::load_scene(&scene, &overrides)
        .unwrap_or_else(|e| panic!("{integrator:?}: {e}"));
    (first..first + RUNS)
        .map(|seed| {
            loaded.scene.seed = seed;
            loaded.integrator.preprocess(&loaded.scene);
            let film =
                lumis_core::render::render(&loaded.scene, loaded.integrator.as_ref(), 2, &|_| {})
                    .expect("render")
                    .0;
            let image: Vec<f64> = film.color.iter().map(|c| luminance(*c) as f64).collect();
            assert!(
                image.iter().all(|y| y.is_finite()),
                "{integrator:?}, seed {seed}"
            );
            image
        })
        .collect()
}

/// Each image's mean over the pixels of `pixels`: one value per render.
fn region_means(images: &[Vec<f64>], pixels: &[usize]) -> Vec<f64> {
    let means = images
        .iter()
        .map(|image| pixels.iter().map(|&p| image[p]).sum::<f64>());
    means.map(|sum| sum / pixels.len() as f64).collect()
}

/// The sample mean and the variance of that mean.
fn mean_and_variance(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, variance / n)
}

/// Each example method's image has `balance`'s mean: Welch's t-test of the mean luminance
/// of the reflected light over independent renders (seeds from `LUMIS_TEST_SEED`), at the
/// suite's family-wise false-alarm rate, with the power it states: the relative bias
/// detected with probability 0.9 must be below 2 %.
#[test]
fn example_methods_converge_to_balance() {
    let first = test_seed() * 1_000_000;
    let methods: [&[&str]; 2] = [&["type=power_beta"], &["type=lit_fraction"]];
    let balance = images(&["type=balance"], first);
    // The light seen directly is the same in every render of every method: only the
    // pixels that vary are compared, so that the bias is relative to the reflected light.
    let pixels: Vec<usize> = (0..balance[0].len())
        .filter(|&p| balance.iter().any(|image| image[p] != balance[0][p]))
        .collect();
    assert!(
        pixels.len() > balance[0].len() / 2,
        "{} pixels vary",
        pixels.len()
    );
    let (reference, reference_variance) = mean_and_variance(&region_means(&balance, &pixels));
    let alpha = sidak(FAMILY_FALSE_ALARM, methods.len());
    let mut failures = Vec::new();
    for (k, method) in methods.iter().enumerate() {
        let method_images = images(method, first + 1000 * (k as u64 + 1));
        let (mean, variance) = mean_and_variance(&region_means(&method_images, &pixels));
        let error = (variance + reference_variance).sqrt();
        // Welch–Satterthwaite degrees of freedom.
        let runs = (RUNS - 1) as f64;
        let freedom = (variance + reference_variance).powi(2)
            / (variance.powi(2) / runs + reference_variance.powi(2) / runs);
        let t = StudentsT::new(0.0, 1.0, freedom).expect("a t distribution");
        let limit = t.inverse_cdf(1.0 - alpha / 2.0);
        let detectable = (limit + z_limit(0.2)) * error / reference;
        let relative = (mean - reference) / reference;
        eprintln!(
            "{method:?}: {:+.3} % ± {:.3} % of balance's mean (t limit {limit:.2}, detects {:.2} %)",
            100.0 * relative,
            100.0 * error / reference,
            100.0 * detectable
        );
        if (mean - reference).abs() >= limit * error || detectable > 0.02 {
            failures.push(format!(
                "{method:?}: {mean} vs balance's {reference} ± {error} (limit {limit:.2}, detects {:.2} %, seed {})",
                100.0 * detectable,
                test_seed()
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
