//! Replays the fuzzers' committed corpora (`fuzz/corpus/<target>/`) through the same entry
//! points the fuzz targets call: every input must give a result or an error, never a panic, so
//! a regression on anything the fuzzers once found fails here, in the ordinary test suite.

use std::path::Path;

fn replay(target: &str, run: fn(&[u8]) -> bool) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target);
    let mut inputs = 0;
    let mut accepted = 0;
    for entry in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.unwrap().path();
        let data = std::fs::read(&path).unwrap();
        let outcome = std::panic::catch_unwind(|| run(&data));
        let ok = outcome.unwrap_or_else(|_| panic!("{target}: {} panicked", path.display()));
        inputs += 1;
        accepted += ok as usize;
    }
    assert!(inputs > 0, "{target}: empty corpus");
    // The seeds include valid files: an entry point that refuses everything tests nothing.
    assert!(accepted > 0, "{target}: no input of {inputs} was accepted");
}

#[test]
fn scene_corpus_never_panics() {
    replay("scene", lumis::fuzzing::scene);
}

#[test]
fn gltf_corpus_never_panics() {
    replay("gltf", lumis::fuzzing::gltf);
}

#[test]
fn exr_corpus_never_panics() {
    replay("exr", lumis::fuzzing::exr);
}

/// The defects the fuzzers found, kept as named inputs: each must be refused with an error.
#[test]
fn inputs_that_once_crashed_are_refused() {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus");
    let read = |p: &str| std::fs::read(corpus.join(p)).unwrap();
    // gltf-json indexed `accessors` with a dangling POSITION index and panicked.
    assert!(!lumis::fuzzing::gltf(&read(
        "gltf/regression-dangling-position-accessor.gltf"
    )));
    // gltf's reader hit `unreachable!` on float indices.
    assert!(!lumis::fuzzing::gltf(&read(
        "gltf/regression-float-indices.gltf"
    )));
    // A header declaring 2^60 pixels made the EXR decoder allocate them.
    assert!(!lumis::fuzzing::exr(&read(
        "exr/regression-huge-data-window.exr"
    )));
    // A 584-byte file declared a 3 GB chunk, which the decoder allocated and zeroed (9 s).
    let e = lumis::image_io::decode_exr_rgb(&read("exr/regression-chunk-larger-than-file.exr"))
        .expect_err("refused");
    assert!(
        format!("{e:?}").contains("declares more bytes than the data holds"),
        "{e:?}"
    );
    // The seeds they were derived from are accepted.
    assert!(lumis::fuzzing::gltf(&read("gltf/triangle.gltf")));
    assert!(lumis::fuzzing::exr(&read("exr/tiny_f32.exr")));
}
