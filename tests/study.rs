//! `lumis study`: a reduced study (small images, a short ladder of budgets, few runs) checked
//! for the structure and the sanity of its curves and tables, not their exact numbers: every
//! ratio carries an interval, the K rule picks a round, the reference is cached outside the
//! source tree and reused; interruption keeps the finished scenes; bad arguments get clear
//! errors.

use crate::common;

use common::lumis;
use std::collections::{BTreeSet, HashMap};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read_csv(path: &Path) -> Vec<HashMap<String, String>> {
    let mut reader = csv::Reader::from_path(path).expect("read the CSV");
    let headers = reader.headers().expect("CSV header").clone();
    reader
        .records()
        .map(|r| {
            let r = r.expect("a complete CSV record");
            headers
                .iter()
                .zip(r.iter())
                .map(|(h, v)| (h.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}

fn number(row: &HashMap<String, String>, key: &str) -> f64 {
    row[key]
        .parse()
        .unwrap_or_else(|_| panic!("{key} = {} is not a number", row[key]))
}

/// Every file under `dir` (recursively), to check that a study writes nothing there.
fn files_under(dir: &Path) -> BTreeSet<PathBuf> {
    let mut files = BTreeSet::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).expect("list a directory") {
            let path = entry.expect("an entry").path();
            if path.is_dir() {
                stack.push(path);
            } else {
                files.insert(path);
            }
        }
    }
    files
}

const INTEGRATORS: [&str; 7] = [
    "bsdf",
    "light",
    "balance",
    "power",
    "max",
    "alpha",
    "alpha:mode=preprocessed:alpha_samples=64",
];
const BUDGETS: [u32; 4] = [4, 8, 16, 32];
/// Scenes (paths under `scenes/`, without `.ron`) where every technique, BSDF sampling alone
/// included, meets its lights often enough at these budgets for σ to be measured (docs/study.md,
/// "Heavy tails"): an area light, and area + point lights (paper scene 6).
const SCENES: [&str; 2] = ["cornell", "paper/06"];

/// The name a study gives a scene: its file stem.
fn name(scene: &str) -> &str {
    scene.rsplit('/').next().unwrap_or(scene)
}

fn study_args<'a>(scenes: &'a [String], out: &'a str, cache: &'a str) -> Vec<&'a str> {
    let mut args: Vec<&str> = vec!["study"];
    args.extend(scenes.iter().map(String::as_str));
    args.extend([
        "--set",
        "film.width=48",
        "--set",
        "film.height=32",
        "--set",
        "sampler.spp=1",
        "--budgets",
        "4,8,16,32",
        "--runs",
        "3",
        "--reference-samples",
        "1024",
        "--out",
        out,
        "--cache-dir",
        cache,
    ]);
    args
}

#[test]
fn reduced_study_has_curves_trade_and_intervals_on_every_ratio_and_writes_only_its_outputs() {
    let scenes_before = files_under(&repo().join("scenes"));
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("out");
    let cache = dir.path().join("cache");
    let report = dir.path().join("report.md");
    let notes = dir.path().join("notes.md");
    std::fs::write(&notes, "A reading of the results, by hand.\n").expect("notes");
    let scenes: Vec<String> = SCENES.iter().map(|s| format!("scenes/{s}.ron")).collect();
    let (out_dir, cache_dir, report_file, notes_file) = (
        out.display().to_string(),
        cache.display().to_string(),
        report.display().to_string(),
        notes.display().to_string(),
    );
    let integrators = INTEGRATORS.join(",");
    let mut args = study_args(&scenes, &out_dir, &cache_dir);
    args.extend([
        "--integrators",
        &integrators,
        "--report",
        &report_file,
        "--notes",
        &notes_file,
        "--max-runs",
        "6",
        "--sweeps",
        "all",
    ]);
    let output = lumis(&repo(), &args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    // stderr is not a terminal: one line per finished run and scene.
    for scene in SCENES.map(name) {
        assert!(
            stderr.contains(&format!("{scene}: run 1 of 3 done")),
            "{stderr}"
        );
        assert!(stderr.contains(&format!("{scene}: reference,")), "{stderr}");
    }

    let rows = read_csv(&out.join("results.csv"));
    let curve: Vec<_> = rows.iter().filter(|r| r["group"] == "curve").collect();
    assert_eq!(
        curve.len(),
        SCENES.len() * INTEGRATORS.len() * BUDGETS.len()
    );
    for scene in SCENES.map(name) {
        let of_scene: Vec<_> = curve.iter().filter(|r| r["scene"] == scene).collect();
        // The K rule picks one round for every curve of a scene: K₀ or 2K₀.
        let k = number(of_scene[0], "runs");
        assert!(k == 3.0 || k == 6.0, "{scene}: K = {k}");
        for integrator in INTEGRATORS {
            let samples: Vec<f64> = of_scene
                .iter()
                .filter(|r| r["integrator"] == integrator)
                .map(|r| number(r, "samples"))
                .collect();
            assert_eq!(samples, BUDGETS.map(f64::from), "{scene} {integrator}");
        }
        for row in &of_scene {
            assert_eq!(number(row, "runs"), k);
        }
    }
    for row in &rows {
        let what = format!(
            "{} {} {} N={}",
            row["scene"], row["group"], row["integrator"], row["samples"]
        );
        assert_eq!(number(row, "width"), 48.0, "{what}");
        for key in [
            "cpu_time",
            "relative_variance",
            "variance",
            "delta_e",
            "efficiency",
            "ratio_relative_variance",
            "ratio_median_variance",
            "ratio_variance",
            "ratio_relative_mse",
            "ratio_delta_e",
            "ratio_cpu_time",
            "ratio_efficiency",
        ] {
            let (v, lo, hi) = (
                number(row, key),
                number(row, &format!("{key}_lo")),
                number(row, &format!("{key}_hi")),
            );
            // The median of per-pixel ratios is 0 where most pixels see no light at all (BSDF
            // sampling of a small light at a low budget).
            let positive = v > 0.0 || (key == "ratio_median_variance" && v == 0.0);
            assert!(v.is_finite() && positive, "{what}: {key} = {v}");
            assert!(
                lo <= v && v <= hi,
                "{what}: {key} = {v} not in [{lo}, {hi}]"
            );
        }
        // Every integrator is unbiased: its mean is within 4σ of the reference's (4, not 3:
        // dozens of rows are checked).
        let z = number(row, "z");
        assert!(z.abs() < 4.0, "{what}: z = {z}");
        // MIS integrators report V[L₁] on both bases; a fixed split's are the same quantity.
        if row["kind"] != "bsdf" && row["kind"] != "light" {
            let settled = number(row, "sampling_variance");
            let estimate = number(row, "sampling_variance_estimate");
            assert!(settled > 0.0 && estimate > 0.0, "{what}");
            if row["kind"] != "alpha" {
                assert_eq!(settled, estimate, "{what}");
            }
        }
    }
    // Balance against itself is exactly 1 (paired replicates), which checks the pairing.
    for row in rows
        .iter()
        .filter(|r| r["kind"] == "balance" && r["group"] == "curve")
    {
        assert_eq!(number(row, "ratio_relative_variance_lo"), 1.0);
        assert_eq!(number(row, "ratio_relative_variance_hi"), 1.0);
    }
    // The sweeps at the target budget N = 8 (the middle of the ladder): 8 clamp sizes; M in
    // {2, 4, 6} (N/32 … 3N/4, at least 2, below N); N in {2, 4, 8, 16} with M = 2.
    for scene in SCENES.map(name) {
        let count = |group: &str| {
            rows.iter()
                .filter(|p| p["scene"] == scene && p["group"] == group)
                .count()
        };
        assert_eq!(
            (count("sweep clamp"), count("sweep m"), count("sweep n")),
            (8, 3, 4),
            "{scene}"
        );
    }

    let trade = read_csv(&out.join("trade.csv"));
    assert_eq!(trade.len(), SCENES.len() * INTEGRATORS.len());
    for t in &trade {
        assert_eq!(number(t, "target_budget"), 8.0);
        let what = format!("{} {}", t["scene"], t["integrator"]);
        // Balance against itself is exactly 1. Where a reading lies against the measured
        // times (its extent) depends on the machine's timing: tested with synthetic times in
        // `study::collect`; here only that every reading has one.
        if t["integrator"] == "balance" {
            assert_eq!(number(t, "speedup"), 1.0, "{what}");
        }
        for reading in [
            "time_to_target",
            "speedup",
            "equal_time_ratio",
            "speedup_over_headline",
        ] {
            let extent = &t[&format!("{reading}_extent")];
            let expected: &[&str] = if t[reading].is_empty() {
                &[""]
            } else {
                &["within", "extrapolated", "below", "above"]
            };
            assert!(
                expected.contains(&extent.as_str()),
                "{what}: {reading} `{}`, extent `{extent}`",
                t[reading]
            );
        }
        // The headline α against itself: the same curve read twice.
        if t["integrator"] == "alpha" && !t["speedup_over_headline"].is_empty() {
            assert_eq!(number(t, "speedup_over_headline"), 1.0, "{what}");
        }
        if !t["speedup"].is_empty() {
            let (v, lo, hi) = (
                number(t, "speedup"),
                number(t, "speedup_lo"),
                number(t, "speedup_hi"),
            );
            assert!(v > 0.0 && lo <= v && v <= hi, "{what}: {v} [{lo}, {hi}]");
        }
    }
    let alpha_speedup = trade
        .iter()
        .find(|t| t["integrator"] == "alpha")
        .expect("α's trade");
    assert!(!alpha_speedup["speedup"].is_empty(), "{alpha_speedup:?}");

    // The report links into the output directory, relative to itself, and carries the notes.
    let md = std::fs::read_to_string(&report).expect("the report");
    assert!(md.contains("## Summary: the trade against the balance heuristic"));
    assert!(md.contains("Speed-up over `alpha` at equal error"));
    assert!(md.contains("| integrator | median speed-up over balance |"));
    assert!(md.contains("A reading of the results, by hand."));
    for scene in SCENES.map(name) {
        assert!(md.contains(&format!("## {scene} — ")), "{scene} section");
        for file in [
            format!("plots/{scene}-curves.png"),
            format!("panels/{scene}.png"),
        ] {
            assert!(md.contains(&format!("(out/{file})")), "{file} linked");
            let image = common::read_png(&out.join(&file));
            assert!(image.width > 48, "{file}");
        }
    }
    for plot in ["summary", "clamp", "m", "convergence"] {
        let file = format!("plots/{plot}.png");
        assert!(md.contains(&format!("(out/{file})")), "{file} linked");
        common::read_png(&out.join(&file));
    }

    // The references are cached in the cache directory, one per scene; nothing is written
    // into the source tree.
    let cached = files_under(&cache);
    assert_eq!(cached.len(), SCENES.len(), "{cached:?}");
    assert_eq!(files_under(&repo().join("scenes")), scenes_before);

    // A second study with the same scene and reference reads the cached one.
    let out2 = dir.path().join("out2").display().to_string();
    let scene = vec![scenes[0].clone()];
    let mut args = study_args(&scene, &out2, &cache_dir);
    args.extend([
        "--integrators",
        "balance,alpha",
        "--sweeps",
        "none",
        "--max-runs",
        "3",
    ]);
    let output = lumis(&repo(), &args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(
        !stderr.contains("cornell: reference,"),
        "rendered again: {stderr}"
    );
    let md = std::fs::read_to_string(dir.path().join("out2/results.md")).expect("report");
    assert!(md.contains("(cached)"), "{md}");
    assert_eq!(files_under(&cache), cached);
}

#[test]
fn an_interrupted_study_keeps_its_complete_runs_and_exits_130() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("out");
    // A precision no K reaches: the runs keep doubling until the interruption.
    let mut child = Command::new(env!("CARGO_BIN_EXE_lumis"))
        .current_dir(repo())
        .args([
            "study",
            "scenes/veach.ron",
            "--set",
            "film.width=32",
            "--set",
            "film.height=24",
            "--budgets",
            "4,8,16,32,64",
            "--runs",
            "3",
            "--max-runs",
            "96",
            "--precision",
            "0.0001",
            "--reference-samples",
            "256",
            "--integrators",
            "balance,alpha,light",
            "--out",
        ])
        .arg(&out)
        .arg("--cache-dir")
        .arg(dir.path().join("cache"))
        .stderr(Stdio::piped())
        .spawn()
        .expect("start lumis study");
    // stderr is not a terminal: the study prints a line per finished run; wait for the third.
    let stderr = child.stderr.take().expect("stderr");
    let (lines, received) = std::sync::mpsc::channel();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines() {
            let Ok(line) = line else { break };
            if lines.send(line).is_err() {
                break;
            }
        }
    });
    let mut seen = Vec::new();
    while !seen
        .iter()
        .any(|l: &String| l.contains("veach: run 3 of 3 done"))
    {
        let line = received
            .recv_timeout(std::time::Duration::from_secs(300))
            .unwrap_or_else(|e| panic!("no third run after 5 minutes ({e}): {seen:#?}"));
        seen.push(line);
    }
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill -INT");
    assert!(status.success());
    let status = child.wait().expect("wait");
    reader.join().expect("the stderr reader");
    seen.extend(received.try_iter());
    let stderr = seen.join("\n");
    assert_eq!(status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    let rows = read_csv(&out.join("results.csv"));
    assert_eq!(rows.len(), 3 * 5, "{rows:?}");
    for row in &rows {
        assert_eq!(row["scene"], "veach");
        assert_eq!(number(row, "runs"), 3.0, "the complete runs: {row:?}");
        assert!(number(row, "relative_variance") > 0.0);
    }
    let md = std::fs::read_to_string(out.join("results.md")).expect("results.md");
    assert!(md.contains("## veach — "), "{md}");
    // Atomic writes leave no temporary file behind.
    let leftovers: Vec<_> = files_under(dir.path())
        .into_iter()
        .filter(|p| p.to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// A study of `path` rows: its budgets are camera samples per pixel, its baseline (every ratio's
/// denominator) is the row with the balance weighting wherever it is in the list, and its
/// reference is rendered by that row's spec.
#[test]
fn a_path_study_reads_every_row_against_path_with_the_balance_weighting() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (out, cache) = (dir.path().join("out"), dir.path().join("cache"));
    let (out_dir, cache_dir) = (out.display().to_string(), cache.display().to_string());
    let rows = [
        "path:weighting=power:max_depth=3",
        "path:weighting=balance:max_depth=3",
    ];
    let integrators = rows.join(",");
    let args = [
        "study",
        "scenes/cornell.ron",
        "--set",
        "film.width=12",
        "--set",
        "film.height=8",
        "--budgets",
        "1,2",
        "--runs",
        "3",
        "--max-runs",
        "3",
        "--reference-samples",
        "32",
        "--integrators",
        &integrators,
        "--out",
        &out_dir,
        "--cache-dir",
        &cache_dir,
    ];
    let output = lumis(&repo(), &args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let curve: Vec<_> = read_csv(&out.join("results.csv"))
        .into_iter()
        .filter(|r| r["group"] == "curve")
        .collect();
    assert_eq!(curve.len(), rows.len() * 2);
    for row in &curve {
        let baseline = row["integrator"] == rows[1];
        for key in ["ratio_relative_variance", "ratio_cpu_time"] {
            let ratio = number(row, key);
            assert_eq!(
                ratio == 1.0,
                baseline,
                "{} {key} = {ratio}",
                row["integrator"]
            );
        }
    }
    let report = std::fs::read_to_string(out.join("results.md")).expect("the report");
    assert!(
        report.contains(&format!(
            "`{}`, 32 camera samples per pixel in 16 shards",
            rows[1]
        )),
        "{report}"
    );
}

#[test]
fn bad_study_arguments_get_clear_errors() {
    let cases: [(&[&str], &str); 8] = [
        (&["--runs", "2"], "at least 3"),
        (&["--runs", "4", "--max-runs", "3"], "below --runs"),
        (&["--budgets", "8,4"], "increase strictly"),
        (&["--budgets", "8,x"], "`x` is not a positive integer"),
        (
            &["--budgets", "4,8", "--target-budget", "16"],
            "not one of --budgets",
        ),
        (&["--integrators", "balanse"], "balance"),
        (&["--integrators", "alpha:mode"], "is not key=value"),
        (&["--sweeps", "clamps"], "unknown sweep `clamps`"),
    ];
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().display().to_string();
    for (extra, expected) in cases {
        let mut args = vec!["study", "scenes/veach.ron", "--quiet", "--out", &out];
        args.extend(extra);
        let output = lumis(&repo(), &args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{extra:?}: {stderr}");
        assert!(stderr.contains(expected), "{extra:?}: {stderr}");
    }
    let output = lumis(
        &repo(),
        &[
            "study",
            "a.ron",
            "b.ron",
            "--reference",
            "r.exr",
            "--quiet",
            "--out",
            &out,
        ],
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("exactly one scene"), "{stderr}");
    let output = lumis(
        &repo(),
        &[
            "study",
            "scenes/veach.ron",
            "--integrators",
            "alpha,light",
            "--quiet",
            "--out",
            &out,
        ],
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("must include `balance`"), "{stderr}");
    for (integrators, expected) in [
        ("balance,path:weighting=balance", "mixes `path` rows"),
        (
            "path,path:weighting=power",
            "must include `path:weighting=balance`",
        ),
    ] {
        let mut args = vec!["study", "scenes/cornell.ron", "--quiet", "--out", &out];
        args.extend(["--integrators", integrators]);
        let output = lumis(&repo(), &args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{integrators}: {stderr}");
        assert!(stderr.contains(expected), "{integrators}: {stderr}");
    }
}
