//! The root package's integration tests, in one test binary (`cargo test --test integration`;
//! `-- render::` runs one module's tests). Each test binary compiles its own copy of the generic
//! code it uses: as nine binaries these files took 88 s of compile time, as one 33 s
//! (docs/testing.md, "Fewer test binaries"). One binary also lets the harness run the long
//! tests of different modules side by side.
//!
//! Cargo's automatic discovery of `tests/*.rs` is off (`autotests = false`), so a new test file
//! must be declared here; `every_test_file_is_a_module` fails until it is (for this package
//! and for `lumis-bsdfs` and `lumis-emitters`, whose tests are one binary each too).

mod common;

mod distributed;
mod extremes;
mod import;
mod import_hostile;
mod import_materials;
mod integrators;
mod learning;
mod module_layers;
mod one_point;
mod passes;
mod path;
mod render;
mod robustness;
mod study;
mod surfaces;

/// Every `.rs` file and directory module in the `tests/` of each package whose test discovery is
/// off (this one, `lumis-bsdfs`, `lumis-emitters`) is declared in its `tests/main.rs`: one that
/// is not would never be compiled or run.
#[test]
fn every_test_file_is_a_module() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for package in [".", "plugins/bsdfs", "plugins/emitters"] {
        let tests = root.join(package).join("tests");
        let main = tests.join("main.rs");
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
}
