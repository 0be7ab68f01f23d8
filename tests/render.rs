//! Rendering end to end: determinism across thread counts, analytic answers, outputs.
//!
//! Why one file of over 600 lines: end-to-end render tests sharing the small scenes and helpers
//! defined here.

use crate::common;
use common::{SMALL_SCENE, example_library, load, lumis, scene_file};
use std::path::Path;

fn render_film(path: &Path, overrides: &[&str], threads: usize) -> lumis::film::Film {
    common::render(path, overrides, threads)
}

fn repo_path(relative: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

/// One and two threads give the same file, byte for byte, not only the same pixels: at 512×512
/// the EXR holds 64 tiles, whose compression runs in parallel and whose order in the file (and
/// its chunk table) must not depend on which finishes first. One sample per pixel and per
/// technique keeps it cheap.
#[test]
fn one_and_two_threads_give_bit_identical_exrs() {
    let dir = tempfile::tempdir().unwrap();
    let scene = repo_path("scenes/cornell.ron");
    let common = [
        "--set",
        "film.width=512",
        "--set",
        "film.height=512",
        "--set",
        "integrator.samples=1",
        "--spp",
        "1",
        "--quiet",
    ];
    for threads in ["1", "2"] {
        let out_name = format!("t{threads}.exr");
        let mut args = vec![
            "render",
            scene.to_str().unwrap(),
            "-o",
            &out_name,
            "--threads",
            threads,
        ];
        args.extend(common);
        let out = lumis(dir.path(), &args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let a = std::fs::read(dir.path().join("t1.exr")).unwrap();
    let b = std::fs::read(dir.path().join("t2.exr")).unwrap();
    let meta = exr::meta::MetaData::read_from_file(dir.path().join("t1.exr"), false).unwrap();
    assert!(
        meta.headers[0].chunk_count > 1,
        "one chunk: no order to test"
    );
    assert!(a == b, "EXRs differ between 1 and 2 threads");
    assert!(
        dir.path().join("t1.png").exists(),
        "PNG preview beside the EXR"
    );
}

#[test]
fn cornell_box_is_finite_and_lit_where_expected() {
    let film = render_film(
        &repo_path("scenes/cornell.ron"),
        &["film.width=32", "film.height=32", "sampler.spp=1"],
        2,
    );
    assert!(
        film.color
            .iter()
            .all(|c| c.is_finite() && c.min_element() >= 0.0)
    );
    let px = |x: usize, y: usize| film.color[y * 32 + x];
    // The light (top centre) is the brightest; the left wall is red, the right wall green.
    assert!(px(16, 4).x > 10.0, "light {:?}", px(16, 4));
    let left = px(2, 16);
    let right = px(29, 16);
    assert!(
        left.x > 2.0 * left.y && left.x > 2.0 * left.z,
        "left wall {left:?}"
    );
    assert!(
        right.y > 2.0 * right.x && right.y > 2.0 * right.z,
        "right wall {right:?}"
    );
}

#[test]
fn exr_has_colour_channels_metadata_and_crop_window() {
    let (dir, path) = scene_file("scene.ron", SMALL_SCENE);
    let text = SMALL_SCENE.replace(
        "height: 16)",
        "height: 16, crop: (x: 4, y: 2, width: 8, height: 6))",
    );
    std::fs::write(&path, text).unwrap();
    let out = lumis(dir.path(), &["render", "scene.ron", "--quiet"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let exr = dir.path().join("scene.exr");
    let channels = lumis::image_io::read_exr_channels(&exr).unwrap();
    let names: Vec<&str> = channels.iter().map(|c| c.0.as_str()).collect();
    assert_eq!(names, ["B", "G", "R"]);
    assert_eq!(channels[0].1.len(), 8 * 6);
    let meta = exr::meta::MetaData::read_from_file(&exr, false).unwrap();
    let header = &meta.headers[0];
    assert_eq!(header.own_attributes.layer_position, exr::math::Vec2(4, 2));
    assert_eq!(
        header.shared_attributes.display_window.size,
        exr::math::Vec2(16, 16)
    );
    let lumis_attribute = header
        .own_attributes
        .other
        .get(&exr::meta::attribute::Text::from("lumis"));
    let Some(exr::meta::attribute::AttributeValue::Text(text)) = lumis_attribute else {
        panic!("no lumis attribute: {:?}", header.own_attributes.other);
    };
    let text = text.to_string();
    for line in [
        "integrator=balance\n",
        "integrator.samples=4\n",
        "spp=2\n",
        "seed=1\n",
    ] {
        assert!(text.contains(line), "{line:?} missing from {text}");
    }
    let png = common::read_png(&dir.path().join("scene.png"));
    assert_eq!(
        (png.width, png.height, png.color),
        (8, 6, png::ColorType::Rgb)
    );
}

/// Renders an 8×8 image of (nearly) one floor point and returns the mean and its standard error,
/// from the spread of the 64 independent pixel estimates.
/// `--lanes` changes the time, never the image: the batch kernels at four, eight and sixteen
/// lanes (as wide as the processor allows) write the same file, byte for byte, on glossy
/// plates lit by spheres, an environment map and the α integrator's sums; a width that is
/// not one is refused with the widths there are.
#[test]
fn every_lane_width_gives_the_same_exr() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = [
        ("scenes/veach.ron", "balance"),
        ("scenes/envmap.ron", "power"),
        ("scenes/cornell.ron", "alpha"),
    ];
    for (scene, integrator) in scenes {
        let scene = repo_path(scene);
        let integrator = format!("integrator.type=\"{integrator}\"");
        let render = |lanes: &str| {
            let out_name = format!("lanes{lanes}.exr");
            let args = [
                "render",
                scene.to_str().unwrap(),
                "-o",
                &out_name,
                "--lanes",
                lanes,
                "--set",
                &integrator,
                "--set",
                "film.width=48",
                "--set",
                "film.height=36",
                "--spp",
                "4",
                "--quiet",
            ];
            let out = lumis(dir.path(), &args);
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            std::fs::read(dir.path().join(out_name)).unwrap()
        };
        let eight = render("8");
        for lanes in ["4", "16"] {
            assert!(
                render(lanes) == eight,
                "{scene:?}: {lanes} lanes against eight"
            );
        }
    }
    let out = lumis(
        dir.path(),
        &["render", "scenes/cornell.ron", "--lanes", "12"],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("4, 8 or 16"),
        "{stderr}"
    );
}

fn mean_and_standard_error(film: &lumis::film::Film) -> (f64, f64) {
    let values: Vec<f64> = film.color.iter().map(|c| c.y as f64).collect();
    common::mean_and_standard_error(&values)
}

fn floor_scene(light: &str) -> String {
    format!(
        r#"Scene(
    camera: (position: (0.6, 1.0, -1.2), target: (0, 0, 0), fov: 0.01),
    film: (width: 8, height: 8),
    sampler: (spp: 4, seed: 3),
    integrator: (type: "balance", samples: 16),
    bsdfs: {{ "grey": (type: "diffuse", reflectance: 0.5) }},
    shapes: [
        (type: "rectangle", bsdf: "grey", transform: (scale: (10, 10, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
        {light}
    ],
)"#
    )
}

#[test]
fn sphere_light_gives_the_analytic_radiance_on_axis() {
    // E = pi L (r/d)^2 on axis, so a Lambertian floor of albedo rho reflects rho L (r/d)^2.
    let (r, d, radiance, rho) = (0.25f64, 2.0f64, 10.0f64, 0.5f64);
    let light = format!(
        "(type: \"sphere\", bsdf: \"grey\", radius: {r}, center: (0, {d}, 0), emitter: (type: \"area\", radiance: {radiance})),"
    );
    let (_dir, path) = scene_file("sphere.ron", &floor_scene(&light));
    let film = render_film(&path, &[], 2);
    let (mean, se) = mean_and_standard_error(&film);
    let expected = rho * radiance * (r / d).powi(2);
    assert!(se < 0.02 * expected, "too noisy to test: se {se}");
    assert!(
        (mean - expected).abs() < 4.0 * se,
        "mean {mean} vs {expected} (se {se})"
    );
}

#[test]
fn disk_light_gives_the_analytic_radiance_on_axis() {
    // A disk of radius R at height h: E = pi L R^2 / (h^2 + R^2).
    let (big_r, h, radiance, rho) = (0.5f64, 1.0f64, 4.0f64, 0.5f64);
    let light = format!(
        "(type: \"disk\", segments: 4096, bsdf: \"grey\", transform: (scale: ({big_r}, {big_r}, 1), rotate: [(axis: (1, 0, 0), angle: 90)], translate: (0, {h}, 0)), emitter: (type: \"area\", radiance: {radiance})),"
    );
    let (_dir, path) = scene_file("disk.ron", &floor_scene(&light));
    let film = render_film(&path, &[], 2);
    let (mean, se) = mean_and_standard_error(&film);
    let expected = rho * radiance * big_r * big_r / (h * h + big_r * big_r);
    assert!(se < 0.02 * expected, "too noisy to test: se {se}");
    assert!(
        (mean - expected).abs() < 4.0 * se,
        "mean {mean} vs {expected} (se {se})"
    );
}

#[test]
fn gltf_meshes_load_with_node_transforms_and_names() {
    let (_dir, path) = scene_file(
        "bunny.ron",
        &SMALL_SCENE.replacen(
            "(type: \"rectangle\", bsdf: \"white\",",
            &format!(
                "(type: \"gltf\", file: \"{}\", bsdf: \"white\",",
                repo_path("scenes/meshes/bunny.glb").display()
            ),
            1,
        ),
    );
    let loaded = load(&path, &[]).expect("bunny loads");
    let lumis::geometry::ShapeGeometry::Mesh(mesh) = &loaded.scene.geometry.shapes()[0] else {
        panic!("a mesh");
    };
    assert_eq!(mesh.indices.len(), 3674);
    assert!(
        mesh.normals
            .as_ref()
            .is_some_and(|n| n.len() == mesh.positions.len())
    );
    let film = render_film(&path, &[], 1);
    assert!(film.color.iter().all(|c| c.is_finite()));
}

/// Every plugin file (a file of a plugin crate that submits a registration) is registered
/// under its file's name: the facade links every plugin crate, and the linker kept every
/// registration. The list comes from the source tree, so a new plugin is checked as soon as its
/// file exists.
#[test]
fn every_plugin_file_is_registered() {
    use lumis::registry::{
        BsdfPlugin, EmitterPlugin, IntegratorPlugin, PluginInfo, TexturePlugin, builtin,
    };
    lumis::link_plugins();
    fn check<P: PluginInfo + lumis::inventory::Collect>(dir: &str, least: usize) {
        let mut files: Vec<String> = std::fs::read_dir(repo_path(&format!("plugins/{dir}/src")))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|path| {
                std::fs::read_to_string(path).is_ok_and(|t| t.contains("inventory::submit!"))
            })
            .map(|path| path.file_stem().unwrap().to_string_lossy().into_owned())
            .collect();
        files.sort();
        let registered: Vec<&str> = builtin::<P>().iter().map(|p| p.name()).collect();
        assert!(files.len() >= least, "{dir}: found only {files:?}");
        assert_eq!(
            registered, files,
            "{dir}: registered plugins vs plugin files"
        );
    }
    check::<BsdfPlugin>("bsdfs", 4);
    check::<EmitterPlugin>("emitters", 4);
    check::<TexturePlugin>("textures", 1);
    check::<IntegratorPlugin>("integrators", 4);
}

#[test]
fn plugin_reference_is_current() {
    lumis::link_plugins();
    let doc = std::fs::read_to_string(repo_path("docs/plugins.md")).expect("docs/plugins.md");
    assert_eq!(
        doc,
        lumis::registry::plugins_markdown(),
        "regenerate with `lumis plugins --markdown > docs/plugins.md`"
    );
}

/// Each plugin lives in the file named after it, whose doc comment lists every parameter with
/// its default.
#[test]
fn plugin_files_document_their_parameters() {
    use lumis::registry::{
        BsdfPlugin, EmitterPlugin, IntegratorPlugin, PluginInfo, TexturePlugin, builtin,
    };
    lumis::link_plugins();
    fn check<P: PluginInfo + lumis::inventory::Collect>(dir: &str) {
        for p in builtin::<P>() {
            let file = repo_path(&format!("plugins/{dir}/src/{}.rs", p.name()));
            let text = std::fs::read_to_string(&file)
                .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
            let doc: String = text
                .lines()
                .filter(|l| l.starts_with("//!"))
                .collect::<Vec<_>>()
                .join("\n");
            assert!(
                doc.contains(&format!("`{}`", p.name())),
                "{}: doc names the plugin",
                file.display()
            );
            for q in p.params() {
                let name = format!("`{}`", q.name);
                let default = q.default_text();
                let default = default.trim_matches('"');
                assert!(
                    doc.lines()
                        .any(|l| l.contains(&name) && l.contains(default)),
                    "{}: no doc line gives `{}` with its default {default}",
                    file.display(),
                    q.name
                );
            }
        }
    }
    check::<BsdfPlugin>("bsdfs");
    check::<EmitterPlugin>("emitters");
    check::<TexturePlugin>("textures");
    check::<IntegratorPlugin>("integrators");
}

#[test]
fn outputs_are_replaced_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("out.exr");
    std::fs::write(&target, b"previous").unwrap();
    // A writer that fails half-way leaves the previous file intact and no temporary behind.
    let r = lumis::image_io::write_atomically(&target, |f| {
        use std::io::Write;
        f.write_all(b"partial").unwrap();
        Err("interrupted".into())
    });
    assert!(r.unwrap_err().to_string().contains("interrupted"));
    assert_eq!(std::fs::read(&target).unwrap(), b"previous");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "temporary left behind"
    );
    lumis::image_io::write_atomically(&target, |f| {
        use std::io::Write;
        f.write_all(b"new").map_err(|e| e.to_string())
    })
    .unwrap();
    assert_eq!(std::fs::read(&target).unwrap(), b"new");
}

/// A `.gltf` with an external `.bin`: two named nodes, one translated under a scaled parent.
fn write_two_node_gltf(dir: &Path) {
    let positions: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"uri":"two.bin","byteLength":{len}}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
        "meshes":[{{"name":"tri","primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "nodes":[{{"name":"parent","scale":[2,2,2],"children":[1]}},
                 {{"name":"moved","mesh":0,"translation":[10,0,0]}},
                 {{"name":"plain","mesh":0}}],
        "scenes":[{{"nodes":[0,2]}}],"scene":0}}"#,
        len = positions.len()
    );
    std::fs::write(dir.join("two.gltf"), gltf).unwrap();
    std::fs::write(dir.join("two.bin"), positions).unwrap();
}

#[test]
fn gltf_nodes_are_transformed_and_selectable_by_name() {
    let dir = tempfile::tempdir().unwrap();
    write_two_node_gltf(dir.path());
    let path = dir.path().join("two.gltf");
    let all = lumis::scene::gltf::load(&path, None).unwrap();
    assert_eq!(all.indices.len(), 2);
    let moved = lumis::scene::gltf::load(&path, Some("moved")).unwrap();
    // Parent scale 2 applies after the child's translation: x in [20, 22].
    let xs: Vec<f32> = moved.positions.iter().map(|p| p.x).collect();
    assert_eq!(xs, [20.0, 22.0, 20.0]);
    assert!(moved.normals.is_none());
    let by_parent = lumis::scene::gltf::load(&path, Some("parent")).unwrap();
    assert_eq!(by_parent.positions, moved.positions);
    let e = lumis::scene::gltf::load(&path, Some("moved2")).unwrap_err();
    assert!(
        e.contains("no node or mesh named `moved2`") && e.contains("did you mean `moved`"),
        "{e}"
    );
}

/// Every bundled scene (`scenes/` and the paper's, `scenes/paper/`) renders (small, 1 spp) with
/// every registered integrator and every AOV without a NaN, an Inf or a negative value.
#[test]
fn every_bundled_scene_renders_finite_values_with_every_integrator() {
    let mut count = 0;
    let mirror = scenes_mirror();
    let scenes = mirror.path().join("scenes");
    let dirs = [scenes.clone(), scenes.join("paper")].map(|dir| std::fs::read_dir(dir).unwrap());
    for entry in dirs.into_iter().flatten() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "ron") {
            continue;
        }
        generate_assets(&path, &scenes);
        let text = std::fs::read_to_string(&path).unwrap();
        let every_aov = format!("integrator.aovs={:?}", lumis::integrators::aovs::NAMES);
        // The scene is built once (its meshes, BVH and maps took most of this test's time when
        // it was rebuilt for every integrator); each integrator is built from the description
        // with its overrides, as loading builds it.
        let film_overrides = ["film.width=24", "film.height=16", "sampler.spp=1"];
        let loaded = common::load(&path, &film_overrides)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        for integrator in common::integrators() {
            let set = format!("integrator.type={integrator}");
            let overrides: Vec<String> = film_overrides
                .iter()
                .chain(&[set.as_str(), "integrator.samples=4", &every_aov])
                .map(|o| o.to_string())
                .collect();
            let description = lumis::scene::load::parse_description(&path, &text, &overrides)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let mut built = lumis::scene::load::build_integrator(
                &description.integrator,
                path.parent().unwrap(),
            )
            .unwrap_or_else(|e| panic!("{} with {integrator}: {e}", path.display()));
            let film = common::render_with(&loaded.scene, built.as_mut(), 2);
            let name = format!("{} with {integrator}", path.display());
            common::assert_finite_outputs(&film, &name);
            assert!(
                film.color.iter().any(|c| c.max_element() > 0.0),
                "{name}: black image"
            );
        }
        count += 1;
    }
    assert!(count >= 19, "found {count} scenes");
}

/// `scenes/` rebuilt in a temporary directory as `scenes/` from links to its files (`paper/` a
/// real folder of links, so that its `../` paths stay inside the copy): the assets that scenes
/// generate land there, never in the source tree. Beside it, `target/debug/` holds a link to the
/// example plugin library, where `scenes/plugin.ron` looks for it, wherever cargo's target
/// directory is.
fn scenes_mirror() -> tempfile::TempDir {
    fn link_entries(from: &Path, to: &Path) {
        for entry in std::fs::read_dir(from).unwrap() {
            let entry = entry.unwrap();
            let target = to.join(entry.file_name());
            if entry.file_name() == "paper" {
                std::fs::create_dir(&target).unwrap();
                link_entries(&entry.path(), &target);
            } else {
                std::os::unix::fs::symlink(entry.path(), &target).unwrap();
            }
        }
    }
    let mirror = tempfile::tempdir().unwrap();
    let debug = mirror.path().join("target/debug");
    std::fs::create_dir_all(&debug).unwrap();
    let library = example_library();
    std::os::unix::fs::symlink(library, debug.join(library.file_name().unwrap())).unwrap();
    std::fs::create_dir(mirror.path().join("scenes")).unwrap();
    link_entries(&repo_path("scenes"), &mirror.path().join("scenes"));
    mirror
}

/// Runs the asset-generating commands a scene documents in its comments
/// (`//   cargo run --release -- merl ... -o scenes/FILE`), when FILE is missing from the
/// `scenes` copy, as a user would.
fn generate_assets(scene: &Path, scenes: &Path) {
    let text = std::fs::read_to_string(scene).unwrap();
    for line in text.lines() {
        let Some(command) = line
            .trim_start_matches('/')
            .trim()
            .strip_prefix("cargo run --release -- ")
        else {
            continue;
        };
        // Split on spaces outside single quotes.
        let mut args = Vec::new();
        let (mut current, mut quoted) = (String::new(), false);
        for c in command.chars() {
            match c {
                '\'' => quoted = !quoted,
                ' ' if !quoted => {
                    if !current.is_empty() {
                        args.push(std::mem::take(&mut current));
                    }
                }
                _ => current.push(c),
            }
        }
        args.push(current);
        let output = args
            .iter()
            .position(|a| a == "-o")
            .map(|i| {
                let file = args[i + 1].strip_prefix("scenes/").expect("-o scenes/FILE");
                scenes.join(file)
            })
            .expect("-o FILE");
        if !output.exists() {
            std::fs::create_dir_all(output.parent().unwrap()).unwrap();
            let mut args: Vec<&str> = args.iter().map(String::as_str).collect();
            let o = args.iter().position(|a| *a == "-o").unwrap();
            args[o + 1] = output.to_str().unwrap();
            let out = lumis(&repo_path(""), &args);
            assert!(
                out.status.success(),
                "{}: {}",
                scene.display(),
                String::from_utf8_lossy(&out.stderr)
            );
        }
    }
}

/// A sphere of `measured` tabulated from a `glossy` BRDF and a sphere of that `glossy`, lit
/// symmetrically, are mirror images of each other up to noise and interpolation error.
#[test]
fn measured_renders_like_the_brdf_it_was_tabulated_from() {
    let dir = tempfile::tempdir().unwrap();
    let spec = r#"(type: "glossy", roughness: 0.2, specular: (0.9, 0.6, 0.5), diffuse: 0.1)"#;
    let file = dir.path().join("tab.binary");
    let out = lumis(
        dir.path(),
        &["merl", "--bsdf", spec, "-o", file.to_str().unwrap()],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = format!(
        r#"Scene(
    camera: (position: (0, 1, -5), target: (0, 1, 0), fov: 30),
    film: (width: 48, height: 24),
    sampler: (spp: 64, seed: 5),
    integrator: (type: "balance", samples: 32),
    bsdfs: {{ "m": (type: "measured", file: "tab.binary"), "g": {spec}, "black": (type: "diffuse", reflectance: 0) }},
    shapes: [
        (type: "sphere", bsdf: "m", center: (1.1, 1, 0), radius: 1),
        (type: "sphere", bsdf: "g", center: (-1.1, 1, 0), radius: 1),
        (type: "rectangle", bsdf: "black", transform: (look_at: (origin: (0, 4, -3), target: (0, 1, 0))),
            emitter: (type: "area", radiance: 10)),
    ],
)"#
    );
    let path = dir.path().join("scene.ron");
    std::fs::write(&path, text).unwrap();
    let film = render_film(&path, &[], 2);
    let (w, h) = (48usize, 24usize);
    let diffs: Vec<f64> = (0..h)
        .flat_map(|y| (0..w / 2).map(move |x| (x, y)))
        .map(|(x, y)| (film.color[y * w + x].y - film.color[y * w + w - 1 - x].y) as f64)
        .collect();
    let level: f64 = film.color.iter().map(|c| c.y as f64).sum::<f64>() / film.color.len() as f64;
    let n = diffs.len() as f64;
    let mean = diffs.iter().sum::<f64>() / n;
    let se = (diffs.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
    // 4 standard errors of noise, plus 2 % for the table's interpolation error (its median
    // relative error is under 1 %, see the bsdfs tests).
    assert!(level > 0.01, "scene too dark: {level}");
    assert!(
        mean.abs() <= 4.0 * se + 0.02 * level,
        "measured vs glossy: mean difference {mean}, se {se}, level {level}"
    );
}

/// Writes a constant-radiance environment map.
fn write_uniform_envmap(path: &Path, radiance: f32) {
    exr::prelude::write_rgb_file(path, 16, 8, |_, _| (radiance, radiance, radiance)).unwrap();
}

/// A diffuse floor under a uniform environment of radiance L reflects ρ·L (E = πL).
#[test]
fn uniform_environment_lights_a_diffuse_floor_to_rho_l() {
    let dir = tempfile::tempdir().unwrap();
    write_uniform_envmap(&dir.path().join("white.exr"), 2.0);
    let text = r#"Scene(
    camera: (position: (0.3, 1, -1), target: (0, 0, 0), fov: 0.01),
    film: (width: 8, height: 8),
    sampler: (spp: 4, seed: 2),
    integrator: (type: "balance", samples: 16),
    bsdfs: { "grey": (type: "diffuse", reflectance: 0.5) },
    shapes: [(type: "rectangle", bsdf: "grey", transform: (scale: (5, 5, 1), rotate: [(axis: (1, 0, 0), angle: -90)]))],
    emitters: [(type: "envmap", file: "white.exr")],
)"#;
    let path = dir.path().join("scene.ron");
    std::fs::write(&path, text).unwrap();
    let film = render_film(&path, &[], 2);
    let (mean, se) = mean_and_standard_error(&film);
    assert!(se < 0.02, "too noisy to test: se {se}");
    assert!(
        (mean - 1.0).abs() < 4.0 * se,
        "mean {mean} (se {se}), expected 1"
    );
}

/// Point and directional lights take one sample each and need no MIS: a diffuse floor under
/// them has exactly ρ/π · (I/d² + E), up to the pixel's tiny footprint. Each light's term is
/// well above 1 (5.1 and 4.8), where arithmetic slips such as `%` for `/` show (below 1 they
/// did not: a mutant survived).
#[test]
fn delta_lights_give_exact_radiance() {
    let text = r#"Scene(
    camera: (position: (0.3, 1, -1), target: (0, 0, 0), fov: 0.01),
    film: (width: 4, height: 4),
    sampler: (spp: 2, seed: 2),
    integrator: (type: "balance", samples: 4),
    bsdfs: { "grey": (type: "diffuse", reflectance: 0.5) },
    shapes: [(type: "rectangle", bsdf: "grey", transform: (scale: (5, 5, 1), rotate: [(axis: (1, 0, 0), angle: -90)]))],
    emitters: [
        (type: "point", position: (0, 2, 0), intensity: 128),
        (type: "directional", direction: (0, -1, 0), irradiance: 30),
    ],
)"#;
    let (_dir, path) = scene_file("delta.ron", text);
    let film = render_film(&path, &[], 1);
    let expected = 0.5 / std::f32::consts::PI * (128.0 / 4.0 + 30.0);
    for c in &film.color {
        assert!(
            (c.x - expected).abs() < 1e-4 * expected,
            "{} vs {expected}",
            c.x
        );
    }
    // The lights are never seen directly and a second light adds linearly: drop the point light.
    let film = render_film(&path, &["emitters[0].intensity=0"], 1);
    let directional = 0.5 / std::f32::consts::PI * 30.0;
    assert!((film.color[0].x - directional).abs() < 1e-4 * directional);
}

/// A shadow ray toward a directional light goes to infinity: a roof blocks it.
#[test]
fn directional_light_is_blocked_by_an_occluder() {
    let text = r#"Scene(
    camera: (position: (0.3, 1, -1), target: (0, 0, 0), fov: 0.01),
    film: (width: 2, height: 2),
    integrator: (type: "balance", samples: 4),
    bsdfs: { "grey": (type: "diffuse", reflectance: 0.5) },
    shapes: [
        (type: "rectangle", bsdf: "grey", transform: (scale: (5, 5, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
        (type: "rectangle", bsdf: "grey", transform: (scale: (0.5, 0.5, 1), rotate: [(axis: (1, 0, 0), angle: 90)], translate: (0, 50, 0))),
    ],
    emitters: [(type: "directional", direction: (0, -1, 0), irradiance: 3)],
)"#;
    let (_dir, path) = scene_file("shadow.ron", text);
    let film = render_film(&path, &[], 1);
    assert!(
        film.color.iter().all(|c| *c == glam::Vec3::ZERO),
        "{:?}",
        film.color[0]
    );
}

/// Ctrl-C (SIGINT) during a render writes the finished pixels as a valid EXR and PNG marked
/// partial, and exits with status 130. The signal is sent once the render reports its first
/// tenth of the pixels done (its plain progress lines on a non-terminal stderr), not after a
/// guessed delay.
#[test]
fn interrupted_render_writes_a_partial_image_and_fails() {
    use std::io::BufRead;
    let dir = tempfile::tempdir().unwrap();
    let scene = repo_path("scenes/cornell.ron");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_lumis"))
        .current_dir(dir.path())
        .args([
            "render",
            scene.to_str().unwrap(),
            "-o",
            "cut.exr",
            "--threads",
            "1",
        ])
        // A tenth of the image in about a second; the other nine tenths take far longer than the
        // signal takes to arrive.
        .args(["--spp", "4", "--set", "integrator.samples=16"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr_lines = std::io::BufReader::new(child.stderr.take().unwrap()).lines();
    let mut before = String::new();
    for line in stderr_lines.by_ref() {
        let line = line.unwrap();
        let started = line.starts_with("rendered ");
        before.push_str(&line);
        before.push('\n');
        if started {
            break;
        }
    }
    assert!(
        before.starts_with("rendered ") || before.contains("\nrendered "),
        "no progress before the render ended: {before}"
    );
    let status = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let rest: Vec<String> = stderr_lines.map(|l| l.unwrap()).collect();
    let stderr = before + &rest.join("\n");
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(
        stderr.contains("interrupted: wrote a partial image"),
        "{stderr}"
    );
    let meta = exr::meta::MetaData::read_from_file(dir.path().join("cut.exr"), false).unwrap();
    let Some(exr::meta::attribute::AttributeValue::Text(text)) = meta.headers[0]
        .own_attributes
        .other
        .get(&exr::meta::attribute::Text::from("lumis"))
    else {
        panic!("no lumis attribute");
    };
    let text = text.to_string();
    assert!(text.contains("partial=true\n"), "{text}");
    // "pixels=K of N": some but not all pixels were finished, and they are in the image.
    let pixels = text
        .lines()
        .find_map(|l| l.strip_prefix("pixels="))
        .unwrap();
    let (done, total) = pixels.split_once(" of ").unwrap();
    let (done, total): (u64, u64) = (done.parse().unwrap(), total.parse().unwrap());
    assert!(done > 0 && done < total, "{pixels}");
    assert!(text.contains("tiles="), "{text}");
    let channels = lumis::image_io::read_exr_channels(&dir.path().join("cut.exr")).unwrap();
    let red = &channels.iter().find(|c| c.0 == "R").unwrap().1;
    assert!(
        red.iter().any(|v| *v > 0.0),
        "the finished pixels are missing"
    );
    common::read_png(&dir.path().join("cut.png"));
    assert!(
        std::fs::read_dir(dir.path()).unwrap().all(|e| !e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .ends_with(".tmp"))
    );
}

/// A test integrator: each camera sample returns its index as colour and adds 1 and its index
/// to the pixel's two sums; its AOV `count` resolves to the number of samples summed. It can
/// also raise `cancel` once it has shaded `cancel_after` camera samples.
struct Counting {
    shaded: std::sync::atomic::AtomicU64,
    cancel_after: u64,
    cancel: std::sync::atomic::AtomicBool,
}

impl lumis::integrator::Integrator for Counting {
    fn aovs(&self, _scene: &lumis::scene::Scene) -> Vec<lumis::output::Aov> {
        vec![lumis::output::Aov {
            name: "count".into(),
            channels: vec!["sums".into(), "samples".into()],
            preview: false,
        }]
    }

    fn pixel_sums(&self, _scene: &lumis::scene::Scene) -> usize {
        2
    }

    fn shade(
        &self,
        scene: &lumis::scene::Scene,
        sample: &mut lumis::integrator::CameraSample,
        sums: &mut [f64],
    ) -> lumis::math::Rgb {
        use std::sync::atomic::Ordering;
        let expected = lumis::integrator::CameraSample::new(scene, sample.pixel, sample.index);
        assert_eq!(sample.ray.direction, expected.ray.direction);
        if self.shaded.fetch_add(1, Ordering::Relaxed) + 1 == self.cancel_after {
            self.cancel.store(true, Ordering::Relaxed);
        }
        sums[0] += 1.0;
        sums[1] += sample.index as f64;
        lumis::math::Rgb::splat(sample.index as f32)
    }

    fn resolve(&self, _scene: &lumis::scene::Scene, sums: &[f64], samples: u32, aovs: &mut [f32]) {
        aovs[0] = sums[0] as f32;
        aovs[1] = samples as f32;
    }
}

fn counting(cancel_after: u64) -> Counting {
    Counting {
        shaded: Default::default(),
        cancel_after,
        cancel: Default::default(),
    }
}

/// Core runs every camera sample of every pixel once, sums colours and the integrator's sums
/// per pixel, and resolves each pixel once from its sums.
#[test]
fn camera_samples_are_summed_per_pixel_and_resolved() {
    let (_dir, path) = scene_file("scene.ron", SMALL_SCENE);
    let loaded = load(&path, &["sampler.spp=5"]).unwrap();
    let integrator = counting(0);
    let (film, stats) =
        lumis::render::render(&loaded.scene, &integrator, 2, &|_| {}).expect("render");
    assert_eq!(stats.pixels_done, 256);
    assert_eq!(stats.camera_samples, 256 * 5);
    assert!(!stats.partial());
    let layer = film.aov("count").expect("the count layer");
    assert_eq!(layer.channel("sums").unwrap(), vec![5.0; 256]);
    assert_eq!(layer.channel("samples").unwrap(), vec![5.0; 256]);
    // Mean of the indices 0 … 4.
    assert!(film.color.iter().all(|c| *c == glam::Vec3::splat(2.0)));
    assert!(film.aov("absent").is_none() && layer.channel("absent").is_none());
}

/// Cancelling stops before the next packet of camera samples (the `PACKET_SIZE` samples of
/// consecutive pixels that are traced and shaded together): with one thread and 1000 samples a
/// pixel, a cancel raised by the 2500th sample lets its packet finish and leaves exactly two
/// finished pixels, kept, and the third, cut short, black (its sums from before the pass given
/// back); the statistics say so.
#[test]
fn cancelling_stops_at_the_next_packet_and_keeps_finished_pixels() {
    use std::sync::atomic::Ordering;
    let (_dir, path) = scene_file("scene.ron", SMALL_SCENE);
    let loaded = load(&path, &["sampler.spp=1000"]).unwrap();
    let integrator = counting(2500);
    let (film, stats) = lumis::render::render_cancellable(
        &loaded.scene,
        &integrator,
        1,
        &|_| {},
        &integrator.cancel,
    )
    .expect("render");
    // The 2500th sample is in packet 2499 / PACKET_SIZE of the tile, which is shaded whole.
    let packet = lumis::geometry::PACKET_SIZE as u64;
    let shaded = (2499 / packet + 1) * packet;
    assert_eq!(integrator.shaded.load(Ordering::Relaxed), shaded);
    assert_eq!((stats.pixels_done, stats.pixels_total), (2, 256));
    assert_eq!((stats.tiles_done, stats.tiles_total), (0, 1));
    assert_eq!(stats.camera_samples, 2000);
    assert!(stats.partial());
    let mean_index = glam::Vec3::splat(999.0 / 2.0);
    assert_eq!(film.color[..2], [mean_index; 2]);
    assert!(film.color[2..].iter().all(|c| *c == glam::Vec3::ZERO));
    let counts = film.aov("count").unwrap().channel("samples").unwrap();
    assert_eq!(counts[..3], [1000.0, 1000.0, 0.0]);
}

/// A pixel's camera samples made four rays at a time (`CameraSample::extend_pixel`, which the
/// render loop uses) are each what `CameraSample::new` makes, bit for bit: stream, film ray,
/// index and pixel, for runs of 1 to 9 samples from several first indices (whole fours, a lone
/// sample left, three left), jittered and not.
#[test]
fn camera_samples_made_four_at_a_time_are_made_as_one_at_a_time() {
    use lumis::integrator::CameraSample;
    let path = repo_path("scenes/cornell.ron");
    let mut compared = 0;
    for jitter in ["sampler.jitter=true", "sampler.jitter=false"] {
        let loaded = load(&path, &["film.width=24", "film.height=16", jitter])
            .unwrap_or_else(|e| panic!("{e}"));
        let scene = &loaded.scene;
        for pixel in [
            glam::UVec2::new(0, 0),
            glam::UVec2::new(23, 15),
            glam::UVec2::new(7, 9),
        ] {
            for first in [0u32, 3, 16] {
                for count in 1..=9u32 {
                    let mut made = Vec::new();
                    CameraSample::extend_pixel(scene, pixel, first..first + count, &mut made);
                    assert_eq!(made.len(), count as usize);
                    for (k, mut sample) in made.into_iter().enumerate() {
                        let index = first + k as u32;
                        let mut alone = CameraSample::new(scene, pixel, index);
                        assert_eq!((sample.pixel, sample.index), (pixel, index));
                        let ray_bits = |s: &CameraSample| {
                            let r = s.ray;
                            let coordinates = [r.origin.to_array(), r.direction.to_array()];
                            let all = coordinates.concat().into_iter().chain([r.t_max]);
                            all.map(f32::to_bits).collect::<Vec<_>>()
                        };
                        assert_eq!(
                            ray_bits(&sample),
                            ray_bits(&alone),
                            "{jitter}, {pixel}, sample {index}"
                        );
                        let numbers = |s: &mut CameraSample| -> Vec<u32> {
                            (0..4).map(|_| s.sampler.next_1d().to_bits()).collect()
                        };
                        assert_eq!(
                            numbers(&mut sample),
                            numbers(&mut alone),
                            "stream of sample {index}"
                        );
                        compared += 1;
                    }
                }
            }
        }
    }
    assert_eq!(compared, 2 * 3 * 3 * 45);
}
