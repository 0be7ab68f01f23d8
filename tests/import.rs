//! Scenes from the ecosystem: one cube written as OBJ, PLY (ASCII, binary little- and
//! big-endian), glTF and Mitsuba's `.serialized` renders bit-identically to the built-in cube;
//! OBJ groups and shape options; glTF cameras, lights and materials; Mitsuba XML scenes (with
//! includes, 0.x files, filters, spectra) convert and render, and what cannot be converted is
//! named once with its file and line.
//!
//! Why one file of over 600 lines: one subject, scenes from other tools (OBJ, PLY, glTF, Mitsuba
//! XML), whose tests share the writers of the same cube in each format.

use crate::common;

use common::{lumis, render, scene_file};
use lumis::geometry::{Mesh, cube};
use lumis::scene::description::{CropDescription, SceneDescription};
use std::fmt::Write as _;
use std::path::Path;

fn obj_text(m: &Mesh) -> String {
    let mut s = String::from("# cube\nmtllib /etc/passwd\no cube\n");
    for p in &m.positions {
        writeln!(s, "v {} {} {}", p.x, p.y, p.z).unwrap();
    }
    for n in m.normals.as_ref().unwrap() {
        writeln!(s, "vn {} {} {}", n.x, n.y, n.z).unwrap();
    }
    // OBJ's v runs up the image: the loader turns it to 1 − v (exact for the cube's 0 and 1).
    for t in m.uvs.as_ref().unwrap() {
        writeln!(s, "vt {} {}", t.x, 1.0 - t.y).unwrap();
    }
    // Quads (the cube's triangle pairs share their first vertex); every other face with
    // negative indices.
    let count = m.positions.len() as i64;
    for (f, pair) in m.indices.chunks(2).enumerate() {
        let corners = [pair[0][0], pair[0][1], pair[0][2], pair[1][2]];
        s.push('f');
        for c in corners {
            let i = if f % 2 == 0 {
                c as i64 + 1
            } else {
                c as i64 - count
            };
            write!(s, " {i}/{i}/{i}").unwrap();
        }
        s.push('\n');
    }
    s
}

fn ply_bytes(m: &Mesh, format: &str) -> Vec<u8> {
    let mut out = format!(
        "ply\nformat {format} 1.0\ncomment cube\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nproperty float nx\nproperty float ny\n\
         property float nz\nproperty float u\nproperty float v\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.positions.len(),
        m.indices.len() / 2
    )
    .into_bytes();
    let normals = m.normals.as_ref().unwrap();
    let uvs = m.uvs.as_ref().unwrap();
    let quads: Vec<[u32; 4]> = m
        .indices
        .chunks(2)
        .map(|p| [p[0][0], p[0][1], p[0][2], p[1][2]])
        .collect();
    let float = |out: &mut Vec<u8>, x: f32| match format {
        "binary_big_endian" => out.extend(x.to_be_bytes()),
        _ => out.extend(x.to_le_bytes()),
    };
    let int = |out: &mut Vec<u8>, x: u32| match format {
        "binary_big_endian" => out.extend((x as i32).to_be_bytes()),
        _ => out.extend((x as i32).to_le_bytes()),
    };
    if format == "ascii" {
        let mut s = String::new();
        for ((p, n), t) in m.positions.iter().zip(normals).zip(uvs) {
            writeln!(
                s,
                "{} {} {} {} {} {} {} {}",
                p.x, p.y, p.z, n.x, n.y, n.z, t.x, t.y
            )
            .unwrap();
        }
        for q in &quads {
            writeln!(s, "4 {} {} {} {}", q[0], q[1], q[2], q[3]).unwrap();
        }
        out.extend(s.into_bytes());
    } else {
        for ((p, n), t) in m.positions.iter().zip(normals).zip(uvs) {
            for x in p
                .to_array()
                .into_iter()
                .chain(n.to_array())
                .chain(t.to_array())
            {
                float(&mut out, x);
            }
        }
        for q in &quads {
            out.push(4);
            for &i in q {
                int(&mut out, i);
            }
        }
    }
    out
}

/// A `.gltf` and its external buffer `cube.bin`: POSITION, NORMAL, TEXCOORD_0, u32 indices.
fn gltf_files(m: &Mesh) -> (String, Vec<u8>) {
    let mut bin = Vec::new();
    for p in &m.positions {
        bin.extend(p.to_array().iter().flat_map(|x| x.to_le_bytes()));
    }
    let normals_at = bin.len();
    for n in m.normals.as_ref().unwrap() {
        bin.extend(n.to_array().iter().flat_map(|x| x.to_le_bytes()));
    }
    let uvs_at = bin.len();
    for t in m.uvs.as_ref().unwrap() {
        bin.extend(t.to_array().iter().flat_map(|x| x.to_le_bytes()));
    }
    let indices_at = bin.len();
    for t in &m.indices {
        bin.extend(t.iter().flat_map(|i| i.to_le_bytes()));
    }
    let n = m.positions.len();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0,"name":"cube"}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1,"TEXCOORD_0":3}},"indices":2}}]}}],
        "buffers":[{{"byteLength":{len},"uri":"cube.bin"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{normals_at}}},
            {{"buffer":0,"byteOffset":{normals_at},"byteLength":{nlen}}},
            {{"buffer":0,"byteOffset":{indices_at},"byteLength":{ilen}}},
            {{"buffer":0,"byteOffset":{uvs_at},"byteLength":{tlen}}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{n},"type":"VEC3","min":[-1,-1,-1],"max":[1,1,1]}},
            {{"bufferView":1,"componentType":5126,"count":{n},"type":"VEC3"}},
            {{"bufferView":2,"componentType":5125,"count":{icount},"type":"SCALAR"}},
            {{"bufferView":3,"componentType":5126,"count":{n},"type":"VEC2"}}]}}"#,
        len = bin.len(),
        nlen = uvs_at - normals_at,
        tlen = indices_at - uvs_at,
        ilen = bin.len() - indices_at,
        icount = m.indices.len() * 3,
    );
    (json, bin)
}

/// A glossy cube on a floor under an area light, the cube given as `shape`.
fn cube_scene(shape: &str) -> String {
    format!(
        r#"Scene(
    camera: (position: (2.5, 2, -3), target: (0, 0.3, 0), fov: 45),
    film: (width: 32, height: 24),
    sampler: (spp: 4, seed: 3),
    integrator: (type: "balance", samples: 4),
    bsdfs: {{
        "floor": (type: "diffuse", reflectance: 0.6),
        "metal": (type: "glossy", roughness: 0.2, specular: 0.9, diffuse: 0.2),
    }},
    shapes: [
        ({shape}, bsdf: "metal", transform: (scale: (0.5, 0.5, 0.5), rotate: [(axis: (0, 1, 0), angle: 30)], translate: (0, 0.5, 0))),
        (type: "rectangle", bsdf: "floor", transform: (scale: (4, 4, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
        (type: "rectangle", bsdf: "floor",
            transform: (scale: (0.5, 0.5, 1), rotate: [(axis: (1, 0, 0), angle: 90)], translate: (0.5, 2.5, -0.5)),
            emitter: (type: "area", radiance: 8)),
    ],
)
"#
    )
}

#[test]
fn one_cube_in_every_format_renders_bit_identically() {
    let m = cube();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("cube.obj"), obj_text(&m)).unwrap();
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        std::fs::write(d.join(format!("{format}.ply")), ply_bytes(&m, format)).unwrap();
    }
    let (json, bin) = gltf_files(&m);
    std::fs::write(d.join("cube.gltf"), json).unwrap();
    std::fs::write(d.join("cube.bin"), bin).unwrap();
    // Mitsuba's `.serialized`: format 4 in f32, and format 3 in f64 as the second mesh of two.
    let serialized = lumis::scene::serialized::write;
    std::fs::write(
        d.join("cube.serialized"),
        serialized(std::slice::from_ref(&m), 4, false),
    )
    .unwrap();
    let pair = [lumis::geometry::rectangle(), m.clone()];
    std::fs::write(d.join("pair.serialized"), serialized(&pair, 3, true)).unwrap();

    // The importers give the built-in cube exactly.
    assert_eq!(
        lumis::scene::obj::load(&d.join("cube.obj"), None).unwrap(),
        m
    );
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let ply = lumis::scene::ply::load(&d.join(format!("{format}.ply"))).unwrap();
        assert_eq!(ply, m, "{format}");
    }
    assert_eq!(
        lumis::scene::gltf::load(&d.join("cube.gltf"), None).unwrap(),
        m
    );

    let reference = {
        std::fs::write(d.join("builtin.ron"), cube_scene(r#"type: "cube""#)).unwrap();
        render(&d.join("builtin.ron"), &[], 2)
    };
    assert!(reference.color.iter().any(|c| c.max_element() > 0.0));
    for (name, shape) in [
        ("obj", r#"type: "obj", file: "cube.obj""#),
        (
            "obj group",
            r#"type: "obj", file: "cube.obj", mesh: "cube""#,
        ),
        ("ply ascii", r#"type: "ply", file: "ascii.ply""#),
        ("ply le", r#"type: "ply", file: "binary_little_endian.ply""#),
        ("ply be", r#"type: "ply", file: "binary_big_endian.ply""#),
        ("gltf", r#"type: "gltf", file: "cube.gltf""#),
        (
            "serialized",
            r#"type: "serialized", file: "cube.serialized""#,
        ),
        (
            "serialized second",
            r#"type: "serialized", file: "pair.serialized", shape_index: 1"#,
        ),
    ] {
        let path = d.join(format!("{}.ron", name.replace(' ', "_")));
        std::fs::write(&path, cube_scene(shape)).unwrap();
        let film = render(&path, &[], 2);
        assert!(
            film.color == reference.color,
            "{name}: the image differs from the built-in cube's"
        );
    }
}

#[test]
fn obj_polygons_groups_and_normal_options() {
    // A pentagon in group `a`, a triangle in object `b`; normals on every corner.
    let obj = "v 0 0 0\nv 1 0 0\nv 1.5 1 0\nv 0.5 1.8 0\nv -0.5 1 0\nvn 0 0 1\n\
               g a\nf 1//1 2//1 3//1 4//1 5//1\no b\nf 1//-1 2//-1 4//-1\n";
    let all = lumis::scene::obj::parse(obj.as_bytes(), None).unwrap();
    assert_eq!(all.indices.len(), 4);
    let a = lumis::scene::obj::parse(obj.as_bytes(), Some("a")).unwrap();
    assert_eq!(a.indices, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    assert_eq!(a.normals.as_ref().unwrap().len(), 5);

    // Through a scene: `mesh` selects, `face_normals` drops the normals, `flip_normals`
    // reverses the faces; an unknown group names the file and the groups it has.
    let (dir, _) = scene_file("a.obj", obj);
    let load = |fields: &str| {
        let path = dir.path().join("s.ron");
        std::fs::write(
            &path,
            common::SMALL_SCENE.replace(
                r#"(type: "rectangle", bsdf: "white",
            transform: (scale: (3, 3, 1)"#,
                &format!(
                    r#"(type: "obj", file: "a.obj", bsdf: "white"{fields}), (type: "rectangle", bsdf: "white",
            transform: (scale: (3, 3, 1)"#
                ),
            ),
        )
        .unwrap();
        common::load(&path, &[])
    };
    let mesh_of = |loaded: lumis::scene::load::LoadedScene| match &loaded.scene.geometry.shapes()[0]
    {
        lumis::geometry::ShapeGeometry::Mesh(m) => m.clone(),
        _ => panic!("not a mesh"),
    };
    let b = mesh_of(load(r#", mesh: "b""#).unwrap());
    assert_eq!(b.indices.len(), 1);
    let flat = mesh_of(load(", face_normals: true").unwrap());
    assert_eq!(flat.normals, None);
    let flipped = mesh_of(load(", flip_normals: true").unwrap());
    assert_eq!(flipped.indices[0], [0, 2, 1]);
    assert_eq!(flipped.normals.as_ref().unwrap()[0], -glam::Vec3::Z);
    let e = load(r#", mesh: "c""#).err().unwrap().to_string();
    assert!(
        e.contains("a.obj") && e.contains("no object or group named `c`") && e.contains("a, b"),
        "{e}"
    );
}

/// A triangle's positions, the buffer `tri.bin` of [`gltf_scene_file`].
fn triangle_bin() -> Vec<u8> {
    [-1f32, 0., -1., 1., 0., -1., 0., 0., 1.]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect()
}

/// A glTF scene: a camera node, a point and a directional light (and a spot light), and two
/// materials on two meshes made of the same triangle.
fn gltf_scene_file(spot: bool) -> String {
    let third_light = if spot {
        r#",{"type":"spot","name":"spot","spot":{}}"#
    } else {
        ""
    };
    format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["KHR_lights_punctual"],
        "extensions":{{"KHR_lights_punctual":{{"lights":[
            {{"type":"point","name":"bulb","color":[1,0.5,0.25],"intensity":4}},
            {{"type":"directional","name":"sun","intensity":2}}{third_light}]}}}},
        "scene":0,"scenes":[{{"nodes":[0,1,2,3,4{spot_node}]}}],
        "nodes":[
            {{"name":"eye","camera":0,"translation":[0,1,5]}},
            {{"name":"gold","mesh":0}},
            {{"name":"clay","mesh":1,"translation":[0,0.5,0]}},
            {{"name":"bulb","translation":[1,2,3],"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}},
            {{"name":"sun","rotation":[-0.7071068,0,0,0.7071068],"extensions":{{"KHR_lights_punctual":{{"light":1}}}}}}
            {spot_def}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.5,"znear":0.1}}}}],
        "materials":[
            {{"name":"gold","pbrMetallicRoughness":{{"baseColorFactor":[1,0.75,0.25,1],"metallicFactor":1,"roughnessFactor":0.5}}}},
            {{"name":"clay","pbrMetallicRoughness":{{"baseColorFactor":[0.5,0.25,0.125,1],"metallicFactor":0,"roughnessFactor":1}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"material":0}}]}},
                  {{"primitives":[{{"attributes":{{"POSITION":0}},"material":1}}]}}],
        "buffers":[{{"byteLength":36,"uri":"tri.bin"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[-1,0,-1],"max":[1,0,1]}}]}}"#,
        spot_node = if spot { ",5" } else { "" },
        spot_def = if spot {
            r#",{"name":"cone","extensions":{"KHR_lights_punctual":{"light":2}}}"#
        } else {
            ""
        },
    )
}

const SCENE_TAIL: &str = r#"
    film: (width: 24, height: 16),
    sampler: (spp: 2, seed: 5),
    integrator: (type: "power", samples: 2),
"#;

#[test]
fn gltf_camera_lights_and_materials_equal_their_written_out_scene() {
    let (dir, _) = scene_file("s.gltf", &gltf_scene_file(false));
    std::fs::write(dir.path().join("tri.bin"), triangle_bin()).unwrap();
    let from_gltf = dir.path().join("from_gltf.ron");
    std::fs::write(
        &from_gltf,
        format!(
            r#"Scene(camera: (gltf: "s.gltf", name: "eye"),{SCENE_TAIL}
    shapes: [(type: "gltf", file: "s.gltf", lights: true)],
)"#
        ),
    )
    .unwrap();
    // The same scene written by hand with the documented mappings: camera at the node looking
    // down its −z, yfov in degrees; gold: metallic 1, roughness 0.5 → glossy α 0.25, F0 = base
    // colour, no diffuse; clay: metallic 0, roughness 1 → diffuse; the point light's intensity
    // is colour × intensity, the sun (node turned −90° about x) shines down −y.
    let sun = lumis::scene::gltf_scene::gltf_lights(
        &std::fs::read(dir.path().join("s.gltf")).unwrap(),
        &glam::Mat4::IDENTITY,
    )
    .unwrap();
    assert_eq!(sun.len(), 2);
    assert_eq!(sun[0].1.kind, "point");
    let ron::Value::Seq(d) = &sun[1].1.params["direction"] else {
        panic!()
    };
    let d: Vec<f64> = d
        .iter()
        .map(|v| match v {
            ron::Value::Number(n) => n.into_f64(),
            _ => panic!(),
        })
        .collect();
    assert!(
        (d[0]).abs() < 1e-6 && (d[1] + 1.0).abs() < 1e-6 && d[2].abs() < 1e-6,
        "sun {d:?}"
    );
    let written = dir.path().join("written.ron");
    std::fs::write(
        &written,
        format!(
            r#"Scene(camera: (position: (0, 1, 5), target: (0, 1, 4), fov: {fov}),{SCENE_TAIL}
    bsdfs: {{
        "gold": (type: "glossy", roughness: 0.25, specular: (1, 0.75, 0.25), diffuse: 0),
        "clay": (type: "diffuse", reflectance: (0.5, 0.25, 0.125)),
    }},
    shapes: [
        (type: "gltf", file: "s.gltf", mesh: "gold", bsdf: "gold"),
        (type: "gltf", file: "s.gltf", mesh: "clay", bsdf: "clay"),
    ],
    emitters: [
        (type: "point", position: (1, 2, 3), intensity: (4, 2, 1)),
        (type: "directional", direction: ({}, {}, {}), irradiance: 2),
    ],
)"#,
            d[0] as f32,
            d[1] as f32,
            d[2] as f32,
            fov = 0.5f32.to_degrees()
        ),
    )
    .unwrap();
    let a = render(&from_gltf, &[], 2);
    let b = render(&written, &[], 2);
    assert!(a.color.iter().any(|c| c.max_element() > 0.0));
    assert!(a.color == b.color, "the glTF scene renders differently");
    assert_eq!(
        common::load(&from_gltf, &[]).unwrap().scene.emitters.len(),
        2
    );
}

#[test]
fn gltf_scene_errors_name_what_is_wrong() {
    let (dir, _) = scene_file("s.gltf", &gltf_scene_file(true));
    std::fs::write(dir.path().join("tri.bin"), triangle_bin()).unwrap();
    let error = |camera: &str, shape: &str| {
        let path = dir.path().join("e.ron");
        std::fs::write(
            &path,
            format!("Scene(camera: {camera},{SCENE_TAIL} shapes: [{shape}])"),
        )
        .unwrap();
        common::load(&path, &[]).err().unwrap().to_string()
    };
    let cam = r#"(gltf: "s.gltf")"#;
    let plain = r#"(type: "gltf", file: "s.gltf")"#;
    for (camera, shape, needles) in [
        (
            cam,
            r#"(type: "gltf", file: "s.gltf", lights: true)"#,
            vec!["s.gltf", "light `spot` is a spot light"],
        ),
        (
            r#"(gltf: "s.gltf", name: "eyes")"#,
            plain,
            vec!["no camera named `eyes`", "eye"],
        ),
        (
            r#"(gltf: "s.gltf", fov: 30)"#,
            plain,
            vec!["cannot also give"],
        ),
        (
            r#"(position: (0, 0, 1), fov: 30)"#,
            plain,
            vec!["`position`, `target` and `fov`, or `gltf`"],
        ),
        (
            cam,
            r#"(type: "rectangle")"#,
            vec!["only gltf shapes can take their materials"],
        ),
        (
            cam,
            r#"(type: "gltf", file: "s.gltf", segments: 3)"#,
            vec!["`segments` does not apply"],
        ),
    ] {
        let e = error(camera, shape);
        for n in needles {
            assert!(e.contains(n), "expected `{n}` in: {e}");
        }
    }
}

/// A Mitsuba 3 scene written for this test: an OBJ in a rough conductor, a diffuse floor, an
/// area light, a point light and an env map, with `default` parameters and `$` substitution.
const MITSUBA_SCENE: &str = r#"<?xml version="1.0"?>
<scene version="3.0.0">
    <default name="res" value="24"/>
    <default name="spp" value="4"/>
    <integrator type="direct"/>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <string name="fov_axis" value="y"/>
        <transform name="to_world">
            <lookat origin="0, 2, 5" target="0, 0.5, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm">
            <integer name="width" value="$res"/>
            <integer name="height" value="16"/>
            <rfilter type="box"/>
        </film>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
            <integer name="seed" value="7"/>
        </sampler>
    </sensor>
    <bsdf type="twosided" id="metal">
        <bsdf type="roughconductor">
            <string name="distribution" value="ggx"/>
            <float name="alpha" value="0.2"/>
            <string name="material" value="none"/>
        </bsdf>
    </bsdf>
    <shape type="obj">
        <string name="filename" value="meshes/cube.obj"/>
        <transform name="to_world">
            <scale value="0.5"/>
            <rotate y="1" angle="30"/>
            <translate y="0.5"/>
        </transform>
        <ref id="metal"/>
    </shape>
    <shape type="rectangle">
        <transform name="to_world">
            <scale value="4"/>
            <rotate x="1" angle="-90"/>
        </transform>
        <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></bsdf>
    </shape>
    <shape type="rectangle">
        <transform name="to_world">
            <rotate x="1" angle="90"/>
            <translate y="3"/>
        </transform>
        <emitter type="area"><rgb name="radiance" value="5, 4, 3"/></emitter>
    </shape>
    <emitter type="point">
        <point name="position" x="1" y="2" z="1"/>
        <rgb name="intensity" value="2"/>
    </emitter>
    <emitter type="envmap">
        <string name="filename" value="sky.exr"/>
        <transform name="to_world"><rotate y="1" angle="45"/></transform>
    </emitter>
</scene>
"#;

fn write_sky(path: &Path) {
    exr::prelude::write_rgb_file(path, 8, 4, |x, y| {
        (0.2 + 0.1 * x as f32, 0.3, 0.4 + 0.05 * y as f32)
    })
    .unwrap();
}

#[test]
fn a_mitsuba_scene_converts_and_renders() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir_all(d.join("xml/meshes")).unwrap();
    std::fs::create_dir_all(d.join("out")).unwrap();
    std::fs::write(d.join("xml/meshes/cube.obj"), obj_text(&cube())).unwrap();
    write_sky(&d.join("xml/sky.exr"));
    std::fs::write(d.join("xml/scene.xml"), MITSUBA_SCENE).unwrap();

    let out = lumis(
        d,
        &[
            "import",
            "xml/scene.xml",
            "-o",
            "out/scene.ron",
            "-D",
            "spp=2",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    // A note for the shape without BSDF (Mitsuba's default diffuse), none is an error.
    assert!(
        stderr.contains("scene.xml:45: a shape without BSDF"),
        "{stderr}"
    );
    let ron = std::fs::read_to_string(d.join("out/scene.ron")).unwrap();
    for needle in [
        r#"file: "../xml/meshes/cube.obj""#,
        r#"distribution: "ggx""#,
        r#"interpolation: "bilinear", orientation: "mitsuba""#,
        "rotation: 45",
        "spp: 2, seed: 7",
        "fov: 40",
        "(width: 24, height: 16)",
    ] {
        assert!(ron.contains(needle), "`{needle}` missing in:\n{ron}");
    }
    let film = render(&d.join("out/scene.ron"), &[], 2);
    assert!(
        film.color
            .iter()
            .all(|c| c.is_finite() && c.min_element() >= 0.0)
    );
    assert!(film.color.iter().any(|c| c.max_element() > 0.0));
}

/// A Mitsuba 3 scene with every part `lumis import` converts: each shape, BSDF and emitter type,
/// a film crop, `fov_axis`, transforms by `lookat`, `matrix`, `scale`, `rotate` and `translate`.
const MITSUBA_EVERY_PART: &str = r#"<scene version="3.0.0">
    <default name="spp" value="4"/>
    <integrator type="direct">
        <integer name="emitter_samples" value="2"/>
        <integer name="bsdf_samples" value="1"/>
    </integrator>
    <sensor type="perspective">
        <float name="fov" value="50"/>
        <string name="fov_axis" value="smaller"/>
        <float name="near_clip" value="0.01"/>
        <transform name="to_world">
            <lookat origin="1, 3, 6" target="0, 0.5, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm">
            <integer name="width" value="40"/>
            <integer name="height" value="30"/>
            <integer name="crop_offset_x" value="4"/>
            <integer name="crop_offset_y" value="2"/>
            <integer name="crop_width" value="30"/>
            <rfilter type="box"/>
        </film>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
            <integer name="seed" value="3"/>
        </sampler>
    </sensor>
    <bsdf type="twosided" id="gold">
        <bsdf type="roughconductor">
            <string name="distribution" value="ggx"/>
            <float name="alpha_u" value="0.25"/>
            <float name="alpha_v" value="0.25"/>
            <string name="material" value="none"/>
        </bsdf>
    </bsdf>
    <bsdf type="conductor" id="mirror">
        <string name="material" value="none"/>
        <rgb name="specular_reflectance" value="0.9, 0.8, 0.7"/>
    </bsdf>
    <bsdf type="diffuse" id="grey">
        <spectrum name="reflectance" value="0.3"/>
    </bsdf>
    <shape type="obj">
        <string name="filename" value="cube.obj"/>
        <boolean name="face_normals" value="true"/>
        <transform name="to_world">
            <scale value="0.4"/>
            <translate x="-1" y="0.4"/>
        </transform>
        <ref id="gold"/>
    </shape>
    <shape type="ply">
        <string name="filename" value="cube.ply"/>
        <transform name="to_world">
            <scale value="0.3"/>
            <rotate y="1" angle="30"/>
            <translate x="1" y="0.3"/>
        </transform>
        <ref id="mirror"/>
    </shape>
    <shape type="sphere">
        <point name="center" x="0" y="0.5" z="1"/>
        <float name="radius" value="0.5"/>
        <bsdf type="diffuse" id="red">
            <rgb name="reflectance" value="0.7, 0.2, 0.2"/>
        </bsdf>
    </shape>
    <shape type="cube">
        <transform name="to_world">
            <matrix value="0.2 0 0 0.5  0 0.2 0 0.2  0 0 0.2 -1  0 0 0 1"/>
        </transform>
        <bsdf type="twosided">
            <bsdf type="diffuse"/>
        </bsdf>
    </shape>
    <shape type="cube">
        <transform name="to_world">
            <scale value="0.15"/>
            <translate x="-0.5" y="0.15" z="1.5"/>
        </transform>
    </shape>
    <shape type="disk">
        <transform name="to_world">
            <rotate x="1" angle="-90"/>
            <scale value="5"/>
        </transform>
        <ref id="grey"/>
    </shape>
    <shape type="rectangle">
        <boolean name="flip_normals" value="true"/>
        <transform name="to_world">
            <scale x="0.8" y="0.5"/>
            <rotate x="1" angle="-90"/>
            <rotate y="1" angle="20"/>
            <translate y="3"/>
        </transform>
        <ref id="grey"/>
        <emitter type="area">
            <rgb name="radiance" value="6, 5, 4"/>
        </emitter>
    </shape>
    <emitter type="point">
        <transform name="to_world">
            <translate x="2" y="3" z="1"/>
        </transform>
        <rgb name="intensity" value="3, 2, 1"/>
        <float name="scale" value="2"/>
    </emitter>
    <emitter type="directional">
        <vector name="direction" x="-1" y="-1" z="-0.5"/>
        <rgb name="irradiance" value="0.5"/>
    </emitter>
    <emitter type="envmap">
        <string name="filename" value="sky.exr"/>
        <float name="scale" value="0.5"/>
        <transform name="to_world">
            <rotate y="1" angle="-60"/>
        </transform>
    </emitter>
</scene>
"#;

/// `description` with every number of a plugin parameter as lumis reads it, an f32: a
/// parameter written from an f32 reads back as the nearest f64 to its shortest decimal text.
fn as_read(mut description: SceneDescription) -> SceneDescription {
    fn value(v: &mut ron::Value) {
        match v {
            ron::Value::Number(n) => *n = ron::value::Number::from(n.into_f64() as f32),
            ron::Value::Seq(items) => items.iter_mut().for_each(value),
            ron::Value::Map(map) => map.values_mut().for_each(value),
            _ => {}
        }
    }
    let d = &mut description;
    let emitters = d.shapes.iter_mut().filter_map(|s| s.emitter.as_mut());
    let plugins = emitters
        .chain(d.bsdfs.values_mut())
        .chain(d.emitters.iter_mut())
        .chain([&mut d.integrator]);
    for plugin in plugins {
        plugin.params.values_mut().for_each(value);
    }
    description
}

#[test]
fn a_converted_scene_parses_back_into_the_same_description() {
    // The assets the scenes name, which the importer checks.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir_all(d.join("xml/meshes")).unwrap();
    std::fs::write(d.join("xml/meshes/cube.obj"), obj_text(&cube())).unwrap();
    std::fs::write(d.join("xml/cube.obj"), obj_text(&cube())).unwrap();
    std::fs::write(d.join("xml/cube.ply"), ply_bytes(&cube(), "ascii")).unwrap();
    write_sky(&d.join("xml/sky.exr"));
    let converts = |xml| {
        let c = lumis::import::convert(xml, &d.join("xml/scene.xml"), &d.join("out"), &[]).unwrap();
        assert_eq!(c.problems, [], "{xml}");
        c
    };
    let c = converts(MITSUBA_EVERY_PART);
    let d = &c.description;
    assert_eq!(
        (d.shapes.len(), d.bsdfs.len(), d.emitters.len()),
        (7, 6, 3),
        "{}",
        c.ron
    );
    assert_eq!(
        d.film.crop,
        Some(CropDescription {
            x: 4,
            y: 2,
            width: 30,
            height: 28
        })
    );
    assert_eq!(d.bsdfs["gold"].kind, "roughconductor");
    assert_eq!(d.shapes[5].segments, Some(1024));
    for c in [c.clone(), converts(MITSUBA_SCENE)] {
        let parsed: SceneDescription =
            ron::from_str(&c.ron).unwrap_or_else(|e| panic!("{e} in:\n{}", c.ron));
        assert_eq!(as_read(parsed), as_read(c.description), "{}", c.ron);
    }
}

#[test]
fn what_cannot_be_converted_is_named_with_its_line_and_nothing_is_written() {
    let xml = r#"<scene version="3.0.0">
    <integrator type="volpath"/>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <float name="aperture_radius" value="0.1"/>
    </sensor>
    <bsdf type="blendbsdf" id="p"/>
    <shape type="obj">
        <string name="filename" value="x.obj"/>
    </shape><bsdf type="roughconductor" id="r"><string name="distribution" value="phong"/></bsdf>
    <!-- The missing mesh refuses its shape; the BSDF above is read at the scene's level. -->
    <shape type="sphere">
        <bsdf type="diffuse"><texture type="bitmap" name="reflectance"/></bsdf>
    </shape>
    <texture type="checkerboard"/>
    <emitter type="envmap"><string name="filename" value="sky.hdr"/></emitter>
    <emitter type="projector"/>
</scene>
"#;
    let (dir, path) = scene_file("bad.xml", xml);
    let out = lumis(dir.path(), &["import", "bad.xml", "-o", "bad.ron"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    for needle in [
        "bad.xml:2: integrator `volpath` is not converted",
        "bad.xml:5: property `aperture_radius` of the sensor is not converted",
        "bad.xml:7: BSDF `blendbsdf` is not converted",
        "bad.xml:9: mesh file `x.obj` not found",
        "bad.xml:10: microfacet distribution `phong` is not converted",
        "bad.xml:13: a bitmap texture without `filename`",
        "bad.xml:15: <texture> is not converted",
        "bad.xml:16: env map `sky.hdr`: lumis reads OpenEXR maps only",
        "bad.xml:17: emitter `projector` is not converted",
        "nothing written",
    ] {
        assert!(stderr.contains(needle), "`{needle}` missing in:\n{stderr}");
    }
    assert!(!dir.path().join("bad.ron").exists());
    drop(path);
    // --partial writes the rest.
    let out = lumis(
        dir.path(),
        &["import", "bad.xml", "-o", "bad.ron", "--partial"],
    );
    assert!(out.status.success());
    assert!(dir.path().join("bad.ron").exists());
    // An undefined parameter is an error naming it.
    let (dir, _) = scene_file(
        "p.xml",
        r#"<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="$fov"/></sensor></scene>"#,
    );
    let out = lumis(dir.path(), &["import", "p.xml", "-o", "p.ron"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("uses $fov, which no <default> or -D defines"),
        "{stderr}"
    );
}

/// Converts the scene file at `path` (read from disk, with its includes), writing names
/// relative to its folder.
fn convert_at(path: &Path) -> Result<lumis::import::Conversion, String> {
    lumis::import::convert_file(path, path.parent().unwrap(), &[])
}

fn messages(list: &[lumis::import::Problem]) -> String {
    list.iter()
        .map(|p| format!("{p}\n"))
        .collect::<Vec<_>>()
        .concat()
}

/// `<include>` brings in a file's elements (from the including file's folder), `<path>` adds
/// a folder that meshes are looked for in; a missing mesh is a problem naming where it was
/// looked for; includes that loop, a missing included file and a `<path>` to a missing folder
/// are errors naming the file, the line and the chain.
#[test]
fn includes_and_paths_resolve_as_mitsuba_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir_all(d.join("parts")).unwrap();
    std::fs::create_dir_all(d.join("assets/meshes")).unwrap();
    std::fs::write(d.join("assets/meshes/cube.obj"), obj_text(&cube())).unwrap();
    let sensor = r#"<sensor type="perspective"><float name="fov" value="40"/>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/>
        <rfilter type="box"/></film></sensor>"#;
    std::fs::write(
        d.join("main.xml"),
        format!(
            r#"<scene version="3.0.0">
    <path value="assets"/>
    {sensor}
    <include filename="parts/shapes.xml"/>
</scene>"#
        ),
    )
    .unwrap();
    std::fs::write(
        d.join("parts/shapes.xml"),
        r#"<scene version="3.0.0">
    <bsdf type="diffuse" id="white"/>
    <shape type="obj">
        <string name="filename" value="meshes/cube.obj"/>
        <ref id="white"/>
    </shape>
    <shape type="obj">
        <string name="filename" value="meshes/missing.obj"/>
    </shape>
</scene>"#,
    )
    .unwrap();
    let c = convert_at(&d.join("main.xml")).unwrap();
    assert_eq!(c.description.shapes.len(), 1, "{}", c.ron);
    assert_eq!(
        c.description.shapes[0].file.as_deref(),
        Some("assets/meshes/cube.obj")
    );
    let problems = messages(&c.problems);
    assert!(
        problems.contains("shapes.xml:8: mesh file `meshes/missing.obj` not found (looked in")
            && problems.contains("assets"),
        "{problems}"
    );
    assert_eq!(c.problems.len(), 1, "{problems}");

    // Cycles: a file that includes itself, and a loop of two.
    std::fs::write(
        d.join("self.xml"),
        "<scene version=\"3.0.0\">\n<include filename=\"self.xml\"/>\n</scene>",
    )
    .unwrap();
    let e = convert_at(&d.join("self.xml")).unwrap_err();
    assert!(e.contains("self.xml:2: <include> makes a cycle"), "{e}");
    std::fs::write(
        d.join("a.xml"),
        "<scene version=\"3.0.0\">\n<include filename=\"parts/b.xml\"/>\n</scene>",
    )
    .unwrap();
    std::fs::write(
        d.join("parts/b.xml"),
        "<scene version=\"3.0.0\">\n\n<include filename=\"../a.xml\"/>\n</scene>",
    )
    .unwrap();
    let e = convert_at(&d.join("a.xml")).unwrap_err();
    assert!(
        e.contains("b.xml:3: <include> makes a cycle")
            && e.contains("a.xml` includes")
            && e.contains("b.xml` includes"),
        "{e}"
    );
    // A missing included file, a missing folder.
    std::fs::write(
        d.join("gone.xml"),
        "<scene version=\"3.0.0\">\n<include filename=\"nowhere.xml\"/>\n</scene>",
    )
    .unwrap();
    let e = convert_at(&d.join("gone.xml")).unwrap_err();
    assert!(
        e.contains("gone.xml:2: included file `nowhere.xml` not found"),
        "{e}"
    );
    std::fs::write(
        d.join("nofolder.xml"),
        "<scene version=\"3.0.0\">\n\n<path value=\"no/such/folder\"/>\n</scene>",
    )
    .unwrap();
    let e = convert_at(&d.join("nofolder.xml")).unwrap_err();
    assert!(
        e.contains("nofolder.xml:3: <path>: folder") && e.contains("no/such/folder"),
        "{e}"
    );
}

/// A Mitsuba 0.5 file: camelCase names, `<lookAt>`, `srgb` colours and `ldrfilm`, read as
/// Mitsuba 3 upgrades them, with a note naming the version and the default that differs; a
/// 0.x conductor without `material` is copper (`Cu`, noted), a 3.x one a mirror.
#[test]
fn files_older_than_mitsuba_2_are_upgraded_with_a_note() {
    let xml = r##"<?xml version="1.0"?>
<scene version="0.5.0">
    <integrator type="direct">
        <integer name="emitterSamples" value="2"/>
        <integer name="bsdfSamples" value="2"/>
    </integrator>
    <sensor type="perspective">
        <float name="fov" value="30"/>
        <string name="fovAxis" value="y"/>
        <transform name="toWorld">
            <lookAt origin="0, 1, 5" target="0, 0.5, 0" up="0, 1, 0"/>
        </transform>
        <sampler type="ldsampler"><integer name="sampleCount" value="8"/></sampler>
        <film type="ldrfilm">
            <integer name="width" value="32"/>
            <integer name="height" value="24"/>
            <rfilter type="gaussian"><float name="stddev" value="0.25"/></rfilter>
        </film>
    </sensor>
    <bsdf type="diffuse" id="red">
        <srgb name="diffuseReflectance" value="#ff0000"/>
    </bsdf>
    <bsdf type="conductor" id="copper"/>
    <shape type="sphere">
        <float name="radius" value="0.5"/>
        <ref id="red"/>
    </shape>
    <shape type="sphere">
        <point name="center" x="1" y="0" z="0"/>
        <ref id="copper"/>
    </shape>
    <emitter type="constant"><spectrum name="radiance" value="1"/></emitter>
</scene>
"##;
    let (dir, path) = scene_file("old.xml", xml);
    let c = convert_at(&path).unwrap();
    let notes = messages(&c.notes);
    assert!(
        notes.contains("old.xml:2: a Mitsuba 0.5.0 file (before 2.0)")
            && notes.contains("copper, `Cu`"),
        "{notes}"
    );
    assert!(notes.contains("old.xml:11: <lookAt>"), "{notes}");
    assert!(
        notes
            .contains("old.xml:23: a conductor without `material` in a Mitsuba 0.5.0 file is `Cu`"),
        "{notes}"
    );
    assert_eq!(c.problems, [], "{}", messages(&c.problems));
    let d = &c.description;
    assert_eq!(d.bsdfs["red"].kind, "diffuse");
    assert_eq!((d.film.width, d.film.height), (32, 24));
    assert_eq!(d.sampler.spp, 8);
    assert_eq!(d.camera.fov, Some(30.0));
    assert_eq!(d.film.filter.stddev, Some(0.25));
    assert_eq!(d.shapes.len(), 2);
    assert_eq!(d.shapes[1].bsdf.as_deref(), Some("copper"));
    let copper = &d.bsdfs["copper"];
    assert_eq!(copper.kind, "conductor");
    assert_eq!(
        copper.params.get("material"),
        Some(&ron::Value::String("Cu".into()))
    );
    // The same conductor in a Mitsuba 3 file is a mirror.
    let (_d3, path3) = scene_file(
        "new.xml",
        &xml.replace("0.5.0", "3.0.0")
            .replace("<srgb name=\"diffuseReflectance\" value=\"#ff0000\"/>", "")
            .replace("fovAxis", "fov_axis")
            .replace("toWorld", "to_world")
            .replace("lookAt", "lookat")
            .replace("emitterSamples", "emitter_samples")
            .replace("bsdfSamples", "bsdf_samples")
            .replace("sampleCount", "sample_count")
            .replace("ldrfilm", "hdrfilm"),
    );
    let c3 = convert_at(&path3).unwrap();
    assert_eq!(c3.problems, [], "{}", messages(&c3.problems));
    let copper = &c3.description.bsdfs["copper"];
    assert_eq!(copper.kind, "conductor");
    assert_eq!(copper.params.get("material"), None);
    drop(dir);
}

/// In a 0.x file a nested texture's name is upgraded as a property's is (a `roughplastic`'s
/// `diffuseReflectance` texture is its `diffuse_reflectance`, not a refused object), and
/// `highQualityEdges`, 0.x's `sample_border`, is noted as ignored.
#[test]
fn nested_textures_and_edges_of_files_older_than_mitsuba_2_convert() {
    let xml = r##"<scene version="0.5.0">
    <sensor type="perspective">
        <float name="fov" value="30"/>
        <film type="hdrfilm">
            <integer name="width" value="8"/>
            <integer name="height" value="8"/>
            <boolean name="highQualityEdges" value="true"/>
        </film>
    </sensor>
    <bsdf type="roughplastic" id="board">
        <texture name="diffuseReflectance" type="checkerboard"/>
    </bsdf>
    <shape type="sphere"><ref id="board"/></shape>
</scene>
"##;
    let (_dir, path) = scene_file("old.xml", xml);
    let c = convert_at(&path).unwrap();
    assert_eq!(c.problems, [], "{}", messages(&c.problems));
    let notes = messages(&c.notes);
    assert!(notes.contains("old.xml:7: `highQualityEdges`"), "{notes}");
    let board = &c.description.bsdfs["board"];
    assert_eq!(board.kind, "roughplastic");
    assert!(
        matches!(
            board.params.get("diffuse_reflectance"),
            Some(ron::Value::Map(_))
        ),
        "{:?}",
        board.params
    );
}

/// The sensor: `focal_length` (and its default, 50 mm, when no `fov` is given) becomes the
/// field of view Mitsuba derives from it; `focus_distance` on a pinhole is noted and ignored;
/// a film without `rfilter` gets Mitsuba's Gaussian. Spectra on emitters are read as
/// Mitsuba's RGB variants read them; a blackbody is refused once, with its line.
#[test]
fn sensors_filters_and_spectra_convert_as_mitsuba_reads_them() {
    let scene = |sensor: &str, emitter: &str| {
        format!(
            r#"<scene version="3.0.0">
    <sensor type="perspective">
        {sensor}
        <film type="hdrfilm"><integer name="width" value="36"/><integer name="height" value="24"/></film>
    </sensor>
    {emitter}
</scene>"#
        )
    };
    let constant = r#"<emitter type="constant"><spectrum name="radiance" value="2"/></emitter>"#;
    let (_a, path) = scene_file(
        "focal.xml",
        &scene(
            r#"<string name="focal_length" value="35mm"/>
        <float name="focus_distance" value="3"/>"#,
            constant,
        ),
    );
    let c = convert_at(&path).unwrap();
    assert_eq!(c.problems, [], "{}", messages(&c.problems));
    // A 35 mm lens on 35 mm film (diagonal 43.27 mm) along the 36×24 film's diagonal: the
    // vertical field of view is 2·atan(12 / 35) = 37.85°.
    let fov = c.description.camera.fov.unwrap();
    assert!((fov - 37.849_3).abs() < 1e-3, "{fov}");
    let notes = messages(&c.notes);
    assert!(
        notes.contains("focal.xml:4: `focus_distance` is ignored"),
        "{notes}"
    );
    assert!(notes.contains("no <rfilter>: Mitsuba's default"), "{notes}");
    assert_eq!(c.description.film.filter.kind, "gaussian");
    // A uniform spectrum of 2 on an emitter: Mitsuba's RGB variants give 2 × (1.2048, 0.9483,
    // 0.9089), not grey.
    let radiance = &c.description.emitters[0].params["radiance"];
    let text = ron::to_string(radiance).unwrap();
    assert!(text.starts_with("[2.409"), "{text}");

    let (_b, path) = scene_file("default.xml", &scene("", constant));
    let c = convert_at(&path).unwrap();
    let fov = c.description.camera.fov.unwrap();
    // 50 mm: vertical 2·atan(12 / 50) = 26.99°.
    assert!((fov - 26.991).abs() < 1e-2, "{fov}");
    assert!(messages(&c.notes).contains("no `fov`: Mitsuba's default focal length, 50 mm"));

    let (_c, path) = scene_file(
        "black.xml",
        &scene(
            r#"<float name="fov" value="40"/>"#,
            r#"<emitter type="constant">
        <spectrum name="radiance" type="blackbody"><float name="temperature" value="3000"/></spectrum>
    </emitter>"#,
        ),
    );
    let c = convert_at(&path).unwrap();
    let problems = messages(&c.problems);
    assert!(
        problems.contains("black.xml:7: a blackbody spectrum is not converted"),
        "{problems}"
    );
    assert_eq!(c.problems.len(), 1, "{problems}");
    assert!(c.description.emitters.is_empty());
    // Sampled spectra that Mitsuba refuses are errors with their line.
    for (value, expect) in [("500:1", "at least two"), ("600:1, 500:2", "must increase")] {
        let (_d, path) = scene_file(
            "bad.xml",
            &scene(
                r#"<float name="fov" value="40"/>"#,
                &format!(
                    r#"<emitter type="constant"><spectrum name="radiance" value="{value}"/></emitter>"#
                ),
            ),
        );
        let e = convert_at(&path).unwrap_err();
        assert!(e.contains("bad.xml:6:") && e.contains(expect), "{e}");
    }
}

/// Refusals come once per element: an unknown BSDF with many properties is one problem, not
/// one per property; with `--partial` its shape keeps its geometry with the default BSDF.
#[test]
fn an_element_that_is_refused_is_reported_once() {
    let xml = r#"<scene version="3.0.0">
    <sensor type="perspective"><float name="fov" value="40"/></sensor>
    <bsdf type="principled" id="p">
        <rgb name="base_color" value="0.8"/>
        <float name="metallic" value="0.1"/>
        <float name="roughness" value="0.3"/>
        <float name="spec_tint" value="0.5"/>
    </bsdf>
    <shape type="sphere"><ref id="p"/></shape>
</scene>"#;
    let (_dir, path) = scene_file("once.xml", xml);
    let c = convert_at(&path).unwrap();
    assert_eq!(
        messages(&c.problems),
        format!(
            "{}:3: BSDF `principled` is not converted: lumis has no principled BSDF (none \
             verified against Mitsuba's)\n",
            path.display()
        )
    );
    assert_eq!(c.description.shapes.len(), 1);
    assert_eq!(c.description.shapes[0].bsdf.as_deref(), Some("default"));
}

/// A shape may refer to an `area` emitter given later in the file by its `id`, as Mitsuba
/// resolves references once everything is read.
#[test]
fn shapes_take_area_emitters_defined_after_them() {
    let xml = r#"<scene version="3.0.0">
    <sensor type="perspective"><float name="fov" value="40"/></sensor>
    <shape type="rectangle">
        <ref id="light"/>
        <bsdf type="diffuse"/>
    </shape>
    <emitter type="area" id="light"><rgb name="radiance" value="3"/></emitter>
</scene>"#;
    let (_dir, path) = scene_file("later.xml", xml);
    let c = convert_at(&path).unwrap();
    assert_eq!(c.problems, [], "{}", messages(&c.problems));
    let emitter = c.description.shapes[0].emitter.as_ref().unwrap();
    assert_eq!(emitter.kind, "area");
}

/// Mitsuba's `direct` with one technique becomes lumis' `light` or `bsdf` with its sample count.
/// Its emitter samples of a delta light are each weighted 1, not 1/`emitter_samples`
/// (direct.cpp): the delta lights' `scale` is multiplied by `emitter_samples` (they are left out
/// at 0, as BSDF samples never reach them), with a note; area and env lights are unchanged.
#[test]
fn direct_converts_each_technique_and_mitsubas_delta_light_weight() {
    let scene = |integrator: &str| {
        format!(
            r#"<scene version="3.0.0">
    <integrator type="direct">{integrator}</integrator>
    <sensor type="perspective"><float name="fov" value="40"/></sensor>
    <shape type="sphere"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
    <emitter type="point"><point name="position" x="0" y="2" z="0"/><rgb name="intensity" value="3"/><float name="scale" value="2"/></emitter>
    <emitter type="spot"><rgb name="intensity" value="1"/></emitter>
</scene>"#
        )
    };
    let convert = |integrator: &str| {
        let (dir, path) = scene_file("direct.xml", &scene(integrator));
        let c = convert_at(&path);
        drop(dir);
        c
    };
    let scales = |c: &lumis::import::Conversion| -> Vec<(String, String)> {
        c.description
            .emitters
            .iter()
            .map(|e| (e.kind.clone(), ron::to_string(&e.params["scale"]).unwrap()))
            .collect()
    };
    let samples = |c: &lumis::import::Conversion| {
        let i = &c.description.integrator;
        (
            i.kind.clone(),
            ron::to_string(&i.params["samples"]).unwrap(),
        )
    };

    let c = convert(
        r#"<integer name="emitter_samples" value="4"/><integer name="bsdf_samples" value="0"/>"#,
    )
    .unwrap();
    assert_eq!(c.problems, [], "{}", messages(&c.problems));
    assert_eq!(samples(&c), ("light".into(), "4".into()));
    assert_eq!(
        scales(&c),
        [
            ("point".into(), "8.0".into()),
            ("spot".into(), "4.0".into())
        ]
    );
    let notes = messages(&c.notes);
    assert!(
        notes.contains("direct.xml:2: `direct` (4 emitter + 0 BSDF samples"),
        "{notes}"
    );
    assert!(
        notes.contains("2 point, spot or directional light(s) 4 times as bright"),
        "{notes}"
    );

    let c = convert(r#"<integer name="emitter_samples" value="0"/>"#).unwrap();
    assert_eq!(c.problems, [], "{}", messages(&c.problems));
    assert_eq!(samples(&c), ("bsdf".into(), "1".into()));
    assert!(c.description.emitters.is_empty(), "{}", c.ron);
    assert_eq!(
        c.description.shapes[0].emitter.as_ref().unwrap().kind,
        "area"
    );
    assert!(messages(&c.notes).contains("never reaches a delta light"));

    // One sample of each: the power heuristic, and every light as the file gives it.
    let c = convert("").unwrap();
    assert_eq!(samples(&c), ("power".into(), "2".into()));
    assert_eq!(
        scales(&c),
        [
            ("point".into(), "2.0".into()),
            ("spot".into(), "1.0".into())
        ]
    );
    assert!(!messages(&c.notes).contains("times as bright"));

    // What Mitsuba refuses, refused with the line.
    for (integrator, expect) in [
        (
            r#"<integer name="emitter_samples" value="0"/><integer name="bsdf_samples" value="0"/>"#,
            "direct.xml:2: `direct` with no emitter and no BSDF sample",
        ),
        (
            r#"<integer name="shading_samples" value="2"/><integer name="bsdf_samples" value="1"/>"#,
            "direct.xml:2: `shading_samples` with `emitter_samples` or `bsdf_samples`",
        ),
        (
            r#"<integer name="bsdf_samples" value="-1"/>"#,
            "direct.xml:2: `bsdf_samples` must be a non-negative integer",
        ),
    ] {
        let c = convert(integrator).unwrap();
        let problems = messages(&c.problems);
        assert!(problems.contains(expect), "{problems}");
    }
}

/// Mitsuba 3 does not normalise a rotation axis (Dr.Jit's `rotate`): (0, 1, 1) at 90° turns
/// and stretches, and is converted as Mitsuba reads it, with a note.
#[test]
fn a_rotation_about_an_axis_of_other_length_is_read_as_mitsuba_reads_it() {
    let xml = r#"<scene version="3.0.0">
    <sensor type="perspective"><float name="fov" value="40"/></sensor>
    <shape type="sphere">
        <transform name="to_world"><rotate y="1" z="1" angle="90"/></transform>
    </shape>
</scene>"#;
    let (_dir, path) = scene_file("axis.xml", xml);
    let c = convert_at(&path).unwrap();
    assert_eq!(c.problems, [], "{}", messages(&c.problems));
    assert!(messages(&c.notes).contains("axis.xml:4: the rotation axis (0, 1, 1) is not of unit"));
    let text = ron::to_string(&c.description.shapes[0].transform).unwrap();
    // c I + (1 − c) a aᵀ + s [a]× at c = 0, s = 1, a = (0, 1, 1), row by row (as Mitsuba's
    // Python `ScalarTransform4f().rotate([0, 1, 1], 90)` gives it).
    assert!(
        text.contains("(0.0,-1.0,1.0,0.0,1.0,1.0,1.0,0.0,-1.0,1.0,1.0,0.0,0.0,0.0,0.0,1.0)"),
        "{text}"
    );
}

/// Mitsuba reads `$name` parameters in document order, an included file where its `<include>`
/// is: a `<default>` in an included file serves what comes after the include (in the including
/// file too), and a parameter used before the `<default>` that defines it is refused, as
/// Mitsuba refuses it, unless `-D` gives it.
#[test]
fn parameters_defined_later_in_an_include_are_refused_as_mitsuba_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("inc.xml"),
        r#"<scene version="3.0.0"><default name="fov" value="40"/></scene>"#,
    )
    .unwrap();
    let scene = |first: &str, second: &str| {
        format!(
            r#"<scene version="3.0.0">
    {first}
    {second}
</scene>"#
        )
    };
    let include = r#"<include filename="inc.xml"/>"#;
    let sensor = r#"<sensor type="perspective"><float name="fov" value="$fov"/></sensor>"#;
    std::fs::write(d.join("after.xml"), scene(include, sensor)).unwrap();
    // `fov` is horizontal in Mitsuba, vertical in lumis: 2·atan(tan(20°) · 576/768) = 30.537°
    // on Mitsuba's default 768×576 film.
    let vertical = |c: &lumis::import::Conversion| c.description.camera.fov.unwrap();
    let c = convert_at(&d.join("after.xml")).unwrap();
    assert!((vertical(&c) - 30.537).abs() < 1e-3, "{}", vertical(&c));

    std::fs::write(d.join("before.xml"), scene(sensor, include)).unwrap();
    let e = convert_at(&d.join("before.xml")).unwrap_err();
    assert!(
        e.contains("before.xml:2: `$fov` is used before the <default> that defines it"),
        "{e}"
    );
    let given = [("fov".to_string(), "30".to_string())];
    let c = lumis::import::convert_file(&d.join("before.xml"), d, &given).unwrap();
    // 2·atan(tan(15°) · 576/768) = 22.73°.
    assert!((vertical(&c) - 22.73).abs() < 1e-2, "{}", vertical(&c));
}

/// Through the whole chain (Mitsuba XML → `lumis import` → RON → scene loader → a ray's hit):
/// a PLY mesh without normals gets Mitsuba's smooth vertex normals. On an octahedron each
/// vertex's angle-weighted normal is its own direction (by symmetry), so a hit near the +z
/// corner of the (+x, +y, +z) face has the interpolated shading normal there, not the face's;
/// with `face_normals` the shading normal is the face's.
#[test]
fn a_mesh_without_normals_is_shaded_smooth_once_loaded() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let vertices = [
        [1.0f32, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ];
    // Counter-clockwise seen from outside.
    let faces = [
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ];
    let mut ply = String::from(
        "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\n\
         property float z\nelement face 8\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for v in vertices {
        writeln!(ply, "{} {} {}", v[0], v[1], v[2]).unwrap();
    }
    for f in faces {
        writeln!(ply, "3 {} {} {}", f[0], f[1], f[2]).unwrap();
    }
    std::fs::write(d.join("octahedron.ply"), ply).unwrap();
    let hit_normals = |options: &str| {
        let xml = format!(
            r#"<scene version="3.0.0">
    <sensor type="perspective"><float name="fov" value="40"/></sensor>
    <shape type="ply"><string name="filename" value="octahedron.ply"/>{options}</shape>
</scene>"#
        );
        std::fs::write(d.join("scene.xml"), xml).unwrap();
        let c = convert_at(&d.join("scene.xml")).unwrap();
        assert_eq!(c.problems, [], "{}", messages(&c.problems));
        std::fs::write(d.join("scene.ron"), &c.ron).unwrap();
        let loaded = common::load(&d.join("scene.ron"), &[]).unwrap();
        // Toward the point with barycentrics (0.1, 0.1, 0.8) of the face (+x, +y, +z).
        let target = glam::Vec3::new(0.1, 0.1, 0.8);
        let origin = target * 3.0;
        let ray = lumis::geometry::Ray {
            origin,
            direction: (target - origin).normalize(),
            t_max: f32::INFINITY,
        };
        let hit = loaded
            .scene
            .intersect(&ray)
            .expect("the ray meets the octahedron");
        (hit.shading_normal, hit.geometric_normal)
    };
    let face = glam::Vec3::ONE.normalize();
    let smooth = glam::Vec3::new(0.1, 0.1, 0.8).normalize();
    let (shading, geometric) = hit_normals("");
    assert!(geometric.abs_diff_eq(face, 1e-5), "{geometric}");
    assert!(
        shading.abs_diff_eq(smooth, 1e-4),
        "{shading} instead of {smooth}"
    );
    let (shading, _) = hit_normals(r#"<boolean name="face_normals" value="true"/>"#);
    assert!(shading.abs_diff_eq(face, 1e-5), "{shading}");
}

/// A spot light with a texture and an env map under a scaling transform are each refused once,
/// with the reason, and left out.
#[test]
fn spot_textures_and_scaled_env_maps_are_refused_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_sky(&d.join("sky.exr"));
    let xml = r#"<scene version="3.0.0">
    <sensor type="perspective"><float name="fov" value="40"/></sensor>
    <emitter type="spot">
        <rgb name="intensity" value="1"/>
        <float name="cutoff_angle" value="30"/>
        <texture type="bitmap" name="texture"><string name="filename" value="sky.exr"/></texture>
    </emitter>
    <emitter type="envmap">
        <string name="filename" value="sky.exr"/>
        <transform name="to_world"><scale value="2"/></transform>
    </emitter>
</scene>"#;
    std::fs::write(d.join("refused.xml"), xml).unwrap();
    let c = convert_at(&d.join("refused.xml")).unwrap();
    let problems = messages(&c.problems);
    assert_eq!(c.problems.len(), 2, "{problems}");
    assert!(
        problems.contains("refused.xml:6: a spot light with a `texture`"),
        "{problems}"
    );
    assert!(
        problems.contains("refused.xml:8: an env map's `to_world` that scales"),
        "{problems}"
    );
    assert!(c.description.emitters.is_empty());
}
