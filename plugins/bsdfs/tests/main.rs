//! The BSDFs' integration tests, in one test binary (`cargo test -p lumis-bsdfs --test bsdfs`;
//! `-- evaluation::` runs one module's tests): one binary compiles in less time than one per
//! file. Discovery of `tests/*.rs` is off (`autotests = false`), so a new test file must be
//! declared here; the root package's `every_test_file_is_a_module` fails until it is.

mod bsdfs;
mod dielectrics;
mod evaluation;
mod glossy_masking;
mod ior;
mod materials;
mod measured;
mod microfacet;
