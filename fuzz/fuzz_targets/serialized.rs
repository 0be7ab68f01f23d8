//! Mitsuba `.serialized` bytes → a mesh or an error, never a panic, a hang or unbounded memory.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    lumis::fuzzing::serialized(data);
});
