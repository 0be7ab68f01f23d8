//! Hostile OBJ and PLY files (`tests/hostile-import/`), each loaded through a scene: every one
//! gives the error its file announces (`# expect: ...` in OBJ, `comment expect: ...` in the PLY
//! header) naming the file, or loads (`expect: ok`), and none panics. Then the fuzzers' seed
//! corpora for the importers (`fuzz/corpus/{obj,ply,mitsuba_xml}`) replayed through the fuzz
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
}
