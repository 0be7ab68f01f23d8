//! Texture image bytes (PNG, JPEG, EXR) → a decoded image or an error, never a panic, never an
//! allocation of what a header claims before it is checked.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    lumis::fuzzing::texture(data);
});
