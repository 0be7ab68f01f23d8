//! For programs that embed lumis (the Python binding): a panic inside lumis is a bug in lumis,
//! never the caller's fault, and must not unwind into the host program; [`catch_panic`] turns
//! it into an error message that says so.

use std::panic::{AssertUnwindSafe, catch_unwind};

/// The message a panic was raised with.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

/// Runs `f`, turning a panic into an error message (a bug in lumis, never the user's fault).
pub fn catch_panic<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|payload| {
        format!(
            "internal error: {} (a bug in lumis; please report it with the scene)",
            panic_message(payload.as_ref())
        )
    })
}
