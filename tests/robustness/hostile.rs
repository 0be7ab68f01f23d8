//! Replays the hostile-input corpus, `tests/hostile/*.ron`: each scene is rendered by the CLI
//! in a child process, and must give the outcome its header states, never a panic, an abort, a
//! hang or a non-finite pixel. The header is comment lines at the top of the scene:
//!
//! ```text
//! // expect: error | warning | ok
//! // message: text that stderr must contain (repeatable)
//! // args: extra arguments (OUT is the case's output directory)
//! // env: NAME=value
//! // setup: dir OUT/path      (a directory to create first)
//! // absent: OUT/path         (a file that must not exist afterwards)
//! // max-stderr: 400          (a bound on the message's length)
//! ```
//!
//! `error`: exit status 1, stderr starts with "error: ". `warning`: exit status 0, stderr has
//! "warning: ". `ok`: exit status 0. Whenever an image is written, every value in it is finite.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A case taking this long is a hang (every case takes well under a second).
const TIMEOUT: Duration = Duration::from_secs(60);

#[derive(Debug, Default)]
struct Case {
    path: PathBuf,
    expect: String,
    messages: Vec<String>,
    args: Vec<String>,
    env: Vec<(String, String)>,
    setup_dirs: Vec<String>,
    absent: Vec<String>,
    max_stderr: Option<usize>,
}

fn parse(path: &Path) -> Case {
    let text = std::fs::read_to_string(path).unwrap();
    let mut case = Case {
        path: path.to_path_buf(),
        ..Case::default()
    };
    for line in text.lines().map_while(|l| l.strip_prefix("// ")) {
        let Some((key, value)) = line.split_once(": ") else {
            continue;
        };
        let value = value.to_string();
        match key {
            "expect" => case.expect = value,
            "message" => case.messages.push(value),
            "args" => case.args = value.split_whitespace().map(String::from).collect(),
            "env" => {
                let (k, v) = value.split_once('=').expect("env: NAME=value");
                case.env.push((k.into(), v.into()));
            }
            "setup" => case
                .setup_dirs
                .push(value.strip_prefix("dir ").expect("setup: dir PATH").into()),
            "absent" => case.absent.push(value),
            "max-stderr" => case.max_stderr = Some(value.parse().unwrap()),
            _ => {}
        }
    }
    assert!(
        ["error", "warning", "ok"].contains(&case.expect.as_str()),
        "{}: no `// expect:` line",
        path.display()
    );
    case
}

/// Runs one case; `Err` says what went wrong.
fn run(case: &Case) -> Result<(), String> {
    let out_dir = tempfile::tempdir().unwrap();
    let out = |s: &str| s.replace("OUT", out_dir.path().to_str().unwrap());
    for dir in &case.setup_dirs {
        std::fs::create_dir_all(out(dir)).unwrap();
    }
    let mut args = vec![
        "render".to_string(),
        case.path.to_str().unwrap().to_string(),
    ];
    if !case.args.iter().any(|a| a == "-o") {
        args.extend(["-o".into(), out("OUT/image.exr")]);
    }
    args.extend(case.args.iter().map(|a| out(a)));
    let mut command = Command::new(env!("CARGO_BIN_EXE_lumis"));
    command
        .args(&args)
        .current_dir(out_dir.path())
        .env_remove("LUMIS_MEMORY_LIMIT")
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    for (k, v) in &case.env {
        command.env(k, v);
    }
    let mut child = command.spawn().unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > TIMEOUT {
            let _ = child.kill();
            return Err(format!("no answer after {TIMEOUT:?} (a hang)"));
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    let say = |what: String| Err(format!("{what}; stderr:\n{stderr}"));
    if stderr.contains("panicked") || stderr.contains("RUST_BACKTRACE") {
        return say("panicked".into());
    }
    let code = status.code();
    match case.expect.as_str() {
        "error" if code != Some(1) || !stderr.starts_with("error: ") => {
            return say(format!("expected an error (status 1), got {status}"));
        }
        "warning" if code != Some(0) || !stderr.contains("warning: ") => {
            return say(format!("expected a warning and status 0, got {status}"));
        }
        "ok" if code != Some(0) => return say(format!("expected success, got {status}")),
        _ => {}
    }
    for m in &case.messages {
        if !stderr.contains(m.as_str()) {
            return say(format!("stderr lacks {m:?}"));
        }
    }
    if let Some(max) = case.max_stderr
        && stderr.len() > max
    {
        return say(format!("stderr is {} bytes, more than {max}", stderr.len()));
    }
    for path in &case.absent {
        if Path::new(&out(path)).exists() {
            return say(format!("{path} exists"));
        }
    }
    // Whatever image was written holds finite values only.
    for entry in std::fs::read_dir(out_dir.path()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "exr") {
            let channels = lumis::image_io::read_exr_channels(&path).map_err(|e| e.to_string())?;
            if let Some((name, _)) = channels
                .iter()
                .find(|(_, values)| values.iter().any(|v| !v.is_finite()))
            {
                return say(format!(
                    "channel {name} of {} is not finite",
                    path.display()
                ));
            }
        }
        if path.to_string_lossy().ends_with(".tmp") {
            return say(format!("temporary file {} left behind", path.display()));
        }
    }
    let default_output = !case.args.iter().any(|a| a == "-o");
    if case.expect != "error" && default_output && !out_dir.path().join("image.exr").exists() {
        return say("no image written".into());
    }
    Ok(())
}

#[test]
fn every_hostile_input_gets_its_outcome() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/hostile");
    let mut cases: Vec<Case> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .map(|p| parse(&p))
        .collect();
    cases.sort_by(|a, b| a.path.cmp(&b.path));
    assert!(cases.len() >= 40, "only {} cases", cases.len());
    // Two at a time: each is a short process, mostly waiting on start-up.
    let next = std::sync::atomic::AtomicUsize::new(0);
    let failures = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(case) = cases.get(i) else { break };
                    if let Err(e) = run(case) {
                        let name = case.path.file_name().unwrap().to_string_lossy();
                        failures.lock().unwrap().push(format!("{name}: {e}"));
                    }
                }
            });
        }
    });
    let failures = failures.into_inner().unwrap();
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n\n")
    );
}
