//! Interrupting `lumis render`: the first Ctrl-C (SIGINT) or a SIGTERM stops the render and
//! writes what is finished as a partial image; a second one exits at once. Each test starts the
//! CLI as a child process, waits for it to say on stderr that the render runs (no fixed sleep),
//! and signals it.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

fn cornell() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell.ron")
}

/// A render of the Cornell box in `dir` with `args`, and a channel of its stderr lines.
fn start(dir: &Path, args: &[&str]) -> (Child, mpsc::Receiver<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lumis"))
        .current_dir(dir)
        .arg("render")
        .arg(cornell())
        .args(["-o", "cut.exr"])
        .args(args)
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let (send, lines) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if send.send(line).is_err() {
                break;
            }
        }
    });
    (child, lines)
}

/// Waits for a stderr line starting with `prefix`; the lines seen so far otherwise.
fn wait_for(lines: &mpsc::Receiver<String>, prefix: &str, seen: &mut Vec<String>) {
    let deadline = Instant::now() + Duration::from_secs(120);
    while Instant::now() < deadline {
        match lines.recv_timeout(Duration::from_millis(100)) {
            Ok(line) => {
                let found = line.starts_with(prefix);
                seen.push(line);
                if found {
                    return;
                }
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        }
    }
    panic!("no line starting with {prefix:?}; stderr: {seen:#?}");
}

fn signal(child: &Child, signal: libc::c_int) {
    // SAFETY: kill(2) on the pid of a child this test started and has not reaped.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
}

/// Waits for the child to exit, at most `limit`; its status code and the time it took.
fn wait_exit(child: &mut Child, limit: Duration) -> (Option<i32>, Duration) {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return (status.code(), start.elapsed());
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("still running {limit:?} after the signal");
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The `lumis` header attribute of an EXR.
fn metadata(path: &Path) -> String {
    lumis::image_io::read_exr_metadata(path)
        .unwrap()
        .iter()
        .map(|(k, v)| format!("{k}={v}\n"))
        .collect()
}

fn no_temporaries(dir: &Path) -> bool {
    std::fs::read_dir(dir)
        .unwrap()
        .all(|e| !e.unwrap().file_name().to_string_lossy().ends_with(".tmp"))
}

/// The case: at 200 000 spp one 16 × 16 tile takes minutes, so a stop flag read between
/// tiles is not enough; the render loop reads it before every camera sample.
#[test]
fn ctrl_c_stops_a_200000_spp_render_within_2_s() {
    let dir = tempfile::tempdir().unwrap();
    let (mut child, lines) = start(dir.path(), &["--spp", "200000"]);
    let mut seen = Vec::new();
    wait_for(&lines, "rendering ", &mut seen);
    signal(&child, libc::SIGINT);
    let (code, took) = wait_exit(&mut child, Duration::from_secs(30));
    assert!(took < Duration::from_secs(2), "took {took:?}");
    assert_eq!(code, Some(130));
    let text = metadata(&dir.path().join("cut.exr"));
    assert!(text.contains("partial=true\n"), "{text}");
    assert!(dir.path().join("cut.png").exists());
    assert!(no_temporaries(dir.path()));
}

/// The same with `path`, paths unbounded and Russian roulette off (each camera sample may run to
/// the hard cap of 1024 vertices): the flag read before every camera sample still stops it.
#[test]
fn ctrl_c_stops_an_unbounded_path_render_within_2_s() {
    let dir = tempfile::tempdir().unwrap();
    let (mut child, lines) = start(
        dir.path(),
        &[
            "--spp",
            "200000",
            "--set",
            "integrator=(type: \"path\")",
            "--set",
            "integrator.max_depth=-1",
            "--set",
            "integrator.rr_depth=2147483647",
        ],
    );
    let mut seen = Vec::new();
    wait_for(&lines, "rendering ", &mut seen);
    signal(&child, libc::SIGINT);
    let (code, took) = wait_exit(&mut child, Duration::from_secs(30));
    assert!(took < Duration::from_secs(2), "took {took:?}");
    assert_eq!(code, Some(130), "{seen:#?}");
    assert!(no_temporaries(dir.path()));
}

#[test]
fn a_second_ctrl_c_exits_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let (mut child, lines) = start(dir.path(), &["--spp", "200000"]);
    let mut seen = Vec::new();
    wait_for(&lines, "rendering ", &mut seen);
    signal(&child, libc::SIGINT);
    wait_for(&lines, "interrupted: finishing", &mut seen);
    signal(&child, libc::SIGINT);
    let (code, took) = wait_exit(&mut child, Duration::from_secs(30));
    assert!(took < Duration::from_secs(2), "took {took:?}");
    assert_eq!(code, Some(130), "{seen:#?}");
    assert!(no_temporaries(dir.path()));
}

#[test]
fn sigterm_writes_the_partial_image_and_exits_143() {
    let dir = tempfile::tempdir().unwrap();
    // About 2 s on one thread; SIGTERM once a tenth is done.
    let (mut child, lines) = start(
        dir.path(),
        &[
            "--threads",
            "1",
            "--spp",
            "64",
            "--set",
            "integrator.samples=64",
        ],
    );
    let mut seen = Vec::new();
    wait_for(&lines, "rendered 10%", &mut seen);
    signal(&child, libc::SIGTERM);
    let (code, _) = wait_exit(&mut child, Duration::from_secs(60));
    for line in lines.try_iter() {
        seen.push(line);
    }
    assert_eq!(code, Some(143), "{seen:#?}");
    assert!(
        seen.iter()
            .any(|l| l.starts_with("interrupted: wrote a partial image") && l.ends_with("SIGTERM")),
        "{seen:#?}"
    );
    let text = metadata(&dir.path().join("cut.exr"));
    assert!(text.contains("partial=true\n"), "{text}");
    let tiles = text.lines().find_map(|l| l.strip_prefix("tiles=")).unwrap();
    let (done, total) = tiles.split_once(" of ").unwrap();
    let (done, total): (u32, u32) = (done.parse().unwrap(), total.parse().unwrap());
    assert!(done > 0 && done < total, "{tiles}");
    let pixels = text
        .lines()
        .find_map(|l| l.strip_prefix("pixels="))
        .unwrap();
    let (done, total) = pixels.split_once(" of ").unwrap();
    let (done, total): (u64, u64) = (done.parse().unwrap(), total.parse().unwrap());
    assert!(done > 0 && done < total, "{pixels}");
    assert!(dir.path().join("cut.png").exists());
    assert!(no_temporaries(dir.path()));
}

/// A render in passes interrupted in its second pass: the first pass is written within 2 s,
/// marked partial, with the render's state beside it; the same command with `--resume` then
/// finishes it into the image of a render never interrupted, and removes the state.
#[test]
fn ctrl_c_in_a_render_in_passes_saves_a_state_that_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = [
        "--passes",
        "2",
        "--spp",
        "32",
        "--threads",
        "1",
        "--set",
        "film.width=64",
        "--set",
        "film.height=64",
        "--set",
        "integrator.samples=64",
    ];
    let (mut child, lines) = start(d, &args);
    let mut seen = Vec::new();
    wait_for(&lines, "pass 1:", &mut seen);
    signal(&child, libc::SIGINT);
    let (code, took) = wait_exit(&mut child, Duration::from_secs(30));
    assert!(took < Duration::from_secs(2), "took {took:?}");
    assert_eq!(code, Some(130), "{seen:#?}");
    for line in lines.try_iter() {
        seen.push(line);
    }
    let text = metadata(&d.join("cut.exr"));
    assert!(
        text.contains("partial=true\n") && text.contains("passes=1\n"),
        "{text}"
    );
    assert!(
        seen.iter()
            .any(|l| l.contains("continue it with") && l.contains("--resume")),
        "{seen:#?}"
    );
    assert!(d.join("cut.lshard").exists());
    assert!(no_temporaries(d));

    let run = |extra: &[&str], out: &str| {
        let status = Command::new(env!("CARGO_BIN_EXE_lumis"))
            .current_dir(d)
            .arg("render")
            .arg(cornell())
            .args(["-q", "-o", out])
            .args(args)
            .args(extra)
            .status()
            .unwrap();
        assert!(status.success());
    };
    run(&["--resume", "cut.lshard"], "cut.exr");
    assert!(!d.join("cut.lshard").exists());
    run(&[], "whole.exr");
    let channels = |f: &str| lumis::image_io::read_exr_channels(&d.join(f)).unwrap();
    assert_eq!(channels("cut.exr"), channels("whole.exr"));
    assert!(metadata(&d.join("cut.exr")).contains("partial=false\n"));
}
