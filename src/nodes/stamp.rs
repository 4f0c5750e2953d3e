//! The stamp of [`crate::ops::stamp`] as a node: place an RGBN stamp at positions with an affine map
//! ([`stamp_image`]).

use super::kit::curl_port;
use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::params::{Meta, ParamVisitor, Params};
use crate::ops::stamp::{stamp_image, StampColor, StampParams};

/// Parameters of [`StampNode`].
#[derive(Clone, Debug, PartialEq)]
pub struct StampNodeParams {
    /// Centres `(x, row)`.
    pub positions: Vec<[f64; 2]>,
    /// Scale along the stamp's u axis.
    pub scale_x: f64,
    /// Scale along the stamp's v axis.
    pub scale_y: f64,
    /// Rotation.
    pub angle_rad: f64,
    /// Shear.
    pub shear: f64,
    /// Relief factor.
    pub height_scale: f64,
    /// Edge fade.
    pub falloff_px: f64,
    /// Composite colour.
    pub color: bool,
    /// Colour opacity.
    pub opacity: f64,
}

impl Default for StampNodeParams {
    fn default() -> Self {
        let d = StampParams::default();
        let opacity = match d.color {
            StampColor::Over { opacity } => f64::from(opacity),
            StampColor::None => 1.0,
        };
        Self {
            positions: d.positions.iter().map(|p| p.map(f64::from)).collect(),
            scale_x: f64::from(d.scale[0]),
            scale_y: f64::from(d.scale[1]),
            angle_rad: f64::from(d.angle_rad),
            shear: f64::from(d.shear),
            height_scale: f64::from(d.height_scale),
            falloff_px: f64::from(d.falloff_px),
            color: matches!(d.color, StampColor::Over { .. }),
            opacity,
        }
    }
}

impl Params for StampNodeParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.points(
            "positions",
            &mut self.positions,
            &Meta::new("Where the stamp's centre goes, in pixels (x, row); at least one.")
                .unit("px"),
        );
        let big = |doc| Meta::new(doc).range(-1e4, 1e4);
        v.float(
            "scale_x",
            &mut self.scale_x,
            &big("Scale along the stamp's own u axis (negative mirrors)."),
        );
        v.float(
            "scale_y",
            &mut self.scale_y,
            &big("Scale along the stamp's own v axis (negative mirrors)."),
        );
        v.float(
            "angle_rad",
            &mut self.angle_rad,
            &big("Rotation, counter-clockwise on screen.").unit("rad"),
        );
        v.float(
            "shear",
            &mut self.shear,
            &big("Shear u += shear·v in the stamp frame (before the rotation)."),
        );
        v.float(
            "height_scale",
            &mut self.height_scale,
            &big("Multiplies the relief (−1 engraves instead of embossing)."),
        );
        v.float(
            "falloff_px",
            &mut self.falloff_px,
            &Meta::new("Width of the fade at each stamp edge, in stamp pixels (0 = hard edge).")
                .unit("px")
                .range(0.0, 1e4),
        );
        v.bool(
            "color",
            &mut self.color,
            &Meta::new("Composite the stamp's colour over the image (else relief only)."),
        );
        v.float(
            "opacity",
            &mut self.opacity,
            &Meta::new("Opacity of the stamp's colour.").range(0.0, 1.0),
        );
    }
}

impl StampNodeParams {
    fn to_params(&self) -> Result<StampParams, RgbnError> {
        let p = StampParams {
            positions: self.positions.iter().map(|p| p.map(|v| v as f32)).collect(),
            scale: [self.scale_x as f32, self.scale_y as f32],
            angle_rad: self.angle_rad as f32,
            shear: self.shear as f32,
            height_scale: self.height_scale as f32,
            falloff_px: self.falloff_px as f32,
            color: if self.color {
                StampColor::Over {
                    opacity: self.opacity as f32,
                }
            } else {
                StampColor::None
            },
        };
        p.validate().map_err(|e| match e {
            RgbnError::InvalidParam { name, detail } if name == "scale" => {
                RgbnError::param("scale_x", detail)
            }
            other => other,
        })?;
        Ok(p)
    }
}

/// Stamp.
pub struct StampNode;

impl Operator for StampNode {
    type Params = StampNodeParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "stamp",
            "Stamp",
            "combine",
            "Places a small RGBN (its relief, optionally its colour) at positions with an affine map (Pereira & Velho §IV, Fig. 4). The stamp is integrated once and its windowed height added, so the stamped relief is integrable for any map.",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Target image."))
        .input(PortSpec::new(
            "stamp",
            PortType::Rgbn,
            "The stamp (at most 512 px a side); its mask limits the colour.",
        ))
        .output(PortSpec::new("image", PortType::Rgbn, "Stamped image."))
        .output(curl_port("result's gradients"))
    }
    fn check(p: &StampNodeParams) -> Result<(), RgbnError> {
        p.to_params().map(|_| ())
    }
    fn run(p: &StampNodeParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let (img, rep) = stamp_image(i.rgbn("image")?, i.rgbn("stamp")?, &p.to_params()?)?;
        Ok(vec![
            Value::Rgbn(img),
            Value::Number(rep.curl_after.relative),
        ])
    }
}
