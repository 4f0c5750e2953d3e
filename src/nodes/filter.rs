//! The linear gradient filters of [`crate::ops::filter`] as graph nodes: one node type per
//! [`crate::ops::filter::Kernel`] variant (`filter.gaussian`, `filter.sharpen`, …), each with the kernel's own
//! parameters plus `border` and `mask_aware`. The node adds no maths: it calls
//! [`filter_normals`](crate::ops::filter::filter_normals) with a one-kernel list.

use super::kit::kernel_kind;
use super::{Coarse, Kind, OpSpec, Operator, RunContext};
use crate::error::RgbnError;
use crate::ops::filter::{
    filter_image, BoxParams, DenseParams, DogParams, EdgeParams, FilterOptions, GaussianParams,
    HighPassParams, KernelParams, LogParams, ScaleParams, SeparableParams, SharpenParams,
};
use crate::params::{ParamVisitor, Params};
use crate::RgbnImage;
use std::marker::PhantomData;

/// The node identity of a kernel's parameters ([`KernelParams`], declared in
/// [`crate::ops::filter`]).
pub trait KernelNode: KernelParams {
    /// Operator id.
    const ID: &'static str;
    /// Title.
    const TITLE: &'static str;
    /// Documentation.
    const DOC: &'static str;
}

/// Parameters of a filter node: the kernel's, then the options (border mode and mask
/// awareness).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FilterParams<K> {
    /// Kernel parameters.
    pub kernel: K,
    /// Border mode and mask awareness.
    pub options: FilterOptions,
}

impl<K: KernelNode> Params for FilterParams<K> {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        self.kernel.visit(v);
        self.options.visit(v);
    }
}

crate::inputs! {
    /// Inputs of a filter node.
    pub struct FilterIn {
        /// Image to filter.
        pub image: RgbnImage,
    }
}

crate::outputs! {
    /// Outputs of a filter node.
    pub struct FilterOut {
        /// Filtered normals; colour and mask unchanged.
        pub image: RgbnImage,
    }
}

/// A filter node for kernel parameters `K`.
pub struct FilterOp<K>(PhantomData<fn() -> K>);

impl<K: KernelNode> Operator for FilterOp<K> {
    type Params = FilterParams<K>;
    type In = FilterIn;
    type Out = FilterOut;
    fn spec() -> OpSpec {
        OpSpec::new(K::ID, K::TITLE, "filter", K::DOC)
    }
    fn check(p: &FilterParams<K>) -> Result<(), RgbnError> {
        p.kernel.kernel().validate()
    }
    fn kind(p: &FilterParams<K>) -> Kind {
        let coarse = if K::COARSE {
            Coarse::Scaled
        } else {
            Coarse::None
        };
        kernel_kind(p.options.border, p.kernel.kernel().support_px(), coarse)
    }
    fn run(p: &FilterParams<K>, i: FilterIn, _: &RunContext) -> Result<FilterOut, RgbnError> {
        let image = filter_image(&i.image, &[p.kernel.kernel()], &p.options)?;
        Ok(FilterOut { image })
    }
}

/// Declares the node identity of a kernel's parameters.
macro_rules! kernel_node {
    ($params:ty, $id:literal, $title:literal, $doc:literal) => {
        impl KernelNode for $params {
            const ID: &'static str = $id;
            const TITLE: &'static str = $title;
            const DOC: &'static str = $doc;
        }
    };
}

kernel_node!(
    GaussianParams,
    "filter.gaussian",
    "Gaussian blur",
    "Smooths the relief: G_σ * g on the gradients (recursive Deriche filter for σ ≥ 3)."
);
kernel_node!(
    BoxParams,
    "filter.box",
    "Box blur",
    "Mean over a (2r+1)×(2r+1) window of the gradients."
);
kernel_node!(
    SharpenParams,
    "filter.sharpen",
    "Sharpen",
    "Sharpens the relief: g + amount·(g − G_σ * g) (all-pass plus a multiple of the high-pass)."
);
kernel_node!(
    EdgeParams,
    "filter.edge",
    "Edge enhance",
    "Enhances a band of detail: g + amount·(G_fine − G_coarse) * g."
);
kernel_node!(
    HighPassParams,
    "filter.highpass",
    "High-pass",
    "Keeps the fine detail only: g − G_σ * g."
);
kernel_node!(
    DogParams,
    "filter.dog",
    "Difference of Gaussians",
    "Keeps one band of detail: (G_fine − G_coarse) * g."
);
kernel_node!(
    LogParams,
    "filter.log",
    "Laplacian of Gaussian",
    "Scale-normalised Laplacian of Gaussian, −σ²∇²(G_σ * g) (centre-positive blob detector)."
);
kernel_node!(
    ScaleParams,
    "filter.scale",
    "Depth scale",
    "Scales the relief depth: s·g (exaggerates with s > 1, flattens with s < 1, inverts with s < 0)."
);
kernel_node!(
    SeparableParams,
    "filter.separable",
    "Separable kernel",
    "A user kernel given by its row taps and column taps (row 0 of the column at the top)."
);
kernel_node!(
    DenseParams,
    "filter.dense",
    "Dense kernel",
    "A small direct 2-D user kernel (odd sizes up to 63)."
);
