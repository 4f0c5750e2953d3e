//! DiLiGenT's ground truth and baselines are MATLAB files: one reader, shared by the
//! real-data tests and `examples/diligent_ps.rs` (which includes this file by path; `matfile`
//! is a dev-dependency).

use std::path::Path;

/// Reads a MATLAB `h × w × 3` double array (column-major) into normal planes; panics with the
/// file and variable named when either is not what DiLiGenT ships.
pub fn read_mat_normals(path: &Path, name: &str, w: usize, h: usize) -> [Vec<f32>; 3] {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mat = matfile::MatFile::parse(file)
        .unwrap_or_else(|e| panic!("{}: not a MAT v5 file: {e:?}", path.display()));
    let arr = mat
        .find_by_name(name)
        .unwrap_or_else(|| panic!("{}: no variable {name}", path.display()));
    assert_eq!(
        arr.size(),
        &vec![h, w, 3],
        "{}: {name}'s size",
        path.display()
    );
    let matfile::NumericData::Double { real, .. } = arr.data() else {
        panic!("{}: {name} is not an array of doubles", path.display());
    };
    std::array::from_fn(|k| {
        (0..w * h)
            .map(|i| real[(i / w) + h * ((i % w) + w * k)] as f32)
            .collect()
    })
}
