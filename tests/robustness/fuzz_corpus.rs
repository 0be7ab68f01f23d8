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

#[test]
fn texture_corpus_never_panics() {
    replay("texture", lumis::fuzzing::texture);
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
    // A 457-byte file declaring 33 554 435 pixels, whose ZIP data is corrupt: lumis's image
    // buffer was written in full (400 MB) before the decoder found out.
    assert!(!lumis::fuzzing::exr(&read(
        "exr/regression-large-image-corrupt-data.exr"
    )));
    // The seeds they were derived from are accepted.
    assert!(lumis::fuzzing::gltf(&read("gltf/triangle.gltf")));
    assert!(lumis::fuzzing::exr(&read("exr/tiny_f32.exr")));
}

/// EXR files of under a kilobyte that declare a 3 GB chunk, or a 33-million-pixel image whose
/// data is corrupt, are refused without touching the memory they declare: the peak resident
/// memory of `lumis render` with one as its environment map stays under 64 MiB (it was 3.0 GB
/// and 400 MB).
#[cfg(target_os = "linux")]
#[test]
fn tiny_hostile_exr_files_do_not_fill_memory() {
    use crate::common::{SMALL_SCENE, scene_file};
    // Linux counts in a child's peak memory its parent's at the time it was started (exec keeps
    // the larger of the two), and this binary's other tests hold hundreds of megabytes: the
    // test runs again in a fresh process of this binary, which starts `lumis` itself.
    const FRESH: &str = "LUMIS_TEST_FRESH_PROCESS";
    if std::env::var_os(FRESH).is_none() {
        let module = module_path!().split_once("::").map_or("", |(_, m)| m);
        let name = format!("{module}::tiny_hostile_exr_files_do_not_fill_memory");
        let out = std::process::Command::new(std::env::current_exe().unwrap())
            .args(["--exact", &name, "--test-threads", "1"])
            .env(FRESH, "1")
            .output()
            .unwrap();
        let report = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success() && report.contains("1 passed"),
            "{report}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        return;
    }
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus/exr");
    let text = SMALL_SCENE.replace(
        "    ],\n)",
        "    ],\n    emitters: [(type: \"envmap\", file: \"map.exr\")],\n)",
    );
    for (file, reason) in [
        (
            "regression-chunk-larger-than-file.exr",
            "declares more bytes than the data holds",
        ),
        (
            "regression-large-image-corrupt-data.exr",
            "zlib-compressed data malformed",
        ),
    ] {
        let (dir, _) = scene_file("scene.ron", &text);
        std::fs::copy(corpus.join(file), dir.path().join("map.exr")).unwrap();
        let errors = dir.path().join("errors.txt");
        #[expect(
            clippy::zombie_processes,
            reason = "reaped by wait4, which also gives its peak memory"
        )]
        let child = std::process::Command::new(env!("CARGO_BIN_EXE_lumis"))
            .current_dir(dir.path())
            .args(["render", "scene.ron"])
            .stdout(std::process::Stdio::null())
            .stderr(std::fs::File::create(&errors).unwrap())
            .spawn()
            .unwrap();
        let (status, peak_kib) = wait_with_peak_memory(&child);
        let message = std::fs::read_to_string(&errors).unwrap();
        assert!(status != 0 && message.contains(reason), "{file}: {message}");
        assert!(peak_kib < 64 * 1024, "{file}: peak {peak_kib} KiB");
    }
}

/// Waits for `child` and returns its exit status and its peak resident memory in KiB
/// (`wait4`'s resource usage, of that child alone).
#[cfg(target_os = "linux")]
fn wait_with_peak_memory(child: &std::process::Child) -> (libc::c_int, libc::c_long) {
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: rusage is plain data, for which all zeros is a valid value.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `pid` is this process's child, not yet waited for; both pointers are valid.
    let waited = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(waited, pid, "wait4: {}", std::io::Error::last_os_error());
    (status, usage.ru_maxrss)
}
