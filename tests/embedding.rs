//! The tests of `lumis::embedding` (`src/embedding.rs`).

use lumis::embedding::*;

#[test]
fn panics_become_messages() {
    let caught = catch_panic(|| -> u32 { panic!("boom at {}", 3) });
    let message = caught.expect_err("the panic is caught");
    assert!(message.contains("internal error: boom at 3"), "{message}");
    let caught = catch_panic(|| -> u32 { std::panic::panic_any(7u8) });
    assert!(caught.expect_err("caught").contains("unknown panic"));
    assert_eq!(catch_panic(|| 7), Ok(7));
}
