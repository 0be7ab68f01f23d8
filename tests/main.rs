//! The root package's integration tests, in one test binary (`cargo test --test integration`;
//! `-- render::` runs one module's tests). Each test binary compiles its own copy of the generic
//! code it uses: as nine binaries these files took 88 s of compile time, as one 33 s
//! (docs/testing.md, "Fewer test binaries"). One binary also lets the harness run the long
//! tests of different modules side by side.
//!
//! Cargo's automatic discovery of `tests/*.rs` is off (`autotests = false`), so a new test file
//! must be declared here; `every_test_file_is_a_module` fails until it is (for this package
//! and for every workspace package whose tests are one binary too). The library's own test
//! build is off (`[lib] test = false`): its tests are here, and
//! `no_test_is_left_in_a_library_built_without_tests` checks that none is left in `src/`.

mod common;

mod distributed;
mod embedding;
mod extremes;
mod import;
mod import_hostile;
mod import_materials;
mod integrators;
mod learning;
mod mitsuba_parts;
mod module_layers;
mod one_point;
mod passes;
mod path;
mod render;
mod robustness;
mod study;
mod study_analysis;
mod study_plan;
mod surfaces;

/// The workspace's packages, as folders relative to the root: the root package and its
/// `members` (read from the root Cargo.toml, so that a new member is covered).
fn workspace_packages() -> Vec<std::path::PathBuf> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).expect("the root Cargo.toml");
    let members = manifest
        .lines()
        .find_map(|l| l.trim().strip_prefix("members = ["))
        .expect("the workspace's `members = [...]`, on one line");
    let mut packages = vec![root.to_path_buf()];
    packages.extend(
        members
            .split('"')
            .skip(1)
            .step_by(2)
            .map(|member| root.join(member)),
    );
    packages
}

/// Whether a package's Cargo.toml has `key = false` in its `section` (`[package]`, `[lib]`).
fn manifest_says_false(package: &std::path::Path, section: &str, key: &str) -> bool {
    let path = package.join("Cargo.toml");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut in_section = false;
    for line in text.lines().map(str::trim) {
        if line.starts_with('[') {
            in_section = line == section;
        } else if in_section
            && line
                .split_once('=')
                .is_some_and(|(k, v)| k.trim() == key && v.trim() == "false")
        {
            return true;
        }
    }
    false
}

/// Every `.rs` file and directory module in the `tests/` of each workspace package whose test
/// discovery is off (`autotests = false`) and whose tests are one binary, `tests/main.rs`, is
/// declared in that `tests/main.rs`: one that is not would never be compiled or run.
#[test]
fn every_test_file_is_a_module() {
    let mut checked = 0;
    for package in workspace_packages() {
        let tests = package.join("tests");
        let main = tests.join("main.rs");
        if !manifest_says_false(&package, "[package]", "autotests") || !main.is_file() {
            continue;
        }
        checked += 1;
        let main_text =
            std::fs::read_to_string(&main).unwrap_or_else(|e| panic!("{}: {e}", main.display()));
        let declared: std::collections::BTreeSet<&str> = main_text
            .lines()
            .filter_map(|l| l.strip_prefix("mod ")?.strip_suffix(';'))
            .collect();
        let entries =
            std::fs::read_dir(&tests).unwrap_or_else(|e| panic!("{}: {e}", tests.display()));
        for entry in entries {
            let path = entry.expect("a readable directory entry").path();
            let module = if path.extension().is_some_and(|e| e == "rs") {
                path.file_stem()
            } else if path.join("mod.rs").is_file() {
                path.file_name()
            } else {
                continue;
            };
            let module = module.and_then(|m| m.to_str()).expect("a UTF-8 file name");
            assert!(
                module == "main" || declared.contains(module),
                "{} is not declared in {} (`mod {module};`), so it never runs",
                path.display(),
                main.display()
            );
        }
    }
    // This package, the BSDFs, emitters, integrators, textures and the example methods.
    assert!(checked >= 6, "only {checked} packages checked");
}

/// A package whose library is not built as a test (`[lib] test = false`, so that `cargo test`
/// compiles it once) has no test in its `src/`: one there would never be compiled or run.
#[test]
fn no_test_is_left_in_a_library_built_without_tests() {
    let mut checked = 0;
    for package in workspace_packages() {
        if !manifest_says_false(&package, "[lib]", "test") {
            continue;
        }
        checked += 1;
        let mut folders = vec![package.join("src")];
        while let Some(folder) = folders.pop() {
            let entries =
                std::fs::read_dir(&folder).unwrap_or_else(|e| panic!("{}: {e}", folder.display()));
            for entry in entries {
                let path = entry.expect("a readable directory entry").path();
                if path.is_dir() {
                    folders.push(path);
                } else if path.extension().is_some_and(|e| e == "rs") {
                    let text = std::fs::read_to_string(&path)
                        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                    for attribute in ["#[test]", "#[cfg(test)]"] {
                        assert!(
                            !text.contains(attribute),
                            "{} has `{attribute}`, but its package's library is built without \
                             tests (`[lib] test = false`): move the test to the package's tests/",
                            path.display()
                        );
                    }
                }
            }
        }
    }
    // This package, the BSDFs, emitters, integrators, textures, the example methods and the
    // Python binding.
    assert!(checked >= 7, "only {checked} packages checked");
}
