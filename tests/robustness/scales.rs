//! Scale invariance and its limits: a scene (camera, shape, light) scaled as a whole by any
//! factor from 1e-30 to 1e30, for every shape kind (OBJ and PLY meshes included) and for glTF
//! meshes scaled by the shape's transform or by their own node, either renders finite pixels or is refused with a message
//! that names the limit it crosses. Within the supported range it renders the same image as at
//! scale 1: the sampler draws the same numbers, so only rounding at silhouettes can differ.

use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use std::path::Path;

/// The messages of the geometric limits (docs/robustness.md).
const NAMED_LIMITS: [&str; 6] = [
    "beyond the supported",
    "below the smallest supported size",
    "none of its triangles has an area",
    "the transform is singular",
    "must be in [-1e12, 1e12] per component",
    "the file has no triangles",
];

/// The shapes under test, as they are written in a scene (`{s}`: the scale).
fn shape(kind: &str) -> String {
    match kind {
        "rectangle" | "cube" | "disk" => format!(
            r#"(type: "{kind}", bsdf: "white", transform: (scale: ({{s}}, {{s}}, {{s}}), rotate: [(axis: (1, 0, 0), angle: -110)]))"#
        ),
        "sphere" => r#"(type: "sphere", bsdf: "white", radius: {s})"#.into(),
        // The bunny is about 10 across: scaled down to about the others' size.
        "gltf" => r#"(type: "gltf", file: "BUNNY", bsdf: "white", transform: (scale: ({s6}, {s6}, {s6})))"#
            .into(),
        "gltf_node" => r#"(type: "gltf", file: "node.gltf", bsdf: "white")"#.into(),
        "obj" | "ply" => format!(
            r#"(type: "{kind}", file: "quad.{kind}", bsdf: "white", transform: (scale: ({{s}}, {{s}}, {{s}}), rotate: [(axis: (1, 0, 0), angle: -110)]))"#
        ),
        _ => unreachable!(),
    }
}

const KINDS: [&str; 8] = [
    "rectangle",
    "cube",
    "disk",
    "sphere",
    "gltf",
    "gltf_node",
    "obj",
    "ply",
];

/// The unit quad of the rectangle, as an OBJ and as an ASCII PLY file.
const QUAD_OBJ: &str = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3 4\n";
const QUAD_PLY: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n\
    property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n\
    end_header\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n4 0 1 2 3\n";

/// The scene of `kind` scaled by `s`, written in `dir` (with the glTF whose node scales by `s`).
fn scene(dir: &Path, kind: &str, s: f64) -> std::path::PathBuf {
    let bunny = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/bunny.glb");
    let shape = shape(kind)
        .replace("{s6}", &format!("{:e}", 0.15 * s))
        .replace("{s}", &format!("{s:e}"))
        .replace("BUNNY", bunny.to_str().unwrap());
    let text = format!(
        r#"Scene(
    camera: (position: (0, {cy:e}, {cz:e}), target: (0, 0, 0), fov: 50),
    film: (width: 8, height: 8),
    sampler: (spp: 1, seed: 5),
    integrator: (type: "balance", samples: 2),
    bsdfs: {{ "white": (type: "diffuse", reflectance: 0.7) }},
    shapes: [
        {shape},
        (type: "rectangle", bsdf: "white", transform: (scale: ({l:e}, {l:e}, {s:e}), rotate: [(axis: (1, 0, 0), angle: 90)], translate: (0, {ly:e}, 0)), emitter: (type: "area", radiance: 4, two_sided: true)),
    ],
)"#,
        cy = 1.5 * s,
        cz = -4.0 * s,
        l = 0.7 * s,
        ly = 2.5 * s,
    );
    // A one-quad glTF whose node carries the scale.
    let quad: Vec<u8> = [-1f32, -1., 0., 1., -1., 0., 1., 1., 0., -1., 1., 0.]
        .iter()
        .flat_map(|f| f.to_le_bytes())
        .chain([0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()))
        .collect();
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},
        "buffers":[{{"uri":"data:application/octet-stream;base64,{data}","byteLength":60}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":12}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]}},
                     {{"bufferView":1,"componentType":5123,"count":6,"type":"SCALAR"}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "nodes":[{{"mesh":0,"scale":[{s:e},{s:e},{s:e}],"rotation":[-0.8191520,0,0,0.5735764]}}],
        "scenes":[{{"nodes":[0]}}],"scene":0}}"#,
        data = base64(&quad),
    );
    std::fs::write(dir.join("node.gltf"), gltf).unwrap();
    std::fs::write(dir.join("quad.obj"), QUAD_OBJ).unwrap();
    std::fs::write(dir.join("quad.ply"), QUAD_PLY).unwrap();
    let path = dir.join(format!("{kind}.ron"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Standard base64 (the test writes one small buffer; no dependency for it).
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Renders `kind` at scale `s`: the pixels' luminances, or the loader's message.
fn render(kind: &str, s: f64) -> Result<Vec<f64>, String> {
    let dir = tempfile::tempdir().unwrap();
    let path = scene(dir.path(), kind, s);
    let loaded = crate::common::load(&path, &[]).map_err(|e| e.to_string())?;
    let film = lumis::render::render(&loaded.scene, loaded.integrator.as_ref(), 1, &|_| {})
        .expect("render")
        .0;
    crate::common::assert_finite_outputs(&film, &format!("{kind} at scale {s:e}"));
    Ok(film
        .color
        .iter()
        .map(|c| lumis::math::luminance(*c) as f64)
        .collect())
}

#[test]
fn every_scale_renders_the_same_image_or_names_its_limit() {
    let references: Vec<Vec<f64>> = KINDS
        .iter()
        .map(|kind| render(kind, 1.0).unwrap_or_else(|e| panic!("{kind} at scale 1: {e}")))
        .collect();
    for (kind, reference) in KINDS.iter().zip(&references) {
        assert!(
            reference.iter().any(|&v| v > 0.0),
            "{kind}: the unit scene is black"
        );
    }
    let mut runner = TestRunner::new(Config {
        cases: 40,
        ..Config::default()
    });
    let (rendered, refused) = (std::cell::Cell::new(0), std::cell::Cell::new(0));
    runner
        .run(&(-30.0f64..30.0), |log_scale| {
            let s = 10f64.powf(log_scale);
            for (kind, reference) in KINDS.iter().zip(&references) {
                match render(kind, s) {
                    Ok(pixels) => {
                        rendered.set(rendered.get() + 1);
                        // The same image up to rounding: a pixel may differ only where a ray
                        // grazes a silhouette or the light's edge (at most 2 of 64 here).
                        let differing = pixels
                            .iter()
                            .zip(reference)
                            .filter(|(a, b)| (*a - *b).abs() > 1e-3 * b.abs().max(1e-6))
                            .count();
                        prop_assert!(
                            differing <= 2,
                            "{} at scale {:e}: {} of 64 pixels differ from scale 1",
                            kind,
                            s,
                            differing
                        );
                    }
                    Err(e) => {
                        refused.set(refused.get() + 1);
                        prop_assert!(
                            NAMED_LIMITS.iter().any(|m| e.contains(m)),
                            "{} at scale {:e}: unexpected error {}",
                            kind,
                            s,
                            e
                        );
                        // Only scales outside the supported range are refused.
                        prop_assert!(
                            !(1e-9..=1e11).contains(&s),
                            "{} at scale {:e} is refused: {}",
                            kind,
                            s,
                            e
                        );
                    }
                }
            }
            Ok(())
        })
        .unwrap();
    // The draws cover both sides of the limits.
    let (rendered, refused) = (rendered.get(), refused.get());
    assert!(
        rendered > 0 && refused > 0,
        "{rendered} rendered, {refused} refused"
    );
}
