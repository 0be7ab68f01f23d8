//! Cache hints.

/// Asks the processor to bring `value`'s cache line in, so that a read soon after finds it
/// there (x86-64; elsewhere nothing). For a table larger than the caches read at a position
/// known well before the read: the miss then overlaps the work in between.
#[inline(always)]
pub fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint that never faults, and `value` is a valid reference anyway.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>((value as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
