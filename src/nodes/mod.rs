//! Operators as typed graph nodes. Each file `src/nodes/<name>.rs` is the node form of a pure
//! operator (`src/ops/<name>.rs`, or code in `raster`, `render`, `capture`): an [`Operator`]
//! that states its identity, its parameters, its ports and its [`Kind`], and whose `run` adapts
//! the typed inputs to the pure function and its results to the typed outputs, nothing else.
//!
//! This module holds the node interface ([`Operator`], [`Kind`], [`OpSpec`], the ports of
//! [`ports`], the values of [`value`], [`RunContext`]), the type-erased face the graph and the
//! engine use ([`DynOp`], with parameters parsed once into [`Parsed`]) and the [`registry`]:
//! the single list an operator is added to. Registering puts it under test (every registered
//! operator must appear in some `graphs/*.ron` and document itself, each port and each
//! parameter). See `CONTRIBUTING.md`.
//!
//! ## An operator in full
//!
//! Given a pure function such as `emboss` below (normally in `src/ops/emboss.rs`, with tests)
//! and its parameters declared once, the node declares its ports, its kind and a one-line
//! `run`:
//!
//! ```
//! use rgbn::error::RgbnError;
//! use rgbn::nodes::{Coarse, Kind, OpSpec, Operator, RunContext};
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
//! rgbn::inputs! {
//!     /// Inputs of the emboss node.
//!     pub struct EmbossIn {
//!         /// Image to emboss.
//!         pub image: RgbnImage,
//!     }
//! }
//! rgbn::outputs! {
//!     /// Outputs of the emboss node.
//!     pub struct EmbossOut {
//!         /// The embossed image.
//!         pub image: RgbnImage,
//!     }
//! }
//!
//! /// The node (`src/nodes/emboss.rs`).
//! pub struct EmbossNode;
//! impl Operator for EmbossNode {
//!     type Params = EmbossParams;
//!     type In = EmbossIn;
//!     type Out = EmbossOut;
//!     fn spec() -> OpSpec {
//!         OpSpec::new("emboss", "Emboss", "filter", "Embosses the relief.")
//!     }
//!     // An output pixel reads only the same input pixel; no lengths, so the same parameters
//!     // compute it at a coarse level.
//!     fn kind(_: &EmbossParams) -> Kind {
//!         Kind::Point { coarse: Coarse::Scaled }
//!     }
//!     fn run(p: &EmbossParams, i: EmbossIn, _: &RunContext) -> Result<EmbossOut, RgbnError> {
//!         Ok(EmbossOut { image: emboss(&i.image, p)? })
//!     }
//! }
//! # let img = RgbnImage::flat(4, 4, [0.5; 3]);
//! # let out = EmbossNode::run(&EmbossParams::default(), EmbossIn { image: img.clone() }, &RunContext::default()).unwrap();
//! # assert_eq!(out.image, img);
//! ```
//!
//! then add `EmbossNode` to [`registry`] and an example `graphs/emboss.ron`. Bump
//! [`OpSpec::version`] whenever the maths changes, so cached results are not reused.

pub mod band;
pub mod bilateral;
pub mod bound;
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
pub mod ports;
pub mod publish;
pub mod render;
pub mod rotate;
pub mod save;
pub mod stamp;
pub mod transform;
pub mod value;

pub use ports::{InPorts, InValue, Mask, NoInputs, OutPorts, OutValue, PortSpec, Read, Scalar};
pub use value::{Picture, PortType, Value};

use crate::error::RgbnError;
use crate::params::{self, Meta, ParamError, ParamInfo, ParamValue, Params};
use crate::raster::window::Window;
use parking_lot::Mutex;
use std::any::Any;
use std::collections::{BTreeMap, HashMap};
use std::marker::PhantomData;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

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
    /// Input ports (from [`Operator::In`]).
    pub inputs: Vec<PortSpec>,
    /// Output ports (from [`Operator::Out`]).
    pub outputs: Vec<PortSpec>,
    /// The node has an effect outside the graph (writes a file): it is never cached.
    pub side_effect: bool,
    /// The operator may leave out the outputs an evaluation does not read
    /// ([`RunContext::wants`]): their values are then placeholders, which the evaluator
    /// never hands on (it records them as skipped and runs the node again when one is asked
    /// for). Declared with [`OpSpec::lazy_outputs`].
    pub lazy_outputs: bool,
}

impl OpSpec {
    /// A spec with version 1; its ports are filled in from the operator's port structs.
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
            lazy_outputs: false,
        }
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
    /// Declares that the operator computes only the outputs [`RunContext::wants`] (the
    /// bilateral's detail and readout when only its base is read).
    #[must_use]
    pub fn lazy_outputs(mut self) -> Self {
        self.lazy_outputs = true;
        self
    }
    /// The outputs (bit `k`: port `k`) a run that reads only `wanted` leaves out: those not
    /// wanted when the operator is lazy, none otherwise.
    #[must_use]
    pub fn skipped(&self, wanted: u64) -> u64 {
        if !self.lazy_outputs {
            return 0;
        }
        let n = self.outputs.len();
        let all = if n >= 64 { ALL_PORTS } else { (1u64 << n) - 1 };
        !wanted & all
    }
}

/// Every output port wanted (bit `k`: port `k`).
pub const ALL_PORTS: u64 = u64::MAX;

/// What a running node may know about its surroundings.
#[derive(Clone, Debug)]
pub struct RunContext {
    /// Files read by the graph; writing nodes refuse to overwrite them.
    pub protected: Vec<PathBuf>,
    /// The outputs the evaluation reads, bit `k` for port `k` ([`ALL_PORTS`] unless the
    /// operator declares [`OpSpec::lazy_outputs`]).
    pub wanted: u64,
    /// The evaluation's cancellation token: the operator's kernels see it as
    /// [`Cancel::current`](crate::cancel::Cancel::current) while it runs.
    pub cancel: crate::cancel::Cancel,
}

impl Default for RunContext {
    fn default() -> Self {
        Self::new(Vec::new())
    }
}

impl RunContext {
    /// A context wanting every output.
    #[must_use]
    pub fn new(protected: Vec<PathBuf>) -> Self {
        Self {
            protected,
            wanted: ALL_PORTS,
            cancel: crate::cancel::Cancel::never(),
        }
    }
    /// Whether output `port` (port order) is read. Ports past 63 always are.
    #[must_use]
    pub fn wants(&self, port: usize) -> bool {
        port >= 64 || self.wanted & (1 << port) != 0
    }
    /// This context wanting only the outputs in `wanted`.
    #[must_use]
    pub fn wanting(&self, wanted: u64) -> Self {
        Self {
            protected: self.protected.clone(),
            wanted,
            cancel: self.cancel.clone(),
        }
    }
    /// This context with cancellation token `cancel`.
    #[must_use]
    pub fn with_cancel(mut self, cancel: crate::cancel::Cancel) -> Self {
        self.cancel = cancel;
        self
    }
}

/// What part of an input an operator needs to compute part of its outputs (GEGL's
/// `get_required_for_output`), as the engine sees it: derived from the operator's [`Kind`] and
/// the input's [`Read`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Footprint {
    /// An output pixel depends only on the pixels of this input within `halo` pixels of it
    /// (Chebyshev distance; 0: a point operation). Run on a crop of the input with its
    /// positions shifted, the operator gives the pixels that lie `halo` or more inside the
    /// crop's cut edges exactly as on the whole image (within the operator's documented
    /// truncation, e.g. a recursive Gaussian's). The outputs then have the crop's size.
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

/// Whether an operator has a form at a coarse level of detail (inputs reduced `s` times).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coarse {
    /// It has: its parameters at the level are [`Operator::scaled`] (by default from the
    /// declarations: lengths in `px` divided by `s`, points mapped with [`params::scale_point`]),
    /// and its outputs approximate the full-resolution ones reduced. A coarse level then costs
    /// the level's pixels.
    Scaled,
    /// It has not (a nonlinear operator, a kernel in whole pixels, taps): a coarse level
    /// computes it at full resolution over what is needed and reduces the result.
    None,
}

/// What an operator is, for the region engine (GEGL's operation classes: point filter, area
/// filter, source, and operations that need everything). Every operator states its kind, as a
/// function of its parameters; the kind answers the region questions — which input pixels an
/// output pixel reads ([`Footprint`]), whether positions move on a crop (every `points`
/// parameter does), and whether a coarse level has its own form ([`Coarse`]). There is no
/// default: `Global` is written in the node when it is the answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// An output pixel depends only on the same pixel of the inputs.
    Point {
        /// A coarse form.
        coarse: Coarse,
    },
    /// An output pixel depends on the input pixels within `halo` pixels of it.
    Area {
        /// Reach in pixels.
        halo: usize,
        /// A coarse form.
        coarse: Coarse,
    },
    /// Procedural: any window of the outputs at any level, computed on its own
    /// ([`Operator::run_region`]); its inputs, if any, come whole.
    Source,
    /// The inputs are needed whole (solvers, statistics, files, writers, a periodic border).
    /// With a coarse form, a coarse level runs it whole on the inputs at that level
    /// ([`Operator::level_outputs`] maps units back).
    Global {
        /// A coarse form.
        coarse: Coarse,
    },
}

impl Kind {
    /// A point operation with a coarse form from its declarations.
    pub const POINT: Self = Self::Point {
        coarse: Coarse::Scaled,
    };
    /// A global operation with no coarse form.
    pub const GLOBAL: Self = Self::Global {
        coarse: Coarse::None,
    };

    /// Its coarse form.
    #[must_use]
    pub fn coarse(self) -> Coarse {
        match self {
            Kind::Point { coarse } | Kind::Area { coarse, .. } | Kind::Global { coarse } => coarse,
            Kind::Source => Coarse::None,
        }
    }

    /// What an input read as `read` must provide.
    #[must_use]
    pub fn footprint(self, read: Read) -> Footprint {
        match (read, self) {
            (Read::Pattern, _) => Footprint::Pattern,
            (Read::Whole, _) | (_, Kind::Global { .. } | Kind::Source) => Footprint::Global,
            (Read::ByKind, Kind::Point { .. }) => Footprint::POINT,
            (Read::ByKind, Kind::Area { halo, .. }) => Footprint::Local { halo },
        }
    }
}

/// A typed node. See the module docs for an operator in full.
pub trait Operator: Send + Sync + 'static {
    /// Parameters, declared once (`params!`).
    type Params: Params;
    /// Input ports (`inputs!`).
    type In: InPorts;
    /// Output ports (`outputs!`).
    type Out: OutPorts;
    /// Identity and documentation (the ports come from `In` and `Out`).
    fn spec() -> OpSpec;
    /// What it is for the region engine (no default: see [`Kind`]).
    fn kind(params: &Self::Params) -> Kind;
    /// Checks combinations of parameters beyond the per-parameter ranges (called once, when
    /// the parameters are parsed).
    fn check(_params: &Self::Params) -> Result<(), RgbnError> {
        Ok(())
    }
    /// Computes the outputs.
    fn run(
        params: &Self::Params,
        inputs: Self::In,
        ctx: &RunContext,
    ) -> Result<Self::Out, RgbnError>;
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
    /// The parameters at a level `s` times coarser, when [`Kind::coarse`] is
    /// [`Coarse::Scaled`]. Default: from the declarations ([`params::scaled`]: lengths in `px`
    /// ÷ `s` within their range, points through [`params::scale_point`]). Override only for
    /// what the declarations cannot say (a principal point, a weight that scales with `s²`);
    /// `None` when these particular parameters have no coarse form.
    fn scaled(params: &Self::Params, s: f64) -> Option<Self::Params> {
        Some(params::scaled(params, s))
    }
    /// The outputs of a run at a level of detail (inputs reduced by `s`, parameters from
    /// [`Operator::scaled`]) mapped to approximate the full-resolution outputs reduced by `s`:
    /// a height in pixels is multiplied by `s`. Default: unchanged (normals, colours, slopes).
    fn level_outputs(_params: &Self::Params, _s: f64, outputs: Self::Out) -> Self::Out {
        outputs
    }
    /// The outputs over `win` of the whole image, at `win.scale`, for a [`Kind::Source`]:
    /// what the full-resolution outputs reduced by the scale would be, or the procedure
    /// sampled on the coarse grid directly. Every source implements it; for other kinds it is
    /// never called.
    fn run_region(
        _params: &Self::Params,
        _inputs: Self::In,
        _win: Window,
        _ctx: &RunContext,
    ) -> Result<Self::Out, RgbnError> {
        Err(RgbnError::InvalidImage(format!(
            "operator {} computes no windows (it is not a source)",
            Self::spec().id
        )))
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

/// An operator's parameters parsed and checked once: the typed struct, the canonical map
/// (every parameter present; what files store and `--set` edits) and the hash of that map that
/// content keys use (input file paths left out: files are keyed by their bytes). Cloning is
/// cheap.
#[derive(Clone)]
pub struct Parsed {
    typed: Arc<dyn Any + Send + Sync>,
    values: Arc<BTreeMap<String, ParamValue>>,
    hash: u128,
}

impl Parsed {
    /// The canonical map.
    #[must_use]
    pub fn values(&self) -> &BTreeMap<String, ParamValue> {
        &self.values
    }
    /// The typed parameters, when they are a `P`.
    #[must_use]
    pub fn get<P: 'static>(&self) -> Option<&P> {
        self.typed.downcast_ref()
    }
    /// Hash of the canonical map, input file paths left out.
    #[must_use]
    pub fn hash(&self) -> u128 {
        self.hash
    }
}

impl PartialEq for Parsed {
    fn eq(&self, o: &Self) -> bool {
        self.hash == o.hash && self.values == o.values
    }
}

impl std::fmt::Debug for Parsed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.values.fmt(f)
    }
}

/// The object-safe face of an [`Operator`], as held by the registry. Every method but
/// [`DynOp::parse`] takes parameters already parsed.
pub trait DynOp: Send + Sync {
    /// The spec.
    fn spec(&self) -> &OpSpec;
    /// Every parameter with doc, range and default.
    fn params(&self) -> &[ParamInfo];
    /// Applies `values` over the defaults and checks them ([`Operator::check`]): the one parse
    /// of a node's parameters (memoised by content: parsing the same map again returns the
    /// same [`Parsed`]).
    fn parse(&self, values: &BTreeMap<String, ParamValue>) -> Result<Parsed, ParamError>;
    /// `p` with every path parameter passed through `f` (name, metadata, value): relative
    /// paths resolved against a folder. Not a parse: the typed parameters are rewritten.
    fn map_paths(&self, p: &Parsed, f: &mut dyn FnMut(&'static str, &Meta, &mut String)) -> Parsed;
    /// [`Operator::kind`].
    fn kind(&self, p: &Parsed) -> Kind;
    /// What input `input` (port order) must provide, from the kind and the port's [`Read`].
    fn footprint(&self, p: &Parsed, input: usize) -> Footprint {
        let read = self
            .spec()
            .inputs
            .get(input)
            .map_or(Read::Whole, |s| s.read);
        self.kind(p).footprint(read)
    }
    /// Whether it computes windows on its own ([`Kind::Source`]).
    fn regional(&self, p: &Parsed) -> bool {
        self.kind(p) == Kind::Source
    }
    /// The parameters at a level `s` times coarser (`None`: no coarse form).
    fn scaled(&self, p: &Parsed, s: f64) -> Option<Parsed>;
    /// [`Operator::out_size`].
    fn out_size(&self, p: &Parsed, inputs: &[Option<(usize, usize)>]) -> Option<(usize, usize)>;
    /// [`Operator::SCRATCH`].
    fn scratch(&self) -> f64;
    /// [`Operator::damage`].
    fn damage(
        &self,
        old: &Parsed,
        new: &Parsed,
        inputs: &[Option<(usize, usize)>],
    ) -> Option<Vec<[f64; 4]>>;
    /// Runs on the whole inputs.
    fn run(
        &self,
        p: &Parsed,
        inputs: Vec<Option<Value>>,
        ctx: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        self.run_at(p, inputs, ctx, (0, 0), 1)
    }
    /// Runs on the crop whose top-left pixel is `origin` of the whole image (positions
    /// shifted by the declarations), at a level of reduction `scale` (`p` already scaled;
    /// outputs mapped by [`Operator::level_outputs`] when `scale > 1`).
    fn run_at(
        &self,
        p: &Parsed,
        inputs: Vec<Option<Value>>,
        ctx: &RunContext,
        origin: (usize, usize),
        scale: usize,
    ) -> Result<Vec<Value>, RgbnError>;
    /// [`Operator::run_region`].
    fn run_region(
        &self,
        p: &Parsed,
        inputs: Vec<Option<Value>>,
        win: Window,
        ctx: &RunContext,
    ) -> Result<Vec<Value>, RgbnError>;
}

/// Parsed parameters kept per operator, by the hash of the map they were parsed from.
const MEMO: usize = 512;

struct Entry<T: Operator> {
    spec: OpSpec,
    params: Vec<ParamInfo>,
    memo: Mutex<HashMap<u128, Parsed>>,
    _op: PhantomData<fn() -> T>,
}

impl<T: Operator> Entry<T> {
    fn boxed() -> Box<dyn DynOp> {
        let mut spec = T::spec();
        debug_assert!(spec.inputs.is_empty() && spec.outputs.is_empty());
        spec.inputs = T::In::ports();
        spec.outputs = T::Out::ports();
        Box::new(Self {
            spec,
            params: params::describe::<T::Params>(),
            memo: Mutex::new(HashMap::new()),
            _op: PhantomData,
        })
    }

    fn typed<'a>(&self, p: &'a Parsed) -> &'a T::Params {
        p.get::<T::Params>()
            .unwrap_or_else(|| panic!("parameters of another operator passed to {}", self.spec.id))
    }

    /// Wraps typed parameters with their canonical map and hash.
    fn wrap(&self, typed: T::Params) -> Parsed {
        let values = params::to_values(&typed);
        // Input files are keyed by their bytes elsewhere, not by their path here.
        let hash = map_hash(&values, |name| {
            self.params
                .iter()
                .any(|i| i.name == name && i.kind == params::ParamKind::Path && !i.meta.output)
        });
        Parsed {
            typed: Arc::new(typed),
            values: Arc::new(values),
            hash,
        }
    }
}

/// The hash of a parameter map: each name, then its value, or only the marker `input-file`
/// for the names `input_file` picks.
fn map_hash(values: &BTreeMap<String, ParamValue>, input_file: impl Fn(&str) -> bool) -> u128 {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    for (name, value) in values {
        h.update(&(name.len() as u64).to_le_bytes());
        h.update(name.as_bytes());
        if input_file(name) {
            h.update(b"input-file");
        } else {
            value.hash_into(&mut h);
        }
    }
    h.digest128()
}

impl<T: Operator> DynOp for Entry<T> {
    fn spec(&self) -> &OpSpec {
        &self.spec
    }
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }
    fn parse(&self, values: &BTreeMap<String, ParamValue>) -> Result<Parsed, ParamError> {
        let key = map_hash(values, |_| false);
        if let Some(p) = self.memo.lock().get(&key) {
            return Ok(p.clone());
        }
        let typed: T::Params = params::from_values(values)?;
        T::check(&typed).map_err(|e| match e {
            RgbnError::InvalidParam { name, detail } => ParamError::Range { name, detail },
            // Not about one parameter (checks report `InvalidParam`): name the operator.
            other => ParamError::Range {
                name: self.spec.id.to_string(),
                detail: other.to_string(),
            },
        })?;
        let p = self.wrap(typed);
        let mut memo = self.memo.lock();
        if memo.len() >= MEMO {
            memo.clear();
        }
        memo.insert(key, p.clone());
        Ok(p)
    }
    fn map_paths(&self, p: &Parsed, f: &mut dyn FnMut(&'static str, &Meta, &mut String)) -> Parsed {
        let mut typed = self.typed(p).clone();
        params::map_paths(&mut typed, f);
        self.wrap(typed)
    }
    fn kind(&self, p: &Parsed) -> Kind {
        T::kind(self.typed(p))
    }
    fn scaled(&self, p: &Parsed, s: f64) -> Option<Parsed> {
        let t = self.typed(p);
        match T::kind(t).coarse() {
            Coarse::Scaled => T::scaled(t, s).map(|t| self.wrap(t)),
            Coarse::None => None,
        }
    }
    fn out_size(&self, p: &Parsed, inputs: &[Option<(usize, usize)>]) -> Option<(usize, usize)> {
        T::out_size(self.typed(p), inputs)
    }
    fn scratch(&self) -> f64 {
        T::SCRATCH
    }
    fn damage(
        &self,
        old: &Parsed,
        new: &Parsed,
        inputs: &[Option<(usize, usize)>],
    ) -> Option<Vec<[f64; 4]>> {
        T::damage(self.typed(old), self.typed(new), inputs)
    }
    fn run_at(
        &self,
        p: &Parsed,
        inputs: Vec<Option<Value>>,
        ctx: &RunContext,
        origin: (usize, usize),
        scale: usize,
    ) -> Result<Vec<Value>, RgbnError> {
        let t = self.typed(p);
        let shifted;
        let t = if origin == (0, 0) {
            t
        } else {
            shifted = params::shifted(t, origin.0 as f64, origin.1 as f64);
            &shifted
        };
        let out = {
            let _current = ctx.cancel.enter();
            T::run(t, T::In::from_values(inputs)?, ctx)
        };
        // A result finished after cancellation may be partial: never let it out.
        ctx.cancel.check()?;
        let mut out = out?;
        if scale > 1 {
            out = T::level_outputs(t, scale as f64, out);
        }
        Ok(out.into_values())
    }
    fn run_region(
        &self,
        p: &Parsed,
        inputs: Vec<Option<Value>>,
        win: Window,
        ctx: &RunContext,
    ) -> Result<Vec<Value>, RgbnError> {
        let out = {
            let _current = ctx.cancel.enter();
            T::run_region(self.typed(p), T::In::from_values(inputs)?, win, ctx)
        };
        ctx.cancel.check()?;
        Ok(out?.into_values())
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
            Entry::<transform::TransformNode>::boxed(),
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

/// The source node of a value bound from memory with port type `ty` ([`bound`]; Rgbn, Mask or
/// Scalar), outside the registry: graph files cannot name it.
#[must_use]
pub fn bound_op(ty: PortType) -> Option<&'static dyn DynOp> {
    static BOUND: OnceLock<[Box<dyn DynOp>; 3]> = OnceLock::new();
    let ops = BOUND.get_or_init(|| {
        [
            Entry::<bound::BoundRgbn>::boxed(),
            Entry::<bound::BoundMask>::boxed(),
            Entry::<bound::BoundScalar>::boxed(),
        ]
    });
    ops.iter()
        .map(|b| b.as_ref())
        .find(|o| o.spec().outputs[0].ty == ty)
}

/// The id of the reusable-graph node (a graph file used as a node; see `crate::graph`).
pub const GRAPH_NODE_OP: &str = "graph";

/// The id of the reroute node: a point on a wire, one input `in` and one output `out` of the
/// type of what feeds it (see `crate::graph::reroute`). It runs nothing: the plan connects
/// its users straight to its source.
pub const REROUTE_OP: &str = "reroute";

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
        assert!(!ids.contains(&REROUTE_OP));
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
                assert!(op.parse(&BTreeMap::new()).is_err(), "{}", s.id);
            }
            assert!(op.parse(&given).is_ok(), "{}", s.id);
        }
    }

    #[test]
    fn every_source_computes_its_windows_as_the_whole_image_has_them() {
        // A source (Kind::Source) is tiled by the engine: its run_region must be implemented
        // and give, at full resolution, exactly the pixels of the whole run.
        let mut sources = 0;
        for op in registry() {
            let Ok(p) = op.parse(&BTreeMap::new()) else {
                continue;
            };
            if op.kind(&p) != Kind::Source {
                continue;
            }
            sources += 1;
            let id = op.spec().id;
            let none = || vec![None; op.spec().inputs.len()];
            let ctx = RunContext::default();
            let whole = op
                .run(&p, none(), &ctx)
                .unwrap_or_else(|e| panic!("{id}: {e}"));
            let win = Window {
                x: 3,
                y: 5,
                w: 20,
                h: 11,
                scale: 1,
            };
            let part = op
                .run_region(&p, none(), win, &ctx)
                .unwrap_or_else(|e| panic!("{id}: {e}"));
            assert_eq!(part.len(), whole.len(), "{id}");
            for (a, b) in part.iter().zip(&whole) {
                assert_eq!(*a, value::window_of(b, win), "{id}");
            }
        }
        assert!(sources >= 2, "demo and surface are sources");
    }
}
