//! The `path` integrator: direct lighting (`max_depth` 2, every light) is the direct
//! integrators' image bit for bit, for every weighting and allocation; a closed furnace gives
//! its closed form at every depth and unbounded; its extremes (depths 0, 1, 10⁶ and unbounded in
//! a box of mirrors, a light in a closed glass sphere) end, are finite and warn where they must.

use crate::common;
use common::scene_file;
use lumis::chi2::{FAMILY_FALSE_ALARM, sidak, test_seed, z_limit};
use lumis::integrators::{aovs, path};
use lumis::passes::{Settings, Stopping};
use lumis::progressive::{Control, RenderState, Scope};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

fn repo_path(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

fn render(path: &Path, overrides: &[String]) -> lumis::film::Film {
    let overrides: Vec<&str> = overrides.iter().map(String::as_str).collect();
    common::render(path, &overrides, 2)
}

/// Each direct integrator (with its parameters) and the `path` configuration that must give its
/// image: the same N, the same split and the same weights at the first vertex, nothing beyond.
fn direct_and_path_pairs() -> Vec<(Vec<&'static str>, Vec<&'static str>)> {
    let direct = |s: &[&'static str]| s.to_vec();
    vec![
        (
            direct(&["type=balance"]),
            direct(&["weighting=\"balance\""]),
        ),
        (direct(&["type=power"]), direct(&["weighting=\"power\""])),
        (direct(&["type=max"]), direct(&["weighting=\"max\""])),
        (
            direct(&["type=cutoff", "threshold=0.3"]),
            direct(&["weighting=\"cutoff\"", "threshold=0.3"]),
        ),
        (
            direct(&["type=bsdf"]),
            direct(&["weighting=\"balance\"", "fixed=1"]),
        ),
        (
            direct(&["type=light"]),
            direct(&["weighting=\"balance\"", "fixed=0"]),
        ),
        (
            direct(&["type=optimal_mis", "mode=\"progressive\""]),
            direct(&["weighting=\"optimal_mis\""]),
        ),
        (
            direct(&["type=alpha"]),
            direct(&["weighting=\"balance\"", "allocation=\"alpha\""]),
        ),
        (
            direct(&["type=alpha", "mode=\"preprocessed\"", "alpha_samples=24"]),
            direct(&[
                "weighting=\"balance\"",
                "allocation=\"alpha\"",
                "mode=\"preprocessed\"",
                "alpha_samples=24",
            ]),
        ),
        (
            direct(&["type=exact_alpha", "variance=\"stratified\""]),
            direct(&[
                "weighting=\"balance\"",
                "allocation=\"exact_alpha\"",
                "variance=\"stratified\"",
            ]),
        ),
        (
            direct(&["type=cost_alpha", "cost_ratio=2"]),
            direct(&[
                "weighting=\"balance\"",
                "allocation=\"cost_alpha\"",
                "cost_ratio=2",
            ]),
        ),
        (
            direct(&["type=pooled_alpha"]),
            direct(&["weighting=\"balance\"", "allocation=\"pooled_alpha\""]),
        ),
        (
            direct(&["type=variance_aware", "block=4"]),
            direct(&["allocation=\"variance_aware\"", "block=4"]),
        ),
    ]
}

fn bits(film: &lumis::film::Film) -> (Vec<[u32; 3]>, Vec<u32>) {
    (
        film.color
            .iter()
            .map(|c| c.to_array().map(f32::to_bits))
            .collect(),
        film.aov_data.iter().map(|v| v.to_bits()).collect(),
    )
}

/// `path` with `max_depth` 2 and `lights: all` is direct lighting with its first vertex's
/// method: every direct integrator's image (and AOVs) bit for bit, on scenes with area, point,
/// directional and environment lights and mirrors.
#[test]
fn direct_lighting_is_the_direct_integrators_image_bit_for_bit() {
    let scenes = [
        "scenes/cornell.ron",
        "scenes/lights.ron",
        "scenes/envmap.ron",
        "scenes/veach.ron",
    ];
    let mut compared = 0;
    for scene in scenes {
        let file = repo_path(scene);
        for (k, (direct, path_params)) in direct_and_path_pairs().into_iter().enumerate() {
            // AOVs with one method in three (they are sums over the same phases).
            let aov_list = if k % 3 == 0 {
                format!(
                    "[{:?}, {:?}, {:?}]",
                    aovs::ALPHA,
                    aovs::SAMPLING_VARIANCE,
                    aovs::SAMPLE_COUNTS
                )
            } else {
                "[]".to_string()
            };
            let base = [
                "film.width=20".to_string(),
                "film.height=14".to_string(),
                "sampler.spp=3".to_string(),
            ];
            let mut direct_set: Vec<String> = base.to_vec();
            direct_set.push("integrator=(type: \"balance\")".into());
            direct_set.extend(direct.iter().map(|p| format!("integrator.{p}")));
            direct_set.push("integrator.samples=8".into());
            direct_set.push(format!("integrator.aovs={aov_list}"));
            let mut path_set: Vec<String> = base.to_vec();
            path_set.push(format!("integrator=(type: {:?})", path::NAME));
            path_set.push(format!("integrator.{}=2", path::MAX_DEPTH));
            path_set.extend(path_params.iter().map(|p| format!("integrator.{p}")));
            path_set.push("integrator.samples=8".into());
            path_set.push(format!("integrator.aovs={aov_list}"));
            let expected = render(&file, &direct_set);
            let got = render(&file, &path_set);
            assert_eq!(
                expected.aovs, got.aovs,
                "{scene}: {direct:?}: the same layers"
            );
            assert!(
                bits(&expected) == bits(&got),
                "{scene}: {direct:?} and path {path_params:?} differ"
            );
            compared += 1;
        }
    }
    assert_eq!(compared, 4 * direct_and_path_pairs().len());
}

/// A closed box whose inside emits L_e and reflects diffusely with albedo ρ, seen from inside:
/// the radiance everywhere is L_e Σ_{k<d} ρ^k = L_e (1 − ρ^d)/(1 − ρ) with paths of at most d
/// segments (`max_depth` d, Mitsuba's convention: d = 1 the emission seen, d = 2 one
/// reflection more), and L_e/(1 − ρ) unbounded.
fn furnace_scene(rho: f64) -> String {
    format!(
        r#"Scene(
    camera: (position: (0.1, 0.2, -0.3), target: (0.5, 0.3, 1), fov: 90),
    film: (width: 16, height: 16),
    sampler: (spp: 64, seed: 1),
    integrator: (type: "path"),
    bsdfs: {{ "grey": (type: "diffuse", reflectance: {rho}) }},
    shapes: [
        (type: "cube", bsdf: "grey", emitter: (type: "area", radiance: 1, two_sided: true)),
    ],
)"#
    )
}

/// The furnace's closed form at every depth tested, for two weightings and both light
/// selections (one light: the box is one light, chosen with probability 1, but through the
/// selection's code), with Russian roulette from the default depth 5. Each case's 256 pixels are
/// independent estimates of the same radiance: their mean is tested against the closed form
/// (Student's t, Šidák over the cases at the suite's rate), and the test must detect a 1 % bias
/// with probability 0.9.
#[test]
fn a_furnace_gives_its_closed_form_at_every_depth_and_unbounded() {
    let rho = 0.6;
    let (_dir, file) = scene_file("furnace.ron", &furnace_scene(rho));
    let mut cases = Vec::new();
    for depth in [1i64, 2, 3, 7, -1] {
        for (weighting, lights) in [
            ("balance", "all"),
            ("power", "one"),
            ("max", "all"),
            ("cutoff", "one"),
            ("optimal_mis", "all"),
        ] {
            cases.push((depth, weighting, lights));
        }
    }
    let alpha = sidak(FAMILY_FALSE_ALARM, cases.len());
    let limit = z_limit(alpha);
    let mut failures = Vec::new();
    for (i, &(depth, weighting, lights)) in cases.iter().enumerate() {
        let expected = if depth < 0 {
            1.0 / (1.0 - rho)
        } else {
            (1.0 - rho.powi(depth as i32)) / (1.0 - rho)
        };
        let film = render(
            &file,
            &[
                format!("integrator.{}={depth}", path::MAX_DEPTH),
                format!("integrator.{}={weighting:?}", path::WEIGHTING),
                format!("integrator.{}={lights:?}", path::LIGHTS),
                format!("sampler.seed={}", test_seed() * 100 + i as u64),
                // Russian roulette adds variance: more samples unbounded. At 64 spp the
                // detectable bias at depth 2 sat at 1.00 % under seed 2; 100 gives a margin.
                format!("sampler.spp={}", if depth < 0 { 256 } else { 100 }),
            ],
        );
        let values: Vec<f64> = film.color.iter().map(|c| c.x as f64).collect();
        let (mean, se) = common::mean_and_standard_error(&values);
        // At depth 1 every pixel is the emission exactly.
        let se = se.max(4.0 * f32::EPSILON as f64 * expected);
        let z = (mean - expected) / se;
        let detected = (limit + 1.281_551_6) * se / expected;
        eprintln!(
            "furnace ρ = {rho}, max_depth {depth}, {weighting}, lights {lights}: {mean:.5} ± \
             {se:.5}, closed form {expected:.5} (z = {z:+.2}, limit {limit:.2}); detects {:.2} %",
            100.0 * detected
        );
        if z.abs() >= limit || !z.is_finite() {
            failures.push(format!(
                "max_depth {depth}, {weighting}, lights {lights}: {mean} ± {se} vs {expected} \
                 (z = {z:.2}, seed {})",
                test_seed()
            ));
        }
        if detected > 0.01 {
            failures.push(format!(
                "max_depth {depth}: the test detects only biases above {:.2} %",
                100.0 * detected
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A closed box of perfect mirrors around a small light: at `max_depth` 0 black, at 1 only
/// the light seen directly, and unbounded (Russian roulette from the default depth, or from a
/// depth no path reaches: then the hard cap of `path::MAX_VERTICES` vertices ends it) the
/// render ends and every pixel is finite.
#[test]
fn a_box_of_mirrors_ends_at_every_depth() {
    let text = r#"Scene(
    camera: (position: (0.3, 0.2, -0.5), target: (0, 0, 1), fov: 70),
    film: (width: 12, height: 8),
    sampler: (spp: 2, seed: 5),
    integrator: (type: "path"),
    bsdfs: { "mirror": (type: "mirror"), "white": (type: "diffuse", reflectance: 0.8) },
    shapes: [
        (type: "cube", bsdf: "mirror"),
        (type: "sphere", bsdf: "white", center: (0, 0, 0.5), radius: 0.1,
         emitter: (type: "area", radiance: 1)),
    ],
)"#;
    let (_dir, file) = scene_file("mirrors.ron", text);
    for (max_depth, rr_depth) in [
        (0i64, 5i64),
        (1, 5),
        (-1, 5),
        (1_000_000, 5),
        (-1, 2147483647),
    ] {
        let started = std::time::Instant::now();
        let film = render(
            &file,
            &[
                format!("integrator.{}={max_depth}", path::MAX_DEPTH),
                format!("integrator.{}={rr_depth}", path::RR_DEPTH),
            ],
        );
        common::assert_finite_outputs(&film, &format!("max_depth {max_depth}"));
        let total: f32 = film.color.iter().map(|c| c.x).sum();
        eprintln!(
            "mirror box, max_depth {max_depth}, rr_depth {rr_depth}: sum {total}, {:?}",
            started.elapsed()
        );
        match max_depth {
            0 => assert_eq!(total, 0.0, "max_depth 0 is black"),
            // The light seen directly: radiance 1 or 0 in each pixel's samples.
            1 => assert!(film.color.iter().all(|c| c.x <= 1.0 + 1e-6)),
            // The mirrors show the light again and again: more than the light alone.
            _ => assert!(total > 0.0),
        }
    }
}

/// The only light a point inside a closed glass sphere: no path can reach it (a point is never
/// hit, and light sampling through glass is blocked), so the image is black by design, and the
/// scene's load says no light is likely to reach the camera.
#[test]
fn a_point_light_inside_closed_glass_is_black_with_a_warning() {
    let text = r#"Scene(
    camera: (position: (0, 1, -4), target: (0, 0, 0), fov: 40),
    film: (width: 16, height: 12),
    sampler: (spp: 4, seed: 2),
    integrator: (type: "path"),
    bsdfs: { "glass": (type: "dielectric"), "white": (type: "diffuse", reflectance: 0.8) },
    shapes: [
        (type: "sphere", bsdf: "glass", center: (0, 0, 0), radius: 1),
        (type: "rectangle", bsdf: "white", transform: (scale: (10, 10, 1), translate: (0, -1, 0),
         rotate: [(axis: (1, 0, 0), angle: -90)])),
    ],
    emitters: [(type: "point", position: (0, 0, 0), intensity: 10)],
)"#;
    let (_dir, file) = scene_file("glass.ron", text);
    let loaded = common::load(&file, &[]).expect("loads");
    assert!(
        loaded.warnings.iter().any(|w| w.contains("no light")),
        "{:?}",
        loaded.warnings
    );
    let film = render(&file, &[]);
    assert!(film.color.iter().all(|c| *c == glam::Vec3::ZERO));
}

/// Mitsuba's `path` (inside `moment`) converts to lumis' `path` with its depths and
/// `hide_emitters`, and Mitsuba's estimator (one light per vertex, power heuristic); the three
/// dielectrics convert with their named and numeric indices and roughness, emitters with their
/// `sampling_weight`; what lumis does not
/// take (an index beyond its range, an unknown name, anisotropic roughness) is named with its line.
#[test]
fn mitsuba_path_and_dielectrics_convert() {
    let xml = r#"<scene version="3.0.0">
    <integrator type="moment">
        <integrator type="path">
            <integer name="max_depth" value="7"/>
            <integer name="rr_depth" value="3"/>
            <boolean name="hide_emitters" value="true"/>
        </integrator>
    </integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film>
    </sensor>
    <shape type="sphere">
        <bsdf type="dielectric"><string name="int_ior" value="water"/><float name="ext_ior" value="1"/></bsdf>
    </shape>
    <shape type="sphere">
        <point name="center" x="2" y="0" z="0"/>
        <bsdf type="roughdielectric">
            <string name="distribution" value="ggx"/>
            <float name="alpha" value="0.25"/>
            <boolean name="sample_visible" value="false"/>
        </bsdf>
    </shape>
    <shape type="sphere">
        <point name="center" x="-2" y="0" z="0"/>
        <bsdf type="thindielectric"><float name="int_ior" value="1.4"/></bsdf>
    </shape>
    <emitter type="point">
        <point name="position" x="0" y="3" z="0"/><float name="sampling_weight" value="3"/>
    </emitter>
</scene>
"#;
    let (dir, _) = scene_file("glass.xml", xml);
    let out = common::lumis(dir.path(), &["import", "glass.xml", "-o", "glass.ron"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("`sample_visible` is dropped"), "{stderr}");
    let ron = std::fs::read_to_string(dir.path().join("glass.ron")).unwrap();
    for needle in [
        r#"type: "path""#,
        "max_depth: 7",
        "rr_depth: 3",
        "hide_emitters: true",
        r#"lights: "one""#,
        r#"weighting: "power""#,
        r#"type: "dielectric""#,
        r#"int_ior: "water""#,
        r#"type: "roughdielectric""#,
        r#"distribution: "ggx""#,
        "alpha: 0.25",
        r#"type: "thindielectric""#,
        "int_ior: 1.4",
        "sampling_weight: 3",
    ] {
        assert!(ron.contains(needle), "`{needle}` missing in:\n{ron}");
    }
    let film = render(&dir.path().join("glass.ron"), &[]);
    common::assert_finite_outputs(&film, "converted glass");

    let bad = r#"<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="-2"/></integrator>
    <shape type="sphere"><bsdf type="dielectric"><float name="int_ior" value="1e9"/></bsdf></shape>
    <shape type="sphere"><bsdf type="dielectric"><string name="ext_ior" value="glass"/></bsdf></shape>
    <shape type="sphere"><bsdf type="roughdielectric">
        <float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.3"/>
    </bsdf></shape>
</scene>
"#;
    let (dir, _) = scene_file("bad.xml", bad);
    let out = common::lumis(dir.path(), &["import", "bad.xml", "-o", "bad.ron"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    for needle in [
        "bad.xml:2: `max_depth` must be an integer of at least -1",
        "bad.xml:3: `int_ior` 1000000000 is outside lumis' [0.000001, 1000000]",
        "bad.xml:4: `ext_ior`: unknown index of refraction `glass`",
        "anisotropic roughness is not converted",
    ] {
        assert!(stderr.contains(needle), "`{needle}` missing in:\n{stderr}");
    }
}

/// Every weighting, the paper's α at the first vertex, and one light per vertex converge to the
/// mean of `path` with the balance heuristic on the Cornell box with its indirect light
/// (`max_depth` 4: three bounces), by the repo's same-mean test (whole image and blocks, power
/// required: a 2 % bias detected with probability 0.9; tests/integrators.rs).
#[test]
fn every_weighting_gives_the_same_mean_with_indirect_light() {
    let file = repo_path("scenes/cornell.ron");
    let path_with = |extra: &[String]| -> Vec<String> {
        [
            vec![
                format!("integrator.type={}", path::NAME),
                format!("integrator.{}=4", path::MAX_DEPTH),
                format!("integrator.{}=4", path::DEEP_SAMPLES),
            ],
            extra.to_vec(),
        ]
        .concat()
    };
    let weighting = |w: &str| format!("integrator.{}={w:?}", path::WEIGHTING);
    let reference = path_with(&[weighting("balance")]);
    // `optimal_mis` has its own test on image means: its per-pixel variance estimate at deeper
    // vertices is heavy-tailed, and under seed 2 this one could detect only a 4.65 % bias in it.
    let mut configurations: Vec<(String, Vec<String>)> = ["power", "max", "cutoff"]
        .into_iter()
        .map(|w| (format!("path {w}"), path_with(&[weighting(w)])))
        .collect();
    configurations.push((
        "path power, one light".into(),
        path_with(&[
            weighting("power"),
            format!("integrator.{}={:?}", path::LIGHTS, path::ONE),
        ]),
    ));
    configurations.push((
        "path balance, alpha at the first vertex".into(),
        path_with(&[
            weighting("balance"),
            format!("integrator.{}=\"alpha\"", path::ALLOCATION),
        ]),
    ));
    crate::integrators::same_mean(
        "Cornell box, max_depth 4",
        &file,
        16,
        &reference,
        &configurations,
        0.02,
        crate::integrators::RUNS,
    );
}

/// `hide_emitters`: an area light filling the view, facing the camera in front of a white wall
/// it does not light, shows its radiance, and nothing when hidden (camera rays pass through it,
/// as Mitsuba's do, to the unlit wall).
#[test]
fn hidden_emitters_are_seen_through() {
    let text = r#"Scene(
    camera: (position: (0, 0, -3), target: (0, 0, 0), fov: 20),
    film: (width: 8, height: 8),
    sampler: (spp: 2, seed: 4),
    integrator: (type: "path"),
    bsdfs: { "white": (type: "diffuse", reflectance: 0.8) },
    shapes: [
        (type: "rectangle", bsdf: "white", transform: (scale: (5, 5, 1), rotate: [(axis: (0, 1, 0), angle: 180)]),
         emitter: (type: "area", radiance: 2)),
        (type: "rectangle", bsdf: "white", transform: (scale: (9, 9, 1), translate: (0, 0, 1),
         rotate: [(axis: (0, 1, 0), angle: 180)])),
    ],
)"#;
    let (_dir, file) = scene_file("hidden.ron", text);
    let seen = render(&file, &[]);
    assert!(
        seen.color.iter().all(|c| (c.x - 2.0).abs() < 1e-5),
        "the light seen: {:?}",
        &seen.color[..4]
    );
    let hidden = render(&file, &[format!("integrator.{}=true", path::HIDE_EMITTERS)]);
    assert!(
        hidden.color.iter().all(|c| *c == glam::Vec3::ZERO),
        "hidden: {:?}",
        &hidden.color[..4]
    );
}

/// The `depth_samples` layer counts the samples drawn at each vertex depth, summed over a
/// pixel's camera samples: N = `samples` per non-delta light at vertex 1, `deep_samples` per
/// light at vertex 2, nothing at vertex 3 and deeper with `max_depth` 3 (vertex 3 only ends
/// paths of 3 segments).
#[test]
fn depth_samples_count_each_vertex_depth() {
    let file = repo_path("scenes/cornell.ron");
    let (spp, samples, deep) = (2.0f32, 8.0f32, 4.0f32);
    let film = render(
        &file,
        &[
            "film.width=16".into(),
            "film.height=12".into(),
            format!("sampler.spp={spp}"),
            format!("integrator=(type: {:?})", path::NAME),
            format!("integrator.{}=3", path::MAX_DEPTH),
            format!("integrator.samples={samples}"),
            format!("integrator.{}={deep}", path::DEEP_SAMPLES),
            format!("integrator.aovs=[{:?}]", path::DEPTH_SAMPLES),
        ],
    );
    let channels = film.aov(path::DEPTH_SAMPLES).expect("the layer").channels();
    assert_eq!(channels.len(), 8);
    let first_max = channels[0].iter().cloned().fold(0.0, f32::max);
    let lights = first_max / (spp * samples);
    assert!(lights >= 1.0 && lights.fract() == 0.0, "{first_max}");
    for (d1, d2) in channels[0].iter().zip(&channels[1]) {
        // Each camera sample meets a surface (N per light there) or leaves the scene.
        assert!(
            (d1 / (samples * lights)).fract() == 0.0 && *d1 <= first_max,
            "{d1}"
        );
        assert!(
            (d2 / (deep * lights)).fract() == 0.0 && *d2 <= spp * deep * lights,
            "{d2}"
        );
    }
    assert!(channels[1].iter().any(|&d2| d2 > 0.0));
    assert!(channels[2..].iter().flatten().all(|&d| d == 0.0));
}

/// `scene` rendered with `overrides` in `passes` uniform passes of `spp` samples in all, on
/// `threads` threads, as `lumis render --passes` does: each pass's `begin_pass` sees the passes
/// before it (a learned α at the deeper vertices reads them).
fn render_in_passes(
    file: &Path,
    overrides: &[String],
    spp: u32,
    passes: u32,
    threads: usize,
) -> lumis::film::Film {
    let overrides: Vec<&str> = overrides.iter().map(String::as_str).collect();
    let mut loaded =
        common::load(file, &overrides).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let settings = Settings {
        stopping: Stopping::Samples { spp, passes },
        ..Settings::samples(spp)
    };
    loaded.integrator.preprocess(&loaded.scene);
    let mut state = RenderState::new(&loaded.scene, loaded.integrator.as_ref(), &settings);
    lumis::progressive::run(
        &loaded.scene,
        loaded.integrator.as_mut(),
        &settings,
        &mut state,
        Scope::whole(threads),
        &AtomicBool::new(false),
        &|_| {},
        &mut |_| Control::Continue,
    )
    .expect("render");
    state
        .sums
        .resolve(&loaded.scene, loaded.integrator.as_ref())
}

/// Each render's image mean per channel, over `runs` seeds from `first`.
fn image_means(
    file: &Path,
    overrides: &[String],
    (spp, passes): (u32, u32),
    seeds: std::ops::Range<u64>,
) -> Vec<[f64; 3]> {
    seeds
        .map(|seed| {
            let mut set = overrides.to_vec();
            set.push(format!("sampler.seed={seed}"));
            let film = render_in_passes(file, &set, spp, passes, 2);
            let n = film.color.len() as f64;
            let sum = film.color.iter().fold([0.0f64; 3], |acc, c| {
                [
                    acc[0] + c.x as f64,
                    acc[1] + c.y as f64,
                    acc[2] + c.z as f64,
                ]
            });
            sum.map(|s| s / n)
        })
        .collect()
}

/// The same-mean test on image means: each configuration's renders (independent seeds, in
/// passes) against the reference's, per channel, by Welch's t on the renders' image means
/// (each the mean of many pixels: near normal even where single pixels are heavy-tailed, as
/// `optimal_mis`'s deeper vertices make them), Šidák over channels and configurations at the
/// suite's rate. Power required: a relative bias of `detectable` found with probability 0.9.
fn same_image_mean(
    name: &str,
    file: &Path,
    (spp, passes, runs): (u32, u32, u64),
    reference: &[String],
    configurations: &[(String, Vec<String>)],
    detectable: f64,
) {
    use lumis::same_mean::{Z_POWER_90, t_limit};
    let first = test_seed() * 1_000_000 + 500_000;
    let reference_means = image_means(file, reference, (spp, passes), first..first + runs);
    let alpha = sidak(FAMILY_FALSE_ALARM, 3 * configurations.len());
    let moments = |values: &[[f64; 3]], c: usize| {
        let n = values.len() as f64;
        let mean = values.iter().map(|v| v[c]).sum::<f64>() / n;
        let var = values.iter().map(|v| (v[c] - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, var / n)
    };
    let mut failures = Vec::new();
    for (i, (label, extra)) in configurations.iter().enumerate() {
        let seeds = first + 1000 * (i as u64 + 1);
        let tested = image_means(file, extra, (spp, passes), seeds..seeds + runs);
        for c in 0..3 {
            let (m_ref, v_ref) = moments(&reference_means, c);
            let (m, v) = moments(&tested, c);
            let se = (v + v_ref).sqrt();
            let nu = (v + v_ref).powi(2)
                / (v * v / (runs as f64 - 1.0) + v_ref * v_ref / (runs as f64 - 1.0));
            let limit = t_limit(alpha, nu);
            let t = (m - m_ref) / se;
            let detected = (limit + Z_POWER_90) * se / m_ref;
            eprintln!(
                "{name}: {label}, channel {c}: {m:.5} vs {m_ref:.5} (relative {:+.3} % ± {:.3} %, \
                 t = {t:+.2}, ν = {nu:.0}, limit {limit:.2}); detects {:.2} % with probability 0.9",
                100.0 * (m / m_ref - 1.0),
                100.0 * se / m_ref,
                100.0 * detected
            );
            if t.abs() >= limit || !t.is_finite() {
                failures.push(format!(
                    "{name}: {label}, channel {c}: {m} vs {m_ref} (t = {t:.2}, limit {limit:.2}, \
                     seed {})",
                    test_seed()
                ));
            }
            if detected > detectable {
                failures.push(format!(
                    "{name}: {label}, channel {c}: the test detects only biases above {:.2} %",
                    100.0 * detected
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The Cornell box with three bounces (`max_depth` 4), small.
fn cornell_path(extra: &[&str]) -> Vec<String> {
    let mut set = vec![
        "film.width=24".to_string(),
        "film.height=18".to_string(),
        "sampler.jitter=false".to_string(),
        format!("integrator=(type: {:?})", path::NAME),
        format!("integrator.{}=4", path::MAX_DEPTH),
    ];
    set.extend(extra.iter().map(|s| format!("integrator.{s}")));
    set
}

/// `optimal_mis` at every vertex gives `path` balance's mean on the Cornell box with its
/// indirect light: with N = 16 at the first vertex and 4 past it (its progressive estimator at
/// every vertex), and with 4 and 2 (balance past the first: the direct estimator there read
/// 40–80 % high, its fit interpolating the vertex's two samples). Its pixels are heavy-tailed
/// (the per-pixel test could detect only 4.65 % under one seed), so the test compares renders'
/// image means instead (tests [`same_image_mean`]), with power: 2 % detected with probability
/// 0.9.
#[test]
fn optimal_mis_gives_the_same_mean_with_indirect_light() {
    let file = repo_path("scenes/cornell.ron");
    let optimal = |samples: &str, deep: &str| {
        (
            format!("path optimal_mis, {samples}, {deep}"),
            cornell_path(&["weighting=\"optimal_mis\"", samples, deep]),
        )
    };
    same_image_mean(
        "Cornell box, max_depth 4",
        &file,
        (16, 1, 12),
        &cornell_path(&["weighting=\"balance\"", "samples=16", "deep_samples=4"]),
        &[
            optimal("samples=16", "deep_samples=4"),
            optimal("samples=4", "deep_samples=2"),
        ],
        0.02,
    );
}

/// `optimal_mis` makes its own split of each vertex's samples (its progressive estimator):
/// with another allocation, `path` names the conflict rather than weigh that allocation's
/// phases with the direct estimator, whose bias stays in a path's image.
#[test]
fn optimal_mis_refuses_another_allocation() {
    let file = repo_path("scenes/cornell.ron");
    let overrides = cornell_path(&["weighting=\"optimal_mis\"", "allocation=\"alpha\""]);
    let overrides: Vec<&str> = overrides.iter().map(String::as_str).collect();
    let message = common::load(&file, &overrides)
        .err()
        .expect("optimal_mis with the alpha allocation refused")
        .to_string();
    assert!(
        message.contains("path") && message.contains("`allocation` \"fixed\" only, not \"alpha\""),
        "{message}"
    );
}

/// The one-sample mixture at the deeper vertices (α fixed, learned from the earlier passes by
/// the second moment, or practical path guiding's fraction) gives plain `path`'s mean on the
/// Cornell box with its indirect light, rendered in 4 passes (the learned α from the second on;
/// a coarse cache, so that its cells have the samples to learn), with power: a 1.5 % bias
/// detected with probability 0.9.
#[test]
fn the_deeper_mixture_gives_the_same_mean_with_indirect_light() {
    let file = repo_path("scenes/cornell.ron");
    let deep = |mode: &str| format!("{}={mode:?}", path::DEEP_ALLOCATION);
    let configurations: Vec<(String, Vec<String>)> = [
        (path::MIXTURE, "fixed=0.3"),
        (path::LEARNED, "cache_resolution=4"),
        (path::GUIDING_FRACTION, "cache_resolution=4"),
    ]
    .into_iter()
    .map(|(mode, extra)| {
        (
            format!("path, {mode} ({extra})"),
            cornell_path(&[&deep(mode), extra]),
        )
    })
    .collect();
    same_image_mean(
        "Cornell box, max_depth 4, 4 passes",
        &file,
        (16, 4, 32),
        &cornell_path(&[]),
        &configurations,
        0.015,
    );
}

/// The furnace's closed form with the one-sample mixture at the deeper vertices (fixed α at
/// both ends of its range, and both learned α in 4 passes): the mixture's weight f / q_α must
/// use the density its directions are drawn with, or the closed form is missed.
#[test]
fn the_deeper_mixture_gives_the_furnace_closed_form() {
    let rho = 0.6;
    let (_dir, file) = scene_file("furnace.ron", &furnace_scene(rho));
    let cases = [
        (3i64, path::MIXTURE, "fixed=0.1"),
        (3, path::MIXTURE, "fixed=0.9"),
        (-1, path::MIXTURE, "fixed=0.5"),
        (3, path::LEARNED, "cache_resolution=2"),
        (-1, path::LEARNED, "cache_resolution=2"),
        (-1, path::GUIDING_FRACTION, "cache_resolution=2"),
    ];
    let limit = z_limit(sidak(FAMILY_FALSE_ALARM, cases.len()));
    let mut failures = Vec::new();
    for (i, &(depth, mode, extra)) in cases.iter().enumerate() {
        let expected = if depth < 0 {
            1.0 / (1.0 - rho)
        } else {
            (1.0 - rho.powi(depth as i32)) / (1.0 - rho)
        };
        let film = render_in_passes(
            &file,
            &[
                format!("integrator.{}={depth}", path::MAX_DEPTH),
                format!("integrator.{}={mode:?}", path::DEEP_ALLOCATION),
                format!("integrator.{extra}"),
                format!("sampler.seed={}", test_seed() * 100 + 50 + i as u64),
            ],
            if depth < 0 { 256 } else { 100 },
            4,
            2,
        );
        let values: Vec<f64> = film.color.iter().map(|c| c.x as f64).collect();
        let (mean, se) = common::mean_and_standard_error(&values);
        let z = (mean - expected) / se;
        let detected = (limit + 1.281_551_6) * se / expected;
        eprintln!(
            "furnace ρ = {rho}, max_depth {depth}, {mode} {extra}: {mean:.5} ± {se:.5}, closed \
             form {expected:.5} (z = {z:+.2}, limit {limit:.2}); detects {:.2} %",
            100.0 * detected
        );
        if z.abs() >= limit || !z.is_finite() {
            failures.push(format!(
                "max_depth {depth}, {mode} {extra}: {mean} ± {se} vs {expected} (z = {z:.2}, \
                 seed {})",
                test_seed()
            ));
        }
        if detected > 0.01 {
            failures.push(format!(
                "max_depth {depth}, {mode}: the test detects only biases above {:.2} %",
                100.0 * detected
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A learned α at the deeper vertices is frozen for each pass from the passes before it, its
/// statistics summed as integers: the image is the same bit for bit on 1 and 2 threads (and
/// differs from the fixed mixture's, so that the cache is seen to act).
#[test]
fn the_learned_alpha_is_the_same_for_any_thread_count() {
    let file = repo_path("scenes/cornell.ron");
    for mode in [path::LEARNED, path::GUIDING_FRACTION] {
        let set = cornell_path(&[
            &format!("{}={mode:?}", path::DEEP_ALLOCATION),
            "cache_resolution=4",
        ]);
        let one = render_in_passes(&file, &set, 12, 3, 1);
        let two = render_in_passes(&file, &set, 12, 3, 2);
        assert!(bits(&one) == bits(&two), "{mode}: 1 and 2 threads differ");
        let fixed = render_in_passes(
            &file,
            &cornell_path(&[&format!("{}=\"mixture\"", path::DEEP_ALLOCATION)]),
            12,
            3,
            2,
        );
        assert!(
            bits(&one) != bits(&fixed),
            "{mode}: the cache changed nothing"
        );
    }
}

/// A measured BRDF (MERL table) seen and lit at grazing angles, under lights of extreme
/// radiance (1e12, the loader's largest, and 1e-30; a point light of intensity 1e12), at
/// `max_depth` 2 and unbounded, with the split and the mixture past the first vertex: every
/// pixel and AOV value is finite (an overflow in a vertex's estimate or throughput is
/// dropped, never written), and the image is not black.
#[test]
fn a_measured_brdf_at_grazing_angles_under_extreme_lights_stays_finite() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("m.binary");
    let spec = r#"(type: "glossy", roughness: 0.05, specular: (0.95, 0.64, 0.54), diffuse: 0.02)"#;
    let out = common::lumis(
        dir.path(),
        &["merl", "--bsdf", spec, "-o", table.to_str().unwrap()],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = r#"Scene(
    camera: (position: (0, 0.002, -6), target: (0, 0, 4), fov: 30),
    film: (width: 24, height: 16),
    sampler: (spp: 8, seed: 3),
    integrator: (type: "path"),
    bsdfs: { "m": (type: "measured", file: "m.binary"), "black": (type: "diffuse", reflectance: 0) },
    shapes: [
        (type: "rectangle", bsdf: "m",
            transform: (scale: (20, 20, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
        (type: "sphere", bsdf: "m", center: (0.4, 0.3, 1), radius: 0.3),
        (type: "rectangle", bsdf: "black",
            transform: (look_at: (origin: (0, 0.001, 8), target: (0, 0.001, 0)), scale: (4, 0.0005, 1)),
            emitter: (type: "area", radiance: 1e12)),
        (type: "sphere", bsdf: "m", center: (-0.5, 0.2, 2), radius: 0.2,
            emitter: (type: "area", radiance: 1e-30)),
    ],
    emitters: [(type: "point", position: (0, 0.0001, 3), intensity: 1e12)],
)"#;
    std::fs::write(dir.path().join("grazing.ron"), text).unwrap();
    let file = dir.path().join("grazing.ron");
    for (lights, deep) in [
        ("all", path::SPLIT),
        ("one", path::SPLIT),
        ("all", path::MIXTURE),
        ("one", path::LEARNED),
    ] {
        for depth in [2i64, -1] {
            let film = render_in_passes(
                &file,
                &[
                    format!("integrator.{}={depth}", path::MAX_DEPTH),
                    format!("integrator.{}={lights:?}", path::LIGHTS),
                    format!("integrator.{}={deep:?}", path::DEEP_ALLOCATION),
                    format!("integrator.aovs=[{:?}]", path::DEPTH_SAMPLES),
                ],
                8,
                2,
                2,
            );
            let name = format!("lights {lights}, {deep}, max_depth {depth}");
            common::assert_finite_outputs(&film, &name);
            assert!(
                film.color.iter().any(|c| c.max_element() > 0.0),
                "{name}: black"
            );
        }
    }
}

/// Two area lights and a point light over a diffuse room, with each emitter's
/// `sampling_weight` given by `weights`.
fn weighted_lights_scene(weights: [f32; 3]) -> String {
    format!(
        r#"Scene(
    camera: (position: (0, 1, -3.5), target: (0, 0.8, 0), fov: 50),
    film: (width: 24, height: 18),
    sampler: (spp: 16, seed: 0),
    integrator: (type: "path", lights: "one", max_depth: 4),
    bsdfs: {{ "white": (type: "diffuse", reflectance: 0.7), "black": (type: "diffuse", reflectance: 0) }},
    shapes: [
        (type: "cube", bsdf: "white", transform: (scale: (2, 1, 4), translate: (0, 1, 0))),
        (type: "rectangle", bsdf: "black",
            transform: (scale: (0.3, 0.3, 1), rotate: [(axis: (1, 0, 0), angle: 90)], translate: (0.8, 1.98, 0.5)),
            emitter: (type: "area", radiance: 8, sampling_weight: {})),
        (type: "sphere", bsdf: "black", center: (-1, 0.4, 1), radius: 0.3,
            emitter: (type: "area", radiance: 5, sampling_weight: {})),
    ],
    emitters: [(type: "point", position: (0, 1.5, -1), intensity: 2, sampling_weight: {})],
)"#,
        weights[0], weights[1], weights[2]
    )
}

/// `lights: one` with emitters' `sampling_weight`s (Mitsuba's) gives the mean of uniform
/// choice (image means over 24 renders each, a 2 % bias detected with probability 0.9: 1.32–1.71 %
/// at seeds 0–2, 1.40 % with 32 renders at seed 0); a weight of
/// 0 (so also a total weight of 0) or a negative one is an error naming the scene and the
/// emitter.
#[test]
fn sampling_weights_choose_lights_with_the_same_mean() {
    let (_dir, uniform) = scene_file("uniform.ron", &weighted_lights_scene([1.0, 1.0, 1.0]));
    let (_dir2, weighted) = scene_file("weighted.ron", &weighted_lights_scene([1.0, 4.0, 0.25]));
    let dir = _dir2.path().to_path_buf();
    let copy = |name: &str, weights: [f32; 3]| {
        let file = dir.join(name);
        std::fs::write(&file, weighted_lights_scene(weights)).unwrap();
        file
    };
    let first = test_seed() * 1_000_000 + 700_000;
    let runs = 24;
    let reference = image_means(&uniform, &[], (128, 1), first..first + runs);
    let alpha = sidak(FAMILY_FALSE_ALARM, 1);
    let tested = image_means(&weighted, &[], (128, 1), first + 1000..first + 1000 + runs);
    let (m, v) = mean_and_variance_of_mean(&tested);
    let (m_ref, v_ref) = mean_and_variance_of_mean(&reference);
    let se = (v + v_ref).sqrt();
    let nu = (v + v_ref).powi(2) / ((v * v + v_ref * v_ref) / (runs as f64 - 1.0));
    let limit = lumis::same_mean::t_limit(alpha, nu);
    let t = (m - m_ref) / se;
    let detected = (limit + lumis::same_mean::Z_POWER_90) * se / m_ref;
    eprintln!(
        "sampling_weight 1, 4, 0.25: {m:.5} vs uniform {m_ref:.5} (t = {t:+.2}, limit \
         {limit:.2}); detects {:.2} % with probability 0.9",
        100.0 * detected
    );
    assert!(t.abs() < limit, "t = {t}, seed {}", test_seed());
    assert!(detected <= 0.02, "detects only {:.2} %", 100.0 * detected);
    // A light of weight 0 would never be chosen, and `path` finds a light only through the
    // estimate of the light it chose: refused, so that no total weight is 0 either.
    for (name, weights, emitter) in [
        (
            "zero.ron",
            [2.0, 0.0, 1.0],
            "shapes[2] (sphere).emitter (area)",
        ),
        (
            "all_zero.ron",
            [0.0, 0.0, 0.0],
            "shapes[1] (rectangle).emitter (area)",
        ),
    ] {
        let message = common::load(&copy(name, weights), &[])
            .err()
            .expect("a weight of 0 refused")
            .to_string();
        assert!(
            message.contains(name) && message.contains(&format!("{emitter}: `sampling_weight`")),
            "{message}"
        );
    }
    let bad = copy("bad.ron", [1.0, 1.0, -2.0]);
    let message = common::load(&bad, &[])
        .err()
        .expect("a negative weight refused")
        .to_string();
    assert!(
        message.contains("bad.ron") && message.contains("emitters[0] (point): `sampling_weight`"),
        "{message}"
    );
}

/// The luminance of each render's image mean: its mean over the renders, and the variance of
/// that mean.
fn mean_and_variance_of_mean(values: &[[f64; 3]]) -> (f64, f64) {
    let y: Vec<f64> = values
        .iter()
        .map(|v| 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2])
        .collect();
    let (mean, se) = common::mean_and_standard_error(&y);
    (mean, se * se)
}

/// The one-sample mixture past the first vertex draws its directions with the density its
/// weight divides by, q_α = α p_B + (1 − α) p_J: χ² over the sphere of directions at a point
/// of a glossy floor lit by a sphere light and a rectangle light, for each light and α ∈ {0.2,
/// ½, 0.9} (Šidák over the cases at the suite's rate).
#[test]
fn the_mixture_samples_its_density() {
    use lumis::chi2::Chi2Test;
    use lumis::geometry::Ray;
    use lumis::integrators::shading_point::ShadingPoint;
    let text = r#"Scene(
    camera: (position: (0, 1, -3), target: (0, 0, 0), fov: 30),
    film: (width: 4, height: 4),
    integrator: (type: "path", deep_allocation: "mixture"),
    bsdfs: {
        "floor": (type: "glossy", roughness: 0.3, specular: 0.5, diffuse: 0.3),
        "black": (type: "diffuse", reflectance: 0),
    },
    shapes: [
        (type: "rectangle", bsdf: "floor",
            transform: (scale: (5, 5, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
        (type: "sphere", bsdf: "black", center: (0.5, 1.2, 0.6), radius: 0.4,
            emitter: (type: "area", radiance: 1)),
        (type: "rectangle", bsdf: "black",
            transform: (look_at: (origin: (-1, 1.5, 0.5), target: (0, 0, 0)), scale: (0.6, 0.3, 1)),
            emitter: (type: "area", radiance: 1)),
    ],
)"#;
    let (_dir, file) = scene_file("mixture.ron", text);
    let loaded = common::load(&file, &[]).expect("loads");
    let scene = &loaded.scene;
    let camera = glam::Vec3::new(0.0, 1.0, -3.0);
    let ray = Ray {
        origin: camera,
        direction: (glam::Vec3::new(0.1, 0.0, 0.05) - camera).normalize(),
        t_max: f32::INFINITY,
    };
    let hit = scene.geometry.intersect(&ray).expect("the floor");
    let sp = ShadingPoint::new(scene, &hit, -ray.direction);
    let cases: Vec<(usize, f64)> = (0..scene.emitters.len())
        .flat_map(|light| [0.2, 0.5, 0.9].map(|alpha| (light, alpha)))
        .collect();
    let alpha_test = sidak(FAMILY_FALSE_ALARM, cases.len());
    for (light, alpha) in cases {
        let outcome = Chi2Test {
            axis: sp.frame.to_world(glam::Vec3::Z),
            samples: 400_000,
            horizon: Some(sp.frame.to_world(glam::Vec3::Z)),
            ..Chi2Test::default()
        }
        .run(
            |sampler| {
                path::sample_mixture(scene, &sp, light, alpha, sampler)
                    .filter(|d| !d.delta)
                    .map(|d| d.ray.direction)
            },
            |wi| path::mixture_density(scene, &sp, light, alpha, wi),
        );
        outcome.assert_passes(alpha_test, &format!("mixture, light {light}, α = {alpha}"));
    }
}

/// The one-sample mixture past the first vertex chooses the light it samples by the emitters'
/// `sampling_weight`s, and any choice is unbiased: with weights 1, 4, ¼ its image mean is the
/// uniform choice's. Paired renders (the same seeds; every light at the first vertex, so that
/// the two differ only past it) by a t-test on the per-seed differences of the image means'
/// luminance, at the suite's rate; power required: a 2 % bias found with probability 0.9.
#[test]
fn the_mixture_chooses_lights_by_weight_with_the_same_mean() {
    let (_dir, uniform) = scene_file("uniform.ron", &weighted_lights_scene([1.0, 1.0, 1.0]));
    let (_dir2, weighted) = scene_file("weighted.ron", &weighted_lights_scene([1.0, 4.0, 0.25]));
    let set = [
        format!("integrator.{}=\"mixture\"", path::DEEP_ALLOCATION),
        "integrator.lights=\"all\"".to_string(),
    ];
    let first = test_seed() * 1_000_000 + 710_000;
    let runs = 16;
    let luminance = |v: &[f64; 3]| 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
    let seeds = first..first + runs;
    let reference = image_means(&uniform, &set, (32, 1), seeds.clone());
    let tested = image_means(&weighted, &set, (32, 1), seeds);
    let differences: Vec<f64> = tested
        .iter()
        .zip(&reference)
        .map(|(t, r)| luminance(t) - luminance(r))
        .collect();
    let (d, se) = common::mean_and_standard_error(&differences);
    let m_ref = reference.iter().map(luminance).sum::<f64>() / runs as f64;
    let limit = lumis::same_mean::t_limit(sidak(FAMILY_FALSE_ALARM, 1), runs as f64 - 1.0);
    let t = d / se;
    let detected = (limit + lumis::same_mean::Z_POWER_90) * se / m_ref;
    eprintln!(
        "mixture, sampling_weight 1, 4, 0.25 against uniform: difference {d:+.5} of {m_ref:.5} \
         (t = {t:+.2}, limit {limit:.2}); detects {:.2} % with probability 0.9",
        100.0 * detected
    );
    assert!(t.abs() < limit, "t = {t}, seed {}", test_seed());
    assert!(detected <= 0.02, "detects only {:.2} %", 100.0 * detected);
}

/// A wave of camera samples shaded together (`Integrator::shade_together`: each vertex depth's
/// lights drawn together for the wave's live paths)
/// gives what shading them one by one gives, bit for bit: each sample's colour and its pixel's
/// sums. On the path scenes and on scenes of area, sphere, delta and environment lights and
/// several materials (glass, mirrors, glossy), with every light or one chosen per vertex, hidden
/// emitters, optimal MIS, adaptive first allocations (pilots included), N that fills the lanes
/// (point by point), short paths and early roulette; waves of 16 traced samples and of 5
/// untraced ones, and at every 13th pixel a whole wave (`WAVE_SIZE`, traced in packets).
#[test]
fn a_wave_shaded_together_gives_what_one_by_one_gives() {
    let configurations: &[&[&str]] = &[
        &[],
        &["lights=\"one\"", "max_depth=7"],
        &["hide_emitters=true", "rr_depth=1"],
        &["weighting=\"optimal_mis\"", "samples=4", "deep_samples=4"],
        &["allocation=\"alpha\"", "samples=8", "deep_samples=1"],
        &["samples=16", "deep_samples=3", "max_depth=3"],
        &["weighting=\"balance\"", "fixed=0", "lights=\"one\""],
        &["allocation=\"variance_aware\"", "block=4", "samples=8"],
        &["allocation=\"pooled_alpha\"", "samples=8", "max_depth=4"],
    ];
    let (mut compared, mut lit, mut whole_waves) = (0, 0, 0);
    for file in [
        "scenes/cornell-bounce.ron",
        "scenes/cornell-glass.ron",
        "scenes/cornell-glossy.ron",
        "scenes/materials.ron",
        "scenes/lights.ron",
        "scenes/envmap.ron",
    ] {
        let path = repo_path(file);
        let text = std::fs::read_to_string(&path).unwrap();
        let film = ["film.width=16", "film.height=12"];
        let loaded = common::load(&path, &film).unwrap_or_else(|e| panic!("{file}: {e}"));
        let scene = &loaded.scene;
        let pixels = common::every_nth_pixel(scene, 5);
        for configuration in configurations {
            let overrides: Vec<String> = film
                .iter()
                .map(|o| o.to_string())
                .chain(["integrator.type=\"path\"".to_string()])
                .chain(configuration.iter().map(|o| format!("integrator.{o}")))
                .collect();
            let name = format!("{file}, {configuration:?}");
            let built = common::preprocessed_integrator(&path, &text, &overrides, scene, &name);
            for (j, &pixel) in pixels.iter().enumerate() {
                let whole_wave = 0..lumis::integrator::WAVE_SIZE as u32;
                let waves = [0..16, 16..21, whole_wave];
                for indices in waves.into_iter().take(if j % 13 == 0 { 3 } else { 2 }) {
                    let shaded =
                        common::shade_packet_both_ways(scene, &*built, pixel, indices, &name);
                    let (mut alone, mut together) = (shaded.alone, shaded.together);
                    let expected = shaded.expected;
                    // Each sample's stream is where `shade` left it.
                    let next: Vec<f32> = together.iter_mut().map(|s| s.sampler.next_1d()).collect();
                    let next_alone: Vec<f32> =
                        alone.iter_mut().map(|s| s.sampler.next_1d()).collect();
                    assert_eq!(next, next_alone, "{name}, pixel {pixel}: streams");
                    compared += 1;
                    whole_waves += usize::from(expected.len() == lumis::integrator::WAVE_SIZE);
                    lit += expected.iter().filter(|c| c.max_element() > 0.0).count();
                }
            }
        }
    }
    assert!(compared > 1_000, "{compared} waves");
    assert!(whole_waves >= 100, "{whole_waves} whole waves");
    assert!(lit > 10_000, "{lit} lit samples");
}
