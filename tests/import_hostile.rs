//! Hostile OBJ and PLY files (`tests/hostile-import/`), each loaded through a scene: every one
//! gives the error its file announces (`# expect: ...` in OBJ, `comment expect: ...` in the PLY
//! header) naming the file, or loads (`expect: ok`), and none panics. Then the fuzzers' seed
//! corpora for the importers (`fuzz/corpus/{obj,ply,mitsuba_xml,serialized}`) replayed through the fuzz
//! targets' entry points, for when cargo-fuzz is not at hand.

use crate::common;

use std::path::{Path, PathBuf};

fn repo(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

/// The text after `marker` on its line, in the file's first lines.
fn annotation(bytes: &[u8], marker: &str) -> Option<String> {
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(400)]);
    head.lines().find_map(|l| {
        l.split_once(marker)
            .map(|(_, rest)| rest.trim().to_string())
    })
}

#[test]
fn hostile_meshes_give_their_announced_errors_and_never_panic() {
    let dir = repo("tests/hostile-import");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    let (mut refused, mut accepted) = (0, 0);
    let mut wrong = Vec::new();
    for file in &files {
        let bytes = std::fs::read(file).unwrap();
        let name = file.file_name().unwrap().to_str().unwrap();
        let kind = file.extension().unwrap().to_str().unwrap();
        let expect = annotation(&bytes, "expect: ")
            .unwrap_or_else(|| panic!("{name}: no `expect:` annotation"));
        let mesh =
            annotation(&bytes, "# mesh: ").map_or(String::new(), |m| format!(", mesh: {m:?}"));
        let work = tempfile::tempdir().unwrap();
        std::fs::copy(file, work.path().join(name)).unwrap();
        let scene = work.path().join("scene.ron");
        std::fs::write(
            &scene,
            common::SMALL_SCENE.replace(
                "shapes: [",
                &format!(r#"shapes: [(type: "{kind}", file: "{name}", bsdf: "white"{mesh}),"#),
            ),
        )
        .unwrap();
        let outcome = std::panic::catch_unwind(|| common::load(&scene, &[]).map(|_| ()))
            .unwrap_or_else(|_| panic!("{name}: the loader panicked"));
        match (expect.as_str(), outcome) {
            ("ok", Ok(())) => accepted += 1,
            ("ok", Err(e)) => wrong.push(format!("{name}: expected to load, got: {e}")),
            (_, Ok(())) => wrong.push(format!("{name}: expected an error with `{expect}`")),
            (_, Err(e)) => {
                let e = e.to_string();
                if e.contains(&expect) && e.contains(name) {
                    refused += 1;
                } else {
                    wrong.push(format!(
                        "{name}: expected the file name and `{expect}` in: {e}"
                    ));
                }
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    assert!(
        refused >= 40 && accepted >= 5,
        "{refused} refused, {accepted} accepted"
    );
}

fn replay(target: &str, run: fn(&[u8]) -> bool) {
    let dir = repo("fuzz/corpus").join(target);
    let mut inputs = 0;
    let mut accepted = 0;
    for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.unwrap().path();
        let data = std::fs::read(&path).unwrap();
        let ok = std::panic::catch_unwind(|| run(&data))
            .unwrap_or_else(|_| panic!("{target}: {} panicked", path.display()));
        inputs += 1;
        accepted += ok as usize;
    }
    assert!(inputs > 0, "{target}: empty corpus");
    // Seeds include valid files: an entry point that refuses everything tests nothing.
    assert!(accepted > 0, "{target}: no input of {inputs} was accepted");
}

#[test]
fn importer_fuzz_corpora_never_panic() {
    replay("obj", lumis::fuzzing::obj);
    replay("ply", lumis::fuzzing::ply);
    replay("mitsuba_xml", lumis::fuzzing::mitsuba_xml);
    replay("serialized", lumis::fuzzing::serialized);
}

/// The hostile `.serialized` seeds of the fuzz corpus, each loaded through a scene: the
/// error names the file and the problem (binary files carry no annotation, so the expected
/// errors are listed here).
#[test]
fn hostile_serialized_meshes_give_clear_errors() {
    let dir = repo("fuzz/corpus/serialized");
    for (name, expect) in [
        ("truncated", "the zlib stream ends or is corrupt"),
        ("version-5", "version 5 is not read"),
        ("counts-overflow", "more than its zlib stream"),
        ("bomb-declared-huge", "more than its zlib stream"),
        ("index-out-of-range", "vertex index 9 is out of range"),
        ("nan-position", "is not finite"),
        ("not-serialized", "not a Mitsuba serialized mesh"),
        ("v4-quad", "ok"),
        ("v3-quad-double", "ok"),
        ("v4-two-meshes", "ok"),
    ] {
        let work = tempfile::tempdir().unwrap();
        let file = format!("{name}.serialized");
        std::fs::copy(dir.join(name), work.path().join(&file)).unwrap();
        let scene = work.path().join("scene.ron");
        std::fs::write(
            &scene,
            common::SMALL_SCENE.replace(
                "shapes: [",
                &format!(r#"shapes: [(type: "serialized", file: "{file}", bsdf: "white"),"#),
            ),
        )
        .unwrap();
        let outcome = std::panic::catch_unwind(|| common::load(&scene, &[]).map(|_| ()))
            .unwrap_or_else(|_| panic!("{name}: the loader panicked"));
        match (expect, outcome) {
            ("ok", outcome) => outcome.unwrap_or_else(|e| panic!("{name}: {e}")),
            (_, Ok(())) => panic!("{name}: expected an error with `{expect}`"),
            (_, Err(e)) => {
                let e = e.to_string();
                assert!(e.contains(expect) && e.contains(&file), "{name}: {e}");
            }
        }
    }
}

/// Hostile Mitsuba scenes (`fuzz/corpus/mitsuba_xml/hostile-*.xml`, also fuzzing seeds): each
/// gives an error or a problem naming the file, the line and the problem, and none panics.
#[test]
fn hostile_mitsuba_scenes_give_clear_errors() {
    let dir = repo("fuzz/corpus/mitsuba_xml");
    for (name, line, expect) in [
        ("hostile-include-self.xml", 2, "<include> makes a cycle"),
        ("hostile-path-missing.xml", 2, "<path>: folder"),
        ("hostile-spectrum-one-pair.xml", 3, "at least two"),
        (
            "hostile-spectrum-unsorted.xml",
            3,
            "wavelengths must increase",
        ),
        (
            "hostile-spot-cutoff-zero.xml",
            5,
            "`cutoff_angle` of 0° is out of range",
        ),
        (
            "hostile-spot-cutoff-over-180.xml",
            5,
            "`cutoff_angle` of 270° is out of range",
        ),
        (
            "hostile-filter-radius-zero.xml",
            7,
            "tent filter `radius` must be in",
        ),
        (
            "hostile-filter-stddev-huge.xml",
            7,
            "gaussian filter `stddev` must be in",
        ),
        ("hostile-version-missing.xml", 1, "has no `version`"),
    ] {
        let work = tempfile::tempdir().unwrap();
        let path = work.path().join(name);
        std::fs::copy(dir.join(name), &path).unwrap();
        let outcome = std::panic::catch_unwind(|| {
            lumis::import::convert_file(&path, work.path(), &[]).map(|c| {
                c.problems
                    .iter()
                    .map(|p| format!("{p}\n"))
                    .collect::<String>()
            })
        })
        .unwrap_or_else(|_| panic!("{name}: the importer panicked"));
        let message = outcome.unwrap_or_else(|e| e);
        let at = format!("{name}:{line}:");
        assert!(
            message.contains(&at) && message.contains(expect),
            "{name}: expected `{at}` and `{expect}` in: {message}"
        );
    }
}
