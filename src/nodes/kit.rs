//! Pieces shared by several nodes.

use super::{Coarse, Kind};
use crate::raster::convolve::BorderMode;

/// The kind of a kernel of reach `halo` under `border`: an area operator, except with a
/// periodic border, where a pixel near one edge reads the opposite one (global).
#[must_use]
pub fn kernel_kind(border: BorderMode, halo: usize, coarse: Coarse) -> Kind {
    if border == BorderMode::Wrap {
        Kind::Global { coarse }
    } else {
        Kind::Area { halo, coarse }
    }
}
