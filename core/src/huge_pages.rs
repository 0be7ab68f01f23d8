//! Huge pages for the large tables that rays and light samples read at random: the BVH's nodes
//! and primitives, an environment map's texels and sampling tables. With 4 KiB pages, a read
//! at a random place in a table of several MiB misses the TLB as well as the caches. Linux backs
//! a region with 2 MiB pages when asked (`madvise(MADV_HUGEPAGE)`) before the region is first
//! written. Linux does this when transparent huge pages are `always` or `madvise`, the common
//! default. Elsewhere nothing is done.

/// An empty vector with room for `capacity` elements, whose memory Linux is asked to back with
/// huge pages: fill it afterwards (`push`, `extend`), so that its pages are first touched after
/// the request. Tables under 2 MiB are left alone.
pub fn vec_with_capacity<T>(capacity: usize) -> Vec<T> {
    let vec: Vec<T> = Vec::with_capacity(capacity);
    advise(vec.as_ptr().cast(), capacity * size_of::<T>());
    vec
}

/// Size of a huge page on x86-64 and on aarch64 with 4 KiB pages.
const HUGE_PAGE: usize = 2 << 20;

#[cfg(target_os = "linux")]
fn advise(start: *const u8, bytes: usize) {
    if bytes < HUGE_PAGE {
        return;
    }
    // SAFETY: sysconf has no preconditions.
    let page = usize::try_from(unsafe { libc::sysconf(libc::_SC_PAGESIZE) }).unwrap_or(4096);
    // madvise takes page-aligned bounds; the kernel uses huge pages for the aligned 2 MiB
    // blocks within.
    let begin = (start as usize).next_multiple_of(page);
    let end = (start as usize + bytes) / page * page;
    if end > begin {
        // SAFETY: the range lies within this vector's allocation, which this process owns;
        // MADV_HUGEPAGE changes no contents. Its result is ignored: where huge pages are off
        // or unsupported the call fails and the pages stay ordinary.
        unsafe {
            libc::madvise(begin as *mut libc::c_void, end - begin, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise(_start: *const u8, _bytes: usize) {}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    /// The `VmFlags` of the mapping that contains `address`, from /proc/self/smaps.
    fn flags_at(address: usize) -> Option<String> {
        let smaps = std::fs::read_to_string("/proc/self/smaps").expect("/proc/self/smaps");
        let mut inside = false;
        for line in smaps.lines() {
            if let Some((range, _)) = line.split_once(' ')
                && let Some((lo, hi)) = range.split_once('-')
                && let (Ok(lo), Ok(hi)) =
                    (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
            {
                inside = (lo..hi).contains(&address);
            } else if inside && let Some(flags) = line.strip_prefix("VmFlags:") {
                return Some(flags.to_string());
            }
        }
        None
    }

    /// Where the kernel has transparent huge pages, the middle of a 16 MiB table is advised
    /// for them (`hg`); the table holds what was put in it.
    #[test]
    fn large_tables_are_advised_for_huge_pages() {
        let mut large: Vec<u64> = vec_with_capacity(2 << 20);
        large.extend(0..2 << 20);
        assert!(large.iter().enumerate().all(|(i, &v)| v == i as u64));
        let advised = |address: usize| {
            let flags = flags_at(address).expect("the table's mapping in /proc/self/smaps");
            flags.split_whitespace().any(|flag| flag == "hg")
        };
        if std::path::Path::new("/sys/kernel/mm/transparent_hugepage").exists() {
            assert!(
                advised(large.as_ptr() as usize + (8 << 20)),
                "16 MiB table not advised"
            );
        } else {
            eprintln!("no transparent huge pages in this kernel: the advice is not checked");
        }
    }
}
