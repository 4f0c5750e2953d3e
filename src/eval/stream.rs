//! Streamed evaluation: a plan whose requested outputs depend, through local operators only, on
//! one `load` of PNG, TIFF or EXR files is run strip by strip ([`crate::raster::strips`]), so `rgbn eval`
//! processes images larger than memory with a peak set by the strip.
//!
//! Per strip, the `load` instance yields the strip's window (the strip grown by the plan's
//! halo, [`StreamPlan::halo`]), and every instance on the way to the outputs runs on that
//! window as on a crop ([`crate::nodes::DynOp::run_at`], positional parameters shifted), in
//! plan order; the outputs' core rows are handed on. As with region evaluation
//! ([`super::region`]), the halo is each instance's largest local footprint added up along the
//! longest path, so the core rows are what a whole-image run gives (bit for bit for finite
//! kernels; within the documented truncation of a recursive Gaussian otherwise).
//!
//! Nothing is cached: a streamed run reads each file once, top to bottom.

// Graph errors carry their location by value; they are cold paths.
#![allow(clippy::result_large_err)]

use super::{Conn, Plan};
use crate::error::RgbnError;
use crate::graph::GraphError;
use crate::nodes::load::LoadParams;
use crate::nodes::{Footprint, PortType, RunContext, Value};
use crate::raster::strips::{self, Opened, StreamInput};

/// A plan that can be streamed, with its opened input.
pub struct StreamPlan<'p> {
    plan: &'p Plan,
    /// The `load` instance.
    source: usize,
    /// The instances to run per strip, in plan order (the source excluded).
    order: Vec<usize>,
    /// The requested outputs: instance, port.
    outputs: Vec<(usize, usize)>,
    input: StreamInput,
    halo: usize,
    /// The outputs read of each instance ([`Plan::demand`]).
    demand: Vec<u64>,
    /// The image pixel of the input's first (top-left) pixel: (0, 0) unless a window is read
    /// ([`StreamPlan::set_window`]).
    origin: (usize, usize),
}

/// What [`StreamPlan::check`] found.
pub enum Streamable<'p> {
    /// The plan streams.
    Yes(Box<StreamPlan<'p>>),
    /// It does not, for this reason.
    No(String),
}

impl<'p> StreamPlan<'p> {
    /// Checks that `outputs` (graph output names) can be streamed from `plan`: each an image or
    /// a picture, all depending on one `load` of PNG, TIFF or EXR files through operators whose inputs are
    /// all local ([`Footprint::Local`]), none read through a number port. Opens the files.
    pub fn check(plan: &'p Plan, outputs: &[&str]) -> Result<Streamable<'p>, GraphError> {
        let no = |s: String| Ok(Streamable::No(s));
        let mut outs = Vec::new();
        for name in outputs {
            let Some(Conn::Slot(i, port)) = plan.outputs.get(*name) else {
                return no(format!("graph output {name:?} is not connected to a node"));
            };
            match plan.output_types.get(*name) {
                Some(PortType::Rgbn | PortType::Picture) => outs.push((*i, *port)),
                Some(t) => {
                    return no(format!(
                        "graph output {name:?} is a {t:?}; only images and pictures are written row by row"
                    ))
                }
                None => return no(format!("graph output {name:?} has no type")),
            }
        }
        if outs.is_empty() {
            return no("no output is requested".into());
        }
        // Instances needed, and the context each output of theirs needs (the halo).
        let n = plan.instances.len();
        let mut need: Vec<Option<usize>> = vec![None; n];
        for &(i, _) in &outs {
            need[i] = Some(0);
        }
        let mut source = None;
        let mut order = Vec::new();
        for i in (0..n).rev() {
            let Some(below) = need[i] else { continue };
            let inst = &plan.instances[i];
            let spec = inst.op.spec();
            let node = |why: &str| {
                format!(
                    "node {} ({}) {why}",
                    inst.at.node.map_or_else(|| "?".into(), |id| id.to_string()),
                    spec.id
                )
            };
            if spec.id == "load" {
                if source.is_some_and(|s| s != i) {
                    return no("the outputs depend on more than one loaded image".into());
                }
                source = Some(i);
                continue;
            }
            if spec.side_effect {
                return no(node("writes files"));
            }
            let mut connected = false;
            let mut halo = 0;
            for (k, c) in inst.inputs.iter().enumerate() {
                match c {
                    Conn::Slot(j, port) => {
                        connected = true;
                        if plan.is_number(*j, *port) {
                            return no(node("reads a number, which summarises a whole image"));
                        }
                        match inst.op.footprint(&inst.params, k) {
                            Footprint::Local { halo: h } => halo = halo.max(h),
                            Footprint::Global | Footprint::Pattern => {
                                return no(node(&format!(
                                    "needs its whole input {:?}",
                                    spec.inputs[k].name
                                )))
                            }
                        }
                    }
                    Conn::Unbound { name, .. } => {
                        return no(format!("graph input {name:?} is not bound"))
                    }
                    Conn::None => {}
                }
            }
            if !connected {
                return no(node("is a source other than a file"));
            }
            for c in &inst.inputs {
                if let Conn::Slot(j, _) = c {
                    need[*j] = Some(need[*j].unwrap_or(0).max(below + halo));
                }
            }
            order.push(i);
        }
        order.reverse();
        let Some(source) = source else {
            return no("the outputs depend on no loaded image".into());
        };
        let Some(p) = plan.instances[source].params.get::<LoadParams>() else {
            return no("the loaded image comes from another operator".into());
        };
        let at = plan.instances[source].at.clone();
        let spec = p.input_spec().map_err(|source| GraphError::Node {
            op: "load".into(),
            source,
            at: at.clone(),
        })?;
        let lopts = p.load_options();
        let input = match StreamInput::open(&spec, &lopts).map_err(|source| GraphError::Node {
            op: "load".into(),
            source,
            at,
        })? {
            Opened::Stream(s) => *s,
            Opened::Whole(why) => return no(why),
        };
        let asked: Vec<(usize, Option<usize>)> = outs.iter().map(|&(i, p)| (i, Some(p))).collect();
        let demand = plan.demand(&asked);
        Ok(Streamable::Yes(Box::new(StreamPlan {
            demand,
            plan,
            source,
            order,
            outputs: outs,
            halo: need[source].unwrap_or(0),
            input,
            origin: (0, 0),
        })))
    }

    /// Rows of context per strip edge: the footprints added up along the longest path.
    #[must_use]
    pub fn halo(&self) -> usize {
        self.halo
    }

    /// The image's width and height (the window's once one is set).
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        self.input.size()
    }

    /// Runs over `window` of the image only (an OME-Zarr input; else the reason it cannot):
    /// the strips are the window's, positional parameters are shifted to it, and its edges
    /// are taken for the image's, so only what lies [`StreamPlan::halo`] inside an edge that is
    /// not the image's own is what a whole run gives (a caller asks for its rectangle grown by
    /// the halo and keeps the rectangle: `rgbn.dask`'s tasks). Before [`StreamPlan::run`].
    pub fn set_window(&mut self, window: crate::raster::window::Rect) -> Result<(), String> {
        self.input.set_window(window)?;
        self.origin = (window.x, window.y);
        Ok(())
    }

    /// Runs the plan strip by strip (`strip` rows each, by default a window of planes under
    /// [`crate::recycle::BIG`], below); `out` receives, per strip, its first row, the requested outputs'
    /// values over its window, in the order requested, and the window rows that are the strip's
    /// (the rest is halo: write only these).
    pub fn run<E: From<GraphError>>(
        mut self,
        strip: Option<usize>,
        cancel: &crate::cancel::Cancel,
        mut out: impl FnMut(usize, &[Value], std::ops::Range<usize>) -> Result<(), E>,
    ) -> Result<(), E> {
        let (w, _) = self.input.size();
        let halo = self.halo;
        // By default a window's planes stay just under [`crate::recycle::BIG`]: the system
        // allocator's heap (kept by `recycle::keep_freed_memory`) hands the same blocks back
        // strip after strip, where bigger ones, mapped and unmapped, were page-faulted and
        // zero-filled afresh (a 4K graph: 0.29 s of system time with 273-row strips, 0.17 s
        // with 240). At least 256 rows (strips are what overlaps the decoding with the
        // operators; a 16K image keeps its 256 rows) and four halos.
        let strip = strip.unwrap_or_else(|| {
            (crate::recycle::BIG / (4 * w.max(1)))
                .saturating_sub(2 * halo)
                .max(256)
                .max(4 * halo)
        });
        let plan = self.plan;
        // Each instance told which of its outputs are read (a lazy operator skips the rest).
        let ctx = RunContext::new(plan.protected.clone()).with_cancel(cancel.clone());
        let ctxs: Vec<RunContext> = self
            .demand
            .iter()
            .enumerate()
            .map(|(i, &d)| {
                if plan.instances[i].op.spec().skipped(d) != 0 {
                    ctx.wanting(d)
                } else {
                    ctx.clone()
                }
            })
            .collect();
        let source_at = plan.instances[self.source].at.clone();
        let node_err = |i: usize, source: RgbnError| {
            GraphError::node(
                plan.instances[i].op.spec().id,
                source,
                plan.instances[i].at.clone(),
            )
        };
        let (order, outputs, src) = (&self.order, &self.outputs, self.source);
        let (ox, oy) = self.origin;
        let mut failed: Option<E> = None;
        let r = strips::for_each_strip_image(&mut self.input, halo, strip, |img, y0, core| {
            if cancel.is_cancelled() {
                return Err(Fail::Graph(GraphError::Cancelled));
            }
            let mut values: Vec<Option<Vec<Value>>> = vec![None; plan.instances.len()];
            values[src] = Some(vec![Value::Rgbn(img.clone())]);
            for &i in order {
                let inst = &plan.instances[i];
                let inputs: Vec<Option<Value>> = inst
                    .inputs
                    .iter()
                    .map(|c| match c {
                        Conn::Slot(j, port) => {
                            values[*j].as_ref().and_then(|v| v.get(*port)).cloned()
                        }
                        _ => None,
                    })
                    .collect();
                let v = inst
                    .op
                    .run_at(&inst.params, inputs, &ctxs[i], (ox, oy + y0), 1)
                    .map_err(|e| Fail::Graph(node_err(i, e)))?;
                values[i] = Some(v);
            }
            let got: Vec<Value> = outputs
                .iter()
                .map(|&(i, port)| values[i].as_ref().expect("computed above")[port].clone())
                .collect();
            // Only the outputs live on while they are written.
            drop(values);
            out(oy + y0 + core.start, &got, core).map_err(|e| {
                failed = Some(e);
                Fail::Out
            })
        });
        match r {
            Ok(_) => Ok(()),
            Err(Fail::Out) => Err(failed.expect("set with Fail::Out")),
            Err(Fail::Graph(e)) => Err(e.into()),
            Err(Fail::Read(source)) => Err(GraphError::node("load", source, source_at).into()),
        }
    }
}

/// Why a strip stopped.
enum Fail {
    /// An operator failed (or the run was cancelled).
    Graph(GraphError),
    /// Reading the files failed.
    Read(RgbnError),
    /// The consumer of the outputs failed (its error is kept aside).
    Out,
}

impl From<RgbnError> for Fail {
    fn from(e: RgbnError) -> Self {
        Fail::Read(e)
    }
}
