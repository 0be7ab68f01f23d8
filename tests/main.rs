//! The root package's integration tests, in one test binary (`cargo test --test integration`;
//! `-- render::` runs one module's tests). Each test binary links the library and instantiates
//! its generic code anew, so nine binaries cost CI about 88 s of compiling against one; one
//! binary also lets the harness run the long tests of different modules side by side.
//!
//! Cargo's automatic discovery of `tests/*.rs` is off (`autotests = false`), so a new test file
//! must be declared here; `every_test_file_is_a_module` fails until it is.

mod common;

mod distributed;
mod extremes;
mod import;
mod import_hostile;
mod integrators;
mod one_point;
mod render;
mod robustness;
mod study;

/// Every `.rs` file and directory module in `tests/` is declared above: with discovery off, one
/// that is not would never be compiled or run.
#[test]
fn every_test_file_is_a_module() {
    let tests = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let declared: std::collections::BTreeSet<String> = include_str!("main.rs")
        .lines()
        .filter_map(|l| l.strip_prefix("mod ")?.strip_suffix(';'))
        .map(str::to_string)
        .collect();
    let entries = std::fs::read_dir(&tests).unwrap_or_else(|e| panic!("{}: {e}", tests.display()));
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
            "{} is not declared in tests/main.rs (`mod {module};`), so it never runs",
            path.display()
        );
    }
}
