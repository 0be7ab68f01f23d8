//! PLY bytes (ASCII or binary) → a mesh or an error, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    lumis::fuzzing::ply(data);
});
