//! The command's allocator: the system's, with every block of 2 MiB or more
//! marked for transparent huge pages (`madvise(MADV_HUGEPAGE)`, which Debian's
//! kernels honour by default). A reconstruction touches tens of megabytes of
//! fresh memory (decoded frames, the volume, hole-filling tables); in 4 KiB
//! pages each of those costs the kernel a page fault, and the faults were about
//! a sixth of `probecal reconstruct`'s time. The memory's contents and sizes are
//! unchanged; only the kernel's page size for it is.

use std::alloc::{GlobalAlloc, Layout, System};

/// The system allocator with large blocks advised to use huge pages.
pub struct LargePages;

/// A huge page on x86-64 and aarch64 (with 4 KiB base pages).
const HUGE_PAGE: usize = 2 << 20;

/// Marks the whole huge pages inside `[ptr, ptr + size)`; a failure (a kernel
/// without transparent huge pages) changes nothing and is ignored.
fn advise(ptr: *mut u8, size: usize) {
    if ptr.is_null() || size < HUGE_PAGE {
        return;
    }
    let start = (ptr as usize).next_multiple_of(HUGE_PAGE);
    let end = (ptr as usize).saturating_add(size) / HUGE_PAGE * HUGE_PAGE;
    if end > start {
        // SAFETY: the range lies inside a block this allocator just handed out;
        // MADV_HUGEPAGE only changes how its pages are backed, not their contents.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

// SAFETY: every call is forwarded to `System` with the same arguments; `advise`
// does not touch the memory's contents.
unsafe impl GlobalAlloc for LargePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let ptr = System.alloc(layout);
        advise(ptr, layout.size());
        ptr
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let ptr = System.alloc_zeroed(layout);
        advise(ptr, layout.size());
        ptr
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let ptr = System.realloc(ptr, layout, new_size);
        advise(ptr, new_size);
        ptr
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_keep_their_contents() {
        let allocator = LargePages;
        for size in [16, HUGE_PAGE - 1, HUGE_PAGE, 3 * HUGE_PAGE + 12345] {
            let layout = Layout::from_size_align(size, 64).expect("a layout");
            // SAFETY: the layout is non-zero; every pointer is freed with it.
            unsafe {
                let zeroed = allocator.alloc_zeroed(layout);
                assert!(!zeroed.is_null());
                let bytes = std::slice::from_raw_parts_mut(zeroed, size);
                assert!(bytes.iter().all(|&b| b == 0), "{size} bytes not zeroed");
                for (i, b) in bytes.iter_mut().enumerate() {
                    *b = (i % 251) as u8;
                }
                let grown = allocator.realloc(zeroed, layout, size * 2);
                let bytes = std::slice::from_raw_parts(grown, size);
                assert!(
                    bytes.iter().enumerate().all(|(i, &b)| b == (i % 251) as u8),
                    "{size} bytes moved wrongly"
                );
                allocator.dealloc(grown, Layout::from_size_align(size * 2, 64).expect("a layout"));
            }
        }
    }
}
