//! Parallel helpers shared by the raster passes: a raw pointer that rayon tasks share to write
//! disjoint parts of one buffer ([`SharedMut`]), and column groups of a row-major buffer
//! ([`par_column_groups`]) for column passes without a transpose.

use rayon::prelude::*;

/// A raw pointer that may be shared between rayon tasks writing disjoint elements of one buffer
/// (column groups in [`par_column_groups`], `convolve::filter_columns` and
/// `smooth::smooth_normals`).
///
/// Every dereference is `unsafe` at its use site, with the disjointness argument there.
pub(crate) struct SharedMut<T>(pub(crate) *mut T);

impl<T> Clone for SharedMut<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for SharedMut<T> {}

impl<T> SharedMut<T> {
    /// The pointer. A method (not field access) so closures capture the whole `Sync` wrapper.
    pub(crate) fn get(self) -> *mut T {
        self.0
    }
}
// SAFETY: used only to write disjoint elements (column groups) from parallel tasks: see
// `par_column_groups`, `convolve::filter_columns` and `smooth::smooth_normals`, whose tasks
// touch disjoint columns. `T: Send` because the elements are written from other threads.
unsafe impl<T: Send> Send for SharedMut<T> {}
unsafe impl<T: Send> Sync for SharedMut<T> {}

/// Columns `c0..c0 + cols` of every row of a row-major buffer, owned by one rayon task.
pub(crate) struct ColumnGroup<'a, T> {
    ptr: SharedMut<T>,
    width: usize,
    height: usize,
    pub(crate) c0: usize,
    pub(crate) cols: usize,
    _data: std::marker::PhantomData<&'a mut [T]>,
}

impl<T> ColumnGroup<'_, T> {
    /// The group's part of row `r` (borrowing the group, so one row slice at a time).
    pub(crate) fn row(&mut self, r: usize) -> &mut [T] {
        assert!(r < self.height);
        // SAFETY: columns c0..c0+cols of row r lie inside the buffer (r < height and
        // c0 + cols ≤ width by construction in `par_column_groups`); no other task touches
        // these columns while the group lives, and `&mut self` allows one slice at a time.
        unsafe {
            std::slice::from_raw_parts_mut(self.ptr.get().add(r * self.width + self.c0), self.cols)
        }
    }
}

/// Runs `f(state, group)` for groups of `group` columns (fewer in the last) of a row-major
/// `width`-wide buffer, groups in parallel, with one `init()` state per rayon job. Columns are
/// gathered / scattered in row segments a cache line wide, so a column transform moves no
/// more memory than a row pass and needs no transpose.
pub(crate) fn par_column_groups<T: Send, S: Send>(
    data: &mut [T],
    width: usize,
    group: usize,
    init: impl Fn() -> S + Sync + Send,
    f: impl Fn(&mut S, &mut ColumnGroup<'_, T>) + Sync + Send,
) {
    if width == 0 || data.is_empty() {
        return;
    }
    let height = data.len() / width;
    assert_eq!(data.len(), width * height);
    let ptr = SharedMut(data.as_mut_ptr());
    (0..width.div_ceil(group))
        .into_par_iter()
        .for_each_init(init, |state, gi| {
            let c0 = gi * group;
            let mut cg = ColumnGroup {
                ptr,
                width,
                height,
                c0,
                cols: group.min(width - c0),
                _data: std::marker::PhantomData,
            };
            f(state, &mut cg);
        });
}
