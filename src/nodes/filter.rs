//! The linear gradient filters of [`crate::ops::filter`] as graph nodes: one node type per
//! [`Kernel`] variant (`filter.gaussian`, `filter.sharpen`, …), each with the kernel's own
//! parameters plus `border` and `mask_aware`. The node adds no maths: it calls
//! [`filter_normals`] with a one-kernel list.

use super::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
use crate::error::RgbnError;
use crate::ops::filter::{filter_normals, FilterOptions, Kernel};
use crate::ops::params::{Meta, ParamVisitor, Params};
use std::marker::PhantomData;

/// The kernel-specific half of a filter node's parameters.
pub trait KernelNode: Params {
    /// Operator id.
    const ID: &'static str;
    /// Title.
    const TITLE: &'static str;
    /// Documentation.
    const DOC: &'static str;
    /// The kernel these parameters describe.
    fn kernel(&self) -> Kernel;
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

/// A filter node for kernel parameters `K`.
pub struct FilterOp<K>(PhantomData<fn() -> K>);

impl<K: KernelNode> Operator for FilterOp<K> {
    type Params = FilterParams<K>;
    fn spec() -> OpSpec {
        OpSpec::new(K::ID, K::TITLE, "filter", K::DOC)
            .input(PortSpec::new("image", PortType::Rgbn, "Image to filter."))
            .output(PortSpec::new(
                "image",
                PortType::Rgbn,
                "Filtered normals; colour and mask unchanged.",
            ))
    }
    fn check(p: &FilterParams<K>) -> Result<(), RgbnError> {
        p.kernel.kernel().validate()
    }
    fn run(p: &FilterParams<K>, i: &Inputs<'_>, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
        let (out, _) = filter_normals(i.rgbn("image")?, &[p.kernel.kernel()], &p.options)?;
        Ok(vec![Value::Rgbn(out)])
    }
}

fn sigma(doc: &'static str) -> Meta {
    Meta::new(doc).unit("px").range(0.05, 4096.0)
}

fn amount(doc: &'static str) -> Meta {
    Meta::new(doc).range(-100.0, 100.0)
}

macro_rules! kernel_node {
    ($(#[$m:meta])* $name:ident, $id:literal, $title:literal, $doc:literal,
     { $($field:ident = $default:expr, $meta:expr;)* }, |$s:ident| $kernel:expr) => {
        $(#[$m])*
        #[derive(Clone, Debug, PartialEq)]
        pub struct $name {
            $(#[doc = concat!("`", stringify!($field), "` (see the node doc).")] pub $field: f64,)*
        }
        impl Default for $name {
            fn default() -> Self {
                Self { $($field: $default,)* }
            }
        }
        impl Params for $name {
            fn visit(&mut self, v: &mut dyn ParamVisitor) {
                $(v.float(stringify!($field), &mut self.$field, &$meta);)*
            }
        }
        impl KernelNode for $name {
            const ID: &'static str = $id;
            const TITLE: &'static str = $title;
            const DOC: &'static str = $doc;
            fn kernel(&self) -> Kernel {
                let $s = self;
                $kernel
            }
        }
    };
}

kernel_node!(
    /// Gaussian blur.
    GaussianK, "filter.gaussian", "Gaussian blur",
    "Smooths the relief: G_σ * g on the gradients (recursive Deriche filter for σ ≥ 3).",
    { sigma_px = 2.0, sigma("Standard deviation of the Gaussian."); },
    |s| Kernel::Gaussian { sigma_px: s.sigma_px as f32 }
);

kernel_node!(
    /// Unsharp masking.
    SharpenK, "filter.sharpen", "Sharpen",
    "Sharpens the relief: g + amount·(g − G_σ * g) (all-pass plus a multiple of the high-pass).",
    {
        sigma_px = 2.0, sigma("σ of the Gaussian whose residual is added.");
        amount = 1.0, amount("How much of the high-pass is added.");
    },
    |s| Kernel::Sharpen { sigma_px: s.sigma_px as f32, amount: s.amount as f32 }
);

kernel_node!(
    /// Band-pass enhancement.
    EdgeK, "filter.edge", "Edge enhance",
    "Enhances a band of detail: g + amount·(G_fine − G_coarse) * g.",
    {
        sigma_fine_px = 1.0, sigma("σ of the finer Gaussian.");
        sigma_coarse_px = 4.0, sigma("σ of the coarser Gaussian.");
        amount = 1.0, amount("How much of the band-pass is added.");
    },
    |s| Kernel::EdgeEnhance {
        sigma_fine_px: s.sigma_fine_px as f32,
        sigma_coarse_px: s.sigma_coarse_px as f32,
        amount: s.amount as f32,
    }
);

kernel_node!(
    /// High-pass.
    HighPassK, "filter.highpass", "High-pass",
    "Keeps the fine detail only: g − G_σ * g.",
    { sigma_px = 4.0, sigma("σ of the Gaussian removed."); },
    |s| Kernel::HighPass { sigma_px: s.sigma_px as f32 }
);

kernel_node!(
    /// Difference of Gaussians.
    DogK, "filter.dog", "Difference of Gaussians",
    "Keeps one band of detail: (G_fine − G_coarse) * g.",
    {
        sigma_fine_px = 1.0, sigma("σ of the finer Gaussian.");
        sigma_coarse_px = 4.0, sigma("σ of the coarser Gaussian.");
    },
    |s| Kernel::DoG {
        sigma_fine_px: s.sigma_fine_px as f32,
        sigma_coarse_px: s.sigma_coarse_px as f32,
    }
);

kernel_node!(
    /// Laplacian of Gaussian.
    LogK, "filter.log", "Laplacian of Gaussian",
    "Scale-normalised Laplacian of Gaussian, −σ²∇²(G_σ * g) (centre-positive blob detector).",
    { sigma_px = 2.0, sigma("σ of the Gaussian."); },
    |s| Kernel::LoG { sigma_px: s.sigma_px as f32 }
);

kernel_node!(
    /// Depth scale.
    ScaleK, "filter.scale", "Depth scale",
    "Scales the relief depth: s·g (exaggerates with s > 1, flattens with s < 1, inverts with s < 0).",
    { scale = 2.0, amount("Factor on the gradients."); },
    |s| Kernel::DepthScale { scale: s.scale as f32 }
);

/// Box filter.
#[derive(Clone, Debug, PartialEq)]
pub struct BoxK {
    /// Half-width of the window.
    pub radius_px: i64,
}

impl Default for BoxK {
    fn default() -> Self {
        Self { radius_px: 2 }
    }
}

impl Params for BoxK {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.int(
            "radius_px",
            &mut self.radius_px,
            &Meta::new("Half-width: the mean over a (2r+1)² window.")
                .unit("px")
                .range(1.0, 4096.0),
        );
    }
}

impl KernelNode for BoxK {
    const ID: &'static str = "filter.box";
    const TITLE: &'static str = "Box blur";
    const DOC: &'static str = "Mean over a (2r+1)×(2r+1) window of the gradients.";
    fn kernel(&self) -> Kernel {
        Kernel::Box {
            radius_px: self.radius_px.clamp(0, u32::MAX as i64) as u32,
        }
    }
}

fn f32s(v: &[f64]) -> Vec<f32> {
    v.iter().map(|x| *x as f32).collect()
}

/// A separable user kernel.
#[derive(Clone, Debug, PartialEq)]
pub struct SeparableK {
    /// Row (horizontal) taps.
    pub row: Vec<f64>,
    /// Column (vertical) taps.
    pub col: Vec<f64>,
}

impl Default for SeparableK {
    fn default() -> Self {
        Self {
            row: vec![0.25, 0.5, 0.25],
            col: vec![0.25, 0.5, 0.25],
        }
    }
}

impl Params for SeparableK {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        let m = Meta::new("Taps (odd count ≤ 63), applied as given.").range(-1e6, 1e6);
        v.floats("row", &mut self.row, &m);
        v.floats("col", &mut self.col, &m);
    }
}

impl KernelNode for SeparableK {
    const ID: &'static str = "filter.separable";
    const TITLE: &'static str = "Separable kernel";
    const DOC: &'static str =
        "A user kernel given by its row taps and column taps (row 0 of the column at the top).";
    fn kernel(&self) -> Kernel {
        Kernel::Separable {
            row: f32s(&self.row),
            col: f32s(&self.col),
        }
    }
}

/// A dense user kernel.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseK {
    /// Columns.
    pub width: i64,
    /// Rows.
    pub height: i64,
    /// Row-major weights.
    pub weights: Vec<f64>,
}

impl Default for DenseK {
    fn default() -> Self {
        Self {
            width: 3,
            height: 3,
            weights: vec![0.0, 0.125, 0.0, 0.125, 0.5, 0.125, 0.0, 0.125, 0.0],
        }
    }
}

impl Params for DenseK {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        let m = Meta::new("Kernel size (odd).").unit("px").range(1.0, 63.0);
        v.int("width", &mut self.width, &m);
        v.int("height", &mut self.height, &m);
        v.floats(
            "weights",
            &mut self.weights,
            &Meta::new("width × height weights, row-major, row 0 at the top.").range(-1e6, 1e6),
        );
    }
}

impl KernelNode for DenseK {
    const ID: &'static str = "filter.dense";
    const TITLE: &'static str = "Dense kernel";
    const DOC: &'static str = "A small direct 2-D user kernel (odd sizes up to 63).";
    fn kernel(&self) -> Kernel {
        Kernel::Dense {
            width: self.width.max(0) as usize,
            height: self.height.max(0) as usize,
            weights: f32s(&self.weights),
        }
    }
}
