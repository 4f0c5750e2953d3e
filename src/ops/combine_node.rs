//! The two combines as nodes: the linear combine of [`super::combine`] (`combine.linear`, with a
//! detail given as normals or as a height) and the rotation combine of [`super::rotate`]
//! (`combine.rotation`).

use super::combine::{linear_combine_height, linear_combine_images, LinearCombineParams};
use super::node_kit::{border_mode, curl_port, visit_border, BandChoice, FrameChoice};
use super::params::{Meta, ParamVisitor, Params};
use super::rotate::{rotation_combine, CombineMode, RotateParams};
use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::raster::gradient::GradientField;

/// Parameters of [`LinearCombineNode`].
#[derive(Clone, Debug, PartialEq)]
pub struct LinearCombineNodeParams {
    /// Amount of detail α.
    pub alpha: f64,
    /// The band replaced (`none` = plain addition).
    pub replace_band: BandChoice,
    /// Border mode of the band kernels.
    pub border: &'static str,
}

impl Default for LinearCombineNodeParams {
    fn default() -> Self {
        Self {
            alpha: 1.0,
            replace_band: BandChoice::new("none"),
            border: "mirror",
        }
    }
}

impl Params for LinearCombineNodeParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.float(
            "alpha",
            &mut self.alpha,
            &Meta::new("Amount of detail α (1 = as is, negative inverts the detail's relief).")
                .range(-1000.0, 1000.0),
        );
        self.replace_band.visit(
            v,
            "replace_band",
            &["none", "lowpass", "highpass", "bandpass", "log"],
            "none: w = ∇b + α·m·∇h; otherwise the base loses this band where the detail goes and gets the detail's band: w = ∇b − m·B(∇b) + α·m·B(∇h).",
        );
        visit_border(v, &mut self.border);
    }
}

impl LinearCombineNodeParams {
    fn to_params(&self) -> Result<LinearCombineParams, RgbnError> {
        let p = LinearCombineParams {
            alpha: self.alpha as f32,
            replace_band: self.replace_band.band()?,
            border: border_mode(self.border),
        };
        p.validate()?;
        Ok(p)
    }
}

/// Linear combine of gradients.
pub struct LinearCombineNode;

impl Operator for LinearCombineNode {
    type Params = LinearCombineNodeParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "combine.linear",
            "Linear combine",
            "combine",
            "Adds a detail's relief to a base through their gradients (Pereira & Velho §IV): ∇b + α·m·∇h, optionally replacing a band of the base. With weight 1 it is the partial-derivative blend. A detail given as a height adds α·∇(m·h) instead, which stays integrable for any weight.",
        )
        .input(PortSpec::new("base", PortType::Rgbn, "Base image (colour and mask are kept)."))
        .input(
            PortSpec::new(
                "detail",
                PortType::Rgbn,
                "Detail as normals (connect this or detail_height).",
            )
            .optional(),
        )
        .input(
            PortSpec::new(
                "detail_height",
                PortType::Scalar,
                "Detail as a height in pixels (connect this or detail).",
            )
            .optional(),
        )
        .input(
            PortSpec::new(
                "weight",
                PortType::Mask,
                "Per-pixel weight m in [0, 1] (1 everywhere when unconnected).",
            )
            .optional(),
        )
        .output(PortSpec::new("image", PortType::Rgbn, "Combined image."))
        .output(curl_port("combined gradients"))
    }
    fn check(p: &LinearCombineNodeParams) -> Result<(), RgbnError> {
        p.to_params().map(|_| ())
    }
    fn run(
        p: &LinearCombineNodeParams,
        i: &Inputs<'_>,
        _: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        let params = p.to_params()?;
        let base = i.rgbn("base")?;
        let weight = i.mask("weight")?;
        match (i.rgbn_opt("detail")?, i.scalar("detail_height")?) {
            (Some(detail), None) => {
                let (img, rep) = linear_combine_images(base, detail, weight, &params)?;
                Ok(vec![
                    Value::Rgbn(img),
                    Value::Number(rep.curl_after.relative),
                ])
            }
            (None, Some(h)) => {
                let g =
                    linear_combine_height(&GradientField::from_normals(base), h, weight, &params)?;
                let mut img = base.clone();
                g.write_normals(&mut img);
                let curl = g.curl_stats(base.mask()).relative;
                Ok(vec![Value::Rgbn(img), Value::Number(curl)])
            }
            _ => Err(RgbnError::param(
                "detail",
                "connect exactly one of the inputs detail (normals) and detail_height (height)",
            )),
        }
    }
}

/// Mode names of [`RotationCombineNode`], in [`CombineMode`] order.
pub const ROTATION_MODES: [&str; 7] = [
    "replace",
    "blend",
    "rotate",
    "rnm",
    "udn",
    "whiteout",
    "partial_derivative",
];

/// Parameters of [`RotationCombineNode`].
#[derive(Clone, Debug, PartialEq)]
pub struct RotationCombineNodeParams {
    /// Mode name ([`ROTATION_MODES`]).
    pub mode: &'static str,
    /// Frame.
    pub frame: FrameChoice,
    /// Global weight.
    pub strength: f64,
    /// Saturate at `min_z`.
    pub saturate: bool,
    /// Saturation threshold.
    pub min_z: f64,
}

impl Default for RotationCombineNodeParams {
    fn default() -> Self {
        let d = RotateParams::default();
        Self {
            mode: "blend",
            frame: FrameChoice::default(),
            strength: f64::from(d.strength),
            saturate: d.saturate,
            min_z: f64::from(d.min_z),
        }
    }
}

impl Params for RotationCombineNodeParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.choice(
            "mode",
            &mut self.mode,
            &ROTATION_MODES,
            &Meta::new("replace: F d where w ≥ ½; blend: F slerp(e_z, d, w); rotate: rotate the existing normal by the detail's rotation in the base frame; rnm, udn, whiteout, partial_derivative: the blends of Barré-Brisebois & Hill."),
        );
        self.frame.visit(v);
        v.float(
            "strength",
            &mut self.strength,
            &Meta::new("Global weight multiplying the per-pixel weight.").range(0.0, 1.0),
        );
        v.bool(
            "saturate",
            &mut self.saturate,
            &Meta::new("Move results with n_z < min_z back along the great arc to n_z = min_z."),
        );
        v.float(
            "min_z",
            &mut self.min_z,
            &Meta::new("Saturation threshold on n_z.").range(0.0, 0.999),
        );
    }
}

impl RotationCombineNodeParams {
    fn to_params(&self) -> Result<RotateParams, RgbnError> {
        let mode = match self.mode {
            "replace" => CombineMode::Replace,
            "rotate" => CombineMode::Rotate,
            "rnm" => CombineMode::Rnm,
            "udn" => CombineMode::Udn,
            "whiteout" => CombineMode::Whiteout,
            "partial_derivative" => CombineMode::PartialDerivative,
            _ => CombineMode::Blend,
        };
        let p = RotateParams {
            mode,
            frame: self.frame.frame()?,
            strength: self.strength as f32,
            saturate: self.saturate,
            min_z: self.min_z as f32,
        };
        p.validate()?;
        Ok(p)
    }
}

/// Rotation combine of normals.
pub struct RotationCombineNode;

impl Operator for RotationCombineNode {
    type Params = RotationCombineNodeParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "combine.rotation",
            "Rotation combine",
            "combine",
            "Expresses a detail normal in the tangent frame of a base normal (Pereira & Velho §VII), so the detail keeps its look on a tilted base; industry blends (RNM, UDN, whiteout, partial derivative) as modes. Nonlinear: the curl of the result is reported.",
        )
        .input(PortSpec::new("base", PortType::Rgbn, "Base image (colour and mask are kept)."))
        .input(PortSpec::new(
            "detail",
            PortType::Rgbn,
            "Detail normals, in the base's tangent frame (+z = no detail).",
        ))
        .input(
            PortSpec::new(
                "existing",
                PortType::Rgbn,
                "Rotate mode: the normals rotated (the base when unconnected).",
            )
            .optional(),
        )
        .input(
            PortSpec::new(
                "weight",
                PortType::Mask,
                "Per-pixel weight in [0, 1] (1 everywhere when unconnected).",
            )
            .optional(),
        )
        .output(PortSpec::new("image", PortType::Rgbn, "Combined image."))
        .output(PortSpec::new(
            "saturated",
            PortType::Number,
            "Pixels moved back to n_z = min_z.",
        ))
        .output(curl_port("combined gradients"))
    }
    fn check(p: &RotationCombineNodeParams) -> Result<(), RgbnError> {
        p.to_params().map(|_| ())
    }
    fn run(
        p: &RotationCombineNodeParams,
        i: &Inputs<'_>,
        _: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        let (img, rep) = rotation_combine(
            i.rgbn("base")?,
            i.rgbn("detail")?,
            i.rgbn_opt("existing")?,
            i.mask("weight")?,
            &p.to_params()?,
        )?;
        Ok(vec![
            Value::Rgbn(img),
            Value::Number(rep.saturated as f64),
            Value::Number(rep.curl_after.relative),
        ])
    }
}
