//! Mitsuba 3 XML → a RON scene and its list of problems, or an error, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    lumis::fuzzing::mitsuba_xml(data);
});
