//! Image-sized buffers backed by transparent huge pages.
//!
//! A 4K plane is 33 MB. A freshly allocated buffer is mapped lazily, one 4 KiB page fault at a
//! time on first touch; on the 2-core VMs we run on, that costs 1–2.5 µs a page, i.e. 8–20 ms
//! per 4K plane, before any pixel maths (measured: first write of a fresh 33 MB buffer
//! 8.4–21 ms, with 2 MiB huge pages 4.9–6.3 ms, an already mapped one 2.5–3.7 ms). A fused
//! filter writes three such planes, so page faults were a third of its time. Buffers from this
//! module ask the kernel for transparent huge pages (`madvise(MADV_HUGEPAGE)`, honoured when
//! `/sys/kernel/mm/transparent_hugepage/enabled` is `madvise` or `always`; NumPy does the same
//! for arrays over 4 MB), which cuts the faults 512-fold. Elsewhere, or when the kernel says
//! no, they are ordinary `Vec`s: the advice changes speed only, never contents.

/// Buffers smaller than this are left alone (a huge page would not fit inside them).
const MIN_ADVISED_BYTES: usize = 4 << 20;

/// A zero-filled `Vec<f32>` of `n` values (untouched until written).
#[must_use]
pub fn zeroed_f32(n: usize) -> Vec<f32> {
    let v = vec![0.0f32; n];
    advise_huge_pages(&v);
    v
}

/// An empty `Vec<f32>` with room for `n` values, for a kernel that writes all of them through
/// raw pointers and then sets the length: nothing is zero-filled first, so a block the
/// allocator reuses (see [`crate::recycle::Recycler`]) is written once, and a fresh one is
/// faulted in by the kernel's own writes.
#[must_use]
pub fn reserved_f32(n: usize) -> Vec<f32> {
    let mut v = Vec::with_capacity(n);
    advise_huge_pages(v.spare_capacity_mut());
    v
}

/// A zero-filled `Vec<u8>` of `n` bytes (untouched until written).
#[must_use]
pub fn zeroed_u8(n: usize) -> Vec<u8> {
    let v = vec![0u8; n];
    advise_huge_pages(&v);
    v
}

/// A `Vec<f32>` of `n` copies of `value`. Large buffers are filled by all threads, so that
/// their first-touch page faults (most of the cost) are taken in parallel too.
#[must_use]
pub fn filled_f32(n: usize, value: f32) -> Vec<f32> {
    if n * std::mem::size_of::<f32>() < MIN_ADVISED_BYTES {
        return vec![value; n];
    }
    let mut v = zeroed_f32(n);
    if value.to_bits() != 0 {
        use rayon::prelude::*;
        v.par_chunks_mut(1 << 18).for_each(|c| c.fill(value));
    }
    v
}

/// Three zero-filled planes of `n` values.
#[must_use]
pub fn zeroed_planes(n: usize) -> [Vec<f32>; 3] {
    [zeroed_f32(n), zeroed_f32(n), zeroed_f32(n)]
}

/// Advises the kernel to back the 2 MiB-aligned interior of `buf` with huge pages (call it
/// before the buffer is first written; buffers under 4 MiB are left alone).
pub fn advise_huge_pages<T>(buf: &[T]) {
    let bytes = std::mem::size_of_val(buf);
    if bytes < MIN_ADVISED_BYTES || !crate::recycle::huge_pages() {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let start = (buf.as_ptr() as usize).next_multiple_of(HUGE);
        let end = (buf.as_ptr() as usize + bytes) & !(HUGE - 1);
        if end > start {
            // SAFETY: `[start, end)` lies inside `buf`'s allocation and is page aligned;
            // MADV_HUGEPAGE only changes how the range is backed, never its contents, and a
            // refusal (e.g. THP disabled) is harmless, so the result is ignored.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_hold_what_was_asked_for() {
        // Both sides of the advice threshold, and a non-zero fill.
        for n in [0, 5, (MIN_ADVISED_BYTES / 4) + 12_345] {
            let z = zeroed_f32(n);
            assert_eq!(z.len(), n);
            assert!(z.iter().all(|v| v.to_bits() == 0));
            let f = filled_f32(n, -2.5);
            assert_eq!(f.len(), n);
            assert!(f.iter().all(|&v| v == -2.5));
            let b = zeroed_u8(n * 4);
            assert_eq!(b.len(), n * 4);
            assert!(b.iter().all(|&v| v == 0));
        }
        assert!(filled_f32(3, -0.0)
            .iter()
            .all(|v| v.to_bits() == (-0.0f32).to_bits()));
    }
}
