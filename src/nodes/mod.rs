//! Operators as typed graph nodes. Each file `src/nodes/<name>.rs` is the node form of the pure
//! operator `src/ops/<name>.rs` (or of code living elsewhere: `load`, `save`, `render`,
//! `integrate`, `capture`): an [`Operator`] whose spec names the ports and whose `run` adapts
//! the input values to the pure function and its results to output values, nothing else.
//!
//! This module holds the graph types ([`Operator`], [`OpSpec`], [`PortSpec`], [`PortType`],
//! [`Value`], [`Inputs`], [`RunContext`]) and the [`registry`]: the single list an operator is
//! added to; registering it puts it under test (every registered operator must appear in some
//! `graphs/*.ron` and document itself and each parameter). See `CONTRIBUTING.md`.
//!
//! ## Wrapping a pure function as a node
//!
//! Given a pure function such as `emboss` below (normally in `src/ops/emboss.rs`, with tests)
//! and its parameters declared once, the node is a spec and a one-line `run`:
//!
//! ```
//! use rgbn::error::RgbnError;
//! use rgbn::nodes::{Inputs, OpSpec, Operator, PortSpec, PortType, RunContext, Value};
//! use rgbn::RgbnImage;
//!
//! rgbn::params! {
//!     /// Parameters of [`emboss`].
//!     #[derive(Clone, Debug, PartialEq)]
//!     pub struct EmbossParams {
//!         /// How much.
//!         pub strength: f64 = 1.0 => float.range(0.0, 10.0),
//!     }
//! }
//!
//! /// The pure function.
//! pub fn emboss(img: &RgbnImage, p: &EmbossParams) -> Result<RgbnImage, RgbnError> {
//!     let mut out = img.clone();
//!     for v in &mut out.normal_mut()[0] {
//!         *v *= p.strength as f32;
//!     }
//!     out.normalize();
//!     Ok(out)
//! }
//!
//! /// The node (`src/nodes/emboss.rs`).
//! pub struct EmbossNode;
//! impl Operator for EmbossNode {
//!     type Params = EmbossParams;
//!     fn spec() -> OpSpec {
//!         OpSpec::new("emboss", "Emboss", "filter", "Embosses the relief.")
//!             .input(PortSpec::new("image", PortType::Rgbn, "Input."))
//!             .output(PortSpec::new("image", PortType::Rgbn, "Embossed."))
//!     }
//!     fn run(p: &EmbossParams, i: &Inputs, _: &RunContext) -> Result<Vec<Value>, RgbnError> {
//!         Ok(vec![Value::Rgbn(emboss(i.rgbn("image")?, p)?)])
//!     }
//! }
//! # let img = RgbnImage::flat(4, 4, [0.5; 3]);
//! # let spec = EmbossNode::spec();
//! # let v = [Some(Value::Rgbn(img.clone()))];
//! # let out = EmbossNode::run(&EmbossParams::default(), &Inputs::new(&spec.inputs, &v), &RunContext::default()).unwrap();
//! # assert_eq!(out, vec![Value::Rgbn(img)]);
//! ```
//!
//! then add `EmbossNode` to [`registry`] and an example `graphs/emboss.ron`. Bump
//! [`OpSpec::version`] whenever the maths changes, so cached results are not reused.

pub mod band;
pub mod bilateral;
pub mod brush;
pub mod capture;
pub mod combine;
pub mod curl;
pub mod filter;
pub mod integrate;
pub mod kit;
pub mod load;
pub mod normalize;
pub mod pen;
pub mod publish;
pub mod render;
pub mod rotate;
pub mod save;
pub mod stamp;
pub mod value;

pub use value::{Picture, PortType, Value};

use crate::error::RgbnError;
use crate::params::{self, ParamError, ParamInfo, ParamValue, Params};
use crate::raster::window::Window;
use crate::raster::{Plane, RgbnImage};
use std::collections::BTreeMap;
use std::marker::PhantomData;
use std::path::PathBuf;
use std::sync::OnceLock;

/// One input or output port.
#[derive(Clone, Debug, PartialEq)]
pub struct PortSpec {
    /// Name, unique among the node's inputs (or outputs).
    pub name: String,
    /// Type.
    pub ty: PortType,
    /// One-sentence doc.
    pub doc: String,
    /// Inputs only: may stay unconnected.
    pub optional: bool,
}

impl PortSpec {
    /// A required port.
    #[must_use]
    pub fn new(name: &str, ty: PortType, doc: &str) -> Self {
        Self {
            name: name.into(),
            ty,
            doc: doc.into(),
            optional: false,
        }
    }
    /// Marks an input as optional.
    #[must_use]
    pub fn optional(mut self) -> Self {
        self.optional = true;
        self
    }
}

/// What an operator is: identity, documentation, ports.
#[derive(Clone, Debug, PartialEq)]
pub struct OpSpec {
    /// Stable id used in graph files (`filter.gaussian`).
    pub id: &'static str,
    /// Human title.
    pub title: &'static str,
    /// Menu category (`input`, `filter`, `render`, `analysis`, `output`).
    pub category: &'static str,
    /// Documentation (first sentence is the summary).
    pub doc: &'static str,
    /// Bumped when the output for the same inputs and params changes (invalidates caches).
    pub version: u32,
    /// Input ports.
    pub inputs: Vec<PortSpec>,
    /// Output ports.
    pub outputs: Vec<PortSpec>,
    /// The node has an effect outside the graph (writes a file): it is never cached.
    pub side_effect: bool,
}

impl OpSpec {
    /// A spec with no ports, version 1.
    #[must_use]
    pub fn new(
        id: &'static str,
        title: &'static str,
        category: &'static str,
        doc: &'static str,
    ) -> Self {
        Self {
            id,
            title,
            category,
            doc,
            version: 1,
            inputs: Vec::new(),
            outputs: Vec::new(),
            side_effect: false,
        }
    }
    /// Adds an input port.
    #[must_use]
    pub fn input(mut self, p: PortSpec) -> Self {
        self.inputs.push(p);
        self
    }
    /// Adds an output port.
    #[must_use]
    pub fn output(mut self, p: PortSpec) -> Self {
        self.outputs.push(p);
        self
    }
    /// Sets the version.
    #[must_use]
    pub fn version(mut self, v: u32) -> Self {
        self.version = v;
        self
    }
    /// Marks the node as writing outside the graph.
    #[must_use]
    pub fn side_effect(mut self) -> Self {
        self.side_effect = true;
        self
    }
}

/// What a running node may know about its surroundings.
#[derive(Clone, Debug, Default)]
pub struct RunContext {
    /// Files read by the graph; writing nodes refuse to overwrite them.
    pub protected: Vec<PathBuf>,
}

/// The values on a node's input ports, by name (unconnected optional inputs are `None`).
pub struct Inputs<'a> {
    ports: &'a [PortSpec],
    values: &'a [Option<Value>],
}

impl<'a> Inputs<'a> {
    /// Wraps values in port order.
    #[must_use]
    pub fn new(ports: &'a [PortSpec], values: &'a [Option<Value>]) -> Self {
        Self { ports, values }
    }
    /// The value on port `name`, if connected.
    #[must_use]
    pub fn get(&self, name: &str) -> Option<&'a Value> {
        let i = self.ports.iter().position(|p| p.name == name)?;
        self.values.get(i)?.as_ref()
    }
    fn missing(name: &str) -> RgbnError {
        RgbnError::InvalidImage(format!(
            "input {name:?} is not connected or has the wrong type"
        ))
    }
    /// The RGBN image on port `name`.
    pub fn rgbn(&self, name: &str) -> Result<&'a RgbnImage, RgbnError> {
        match self.get(name) {
            Some(Value::Rgbn(i)) => Ok(i),
            _ => Err(Self::missing(name)),
        }
    }
    /// The RGBN image on port `name`, `None` when unconnected (optional inputs).
    pub fn rgbn_opt(&self, name: &str) -> Result<Option<&'a RgbnImage>, RgbnError> {
        match self.get(name) {
            Some(Value::Rgbn(i)) => Ok(Some(i)),
            None => Ok(None),
            _ => Err(Self::missing(name)),
        }
    }
    /// The scalar field on port `name`, `None` when unconnected.
    pub fn scalar(&self, name: &str) -> Result<Option<&'a Plane>, RgbnError> {
        match self.get(name) {
            Some(Value::Scalar(p)) => Ok(Some(p)),
            None => Ok(None),
            _ => Err(Self::missing(name)),
        }
    }
    /// The mask on port `name`, `None` when unconnected.
    pub fn mask(&self, name: &str) -> Result<Option<&'a Plane>, RgbnError> {
        match self.get(name) {
            Some(Value::Mask(m)) => Ok(Some(m)),
            None => Ok(None),
            _ => Err(Self::missing(name)),
        }
    }
}

/// What part of an input an operator needs to compute part of its outputs: how the evaluator
/// may compute it region by region (see `eval::region`; GEGL's `get_required_for_output`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Footprint {
    /// An output pixel depends only on the pixels of this input within `halo` pixels of it
    /// (Chebyshev distance; 0: a point operation), and on its own position only through the
    /// parameters [`Operator::shifted`] moves. Run on a crop of the input, the operator gives
    /// the pixels that lie `halo` or more inside the crop's cut edges exactly as on the whole
    /// image (within the operator's documented truncation, e.g. a recursive Gaussian's). The
    /// outputs then have the crop's size.
    Local {
        /// Reach in pixels.
        halo: usize,
    },
    /// The input is needed whole: transforms and solvers, statistics, resampling, a periodic
    /// border, or a small image used everywhere (a stamp).
    Global,
    /// The input is needed whole and at its own resolution at every level of detail: a small
    /// pattern sampled in coordinates relative to its own size (the pen's texture), which the
    /// evaluator must not reduce with the image.
    Pattern,
}

impl Footprint {
    /// A point operation.
    pub const POINT: Self = Self::Local { halo: 0 };
}

/// A typed node. See the module docs for how to wrap a pure function.
pub trait Operator: Send + Sync + 'static {
    /// Parameters, declared once through [`Params::visit`].
    type Params: Params;
    /// Identity, doc and ports.
    fn spec() -> OpSpec;
    /// Checks combinations of parameters beyond the per-parameter ranges (called when a graph
    /// is validated, before evaluation).
    fn check(_params: &Self::Params) -> Result<(), RgbnError> {
        Ok(())
    }
    /// Computes the outputs, in the order of `spec().outputs`.
    fn run(
        params: &Self::Params,
        inputs: &Inputs<'_>,
        ctx: &RunContext,
    ) -> Result<Vec<Value>, RgbnError>;
    /// The pixel size (width, height) of the outputs, known before running, from the sizes of
    /// the inputs in port order (`None`: unconnected or unknown). Sources state it from their
    /// parameters or file headers; every other operator makes outputs of its first image
    /// input's size (the default). `None` when it cannot be known without running.
    fn out_size(
        _params: &Self::Params,
        inputs: &[Option<(usize, usize)>],
    ) -> Option<(usize, usize)> {
        inputs.iter().flatten().next().copied()
    }
    /// Working memory while running beyond inputs and outputs, in multiples of the output
    /// bytes (gradient planes, transforms, solver vectors): used by the evaluator's estimate of
    /// a plan's peak memory (see `eval::memory`).
    const SCRATCH: f64 = 1.0;
    /// What input `input` (port order) must provide for a region of the outputs. An operator
    /// is computed region by region when at least one of its inputs is
    /// [`Footprint::Local`]; its `Global` inputs are then passed whole, and its `Number`
    /// outputs are not computed (a consumer of one needs the operator whole). Default: global
    /// (sources, solvers, sinks).
    fn footprint(_params: &Self::Params, _input: usize) -> Footprint {
        Footprint::Global
    }
    /// The parameters that compute, on the crop of the inputs whose top-left pixel is `(dx, dy)`
    /// of the whole image, the same pixels as `params` on the whole image: positions (pen and
    /// brush points, stamp placements) moved by `(−dx, −dy)`. Default: unchanged (nothing
    /// positional).
    fn shifted(params: &Self::Params, _dx: f64, _dy: f64) -> Self::Params {
        params.clone()
    }
    /// The parameters that compute this operator on its inputs reduced by `s` (a level of
    /// detail, [`crate::raster::pyramid`]) so that the outputs approximate its full-resolution
    /// outputs reduced by `s`: lengths in pixels divided by `s`, positions mapped with
    /// [`scale_point`]. `None` when it has no such form (then a coarse level computes it at full
    /// resolution and reduces it). Default: `None`.
    fn scaled(_params: &Self::Params, _s: f64) -> Option<Self::Params> {
        None
    }
    /// The outputs of a run at a level of detail (inputs reduced by `s`, `params` from
    /// [`Operator::scaled`]) mapped to approximate the full-resolution outputs reduced by `s`:
    /// a height in pixels is multiplied by `s`. Default: unchanged (normals, colours, slopes).
    fn level_outputs(_params: &Self::Params, _s: f64, outputs: Vec<Value>) -> Vec<Value> {
        outputs
    }
    /// Whether the outputs can be computed over any window, at any level of detail, without
    /// the rest of the image ([`Operator::run_region`]): procedural sources. The region
    /// evaluator then computes them tile by tile rather than whole. Default: no.
    fn regional(_params: &Self::Params) -> bool {
        false
    }
    /// The outputs of [`Operator::run`] over `win` of the whole image, at `win.scale`: what
    /// [`crate::raster::pyramid`] makes of the full-resolution outputs, or (procedural sources)
    /// the surface sampled on the coarse grid directly. Default: `run` on the whole image, then
    /// cut and reduced — correct, but it computes everything.
    fn run_region(
        params: &Self::Params,
        inputs: &Inputs<'_>,
        win: Window,
        ctx: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        Ok(Self::run(params, inputs, ctx)?
            .iter()
            .map(|v| value::window_of(v, win))
            .collect())
    }
    /// Where the outputs can change when the parameters go from `old` to `new` and the inputs
    /// (sizes in port order, `None` when unconnected) stay the same: boxes
    /// `[x0, y0, x1, y1]` in pixel coordinates (pixel centres at whole numbers), or `None` for
    /// anywhere (GEGL's `get_invalidated_by_change`). The evaluator reuses every tile outside
    /// them. Default: anywhere.
    fn damage(
        _old: &Self::Params,
        _new: &Self::Params,
        _inputs: &[Option<(usize, usize)>],
    ) -> Option<Vec<[f64; 4]>> {
        None
    }
}

/// A position of a full-resolution image (pixel centres at whole numbers) on the grid reduced
/// by `s`, whose pixel `X` covers full-resolution pixels `X·s .. (X + 1)·s`.
#[must_use]
pub fn scale_point(p: [f64; 2], s: f64) -> [f64; 2] {
    p.map(|c| (c - (s - 1.0) / 2.0) / s)
}

/// The object-safe face of an [`Operator`], as held by the registry.
pub trait DynOp: Send + Sync {
    /// The spec.
    fn spec(&self) -> &OpSpec;
    /// Every parameter with doc, range and default.
    fn params(&self) -> &[ParamInfo];
    /// Applies `values` over the defaults, checks them, and returns the complete canonical map
    /// (every parameter present), which is what cache keys hash.
    fn canonical(
        &self,
        values: &BTreeMap<String, ParamValue>,
    ) -> Result<BTreeMap<String, ParamValue>, ParamError>;
    /// Runs on canonical params.
    fn run(
        &self,
        values: &BTreeMap<String, ParamValue>,
        inputs: &[Option<Value>],
        ctx: &RunContext,
    ) -> Result<Vec<Value>, RgbnError>;
    /// [`Operator::out_size`] on canonical params (`None` also when they do not parse).
    fn out_size(
        &self,
        values: &BTreeMap<String, ParamValue>,
        inputs: &[Option<(usize, usize)>],
    ) -> Option<(usize, usize)>;
    /// [`Operator::SCRATCH`].
    fn scratch(&self) -> f64;
    /// [`Operator::footprint`] on canonical params (`Global` when they do not parse).
    fn footprint(&self, values: &BTreeMap<String, ParamValue>, input: usize) -> Footprint;
    /// [`Operator::damage`] on canonical params (`None` when they do not parse).
    fn damage(
        &self,
        old: &BTreeMap<String, ParamValue>,
        new: &BTreeMap<String, ParamValue>,
        inputs: &[Option<(usize, usize)>],
    ) -> Option<Vec<[f64; 4]>>;
    /// [`Operator::scaled`] on canonical params, as canonical params (`None` also when they do
    /// not parse).
    fn scaled(
        &self,
        values: &BTreeMap<String, ParamValue>,
        s: f64,
    ) -> Option<BTreeMap<String, ParamValue>>;
    /// [`Operator::level_outputs`] on canonical params (unchanged when they do not parse).
    fn level_outputs(
        &self,
        values: &BTreeMap<String, ParamValue>,
        s: f64,
        outputs: Vec<Value>,
    ) -> Vec<Value>;
    /// [`Operator::regional`] on canonical params (`false` when they do not parse).
    fn regional(&self, values: &BTreeMap<String, ParamValue>) -> bool;
    /// [`Operator::run_region`] on canonical params.
    fn run_region(
        &self,
        values: &BTreeMap<String, ParamValue>,
        inputs: &[Option<Value>],
        win: Window,
        ctx: &RunContext,
    ) -> Result<Vec<Value>, RgbnError>;
    /// Runs on the crop whose top-left pixel is `origin` of the whole image:
    /// [`Operator::run`] with [`Operator::shifted`] params.
    fn run_at(
        &self,
        values: &BTreeMap<String, ParamValue>,
        inputs: &[Option<Value>],
        ctx: &RunContext,
        origin: (usize, usize),
    ) -> Result<Vec<Value>, RgbnError>;
}

struct Entry<T: Operator> {
    spec: OpSpec,
    params: Vec<ParamInfo>,
    _op: PhantomData<fn() -> T>,
}

impl<T: Operator> Entry<T> {
    fn boxed() -> Box<dyn DynOp> {
        Box::new(Self {
            spec: T::spec(),
            params: params::describe::<T::Params>(),
            _op: PhantomData,
        })
    }
}

impl<T: Operator> DynOp for Entry<T> {
    fn spec(&self) -> &OpSpec {
        &self.spec
    }
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }
    fn canonical(
        &self,
        values: &BTreeMap<String, ParamValue>,
    ) -> Result<BTreeMap<String, ParamValue>, ParamError> {
        let p: T::Params = params::from_values(values)?;
        T::check(&p).map_err(|e| match e {
            RgbnError::InvalidParam { name, detail } => ParamError::Range { name, detail },
            // Not about one parameter (checks report `InvalidParam`): name the operator.
            other => ParamError::Range {
                name: self.spec.id.to_string(),
                detail: other.to_string(),
            },
        })?;
        Ok(params::to_values(&p))
    }
    fn run(
        &self,
        values: &BTreeMap<String, ParamValue>,
        inputs: &[Option<Value>],
        ctx: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        self.run_at(values, inputs, ctx, (0, 0))
    }
    fn out_size(
        &self,
        values: &BTreeMap<String, ParamValue>,
        inputs: &[Option<(usize, usize)>],
    ) -> Option<(usize, usize)> {
        let p: T::Params = params::from_values(values).ok()?;
        T::out_size(&p, inputs)
    }
    fn scratch(&self) -> f64 {
        T::SCRATCH
    }
    fn footprint(&self, values: &BTreeMap<String, ParamValue>, input: usize) -> Footprint {
        match params::from_values::<T::Params>(values) {
            Ok(p) => T::footprint(&p, input),
            Err(_) => Footprint::Global,
        }
    }
    fn damage(
        &self,
        old: &BTreeMap<String, ParamValue>,
        new: &BTreeMap<String, ParamValue>,
        inputs: &[Option<(usize, usize)>],
    ) -> Option<Vec<[f64; 4]>> {
        let old: T::Params = params::from_values(old).ok()?;
        let new: T::Params = params::from_values(new).ok()?;
        T::damage(&old, &new, inputs)
    }
    fn scaled(
        &self,
        values: &BTreeMap<String, ParamValue>,
        s: f64,
    ) -> Option<BTreeMap<String, ParamValue>> {
        let p: T::Params = params::from_values(values).ok()?;
        T::scaled(&p, s).map(|p| params::to_values(&p))
    }
    fn level_outputs(
        &self,
        values: &BTreeMap<String, ParamValue>,
        s: f64,
        outputs: Vec<Value>,
    ) -> Vec<Value> {
        match params::from_values::<T::Params>(values) {
            Ok(p) => T::level_outputs(&p, s, outputs),
            Err(_) => outputs,
        }
    }
    fn regional(&self, values: &BTreeMap<String, ParamValue>) -> bool {
        params::from_values::<T::Params>(values).is_ok_and(|p| T::regional(&p))
    }
    fn run_region(
        &self,
        values: &BTreeMap<String, ParamValue>,
        inputs: &[Option<Value>],
        win: Window,
        ctx: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        let p: T::Params = params::from_values(values)?;
        let out = T::run_region(&p, &Inputs::new(&self.spec.inputs, inputs), win, ctx)?;
        debug_assert_eq!(out.len(), self.spec.outputs.len());
        Ok(out)
    }
    fn run_at(
        &self,
        values: &BTreeMap<String, ParamValue>,
        inputs: &[Option<Value>],
        ctx: &RunContext,
        origin: (usize, usize),
    ) -> Result<Vec<Value>, RgbnError> {
        let p: T::Params = params::from_values(values)?;
        let p = if origin == (0, 0) {
            p
        } else {
            T::shifted(&p, origin.0 as f64, origin.1 as f64)
        };
        let out = T::run(&p, &Inputs::new(&self.spec.inputs, inputs), ctx)?;
        debug_assert_eq!(out.len(), self.spec.outputs.len());
        Ok(out)
    }
}

/// Every registered operator, in menu order. **Adding an operator = one line here** (plus its
/// pure file, its node file and an example graph under `graphs/`; see `CONTRIBUTING.md`).
pub fn registry() -> &'static [Box<dyn DynOp>] {
    static REGISTRY: OnceLock<Vec<Box<dyn DynOp>>> = OnceLock::new();
    REGISTRY.get_or_init(|| {
        use crate::ops::filter::{
            BoxParams, DenseParams, DogParams, EdgeParams, GaussianParams, HighPassParams,
            LogParams, ScaleParams, SeparableParams, SharpenParams,
        };
        use filter::FilterOp;
        vec![
            // input
            Entry::<load::Demo>::boxed(),
            Entry::<load::SurfaceOp>::boxed(),
            Entry::<load::Load>::boxed(),
            Entry::<load::LoadMask>::boxed(),
            Entry::<load::ApplyMask>::boxed(),
            Entry::<capture::PhotometricStereoNode>::boxed(),
            // filter
            Entry::<FilterOp<GaussianParams>>::boxed(),
            Entry::<FilterOp<BoxParams>>::boxed(),
            Entry::<FilterOp<SharpenParams>>::boxed(),
            Entry::<FilterOp<EdgeParams>>::boxed(),
            Entry::<FilterOp<HighPassParams>>::boxed(),
            Entry::<FilterOp<DogParams>>::boxed(),
            Entry::<FilterOp<LogParams>>::boxed(),
            Entry::<FilterOp<ScaleParams>>::boxed(),
            Entry::<FilterOp<SeparableParams>>::boxed(),
            Entry::<FilterOp<DenseParams>>::boxed(),
            Entry::<normalize::Normalize>::boxed(),
            Entry::<band::BandNode>::boxed(),
            Entry::<brush::BrushNode>::boxed(),
            Entry::<bilateral::BilateralNode>::boxed(),
            Entry::<integrate::ProjectNode>::boxed(),
            // combine and draw
            Entry::<combine::LinearCombineNode>::boxed(),
            Entry::<rotate::RotationCombineNode>::boxed(),
            Entry::<stamp::ExtractNode>::boxed(),
            Entry::<stamp::StampNode>::boxed(),
            Entry::<pen::PenNode>::boxed(),
            // render and analysis
            Entry::<render::Relight>::boxed(),
            Entry::<render::ViewOp>::boxed(),
            Entry::<curl::CurlOp>::boxed(),
            Entry::<integrate::IntegrateNode>::boxed(),
            // output
            Entry::<save::Save>::boxed(),
            Entry::<integrate::SaveHeight>::boxed(),
            Entry::<integrate::SaveMesh>::boxed(),
            Entry::<publish::PublishNode>::boxed(),
        ]
    })
}

/// The operator with id `id`.
#[must_use]
pub fn find(id: &str) -> Option<&'static dyn DynOp> {
    registry()
        .iter()
        .find(|o| o.spec().id == id)
        .map(|b| b.as_ref())
}

/// The id of the reusable-graph node (a graph file used as a node; see [`crate::graph`]).
pub const GRAPH_NODE_OP: &str = "graph";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registry_ids_unique_ports_named_uniquely() {
        let mut ids: Vec<&str> = registry().iter().map(|o| o.spec().id).collect();
        let n = ids.len();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), n, "duplicate operator ids");
        assert!(!ids.contains(&GRAPH_NODE_OP));
        for op in registry() {
            let s = op.spec();
            for ports in [&s.inputs, &s.outputs] {
                let mut names: Vec<&str> = ports.iter().map(|p| p.name.as_str()).collect();
                names.sort_unstable();
                names.dedup();
                assert_eq!(names.len(), ports.len(), "{}", s.id);
            }
            // Defaults pass their own validation once file paths are given (all of them: some
            // are required only in some combinations, e.g. photometric stereo's light file
            // unless the photos come as an .lp file); without them, a required path is refused.
            let mut given = BTreeMap::new();
            let mut required = false;
            for p in op.params() {
                if p.kind == params::ParamKind::Path {
                    given.insert(p.name.to_string(), ParamValue::Path("x.exr".into()));
                    required |= !p.meta.optional;
                }
            }
            if required {
                assert!(op.canonical(&BTreeMap::new()).is_err(), "{}", s.id);
            }
            assert!(op.canonical(&given).is_ok(), "{}", s.id);
        }
    }
}
