//! File names: found where Mitsuba finds them (`files.rs`), written relative to the RON file's
//! folder.

use std::path::{Component, Path, PathBuf};

/// The file at `found` (where a relative name `name` of the XML was found), as a RON file in
/// `out_dir` must write it: relative to `out_dir`, `/` as the separator; an absolute `name` as
/// it is.
pub(super) fn found_as_written(name: &str, found: &Path, out_dir: &Path) -> String {
    if Path::new(name).is_absolute() {
        return name.to_string();
    }
    relative_path(found, out_dir)
        .to_string_lossy()
        .replace('\\', "/")
}

/// The components of `p` with `.` and `..` resolved lexically.
fn normal(p: &Path) -> Vec<Component<'_>> {
    let mut out: Vec<Component> = Vec::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.last(), Some(Component::Normal(_))) => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// `target` relative to the directory `base` (both made absolute, `.` and `..` resolved
/// lexically).
pub fn relative_path(target: &Path, base: &Path) -> PathBuf {
    // The folder of a bare file name (`-o scene.ron`) is the empty path: the current one.
    let base = if base.as_os_str().is_empty() {
        Path::new(".")
    } else {
        base
    };
    let (Ok(target_abs), Ok(base_abs)) = (std::path::absolute(target), std::path::absolute(base))
    else {
        return target.to_path_buf();
    };
    let (t, b) = (normal(&target_abs), normal(&base_abs));
    let common = t.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..b.len() {
        out.push("..");
    }
    for c in &t[common..] {
        out.push(c.as_os_str());
    }
    out
}
