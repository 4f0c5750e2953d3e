//! The graph commands of the CLI: `eval`, `batch`, `check`, `ops` (a part of [`crate::cli`]).

use super::error::{message, usage, CliError};
use super::image::StreamMode;
use super::out::Out;
use super::png_sink::{PngBand, PngSink};
use super::ExrArgs;
use crate::error::RgbnError;
use crate::eval::region::{RegionOptions, DEFAULT_TILE};
use crate::eval::stream::{StreamPlan, Streamable};
use crate::eval::zarr_sink::ZarrSink;
use crate::eval::{EvalOptions, EvalResult, Evaluator, Plan, Status, DEFAULT_BUDGET};
use crate::graph::{GraphError, LoadedGraph};
use crate::nodes::save::{write_value, write_value_zarr};
use crate::nodes::{PortType, Value};
use crate::raster::io::targets::{ExrTarget, PngTarget, RowEncoding};
use crate::raster::io::{self, SaveOptions};
use crate::raster::io::{Format, NormalConvention};
use crate::raster::window::Rect;
use clap::{Args, ValueEnum};
use parking_lot::Mutex;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// `rgbn eval`.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Graph file (.ron).
    pub graph: PathBuf,
    /// Bind a graph input to a file: NAME=PATH (repeatable).
    #[arg(long = "input", short = 'i', value_name = "NAME=PATH")]
    pub inputs: Vec<String>,
    #[command(flatten)]
    pub set: SetArgs,
    /// Write a graph output: NAME=PATH (repeatable). Without -o every output is evaluated and
    /// summarised, nothing written.
    #[arg(short = 'o', long = "output", value_name = "NAME=PATH")]
    pub outputs: Vec<String>,
    /// Print per-node statistics (time, cache hit/miss, bytes, relative curl, non-integrable
    /// fraction F, and the time of those readouts, taken after the nodes and apart from them).
    #[arg(long)]
    pub stats: bool,
    #[command(flatten)]
    pub cache: CacheArgs,
    /// Evaluate only this rectangle of the outputs, X,Y,W,H in pixels: the engine computes
    /// the tiles it covers plus the halos the operators need (whole only where an operator is
    /// global). Each -o file then holds the rectangle; number outputs have no region.
    #[arg(long, value_name = "X,Y,W,H", value_parser = Rect::parse)]
    pub region: Option<Rect>,
    /// Level of detail: the outputs reduced 2^L times by block means (a preview pyramid's
    /// level L; 0 is full resolution); --region is then in the level's pixels (without it, the
    /// whole level). Operators with a coarse form (Gaussian-family filters, pen, relight,
    /// procedural sources) run on the coarse grid; the others run at full resolution and are
    /// reduced.
    #[arg(long, value_name = "L", default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=20))]
    pub level: u32,
    /// Tile side in pixels for --region and --level.
    #[arg(long, value_name = "PX", default_value_t = DEFAULT_TILE as u64, value_parser = clap::value_parser!(u64).range(16..=8192))]
    pub tile: u64,
    #[command(flatten)]
    pub streaming: GraphStreamArgs,
    #[command(flatten)]
    pub exr: ExrArgs,
}

/// `--set`, shared by `rgbn eval` and `rgbn batch`.
#[derive(Args, Debug, Default)]
pub struct SetArgs {
    /// Set a parameter: NODE.PARAM=VALUE, NODE a node id or name (repeatable; in a batch, for
    /// every file). Lists are comma separated, points x:y,x:y.
    #[arg(
        long = "set",
        short = 's',
        value_name = "NODE.PARAM=VALUE",
        allow_hyphen_values = true
    )]
    pub sets: Vec<String>,
}

/// `--cache-dir`, shared by `rgbn eval` and `rgbn batch`.
#[derive(Args, Debug, Default)]
pub struct CacheArgs {
    /// Keep node results in this folder and reuse them across runs.
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
}

/// Streaming a graph, shared by `rgbn eval` and `rgbn batch`.
#[derive(Args, Debug)]
pub struct GraphStreamArgs {
    /// Evaluate strip by strip, reading and writing rows, with memory bounded by the strip:
    /// `auto` does for images from 2 Mpx (or over the pixel limit) when the graph allows (one
    /// `load` of PNG, TIFF or EXR files, local operators only, images written as PNG or EXR
    /// and pictures as PNG; in a batch, per file), `always` insists (and says why not; in a
    /// batch a file that cannot is a failure), `never` evaluates whole images.
    #[arg(long, value_enum, default_value_t = StreamMode::Auto)]
    pub stream: StreamMode,
    /// Rows per strip when streaming (default: a window of planes under 4 MiB, at least 256
    /// rows and four halos; the first three strips ramp up from an eighth).
    #[arg(long, value_name = "ROWS", value_parser = clap::value_parser!(u64).range(1..))]
    pub strip_rows: Option<u64>,
}

/// `rgbn batch`.
#[derive(Args, Debug)]
pub struct BatchArgs {
    /// Graph file (.ron).
    pub graph: PathBuf,
    /// NAME=GLOB: the graph input fed with each matching file; further NAME=PATH inputs are
    /// the same for every file.
    #[arg(long = "input", short = 'i', value_name = "NAME=GLOB", required = true)]
    pub inputs: Vec<String>,
    #[command(flatten)]
    pub set: SetArgs,
    /// Folder for the results: STEM.OUTPUT.EXT per input file and graph output (.exr for
    /// images and fields, .png for pictures and masks, .txt for numbers).
    #[arg(long)]
    pub out_dir: PathBuf,
    /// Files processed at once.
    #[arg(short = 'j', long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub jobs: u32,
    /// Process only part K of N (K from 1): the matching files, sorted by path, are dealt
    /// round-robin into N disjoint shards that together cover them — one shard per job of a
    /// Slurm array (`--shard $SLURM_ARRAY_TASK_ID/N`), a Kubernetes indexed job or GNU parallel.
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    pub shard: Option<(usize, usize)>,
    #[command(flatten)]
    pub cache: CacheArgs,
    /// File format of image (RGBN) outputs: exr (float normals, colour and mask) or png
    /// (16-bit normal maps). Both are written row by row when streaming (see --stream).
    #[arg(long, value_enum, default_value_t = ImageFiles::Exr)]
    pub images: ImageFiles,
    #[command(flatten)]
    pub streaming: GraphStreamArgs,
    #[command(flatten)]
    pub exr: ExrArgs,
}

/// `rgbn batch --images`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ImageFiles {
    /// OpenEXR: float normals, colour and mask.
    Exr,
    /// 16-bit PNG normal maps (colour and mask are not kept); written row by row when
    /// streaming.
    Png,
}

/// `rgbn check`.
#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Graph file (.ron).
    pub graph: PathBuf,
}

/// `K/N` with 1 ≤ K ≤ N.
fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("{s:?} is not K/N with 1 ≤ K ≤ N (e.g. 2/8)");
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let (k, n): (usize, usize) = (
        k.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if k == 0 || k > n {
        return Err(bad());
    }
    Ok((k, n))
}

fn split_pair<'a>(s: &'a str, what: &str) -> Result<(&'a str, &'a str), CliError> {
    match s.split_once('=') {
        Some((a, b)) if !a.is_empty() && !b.is_empty() => Ok((a, b)),
        _ => Err(usage(format!("{what} {s:?} is not of the form NAME=VALUE"))),
    }
}

fn load_graph(path: &Path, sets: &[String]) -> Result<LoadedGraph, CliError> {
    let mut lg = LoadedGraph::load(path)?;
    apply_sets(&mut lg, sets)?;
    Ok(lg)
}

/// Applies `--set NODE.PARAM=VALUE` arguments to a loaded graph (in order; the graph is
/// validated once after all of them, so parameters that depend on each other can be given in
/// any order). A node is named by id or name; the parameter's text is parsed by its kind.
///
/// # Errors
/// A usage error for text not of that form; the graph's error for an unknown node or
/// parameter, or a value out of range.
pub fn apply_sets(lg: &mut LoadedGraph, sets: &[String]) -> Result<(), CliError> {
    let mut parsed = Vec::with_capacity(sets.len());
    for s in sets {
        let (lhs, value) = s
            .split_once('=')
            .ok_or_else(|| usage(format!("--set {s:?} is not of the form NODE.PARAM=VALUE")))?;
        let (node, param) = lhs
            .rsplit_once('.')
            .filter(|(n, p)| !n.is_empty() && !p.is_empty())
            .ok_or_else(|| usage(format!("--set {s:?} is not of the form NODE.PARAM=VALUE")))?;
        parsed.push((node, param, value));
    }
    if !parsed.is_empty() {
        lg.set_params(&parsed)?;
    }
    Ok(())
}

/// Parses `--input NAME=PATH` arguments into graph-input bindings (a later binding of the same
/// name replaces an earlier one).
///
/// # Errors
/// A usage error for text not of the form `NAME=PATH`.
pub fn parse_inputs(list: &[String]) -> Result<BTreeMap<String, PathBuf>, CliError> {
    let mut m = BTreeMap::new();
    for s in list {
        let (name, path) = split_pair(s, "--input")?;
        m.insert(name.to_string(), PathBuf::from(path));
    }
    Ok(m)
}

/// The evaluator of a command: a memory cache of `budget` bytes (0: none), and the disk cache
/// when asked for.
fn evaluator(cache_dir: Option<&Path>, budget: usize) -> Result<Evaluator, CliError> {
    let ev = Evaluator::new(budget);
    Ok(match cache_dir {
        Some(d) => ev.with_disk_cache(d)?,
        None => ev,
    })
}

fn progress_bar(total_hint: u64) -> indicatif::ProgressBar {
    let pb = indicatif::ProgressBar::new(total_hint);
    pb.set_style(
        indicatif::ProgressStyle::with_template("{spinner} [{bar:30}] {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    pb
}

fn describe_value(v: &Value) -> String {
    match v {
        Value::Rgbn(i) => format!(
            "rgbn {}×{}{}",
            i.width(),
            i.height(),
            if i.mask().is_some() { " masked" } else { "" }
        ),
        Value::Mask(p) => format!("mask {}×{}", p.width(), p.height()),
        Value::Scalar(p) => {
            let (lo, hi) = p
                .data()
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), v| {
                    (a.min(*v), b.max(*v))
                });
            format!(
                "scalar {}×{} in [{lo:.4e}, {hi:.4e}]",
                p.width(),
                p.height()
            )
        }
        Value::Picture(p) => format!("picture {}×{}", p.width, p.height),
        Value::Number(x) => format!("{x:.6e}"),
    }
}

fn print_stats(out: &mut Out<'_>, r: &EvalResult, top: &str) -> Result<(), CliError> {
    out.line(format_args!(
        "{:<28} {:<18} {:<8} {:>10} {:>10} {:>11} {:>9} {:>11}",
        "node", "op", "cache", "time ms", "MB", "curl rel.", "F", "readout ms"
    ))?;
    for s in &r.stats {
        let mut node = match (s.at.node, &s.at.name) {
            (Some(id), Some(n)) => format!("{id} {n}"),
            (Some(id), None) => id.to_string(),
            _ => s.at.file.clone(),
        };
        if s.at.node.is_some() && s.at.file != top {
            // A node inside a graph file used as a node: name the file.
            let file = Path::new(&s.at.file)
                .file_name()
                .map_or_else(String::new, |f| f.to_string_lossy().into_owned());
            node = format!("{file}:{node}");
        }
        let status = match s.status {
            Status::Hit => "hit",
            Status::DiskHit => "disk",
            Status::Miss => "miss",
            Status::Effect => "effect",
        };
        out.line(format_args!(
            "{:<28} {:<18} {:<8} {:>10.1} {:>10.2} {:>11} {:>9} {:>11.1}",
            node,
            s.op,
            status,
            s.time.as_secs_f64() * 1e3,
            s.bytes as f64 / 1e6,
            s.curl.map_or_else(|| "-".into(), |c| format!("{c:.3e}")),
            s.fraction
                .map_or_else(|| "-".into(), |f| format!("{f:.2e}")),
            s.readout.as_secs_f64() * 1e3
        ))?;
    }
    out.line(format_args!(
        "{} nodes: {} hits, {} misses",
        r.stats.len(),
        r.hits(),
        r.misses()
    ))?;
    let budget = crate::eval::memory::budget()?;
    out.line(format_args!(
        "memory: estimated peak {}{}, budget {}{}",
        crate::eval::memory::human(r.memory.peak),
        match r.memory.unknown {
            0 => String::new(),
            n => format!(
                " ({n} node{} of unknown size)",
                if n == 1 { "" } else { "s" }
            ),
        },
        budget.map_or_else(|| "none".into(), crate::eval::memory::human),
        crate::eval::memory::measured_peak().map_or_else(String::new, |m| format!(
            ", measured peak RSS {}",
            crate::eval::memory::human(m)
        )),
    ))
}

/// `rgbn eval`.
pub fn eval_cmd(a: &EvalArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    let lg = load_graph(&a.graph, &a.set.sets)?;
    let inputs = parse_inputs(&a.inputs)?;
    let cwd = PathBuf::from(".");
    let plan = Plan::new(&lg, &inputs, &cwd)?;
    let mut requested: Vec<(String, PathBuf)> = Vec::new();
    for s in &a.outputs {
        let (name, path) = split_pair(s, "-o")?;
        if !plan.outputs.contains_key(name) {
            return Err(GraphError::Unknown {
                what: "graph output",
                name: name.to_string(),
                suggestion: crate::params::nearest(name, plan.outputs.keys().map(String::as_str)),
                at: lg.at(),
            }
            .into());
        }
        let path = PathBuf::from(path);
        let protected: Vec<&Path> = plan.protected.iter().map(PathBuf::as_path).collect();
        io::check_output(&path, &protected)?;
        if requested.iter().any(|(_, p)| p == &path) {
            return Err(usage(format!(
                "two outputs are written to the same file: {}",
                path.display()
            )));
        }
        requested.push((name.to_string(), path));
    }
    let names: Vec<&str> = requested.iter().map(|(n, _)| n.as_str()).collect();
    // Streamed when it can be and should be.
    let why_whole = if a.streaming.stream == StreamMode::Never {
        None
    } else if a.region.is_some() || a.level > 0 {
        Some("--region and --level evaluate tiles of a rectangle".to_string())
    } else if a.stats {
        Some("--stats reports per-node numbers of a whole-image run".to_string())
    } else if requested.is_empty() {
        Some("no output is written (-o NAME=PATH)".to_string())
    } else {
        match stream_plan(&plan, &requested)? {
            Err(why) => Some(why),
            Ok(sp) if a.streaming.stream.streams_graph(sp.size()) => {
                return eval_stream(&plan, sp, &requested, a.streaming.strip_rows, &a.exr, out);
            }
            Ok(_) => None,
        }
    };
    a.streaming.stream.allows(why_whole.as_deref())?;
    // A whole-image run without --stats keeps only its outputs (below) and needs no memory
    // cache: the process ends with this evaluation.
    let whole_kept = a.region.is_none() && a.level == 0 && !a.stats;
    let budget = if whole_kept { 0 } else { DEFAULT_BUDGET };
    let ev = evaluator(a.cache.cache_dir.as_deref(), budget)?;
    let pb = progress_bar(0);
    let pb2 = pb.clone();
    let opts = EvalOptions {
        cancel: super::interrupt::token(),
        progress: Some(Arc::new(move |p| {
            pb2.set_length(p.total as u64);
            pb2.set_position(p.done as u64);
            pb2.set_message(p.op);
        })),
        curl_stats: a.stats,
    };
    if a.region.is_some() || a.level > 0 {
        pb.finish_and_clear();
        // No rectangle: the whole level (the request is clamped to the output).
        let rect = a
            .region
            .unwrap_or(Rect::new(0, 0, usize::MAX / 2, usize::MAX / 2));
        return eval_region(a, &plan, &ev, rect, &requested, &opts, out);
    }
    let r = if whole_kept {
        // Only the outputs are kept: every other value is dropped as soon as no node still
        // to run reads it, so its planes go back to the allocator for the nodes after it
        // (relight's picture reuses the input's freed normal plane instead of faulting in
        // fresh pages).
        let all: Vec<&str> = plan.outputs.keys().map(String::as_str).collect();
        let keep = if names.is_empty() { &all } else { &names };
        ev.eval_kept(&plan, keep, &[], &opts, None)
    } else {
        // --stats: every node's value is kept, each gets its readouts.
        ev.eval(&plan, &names, &opts)
    };
    pb.finish_and_clear();
    let r = r?;
    super::interrupt::check()?;
    let written = write_all(&r.outputs, &requested, &a.exr.save_options());
    // Interrupted while writing: the unfinished files were not put in place.
    super::interrupt::check()?;
    for ((name, path), done) in requested.iter().zip(written) {
        done?;
        out.line(format_args!(
            "wrote {name} ({}): {}",
            describe_value(&r.outputs[name]),
            path.display()
        ))?;
    }
    if requested.is_empty() {
        for (name, v) in &r.outputs {
            out.line(format_args!("{name}: {}", describe_value(v)))?;
        }
    }
    if a.stats {
        print_stats(out, &r, &plan.at.file)?;
    }
    Ok(())
}

/// Writes each requested output to its file, all at once (a PNG's single-threaded encoding
/// beside an EXR's compression, one file's flush to disk beside the next one's writing); the
/// result of each write in the order of `requested`. Every write is atomic on its own, so an
/// output that fails leaves its target untouched whatever the others do.
fn write_all(
    outputs: &BTreeMap<String, Value>,
    requested: &[(String, PathBuf)],
    save: &SaveOptions,
) -> Vec<Result<(), RgbnError>> {
    // Ctrl-C stops a write under way (an EXR between its batches of blocks): its temporary
    // file is removed, and the caller reports the interruption.
    let token = super::interrupt::token();
    if !crate::raster::par::pipelined() {
        // One thread: one file after the other.
        let _current = token.enter();
        return requested
            .iter()
            .map(|(name, path)| write_value(&outputs[name], path, save))
            .collect();
    }
    std::thread::scope(|s| {
        let writes: Vec<_> = requested
            .iter()
            .map(|(name, path)| {
                let v = &outputs[name];
                let token = token.clone();
                s.spawn(move || {
                    let _current = token.enter();
                    write_value(v, path, save)
                })
            })
            .collect();
        writes
            .into_iter()
            .map(|w| w.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
            .collect()
    })
}

/// The plan that writes the requested outputs strip by strip, or why they cannot be.
fn stream_plan<'p>(
    plan: &'p Plan,
    requested: &[(String, PathBuf)],
) -> Result<Result<StreamPlan<'p>, String>, CliError> {
    // Images are written row by row as PNG normal maps or RGBN EXRs, pictures as PNG.
    let rows_ok = |(name, p): &&(String, PathBuf)| match Format::of(p).ok() {
        Some(Format::Png) => true,
        Some(Format::Exr) => plan.output_types.get(name) == Some(&PortType::Rgbn),
        Some(Format::Zarr) => matches!(
            plan.output_types.get(name),
            Some(PortType::Rgbn | PortType::Picture)
        ),
        _ => false,
    };
    if let Some((_, p)) = requested.iter().find(|r| !rows_ok(r)) {
        return Ok(Err(format!(
            "{} is not written row by row (images: PNG, EXR or OME-Zarr; pictures: PNG or OME-Zarr)",
            p.display()
        )));
    }
    let names: Vec<&str> = requested.iter().map(|(n, _)| n.as_str()).collect();
    Ok(match StreamPlan::check(plan, &names)? {
        Streamable::No(why) => Err(why),
        Streamable::Yes(sp) => Ok(*sp),
    })
}

/// Runs `sp`'s strips, each output's rows to its EXR target or PNG sink (by position), and
/// ends every sink (a failed one with its error, which explains a band it refused).
fn stream_strips(
    sp: StreamPlan<'_>,
    strip_rows: Option<usize>,
    cancel: &crate::cancel::Cancel,
    exrs: &mut [Option<ExrTarget>],
    zarrs: &mut [Option<ZarrSink>],
    mut sinks: Vec<Option<PngSink<'_, '_>>>,
) -> Result<(), CliError> {
    let mut stopped = false;
    let r = sp.run(strip_rows, cancel, |_, values, core| {
        super::interrupt::check()?;
        for (((s, e), z), v) in sinks
            .iter_mut()
            .zip(exrs.iter_mut())
            .zip(zarrs.iter_mut())
            .zip(values)
        {
            if let Some(z) = z {
                z.write(v, core.clone())?;
                continue;
            }
            let band = match (v, s, e) {
                (Value::Rgbn(img), _, Some(e)) => {
                    e.write(img, core.clone())?;
                    continue;
                }
                (Value::Rgbn(img), Some(s), _) => {
                    s.write(PngBand::Normals(img.clone(), core.clone()))
                }
                (Value::Picture(p), Some(s), _) => s.write(PngBand::Rgba(p.clone(), core.clone())),
                (other, ..) => {
                    unreachable!("streamed outputs are images and pictures: {other:?}")
                }
            };
            if let Err(e) = band {
                stopped = e.is_none();
                return Err(e.map_or_else(|| usage("a PNG writer stopped"), Into::into));
            }
        }
        Ok::<(), CliError>(())
    });
    let mut ended = Ok(());
    for s in sinks.into_iter().flatten() {
        let f = s.finish();
        if ended.is_ok() {
            ended = f;
        }
    }
    match r {
        Err(_) if stopped && ended.is_err() => Err(ended.unwrap_err().into()),
        Err(e) => Err(e),
        Ok(()) => Ok(ended?),
    }
}

/// `rgbn eval` streamed ([`crate::eval::stream`]): images as 16-bit normal maps and pictures as
/// RGBA PNGs, written row by row.
fn eval_stream(
    plan: &Plan,
    sp: StreamPlan<'_>,
    requested: &[(String, PathBuf)],
    strip_rows: Option<u64>,
    exr_args: &ExrArgs,
    out: &mut Out<'_>,
) -> Result<(), CliError> {
    let (w, h) = sp.size();
    // Per output, a PNG, an EXR or an OME-Zarr target (`None` in the other lists).
    let mut targets = Vec::new();
    let mut exrs = Vec::new();
    let mut zarrs = Vec::new();
    for (name, path) in requested {
        let fmt = Format::of(path)?;
        let exr = fmt == Format::Exr;
        exrs.push(if exr {
            Some(ExrTarget::create(path, w, h, exr_args.format())?)
        } else {
            None
        });
        zarrs.push(
            (fmt == Format::Zarr)
                .then(|| ZarrSink::new(path.clone(), (w, h), exr_args.zarr_options())),
        );
        targets.push(match plan.output_types.get(name) {
            _ if exr || fmt == Format::Zarr => None,
            Some(PortType::Picture) => Some(PngTarget::create_rgba8(path, w, h)?),
            _ => Some(PngTarget::create(path, w, h, SaveOptions::default().bits)?),
        });
    }
    let cancel = super::interrupt::token();
    let encoding = RowEncoding::Normal(NormalConvention::OpenGl);
    let pipelined = crate::raster::par::pipelined();
    // Outside the pool, the PNG outputs are written by tasks on it; a worker of a pool (`--jobs`)
    // must not wait for tasks of its own pool, and writes them on threads of their own.
    let on_pool = rayon::current_thread_index().is_none();
    let strip_rows = strip_rows.map(|r| r as usize);
    if pipelined && on_pool {
        rayon::in_place_scope(|rscope| -> Result<(), CliError> {
            let mut sinks = Vec::new();
            for t in &mut targets {
                sinks.push(match t {
                    Some(t) => Some(PngSink::pool(rscope, t, encoding)?),
                    None => None,
                });
            }
            stream_strips(sp, strip_rows, &cancel, &mut exrs, &mut zarrs, sinks)
        })?;
    } else {
        std::thread::scope(|scope| -> Result<(), CliError> {
            let mut sinks = Vec::new();
            for t in &mut targets {
                sinks.push(match t {
                    Some(t) => Some(if pipelined {
                        PngSink::thread(scope, t, encoding)
                    } else {
                        PngSink::Here(Box::new(t.rows(encoding)?))
                    }),
                    None => None,
                });
            }
            stream_strips(sp, strip_rows, &cancel, &mut exrs, &mut zarrs, sinks)
        })?;
    }
    // Each file is synced and renamed into place; with more than one thread, side by side
    // (one file's wait for the disk beside the other's).
    let commits: Vec<Box<dyn FnOnce() -> Result<(), RgbnError> + Send>> = targets
        .into_iter()
        .flatten()
        .map(|t| Box::new(move || t.commit()) as Box<dyn FnOnce() -> _ + Send>)
        .chain(
            exrs.into_iter()
                .flatten()
                .map(|e| Box::new(move || e.commit()) as Box<dyn FnOnce() -> _ + Send>),
        )
        .chain(
            zarrs
                .into_iter()
                .flatten()
                .map(|z| Box::new(move || z.commit()) as Box<dyn FnOnce() -> _ + Send>),
        )
        .collect();
    let done: Vec<Result<(), RgbnError>> = if pipelined {
        std::thread::scope(|s| {
            let running: Vec<_> = commits.into_iter().map(|c| s.spawn(c)).collect();
            running
                .into_iter()
                .map(|r| r.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
                .collect()
        })
    } else {
        commits.into_iter().map(|c| c()).collect()
    };
    for d in done {
        d?;
    }
    for (name, path) in requested {
        out.line(format_args!(
            "wrote {name} ({w}×{h}, streamed): {}",
            path.display()
        ))?;
    }
    Ok(())
}

/// `rgbn eval --region`: each requested output (every image-like output without -o) over
/// the rectangle.
fn eval_region(
    a: &EvalArgs,
    plan: &Plan,
    ev: &Evaluator,
    rect: Rect,
    requested: &[(String, PathBuf)],
    opts: &EvalOptions,
    out: &mut Out<'_>,
) -> Result<(), CliError> {
    let ropts = RegionOptions {
        tile: a.tile as usize,
        level: a.level,
    };
    let names: Vec<(String, Option<&PathBuf>)> = if requested.is_empty() {
        plan.output_types
            .iter()
            .filter(|(_, t)| **t != PortType::Number)
            .map(|(n, _)| (n.clone(), None))
            .collect()
    } else {
        requested
            .iter()
            .map(|(n, p)| (n.clone(), Some(p)))
            .collect()
    };
    for (name, path) in names {
        let r = ev.eval_region(plan, &name, rect, &ropts, opts)?;
        super::interrupt::check()?;
        let level = if a.level > 0 {
            format!(" (level {}: reduced {}×)", a.level, 1u64 << a.level)
        } else {
            String::new()
        };
        let what = format!(
            "{} of {}×{}{level} at {}",
            describe_value(&r.value),
            r.size.0,
            r.size.1,
            r.rect
        );
        match path {
            Some(path) if a.region.is_some() && Format::of(path)? == Format::Zarr => {
                // Only the chunks of the rectangle, into a store of the output's whole size.
                let region = Some((r.size, r.rect));
                write_value_zarr(&r.value, path, &a.exr.zarr_options(), region)?;
                out.line(format_args!("wrote {name} ({what}): {}", path.display()))?;
            }
            Some(path) => {
                write_value(&r.value, path, &a.exr.save_options())?;
                out.line(format_args!("wrote {name} ({what}): {}", path.display()))?;
            }
            None => out.line(format_args!("{name}: {what}"))?,
        }
        if a.stats {
            out.line(format_args!(
                "zarr chunks read: {}",
                crate::raster::io::zarr::chunks_read()
            ))?;
            out.line(format_args!(
                "{:<28} {:<18} {:>9} {:>9} {:>12}",
                "tiled node", "op", "computed", "cached", "pixels"
            ))?;
            for t in &r.tiles {
                let node = match (t.at.node, &t.at.name) {
                    (Some(id), Some(n)) => format!("{id} {n}"),
                    (Some(id), None) => id.to_string(),
                    _ => t.at.file.clone(),
                };
                out.line(format_args!(
                    "{:<28} {:<18} {:>9} {:>9} {:>12}",
                    node, t.op, t.computed, t.cached, t.pixels
                ))?;
            }
        }
    }
    Ok(())
}

fn extension(ty: PortType, images: ImageFiles) -> &'static str {
    match ty {
        PortType::Rgbn if images == ImageFiles::Png => "png",
        PortType::Rgbn | PortType::Scalar => "exr",
        PortType::Picture | PortType::Mask => "png",
        PortType::Number => "txt",
    }
}

/// `rgbn batch`.
pub fn batch_cmd(a: &BatchArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    let lg = load_graph(&a.graph, &a.set.sets)?;
    let (first, rest) = a
        .inputs
        .split_first()
        .ok_or_else(|| usage("batch needs --input NAME=GLOB"))?;
    let (name, pattern) = split_pair(first, "--input")?;
    let fixed = parse_inputs(rest)?;
    let mut files: Vec<PathBuf> = glob::glob(pattern)
        .map_err(|e| usage(format!("bad glob pattern {pattern:?}: {e}")))?
        .filter_map(Result::ok)
        .filter(|p| p.is_file())
        .collect();
    if files.is_empty() {
        return Err(usage(format!("no files match {pattern:?}")));
    }
    if let Some((k, n)) = a.shard {
        // Round-robin over the sorted list: shards of equal size (±1) for any N.
        files.sort();
        let all = files.len();
        files = files
            .into_iter()
            .enumerate()
            .filter(|(i, _)| i % n == k - 1)
            .map(|(_, f)| f)
            .collect();
        out.line(format_args!(
            "shard {k}/{n}: {} of {all} files",
            files.len()
        ))?;
        if files.is_empty() {
            return Ok(());
        }
    }
    let ev = evaluator(a.cache.cache_dir.as_deref(), DEFAULT_BUDGET)?;
    if !a.out_dir.is_dir() {
        // As `mkdir -p`; a file in the way (or no permission) is an error naming the folder.
        std::fs::create_dir_all(&a.out_dir).map_err(|e| RgbnError::Write {
            detail: format!("cannot create the output folder: {e}"),
            path: a.out_dir.clone(),
        })?;
        out.line(format_args!("created folder {}", a.out_dir.display()))?;
    }
    let pb = progress_bar(files.len() as u64);
    let failures: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
    let written = std::sync::atomic::AtomicUsize::new(0);
    let streamed = std::sync::atomic::AtomicUsize::new(0);
    let run_one = |file: &PathBuf| -> Result<(), CliError> {
        let mut inputs = fixed.clone();
        inputs.insert(name.to_string(), file.clone());
        super::interrupt::check()?;
        let plan = Plan::new(&lg, &inputs, Path::new("."))?;
        let stem = file
            .file_stem()
            .map_or_else(|| "out".into(), |s| s.to_string_lossy().into_owned());
        let protected: Vec<&Path> = plan.protected.iter().map(PathBuf::as_path).collect();
        let mut requested = Vec::new();
        for (oname, ty) in &plan.output_types {
            let ext = extension(*ty, a.images);
            let path = a.out_dir.join(format!("{stem}.{oname}.{ext}"));
            io::check_output(&path, &protected)?;
            requested.push((oname.clone(), path));
        }
        // Strip by strip when it can be and should be (as `rgbn eval`).
        if a.streaming.stream != StreamMode::Never {
            let why = match stream_plan(&plan, &requested)? {
                Ok(sp) if a.streaming.stream.streams_graph(sp.size()) => {
                    let mut sink = std::io::sink();
                    eval_stream(
                        &plan,
                        sp,
                        &requested,
                        a.streaming.strip_rows,
                        &a.exr,
                        &mut Out::new(&mut sink),
                    )?;
                    written.fetch_add(requested.len(), std::sync::atomic::Ordering::Relaxed);
                    streamed.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    return Ok(());
                }
                Ok(_) => None,
                Err(why) => Some(why),
            };
            a.streaming.stream.allows(why.as_deref())?;
        }
        let opts = EvalOptions {
            cancel: super::interrupt::token(),
            ..EvalOptions::default()
        };
        let r = ev.eval(&plan, &[], &opts)?;
        for (oname, path) in &requested {
            super::interrupt::check()?;
            write_value(&r.outputs[oname], path, &a.exr.save_options())?;
            written.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        Ok(())
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.jobs as usize)
        .build()
        .map_err(|e| usage(format!("cannot start {} jobs: {e}", a.jobs)))?;
    pool.scope(|s| {
        for file in &files {
            let (pb, failures, run_one) = (&pb, &failures, &run_one);
            s.spawn(move |_| {
                if super::interrupt::received().is_some() {
                    return; // interrupted: the files not started are skipped, not failed
                }
                pb.set_message(file.display().to_string());
                if let Err(e) = run_one(file) {
                    if super::interrupt::received().is_some() {
                        return;
                    }
                    pb.suspend(|| eprintln!("{}", message(&e)));
                    failures.lock().push(file.clone());
                }
                pb.inc(1);
            });
        }
    });
    pb.finish_and_clear();
    let mut failures = failures.into_inner();
    failures.sort();
    let streamed = streamed.load(std::sync::atomic::Ordering::Relaxed);
    out.line(format_args!(
        "processed {} files{}, wrote {} outputs to {}, {} failed",
        files.len(),
        if streamed > 0 {
            format!(" ({streamed} streamed strip by strip)")
        } else {
            String::new()
        },
        written.load(std::sync::atomic::Ordering::Relaxed),
        a.out_dir.display(),
        failures.len()
    ))?;
    super::interrupt::check()?;
    if failures.is_empty() {
        return Ok(());
    }
    let list: Vec<String> = failures.iter().map(|f| f.display().to_string()).collect();
    Err(CliError::Batch {
        failed: failures.len(),
        total: files.len(),
        list: list.join(", "),
    })
}
