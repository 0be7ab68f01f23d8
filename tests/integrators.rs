//! The MIS integrator family: every registered integrator converges to the same image, `alpha`
//! finds the supplemental's limits in scenes, beats `balance` on the Veach layout, and `alpha`
//! with a fixed α reproduces `balance`, `bsdf` and `light` bit for bit.
//!
//! Why one file of over 600 lines: one subject, the MIS family converging to one image, whose tests
//! share the scenes, the render statistics and the limits defined here.

use crate::common;
use common::{integrators, lumis, scene_file};
use lumis::budgets::Budgets;
use lumis::chi2::{FAMILY_FALSE_ALARM, sidak, test_seed};
use lumis::integrators::{alpha, aovs, balance, bsdf, light, mis, variance_aware};
use lumis::passes::{Settings, Stopping};
use lumis::progressive::{Control, Ending, RenderState, Scope};
use lumis::same_mean::{Comparison, PixelMeans, Z_POWER_90, blocks, t_limit, weights};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

fn repo_path(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

fn render(path: &Path, overrides: &[String]) -> lumis::film::Film {
    let overrides: Vec<&str> = overrides.iter().map(String::as_str).collect();
    common::render(path, &overrides, 2)
}

fn mirror_scene() -> (tempfile::TempDir, PathBuf) {
    let text = format!(
        r#"Scene(
    camera: (position: (0, 1, -3), target: (0, 0.5, 0), fov: 40),
    film: (width: 24, height: 18),
    integrator: (type: "balance"),
    bsdfs: {{ "mirror": (type: "mirror", reflectance: 0.9), "floor": (type: "diffuse", reflectance: 0.5) }},
    shapes: [
        (type: "sphere", bsdf: "mirror", center: (0, 0.6, 0), radius: 0.6),
        (type: "rectangle", bsdf: "floor", transform: (scale: (4, 4, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
    ],
    emitters: [(type: "envmap", file: {:?}, interpolation: "bilinear")],
)"#,
        repo_path("scenes/envmaps/studio.exr").to_str().unwrap()
    );
    scene_file("mirror.ron", &text)
}

/// How many renders the same-mean test makes of each kind. Each comparison's power is required
/// (and printed), so a scene whose noise leaves it far above what is required may take fewer
/// renders ([`FEWER_RUNS`]); the false-alarm rate is the same at any count, since the limits are
/// Student's t quantiles at the measured degrees of freedom.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Runs {
    /// Independent renders per configuration: the per-pixel variance of a render is measured
    /// across them (each render's pixel is the mean of its camera samples).
    pub independent: u64,
    /// Independent renders of a configuration whose pixels are coupled within a render (a
    /// pilot's statistics pooled over blocks of pixels): its comparisons take their variance
    /// from the renders' weighted sums, with `coupled` − 1 degrees of freedom (docs/testing.md).
    pub coupled: u64,
    /// Independent renders of `balance` the tested configurations are compared with.
    pub reference: u64,
    /// Renders of each configuration (and of `balance`) from which the pixel weights are taken,
    /// independent of the compared ones.
    pub pilot: u64,
}

/// The renders of a scene whose noise needs them all for the required power.
pub(crate) const RUNS: Runs = Runs {
    independent: 16,
    coupled: 64,
    reference: 32,
    pilot: 16,
};

/// Half the renders of [`RUNS`] for the independent configurations, the reference and the
/// pilots, on scenes where [`RUNS`] detects biases of a few tenths of a percent or less:
/// `variance_aware`'s 64 (coupled, its power printed, not required) are kept.
pub(crate) const FEWER_RUNS: Runs = Runs {
    independent: 8,
    reference: 16,
    pilot: 8,
    ..RUNS
};

/// Loads the scene once (the seed is read only when rendering, so this equals one load per
/// seed, without parsing and building the env map's distribution for every run).
fn pixel_means(path: &Path, overrides: &[String], seeds: std::ops::Range<u64>) -> PixelMeans {
    pixel_means_rendered(path, overrides, seeds, None)
}

/// A render of the scene's samples in `passes` equal passes whose samples are spread over the
/// pixels by `budgets` (docs/integrators.md, "Passes").
#[derive(Clone, Copy, Debug)]
pub(crate) struct InPasses {
    pub passes: u32,
    pub budgets: Budgets,
}

/// [`pixel_means`] of plain renders (`None`) or of renders in passes.
fn pixel_means_rendered(
    path: &Path,
    overrides: &[String],
    seeds: std::ops::Range<u64>,
    in_passes: Option<InPasses>,
) -> PixelMeans {
    let mut images = Vec::new();
    let strs: Vec<&str> = overrides.iter().map(String::as_str).collect();
    let mut loaded =
        common::load(path, &strs).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    for seed in seeds {
        loaded.scene.seed = seed;
        loaded.integrator.preprocess(&loaded.scene);
        let film = match in_passes {
            None => {
                lumis::render::render(&loaded.scene, loaded.integrator.as_ref(), 2, &|_| {})
                    .expect("render")
                    .0
            }
            Some(InPasses { passes, budgets }) => {
                let spp = loaded.scene.spp;
                let settings = Settings {
                    stopping: Stopping::Samples { spp, passes },
                    ..Settings::samples(spp)
                };
                let integrator = loaded.integrator.as_mut();
                let mut state = RenderState::new(&loaded.scene, integrator, &settings);
                let outcome = lumis::progressive::run(
                    &loaded.scene,
                    integrator,
                    &settings,
                    &mut state,
                    Scope::whole(2).with_budgets(budgets),
                    &AtomicBool::new(false),
                    &|_| {},
                    &mut |_| Control::Continue,
                )
                .expect("render");
                assert_eq!(outcome.ending, Ending::Complete);
                state
                    .sums
                    .resolve(&loaded.scene, loaded.integrator.as_ref())
            }
        };
        assert!(
            film.color.iter().all(|c| c.is_finite()),
            "{}: {overrides:?} seed {seed} is not finite",
            path.display()
        );
        images.push(
            film.color
                .iter()
                .map(|c| lumis::math::luminance(*c) as f64)
                .collect(),
        );
    }
    PixelMeans::new(images)
}

/// Scenes of the same-mean test: diffuse, glossy and mirror surfaces under area, delta, sphere
/// and environment lights (nearest and bilinear maps).
pub(crate) fn same_mean_scene(index: usize) -> (String, Option<tempfile::TempDir>, PathBuf) {
    match index {
        0 => (
            "diffuse + area lights".into(),
            None,
            repo_path("scenes/cornell.ron"),
        ),
        1 => (
            "glossy + env map".into(),
            None,
            repo_path("scenes/envmap.ron"),
        ),
        2 => {
            let (dir, path) = mirror_scene();
            ("mirror + bilinear env map".into(), Some(dir), path)
        }
        3 => (
            "point + directional + area".into(),
            None,
            repo_path("scenes/lights.ron"),
        ),
        _ => ("Veach layout".into(), None, repo_path("scenes/veach.ron")),
    }
}

/// Every registered integrator with its defaults, and the paper's method in its other mode;
/// under the glossy scene's environment map also the map's MIS compensation under two MIS
/// methods. (Light sampling alone from a compensated map is left to the emitter χ² tests: its
/// rare dark directions make its variance estimate too heavy-tailed to promise the 2 % power.)
fn same_mean_configurations(env_map: bool) -> Vec<(String, Vec<String>)> {
    let mut configurations: Vec<(String, Vec<String>)> = integrators()
        .into_iter()
        .map(|name| (name.to_string(), vec![format!("integrator.type={name}")]))
        .collect();
    configurations.push((
        format!("{} {}", alpha::NAME, alpha::PREPROCESSED),
        vec![
            format!("integrator.type={}", alpha::NAME),
            format!("integrator.{}={}", alpha::MODE, alpha::PREPROCESSED),
            format!("integrator.{}=64", alpha::ALPHA_SAMPLES),
        ],
    ));
    if env_map {
        for name in [balance::NAME, alpha::NAME] {
            configurations.push((
                format!("{name}, compensated map"),
                vec![
                    format!("integrator.type={name}"),
                    "emitters[0].compensation=true".to_string(),
                ],
            ));
        }
    }
    configurations
}

/// Every integrator converges to `balance`'s mean on one scene, tested with power.
///
/// Camera rays go through pixel centres (no jitter), so that each pixel is a fixed shading point
/// and its variance across independent renders is the estimator's alone. Pixels of zero variance
/// (directly seen emitters and the environment, no MIS involved) must agree exactly; the others
/// are compared by the relative bias δ̂ of [`Comparison`] over the whole image and over blocks of
/// [`lumis::same_mean::BLOCK`]² pixels, against Student's t limits at the family's false-alarm rate (half for the
/// whole-image tests, half for the blocks, Šidák within each). The test also requires power: the
/// whole-image bias it detects with probability 90 % must be at most `detectable` (relative).
fn same_mean_on_scene(index: usize, spp: u32, detectable: f64, runs: Runs) {
    let (name, _dir, path) = same_mean_scene(index);
    let balance_type = vec![format!("integrator.type={}", balance::NAME)];
    let configurations = same_mean_configurations(index == 1);
    same_mean(
        &name,
        &path,
        spp,
        &balance_type,
        &configurations,
        detectable,
        runs,
    );
}

/// The same-mean test of `configurations` (each a name and its overrides) against the
/// reference configuration `balance_type` (`balance` for the direct integrators; `path` with
/// the balance heuristic for `path`'s weightings, tests/path.rs) on the scene `path`, as
/// [`same_mean_on_scene`] describes it.
pub(crate) fn same_mean(
    name: &str,
    path: &Path,
    spp: u32,
    balance_type: &[String],
    configurations: &[(String, Vec<String>)],
    detectable: f64,
    runs: Runs,
) {
    let plain: Vec<_> = configurations
        .iter()
        .map(|(n, o)| (n.clone(), o.clone(), None))
        .collect();
    same_mean_rendered(name, path, spp, balance_type, &plain, detectable, runs);
}

/// [`same_mean`] of configurations rendered plainly (`None`) or in passes, against plain
/// renders of the reference. A render in passes whose budgets are per pixel, or whose α is
/// pooled over pixels, couples its pixels: it is compared as the coupled configurations are
/// (run sums, `counts.coupled` runs), its power required as every other's.
pub(crate) fn same_mean_rendered(
    name: &str,
    path: &Path,
    spp: u32,
    balance_type: &[String],
    configurations: &[(String, Vec<String>, Option<InPasses>)],
    detectable: f64,
    counts: Runs,
) {
    let path = path.to_path_buf();
    let base = vec![
        "film.width=24".to_string(),
        "film.height=18".to_string(),
        format!("sampler.spp={spp}"),
        "sampler.jitter=false".to_string(),
        format!("integrator.{}=16", mis::SAMPLES),
    ];
    // Seeds: the suite's seed, then disjoint ranges per set of runs.
    let first = test_seed() * 1_000_000;
    let with = |extra: &[String]| [base.clone(), extra.to_vec()].concat();
    let reference_pilot = pixel_means(&path, &with(balance_type), first..first + counts.pilot);
    let reference = pixel_means(
        &path,
        &with(balance_type),
        first + 100..first + 100 + counts.reference,
    );
    let blocks = blocks(24, 18);
    let whole_alpha = sidak(FAMILY_FALSE_ALARM / 2.0, configurations.len());
    let block_alpha = sidak(
        FAMILY_FALSE_ALARM / 2.0,
        configurations.len() * blocks.len(),
    );
    let mut failures = Vec::new();
    for (i, (integrator, extra, in_passes)) in configurations.iter().enumerate() {
        // `variance_aware`'s factors, pooled over blocks of 16² pixels from a pilot of 2 samples
        // per technique and pixel, switch a whole block to one technique in about 6 % of its
        // renders on the Veach layout: its pixels are correlated within a render, and the
        // per-pixel variances would understate the error of δ̂ (docs/testing.md).
        let pooled = extra.iter().any(|o| o.contains("pooled_alpha"));
        let budgets = in_passes.is_some_and(|p| p.budgets != Budgets::Uniform);
        let coupled = integrator == variance_aware::NAME || budgets || pooled;
        let runs = if coupled {
            counts.coupled
        } else {
            counts.independent
        };
        let seeds = first + 1000 * (i as u64 + 1);
        let means = |seeds| pixel_means_rendered(&path, &with(extra), seeds, *in_passes);
        let pilot = means(seeds..seeds + counts.pilot);
        let weights = weights(&reference_pilot, &pilot, runs, counts.reference);
        let seeds = seeds + 100;
        let tested = means(seeds..seeds + runs);
        // Pixels constant over balance's 48 runs: directly seen emission (the environment, an
        // emitter's face), the same whatever the integrator, or a deterministic delta light's,
        // to which another method may add light balance's runs happened never to find (a rare
        // path): never less than balance's value, and equal to it where the tested runs are
        // constant too. (A pixel black under balance may likewise see rare light elsewhere.)
        for p in 0..tested.mean.len() {
            let constant = reference_pilot.variance_of_mean[p] == 0.0
                && reference.variance_of_mean[p] == 0.0
                && reference.mean[p] > 0.0;
            let (a, b) = (tested.mean[p], reference.mean[p]);
            let agrees = if tested.variance_of_mean[p] == 0.0 {
                (a - b).abs() <= 1e-5 * b
            } else {
                a >= b * (1.0 - 1e-5)
            };
            if constant && !agrees {
                failures.push(format!(
                    "{name}: {integrator} pixel {p}, constant under balance ({b}), is {a} ± {}",
                    tested.variance_of_mean[p].sqrt()
                ));
            }
        }
        let whole = Comparison::new(
            &tested,
            &reference,
            &weights,
            &reference_pilot.mean,
            0..tested.mean.len(),
            coupled,
        );
        let limit = t_limit(whole_alpha, whole.degrees_of_freedom);
        let detected = (limit + Z_POWER_90) * whole.standard_error;
        eprintln!(
            "{name}: {integrator}: δ̂ = {:+.4} ± {:.4} (t = {:+.2}, ν = {:.0}, limit {limit:.2}); \
             detects {:.2} % with probability 0.9",
            whole.relative_bias,
            whole.standard_error,
            whole.t(),
            whole.degrees_of_freedom,
            100.0 * detected
        );
        failures.extend((whole.t().abs() >= limit).then(|| {
            format!(
                "{name}: {integrator} differs from balance by {:+.2} % ± {:.2} % (t = {:.2}, \
                 limit {limit:.2}, seed {})",
                100.0 * whole.relative_bias,
                100.0 * whole.standard_error,
                whole.t(),
                test_seed()
            )
        }));
        // Pure BSDF sampling of small lights is a rare-event estimator whose means over the
        // runs are far from normal per block; it is held to the whole-image test only, its
        // detectable bias printed (docs/testing.md). `variance_aware`'s error is carried by
        // rare renders too (one in ~4000 on the Veach layout adds up to 3 times the image):
        // its power is printed, not required, since 64 runs seldom see them (docs/testing.md).
        let rare_events = integrator == bsdf::NAME;
        let power_required = !rare_events && (!coupled || in_passes.is_some());
        failures.extend((detected > detectable && power_required).then(|| {
            format!(
                "{name}: {integrator}: the test detects only biases above {:.2} %",
                100.0 * detected
            )
        }));
        for (b, block) in blocks.iter().enumerate().filter(|_| !rare_events) {
            let c = Comparison::new(
                &tested,
                &reference,
                &weights,
                &reference_pilot.mean,
                block.iter().copied(),
                coupled,
            );
            if c.standard_error.is_nan() {
                continue; // a block with no pixel of positive variance
            }
            let limit = t_limit(block_alpha, c.degrees_of_freedom);
            failures.extend((c.t().abs() >= limit).then(|| {
                format!(
                    "{name}: {integrator}, block {b}: differs from balance by {:+.2} % ± {:.2} % \
                 (t = {:.2}, ν = {:.0}, limit {limit:.2}, seed {})",
                    100.0 * c.relative_bias,
                    100.0 * c.standard_error,
                    c.t(),
                    c.degrees_of_freedom,
                    test_seed()
                )
            }));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The relative bias every same-mean comparison must detect with probability 0.9.
const DETECTABLE: f64 = 0.02;

#[test]
fn same_mean_diffuse_under_area_lights() {
    same_mean_on_scene(0, 4, DETECTABLE, FEWER_RUNS);
}

#[test]
fn same_mean_glossy_under_an_env_map() {
    same_mean_on_scene(1, 12, DETECTABLE, RUNS);
}

#[test]
fn same_mean_mirror_under_a_bilinear_env_map() {
    same_mean_on_scene(2, 12, DETECTABLE, RUNS);
}

#[test]
fn same_mean_under_point_directional_and_area_lights() {
    same_mean_on_scene(3, 4, DETECTABLE, FEWER_RUNS);
}

#[test]
fn same_mean_on_the_veach_layout() {
    same_mean_on_scene(4, 4, DETECTABLE, FEWER_RUNS);
}

/// A grey diffuse floor seen at one point (on the light's axis) by a camera of 0.01° field:
/// every pixel is an independent estimate of the same radiance.
fn analytic_scene(light: &str, emitters: &str) -> String {
    format!(
        r#"Scene(
    camera: (position: (0.6, 1.0, -1.2), target: (0, 0, 0), fov: 0.01),
    film: (width: 16, height: 16),
    integrator: (type: "balance", samples: 16),
    bsdfs: {{ "grey": (type: "diffuse", reflectance: 0.5) }},
    shapes: [
        (type: "rectangle", bsdf: "grey", transform: (scale: (10, 10, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
        {light}
    ],
    emitters: [{emitters}],
)"#
    )
}

/// Every integrator against a closed form, with power: a diffuse floor (ρ = 1/2) on the axis of
/// a sphere light (radiance ρ L (r/d)², 2 % of the upper hemisphere's solid angle: light sampling
/// dominates the MIS weights) and under a uniform environment (ρ L: the map's sampling over the
/// whole sphere against cosine sampling). A bias shared by every MIS method, which the same-mean
/// comparison cannot see (a light-sample density off by 2 % shifts `balance` as much as `light`
/// where p_L ≫ p_B), shows here. The 256 pixels are independent estimates: their mean is tested
/// against the closed form with Student's t (Šidák over every case at the suite's rate), and the
/// relative bias detected with probability 0.9 must be at most 1 % (every method but `bsdf`,
/// which reaches the small sphere by chance; it is tested, its power printed).
#[test]
fn every_integrator_gives_the_closed_form_at_one_point() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("uniform.exr");
    exr::prelude::write_rgb_file(&map, 16, 8, |_, _| (2.0f32, 2.0, 2.0)).unwrap();
    let (r, d, radiance, rho) = (0.25f64, 2.0f64, 10.0f64, 0.5f64);
    let cases = [
        (
            "sphere light",
            analytic_scene(
                &format!(
                    "(type: \"sphere\", bsdf: \"grey\", radius: {r}, center: (0, {d}, 0), \
                     emitter: (type: \"area\", radiance: {radiance})),"
                ),
                "",
            ),
            rho * radiance * (r / d).powi(2),
            32,
        ),
        (
            "uniform environment",
            analytic_scene("", &format!("(type: \"envmap\", file: {map:?})")),
            rho * 2.0,
            256,
        ),
    ];
    let configurations = same_mean_configurations(false);
    let alpha = sidak(FAMILY_FALSE_ALARM, cases.len() * configurations.len());
    let mut failures = Vec::new();
    for (c, (case, text, expected, spp)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("case{c}.ron"));
        std::fs::write(&path, text).unwrap();
        for (i, (integrator, extra)) in configurations.iter().enumerate() {
            let mut overrides = extra.clone();
            overrides.push(format!("sampler.spp={spp}"));
            overrides.push(format!(
                "sampler.seed={}",
                test_seed() * 1000 + 100 * c as u64 + i as u64
            ));
            let film = render(&path, &overrides);
            let values: Vec<f64> = film.color.iter().map(|v| v.y as f64).collect();
            let (mean, se) = common::mean_and_standard_error(&values);
            // Light sampling a sphere from a point on its axis, or cosine-sampling a uniform
            // environment, can be exact to the film's f32 rounding: a few ulps are allowed.
            let se = se.hypot(4.0 * f32::EPSILON as f64 * expected);
            let limit = t_limit(alpha, values.len() as f64 - 1.0);
            let t = (mean - expected) / se;
            let detected = (limit + Z_POWER_90) * se / expected;
            eprintln!(
                "{case}: {integrator}: {mean:.5} ± {se:.5}, closed form {expected:.5} \
                 ({:+.3} %, t = {t:+.2}, limit {limit:.2}); detects {:.2} % with probability 0.9",
                100.0 * (mean / expected - 1.0),
                100.0 * detected
            );
            if t.is_nan() || t.abs() >= limit {
                failures.push(format!(
                    "{case}: {integrator} gives {mean} ± {se}, closed form {expected} (t = {t:.2}, \
                     limit {limit:.2}, seed {})",
                    test_seed()
                ));
            }
            if detected > 0.01 && integrator != bsdf::NAME {
                failures.push(format!(
                    "{case}: {integrator}: the test detects only biases above {:.2} %",
                    100.0 * detected
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// MIS compensation of an environment map (sampling it from max(Y − Ȳ, Ȳ/100)) changes the
/// light technique's density, not the integral: every registered integrator with a compensated
/// map converges to the mean of `balance` with the plain map, on both env-map scenes (|z| < 3).
/// Every registered integrator (with its `preprocess`, so the pilot-based methods run their
/// pilots) on a Lambertian floor under a sphere light, seen at (nearly) one point: the mean over
/// the 64 independent pixel estimates is within 4 standard errors of the analytic ρ L (r/d)²
/// (E = π L (r/d)² on the sphere's axis).
#[test]
fn every_integrator_gives_the_analytic_radiance_under_a_sphere_light() {
    let (r, d, radiance, rho) = (0.25f64, 2.0f64, 10.0f64, 0.5f64);
    let text = format!(
        r#"Scene(
    camera: (position: (0.6, 1.0, -1.2), target: (0, 0, 0), fov: 0.01),
    film: (width: 8, height: 8),
    sampler: (spp: 4, seed: 3),
    integrator: (type: "balance", samples: 256),
    bsdfs: {{ "grey": (type: "diffuse", reflectance: {rho}) }},
    shapes: [
        (type: "rectangle", bsdf: "grey", transform: (scale: (10, 10, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
        (type: "sphere", bsdf: "grey", radius: {r}, center: (0, {d}, 0), emitter: (type: "area", radiance: {radiance})),
    ],
)"#
    );
    let (_dir, path) = scene_file("sphere.ron", &text);
    let expected = rho * radiance * (r / d).powi(2);
    for name in integrators() {
        let film = render(&path, &[format!("integrator.type={name}")]);
        let values: Vec<f64> = film.color.iter().map(|c| c.y as f64).collect();
        let (mean, se) = common::mean_and_standard_error(&values);
        assert!(se < 0.05 * expected, "{name}: too noisy to test: se {se}");
        assert!(
            (mean - expected).abs() < 4.0 * se,
            "{name}: mean {mean} vs {expected} (se {se})"
        );
    }
}

/// Mean of the raw combined α over pixels that have a shading point, with its standard error.
fn mean_alpha(film: &lumis::film::Film) -> (f64, f64) {
    let alphas = film
        .aov(aovs::ALPHA)
        .unwrap()
        .channel(aovs::COMBINED)
        .unwrap();
    let colors = film.aov(aovs::ALPHA_COLOR).unwrap().channel("R").unwrap();
    let values: Vec<f64> = alphas
        .into_iter()
        .zip(colors)
        .filter(|(_, red)| *red > 0.0)
        .map(|(a, _)| a as f64)
        .collect();
    common::mean_and_standard_error(&values)
}

fn alpha_scene(material: &str, light: &str, extra: &str) -> String {
    format!(
        r#"Scene(
    camera: (position: (0, 1, -1), target: (0, 0, 0), fov: 20),
    film: (width: 16, height: 16),
    integrator: (type: "alpha", mode: "preprocessed", alpha_samples: 2048, clamp: (0, 1), samples: 4, aovs: ["alpha"]),
    bsdfs: {{ "m": {material}, "black": (type: "diffuse", reflectance: 0) }},
    shapes: [
        (type: "rectangle", bsdf: "m", transform: (scale: (3, 3, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
        {light}
    ],
    {extra}
)"#
    )
}

/// Supplemental §1.4: a highly specular lobe under a broad light gives α̂ → 3/4 (unclamped). The
/// limit is approached, not reached: 0.002 allows for a lobe of roughness 0.001, not a Dirac.
#[test]
fn near_mirror_lobe_under_a_broad_light_gives_three_quarters() {
    let dir = tempfile::tempdir().unwrap();
    exr::prelude::write_rgb_file(dir.path().join("sky.exr"), 32, 16, |_, _| {
        (1.0f32, 1.0f32, 1.0f32)
    })
    .unwrap();
    let text = alpha_scene(
        r#"(type: "glossy", roughness: 0.001, specular: 1)"#,
        "",
        r#"emitters: [(type: "envmap", file: "sky.exr")],"#,
    );
    let path = dir.path().join("scene.ron");
    std::fs::write(&path, text).unwrap();
    let (alpha, se) = mean_alpha(&render(&path, &[]));
    assert!(
        (alpha - 0.75).abs() < 0.002 + 4.0 * se,
        "α = {alpha} ± {se}"
    );
}

/// Supplemental §1.4: a very small light over a diffuse surface gives α̂ → 1/4 (unclamped),
/// within 0.002 for a light of 1 mm.
#[test]
fn tiny_light_over_a_diffuse_surface_gives_one_quarter() {
    let text = alpha_scene(
        r#"(type: "diffuse", reflectance: 0.8)"#,
        r#"(type: "sphere", bsdf: "black", center: (0, 1, 0), radius: 0.001, emitter: (type: "area", radiance: 1e6)),"#,
        "",
    );
    let (_dir, path) = scene_file("tiny.ron", &text);
    let (alpha, se) = mean_alpha(&render(&path, &[]));
    assert!(
        (alpha - 0.25).abs() < 0.002 + 4.0 * se,
        "α = {alpha} ± {se}"
    );
}

/// Mean over pixels of the per-pixel sampling variance V[L_{1,α}].
fn mean_sampling_variance(film: &lumis::film::Film) -> f64 {
    let values = film
        .aov(aovs::SAMPLING_VARIANCE)
        .unwrap()
        .channel(aovs::Y)
        .unwrap();
    values.iter().map(|&v| v as f64).sum::<f64>() / values.len() as f64
}

#[test]
fn alpha_has_lower_sampling_variance_than_balance_on_the_veach_layout() {
    let path = repo_path("scenes/veach.ron");
    let run = |integrator: &str| {
        let film = render(
            &path,
            &[
                "film.width=80".into(),
                "film.height=60".into(),
                format!("integrator.type={integrator}"),
                "integrator.samples=64".into(),
                "integrator.aovs=[\"sampling_variance\"]".into(),
            ],
        );
        mean_sampling_variance(&film)
    };
    let (alpha, balance) = (run(alpha::NAME), run(balance::NAME));
    assert!(alpha < balance, "alpha {alpha} vs balance {balance}");
}

/// `alpha` in fixed mode goes through its own parameters (`mode`, `fixed`) to the fixed
/// allocation the other plugins use: α = ½ must give `balance`'s image, α = 1 `bsdf`'s and α = 0
/// `light`'s, bit for bit, AOVs included; also with a mirror plate, which `light` gives BSDF
/// samples.
#[test]
fn fixed_alpha_reproduces_balance_bsdf_and_light_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let scene = repo_path("scenes/veach.ron");
    let common = [
        "--set",
        "film.width=32",
        "--set",
        "film.height=24",
        "--set",
        "integrator.samples=15",
        "--set",
        "integrator.aovs=[\"alpha\", \"sampling_variance\", \"samples\"]",
        "--quiet",
    ];
    let mirror = "bsdfs.plate0=(type: \"mirror\", reflectance: 0.8)";
    let render = |out: &str, sets: &[String]| {
        let mut args = vec!["render", scene.to_str().unwrap(), "-o", out];
        for s in sets {
            args.extend(["--set", s]);
        }
        args.extend(common);
        let o = lumis(dir.path(), &args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let channels = lumis::image_io::read_exr_channels(&dir.path().join(out)).unwrap();
        channels
            .iter()
            .map(|(name, v)| {
                (
                    name.clone(),
                    v.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                )
            })
            .collect::<Vec<_>>()
    };
    for (plugin, alpha) in [(balance::NAME, 0.5), (bsdf::NAME, 1.0), (light::NAME, 0.0)] {
        let fixed = |extra: &[String]| {
            let mut sets = vec![
                format!("integrator.type={}", alpha::NAME),
                format!("integrator.{}={}", alpha::MODE, alpha::FIXED),
                format!("integrator.{}={alpha}", alpha::FIXED_ALPHA),
            ];
            sets.extend_from_slice(extra);
            sets
        };
        let own = |extra: &[String]| {
            let mut sets = vec![format!("integrator.type={plugin}")];
            sets.extend_from_slice(extra);
            sets
        };
        for extra in [vec![], vec![mirror.to_string()]] {
            let a = render("own.exr", &own(&extra));
            let b = render("fixed.exr", &fixed(&extra));
            assert!(
                a == b,
                "{plugin} and alpha fixed at {alpha} differ ({extra:?})"
            );
        }
    }
}

#[test]
fn alpha_map_and_previews_are_written_when_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let scene = repo_path("scenes/veach.ron");
    let o = lumis(
        dir.path(),
        &[
            "render",
            scene.to_str().unwrap(),
            "-o",
            "v.exr",
            "--quiet",
            "--set",
            "film.width=32",
            "--set",
            "film.height=24",
            "--set",
            "integrator.type=alpha",
            "--set",
            "integrator.samples=16",
            "--set",
            "integrator.aovs=[\"alpha\", \"sampling_variance\", \"samples\"]",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let channels = lumis::image_io::read_exr_channels(&dir.path().join("v.exr")).unwrap();
    let names: Vec<&str> = channels.iter().map(|c| c.0.as_str()).collect();
    let layer = |aov: &str, channel: &str| format!("{aov}.{channel}");
    for name in [
        layer(aovs::ALPHA, aovs::COMBINED),
        layer(aovs::ALPHA, &aovs::light_channel(0)),
        layer(aovs::ALPHA, &aovs::light_channel(3)),
        layer(aovs::ALPHA_COLOR, "R"),
        layer(aovs::SAMPLING_VARIANCE, aovs::Y),
        layer(aovs::SAMPLE_COUNTS, aovs::BSDF),
        layer(aovs::SAMPLE_COUNTS, aovs::LIGHT),
    ] {
        assert!(
            names.contains(&name.as_str()),
            "{name} missing from {names:?}"
        );
    }
    for (name, values) in &channels {
        assert!(
            values.iter().all(|v| v.is_finite()),
            "{name} has a non-finite value"
        );
        if name.starts_with(&format!("{}.", aovs::ALPHA)) {
            assert!(
                values.iter().all(|v| (0.025..=0.975).contains(v)),
                "{name} outside the clamp"
            );
        }
    }
    for png in [
        format!("v.{}.png", aovs::ALPHA_COLOR),
        format!("v.{}.png", aovs::alpha_color_light(0)),
        format!("v.{}.png", aovs::alpha_color_light(3)),
    ] {
        assert!(dir.path().join(&png).exists(), "{png} not written");
    }
    // Without the request (the scene asks for α, an override asks for nothing), no layer and
    // no preview.
    let o = lumis(
        dir.path(),
        &[
            "render",
            scene.to_str().unwrap(),
            "-o",
            "w.exr",
            "--quiet",
            "--set",
            "film.width=8",
            "--set",
            "film.height=8",
            "--set",
            "integrator.aovs=[]",
        ],
    );
    assert!(o.status.success());
    assert_eq!(
        lumis::image_io::read_exr_channels(&dir.path().join("w.exr"))
            .unwrap()
            .len(),
        3
    );
    assert!(
        !dir.path()
            .join(format!("w.{}.png", aovs::ALPHA_COLOR))
            .exists()
    );
}

/// The study's default list (a string, for its command line) names registered integrators with
/// parameters they accept, so that renaming a plugin or a parameter fails here, not in a study.
#[test]
fn the_study_default_integrators_build() {
    lumis::link_plugins();
    let names = integrators();
    for text in lumis::study::DEFAULT_INTEGRATORS.split(',') {
        let choice = lumis::study::Choice::parse(text).unwrap();
        assert!(names.contains(&choice.spec.kind.as_str()), "{text}");
        lumis::scene::load::build_integrator(&choice.spec, Path::new("."))
            .unwrap_or_else(|e| panic!("{text}: {e}"));
    }
}

/// The phase a `LightSampling` draws at a shading point of the Veach layout: one record per
/// drawn sample (BSDF ones first), black records contributing zero, the contributions adding up
/// to the estimate, the observer seeing the same records, and the same stream giving the same
/// records again.
#[test]
fn a_phase_has_one_record_per_sample_and_contributions_that_add_up() {
    use lumis::integrators::phase::{Observer, Phase, PhaseRole, SampleSplit};
    use lumis::integrators::sampling::{LightSampling, PhaseBuffers};
    use lumis::integrators::shading_point::ShadingPoint;
    use lumis::integrators::weighting::{Balance, PerSample};

    /// Counts what it sees.
    #[derive(Default)]
    struct Seen {
        records: usize,
        black: usize,
    }
    impl Observer for Seen {
        fn observe(&mut self, phase: &Phase, contributions: &[lumis::math::Rgb]) {
            assert_eq!(phase.records.len(), contributions.len());
            self.records += phase.records.len();
            self.black += phase.records.iter().filter(|r| r.is_black()).count();
        }
    }

    let loaded = common::load(&repo_path("scenes/veach.ron"), &[]).unwrap();
    let scene = &loaded.scene;
    let pixel = glam::UVec2::new(160, 150);
    let ray = lumis::integrator::CameraSample::new(scene, pixel, 0).ray;
    let sp = ShadingPoint::new(scene, &scene.intersect(&ray).unwrap(), -ray.direction);
    let split = SampleSplit::new(0.3, 37);
    let mut buffers = PhaseBuffers::default();
    let draw = |buffers: &mut PhaseBuffers, light: usize| {
        let mut sampler = lumis::sampler::Sampler::new(5, 6, 7);
        let mut seen = Seen::default();
        let mut sampling = LightSampling::new(scene, &sp, light, pixel, &mut sampler, buffers);
        let value = sampling.phase(split, PhaseRole::ESTIMATE, &PerSample(Balance), &mut seen);
        let (phase, contributions) = sampling.last_phase().unwrap();
        assert_eq!(phase.split, split);
        assert_eq!(phase.bsdf_records().len(), split.n_bsdf as usize);
        assert_eq!(phase.light_records().len(), split.n_light as usize);
        assert_eq!(seen.records, split.total() as usize);
        let mut sum = lumis::math::Rgb::ZERO;
        for (r, c) in phase.records.iter().zip(contributions) {
            if r.is_black() {
                assert_eq!(*c, lumis::math::Rgb::ZERO);
            }
            sum += *c;
        }
        assert_eq!(sum, value);
        (phase.records.to_vec(), value, seen.black)
    };
    let mut lit = 0;
    for light in 0..scene.emitters.len() {
        let (records, value, black) = draw(&mut buffers, light);
        assert_eq!(draw(&mut buffers, light).0, records, "not deterministic");
        lit += usize::from(value.max_element() > 0.0 && black < records.len());
    }
    assert!(lit >= 2, "only {lit} lights reach the plate");
}

/// A sample that an occluder blocks keeps both densities when a weighting asks for them
/// (`Densities::Both`: `optimal_mis`'s system reads them): the same samples (same stream) at
/// the same floor point of one scene with an occluder below two lights (a sphere of radius
/// above 1, a mesh rectangle) and of the same scene without it have the same densities (the
/// scene away from the origin, where a wrong hit position would go unnoticed). For a
/// BSDF sample blocked before the light, the light's density comes from the light intersected
/// alone; for a blocked light sample, the BSDF's density is evaluated all the same.
/// A BSDF sample takes `BSDF_SAMPLE_NUMBERS` numbers from the stream whatever becomes of it
/// (the phase relies on it to know the first light sample's numbers in advance): on the veach
/// scene's glossy plates, where samples fail, miss and reach lights.
#[test]
fn bsdf_samples_take_a_fixed_count_of_numbers() {
    use lumis::integrators::estimator::{BSDF_SAMPLE_NUMBERS, Densities, draw_bsdf_samples};
    use lumis::integrators::shading_point::ShadingPoint;
    let loaded = common::load(&repo_path("scenes/veach.ron"), &[]).unwrap();
    let scene = &loaded.scene;
    let mut records = Vec::new();
    let mut points = 0;
    for x in (0..scene.width).step_by(7) {
        let mut sample = lumis::integrator::CameraSample::new(scene, glam::UVec2::new(x, 200), 0);
        let Some(hit) = scene.intersect(&sample.ray) else {
            continue;
        };
        let sp = ShadingPoint::new(scene, &hit, -sample.ray.direction);
        for light in 0..scene.emitters.len() {
            for count in [1, 5] {
                let mut expected = sample.sampler.clone();
                expected.skip(BSDF_SAMPLE_NUMBERS * count);
                draw_bsdf_samples(
                    scene,
                    &sp,
                    light,
                    count,
                    &mut sample.sampler,
                    &mut records,
                    Densities::Lit,
                    None,
                );
                assert_eq!(
                    sample.sampler.next_1d().to_bits(),
                    expected.next_1d().to_bits(),
                    "pixel ({x}, 200), light {light}, {count} samples"
                );
            }
        }
        points += 1;
    }
    assert!(points > 10, "only {points} shading points");
    assert!(records.iter().any(|r| !r.is_black()) && records.iter().any(|r| r.is_black()));
}

/// A phase defers the environment lookups of its BSDF samples until after its light samples
/// (a prefetch then has time to land): the records it fills in then are those the samples get
/// when looked up at once, bit for bit, with both densities or one. On the envmap scene's
/// glossy, mirror and diffuse surfaces, where BSDF rays are blocked, reach the map, and fail.
#[test]
fn deferred_environment_lookups_give_the_same_records() {
    use lumis::integrators::estimator::{DeferredLookups, Densities, draw_bsdf_samples};
    use lumis::integrators::shading_point::ShadingPoint;
    let loaded = common::load(&repo_path("scenes/envmap.ron"), &[]).unwrap();
    let scene = &loaded.scene;
    let light = scene
        .environment
        .expect("the envmap scene has an environment");
    let (mut direct, mut deferring) = (Vec::new(), Vec::new());
    let mut deferred = DeferredLookups::default();
    let (mut points, mut reached, mut black) = (0, 0, 0);
    for y in (0..scene.height).step_by(16) {
        for x in (0..scene.width).step_by(16) {
            let sample = lumis::integrator::CameraSample::new(scene, glam::UVec2::new(x, y), 0);
            let Some(hit) = scene.intersect(&sample.ray) else {
                continue;
            };
            let sp = ShadingPoint::new(scene, &hit, -sample.ray.direction);
            for densities in [Densities::Lit, Densities::Both] {
                let (mut a, mut b) = (sample.sampler.clone(), sample.sampler.clone());
                direct.clear();
                deferring.clear();
                draw_bsdf_samples(scene, &sp, light, 6, &mut a, &mut direct, densities, None);
                let later = Some(&mut deferred);
                draw_bsdf_samples(
                    scene,
                    &sp,
                    light,
                    6,
                    &mut b,
                    &mut deferring,
                    densities,
                    later,
                );
                deferred.look_up(scene, &sp, light, &mut deferring);
                assert_eq!(direct, deferring, "pixel ({x}, {y}), {densities:?}");
                assert_eq!(a.next_1d().to_bits(), b.next_1d().to_bits());
                reached += direct.iter().filter(|r| !r.is_black()).count();
                black += direct.iter().filter(|r| r.is_black()).count();
            }
            points += 1;
        }
    }
    // Samples that reached the map (deferred, then filled in) and samples that did not.
    assert!(
        points > 100 && reached > 1000 && black > 200,
        "{points} shading points, {reached} samples reached the map, {black} did not"
    );
}

#[test]
fn occluded_samples_keep_the_densities_of_the_unoccluded_ones() {
    use lumis::integrators::estimator::{
        Densities, SampleRecord, draw_bsdf_samples, draw_light_samples,
    };
    use lumis::integrators::shading_point::ShadingPoint;

    let scene_text = |occluder: &str| {
        format!(
            r#"Scene(
    camera: (position: (5, 1, 4), target: (5, 0, 5), fov: 1),
    film: (width: 3, height: 3),
    integrator: (type: "balance"),
    bsdfs: {{ "grey": (type: "diffuse", reflectance: 0.5) }},
    shapes: [
        (type: "rectangle", bsdf: "grey", transform: (scale: (3, 3, 1), rotate: [(axis: (1, 0, 0), angle: -90)], translate: (5, 0, 5))),
        (type: "sphere", bsdf: "grey", radius: 1.2, center: (6.8, 2.5, 5), emitter: (type: "area", radiance: 1)),
        (type: "rectangle", bsdf: "grey", emitter: (type: "area", radiance: 1),
            transform: (scale: (0.5, 0.5, 1), rotate: [(axis: (1, 0, 0), angle: 90)], translate: (4.2, 1.5, 5))),
        {occluder}
    ],
)"#
        )
    };
    let occluder = r#"(type: "rectangle", bsdf: "grey",
            transform: (scale: (0.5, 0.5, 1), rotate: [(axis: (1, 0, 0), angle: 90)], translate: (5, 0.9, 5)))"#;
    let (_clear_dir, clear_path) = scene_file("clear.ron", &scene_text(""));
    let (_blocked_dir, blocked_path) = scene_file("blocked.ron", &scene_text(occluder));
    let clear = common::load(&clear_path, &[]).unwrap();
    let blocked = common::load(&blocked_path, &[]).unwrap();
    const COUNT: u32 = 8192;
    let records = |scene: &lumis::scene::Scene, light: usize, bsdf_sampling: bool| {
        let ray = lumis::integrator::CameraSample::new(scene, glam::UVec2::new(1, 1), 0).ray;
        let sp = ShadingPoint::new(scene, &scene.intersect(&ray).unwrap(), -ray.direction);
        let mut sampler = lumis::sampler::Sampler::new(11, 12, 13);
        let mut records = Vec::new();
        let both = Densities::Both;
        if bsdf_sampling {
            draw_bsdf_samples(
                scene,
                &sp,
                light,
                COUNT,
                &mut sampler,
                &mut records,
                both,
                None,
            );
        } else {
            draw_light_samples(scene, &sp, light, COUNT, &mut sampler, &mut records, both);
        }
        records
    };
    // The real hit and the light's own intersection differ by rounding: at most 4.8e-7 here.
    let close = |a: f32, b: f32| (a - b).abs() <= 1e-5 * a.max(b);
    for light in 0..clear.scene.emitters.len() {
        for bsdf_sampling in [true, false] {
            let technique = if bsdf_sampling { "BSDF" } else { "light" };
            let open: Vec<SampleRecord> = records(&clear.scene, light, bsdf_sampling);
            let shut = records(&blocked.scene, light, bsdf_sampling);
            assert_eq!(open.len(), shut.len());
            let mut occluded = 0;
            for (i, (o, s)) in open.iter().zip(&shut).enumerate() {
                assert!(
                    close(o.p_bsdf, s.p_bsdf) && close(o.p_light, s.p_light),
                    "light {light}, {technique} sample {i}: densities {o:?} unoccluded, {s:?} \
                     behind the occluder"
                );
                occluded += usize::from(!o.is_black() && s.is_black());
            }
            // Several percent of either technique's samples reach each light through the
            // occluder's place.
            assert!(
                occluded > COUNT as usize / 100,
                "light {light}, {technique}: only {occluded} samples blocked: nothing tested"
            );
        }
    }
}

/// Camera samples shaded as a packet (`Integrator::shade_together`, which the MIS family draws
/// with one batch call per light and technique for all of the packet's samples) give what
/// shading them one by one gives, bit for bit: the estimates and the AOV sums, for every
/// integrator, N = 1, 2, 5 and 8 (drawn together with eight lanes), 16 (`balance` point by
/// point, `alpha`'s phases of 8 together) and 32 (point by point), with and without AOVs, in
/// packets of 16 and of 5 samples (these with their primary rays not yet traced), on
/// scenes with area, sphere, delta and environment lights and with several materials (packets
/// whose samples meet different BSDFs, and samples that miss everything).
#[test]
fn a_packet_shaded_together_gives_what_one_by_one_gives() {
    let (mut mixed_materials, mut with_misses, mut compared) = (0, 0, 0);
    for file in [
        "scenes/cornell.ron",
        "scenes/veach.ron",
        "scenes/envmap.ron",
        "scenes/lights.ron",
        "scenes/materials.ron",
    ] {
        let path = repo_path(file);
        let text = std::fs::read_to_string(&path).unwrap();
        let film = ["film.width=32", "film.height=24"];
        let loaded = common::load(&path, &film).unwrap_or_else(|e| panic!("{file}: {e}"));
        let scene = &loaded.scene;
        let pixels = common::every_nth_pixel(scene, 7);
        for integrator in integrators() {
            let cases = [
                (1, false),
                (2, false),
                (5, false),
                (8, false),
                (16, false),
                (32, false),
                (2, true),
            ];
            for (n, aovs) in cases {
                let aov_list = aov_override(aovs);
                let overrides: Vec<String> = film
                    .iter()
                    .map(|o| o.to_string())
                    .chain([
                        format!("integrator.type={integrator}"),
                        format!("integrator.samples={n}"),
                        aov_list,
                    ])
                    .collect();
                let name = format!("{file}, {integrator}, N = {n}, AOVs {aovs}");
                let built = common::preprocessed_integrator(&path, &text, &overrides, scene, &name);
                for &pixel in &pixels {
                    for indices in [0..16, 16..21] {
                        let shaded =
                            common::shade_packet_both_ways(scene, &*built, pixel, indices, &name);
                        let alone = shaded.alone;
                        compared += 1;
                        let hits: Vec<_> = alone.iter().map(|s| s.intersect(scene)).collect();
                        with_misses += hits.iter().any(|h| h.is_none()) as u32;
                        let bsdfs: Vec<*const ()> = hits
                            .iter()
                            .flatten()
                            .map(|h| scene.bsdf(h) as *const dyn lumis::bsdf::Bsdf as *const ())
                            .collect();
                        mixed_materials += bsdfs.windows(2).any(|w| w[0] != w[1]) as u32;
                    }
                }
            }
        }
    }
    // The packets cover what the batched path must handle: runs of different BSDFs, and
    // samples without a shading point.
    assert!(compared > 10_000, "{compared} packets");
    assert!(
        mixed_materials > 100,
        "{mixed_materials} packets with several materials"
    );
    assert!(with_misses > 100, "{with_misses} packets with misses");
}

/// The render loop's packets span pixels (a pixel's camera samples, then the next pixel's, up
/// to `PACKET_SIZE`), yet each pixel gets what shading its own samples one by one in index order
/// gives, bit for bit: its colour, halves, weight, count and the integrator's sums (the AOVs'
/// statistics, added one by one by the MIS family; without AOVs its packets are drawn
/// together). Two passes with per-pixel budgets: pixels of 0 to 3 samples in the first pass and
/// 0 to 4 more in the second, on a film of several tiles.
#[test]
fn packets_across_pixels_give_each_pixel_its_own_sums() {
    use lumis::integrator::CameraSample;
    use lumis::passes::{Budget, PixelPasses, PlannedPass, give, sample_weight};
    let path = repo_path("scenes/cornell.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    let film = ["film.width=20", "film.height=10"];
    let loaded = common::load(&path, &film).unwrap();
    let scene = &loaded.scene;
    let pool = lumis::render::thread_pool(2).unwrap();
    // Pixel p's samples after pass k, and the samples planned from pass k on (at least one).
    let ends = |p: usize| [(p % 4) as u32, (p % 4 + p % 5) as u32];
    let planned = |p: usize, k: usize| [ends(p)[1] + 1, (p % 5).max(1) as u32][k] as u64;
    let mass = 8.0;
    let luminance = |c: lumis::math::Rgb| {
        0.212_671 * c.x as f64 + 0.715_160 * c.y as f64 + 0.072_169 * c.z as f64
    };
    let mut compared = 0;
    for (kind, aovs) in [("balance", true), ("balance", false), ("alpha", true)] {
        let aov_list = aov_override(aovs);
        let overrides: Vec<String> = film
            .iter()
            .map(|o| o.to_string())
            .chain([
                format!("integrator.type={kind}"),
                "integrator.samples=4".into(),
                aov_list,
            ])
            .collect();
        let description = lumis::scene::load::parse_description(&path, &text, &overrides).unwrap();
        let mut integrator =
            lumis::scene::load::build_integrator(&description.integrator, path.parent().unwrap())
                .unwrap();
        integrator.preprocess(scene);
        let stride = integrator.pixel_sums(scene);
        assert_eq!(stride > 0, aovs, "{kind}: sums with AOVs only");
        let mut sums = lumis::render::FilmSums::new(scene, stride, true);
        let pixels = sums.samples.len();
        for k in 0..2 {
            let budget = Budget {
                mass,
                pixels: PixelPasses::PerPixel(
                    (0..pixels)
                        .map(|p| PlannedPass {
                            end: ends(p)[k],
                            planned: planned(p, k),
                        })
                        .collect(),
                ),
            };
            let cancel = AtomicBool::new(false);
            let shard = lumis::render::Shard::WHOLE;
            let stats = lumis::render::render_pass(
                scene,
                integrator.as_ref(),
                &pool,
                shard,
                &mut sums,
                &budget,
                &|_| {},
                &cancel,
            );
            assert_eq!(stats.pixels_done, pixels as u64);
        }
        for p in 0..pixels {
            let row = sums.row_index(p) as u32;
            let pixel = glam::UVec2::new(row % scene.width, row / scene.width);
            let (mut own, mut color, mut halves) = (vec![0.0; stride], glam::DVec3::ZERO, [0.0; 2]);
            let (mut given, mut start) = (0.0, 0);
            for k in 0..2 {
                let end = ends(p)[k];
                let u = sample_weight(mass, given, planned(p, k));
                for index in start..end {
                    let mut sample = CameraSample::new(scene, pixel, index);
                    let r = integrator.shade(scene, &mut sample, &mut own) * sample.weight;
                    color += r.as_dvec3() * u;
                    halves[(index & 1) as usize] += u * luminance(r);
                }
                if end > start {
                    given = give(given, u, end - start);
                }
                start = end;
            }
            let name = format!("{kind}, AOVs {aovs}, pixel {pixel}");
            let bits = |v: &[f64]| -> Vec<u64> { v.iter().map(|x| x.to_bits()).collect() };
            assert_eq!(sums.samples[p], start, "{name}: samples");
            assert_eq!(
                bits(&sums.sums[p * stride..(p + 1) * stride]),
                bits(&own),
                "{name}: sums"
            );
            assert_eq!(
                bits(&sums.color[p].to_array()),
                bits(&color.to_array()),
                "{name}"
            );
            assert_eq!(bits(&sums.halves[p]), bits(&halves), "{name}: halves");
            assert_eq!(sums.weight[p].to_bits(), given.to_bits(), "{name}: weight");
            compared += u64::from(start > 0);
        }
    }
    // Most pixels have samples; some have none in a pass, or none at all.
    assert!(
        compared > 3 * 150,
        "{compared} pixels with samples compared"
    );
}

/// The override that asks the integrator for every AOV, or for none.
fn aov_override(all: bool) -> String {
    if all {
        format!("integrator.aovs={:?}", aovs::NAMES)
    } else {
        "integrator.aovs=[]".to_string()
    }
}
