//! The MIS integrator family: every registered integrator converges to the same image, `alpha`
//! finds the supplemental's limits in scenes, beats `balance` on the Veach layout, and `alpha`
//! with a fixed α reproduces `balance`, `bsdf` and `light` bit for bit.

mod common;
use common::{integrators, lumis, scene_file};
use lumis::integrators::{alpha, aovs, balance, bsdf, light, mis};
use std::path::{Path, PathBuf};

fn repo_path(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

fn render(path: &Path, overrides: &[String]) -> lumis::film::Film {
    let overrides: Vec<&str> = overrides.iter().map(String::as_str).collect();
    common::render(path, &overrides, 2)
}

/// Paired test of equal means: under "both unbiased" the per-pixel differences d_p are
/// independent with mean 0, so z = Σ d / √(Σ d²) is approximately standard normal.
fn z_statistic(a: &lumis::film::Film, b: &lumis::film::Film) -> f64 {
    let (mut sum, mut sum_sq) = (0.0f64, 0.0f64);
    for (x, y) in a.color.iter().zip(&b.color) {
        let d = (lumis::math::luminance(*x) - lumis::math::luminance(*y)) as f64;
        sum += d;
        sum_sq += d * d;
    }
    if sum_sq == 0.0 {
        0.0
    } else {
        sum / sum_sq.sqrt()
    }
}

/// A mirror sphere and a diffuse floor under the studio map.
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
    emitters: [(type: "envmap", file: {:?})],
)"#,
        repo_path("scenes/envmaps/studio.exr").to_str().unwrap()
    );
    scene_file("mirror.ron", &text)
}

#[test]
fn every_integrator_converges_to_the_same_mean() {
    let (_dir, mirror) = mirror_scene();
    let scenes = [
        ("diffuse + area lights", repo_path("scenes/cornell.ron")),
        ("glossy + env map", repo_path("scenes/envmap.ron")),
        ("mirror + env map", mirror),
        ("point + directional + area", repo_path("scenes/lights.ron")),
        ("Veach layout", repo_path("scenes/veach.ron")),
    ];
    // Every registered integrator with its defaults, and the paper's method in its other mode.
    let mut configurations: Vec<(String, Vec<String>)> = integrators()
        .into_iter()
        .map(|name| (name.to_string(), vec![]))
        .collect();
    configurations.push((
        format!("{} {}", alpha::NAME, alpha::PREPROCESSED),
        vec![
            format!("integrator.{}={}", alpha::MODE, alpha::PREPROCESSED),
            format!("integrator.{}=64", alpha::ALPHA_SAMPLES),
        ],
    ));
    for (name, path) in &scenes {
        let base = |seed: usize, integrator: &str| {
            vec![
                "film.width=24".to_string(),
                "film.height=18".to_string(),
                "sampler.spp=2".to_string(),
                format!("sampler.seed={seed}"),
                format!("integrator.type={integrator}"),
                format!("integrator.{}=16", mis::SAMPLES),
            ]
        };
        let reference = render(path, &base(100, balance::NAME));
        for (i, (integrator, extra)) in configurations.iter().enumerate() {
            let kind = integrator.split(' ').next().unwrap();
            let film = render(path, &[base(i, kind), extra.clone()].concat());
            assert!(
                film.color.iter().all(|c| c.is_finite()),
                "{name}: {integrator} is not finite"
            );
            let z = z_statistic(&film, &reference);
            assert!(
                z.abs() < 3.0,
                "{name}: {integrator} differs from balance by z = {z:.2}"
            );
        }
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
    use lumis::integrators::allocation::{LightSampling, PhaseBuffers, SampleSplit};
    use lumis::integrators::balance::Balance;
    use lumis::integrators::estimator::ShadingPoint;
    use lumis::integrators::phase::{Observer, Phase, PhaseRole};
    use lumis::integrators::weighting::PerSample;

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
    let sp = ShadingPoint::new(scene, scene.intersect(&ray).unwrap(), -ray.direction);
    let split = SampleSplit::new(0.3, 37);
    let mut buffers = PhaseBuffers::default();
    let draw = |buffers: &mut PhaseBuffers, light: usize| {
        let mut sampler = lumis::sampler::Sampler::new(5, 6, 7);
        let mut seen = Seen::default();
        let mut sampling = LightSampling::new(scene, &sp, light, pixel, 37, &mut sampler, buffers);
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
