//! Mitsuba's materials through `lumis import`: plastics, conductors (named, Beckmann by
//! default), `twosided` with one or two BSDFs, `bitmap` and `checkerboard` textures (nested and
//! referenced), and one-sidedness: a converted BSDF is black seen from behind unless
//! `twosided` wraps it.

use crate::common;

use common::{lumis, render};
use std::path::Path;

const SENSOR: &str = r#"
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, -4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="12"/></film>
        <sampler type="independent"><integer name="sample_count" value="2"/></sampler>
    </sensor>
    <emitter type="point"><point name="position" x="0" y="0" z="-3"/><rgb name="intensity" value="10"/></emitter>"#;

const MATERIALS: &str = r#"
    <texture type="bitmap" id="roughness_map">
        <string name="filename" value="roughness.png"/>
        <boolean name="raw" value="true"/>
        <string name="wrap_mode" value="mirror"/>
    </texture>
    <bsdf type="plastic" id="plastic">
        <rgb name="diffuse_reflectance" value="0.8, 0.2, 0.1"/>
        <string name="int_ior" value="bk7"/>
        <boolean name="nonlinear" value="true"/>
    </bsdf>
    <bsdf type="roughplastic" id="rough">
        <float name="alpha" value="0.2"/>
        <texture type="checkerboard" name="diffuse_reflectance">
            <rgb name="color0" value="0.1"/>
            <rgb name="color1" value="0.9"/>
            <transform name="to_uv"><scale x="4" y="2"/><translate x="0.5"/></transform>
        </texture>
    </bsdf>
    <bsdf type="conductor" id="gold"><string name="material" value="Au"/></bsdf>
    <bsdf type="roughconductor" id="copper">
        <string name="material" value="Cu"/>
        <ref name="alpha" id="roughness_map"/>
    </bsdf>
    <bsdf type="twosided" id="sides"><bsdf type="diffuse"/><bsdf type="conductor"/></bsdf>
    <bsdf type="twosided" id="both"><bsdf type="plastic"/></bsdf>"#;

/// A rectangle facing the camera at x, with BSDF `id`.
fn rectangle(x: f32, id: &str) -> String {
    format!(
        r#"<shape type="rectangle"><transform name="to_world"><scale value="0.4"/><rotate y="1" angle="180"/><translate x="{x}"/></transform><ref id="{id}"/></shape>"#
    )
}

/// Writes `xml` as `scene.xml` in `dir`, imports it, and returns the RON text and the stderr.
fn import(dir: &Path, xml: &str) -> (String, String) {
    std::fs::write(dir.join("scene.xml"), xml).unwrap();
    let out = lumis(dir, &["import", "scene.xml", "-o", "scene.ron"]);
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{stderr}");
    (
        std::fs::read_to_string(dir.join("scene.ron")).unwrap(),
        stderr,
    )
}

#[test]
fn mitsuba_materials_and_textures_convert_and_render() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, 2, 2);
    encoder.set_color(png::ColorType::Grayscale);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(&[10, 60, 120, 250]).unwrap();
    writer.finish().unwrap();
    std::fs::write(dir.path().join("roughness.png"), bytes).unwrap();
    let shapes: String = ["plastic", "rough", "gold", "copper", "sides", "both"]
        .iter()
        .enumerate()
        .map(|(i, id)| rectangle(i as f32 - 2.5, id))
        .collect();
    let xml = format!("<scene version=\"3.0.0\">{SENSOR}{MATERIALS}{shapes}</scene>");
    let (ron, _) = import(dir.path(), &xml);
    let scene: lumis::scene::description::SceneDescription = ron::from_str(&ron).unwrap();
    let kind = |id: &str| scene.bsdfs[id].kind.as_str();
    let one_sided =
        |id: &str| scene.bsdfs[id].params.get("one_sided") == Some(&ron::Value::Bool(true));
    assert_eq!(
        ["plastic", "rough", "gold", "copper", "sides", "both"].map(kind),
        [
            "plastic",
            "roughplastic",
            "conductor",
            "roughconductor",
            "twosided",
            "plastic"
        ],
        "{ron}"
    );
    // Mitsuba's non-transmissive BSDFs are one-sided, unless wrapped in twosided.
    for id in ["plastic", "rough", "gold", "copper"] {
        assert!(one_sided(id), "{id} in {ron}");
    }
    for id in ["sides", "both"] {
        assert!(!one_sided(id), "{id} in {ron}");
    }
    for needle in [
        "int_ior: 1.5046",
        "nonlinear: true",
        r#"material: "Au""#,
        r#"material: "Cu""#,
        r#"alpha: (type: "bitmap""#,
        r#"filename: "roughness.png""#,
        r#"wrap_mode: "mirror""#,
        r#"diffuse_reflectance: (type: "checkerboard", color0: 0.1, color1: 0.9"#,
        r#"front: (type: "diffuse""#,
        r#"back: (type: "conductor")"#,
    ] {
        assert!(ron.contains(needle), "`{needle}` missing in:\n{ron}");
    }
    // Beckmann, Mitsuba's default, is lumis' default: no `distribution` written.
    assert!(!ron.contains("distribution"), "{ron}");
    let film = render(&dir.path().join("scene.ron"), &[], 1);
    assert!(
        film.color
            .iter()
            .all(|c| c.is_finite() && c.min_element() >= 0.0)
    );
    assert!(film.color.iter().any(|c| c.max_element() > 0.0));
}

/// A rectangle seen from behind, lit from the camera's side: black with a converted `diffuse`
/// (one-sided, as in Mitsuba), lit when `twosided` wraps it.
#[test]
fn an_imported_surface_is_black_from_behind_unless_twosided() {
    let mut sums = Vec::new();
    for bsdf in [
        r#"<bsdf type="diffuse"/>"#,
        r#"<bsdf type="twosided"><bsdf type="diffuse"/></bsdf>"#,
    ] {
        let dir = tempfile::tempdir().unwrap();
        // Mitsuba's rectangle faces +z, away from the camera at z = −4.
        let xml = format!(
            r#"<scene version="3.0.0">{SENSOR}<shape type="rectangle">{bsdf}</shape></scene>"#
        );
        import(dir.path(), &xml);
        let film = render(&dir.path().join("scene.ron"), &[], 1);
        sums.push(
            film.color
                .iter()
                .map(|c| c.element_sum() as f64)
                .sum::<f64>(),
        );
    }
    assert_eq!(sums[0], 0.0, "one-sided from behind");
    assert!(sums[1] > 0.0, "two-sided from behind");
}

/// Mitsuba's `principled` is refused with the reason, naming its line.
#[test]
fn principled_is_refused_with_its_reason() {
    let dir = tempfile::tempdir().unwrap();
    let xml = format!(
        "<scene version=\"3.0.0\">{SENSOR}\n<shape type=\"sphere\"><bsdf type=\"principled\"/></shape></scene>"
    );
    std::fs::write(dir.path().join("scene.xml"), xml).unwrap();
    let out = lumis(dir.path(), &["import", "scene.xml", "-o", "scene.ron"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains(
            "scene.xml:9: BSDF `principled` is not converted: lumis has no principled BSDF"
        ),
        "{stderr}"
    );
}
