//! Work split over processes (docs/distributed.md): a render's shards merge into the
//! one-process render bit for bit in any shard count; a study planned into cells, run cell by
//! cell (in any order) and collected reports what the local study reports, names its missing
//! and failed cells, and takes the cell index from the environment of an array job.

use crate::common;

use common::lumis;
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
