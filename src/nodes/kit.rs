//! Pieces shared by several nodes: the `relative_rms_curl` output that nonlinear (and any
//! other) editing nodes report.

use super::{Footprint, PortSpec, PortType};
use crate::params::{Meta, ParamVisitor};
use crate::raster::convolve::BorderMode;

/// Border mode names, in [`BorderMode::ALL`] order.
pub const BORDERS: [&str; 4] = ["mirror", "clamp", "wrap", "zero"];

/// Declares a `border` choice parameter.
pub fn visit_border(v: &mut dyn ParamVisitor, border: &mut &'static str) {
    v.choice(
        "border",
        border,
        &BORDERS,
        &Meta::new("How the image is extended beyond its border."),
    );
}

/// The border mode called `name` (the default for an unknown name, which the visitor refuses).
#[must_use]
pub fn border_mode(name: &str) -> BorderMode {
    BorderMode::ALL
        .into_iter()
        .find(|b| b.name() == name)
        .unwrap_or_default()
}

/// The `relative_rms_curl` output port.
#[must_use]
pub fn curl_port(what: &str) -> PortSpec {
    PortSpec {
        name: "relative_rms_curl".into(),
        ty: PortType::Number,
        doc: format!(
            "RMS(curl) / RMS(|g|) of the {what} inside the mask: the integrability readout (0 for the gradients of a height)."
        ),
        optional: false,
    }
}

/// The footprint of a kernel of reach `halo` under `border`: local, except with a periodic
/// border, where a pixel near one edge reads the opposite one.
#[must_use]
pub fn kernel_footprint(border: BorderMode, halo: usize) -> Footprint {
    if border == BorderMode::Wrap {
        Footprint::Global
    } else {
        Footprint::Local { halo }
    }
}

/// `points` moved by `(−dx, −dy)` for a crop at `(dx, dy)` ([`super::Operator::shifted`]).
/// Operators use their points as `f32`; the shift is applied to those values, where moving by
/// whole pixels is exact, so a crop sees the path exactly where the whole image does.
#[must_use]
pub fn shift_points(points: &[[f64; 2]], dx: f64, dy: f64) -> Vec<[f64; 2]> {
    points
        .iter()
        .map(|p| [f64::from(p[0] as f32) - dx, f64::from(p[1] as f32) - dy])
        .collect()
}
