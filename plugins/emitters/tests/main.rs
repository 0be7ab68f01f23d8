//! The emitters' integration tests, in one test binary (`cargo test -p lumis-emitters --test
//! emitters`; `-- envmap_bilinear::` runs one module's tests): one binary compiles in less time
//! than one per file. Discovery of `tests/*.rs` is off (`autotests = false`), so a new test file
//! must be declared here; the root package's `every_test_file_is_a_module` fails until it is.

mod area;
mod delta;
mod emitters;
mod envmap;
mod envmap_bilinear;
