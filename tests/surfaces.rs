//! Surfaces as shading points see them (the BSDF interface, plugin API 4): texture coordinates
//! of the scene's shapes, a texture end to end (RON to render), one-sided BSDFs, BSDFs nested
//! by name or inline, and transmission through the shading point (its side tests, its rays'
//! origins, and renders of a transmitting surface against closed forms).

use crate::common::{self, integrators, load, scene_file};
use glam::{Vec2, Vec3};
use lumis::bsdf::{BsdfContext, Side};
use lumis::chi2::{FAMILY_FALSE_ALARM, sidak, test_seed};
use lumis::geometry::Ray;
use lumis::integrators::optimal_mis;
use lumis::integrators::shading_point::ShadingPoint;
use lumis::same_mean::{Z_POWER_90, t_limit};
use lumis::testing::register_test_bsdfs;
use std::path::Path;

/// A uniform environment of radiance 2, written into `dir`.
fn uniform_map(dir: &Path) -> std::path::PathBuf {
    let map = dir.join("uniform.exr");
    exr::prelude::write_rgb_file(&map, 16, 8, |_, _| (2.0f32, 2.0, 2.0)).unwrap();
    map
}

/// A camera of 0.01° field looking at `target` from above and aside: every pixel is an
/// independent estimate of the radiance leaving that point toward the camera.
fn one_point_camera(target: Vec3) -> String {
    let p = target + Vec3::new(0.6, 1.0, -1.2);
    format!(
        "camera: (position: ({}, {}, {}), target: ({}, {}, {}), fov: 0.01)",
        p.x, p.y, p.z, target.x, target.y, target.z
    )
}

/// The surface `ray` meets in `scene`, shaded from where the ray comes.
fn shading_point(scene: &lumis::scene::Scene, ray: Ray) -> ShadingPoint<'_> {
    let hit = scene.intersect(&ray).expect("the ray meets a surface");
    ShadingPoint::new(scene, &hit, -ray.direction)
}

fn ray(origin: Vec3, direction: Vec3) -> Ray {
    Ray {
        origin,
        direction,
        t_max: f32::INFINITY,
    }
}

/// The scene loader gives a turned sphere and a moved disk Mitsuba's parameterisations in their
/// own frames (Mitsuba 3.9.1's uv at the same rays, as in `geometry::uv`'s test), and a shading
/// point computes them only for a BSDF that varies over the surface.
#[test]
fn the_loader_gives_shapes_mitsubas_texture_coordinates() {
    let text = r#"Scene(
    camera: (position: (0, 0, -10), target: (0, 0, 0), fov: 30),
    film: (width: 4, height: 4),
    integrator: (type: "balance", samples: 1),
    bsdfs: {
        "plain": (type: "diffuse"),
        "checks": (type: "diffuse", reflectance: (type: "checkerboard")),
    },
    shapes: [
        (type: "sphere", bsdf: "checks", transform: (rotate: [(axis: (0, 0, 1), angle: 90)])),
        (type: "disk", bsdf: "plain", transform: (translate: (5, 0, 0))),
    ],
    emitters: [(type: "point", position: (0, 5, 0), intensity: 1)],
)"#;
    let (_dir, path) = scene_file("uv.ron", text);
    let scene = load(&path, &[]).unwrap().scene;
    let close = |a: Vec2, b: Vec2| (a - b).abs().max_element() < 2e-5;
    let sp = shading_point(&scene, ray(Vec3::new(3.0, 0.1, 0.2), -Vec3::X));
    assert!(sp.flags.spatially_varying());
    assert!(
        close(sp.ctx.uv, Vec2::new(0.766272, 0.435906)),
        "{}",
        sp.ctx.uv
    );
    let down = ray(Vec3::new(5.3, -0.6, 3.0), -Vec3::Z);
    let hit = scene.intersect(&down).unwrap();
    assert!(close(scene.geometry.uv(&hit), Vec2::new(0.67082, 0.823792)));
    // Not computed for a BSDF that does not vary.
    let sp = shading_point(&scene, down);
    assert!(!sp.flags.spatially_varying() && sp.ctx.uv == Vec2::ZERO);
}

/// A diffuse plane whose reflectance is a checkerboard (0.2 and 0.8) under a uniform
/// environment of radiance 2 reflects ρ L = 0.4 at a point of a `color0` check and 1.6 at a
/// point of a `color1` check: the mean of 256 independent pixel estimates is within Student's
/// t limit of each (Šidák over the two), and the test detects a 1 % bias with probability 0.9.
#[test]
fn a_checkerboard_plane_reflects_its_two_albedos_where_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let map = uniform_map(dir.path());
    // The rectangle (scale 2) lies in y = 0 facing +y: world (x, 0, z) has uv
    // ((x/2 + 1)/2, (−z/2 + 1)/2); (−1.5, 0, 1.5) is at (0.125, 0.125), a color0 check, and
    // (1, 0, 1.5) at (0.75, 0.125), a color1 check.
    let cases = [
        (Vec3::new(-1.5, 0.0, 1.5), 0.4),
        (Vec3::new(1.0, 0.0, 1.5), 1.6),
    ];
    let alpha = sidak(FAMILY_FALSE_ALARM, cases.len());
    for (k, (point, expected)) in cases.into_iter().enumerate() {
        let text = format!(
            r#"Scene(
    {camera},
    film: (width: 16, height: 16),
    sampler: (spp: 32, seed: {seed}),
    integrator: (type: "balance", samples: 16),
    bsdfs: {{
        "checks": (type: "diffuse", reflectance: (type: "checkerboard", color0: 0.2, color1: 0.8)),
    }},
    shapes: [
        (type: "rectangle", bsdf: "checks", transform: (scale: (2, 2, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
    ],
    emitters: [(type: "envmap", file: {map:?})],
)"#,
            camera = one_point_camera(point),
            seed = test_seed() * 10 + k as u64,
        );
        let path = dir.path().join(format!("checks{k}.ron"));
        std::fs::write(&path, text).unwrap();
        let film = common::render(&path, &[], 2);
        let values: Vec<f64> = film.color.iter().map(|c| c.y as f64).collect();
        let (mean, se) = common::mean_and_standard_error(&values);
        let se = se.hypot(4.0 * f32::EPSILON as f64 * expected);
        let limit = t_limit(alpha, values.len() as f64 - 1.0);
        let detected = (limit + Z_POWER_90) * se / expected;
        eprintln!(
            "checkerboard at {point}: {mean:.5} ± {se:.5}, expected {expected} (detects {:.2} %)",
            100.0 * detected
        );
        assert!(
            (mean - expected).abs() < limit * se,
            "at {point}: {mean} ± {se}, expected {expected} (limit {limit:.2} σ, seed {})",
            test_seed()
        );
        assert!(detected < 0.01, "detects only {:.2} %", 100.0 * detected);
    }
}

/// A plane seen from behind under a uniform environment: black where its BSDF is one-sided
/// (`one_sided: true`), lit where it is two-sided (the default); seen from the front, the
/// one-sided plane renders bit for bit as the two-sided one.
#[test]
fn one_sided_bsdfs_are_black_from_behind() {
    let dir = tempfile::tempdir().unwrap();
    let map = uniform_map(dir.path());
    let scene = |z: f32, one_sided: bool| {
        format!(
            r#"Scene(
    camera: (position: (0.1, 0.2, {z}), target: (0, 0, 0), fov: 20),
    film: (width: 8, height: 8),
    sampler: (spp: 2, seed: 5),
    integrator: (type: "balance", samples: 4),
    bsdfs: {{ "grey": (type: "diffuse", reflectance: 0.5, one_sided: {one_sided}) }},
    shapes: [(type: "rectangle", bsdf: "grey")],
    emitters: [(type: "envmap", file: {map:?})],
)"#
        )
    };
    let render = |z: f32, one_sided: bool| {
        let path = dir.path().join(format!("plane{z}{one_sided}.ron"));
        std::fs::write(&path, scene(z, one_sided)).unwrap();
        common::render(&path, &[], 2).color
    };
    let (behind, behind_two_sided) = (render(-3.0, true), render(-3.0, false));
    assert!(behind.iter().all(|c| *c == glam::Vec3::ZERO), "{behind:?}");
    assert!(behind_two_sided.iter().all(|c| c.min_element() > 0.5));
    assert_eq!(render(3.0, true), render(3.0, false));
    // The back of a one-sided BSDF is the absorber: no lobe.
    let path = dir.path().join("plane-3true.ron");
    let scene = load(&path, &[]).unwrap().scene;
    let sp = shading_point(
        &scene,
        ray(Vec3::new(0.1, 0.2, -3.0), Vec3::new(-0.1, -0.2, 3.0)),
    );
    assert!(sp.ctx.side == Side::Back && sp.flags.is_black());
}

/// A BSDF nested by name or inline: `test_by_side` shows one nested BSDF from the front and the
/// other from the back. A named BSDF's `one_sided` applies where shapes use it, not where it is
/// nested.
#[test]
fn nested_bsdfs_are_built_by_name_or_inline() {
    register_test_bsdfs();
    let text = r#"Scene(
    camera: (position: (0, 0, 3), target: (0, 0, 0), fov: 20),
    film: (width: 4, height: 4),
    integrator: (type: "balance", samples: 1),
    bsdfs: {
        "bright": (type: "diffuse", reflectance: 0.8, one_sided: true),
        "sides": (type: "test_by_side", front: "bright", back: (type: "diffuse", reflectance: 0.2)),
    },
    shapes: [(type: "rectangle", bsdf: "sides")],
    emitters: [(type: "point", position: (0, 0, 5), intensity: 1)],
)"#;
    let (_dir, path) = scene_file("nested.ron", text);
    let scene = load(&path, &[]).unwrap().scene;
    let (wo, wi) = (Vec3::new(0.0, 0.6, 0.8), Vec3::Z);
    for (origin, side, albedo) in [(3.0f32, Side::Front, 0.8f32), (-3.0, Side::Back, 0.2)] {
        let sp = shading_point(
            &scene,
            ray(Vec3::new(0.0, 0.0, origin), Vec3::new(0.0, 0.0, -origin)),
        );
        assert_eq!(sp.ctx.side, side);
        let f = sp.bsdf.eval(&sp.ctx, wo, wi);
        assert!(
            (f.x - albedo / std::f32::consts::PI).abs() < 1e-6,
            "{side:?}: {f}"
        );
    }
}

/// Mistakes in textures, nested BSDFs and sidedness are errors that say what is wrong.
#[test]
fn mistakes_in_textures_and_nested_bsdfs_are_named() {
    register_test_bsdfs();
    let scene = |bsdfs: &str| {
        format!(
            r#"Scene(
    camera: (position: (0, 0, 3), target: (0, 0, 0), fov: 20),
    film: (width: 4, height: 4),
    integrator: (type: "balance", samples: 1),
    bsdfs: {{ {bsdfs} }},
    shapes: [(type: "rectangle", bsdf: "a")],
)"#
        )
    };
    for (bsdfs, needles) in [
        (
            r#""a": (type: "test_by_side", front: "b", back: "a"), "b": (type: "diffuse")"#,
            &[
                "parameter `back` of bsdf `a` (test_by_side)",
                "refers back to itself: a → a",
            ][..],
        ),
        (
            r#""a": (type: "test_by_side", front: "b", back: "b"), "b": (type: "test_by_side", front: "a", back: "a")"#,
            &["bsdf `a` refers back to itself: a → b → a"],
        ),
        (
            r#""a": (type: "test_by_side", front: "gren", back: "green"), "green": (type: "diffuse")"#,
            &[
                "bsdf `gren` is not defined",
                "did you mean `green`",
                "defined bsdfs: a, green",
            ],
        ),
        (
            r#""a": (type: "test_by_side", front: (type: "diffuse", one_sided: true), back: (type: "diffuse"))"#,
            &["`one_sided` is a key of the scene's `bsdfs` entries"],
        ),
        (
            r#""a": (type: "test_transmitter", one_sided: true)"#,
            &[
                "bsdf `a`: `one_sided` applies to BSDFs that only reflect",
                "`test_transmitter` transmits",
            ],
        ),
        (
            r#""a": (type: "diffuse", one_sided: 1)"#,
            &["bsdf `a`: `one_sided` must be true or false, found the number 1"],
        ),
        (
            r#""a": (type: "diffuse", reflectance: (type: "checkerboard", color1: 1.5))"#,
            &[
                "parameter `reflectance` of bsdf `a` (diffuse) must be in [0, 1] per channel",
                "its texture takes values in [0.4, 1.5]",
            ],
        ),
        (
            r#""a": (type: "diffuse", reflectance: (type: "checkerbord"))"#,
            &[
                "unknown texture plugin `checkerbord`",
                "did you mean `checkerboard`",
            ],
        ),
        (
            r#""a": (type: "diffuse", reflectance: (type: "checkerboard", colour0: 0.2))"#,
            &[
                "parameter `reflectance` of bsdf `a` (diffuse)",
                "unknown parameter `colour0`",
                "texture (checkerboard)",
            ],
        ),
        (
            r#""a": (type: "diffuse", reflectance: "checks")"#,
            &["expects an RGB triple (r, g, b), one number, or a texture"],
        ),
        (
            r#""a": (type: "diffuse", reflectance: (type: "checkerboard", to_uv: (scale: (1, 2), skew: 3)))"#,
            &[
                "unknown key `skew`",
                "parameter `to_uv` of texture (checkerboard)",
            ],
        ),
        (
            r#""a": (type: "test_by_side", front: (type: "diffuse"))"#,
            &["parameter `back` of bsdf `a` (test_by_side) is required"],
        ),
    ] {
        let (_dir, path) = scene_file("bad.ron", &scene(bsdfs));
        let e = load(&path, &[]).err().expect("refused").to_string();
        for needle in needles {
            assert!(e.contains(needle), "{bsdfs}: `{needle}` not in: {e}");
        }
    }
}

/// A scene of one transmitting plane (`test_transmitter`: reflection 0.3, transmission 0.5) at
/// height `point.y`, seen at `point`, with `light` as its other shape and `emitters` as its
/// emitters.
fn transmitting_scene(point: Vec3, light: &str, emitters: &str) -> String {
    format!(
        r#"Scene(
    {camera},
    film: (width: 16, height: 16),
    integrator: (type: "balance", samples: 16),
    bsdfs: {{
        "sheet": (type: "test_transmitter", reflectance: 0.3, transmittance: 0.5),
        "grey": (type: "diffuse", reflectance: 0.5),
    }},
    shapes: [
        (type: "rectangle", bsdf: "sheet", transform: (scale: (10, 10, 1), rotate: [(axis: (1, 0, 0), angle: -90)], translate: (0, {height}, 0))),
        {light}
    ],
    emitters: [{emitters}],
)"#,
        camera = one_point_camera(point),
        height = point.y,
    )
}

/// Every integrator against closed forms of a transmitting plane: under a uniform environment
/// of radiance 2 it sends (0.3 + 0.5) · 2 toward the viewer (the far half of the environment
/// comes through, by light samples below the plane and transmitted BSDF samples); with only a
/// sphere light below it (radiance 10, radius 1/4, 2 below), 0.5 · 10 · (1/4 ÷ 2)², all of it
/// transmitted (shadow rays and BSDF rays leave from the far side). The 256 pixels are
/// independent estimates: t-tests at the suite's rate (Šidák), as
/// `every_integrator_gives_the_closed_form_at_one_point`; `optimal_mis` in its unbiased mode
/// (its direct mode is consistent only, its bias O(1/N): here, where the integrand is not a
/// combination of the two densities, 0.1 % at N = 16, which these estimates resolve). A
/// diffuse plane with the light below stays black: no leak.
#[test]
fn transmission_through_a_plane_gives_its_closed_forms() {
    register_test_bsdfs();
    let dir = tempfile::tempdir().unwrap();
    let map = uniform_map(dir.path());
    let point = Vec3::ZERO;
    let below = "(type: \"sphere\", bsdf: \"grey\", radius: 0.25, center: (0, -2, 0), \
                 emitter: (type: \"area\", radiance: 10)),";
    let cases = [
        (
            "uniform environment",
            transmitting_scene(point, "", &format!("(type: \"envmap\", file: {map:?})")),
            0.8 * 2.0,
            64,
        ),
        (
            "sphere light below",
            transmitting_scene(point, below, ""),
            0.5 * 10.0 * (0.25f64 / 2.0).powi(2),
            64,
        ),
    ];
    let names = integrators();
    let alpha = sidak(FAMILY_FALSE_ALARM, cases.len() * names.len());
    let mut failures = Vec::new();
    for (c, (case, text, expected, spp)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("case{c}.ron"));
        std::fs::write(&path, text).unwrap();
        for (i, name) in names.iter().enumerate() {
            let seed = test_seed() * 1000 + 100 * c as u64 + i as u64;
            let mut overrides = vec![
                format!("integrator.type={name}"),
                format!("sampler.spp={spp}"),
                format!("sampler.seed={seed}"),
            ];
            if *name == optimal_mis::NAME {
                overrides.push(format!(
                    "integrator.{}={}",
                    optimal_mis::MODE,
                    optimal_mis::PROGRESSIVE
                ));
            }
            let overrides: Vec<&str> = overrides.iter().map(String::as_str).collect();
            let film = common::render(&path, &overrides, 2);
            let values: Vec<f64> = film.color.iter().map(|v| v.y as f64).collect();
            let (mean, se) = common::mean_and_standard_error(&values);
            let se = se.hypot(4.0 * f32::EPSILON as f64 * expected);
            let limit = t_limit(alpha, values.len() as f64 - 1.0);
            let t = (mean - expected) / se;
            eprintln!(
                "{case}: {name}: {mean:.5} ± {se:.5}, closed form {expected:.5} (t = {t:+.2})"
            );
            if t.is_nan() || t.abs() >= limit {
                failures.push(format!(
                    "{case}: {name} gives {mean} ± {se}, closed form {expected} (t = {t:.2}, \
                     limit {limit:.2}, seed {})",
                    test_seed()
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    let reflecting =
        transmitting_scene(point, below, "").replace("bsdf: \"sheet\"", "bsdf: \"grey\"");
    assert!(reflecting.contains("bsdf: \"grey\", transform: (scale: (10"));
    let (_dir, path) = scene_file("reflecting.ron", &reflecting);
    let film = common::render(&path, &[], 2);
    assert!(film.color.iter().all(|c| *c == glam::Vec3::ZERO));
}

/// At a point of a transmitting plane, the shading point knows the side and the BSDF's
/// transmission, takes a transmitted direction (local z < 0) only toward the far side of the
/// geometric surface, and its ray toward the far side leaves from an origin on that side.
#[test]
fn shading_points_send_transmitted_rays_from_the_far_side() {
    register_test_bsdfs();
    // Off the origin, where a point's rounding error (and so its rays' offset) is not zero.
    let point = Vec3::new(0.37, 0.5, 0.21);
    let (_dir, path) = scene_file("sheet.ron", &transmitting_scene(point, "", ""));
    let scene = load(&path, &[]).unwrap().scene;
    let sp = shading_point(
        &scene,
        ray(
            point + Vec3::new(0.6, 1.0, -1.2),
            Vec3::new(-0.6, -1.0, 1.2),
        ),
    );
    assert!(sp.ctx.side == Side::Front && sp.flags.transmission());
    let up = Vec3::new(0.3, 0.8, 0.1).normalize();
    for (w, far) in [(-up, true), (up, false)] {
        let origin = sp.origin.ray(&sp.hit, w).origin;
        let height = (origin - sp.hit.position).dot(sp.normal);
        assert!((height < 0.0) == far && height != 0.0, "{w}: {height}");
    }
    // A transmitted sample of the BSDF leaves toward the far side.
    let ctx = BsdfContext::FRONT;
    let s = (0..64)
        .find_map(|k| {
            let s = sp
                .bsdf
                .sample(&ctx, sp.wo, 0.01, Vec2::new(0.3, k as f32 / 64.0))?;
            s.transmission().then_some(s)
        })
        .expect("a transmitted sample");
    assert!(sp.frame.to_world(s.wi).dot(sp.normal) < 0.0);
    let from_below = shading_point(
        &scene,
        ray(
            point + Vec3::new(0.6, -1.0, -1.2),
            Vec3::new(-0.6, 1.0, 1.2),
        ),
    );
    assert_eq!(from_below.ctx.side, Side::Back);
}
