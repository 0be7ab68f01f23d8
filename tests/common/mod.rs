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
) -> Result<lumis::scene::load::LoadedScene, lumis::error::SceneError> {
    lumis::link_plugins();
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    lumis::scene::load::load_scene(path, &overrides)
}

/// The names of every registered built-in integrator of direct lighting, so that a new one is
/// tested without being listed anywhere: all but `path`, whose light goes past one bounce. (With
/// `max_depth` 2, `path` gives each of their images bit for bit, tests/path.rs, so what these
/// tests check of them holds for it.)
pub fn integrators() -> Vec<&'static str> {
    use lumis::registry::{IntegratorPlugin, PluginInfo, builtin};
    lumis::link_plugins();
    builtin::<IntegratorPlugin>()
        .iter()
        .map(|p| p.name())
        .filter(|&name| name != lumis::integrators::path::NAME)
        .collect()
}

/// The example plugin library `lumis-oren-nayar`, which cargo builds with the tests (a
/// dev-dependency, its cdylib beside this test's executable): found from the executable's own
/// path, wherever the target directory is (`CARGO_TARGET_DIR`, `--target-dir`).
pub fn example_library() -> &'static Path {
    static LIBRARY: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    LIBRARY.get_or_init(|| {
        let file = format!(
            "{}lumis_oren_nayar{}",
            std::env::consts::DLL_PREFIX,
            std::env::consts::DLL_SUFFIX
        );
        // <target dir>/<profile>/deps/<this test>: the library is in the same directory.
        let exe = std::env::current_exe().expect("the test executable's path");
        let built = exe.with_file_name(&file);
        assert!(
            built.exists(),
            "{} not built (it is a dev-dependency of lumis: `cargo test` builds it)",
            built.display()
        );
        built
    })
}

/// A PNG file, decoded.
pub struct Png {
    pub width: u32,
    pub height: u32,
    pub color: png::ColorType,
    pub bytes: Vec<u8>,
}

/// Decodes the PNG at `path` whole; panics, naming the file, if it is not a complete PNG.
pub fn read_png(path: &Path) -> Png {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut bytes = vec![
        0;
        reader
            .output_buffer_size()
            .expect("a PNG that fits in memory")
    ];
    let frame = reader
        .next_frame(&mut bytes)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    bytes.truncate(frame.buffer_size());
    Png {
        width: frame.width,
        height: frame.height,
        color: frame.color_type,
        bytes,
    }
}

pub use lumis::chi2::mean_and_standard_error;

/// The scene rendered with `threads` threads as `lumis render` does: the integrator's `preprocess` (pilot passes, cost
/// measurements) first.
pub fn render(path: &Path, overrides: &[&str], threads: usize) -> lumis::film::Film {
    let mut loaded = load(path, overrides).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    render_with(&loaded.scene, loaded.integrator.as_mut(), threads)
}

/// Renders a built scene with `integrator`, after its preprocessing.
pub fn render_with(
    scene: &lumis::scene::Scene,
    integrator: &mut dyn lumis::integrator::Integrator,
    threads: usize,
) -> lumis::film::Film {
    integrator.preprocess(scene);
    lumis::render::render(scene, integrator, threads, &|_| {})
        .expect("render")
        .0
}

/// Every pixel and every AOV value is finite and non-negative.
pub fn assert_finite_outputs(film: &lumis::film::Film, name: &str) {
    assert!(
        film.color
            .iter()
            .all(|c| c.is_finite() && c.min_element() >= 0.0),
        "{name}: bad pixel"
    );
    assert!(
        film.aov_data.iter().all(|v| v.is_finite() && *v >= 0.0),
        "{name}: bad AOV value"
    );
}

/// Renders the passes of `state` that `settings` plan, as `scope` says (its threads, shard,
/// budgets and most passes), raising the cancel after `cancel_at` tiles; `on_pass` sees the
/// state after each pass.
pub fn run_passes(
    loaded: &mut lumis::scene::load::LoadedScene,
    state: &mut lumis::progressive::RenderState,
    settings: &lumis::passes::Settings,
    scope: lumis::progressive::Scope,
    cancel_at: Option<u64>,
    on_pass: &mut dyn FnMut(&lumis::progressive::RenderState) -> lumis::progressive::Control,
) -> lumis::progressive::Outcome {
    let tiles = std::sync::atomic::AtomicU64::new(0);
    let cancel = std::sync::atomic::AtomicBool::new(false);
    lumis::progressive::run(
        &loaded.scene,
        loaded.integrator.as_mut(),
        settings,
        state,
        scope,
        &cancel,
        &|_| {
            let done = tiles.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            if Some(done) == cancel_at {
                cancel.store(true, std::sync::atomic::Ordering::Relaxed);
            }
        },
        on_pass,
    )
    .expect("render")
}

/// A packet of camera samples shaded both ways ([`shade_packet_both_ways`]): the samples as
/// `shade` one by one left them, as `shade_together` left them, and the colours `shade` gave.
pub struct PacketShadedBothWays {
    pub alone: Vec<lumis::integrator::CameraSample>,
    pub together: Vec<lumis::integrator::CameraSample>,
    pub expected: Vec<lumis::math::Rgb>,
}

/// Shades camera samples `indices` of `pixel` with `integrator` one by one (`shade`, their
/// primary rays traced together first) and as one wave (`shade_together`; the rays traced
/// beforehand only for whole packets of 16: a shorter wave's are left for the integrator to
/// trace, which it must do as `trace_together` would), and asserts that both ways give the same
/// colours and pixel sums, bit for bit (`name` names the case in the messages).
pub fn shade_packet_both_ways(
    scene: &lumis::scene::Scene,
    integrator: &dyn lumis::integrator::Integrator,
    pixel: glam::UVec2,
    indices: std::ops::Range<u32>,
    name: &str,
) -> PacketShadedBothWays {
    use lumis::integrator::{CameraSample, PacketSums};
    use lumis::math::Rgb;
    let packet = |traced: bool| -> Vec<CameraSample> {
        let mut samples: Vec<CameraSample> = indices
            .clone()
            .map(|s| CameraSample::new(scene, pixel, s))
            .collect();
        if traced {
            CameraSample::trace_together(scene, &mut samples);
        }
        samples
    };
    let traced = indices.len().is_multiple_of(lumis::geometry::PACKET_SIZE);
    let (mut alone, mut together) = (packet(true), packet(traced));
    let stride = integrator.pixel_sums(scene);
    let mut sums_alone = vec![0.0; stride];
    let expected: Vec<Rgb> = alone
        .iter_mut()
        .map(|s| integrator.shade(scene, s, &mut sums_alone))
        .collect();
    let mut sums_together = vec![0.0; stride];
    let mut radiance = vec![Rgb::ZERO; together.len()];
    let mut sums = PacketSums::one_pixel(&mut sums_together, together.len());
    integrator.shade_together(scene, &mut together, &mut sums, &mut radiance);
    let bits =
        |v: &[Rgb]| -> Vec<[u32; 3]> { v.iter().map(|c| c.to_array().map(f32::to_bits)).collect() };
    assert_eq!(bits(&radiance), bits(&expected), "{name}, pixel {pixel}");
    let sum_bits = |v: &[f64]| -> Vec<u64> { v.iter().map(|x| x.to_bits()).collect() };
    assert_eq!(
        sum_bits(&sums_together),
        sum_bits(&sums_alone),
        "{name}, pixel {pixel}: sums"
    );
    PacketShadedBothWays {
        alone,
        together,
        expected,
    }
}

/// Every `n`th pixel of `scene`'s film, in row order over the whole film.
pub fn every_nth_pixel(scene: &lumis::scene::Scene, n: usize) -> Vec<glam::UVec2> {
    (0..scene.width * scene.height)
        .step_by(n)
        .map(|i| glam::UVec2::new(i % scene.width, i / scene.width))
        .collect()
}

/// The integrator that `path` (whose text is `text`) describes with `overrides`, built and
/// preprocessed for `scene` (that file loaded); `name` names the case in the messages.
pub fn preprocessed_integrator(
    path: &Path,
    text: &str,
    overrides: &[String],
    scene: &lumis::scene::Scene,
    name: &str,
) -> Box<dyn lumis::integrator::Integrator> {
    let description = lumis::scene::load::parse_description(path, text, overrides)
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    let parent = path.parent().expect("a scene file is in a directory");
    let mut built = lumis::scene::load::build_integrator(&description.integrator, parent)
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    built.preprocess(scene);
    built
}
