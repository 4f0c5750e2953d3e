//! A global allocator that recycles image-sized blocks.
//!
//! Every evaluation allocates its output planes afresh (a 4K plane is 33 MB), and the planes
//! of the previous evaluation are freed a moment before. The system allocator returns such
//! blocks to the kernel (`munmap`) and maps new ones, so each new plane is faulted in and
//! zero-filled by the kernel page by page on first touch: 100 MB of page clearing for a
//! three-plane result, about 10 ms of a 4K Gaussian filter (measured with `perf`, BENCHMARKS.md).
//! [`Recycler`] keeps a few freed blocks of at least [`BIG`] bytes and hands one back when a
//! block of exactly that size is asked for again, without touching its pages.
//!
//! - A zeroed request (`vec![0.0; n]`) reuses a kept block of its size too, cleared with one
//!   `memset`: writing 33 MB that is already mapped takes 2.5–3.7 ms where a fresh mapping's
//!   first touch takes 4.9–21 ms of page faults, each page zero-filled by the kernel (the
//!   header of `raster::buf`). Without a kept block it gets a fresh mapping: on Unix a big
//!   block is an anonymous mapping of its own, which the kernel zero-fills lazily, so it is
//!   never `memset` (the system allocator's aligned `alloc_zeroed` writes every byte, touching
//!   each page before the huge-page advice could apply).
//!   Kernels that write every value ask for a plain block ([`crate::raster::buf::reserved_f32`]).
//! - At most [`SLOTS`] blocks and [`KEEP_BYTES`] bytes are kept; a block that does not fit is
//!   freed at once. A big request that finds no block of its size frees every kept block
//!   first (the program has moved on to other sizes), so kept blocks never pile up beside new
//!   ones: the peak memory stays what the program itself needed (`RGBN_MEMORY_LIMIT`'s
//!   estimates hold).
//! - Blocks of [`BIG`] bytes or more are aligned to at least 64 bytes (a cache line; a page
//!   when mapped), whatever the request; smaller requests go to the system allocator unchanged.
//!
//! The `rgbn` binary and the benchmarks install it with
//! `#[global_allocator] static A: rgbn::recycle::Recycler = rgbn::recycle::Recycler;`. The
//! library itself does not, so a program embedding it keeps its own allocator.

use std::alloc::{GlobalAlloc, Layout, System};
// std's Mutex, not parking_lot's: this is the global allocator, and parking_lot allocates its
// wait table on first contention (an allocation from inside the allocator). Its poisoned
// lock is treated as "nothing kept" (the allocator falls through to the system).
use std::sync::Mutex;

/// Whether big blocks and image buffers ask for transparent huge pages (the default; see
/// [`set_huge_pages`]).
static HUGE_PAGES: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(true);

/// Turns the `MADV_HUGEPAGE` advice on big blocks ([`Recycler`]) and image buffers
/// (`raster::buf`) on or off for the rest of the process. The `rgbn` binary turns it off when
/// `RGBN_HUGE_PAGES=0` (for measuring what the advice is worth: BENCHMARKS.md); it changes
/// speed only, never contents.
pub fn set_huge_pages(on: bool) {
    HUGE_PAGES.store(on, std::sync::atomic::Ordering::Relaxed);
}

/// Keeps the system allocator's freed memory for reuse instead of handing it back to the
/// kernel (glibc on Linux; elsewhere nothing): blocks under 32 MiB come from the heap rather
/// than from a fresh `mmap` each (`M_MMAP_THRESHOLD`), and the heap is not trimmed below
/// 1 GiB of free memory (`M_TRIM_THRESHOLD`). Without it, each 1–4 MB scratch buffer (an EXR
/// block being compressed, a PNG row band) was a new mapping, page-faulted and zero-filled by
/// the kernel on first touch — most of the system time of a 4K `rgbn eval` (BENCHMARKS.md,
/// "Where the time goes"). Blocks of [`BIG`] bytes and more are [`Recycler`]'s. The command
/// line calls it before running a command (not the editor, whose memory should follow what it
/// holds), and the Python package's Dask tasks on their worker's first task.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets allocator parameters (glibc takes its arena lock, so other
    // threads may be allocating meanwhile).
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
    }
}

/// Whether the huge-page advice is on ([`set_huge_pages`]).
#[must_use]
pub fn huge_pages() -> bool {
    HUGE_PAGES.load(std::sync::atomic::Ordering::Relaxed)
}

/// Blocks of at least this many bytes are recycled (smaller ones are the system's business).
pub const BIG: usize = 4 << 20;
/// Freed blocks kept at most.
pub const SLOTS: usize = 8;
/// Bytes kept at most.
pub const KEEP_BYTES: usize = 512 << 20;
/// The bytes kept at most now ([`set_keep_limit`]; [`KEEP_BYTES`] unless lowered).
static KEEP_LIMIT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(KEEP_BYTES);

/// Keeps at most `bytes` of freed blocks from now on (at most [`KEEP_BYTES`]): the editor
/// gives the pool its share of the memory budget (`app::memory`).
pub fn set_keep_limit(bytes: usize) {
    KEEP_LIMIT.store(bytes.min(KEEP_BYTES), std::sync::atomic::Ordering::Relaxed);
}

/// The bytes kept at most now ([`set_keep_limit`]).
#[must_use]
pub fn keep_limit() -> usize {
    KEEP_LIMIT.load(std::sync::atomic::Ordering::Relaxed)
}

/// Bytes of freed blocks kept for reuse now (0 unless [`Recycler`] is the global allocator).
#[must_use]
pub fn kept_bytes() -> usize {
    KEPT.lock().map_or(0, |k| k.bytes)
}

/// The alignment of big blocks.
const BIG_ALIGN: usize = 64;

/// The global allocator of the module docs.
pub struct Recycler;

/// Kept blocks: (address, size); address 0 = empty slot.
struct Kept {
    blocks: [(usize, usize); SLOTS],
    bytes: usize,
}

static KEPT: Mutex<Kept> = Mutex::new(Kept {
    blocks: [(0, 0); SLOTS],
    bytes: 0,
});

/// The layout big blocks are really allocated with.
fn big_layout(l: Layout) -> Layout {
    // `align_to` only fails for alignments that are not powers of two or sizes that overflow
    // when padded, neither of which a valid `Layout` of ≥ 4 MiB with a 64-byte target hits;
    // keep the request unchanged should it ever happen.
    l.align_to(BIG_ALIGN).unwrap_or(l)
}

/// Whether a big block of layout `l` is an anonymous mapping of its own (on Unix, alignments up
/// to a page): a fresh mapping is zero and untouched, so a zeroed request costs no `memset` —
/// the system allocator's `alloc_zeroed` with a 64-byte alignment writes every byte, faulting
/// each page in at 4 KiB before the huge-page advice could apply — and the advice is given
/// before the first touch.
fn mapped(l: Layout) -> bool {
    cfg!(unix) && l.align() <= 4096
}

/// A new big block for `l` (zero-filled when `zeroed`, or always when [`mapped`]); null on
/// failure.
///
/// # Safety
/// `l` has a non-zero size.
unsafe fn big_alloc(l: Layout, zeroed: bool) -> *mut u8 {
    #[cfg(unix)]
    if mapped(l) {
        // SAFETY: an anonymous private mapping of a non-zero length; no memory is aliased.
        let p = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                l.size(),
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            )
        };
        if p == libc::MAP_FAILED {
            return std::ptr::null_mut();
        }
        let p = p.cast::<u8>();
        advise_huge(p, l.size());
        return p;
    }
    // SAFETY: a valid layout of non-zero size (the caller's contract).
    let p = unsafe {
        if zeroed {
            System.alloc_zeroed(big_layout(l))
        } else {
            System.alloc(big_layout(l))
        }
    };
    advise_huge(p, l.size());
    p
}

/// Frees a block [`big_alloc`] returned for a layout of the same size and alignment.
///
/// # Safety
/// `p` came from `big_alloc` with such a layout and is not used afterwards.
unsafe fn big_free(p: *mut u8, l: Layout) {
    #[cfg(unix)]
    if mapped(l) {
        // SAFETY: `p` is the start of a mapping of `l.size()` bytes (the caller's contract).
        unsafe { libc::munmap(p.cast(), l.size()) };
        return;
    }
    // SAFETY: non-mapped big blocks come from System with `big_layout(l)`.
    unsafe { System.dealloc(p, big_layout(l)) }
}

impl Recycler {
    /// A kept block of exactly `size` bytes, if there is one.
    fn take(size: usize) -> Option<*mut u8> {
        let mut k = KEPT.lock().ok()?;
        let slot = k.blocks.iter().position(|&(a, s)| a != 0 && s == size)?;
        let (addr, _) = std::mem::take(&mut k.blocks[slot]);
        k.bytes -= size;
        Some(addr as *mut u8)
    }

    /// Frees every kept block.
    fn release_all() {
        let blocks = match KEPT.lock() {
            Ok(mut k) => {
                k.bytes = 0;
                std::mem::replace(&mut k.blocks, [(0, 0); SLOTS])
            }
            Err(_) => return,
        };
        for (addr, size) in blocks {
            if addr != 0 {
                // SAFETY: kept blocks are big blocks of alignment ≤ 64 allocated by
                // `big_alloc` with their size; `big_free` with any such layout frees them as
                // they were allocated (64 is a valid power-of-two alignment).
                unsafe {
                    big_free(
                        addr as *mut u8,
                        Layout::from_size_align_unchecked(size, BIG_ALIGN),
                    );
                }
            }
        }
    }

    /// Keeps the block if there is room; false if it must be freed.
    fn keep(ptr: *mut u8, size: usize) -> bool {
        let Ok(mut k) = KEPT.lock() else {
            return false;
        };
        if k.bytes + size > KEEP_LIMIT.load(std::sync::atomic::Ordering::Relaxed) {
            return false;
        }
        let Some(slot) = k.blocks.iter().position(|&(a, _)| a == 0) else {
            return false;
        };
        k.blocks[slot] = (ptr as usize, size);
        k.bytes += size;
        true
    }
}

/// Asks for transparent huge pages over the 2 MiB-aligned interior of a new big block, before
/// anything touches it (pages already faulted in stay small). A kept block keeps its pages, so
/// this is what makes reused output planes huge-paged: a column sweep stores a row apart in
/// each plane, one 4 KiB page per store, and with small pages every one of those stores
/// missed the TLB (BENCHMARKS.md).
fn advise_huge(p: *mut u8, size: usize) {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        if p.is_null() || !huge_pages() {
            return;
        }
        let start = (p as usize).next_multiple_of(HUGE);
        let end = (p as usize + size) & !(HUGE - 1);
        if end > start {
            // SAFETY: `[start, end)` lies inside the block just allocated and is page
            // aligned; MADV_HUGEPAGE only changes how the range is backed, never its
            // contents, and a refusal (THP disabled) is harmless, so the result is ignored.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (p, size);
}

// SAFETY: every block is freed as it was allocated: big requests (size ≥ BIG) by `big_alloc` /
// `big_free` with the request's layout (an anonymous mapping of that size on Unix for
// alignments up to a page, else System with `big_layout(l)`) — a block keeps its size and its
// alignment class — and small ones by System with `l`. A kept block is owned by `KEPT` alone
// until `take` hands it to exactly one caller, with the same size and an alignment (a page, or
// 64) at least the request's whenever that request's alignment is at most 64; other requests
// are never served from `KEPT`.
unsafe impl GlobalAlloc for Recycler {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        if l.size() < BIG {
            // SAFETY: the caller's contract (non-zero size).
            return unsafe { System.alloc(l) };
        }
        if l.align() <= BIG_ALIGN {
            if let Some(p) = Self::take(l.size()) {
                return p;
            }
        }
        Self::release_all();
        // SAFETY: a valid layout of non-zero size.
        unsafe { big_alloc(l, false) }
    }

    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        if l.size() < BIG {
            // SAFETY: the caller's contract.
            return unsafe { System.alloc_zeroed(l) };
        }
        if l.align() <= BIG_ALIGN {
            if let Some(p) = Self::take(l.size()) {
                // SAFETY: `take` hands over a block of `l.size()` bytes owned by no one else.
                unsafe { std::ptr::write_bytes(p, 0, l.size()) };
                return p;
            }
        }
        Self::release_all();
        // SAFETY: a valid layout of non-zero size.
        unsafe { big_alloc(l, true) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, l: Layout) {
        if l.size() < BIG {
            // SAFETY: the caller's contract: `ptr` was allocated with `l` (small: by System).
            return unsafe { System.dealloc(ptr, l) };
        }
        if l.align() <= BIG_ALIGN && Self::keep(ptr, l.size()) {
            return;
        }
        // SAFETY: big blocks were allocated by `big_alloc` with `l`.
        unsafe { big_free(ptr, l) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, l: Layout, new_size: usize) -> *mut u8 {
        if l.size() < BIG && new_size < BIG {
            // SAFETY: the caller's contract; both sizes are small, so System owns the block.
            return unsafe { System.realloc(ptr, l, new_size) };
        }
        // Crossing or above the threshold: allocate, copy, free (each side with its own rule).
        // SAFETY: the caller guarantees `new_size` with `l.align()` is a valid layout.
        let new_l = unsafe { Layout::from_size_align_unchecked(new_size, l.align()) };
        // SAFETY: `new_l` has non-zero size (the caller's contract).
        let new = unsafe { self.alloc(new_l) };
        if !new.is_null() {
            // SAFETY: both blocks are at least `min(old, new)` bytes and do not overlap.
            unsafe { std::ptr::copy_nonoverlapping(ptr, new, l.size().min(new_size)) };
            // SAFETY: `ptr` was allocated by this allocator with `l`.
            unsafe { self.dealloc(ptr, l) };
        }
        new
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kept blocks are process-wide: these tests take turns.
    static TURN: Mutex<()> = Mutex::new(());

    /// The allocator's own rules, exercised directly (the test binary keeps the system
    /// allocator as its global one).
    #[test]
    fn a_freed_big_block_is_handed_back_for_the_same_size_and_is_aligned() {
        let _turn = TURN.lock().unwrap();
        // A size no other test allocates, so the shared cache cannot interfere.
        let size = BIG + 4096 * 7 + 12;
        let l = Layout::from_size_align(size, 4).unwrap();
        let r = Recycler;
        unsafe {
            let a = r.alloc(l);
            assert!(!a.is_null());
            assert_eq!(
                a as usize % BIG_ALIGN,
                0,
                "big blocks are cache-line aligned"
            );
            a.write_bytes(0xAB, size);
            r.dealloc(a, l);
            let b = r.alloc(l);
            assert_eq!(b, a, "the kept block comes back");
            // Not zeroed, not touched: what was written is still there.
            assert_eq!(*b.add(size - 1), 0xAB);
            // A zeroed request gets the kept block too, cleared: every byte is zero.
            r.dealloc(b, l);
            let z = r.alloc_zeroed(l);
            assert_eq!(z, a, "the kept block comes back for a zeroed request");
            assert!((0..size).all(|i| *z.add(i) == 0));
            r.dealloc(z, l);
            // Growing a big block keeps its contents.
            let c = r.alloc(l);
            c.write_bytes(7, size);
            let d = r.realloc(c, l, size * 2);
            assert!((0..size).step_by(4093).all(|i| *d.add(i) == 7));
            r.dealloc(d, Layout::from_size_align(size * 2, 4).unwrap());
            // Small blocks are the system's, as they were.
            let s = Layout::from_size_align(100, 8).unwrap();
            let p = r.alloc(s);
            assert!(!p.is_null());
            let p2 = r.realloc(p, s, 5 << 20);
            assert_eq!(p2 as usize % BIG_ALIGN, 0);
            r.dealloc(p2, Layout::from_size_align(5 << 20, 8).unwrap());
        }
    }

    #[test]
    fn the_kept_bytes_are_bounded_and_a_new_size_releases_them() {
        let _turn = TURN.lock().unwrap();
        let r = Recycler;
        let size = KEEP_BYTES / 2 + 4096 * 3;
        let l = Layout::from_size_align(size, 4).unwrap();
        unsafe {
            let blocks: Vec<*mut u8> = (0..3).map(|_| r.alloc(l)).collect();
            for &b in &blocks {
                r.dealloc(b, l);
            }
            // At most one block of just over half the bound can be kept.
            {
                let k = KEPT.lock().unwrap();
                assert_eq!(k.bytes, size);
                assert_eq!(k.blocks.iter().filter(|&&(a, _)| a != 0).count(), 1);
            }
            // A request of another size finds nothing to reuse and releases what was kept.
            let other = Layout::from_size_align(BIG + 64, 4).unwrap();
            let o = r.alloc(other);
            assert_eq!(KEPT.lock().unwrap().bytes, 0);
            r.dealloc(o, other);
        }
    }
}
