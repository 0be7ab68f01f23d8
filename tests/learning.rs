//! Renders in passes that learn (docs/integrators.md, "Per-pixel budgets" and "Learned α"): per-
//! pixel budgets and α learned from earlier passes converge to `balance`'s image (the same-mean
//! test with its power, on the glossy env-map scene, the Veach layout and paper scene 04); the
//! first pass's α is the default, and α of pass k is a function of the passes before it only.

use crate::common;
use crate::integrators::{InPasses, RUNS, Runs, same_mean_rendered, same_mean_scene};
use lumis::budgets::Budgets;
use lumis::integrators::{alpha, aovs, balance, cost_alpha, exact_alpha, pooled_alpha};
use lumis::passes::{Settings, Stopping};
use lumis::progressive::{Control, Ending, RenderState, Scope};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// The relative bias each comparison must detect with probability 0.9.
const DETECTABLE: f64 = 0.02;

/// The renders in passes compared with plain `balance`: per-pixel budgets alone, each learned
/// α alone and with per-pixel budgets (the cost-aware one at a fixed cost ratio, which the
/// render does not measure).
fn configurations() -> Vec<(String, Vec<String>, Option<InPasses>)> {
    let passes = |budgets| Some(InPasses { passes: 4, budgets });
    let learned = |name: &str| {
        vec![
            format!("integrator.type={name}"),
            "integrator.statistics=passes".to_string(),
        ]
    };
    vec![
        (
            format!("{} + per-pixel budgets", balance::NAME),
            vec![format!("integrator.type={}", balance::NAME)],
            passes(Budgets::PerPixel),
        ),
        (
            format!("learned {}", alpha::NAME),
            learned(alpha::NAME),
            passes(Budgets::Uniform),
        ),
        (
            format!("learned {}", exact_alpha::NAME),
            learned(exact_alpha::NAME),
            passes(Budgets::Uniform),
        ),
        (
            format!("learned {} + per-pixel budgets", exact_alpha::NAME),
            learned(exact_alpha::NAME),
            passes(Budgets::PerPixel),
        ),
        (
            format!("learned {} + per-pixel budgets", pooled_alpha::NAME),
            learned(pooled_alpha::NAME),
            passes(Budgets::PerPixel),
        ),
        (
            format!("learned {} + per-pixel budgets", cost_alpha::NAME),
            [learned(cost_alpha::NAME), vec![cost_ratio()]].concat(),
            passes(Budgets::PerPixel),
        ),
    ]
}

/// A BSDF sample 2.25 times as costly as a light sample (measured on paper scene 03).
fn cost_ratio() -> String {
    format!("integrator.{}=2.25", cost_alpha::COST_RATIO)
}

fn same_mean_learning(name: &str, path: &Path, spp: u32, runs: Runs) {
    let balance_type = vec![format!("integrator.type={}", balance::NAME)];
    same_mean_rendered(
        name,
        path,
        spp,
        &balance_type,
        &configurations(),
        DETECTABLE,
        runs,
    );
}

/// Half of every count of [`RUNS`] but the pilots': scene 04 detects 0.64–0.99 % with
/// probability 0.9 at seeds 0–2 (0.47–0.70 % with [`RUNS`] at seed 0), and fails with 2 % added
/// to the tested renders (|t| ≥ 10 at seed 0).
const SCENE_04_RUNS: Runs = Runs {
    independent: 8,
    coupled: 32,
    reference: 16,
    pilot: 16,
};

/// A quarter of the coupled runs of [`RUNS`], half of the others: the Veach layout detects
/// 0.04–0.05 % with probability 0.9 at seed 0 (0.02–0.03 % with [`RUNS`]), and fails with 2 %
/// added to the tested renders (|t| ≥ 248 at seed 0).
const VEACH_RUNS: Runs = Runs {
    independent: 8,
    coupled: 16,
    reference: 16,
    pilot: 8,
};

fn repo_path(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

#[test]
fn same_mean_learning_glossy_under_an_env_map() {
    let (name, _dir, path) = same_mean_scene(1);
    same_mean_learning(&name, &path, 16, RUNS);
}

#[test]
fn same_mean_learning_on_the_veach_layout() {
    let (name, _dir, path) = same_mean_scene(4);
    same_mean_learning(&name, &path, 8, VEACH_RUNS);
}

#[test]
fn same_mean_learning_on_paper_scene_04() {
    same_mean_learning(
        "paper scene 04",
        &repo_path("scenes/paper/04.ron"),
        8,
        SCENE_04_RUNS,
    );
}

/// Renders `passes` passes of 4 samples (of a 16-sample render in 4 passes) of `loaded` from
/// `state`, and returns the state.
fn passes(loaded: &mut lumis::scene::load::LoadedScene, state: &mut RenderState, passes: usize) {
    let settings = settings();
    let scope = Scope {
        max_passes: Some(passes),
        ..Scope::whole(2)
    };
    lumis::progressive::run(
        &loaded.scene,
        loaded.integrator.as_mut(),
        &settings,
        state,
        scope,
        &AtomicBool::new(false),
        &|_| {},
        &mut |_| Control::Continue,
    )
    .expect("render");
}

fn settings() -> Settings {
    Settings {
        stopping: Stopping::Samples { spp: 16, passes: 4 },
        ..Settings::samples(16)
    }
}

fn load(integrator: &str, learned: bool) -> lumis::scene::load::LoadedScene {
    let mut overrides = vec![
        "film.width=24".to_string(),
        "film.height=18".to_string(),
        "sampler.spp=16".to_string(),
        "sampler.jitter=false".to_string(),
        format!("integrator.type={integrator}"),
        "integrator.samples=8".to_string(),
        r#"integrator.aovs=["alpha"]"#.to_string(),
    ];
    if learned {
        overrides.push("integrator.statistics=passes".to_string());
    }
    if integrator == cost_alpha::NAME {
        overrides.push(cost_ratio());
    }
    let overrides: Vec<&str> = overrides.iter().map(String::as_str).collect();
    common::load(&repo_path("scenes/veach.ron"), &overrides).expect("scene")
}

/// The first pass of a learning α draws at α = ½ with balance weights: its sums are `balance`'s
/// bit for bit (colours and the α AOV). The α of pass 3 is a function of passes 0–2 only: an
/// integrator that never saw them but their sums (a fresh one, resumed from the state after
/// pass 2) uses the same α in pass 3 — bit for bit the same α AOV sums — even when pass 3's
/// samples are other ones (another seed); and it is not ½ everywhere (it learned something).
#[test]
fn the_first_pass_is_balance_and_alpha_reads_only_earlier_passes() {
    for integrator in [
        alpha::NAME,
        exact_alpha::NAME,
        pooled_alpha::NAME,
        cost_alpha::NAME,
    ] {
        let mut learning = load(integrator, true);
        let mut reference = load(balance::NAME, false);
        let mut first =
            RenderState::new(&learning.scene, learning.integrator.as_ref(), &settings());
        let mut balanced =
            RenderState::new(&reference.scene, reference.integrator.as_ref(), &settings());
        passes(&mut learning, &mut first, 1);
        passes(&mut reference, &mut balanced, 1);
        assert!(
            first.sums.color == balanced.sums.color,
            "{integrator}: the first pass is not balance's"
        );
        let lights = learning.scene.emitters.len();
        let alpha_sums = |state: &RenderState| -> Vec<f64> {
            // Each light's AOV sums begin with Σ α and the shading points.
            let stride = state.sums.stride;
            (0..state.sums.samples.len() * lights)
                .flat_map(|i| {
                    let at = (i / lights) * stride + (i % lights) * aovs::PER_LIGHT;
                    state.sums.sums[at..at + 2].to_vec()
                })
                .collect()
        };
        assert!(alpha_sums(&first) == alpha_sums(&balanced));

        let mut before = first.clone();
        passes(&mut learning, &mut before, 2);
        let mut continued = before.clone();
        passes(&mut learning, &mut continued, 1);
        let mut fresh = load(integrator, true);
        fresh.scene.seed += 1;
        let mut resumed = before.clone();
        passes(&mut fresh, &mut resumed, 1);
        let in_pass = |after: &RenderState| -> Vec<f64> {
            alpha_sums(after)
                .iter()
                .zip(alpha_sums(&before))
                .map(|(a, b)| a - b)
                .collect()
        };
        assert!(
            resumed.sums.color != continued.sums.color,
            "{integrator}: another seed gave the same samples"
        );
        let (learned, again) = (in_pass(&continued), in_pass(&resumed));
        assert!(
            learned == again,
            "{integrator}: α of pass 3 depends on more than passes 0–2"
        );
        // Pairs (Σ α, shading points): α ≠ ½ somewhere.
        assert!(
            learned
                .chunks(2)
                .any(|c| c[1] > 0.0 && (c[0] / c[1] - 0.5).abs() > 0.05),
            "{integrator}: α stayed ½ after three passes"
        );
    }
}

fn succeeded(output: std::process::Output) -> String {
    let text = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{text}");
    text
}

fn failed(output: std::process::Output) -> String {
    let text = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(!output.status.success(), "succeeded: {text}");
    text
}

/// A render with per-pixel budgets records them: `--replay` renders the same image without
/// being told them again, and refuses other budgets. Its shards, each pass rendered from the
/// merged state, merge into the one-process image bit for bit (the merged EXR records the
/// budgets too); a state that holds part of a pass, or other budgets, refuses to resume.
#[test]
fn per_pixel_budgets_replay_resume_and_shard_into_one_image() {
    let (dir, path) = common::scene_file("scene.ron", common::SMALL_SCENE);
    let (d, scene) = (dir.path(), path.to_str().unwrap());
    let passes = ["--passes", "3", "--spp", "6"];
    let render = |extra: &[&str]| {
        let mut all = vec!["render", scene, "-q"];
        all.extend(extra);
        common::lumis(d, &all)
    };
    let per_pixel = [&passes[..], &["--budgets", "per-pixel"]].concat();
    succeeded(render(&[&per_pixel[..], &["-o", "b.exr"]].concat()));
    let metadata = lumis::image_io::read_exr_metadata(&d.join("b.exr")).unwrap();
    assert!(
        metadata.contains(&("budgets".into(), "per-pixel".into())),
        "{metadata:?}"
    );
    succeeded(render(&["--replay", "b.exr", "-o", "r.exr"]));
    let channels = |f: &str| lumis::image_io::read_exr_channels(&d.join(f)).unwrap();
    assert_eq!(channels("b.exr"), channels("r.exr"));
    // Uniform budgets give another image, so the replay above did read them.
    succeeded(render(&[&passes[..], &["-o", "u.exr"]].concat()));
    assert_ne!(channels("b.exr"), channels("u.exr"));
    let e = failed(render(&[
        "--replay",
        "b.exr",
        "--budgets",
        "uniform",
        "-o",
        "x.exr",
    ]));
    assert!(
        e.contains("it was rendered with --budgets per-pixel"),
        "{e}"
    );

    // Two shards, pass by pass from the merged state.
    for round in 0..3 {
        let mut merge = vec!["merge", "--quiet", "-o", "m.exr", "--state", "m.lshard"];
        for part in ["0/2", "1/2"] {
            let file = format!("part-{}.lshard", &part[..1]);
            let mut extra = [&per_pixel[..], &["--shard", part, "-o", &file]].concat();
            if round > 0 {
                extra.extend(["--resume", "m.lshard"]);
            }
            succeeded(render(&extra));
            let shard = lumis::shards::ShardFile::read(&d.join(&file)).unwrap();
            assert_eq!(shard.budgets, Budgets::PerPixel);
        }
        merge.extend(["part-0.lshard", "part-1.lshard"]);
        succeeded(common::lumis(d, &merge));
    }
    assert!(
        channels("m.exr") == channels("b.exr"),
        "the shards' image differs"
    );
    let merged = lumis::image_io::read_exr_metadata(&d.join("m.exr")).unwrap();
    assert!(merged.contains(&("budgets".into(), "per-pixel".into())));

    // States that cannot continue this render: other budgets, and part of a pass.
    succeeded(render(
        &[&per_pixel[..], &["--shard", "0/1", "-o", "s.lshard"]].concat(),
    ));
    let e = failed(render(
        &[&passes[..], &["--resume", "s.lshard", "-o", "x.exr"]].concat(),
    ));
    assert!(
        e.contains("is a render with --budgets per-pixel; this one asks for --budgets uniform"),
        "{e}"
    );
    let mut state = lumis::shards::ShardFile::read(&d.join("s.lshard")).unwrap();
    let first = state.state.history.passes[0].pass;
    state.state.current = Some((first, None));
    state.write(&d.join("p.lshard")).unwrap();
    let e = failed(render(
        &[&per_pixel[..], &["--resume", "p.lshard", "-o", "x.exr"]].concat(),
    ));
    assert!(e.contains("holds part of a pass"), "{e}");
}

/// An interrupt of a render with per-pixel budgets drops the pass cut short: the state is the
/// one after the last finished pass (no pass in progress, every pixel's sums as they were), and
/// it continues into the image the uninterrupted render gives, bit for bit.
#[test]
fn an_interrupted_render_with_per_pixel_budgets_resumes_into_the_same_image() {
    let mut loaded = load(balance::NAME, false);
    let whole_settings = settings();
    let scope = Scope::whole(2).with_budgets(Budgets::PerPixel);
    let run = |loaded: &mut lumis::scene::load::LoadedScene,
               state: &mut RenderState,
               cancel_at: Option<u64>| {
        common::run_passes(
            loaded,
            state,
            &whole_settings,
            scope,
            cancel_at,
            &mut |_| Control::Continue,
        )
        .ending
    };
    let fresh = |loaded: &lumis::scene::load::LoadedScene| {
        RenderState::new(&loaded.scene, loaded.integrator.as_ref(), &whole_settings)
    };
    let mut whole = fresh(&loaded);
    assert_eq!(run(&mut loaded, &mut whole, None), Ending::Complete);
    let tiles_per_pass = lumis::film_sums::tiles(loaded.scene.window).count() as u64;
    let mut two = fresh(&loaded);
    let mut scope_two = scope;
    scope_two.max_passes = Some(2);
    lumis::progressive::run(
        &loaded.scene,
        loaded.integrator.as_mut(),
        &whole_settings,
        &mut two,
        scope_two,
        &AtomicBool::new(false),
        &|_| {},
        &mut |_| Control::Continue,
    )
    .expect("render");
    // The cancel comes in the middle of the third pass.
    let mut cut = fresh(&loaded);
    let at = 2 * tiles_per_pass + tiles_per_pass.div_ceil(2);
    assert_eq!(run(&mut loaded, &mut cut, Some(at)), Ending::Interrupted);
    assert_eq!(cut.history.passes.len(), 2);
    assert!(cut.current.is_none());
    assert!(cut.sums == two.sums, "the pass cut short left sums behind");
    assert_eq!(run(&mut loaded, &mut cut, None), Ending::Complete);
    assert!(cut.sums == whole.sums, "the resumed render differs");
}
