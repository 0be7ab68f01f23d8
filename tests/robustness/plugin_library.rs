//! Run-time plugin libraries: the example `oren_nayar` library (built with the tests, as a
//! dev-dependency) is loaded by a scene, rendered, and its sampling checked with the chi-square
//! harness; bad libraries are refused.

use crate::common::{SMALL_SCENE, example_library, lumis, scene_file};
use std::path::PathBuf;

fn scene_with_library(library: &str) -> String {
    SMALL_SCENE
        .replace(
            "(type: \"diffuse\", reflectance: 0.8)",
            "(type: \"oren_nayar\", reflectance: 0.8, sigma: 30)",
        )
        .replace(
            "    ],\n)",
            &format!("    ],\n    plugins: [{library:?}],\n)"),
        )
}

#[test]
fn a_scene_renders_with_a_bsdf_from_a_plugin_library() {
    let library = example_library();
    let (dir, path) = scene_file("scene.ron", &scene_with_library(library.to_str().unwrap()));
    let out = lumis(dir.path(), &["render", path.to_str().unwrap(), "--quiet"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let channels = lumis::image_io::read_exr_channels(&dir.path().join("scene.exr")).unwrap();
    let red = &channels.iter().find(|c| c.0 == "R").unwrap().1;
    assert!(red.iter().all(|v| v.is_finite()) && red.iter().any(|v| *v > 0.0));
    // Without the library the BSDF is unknown.
    let (dir, path) = scene_file(
        "scene.ron",
        &scene_with_library("").replace("    plugins: [\"\"],\n", ""),
    );
    let out = lumis(dir.path(), &["render", path.to_str().unwrap(), "--quiet"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown bsdf plugin `oren_nayar`"));
}

#[test]
fn plugin_library_bsdf_passes_the_chi_square_test() {
    use lumis::bsdf::BsdfContext;
    use lumis::chi2::{Chi2Test, sidak, test_bsdf};
    use lumis::registry::{BsdfPlugin, find};
    lumis::link_plugins();
    lumis::dylib::load_library(example_library()).unwrap();
    let plugin = find::<BsdfPlugin>("oren_nayar").expect("registered by the library");
    let values = ron::from_str("{\"sigma\": 40, \"reflectance\": 0.9}").unwrap();
    let mut params = lumis::params::Params::new("oren_nayar", plugin.params, values).unwrap();
    let bsdf = (plugin.create)(&mut params).unwrap();
    params.finish().unwrap();
    let cases = [1.0f32, 0.7, 1e-3];
    for cos in cases {
        let wo = glam::Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
        test_bsdf(bsdf.as_ref(), &BsdfContext::FRONT, wo, &Chi2Test::default())
            .assert_passes(sidak(0.01, cases.len()), &format!("oren_nayar cos={cos}"));
        // Loading the same library again is a no-op, not a duplicate registration.
        lumis::dylib::load_library(example_library()).unwrap();
    }
}

#[test]
fn missing_library_is_refused_with_its_path() {
    let (dir, path) = scene_file("scene.ron", &scene_with_library("plugins/libnothing.so"));
    let out = lumis(dir.path(), &["render", path.to_str().unwrap(), "--quiet"]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        e.contains("plugins/libnothing.so")
            && e.contains("cannot open plugin library")
            && e.contains("No such file"),
        "{e}"
    );
}

#[test]
fn library_without_the_declaration_is_refused() {
    // The C maths library is a shared library that certainly exports no lumis declaration.
    let libm = ["/lib", "/usr/lib", "/lib64", "/usr/lib64"]
        .iter()
        .flat_map(|d| {
            [
                PathBuf::from(d).join("libm.so.6"),
                PathBuf::from(d).join(format!("{}-linux-gnu/libm.so.6", std::env::consts::ARCH)),
            ]
        })
        .find(|p| p.exists())
        .expect("libm.so.6 on this Linux machine");
    let (dir, path) = scene_file("scene.ron", &scene_with_library(libm.to_str().unwrap()));
    let out = lumis(dir.path(), &["render", path.to_str().unwrap(), "--quiet"]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        e.contains("libm.so.6") && e.contains("does not export LUMIS_PLUGIN_DECLARATION"),
        "{e}"
    );
}
