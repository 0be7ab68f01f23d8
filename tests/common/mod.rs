//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A small valid scene: a diffuse floor under a square area light, 16×16 pixels.
pub const SMALL_SCENE: &str = r#"Scene(
    camera: (position: (0, 2, -4), target: (0, 0, 0), fov: 40),
    film: (width: 16, height: 16),
    sampler: (spp: 2, seed: 1),
    integrator: (type: "balance", samples: 4),
    bsdfs: {
        "white": (type: "diffuse", reflectance: 0.8),
    },
    shapes: [
        (type: "rectangle", bsdf: "white",
            transform: (scale: (3, 3, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
        (type: "rectangle", bsdf: "white",
            transform: (scale: (0.5, 0.5, 1), rotate: [(axis: (1, 0, 0), angle: 90)], translate: (0, 2, 0)),
            emitter: (type: "area", radiance: (5, 5, 5))),
    ],
)
"#;

/// Writes `text` as `name` in a fresh temporary directory, returning both.
pub fn scene_file(name: &str, text: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join(name);
    std::fs::write(&path, text).expect("write scene");
    (dir, path)
}

/// Runs the `lumis` binary in `cwd` with `args`.
pub fn lumis(cwd: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lumis"))
        .current_dir(cwd)
        .args(args)
        .output()
        .expect("run lumis")
}

/// Loads a scene through the library (with every built-in plugin linked).
pub fn load(
    path: &Path,
    overrides: &[&str],
) -> Result<lumis::scene::LoadedScene, lumis::error::SceneError> {
    lumis::link_plugins();
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    lumis::scene::load_scene(path, &overrides)
}
