//! The robustness tests: bad input gets a clear error, never a panic (`errors`, the
//! hostile-input corpus `hostile`, the fuzzers' corpora `fuzz_corpus`), the geometric limits
//! (`scales`), interrupts (`interrupt`) and run-time plugin libraries (`plugin_library`). See
//! docs/robustness.md.

mod errors;
mod fuzz_corpus;
mod hostile;
mod interrupt;
mod plugin_library;
mod scales;
