//! The example methods' tests, in one test binary (`cargo test -p lumis-mis-methods`). Discovery
//! of `tests/*.rs` is off (`autotests = false`), so a new test file must be declared here; the
//! root package's `every_test_file_is_a_module` fails until it is.

mod convergence;
mod methods;
