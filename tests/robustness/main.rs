//! The robustness tests, in one test binary (each integration-test file is a binary to compile
//! and link; one saves CI a minute): bad input gets a clear error, never a panic (`errors`, the
//! hostile-input corpus `hostile`, the fuzzers' corpora `fuzz_corpus`), the geometric limits
//! (`scales`), interrupts (`interrupt`) and run-time plugin libraries (`plugin_library`). See
//! docs/robustness.md.

#[path = "../common/mod.rs"]
mod common;

mod errors;
mod fuzz_corpus;
mod hostile;
mod interrupt;
mod plugin_library;
mod scales;
