//! Work split over processes (docs/distributed.md): a render's shards merge into the
//! one-process render bit for bit in any shard count, pass by pass too, with what the
//! integrator learned across passes (`path`'s cache of α); a study planned into cells, run cell by
//! cell (in any order) and collected reports what the local study reports, names its missing
//! and failed cells, and takes the cell index from the environment of an array job.

use crate::common;

use common::lumis;
use lumis::budgets::Budgets;
use lumis::passes::{Settings, Stopping};
use lumis::progressive::{Control, Ending, RenderState, Scope};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Output;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn ok(output: &Output, what: &str) {
    assert!(
        output.status.success(),
        "{what} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
}

fn failure(output: Output, what: &str) -> String {
    assert!(!output.status.success(), "{what} should fail");
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// The Veach scene small, with the adaptive α (AOV layers from the integrator's own sums) and
/// two camera samples per pixel: 40×36 pixels are 3×3 tiles.
const RENDER: [&str; 8] = [
    "--set",
    "film.width=40",
    "--set",
    "film.height=36",
    "--set",
    "integrator.type=alpha",
    "--spp",
    "2",
];

fn render(dir: &Path, extra: &[&str]) -> Output {
    let scene = repo().join("scenes/veach.ron");
    let mut args = vec!["render", scene.to_str().expect("UTF-8 path"), "--quiet"];
    args.extend(RENDER);
    args.extend(extra);
    lumis(dir, &args)
}

/// Also with a Gaussian reconstruction filter, whose samples land beyond their pixel: each
/// still counts in its own pixel only, so shards stay exact.
#[test]
fn merged_shards_are_the_one_process_render_bit_for_bit() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let gaussian = ["--set", "film.filter.type=gaussian"];
    for (filter, counts) in [(&[][..], &[1u32, 2, 3, 7][..]), (&gaussian[..], &[3][..])] {
        fn with<'a>(filter: &[&'a str], extra: &[&'a str]) -> Vec<&'a str> {
            [filter, extra].concat()
        }
        let name = if filter.is_empty() { "box" } else { "gaussian" };
        let whole_exr = format!("whole-{name}.exr");
        ok(
            &render(d, &with(filter, &["-o", &whole_exr])),
            "the whole render",
        );
        let whole = std::fs::read(d.join(&whole_exr)).expect("the whole EXR");
        for &n in counts {
            let mut shards = Vec::new();
            // Rendered in reverse order and merged in the order given: order does not matter.
            for i in (0..n).rev() {
                let file = format!("part-{name}-{i}-of-{n}.lshard");
                ok(
                    &render(
                        d,
                        &with(filter, &["--shard", &format!("{i}/{n}"), "-o", &file]),
                    ),
                    "a shard",
                );
                shards.push(file);
            }
            let out = format!("merged-{name}-{n}.exr");
            let mut args = vec!["merge", "--quiet", "-o", &out];
            args.extend(shards.iter().map(String::as_str));
            ok(&lumis(d, &args), "the merge");
            let merged = std::fs::read(d.join(&out)).expect("the merged EXR");
            assert!(
                merged == whole,
                "{name}: {n} shards merged differ from the one-process render"
            );
            for preview in ["png", "alpha_color.png"] {
                let a =
                    std::fs::read(d.join(format!("whole-{name}.{preview}"))).expect("a preview");
                let b = std::fs::read(d.join(format!("merged-{name}-{n}.{preview}")))
                    .expect("a preview");
                assert!(a == b, "{name}, {n} shards: the {preview} preview differs");
            }
        }
    }
}

/// A render to a target error in shards: every shard renders a pass, the shards merge, and the
/// next pass's shards resume from the merged state, until the pass planned as the last. The
/// passes are decided from the merged image alone, so 2 and 3 shards give the one-process
/// render's passes and image, bit for bit (the metadata but the render's time too).
#[test]
fn the_passes_of_a_render_to_a_target_merge_pass_by_pass() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let scene = repo().join("scenes/veach.ron");
    let scene = scene.to_str().expect("UTF-8 path");
    let settings = [
        "--set",
        "film.width=40",
        "--set",
        "film.height=36",
        "--set",
        "integrator.samples=4",
        "--target-error",
        "0.05",
        "--quiet",
    ];
    let run = |extra: &[&str]| {
        let mut args = vec!["render", scene];
        args.extend(settings);
        args.extend(extra);
        lumis(d, &args)
    };
    ok(&run(&["-o", "whole.exr"]), "the whole render");
    let metadata = |f: &str| -> Vec<(String, String)> {
        lumis::image_io::read_exr_metadata(&d.join(f))
            .expect("metadata")
            .into_iter()
            .filter(|(k, _)| k != "render_time")
            .collect()
    };
    let whole = lumis::image_io::read_exr_channels(&d.join("whole.exr")).expect("the EXR");
    for n in [2u32, 3] {
        let state = format!("state-{n}.lshard");
        let out = format!("merged-{n}.exr");
        for round in 0.. {
            assert!(round < 20, "{n} shards: no end of the passes");
            let mut parts = Vec::new();
            for i in 0..n {
                let part = format!("part-{i}-of-{n}.lshard");
                let shard = format!("{i}/{n}");
                let mut extra = vec!["--shard", shard.as_str(), "-o", part.as_str()];
                if round > 0 {
                    extra.extend(["--resume", state.as_str()]);
                }
                ok(&run(&extra), "a shard's pass");
                parts.push(part);
            }
            let mut args = vec!["merge", "--quiet", "-o", &out, "--state", &state];
            args.extend(parts.iter().map(String::as_str));
            ok(&lumis(d, &args), "the merge");
            let partial = metadata(&out)
                .iter()
                .any(|(k, v)| k == "partial" && v == "true");
            if !partial {
                break;
            }
        }
        let merged = lumis::image_io::read_exr_channels(&d.join(&out)).expect("the EXR");
        assert!(
            merged == whole,
            "{n} shards' image differs from one process's"
        );
        assert_eq!(metadata(&out), metadata("whole.exr"), "{n} shards");
    }
}

#[test]
fn a_merge_names_missing_duplicate_foreign_and_damaged_shards() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    for i in 0..3 {
        let file = format!("s{i}.lshard");
        ok(
            &render(d, &["--shard", &format!("{i}/3"), "-o", &file]),
            "a shard",
        );
    }
    ok(
        &render(d, &["--shard", "0/3", "--seed", "9", "-o", "other.lshard"]),
        "a shard of another seed",
    );
    let e = failure(lumis(d, &["merge", "s0.lshard", "s2.lshard"]), "a merge");
    assert!(e.contains("shard 1/3") && e.contains("missing"), "{e}");
    let e = failure(
        lumis(
            d,
            &["merge", "s0.lshard", "s1.lshard", "s2.lshard", "s1.lshard"],
        ),
        "a merge",
    );
    assert!(e.contains("are both shard 1/3"), "{e}");
    let e = failure(
        lumis(d, &["merge", "other.lshard", "s1.lshard", "s2.lshard"]),
        "a merge",
    );
    assert!(e.contains("not the same render"), "{e}");
    let bytes = std::fs::read(d.join("s1.lshard")).expect("a shard");
    std::fs::write(d.join("s1.lshard"), &bytes[..bytes.len() / 2]).expect("truncate");
    let e = failure(
        lumis(d, &["merge", "s0.lshard", "s1.lshard", "s2.lshard"]),
        "a merge",
    );
    assert!(e.contains("s1.lshard") && e.contains("past the end"), "{e}");
    // The scene edited after its shards were rendered.
    let scene = d.join("scene.ron");
    std::fs::copy(repo().join("scenes/veach.ron"), &scene).expect("copy");
    let args = |i: &str, out: &str| {
        let mut args = vec!["render", "scene.ron", "--quiet", "--shard", i, "-o", out];
        args.extend(RENDER);
        args.iter().map(|s| s.to_string()).collect::<Vec<_>>()
    };
    let run = |args: Vec<String>| lumis(d, &args.iter().map(String::as_str).collect::<Vec<_>>());
    ok(&run(args("0/2", "e0.lshard")), "a shard");
    ok(&run(args("1/2", "e1.lshard")), "a shard");
    let mut text = std::fs::read_to_string(&scene).expect("the scene");
    text.push_str("\n// edited\n");
    std::fs::write(&scene, text).expect("edit the scene");
    let e = failure(lumis(d, &["merge", "e0.lshard", "e1.lshard"]), "a merge");
    assert!(
        e.contains("has changed since its shards were rendered"),
        "{e}"
    );
    let e = failure(render(d, &["--shard", "3/3"]), "shard 3/3");
    assert!(e.contains("0 ≤ i < n"), "{e}");
    assert!(
        !d.join("veach.exr").exists(),
        "a failed merge writes nothing"
    );
}

/// Every column of results.csv but those that depend on measured time.
fn untimed_rows(path: &Path) -> Vec<HashMap<String, String>> {
    let mut reader = csv::Reader::from_path(path).expect("read the CSV");
    let headers = reader.headers().expect("a header").clone();
    reader
        .records()
        .map(|r| {
            let r = r.expect("a record");
            headers
                .iter()
                .zip(r.iter())
                .filter(|(h, _)| !h.contains("time") && !h.contains("efficiency"))
                .map(|(h, v)| (h.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}

#[test]
fn a_planned_study_collects_to_the_local_report_and_names_missing_and_failed_cells() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    // The scene in the temporary directory, so that a cell can be made to fail by hiding it.
    std::fs::copy(repo().join("scenes/cornell.ron"), d.join("cornell.ron")).expect("copy");
    let study = [
        "study",
        "cornell.ron",
        "--integrators",
        "balance,alpha",
        "--budgets",
        "2,4",
        "--runs",
        "3",
        "--max-runs",
        "6",
        "--reference-samples",
        "32",
        "--set",
        "film.width=16",
        "--set",
        "film.height=16",
        "--threads",
        "1",
        "--quiet",
    ];
    let with = |extra: &[&str]| -> Vec<String> {
        study
            .iter()
            .chain(extra)
            .map(|s| s.to_string())
            .collect::<Vec<_>>()
    };
    let run = |args: Vec<String>| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        lumis(d, &args)
    };
    ok(&run(with(&["--out", "local"])), "the local study");
    let plan = run(with(&["--out", "planned", "--plan", "plan", "--slurm"]));
    ok(&plan, "the plan");
    let script = String::from_utf8_lossy(&plan.stdout).into_owned();
    let manifest = std::fs::read_to_string(d.join("plan/manifest.ron")).expect("the manifest");
    let cells = manifest.matches("scene:").count();
    // 16 reference shards, 4 configurations × 3 runs, the 4 curves' runs 4 to 6.
    assert_eq!(cells, 16 + 4 * 3 + 4 * 3);
    assert!(
        script.contains(&format!("--array=0-{}%64", cells - 1))
            && script.contains("--dependency=afterok:")
            && script.contains("--cell")
            && script.contains("--collect"),
        "{script}"
    );
    assert_eq!(
        std::fs::read_to_string(d.join("plan/slurm.sh")).expect("slurm.sh"),
        script
    );

    let cell = |index: Option<usize>, env: Option<(&str, &str)>| {
        let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_lumis"));
        command
            .current_dir(d)
            .args(["study", "--quiet", "--cell", "plan"]);
        command.env_remove("SLURM_ARRAY_TASK_ID");
        command.env_remove("JOB_COMPLETION_INDEX");
        if let Some(i) = index {
            command.arg(i.to_string());
        }
        if let Some((k, v)) = env {
            command.env(k, v);
        }
        command.output().expect("run lumis")
    };
    let e = failure(cell(None, None), "a cell without an index");
    assert!(
        e.contains("SLURM_ARRAY_TASK_ID") && e.contains("JOB_COMPLETION_INDEX"),
        "{e}"
    );
    // Cells in reverse order, two of them by their array index; cell 20 fails (its scene
    // hidden), cell 21 is never run.
    std::fs::rename(d.join("cornell.ron"), d.join("hidden.ron")).expect("hide the scene");
    let e = failure(cell(Some(20), None), "a cell without its scene");
    assert!(e.contains("cornell.ron"), "{e}");
    std::fs::rename(d.join("hidden.ron"), d.join("cornell.ron")).expect("restore the scene");
    for i in (0..cells).rev().filter(|&i| i != 20 && i != 21) {
        let output = match i {
            3 => cell(None, Some(("SLURM_ARRAY_TASK_ID", "3"))),
            4 => cell(None, Some(("JOB_COMPLETION_INDEX", "4"))),
            _ => cell(Some(i), None),
        };
        ok(&output, "a cell");
    }
    // From another directory: the plan's paths are relative to where it was made.
    let collect = || lumis(&d.join("plan"), &["study", "--quiet", "--collect", "."]);
    let e = failure(collect(), "a collect with cells missing");
    assert!(e.contains("failed: 20") && e.contains("missing: 21"), "{e}");
    assert!(!d.join("planned/results.csv").exists(), "nothing collected");
    ok(&cell(Some(20), None), "cell 20 again");
    assert!(
        !d.join("plan/cells/000020.error").exists(),
        "a cell that succeeds clears its error"
    );
    ok(&cell(Some(21), None), "cell 21");
    ok(&collect(), "the collect");

    let local = untimed_rows(&d.join("local/results.csv"));
    let planned = untimed_rows(&d.join("planned/results.csv"));
    assert_eq!(local.len(), 4, "2 integrators at 2 budgets");
    assert_eq!(planned, local, "the collected report is the local one");
    let md = std::fs::read_to_string(d.join("planned/results.md")).expect("the report");
    assert!(
        md.contains("Made by `lumis study cornell.ron") && !md.contains("--plan"),
        "the report quotes the local command"
    );
}

/// `path`'s world-space cache of α (`deep_allocation` "learned" and "guiding_fraction") travels
/// in state and shard files. A render of the Cornell box in 3 passes (3 tiles each) stopped
/// after pass 1 and continued from its saved state by a new integrator (and by `lumis render
/// --resume`, and as a shard's pass of the command line); cut short in pass 2 (the pass dropped
/// with what the cache learned in it) and continued; or rendered as 2 and 3 shards merged pass
/// by pass (each merged state the one-process state, cache included): each gives the
/// one-process image bit for bit, and continued with an empty cache it does not, so the cache
/// is seen to travel. A saved cache of another resolution or learning, a truncated one,
/// and one in an integrator without a cache are refused naming the problem; caches frozen from
/// different passes do not merge.
#[test]
fn the_path_cache_of_alpha_resumes_and_shards_into_one_image() {
    use lumis::integrators::path as path_plugin;
    use lumis::render::Shard;
    let dir = tempfile::tempdir().expect("a temporary directory");
    let d = dir.path();
    let scene = repo().join("scenes/cornell.ron");
    let overrides = |deep: &str, resolution: u32| -> Vec<String> {
        let mut set = vec![
            "film.width=48".to_string(),
            "film.height=16".to_string(),
            "sampler.jitter=false".to_string(),
            "sampler.spp=6".to_string(),
            format!("integrator=(type: {:?})", path_plugin::NAME),
        ];
        set.extend(
            [
                format!("{}=4", path_plugin::MAX_DEPTH),
                format!("{}={deep:?}", path_plugin::DEEP_ALLOCATION),
                format!("{}={resolution}", path_plugin::CACHE_RESOLUTION),
            ]
            .map(|s| format!("integrator.{s}")),
        );
        set
    };
    let load = |set: &[String]| {
        let set: Vec<&str> = set.iter().map(String::as_str).collect();
        let mut loaded = common::load(&scene, &set).expect("scene");
        loaded.integrator.preprocess(&loaded.scene);
        loaded
    };
    let settings = Settings {
        stopping: Stopping::Samples { spp: 6, passes: 3 },
        ..Settings::samples(6)
    };
    let file = |set: &[String], shard, stats, state: &RenderState| lumis::shards::ShardFile {
        scene_name: "cornell".into(),
        scene_path: scene.clone(),
        scene_hash: lumis::shards::file_hash(&scene).expect("the scene's hash"),
        overrides: set.to_vec(),
        exposure: 0.0,
        shard,
        stats,
        settings: settings.clone(),
        budgets: Budgets::Uniform,
        state: state.clone(),
    };
    let mut second_moment_cache = Vec::new();
    for mode in [path_plugin::LEARNED, path_plugin::GUIDING_FRACTION] {
        let set = overrides(mode, 4);
        let mut whole_loaded = load(&set);
        let fresh = |loaded: &lumis::scene::load::LoadedScene| {
            RenderState::new(&loaded.scene, loaded.integrator.as_ref(), &settings)
        };
        let mut whole = fresh(&whole_loaded);
        let mut after = Vec::new();
        let outcome = common::run_passes(
            &mut whole_loaded,
            &mut whole,
            &settings,
            Scope::whole(2),
            None,
            &mut |state| {
                after.push(state.clone());
                Control::Continue
            },
        );
        assert_eq!(outcome.ending, Ending::Complete);
        assert!(after.iter().all(|s| !s.learned.is_empty()), "{mode}");
        let image = d.join(format!("{mode}.exr"));
        let film = whole
            .sums
            .resolve(&whole_loaded.scene, whole_loaded.integrator.as_ref());
        lumis::render_files::write(&film, &image, 0.0, &Vec::new()).unwrap();
        let channels = |f: &Path| lumis::image_io::read_exr_channels(f).unwrap();

        // Stopped after pass 1, saved, read back and continued by a new integrator.
        let mut first = load(&set);
        let mut state = fresh(&first);
        let one = Scope {
            max_passes: Some(1),
            ..Scope::whole(2)
        };
        let stats = common::run_passes(&mut first, &mut state, &settings, one, None, &mut |_| {
            Control::Continue
        })
        .stats;
        let saved = d.join(format!("{mode}.lshard"));
        file(&set, Shard::WHOLE, stats, &state)
            .write(&saved)
            .unwrap();
        let state = lumis::shards::ShardFile::read(&saved).unwrap().state;
        let mut resumed = state.clone();
        let mut second = load(&set);
        second
            .integrator
            .restore_learned_state(&resumed.learned)
            .unwrap();
        let continued = |loaded: &mut _, state: &mut RenderState| {
            common::run_passes(loaded, state, &settings, Scope::whole(2), None, &mut |_| {
                Control::Continue
            })
            .ending
        };
        assert_eq!(continued(&mut second, &mut resumed), Ending::Complete);
        assert!(
            resumed.sums == whole.sums,
            "{mode}: the resumed render differs"
        );
        // The command line continues it so too: `--resume` in one process, and a shard's pass.
        let command_line = |extra: &[&str]| {
            let mut args = vec!["render", scene.to_str().unwrap(), "-q", "--passes", "3"];
            for s in &set {
                args.extend(["--set", s.as_str()]);
            }
            args.extend(extra);
            lumis(d, &args)
        };
        let resumed_image = d.join(format!("{mode}-resumed.exr"));
        let saved_arg = saved.to_str().unwrap();
        let out = command_line(&["--resume", saved_arg, "-o", resumed_image.to_str().unwrap()]);
        ok(&out, "the resumed render");
        assert!(
            channels(&resumed_image) == channels(&image),
            "{mode}: `lumis render --resume` differs"
        );
        let part = d.join(format!("{mode}-part.lshard"));
        let out = command_line(&[
            "--resume",
            saved_arg,
            "--shard",
            "0/1",
            "-o",
            part.to_str().unwrap(),
        ]);
        ok(&out, "a shard's pass");
        let part = lumis::shards::ShardFile::read(&part).unwrap().state;
        assert!(
            part.sums == after[1].sums && part.learned == after[1].learned,
            "{mode}: `lumis render --shard --resume` differs"
        );
        let mut forgetful = state.clone();
        forgetful.learned.clear();
        continued(&mut load(&set), &mut forgetful);
        assert!(
            forgetful.sums != whole.sums,
            "{mode}: an empty cache gives the same image: the test shows nothing"
        );

        // Cut short in the middle of pass 2 (one thread: the tiles in order).
        let mut cut_loaded = load(&set);
        let mut cut = fresh(&cut_loaded);
        let outcome = common::run_passes(
            &mut cut_loaded,
            &mut cut,
            &settings,
            Scope::whole(1),
            Some(4),
            &mut |_| Control::Continue,
        );
        assert_eq!(outcome.ending, Ending::Interrupted);
        assert!(cut.current.is_none() && cut.history.passes.len() == 1);
        assert!(cut.sums == after[0].sums && cut.learned == after[0].learned);
        assert_eq!(continued(&mut cut_loaded, &mut cut), Ending::Complete);
        assert!(
            cut.sums == whole.sums,
            "{mode}: the render cut short differs"
        );

        // Shards, pass by pass from the merged state.
        for count in [2, 3] {
            let merged_state = d.join(format!("{mode}-{count}.lshard"));
            let merged_image = d.join(format!("{mode}-{count}.exr"));
            for (pass, expected) in after.iter().enumerate() {
                let mut parts = Vec::new();
                for index in 0..count {
                    let shard = Shard { index, count };
                    let mut loaded = load(&set);
                    let mut state = if pass == 0 {
                        fresh(&loaded)
                    } else {
                        let state = lumis::shards::ShardFile::read(&merged_state).unwrap().state;
                        loaded
                            .integrator
                            .restore_learned_state(&state.learned)
                            .unwrap();
                        state
                    };
                    let scope = Scope { shard, ..one };
                    let stats = common::run_passes(
                        &mut loaded,
                        &mut state,
                        &settings,
                        scope,
                        None,
                        &mut |_| Control::Continue,
                    )
                    .stats;
                    state.sums.retain_tiles(|t| shard.has(t));
                    let part = d.join(format!("{mode}-{index}-of-{count}.lshard"));
                    file(&set, shard, stats, &state).write(&part).unwrap();
                    parts.push(part);
                }
                let merged = lumis::shards::merge(
                    &parts,
                    Some(merged_image.as_path()),
                    Some(merged_state.as_path()),
                )
                .unwrap();
                if pass < 2 {
                    let state = lumis::shards::ShardFile::read(&merged_state).unwrap().state;
                    assert!(
                        state.sums == expected.sums && state.learned == expected.learned,
                        "{mode}, {count} shards: the state merged after pass {pass} differs"
                    );
                } else {
                    assert!(merged.state.is_none());
                }
            }
            assert!(
                channels(&merged_image) == channels(&image),
                "{mode}: {count} shards merged differ from the one-process render"
            );
        }

        // Caches that cannot continue this render, or merge.
        let learned = &after[0].learned;
        let error = |set: &[String], bytes: &[u8]| {
            load(set)
                .integrator
                .restore_learned_state(bytes)
                .expect_err("a foreign cache restored")
        };
        let e = error(&overrides(mode, 8), learned);
        assert!(
            e.contains("a resolution of 4 cells") && e.contains("this render's 8"),
            "{e}"
        );
        let e = error(&set, &learned[..learned.len() - 1]);
        assert!(e.contains("truncated"), "{e}");
        // The fixed mixture takes no `cache_resolution`.
        let mut mixture = overrides(path_plugin::MIXTURE, 4);
        mixture.pop();
        let e = error(&mixture, learned);
        assert!(e.contains("learns no α across passes"), "{e}");
        let e = whole_loaded
            .integrator
            .merge_learned_states(learned, &after[1].learned)
            .expect_err("caches of two passes merged");
        assert!(e.contains("frozen from different passes"), "{e}");
        if mode == path_plugin::LEARNED {
            second_moment_cache = learned.clone();
        }
    }
    let e = load(&overrides(path_plugin::GUIDING_FRACTION, 4))
        .integrator
        .restore_learned_state(&second_moment_cache)
        .expect_err("a cache of another learning restored");
    assert!(e.contains("learns the second moment"), "{e}");
}
