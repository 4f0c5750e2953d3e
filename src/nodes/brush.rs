//! The local filter brush of [`crate::ops::brush`] as a node: one linear kernel applied inside a
//! stroke (a polyline swept by a disc with a feather) and/or a mask input ([`brush_image`]).
//! Several strokes: chain brush nodes, or paint them into a mask.

use super::kit::{border_mode, curl_port, visit_border};
use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::brush::{brush_image, BrushParams, BrushStroke};
use crate::ops::filter::{FilterOptions, Kernel};
use crate::ops::params::{Meta, ParamVisitor, Params};
use std::sync::Arc;

/// Kernel names offered by the brush.
pub const BRUSH_KERNELS: [&str; 8] = [
    "gaussian", "box", "sharpen", "edge", "highpass", "dog", "log", "scale",
];

/// Parameters of [`BrushNode`].
#[derive(Clone, Debug, PartialEq)]
pub struct BrushNodeParams {
    /// Kernel name ([`BRUSH_KERNELS`]).
    pub kernel: &'static str,
    /// σ (finer σ of edge/dog).
    pub sigma_px: f64,
    /// Coarser σ of edge/dog.
    pub sigma_coarse_px: f64,
    /// Amount of sharpen/edge; factor of scale.
    pub amount: f64,
    /// Box half-width.
    pub box_radius_px: i64,
    /// Stroke polyline `(x, row)`.
    pub points: Vec<[f64; 2]>,
    /// Full-strength radius.
    pub radius_px: f64,
    /// Fade width.
    pub feather_px: f64,
    /// Border mode name.
    pub border: &'static str,
    /// Normalised convolution inside the image's mask.
    pub mask_aware: bool,
}

impl Default for BrushNodeParams {
    fn default() -> Self {
        Self {
            kernel: "gaussian",
            sigma_px: 3.0,
            sigma_coarse_px: 6.0,
            amount: 1.0,
            box_radius_px: 2,
            points: vec![[32.0, 32.0]],
            radius_px: 8.0,
            feather_px: 4.0,
            border: "mirror",
            mask_aware: false,
        }
    }
}

impl Params for BrushNodeParams {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.choice(
            "kernel",
            &mut self.kernel,
            &BRUSH_KERNELS,
            &Meta::new("The linear filter painted with the brush (as the filter.* nodes): gaussian, box, sharpen, edge, highpass, dog, log, scale."),
        );
        let sigma = |doc| Meta::new(doc).unit("px").range(0.05, 4096.0);
        v.float(
            "sigma_px",
            &mut self.sigma_px,
            &sigma("σ of the kernel (the finer σ of edge and dog)."),
        );
        v.float(
            "sigma_coarse_px",
            &mut self.sigma_coarse_px,
            &sigma("Coarser σ of edge and dog (must exceed sigma_px)."),
        );
        v.float(
            "amount",
            &mut self.amount,
            &Meta::new("Amount of sharpen and edge; the depth factor of scale.")
                .range(-100.0, 100.0),
        );
        v.int(
            "box_radius_px",
            &mut self.box_radius_px,
            &Meta::new("Half-width of the box kernel.")
                .unit("px")
                .range(1.0, 4096.0),
        );
        v.points(
            "points",
            &mut self.points,
            &Meta::new("The stroke: a polyline in pixels (x, row); one point is a dab; empty when only the mask input paints the region.")
                .unit("px"),
        );
        v.float(
            "radius_px",
            &mut self.radius_px,
            &Meta::new("Full-strength radius around the stroke.")
                .unit("px")
                .range(0.0, 10_000.0),
        );
        v.float(
            "feather_px",
            &mut self.feather_px,
            &Meta::new("Width of the smooth (quintic) fade beyond the radius.")
                .unit("px")
                .range(0.0, 10_000.0),
        );
        visit_border(v, &mut self.border);
        v.bool(
            "mask_aware",
            &mut self.mask_aware,
            &Meta::new("Filter inside the image's own mask only (normalised convolution)."),
        );
    }
}

impl BrushNodeParams {
    fn kernel(&self) -> Kernel {
        let (s, c, a) = (
            self.sigma_px as f32,
            self.sigma_coarse_px as f32,
            self.amount as f32,
        );
        match self.kernel {
            "box" => Kernel::Box {
                radius_px: self.box_radius_px.clamp(0, i64::from(u32::MAX)) as u32,
            },
            "sharpen" => Kernel::Sharpen {
                sigma_px: s,
                amount: a,
            },
            "edge" => Kernel::EdgeEnhance {
                sigma_fine_px: s,
                sigma_coarse_px: c,
                amount: a,
            },
            "highpass" => Kernel::HighPass { sigma_px: s },
            "dog" => Kernel::DoG {
                sigma_fine_px: s,
                sigma_coarse_px: c,
            },
            "log" => Kernel::LoG { sigma_px: s },
            "scale" => Kernel::DepthScale { scale: a },
            _ => Kernel::Gaussian { sigma_px: s },
        }
    }

    /// The library parameters; errors name this node's parameters.
    pub fn to_params(&self) -> Result<BrushParams, RgbnError> {
        let strokes = if self.points.is_empty() {
            Vec::new()
        } else {
            vec![BrushStroke {
                points: self.points.iter().map(|p| p.map(|v| v as f32)).collect(),
                radius_px: self.radius_px as f32,
                feather_px: self.feather_px as f32,
            }]
        };
        let p = BrushParams {
            kernels: vec![self.kernel()],
            strokes,
            filter: FilterOptions {
                border: border_mode(self.border),
                mask_aware: self.mask_aware,
            },
        };
        p.validate().map_err(|e| match e {
            RgbnError::InvalidParam { name, detail } if name == "sigma_fine_px" => {
                RgbnError::param("sigma_px", detail)
            }
            RgbnError::InvalidParam { name, detail } if name == "scale" => {
                RgbnError::param("amount", detail)
            }
            other => other,
        })?;
        Ok(p)
    }
}

/// Filter brush.
pub struct BrushNode;

impl Operator for BrushNode {
    type Params = BrushNodeParams;
    fn spec() -> OpSpec {
        OpSpec::new(
            "brush",
            "Filter brush",
            "filter",
            "Applies a linear filter only inside a painted region (Pereira & Velho §III, Fig. 1): g′ = m·K(g) + (1 − m)·g, with m the union of a feathered stroke and the optional mask input. The feather band generally adds curl (reported).",
        )
        .input(PortSpec::new("image", PortType::Rgbn, "Image to edit."))
        .input(
            PortSpec::new(
                "mask",
                PortType::Mask,
                "Extra region in [0, 1] united (max) with the stroke.",
            )
            .optional(),
        )
        .output(PortSpec::new(
            "image",
            PortType::Rgbn,
            "Edited normals; colour and mask unchanged.",
        ))
        .output(PortSpec::new(
            "region",
            PortType::Mask,
            "The region weight m actually used.",
        ))
        .output(curl_port("edited gradients"))
    }
    fn check(p: &BrushNodeParams) -> Result<(), RgbnError> {
        p.to_params().map(|_| ())
    }
    fn run(p: &BrushNodeParams, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let img = i.rgbn("image")?;
        let (out, rep) = brush_image(img, i.mask("mask")?, &p.to_params()?)?;
        let region = rep
            .region
            .ok_or_else(|| RgbnError::InvalidImage("brush returned no region".into()))?;
        Ok(vec![
            Value::Rgbn(out),
            Value::Mask(Arc::new(region)),
            Value::Number(rep.curl_after.relative),
        ])
    }
}
