//! Bad input gets a clear error, never a panic: one test per kind of mistake, asserting what the
//! message says, and that the program exits non-zero without a backtrace.

use crate::common::{SMALL_SCENE, lumis, scene_file};

/// Renders `text` with the CLI and returns its stderr, asserting it failed cleanly.
fn cli_error(text: &str, extra: &[&str]) -> String {
    let (dir, path) = scene_file("scene.ron", text);
    let mut args = vec!["render", path.to_str().unwrap(), "--quiet"];
    args.extend(extra);
    let out = lumis(dir.path(), &args);
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(
        !out.status.success(),
        "expected failure, got success; stderr: {stderr}"
    );
    assert_eq!(out.status.code(), Some(1), "stderr: {stderr}");
    assert!(
        !stderr.contains("panicked") && !stderr.contains("RUST_BACKTRACE"),
        "panic: {stderr}"
    );
    assert!(stderr.starts_with("error: "), "{stderr}");
    assert!(!dir.path().join("scene.exr").exists(), "no output on error");
    stderr
}

fn assert_contains(text: &str, parts: &[&str]) {
    for p in parts {
        assert!(text.contains(p), "expected {p:?} in:\n{text}");
    }
}

#[test]
fn ron_syntax_error_names_file_line_and_column() {
    // The film line lacks its comma: the parser stops at the next field, line 4, column 5.
    let text = SMALL_SCENE.replace(
        "film: (width: 16, height: 16),",
        "film: (width: 16, height: 16)",
    );
    let e = cli_error(&text, &[]);
    assert_contains(&e, &["scene.ron:4:5:", "Expected comma"]);
}

#[test]
fn unknown_scene_field_is_named_with_the_expected_ones() {
    let text = SMALL_SCENE.replace("fov: 40", "fov: 40, fob: 3");
    let e = cli_error(&text, &[]);
    assert_contains(&e, &["scene.ron:2:", "fob", "fov"]);
}

#[test]
fn unknown_bsdf_plugin_lists_known_ones_and_the_closest() {
    let e = cli_error(
        &SMALL_SCENE.replace("type: \"diffuse\"", "type: \"difuse\""),
        &[],
    );
    assert_contains(
        &e,
        &[
            "bsdf `white`",
            "unknown bsdf plugin `difuse`",
            "did you mean `diffuse`",
            "known bsdf plugins: ",
        ],
    );
    let known = e.split("known bsdf plugins: ").nth(1).unwrap_or_default();
    assert!(
        known.split(", ").any(|name| name.trim() == "diffuse"),
        "{known}"
    );
}

#[test]
fn unknown_emitter_plugin_lists_known_ones() {
    let e = cli_error(
        &SMALL_SCENE.replace("type: \"area\"", "type: \"aera\""),
        &[],
    );
    assert_contains(
        &e,
        &[
            "shapes[1] (rectangle).emitter",
            "unknown emitter plugin `aera`",
            "did you mean `area`",
            "known emitter plugins: area",
        ],
    );
}

#[test]
fn unknown_integrator_plugin_lists_known_ones() {
    let e = cli_error(SMALL_SCENE, &["--set", "integrator.type=balanse"]);
    assert_contains(
        &e,
        &[
            "unknown integrator plugin `balanse`",
            "did you mean `balance`",
            "known integrator plugins:",
            "balance",
        ],
    );
}

#[test]
fn unknown_parameter_is_named_with_its_plugin_and_closest_valid_name() {
    let e = cli_error(
        &SMALL_SCENE.replace("reflectance: 0.8", "reflectence: 0.8"),
        &[],
    );
    assert_contains(
        &e,
        &[
            "unknown parameter `reflectence`",
            "did you mean `reflectance`",
            "bsdf `white` (diffuse)",
        ],
    );
    let e = cli_error(SMALL_SCENE, &["--set", "integrator.sample=8"]);
    assert_contains(
        &e,
        &[
            "unknown parameter `sample`",
            "did you mean `samples`",
            "integrator `balance`",
        ],
    );
}

#[test]
fn wrong_parameter_type_says_expected_and_found() {
    let e = cli_error(
        &SMALL_SCENE.replace("reflectance: 0.8", "reflectance: \"grey\""),
        &[],
    );
    assert_contains(
        &e,
        &[
            "`reflectance`",
            "bsdf `white` (diffuse)",
            "expects an RGB triple",
            "found the string \"grey\"",
        ],
    );
    let e = cli_error(SMALL_SCENE, &["--set", "integrator.samples=(1, 2)"]);
    assert_contains(
        &e,
        &[
            "`samples`",
            "expects an integer",
            "found a tuple or list of 2 elements",
        ],
    );
}

#[test]
fn out_of_range_parameter_is_refused() {
    let e = cli_error(
        &SMALL_SCENE.replace("reflectance: 0.8", "reflectance: 1.5"),
        &[],
    );
    assert_contains(&e, &["`reflectance`", "[0, 1]"]);
    let e = cli_error(SMALL_SCENE, &["--set", "integrator.samples=0"]);
    assert_contains(&e, &["`samples`", "must be in [1, 1048576]", "found 0"]);
}

#[test]
fn shape_with_undefined_bsdf_names_both() {
    let text = SMALL_SCENE.replacen("bsdf: \"white\"", "bsdf: \"whit\"", 1);
    let e = cli_error(&text, &[]);
    assert_contains(
        &e,
        &[
            "shapes[0] (rectangle)",
            "bsdf `whit`",
            "not defined",
            "did you mean `white`",
            "defined bsdfs: white",
        ],
    );
}

#[test]
fn unknown_shape_type_lists_the_known_ones() {
    let e = cli_error(
        &SMALL_SCENE.replacen("type: \"rectangle\"", "type: \"rectangel\"", 1),
        &[],
    );
    assert_contains(
        &e,
        &[
            "shapes[0]",
            "unknown shape type `rectangel`",
            "did you mean `rectangle`",
            "gltf, rectangle, cube, disk, sphere",
        ],
    );
}

#[test]
fn missing_gltf_file_names_the_path_and_reason() {
    let text = SMALL_SCENE.replacen(
        "(type: \"rectangle\", bsdf: \"white\",",
        "(type: \"gltf\", file: \"meshes/nothing.glb\", bsdf: \"white\",",
        1,
    );
    let e = cli_error(&text, &[]);
    assert_contains(
        &e,
        &[
            "meshes/nothing.glb",
            "cannot read glTF file",
            "No such file",
            "shapes[0] (gltf)",
        ],
    );
}

#[test]
fn corrupt_gltf_file_names_the_path_and_reason() {
    let text = SMALL_SCENE.replacen(
        "(type: \"rectangle\", bsdf: \"white\",",
        "(type: \"gltf\", file: \"bad.glb\", bsdf: \"white\",",
        1,
    );
    let (dir, path) = scene_file("scene.ron", &text);
    std::fs::write(dir.path().join("bad.glb"), b"glTF\x02\x00\x00\x00garbage").unwrap();
    let out = lumis(dir.path(), &["render", path.to_str().unwrap(), "--quiet"]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert_contains(&e, &["bad.glb", "not a valid glTF file"]);
}

#[test]
fn gltf_with_out_of_range_index_is_refused() {
    // A one-triangle glTF whose index 7 points past its 3 vertices.
    let positions: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let indices: Vec<u8> = [0u16, 1, 7].iter().flat_map(|i| i.to_le_bytes()).collect();
    let mut bin = positions.clone();
    bin.extend(&indices);
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"uri":"tri.bin","byteLength":{len}}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":6}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
                     {{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#,
        len = bin.len()
    );
    let text = SMALL_SCENE.replacen(
        "(type: \"rectangle\", bsdf: \"white\",",
        "(type: \"gltf\", file: \"tri.gltf\", bsdf: \"white\",",
        1,
    );
    let (dir, path) = scene_file("scene.ron", &text);
    std::fs::write(dir.path().join("tri.gltf"), gltf).unwrap();
    std::fs::write(dir.path().join("tri.bin"), bin).unwrap();
    let e = crate::common::load(&path, &[])
        .err()
        .expect("refused")
        .to_string();
    assert_contains(&e, &["tri.gltf", "index 7 is out of range for 3 vertices"]);
}

#[test]
fn missing_or_corrupt_exr_names_the_path_and_reason() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.exr");
    let e = lumis::image_io::read_exr_rgb(&missing).unwrap_err();
    assert_contains(&e, &["missing.exr", "No such file"]);
    let corrupt = dir.path().join("corrupt.exr");
    std::fs::write(&corrupt, b"v/1\x01not an exr at all").unwrap();
    let e = lumis::image_io::read_exr_rgb(&corrupt).unwrap_err();
    assert_contains(&e, &["corrupt.exr"]);
}

#[test]
fn missing_scene_file_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let out = lumis(dir.path(), &["render", "nowhere.ron"]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert_contains(&e, &["nowhere.ron", "cannot read scene file"]);
}

#[test]
fn bad_overrides_are_explained() {
    let e = cli_error(SMALL_SCENE, &["--set", "shapes[9].bsdf=x"]);
    assert_contains(&e, &["--set shapes[9].bsdf=x", "index 9 is out of range"]);
    let e = cli_error(SMALL_SCENE, &["--set", "integrator"]);
    assert_contains(&e, &["expected path=value"]);
    let e = cli_error(SMALL_SCENE, &["--set", "film.width=wide"]);
    assert_contains(
        &e,
        &["after applying the --set overrides", "film.width=wide"],
    );
}

#[test]
fn invalid_film_and_camera_are_refused() {
    let e = cli_error(
        &SMALL_SCENE.replace(
            "width: 16, height: 16",
            "width: 16, height: 16, crop: (x: 10, y: 0, width: 10, height: 4)",
        ),
        &[],
    );
    assert_contains(&e, &["crop", "inside the 16x16 film"]);
    let e = cli_error(&SMALL_SCENE.replace("fov: 40", "fov: 0"), &[]);
    assert_contains(&e, &["`fov` must be in (0, 180)"]);
    let e = cli_error(
        &SMALL_SCENE.replace("target: (0, 0, 0)", "target: (0, 2, -4)"),
        &[],
    );
    assert_contains(&e, &["`position` and `target` must differ"]);
}

#[test]
fn area_emitter_without_a_shape_is_refused() {
    let text = SMALL_SCENE.replace(
        "    ],\n)",
        "    ],\n    emitters: [(type: \"area\", radiance: 1)],\n)",
    );
    let e = cli_error(&text, &[]);
    assert_contains(&e, &["emitters[0]", "must be attached to a shape"]);
}

#[test]
fn missing_plugin_library_names_its_path() {
    let text = SMALL_SCENE.replace("    ],\n)", "    ],\n    plugins: [\"libexample.so\"],\n)");
    let e = cli_error(&text, &[]);
    assert_contains(
        &e,
        &[
            "libexample.so",
            "cannot open plugin library",
            "No such file",
            "listed in the `plugins`",
        ],
    );
}

#[test]
fn output_must_be_exr() {
    let e = cli_error(SMALL_SCENE, &["-o", "out.png"]);
    assert_contains(&e, &["out.png", "must end in .exr"]);
}

#[test]
fn missing_or_corrupt_environment_map_names_the_path_and_reason() {
    let text = SMALL_SCENE.replace(
        "    ],\n)",
        "    ],\n    emitters: [(type: \"envmap\", file: \"maps/sky.exr\")],\n)",
    );
    let e = cli_error(&text, &[]);
    assert_contains(
        &e,
        &[
            "emitters[0] (envmap)",
            "maps/sky.exr",
            "cannot read EXR file",
            "No such file",
        ],
    );
    let (dir, path) = scene_file("scene.ron", &text);
    std::fs::create_dir(dir.path().join("maps")).unwrap();
    std::fs::write(dir.path().join("maps/sky.exr"), b"\x76\x2f\x31\x01garbage").unwrap();
    let out = lumis(dir.path(), &["render", path.to_str().unwrap(), "--quiet"]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert_contains(&e, &["maps/sky.exr", "is not a valid EXR file"]);
}

#[test]
fn second_environment_and_lights_on_shapes_are_refused() {
    let text = SMALL_SCENE.replace(
        "    ],\n)",
        "    ],\n    emitters: [(type: \"envmap\", file: \"a.exr\"), (type: \"envmap\", file: \"a.exr\")],\n)",
    );
    let (dir, path) = scene_file("scene.ron", &text);
    exr::prelude::write_rgb_file(dir.path().join("a.exr"), 4, 2, |_, _| {
        (1.0f32, 1.0f32, 1.0f32)
    })
    .unwrap();
    let out = lumis(dir.path(), &["render", path.to_str().unwrap(), "--quiet"]);
    assert_contains(
        &String::from_utf8_lossy(&out.stderr),
        &["emitters[1]", "at most one environment"],
    );
    let e = cli_error(
        &SMALL_SCENE.replace(
            "emitter: (type: \"area\", radiance: (5, 5, 5))",
            "emitter: (type: \"point\", position: (0, 0, 0), intensity: 1)",
        ),
        &[],
    );
    assert_contains(&e, &["`point` emitter cannot be attached to a shape"]);
}
